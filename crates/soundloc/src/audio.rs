//! Audio input and output: WAV (16/24/32-bit integer, 32-bit float) and FLAC (16/24-bit)
//! files to planar `f32` channels, and WAV output.
//!
//! **Sample values are raw.** Integer PCM is converted to `f32` without normalisation: an
//! int16 sample 1000 becomes 1000.0 (not 1000/32768), an int24 sample its 24-bit integer
//! value, an int32 sample its value rounded to `f32`. 32-bit float samples are taken as
//! they are. HARK works on raw values and the dB scale of MUSIC results depends on it
//! (doubling the amplitude raises R by 6 dB).
//!
//! The format is recognised from the first bytes (`RIFF…WAVE` or `fLaC`), not from the
//! file name. Every error names the file: unreadable path, unknown format, no audio
//! frames, a non-finite sample (`sample 1234 of channel 2 is NaN`, both 0-based), an
//! unsupported bit depth.

use crate::{Error, Result};
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

/// Multichannel audio: `channels[c][n]` is sample n of channel c (planar), all channels
/// the same length, values raw (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Audio {
    /// Sampling rate in Hz.
    pub sample_rate_hz: u32,
    /// One vector of samples per channel, equal lengths.
    pub channels: Vec<Vec<f32>>,
}

/// Sample encoding for [`Audio::write_wav`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleFormat {
    /// 16-bit integer PCM; values are rounded and clamped to [−32768, 32767] (raw, no
    /// scaling).
    Int16,
    /// 32-bit IEEE float; values written as they are (raw, not normalised to ±1).
    Float32,
}

impl Audio {
    /// Audio from planar channels; an error when the channel lengths differ or the sample
    /// rate is 0.
    pub fn new(sample_rate_hz: u32, channels: Vec<Vec<f32>>) -> Result<Self> {
        if sample_rate_hz == 0 {
            return Err(Error::Config("audio: sample rate must be positive".into()));
        }
        if let Some(first) = channels.first() {
            if let Some((c, ch)) = channels.iter().enumerate().find(|(_, c)| c.len() != first.len()) {
                return Err(Error::Mismatch(format!(
                    "audio: channel {c} has {} samples, channel 0 has {}",
                    ch.len(),
                    first.len()
                )));
            }
        }
        Ok(Audio {
            sample_rate_hz,
            channels,
        })
    }

    /// Number of channels.
    pub fn num_channels(&self) -> usize {
        self.channels.len()
    }

    /// Samples per channel (0 without channels).
    pub fn num_samples(&self) -> usize {
        self.channels.first().map_or(0, Vec::len)
    }

    /// Duration in seconds: samples / sample rate.
    pub fn duration_s(&self) -> f64 {
        if self.sample_rate_hz == 0 {
            return 0.0;
        }
        self.num_samples() as f64 / self.sample_rate_hz as f64
    }

    /// A copy with the listed channels (0-based), in the listed order; an error on an
    /// out-of-range index or an empty list.
    pub fn select_channels(&self, indices: &[usize]) -> Result<Audio> {
        if indices.is_empty() {
            return Err(Error::Config("channel selection is empty".into()));
        }
        let n = self.num_channels();
        let channels = indices
            .iter()
            .map(|&i| {
                self.channels.get(i).cloned().ok_or_else(|| {
                    Error::Mismatch(format!(
                        "channel {i} does not exist: the audio has {n} channels (0-based: 0..={})",
                        n.saturating_sub(1)
                    ))
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Audio {
            sample_rate_hz: self.sample_rate_hz,
            channels,
        })
    }

    /// Samples from `start_s` to `end_s` seconds (sample indices rounded to nearest,
    /// `[start, end)`); an error when the range is not finite, empty, negative or extends
    /// past the end by more than half a sample.
    pub fn slice_seconds(&self, start_s: f64, end_s: f64) -> Result<Audio> {
        let dur = self.duration_s();
        if !start_s.is_finite() || !end_s.is_finite() || start_s < 0.0 || end_s <= start_s {
            return Err(Error::Config(format!(
                "time range {start_s} s .. {end_s} s is not a non-empty range starting at or after 0 s"
            )));
        }
        let fs = self.sample_rate_hz as f64;
        let n = self.num_samples();
        let a = (start_s * fs).round();
        let b = (end_s * fs).round();
        if b > n as f64 || a >= b {
            return Err(Error::Mismatch(format!(
                "time range {start_s} s .. {end_s} s is outside the audio ({dur:.6} s, {n} samples)"
            )));
        }
        let (a, b) = (a as usize, b as usize);
        Ok(Audio {
            sample_rate_hz: self.sample_rate_hz,
            channels: self.channels.iter().map(|c| c[a..b].to_vec()).collect(),
        })
    }

    /// Write a WAV file atomically (interleaved, `format` encoding, raw values).
    pub fn write_wav(&self, path: impl AsRef<Path>, format: SampleFormat) -> Result<()> {
        let path = path.as_ref();
        let nch = self.num_channels();
        if nch == 0 || nch > u16::MAX as usize {
            return Err(Error::Config(format!(
                "{}: cannot write {nch} channels to a WAV file",
                path.display()
            )));
        }
        let n = self.num_samples();
        if let Some((c, ch)) = self.channels.iter().enumerate().find(|(_, c)| c.len() != n) {
            return Err(Error::Mismatch(format!(
                "{}: channel {c} has {} samples, channel 0 has {n}",
                path.display(),
                ch.len()
            )));
        }
        let bytes = n as u64 * nch as u64 * if format == SampleFormat::Int16 { 2 } else { 4 };
        if bytes > u32::MAX as u64 - 100 {
            return Err(Error::Config(format!(
                "{}: {bytes} bytes of audio exceed the WAV size limit (4 GiB)",
                path.display()
            )));
        }
        let spec = hound::WavSpec {
            channels: nch as u16,
            sample_rate: self.sample_rate_hz,
            bits_per_sample: if format == SampleFormat::Int16 { 16 } else { 32 },
            sample_format: match format {
                SampleFormat::Int16 => hound::SampleFormat::Int,
                SampleFormat::Float32 => hound::SampleFormat::Float,
            },
        };
        let mut file = crate::output::atomic::AtomicFile::create(path)?;
        let werr = |e: hound::Error| Error::format(path, format!("writing WAV: {e}"));
        {
            let mut w = hound::WavWriter::new(&mut file, spec).map_err(werr)?;
            for i in 0..n {
                for ch in &self.channels {
                    match format {
                        SampleFormat::Int16 => {
                            let v = ch[i].round().clamp(i16::MIN as f32, i16::MAX as f32);
                            // NaN clamps to NaN; `as` maps it to 0.
                            w.write_sample(v as i16).map_err(werr)?;
                        }
                        SampleFormat::Float32 => w.write_sample(ch[i]).map_err(werr)?,
                    }
                }
            }
            w.finalize().map_err(werr)?;
        }
        file.commit()
    }
}

/// Read a WAV or FLAC file (recognised by its magic bytes) into planar raw-valued channels.
pub fn read_audio(path: impl AsRef<Path>) -> Result<Audio> {
    let path = path.as_ref();
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut r = BufReader::new(file);
    let mut magic = [0u8; 12];
    let mut got = 0;
    while got < magic.len() {
        match r.read(&mut magic[got..]) {
            Ok(0) => break,
            Ok(k) => got += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(Error::io(path, e)),
        }
    }
    if got == 0 {
        return Err(Error::format(path, "empty file"));
    }
    r.seek(SeekFrom::Start(0)).map_err(|e| Error::io(path, e))?;
    let audio = if got >= 12 && &magic[0..4] == b"RIFF" && &magic[8..12] == b"WAVE" {
        read_wav(r, path)?
    } else if got >= 4 && &magic[0..4] == b"fLaC" {
        read_flac(r, path)?
    } else {
        let shown: String = magic[..got.min(4)]
            .iter()
            .map(|&b| if b.is_ascii_graphic() { b as char } else { '.' })
            .collect();
        return Err(Error::format(
            path,
            format!("not a WAV (RIFF/WAVE) or FLAC file (starts with \"{shown}\")"),
        ));
    };
    if audio.num_samples() == 0 {
        return Err(Error::format(path, "no audio frames (zero samples)"));
    }
    Ok(audio)
}

fn check_finite(channels: &[Vec<f32>], path: &Path) -> Result<()> {
    for (c, ch) in channels.iter().enumerate() {
        if let Some((n, v)) = ch.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            let what = if v.is_nan() { "NaN" } else { "infinite" };
            return Err(Error::format(
                path,
                format!("sample {n} of channel {c} is {what} (0-based)"),
            ));
        }
    }
    Ok(())
}

fn unsupported_depth(path: &Path, what: &str) -> Error {
    Error::format(
        path,
        format!(
            "unsupported bit depth: {what} (supported: 16-, 24-, 32-bit integer and 32-bit float WAV; 16- and 24-bit FLAC)"
        ),
    )
}

fn read_wav<R: Read + Seek>(r: R, path: &Path) -> Result<Audio> {
    let herr = |e: hound::Error| match e {
        hound::Error::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            Error::format(path, "truncated WAV file")
        }
        hound::Error::IoError(io) => Error::io(path, io),
        hound::Error::Unsupported => Error::format(
            path,
            "unsupported WAV encoding (supported: 16-, 24-, 32-bit integer PCM and 32-bit float)",
        ),
        other => Error::format(path, format!("bad WAV file: {other}")),
    };
    let mut reader = hound::WavReader::new(r).map_err(herr)?;
    let spec = reader.spec();
    let nch = spec.channels as usize;
    if nch == 0 {
        return Err(Error::format(path, "WAV header declares 0 channels"));
    }
    if spec.sample_rate == 0 {
        return Err(Error::format(path, "WAV header declares a sample rate of 0 Hz"));
    }
    let frames = reader.len() as usize / nch;
    let mut channels: Vec<Vec<f32>> = (0..nch).map(|_| Vec::with_capacity(frames)).collect();
    match (spec.sample_format, spec.bits_per_sample) {
        (hound::SampleFormat::Int, 16 | 24 | 32) => {
            for (i, s) in reader.samples::<i32>().enumerate() {
                channels[i % nch].push(s.map_err(herr)? as f32);
            }
        }
        (hound::SampleFormat::Float, 32) => {
            for (i, s) in reader.samples::<f32>().enumerate() {
                channels[i % nch].push(s.map_err(herr)?);
            }
        }
        (hound::SampleFormat::Int, b) => {
            return Err(unsupported_depth(path, &format!("{b}-bit integer PCM")))
        }
        (hound::SampleFormat::Float, b) => return Err(unsupported_depth(path, &format!("{b}-bit float"))),
    }
    // Drop an incomplete trailing frame, if any.
    let n = channels.iter().map(Vec::len).min().unwrap_or(0);
    channels.iter_mut().for_each(|c| c.truncate(n));
    check_finite(&channels, path)?;
    Ok(Audio {
        sample_rate_hz: spec.sample_rate,
        channels,
    })
}

fn read_flac<R: Read>(r: R, path: &Path) -> Result<Audio> {
    let ferr = |e: claxon::Error| match e {
        claxon::Error::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            Error::format(path, "truncated FLAC file")
        }
        claxon::Error::IoError(io) => Error::io(path, io),
        other => Error::format(path, format!("bad FLAC file: {other}")),
    };
    let mut reader = claxon::FlacReader::new(r).map_err(ferr)?;
    let info = reader.streaminfo();
    let nch = info.channels as usize;
    if !matches!(info.bits_per_sample, 16 | 24) {
        return Err(unsupported_depth(
            path,
            &format!("{}-bit FLAC", info.bits_per_sample),
        ));
    }
    if info.sample_rate == 0 {
        return Err(Error::format(path, "FLAC stream declares a sample rate of 0 Hz"));
    }
    let cap = info.samples.unwrap_or(0).min(1 << 28) as usize;
    let mut channels: Vec<Vec<f32>> = (0..nch).map(|_| Vec::with_capacity(cap)).collect();
    let mut blocks = reader.blocks();
    let mut buf = Vec::new();
    while let Some(block) = blocks.read_next_or_eof(buf).map_err(ferr)? {
        if block.channels() as usize != nch {
            return Err(Error::format(
                path,
                format!(
                    "FLAC frame has {} channels, stream header says {nch}",
                    block.channels()
                ),
            ));
        }
        for (c, out) in channels.iter_mut().enumerate() {
            out.extend(block.channel(c as u32).iter().map(|&s| s as f32));
        }
        buf = block.into_buffer();
    }
    Ok(Audio {
        sample_rate_hz: info.sample_rate,
        channels,
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::path::PathBuf;

    pub(crate) fn temp_dir(tag: &str) -> PathBuf {
        use std::sync::atomic::{AtomicU64, Ordering};
        static N: AtomicU64 = AtomicU64::new(0);
        let d = std::env::temp_dir().join(format!(
            "soundloc-audio-{tag}-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn write_int_wav(path: &Path, bits: u16, frames: &[Vec<i32>]) {
        let spec = hound::WavSpec {
            channels: frames[0].len() as u16,
            sample_rate: 16000,
            bits_per_sample: bits,
            sample_format: hound::SampleFormat::Int,
        };
        let mut w = hound::WavWriter::create(path, spec).unwrap();
        for f in frames {
            for &s in f {
                match bits {
                    8 => w.write_sample(s as i8).unwrap(),
                    16 => w.write_sample(s as i16).unwrap(),
                    _ => w.write_sample(s).unwrap(),
                }
            }
        }
        w.finalize().unwrap();
    }

    fn write_float_wav(path: &Path, frames: &[Vec<f32>]) {
        let spec = hound::WavSpec {
            channels: frames[0].len() as u16,
            sample_rate: 48000,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        let mut w = hound::WavWriter::create(path, spec).unwrap();
        for f in frames {
            for &s in f {
                w.write_sample(s).unwrap();
            }
        }
        w.finalize().unwrap();
    }

    /// A minimal FLAC encoder (verbatim subframes, fixed block size) for tests.
    pub(crate) fn encode_flac(sample_rate: u32, bps: u32, channels: &[Vec<i32>]) -> Vec<u8> {
        struct Bits {
            out: Vec<u8>,
            acc: u64,
            n: u32,
        }
        impl Bits {
            fn put(&mut self, v: u64, bits: u32) {
                for i in (0..bits).rev() {
                    self.acc = (self.acc << 1) | ((v >> i) & 1);
                    self.n += 1;
                    if self.n == 8 {
                        self.out.push(self.acc as u8);
                        self.acc = 0;
                        self.n = 0;
                    }
                }
            }
            fn align(&mut self) {
                while self.n != 0 {
                    self.put(0, 1);
                }
            }
        }
        fn crc8(d: &[u8]) -> u8 {
            let mut c = 0u8;
            for &b in d {
                c ^= b;
                for _ in 0..8 {
                    c = if c & 0x80 != 0 { (c << 1) ^ 0x07 } else { c << 1 };
                }
            }
            c
        }
        fn crc16(d: &[u8]) -> u16 {
            let mut c = 0u16;
            for &b in d {
                c ^= (b as u16) << 8;
                for _ in 0..8 {
                    c = if c & 0x8000 != 0 {
                        (c << 1) ^ 0x8005
                    } else {
                        c << 1
                    };
                }
            }
            c
        }
        let nch = channels.len();
        let total = channels[0].len();
        let block = 1024usize;
        let mut b = Bits {
            out: b"fLaC".to_vec(),
            acc: 0,
            n: 0,
        };
        b.put(1, 1); // last metadata block
        b.put(0, 7); // STREAMINFO
        b.put(34, 24);
        b.put(block as u64, 16);
        b.put(block as u64, 16);
        b.put(0, 24);
        b.put(0, 24);
        b.put(sample_rate as u64, 20);
        b.put(nch as u64 - 1, 3);
        b.put(bps as u64 - 1, 5);
        b.put(total as u64, 36);
        b.put(0, 64);
        b.put(0, 64);
        for (fi, start) in (0..total).step_by(block).enumerate() {
            assert!(fi < 128);
            let len = block.min(total - start);
            let frame_start = b.out.len();
            b.put(0b11_1111_1111_1110, 14);
            b.put(0, 1);
            b.put(0, 1); // fixed block size
            b.put(0b0111, 4); // 16-bit block size - 1 at end of header
            b.put(0b0000, 4); // sample rate from STREAMINFO
            b.put(nch as u64 - 1, 4); // independent channels
            b.put(if bps == 16 { 0b100 } else { 0b110 }, 3);
            b.put(0, 1);
            b.put(fi as u64, 8); // UTF-8 frame number (< 128)
            b.put(len as u64 - 1, 16);
            let c8 = crc8(&b.out[frame_start..]);
            b.put(c8 as u64, 8);
            for ch in channels {
                b.put(0, 1);
                b.put(0b000001, 6); // VERBATIM
                b.put(0, 1);
                for &s in &ch[start..start + len] {
                    b.put((s as i64 as u64) & ((1u64 << bps) - 1), bps);
                }
            }
            b.align();
            let c16 = crc16(&b.out[frame_start..]);
            b.put(c16 as u64, 16);
        }
        b.out
    }

    #[test]
    fn reads_int16_raw_values() {
        let d = temp_dir("i16");
        let p = d.join("a.wav");
        let frames: Vec<Vec<i32>> = (0..100).map(|i| vec![1000, -i, 32767, -32768]).collect();
        write_int_wav(&p, 16, &frames);
        let a = read_audio(&p).unwrap();
        assert_eq!(a.sample_rate_hz, 16000);
        assert_eq!((a.num_channels(), a.num_samples()), (4, 100));
        assert_eq!(a.channels[0][5], 1000.0);
        assert_eq!(a.channels[1][7], -7.0);
        assert_eq!(a.channels[2][0], 32767.0);
        assert_eq!(a.channels[3][99], -32768.0);
        assert!((a.duration_s() - 100.0 / 16000.0).abs() < 1e-12);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn reads_int24_and_int32_raw_values() {
        let d = temp_dir("i24");
        let p = d.join("a.wav");
        write_int_wav(&p, 24, &[vec![8_388_607, -8_388_608], vec![1000, -1]]);
        let a = read_audio(&p).unwrap();
        assert_eq!(
            a.channels,
            vec![vec![8_388_607.0, 1000.0], vec![-8_388_608.0, -1.0]]
        );
        let p = d.join("b.wav");
        write_int_wav(&p, 32, &[vec![1 << 30, 123], vec![-7, 0]]);
        let a = read_audio(&p).unwrap();
        assert_eq!(
            a.channels,
            vec![vec![(1u32 << 30) as f32, -7.0], vec![123.0, 0.0]]
        );
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn reads_float32_as_is_any_channel_count() {
        let d = temp_dir("f32");
        let p = d.join("a.wav");
        let frames: Vec<Vec<f32>> = (0..10)
            .map(|i| (0..9).map(|c| i as f32 * 0.25 - c as f32).collect())
            .collect();
        write_float_wav(&p, &frames);
        let a = read_audio(&p).unwrap();
        assert_eq!(a.sample_rate_hz, 48000);
        assert_eq!((a.num_channels(), a.num_samples()), (9, 10));
        assert_eq!(a.channels[8][3], 0.75 - 8.0);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn reads_flac_16_and_24() {
        let d = temp_dir("flac");
        let ch16: Vec<Vec<i32>> = vec![
            (0..2500).map(|i| (i * 13 % 65536) - 32768).collect(),
            (0..2500).map(|i| -(i % 1000)).collect(),
            (0..2500).map(|_| 1000).collect(),
        ];
        let p = d.join("a.flac");
        std::fs::write(&p, encode_flac(16000, 16, &ch16)).unwrap();
        let a = read_audio(&p).unwrap();
        assert_eq!(
            (a.sample_rate_hz, a.num_channels(), a.num_samples()),
            (16000, 3, 2500)
        );
        let want: Vec<Vec<f32>> = ch16
            .iter()
            .map(|c| c.iter().map(|&s| s as f32).collect())
            .collect();
        assert_eq!(a.channels, want);
        let ch24: Vec<Vec<i32>> = vec![vec![8_388_607, -8_388_608, 1000, -1]];
        // A name without the extension: detection is by magic bytes.
        let p = d.join("noext");
        std::fs::write(&p, encode_flac(44100, 24, &ch24)).unwrap();
        let a = read_audio(&p).unwrap();
        assert_eq!(a.sample_rate_hz, 44100);
        assert_eq!(a.channels, vec![vec![8_388_607.0, -8_388_608.0, 1000.0, -1.0]]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn errors_name_the_file() {
        let d = temp_dir("err");
        // Unreadable path.
        let e = read_audio(d.join("missing.wav")).unwrap_err();
        assert!(
            matches!(e, Error::Io { .. }) && e.to_string().contains("missing.wav"),
            "{e}"
        );
        // Empty file.
        let p = d.join("empty.wav");
        std::fs::write(&p, b"").unwrap();
        let e = read_audio(&p).unwrap_err().to_string();
        assert!(e.contains("empty.wav") && e.contains("empty file"), "{e}");
        // Not a WAV/FLAC.
        let p = d.join("text.wav");
        std::fs::write(&p, b"hello, this is not audio").unwrap();
        let e = read_audio(&p).unwrap_err().to_string();
        assert!(e.contains("text.wav") && e.contains("not a WAV"), "{e}");
        // Zero frames.
        let p = d.join("zero.wav");
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: 16000,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        hound::WavWriter::create(&p, spec).unwrap().finalize().unwrap();
        let e = read_audio(&p).unwrap_err().to_string();
        assert!(e.contains("zero.wav") && e.contains("no audio frames"), "{e}");
        // NaN / infinite samples.
        let p = d.join("nan.wav");
        let mut frames = vec![vec![0.0f32; 3]; 2000];
        frames[1234][2] = f32::NAN;
        write_float_wav(&p, &frames);
        let e = read_audio(&p).unwrap_err().to_string();
        assert!(
            e.contains("nan.wav") && e.contains("sample 1234 of channel 2 is NaN"),
            "{e}"
        );
        let p = d.join("inf.wav");
        frames[1234][2] = 0.0;
        frames[7][0] = f32::NEG_INFINITY;
        write_float_wav(&p, &frames);
        let e = read_audio(&p).unwrap_err().to_string();
        assert!(e.contains("sample 7 of channel 0 is infinite"), "{e}");
        // Unsupported bit depth.
        let p = d.join("u8.wav");
        write_int_wav(&p, 8, &[vec![1, 2]]);
        let e = read_audio(&p).unwrap_err().to_string();
        assert!(
            e.contains("u8.wav") && e.contains("unsupported bit depth: 8-bit"),
            "{e}"
        );
        // Truncated data.
        let p = d.join("trunc.wav");
        write_int_wav(&p, 16, &vec![vec![5, 6]; 100]);
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 101]).unwrap();
        match read_audio(&p) {
            Ok(a) => assert!(a.num_samples() < 100),
            Err(e) => assert!(e.to_string().contains("trunc.wav"), "{e}"),
        }
        // Corrupt FLAC.
        let p = d.join("bad.flac");
        let mut f = encode_flac(16000, 16, &[vec![1; 100]]);
        let n = f.len();
        f[n - 10] ^= 0xff;
        std::fs::write(&p, f).unwrap();
        let e = read_audio(&p).unwrap_err().to_string();
        assert!(e.contains("bad.flac"), "{e}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn select_and_slice() {
        let a = Audio::new(
            10,
            vec![(0..20).map(|i| i as f32).collect(), vec![-1.0; 20], vec![2.0; 20]],
        )
        .unwrap();
        let s = a.select_channels(&[2, 0]).unwrap();
        assert_eq!(s.num_channels(), 2);
        assert_eq!(s.channels[0][0], 2.0);
        assert_eq!(s.channels[1][3], 3.0);
        let e = a.select_channels(&[0, 3]).unwrap_err().to_string();
        assert!(e.contains("channel 3") && e.contains("3 channels"), "{e}");
        assert!(a.select_channels(&[]).is_err());
        let t = a.slice_seconds(0.5, 1.2).unwrap();
        assert_eq!(t.num_samples(), 7);
        assert_eq!(t.channels[0][0], 5.0);
        assert!(a.slice_seconds(0.0, 2.0).is_ok());
        assert!(a.slice_seconds(1.0, 2.5).is_err());
        assert!(a.slice_seconds(1.0, 1.0).is_err());
        assert!(a.slice_seconds(-0.1, 1.0).is_err());
        assert!(a.slice_seconds(f64::NAN, 1.0).is_err());
        assert!(Audio::new(10, vec![vec![0.0; 3], vec![0.0; 2]]).is_err());
    }

    #[test]
    fn write_wav_round_trips() {
        let d = temp_dir("write");
        let a = Audio::new(
            16000,
            vec![
                vec![1000.0, -1000.4, 40000.0, -0.6],
                vec![0.5, 1.5, -2.5, 32767.0],
            ],
        )
        .unwrap();
        let p = d.join("i16.wav");
        a.write_wav(&p, SampleFormat::Int16).unwrap();
        let b = read_audio(&p).unwrap();
        assert_eq!(b.channels[0], vec![1000.0, -1000.0, 32767.0, -1.0]);
        assert_eq!(b.channels[1], vec![1.0, 2.0, -3.0, 32767.0]);
        let p = d.join("f32.wav");
        a.write_wav(&p, SampleFormat::Float32).unwrap();
        assert_eq!(read_audio(&p).unwrap(), a);
        // Only the target file is left behind.
        let names: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2);
        std::fs::remove_dir_all(&d).unwrap();
    }
}
