//! WAV streams: RIFF, and RF64 / BW64 (the 64-bit sizes of the EBU's WAV for files past
//! 4 GiB, in a `ds64` chunk before `fmt `) — see the [parent module](super) for what is
//! read and how.

use super::{read_full, PcmReader, RawEncoding};
use super::{AudioFormat, AudioSource};
use crate::{Error, Result};
use std::io::Read;
use std::path::{Path, PathBuf};

/// A WAV stream (see the [module docs](super)).
pub struct WavSource<R> {
    pcm: PcmReader<R>,
    rate: u32,
    name: PathBuf,
    total: Option<u64>,
}

fn u16_at(b: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([b[i], b[i + 1]])
}
fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

impl<R: Read + Send> WavSource<R> {
    /// Parse the header up to the `data` chunk. `greedy`: reads fill whole blocks (a
    /// file) instead of returning what has arrived (a pipe).
    pub fn new(mut r: R, name: &Path, greedy: bool) -> Result<Self> {
        let truncated = || Error::format(name, "truncated WAV file");
        // A chunk's `size` bytes and its pad byte.
        let body = |r: &mut R, size: u32| -> Result<Vec<u8>> {
            let mut b = vec![0u8; size as usize + (size as usize & 1)];
            if read_full(r, &mut b).map_err(|e| Error::io(name, e))? < b.len() {
                return Err(truncated());
            }
            Ok(b)
        };
        let mut head = [0u8; 12];
        if read_full(&mut r, &mut head).map_err(|e| Error::io(name, e))? < 12 {
            return Err(truncated());
        }
        let rf64 = matches!(&head[0..4], b"RF64" | b"BW64");
        if !(rf64 || &head[0..4] == b"RIFF") || &head[8..12] != b"WAVE" {
            return Err(Error::format(name, "bad WAV file: no RIFF/WAVE header"));
        }
        let mut fmt: Option<(RawEncoding, usize, u32)> = None;
        // RF64's data size, from its ds64 chunk.
        let mut ds64_data: Option<u64> = None;
        let mut header_notes = Vec::new();
        loop {
            let mut ch = [0u8; 8];
            if read_full(&mut r, &mut ch).map_err(|e| Error::io(name, e))? < 8 {
                return Err(match fmt {
                    None => Error::format(name, "bad WAV file: no fmt chunk"),
                    Some(_) => Error::format(name, "no audio frames (zero samples): no data chunk"),
                });
            }
            let size = u32_at(&ch, 4);
            if rf64 && ds64_data.is_none() && &ch[0..4] != b"ds64" {
                return Err(Error::format(
                    name,
                    "bad RF64 file: its first chunk is not ds64 (the chunk of its 64-bit sizes)",
                ));
            }
            match &ch[0..4] {
                b"ds64" if rf64 => {
                    // riff size, data size, sample count (u64 each), then a table of other
                    // chunks' sizes, which only chunks before data would need.
                    if !(24..=1 << 16).contains(&size) {
                        return Err(Error::format(
                            name,
                            format!("bad RF64 file: ds64 chunk of {size} bytes"),
                        ));
                    }
                    let d = body(&mut r, size)?;
                    ds64_data = Some(u64::from_le_bytes(d[8..16].try_into().expect("8 bytes")));
                }
                b"fmt " => {
                    if !(16..=1024).contains(&size) {
                        return Err(Error::format(
                            name,
                            format!("bad WAV file: fmt chunk of {size} bytes"),
                        ));
                    }
                    let f = body(&mut r, size)?;
                    let mut tag = u16_at(&f, 0);
                    let channels = u16_at(&f, 2) as usize;
                    let rate = u32_at(&f, 4);
                    let bits = u16_at(&f, 14);
                    if tag == 0xFFFE && size >= 26 {
                        tag = u16_at(&f, 24); // the sub-format GUID's first two bytes
                    }
                    if channels == 0 {
                        return Err(Error::format(name, "WAV header declares 0 channels"));
                    }
                    if rate == 0 {
                        return Err(Error::format(name, "WAV header declares a sample rate of 0 Hz"));
                    }
                    let unsupported = |what: String| {
                        Error::format(
                            name,
                            format!(
                                "unsupported bit depth: {what} (supported: 8-, 16-, 24-, 32-bit integer and 32-, 64-bit float WAV; 16- and 24-bit FLAC)"
                            ),
                        )
                    };
                    let enc = match (tag, bits) {
                        (1, 8) => RawEncoding::U8,
                        (1, 16) => RawEncoding::S16le,
                        (1, 24) => RawEncoding::S24le,
                        (1, 32) => RawEncoding::S32le,
                        (3, 32) => RawEncoding::F32le,
                        (3, 64) => RawEncoding::F64le,
                        (1, b) => return Err(unsupported(format!("{b}-bit integer PCM"))),
                        (3, b) => return Err(unsupported(format!("{b}-bit float"))),
                        _ => {
                            return Err(Error::format(
                                name,
                                "unsupported WAV encoding (supported: 8-, 16-, 24-, 32-bit integer PCM and 32-, 64-bit float)",
                            ))
                        }
                    };
                    // Block align is redundant for packed samples: a wrong one (0, or one
                    // channel's size, as some hand-written headers have) is noted and the
                    // samples read packed; a larger one (24-bit samples in 4-byte slots,
                    // say) would be misread as packed, so it is refused.
                    let align = u16_at(&f, 12) as usize;
                    let packed = channels * enc.bytes();
                    let contradicts = format!(
                        "WAV header contradicts itself: block align {align} bytes, but {channels} channels of {bits}-bit samples make {packed} bytes per frame"
                    );
                    if align > packed {
                        return Err(Error::format(
                            name,
                            format!("{contradicts} (samples in wider slots are not supported)"),
                        ));
                    }
                    if align != packed {
                        header_notes.push(format!(
                            "{}: {contradicts}; read as packed {bits}-bit samples",
                            name.display()
                        ));
                    }
                    if u16_at(&f, 0) == 0xFFFE && size >= 24 && u16_at(&f, 18) > bits {
                        header_notes.push(format!(
                            "{}: WAV header contradicts itself: {} valid bits in {bits}-bit samples; read as {bits}-bit samples",
                            name.display(),
                            u16_at(&f, 18)
                        ));
                    }
                    fmt = Some((enc, channels, rate));
                }
                b"data" => {
                    let Some((enc, channels, rate)) = fmt else {
                        return Err(Error::format(name, "bad WAV file: data chunk before fmt chunk"));
                    };
                    let fb = (enc.bytes() * channels) as u64;
                    let left = match ds64_data {
                        // RF64: the size is in ds64 (0 there too: a stream of unknown length).
                        Some(d) if size == 0xFFFF_FFFF => (d != 0).then_some(d),
                        _ => (size != 0 && size < 0x7FFF_F000).then_some(size as u64),
                    };
                    return Ok(WavSource {
                        pcm: PcmReader {
                            r,
                            enc,
                            channels,
                            left,
                            bytes: Vec::new(),
                            carry: 0,
                            frames_read: 0,
                            ended: false,
                            greedy,
                            notes: header_notes,
                            cut: None,
                            non_finite: 0,
                        },
                        rate,
                        name: name.to_path_buf(),
                        total: left.map(|l| l / fb),
                    });
                }
                _ => {
                    // Skip the chunk (and its pad byte).
                    let skip = size as u64 + (size as u64 & 1);
                    let n = std::io::copy(&mut (&mut r).take(skip), &mut std::io::sink())
                        .map_err(|e| Error::io(name, e))?;
                    if n < skip {
                        return Err(truncated());
                    }
                }
            }
        }
    }
}

impl<R: Read + Send> AudioSource for WavSource<R> {
    fn format(&self) -> AudioFormat {
        AudioFormat {
            sample_rate_hz: self.rate,
            channels: self.pcm.channels,
            total_frames: self.total,
        }
    }
    fn name(&self) -> &Path {
        &self.name
    }
    fn read_interleaved(&mut self, max_frames: usize, buf: &mut Vec<f32>) -> Result<usize> {
        self.pcm.read(&self.name, max_frames, buf, true)
    }
    fn take_notes(&mut self) -> Vec<String> {
        std::mem::take(&mut self.pcm.notes)
    }
}

#[cfg(test)]
mod tests {
    use super::super::open_stream;
    use std::path::Path;

    /// A 16-bit WAV of `frames` (interleaved, `channels`), as RIFF, or as RF64 with
    /// `data_size` in its ds64 chunk and 0xFFFFFFFF in the RIFF and data sizes.
    fn wav(channels: u16, frames: &[i16], rf64: Option<u64>) -> Vec<u8> {
        let data: Vec<u8> = frames.iter().flat_map(|v| v.to_le_bytes()).collect();
        let mut v = Vec::new();
        v.extend(if rf64.is_some() { b"RF64" } else { b"RIFF" });
        v.extend(
            if rf64.is_some() {
                u32::MAX
            } else {
                36 + data.len() as u32
            }
            .to_le_bytes(),
        );
        v.extend(b"WAVE");
        if let Some(size) = rf64 {
            v.extend(b"ds64");
            v.extend(28u32.to_le_bytes());
            v.extend((size + 72).to_le_bytes());
            v.extend(size.to_le_bytes());
            v.extend((size / (2 * channels as u64)).to_le_bytes());
            v.extend(0u32.to_le_bytes());
        }
        v.extend(b"fmt ");
        v.extend(16u32.to_le_bytes());
        v.extend(1u16.to_le_bytes());
        v.extend(channels.to_le_bytes());
        v.extend(16000u32.to_le_bytes());
        v.extend((32000 * channels as u32).to_le_bytes());
        v.extend((2 * channels).to_le_bytes());
        v.extend(16u16.to_le_bytes());
        v.extend(b"data");
        v.extend(
            if rf64.is_some() {
                u32::MAX
            } else {
                data.len() as u32
            }
            .to_le_bytes(),
        );
        v.extend(data);
        v
    }

    fn read(bytes: Vec<u8>) -> crate::Result<(Option<u64>, Vec<f32>)> {
        let mut s = open_stream(std::io::Cursor::new(bytes), Path::new("t.wav"))?;
        let total = s.format().total_frames;
        let (mut all, mut buf) = (Vec::new(), Vec::new());
        while s.read_interleaved(7, &mut buf)? > 0 {
            all.extend_from_slice(&buf);
        }
        Ok((total, all))
    }

    /// RF64 (a WAV past 4 GiB, as field recorders and 60-channel arrays write it) reads
    /// as the same WAV in RIFF form: its length from ds64, its data ended there (a byte
    /// after it is not audio), cut short an error as for RIFF.
    #[test]
    fn rf64_reads_as_its_riff_twin() {
        let frames: Vec<i16> = (0..3 * 500).map(|i| (i * 37 % 2000 - 1000) as i16).collect();
        let size = 2 * frames.len() as u64;
        let riff = read(wav(3, &frames, None)).unwrap();
        assert_eq!(riff.0, Some(500));
        assert_eq!(read(wav(3, &frames, Some(size))).unwrap(), riff);
        let mut bw64 = wav(3, &frames, Some(size));
        bw64[..4].copy_from_slice(b"BW64");
        bw64.extend([1, 2, 3, 4, 5, 6]);
        assert_eq!(read(bw64).unwrap(), riff);
        // ds64's data size 0: a stream of unknown length, read to its end.
        let (total, got) = read(wav(3, &frames, Some(0))).unwrap();
        assert_eq!((total, got), (None, riff.1.clone()));
        // Declared longer than it is: truncated.
        let e = read(wav(3, &frames, Some(size + 600))).unwrap_err().to_string();
        assert!(e.contains("t.wav") && e.contains("truncated"), "{e}");
        // RF64 without its ds64 chunk.
        let mut no_ds64 = wav(3, &frames, None);
        no_ds64[..4].copy_from_slice(b"RF64");
        let e = read(no_ds64).unwrap_err().to_string();
        assert!(e.contains("t.wav") && e.contains("not ds64"), "{e}");
    }
}
