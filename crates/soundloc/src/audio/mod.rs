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
//! frames, a non-finite sample in a file (`sample 1234 of channel 2 is NaN`, both 0-based; a
//! stream replaces it by 0 with a warning), an
//! unsupported bit depth.

pub mod flac_write;
pub mod health;
pub mod resample;
pub mod source;

pub use source::{
    open_source, open_stream, AudioFormat, AudioSource, FlacSource, RawEncoding, RawSource, WavSource,
};

use crate::{Error, Result};
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
        // One channel twice would make every correlation matrix singular.
        if let Some((c, first, again)) = crate::input::repeated(indices) {
            return Err(Error::Mismatch(format!(
                "channel {c} is selected twice (positions {first} and {again} of the selection)"
            )));
        }
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
    read_all(&mut *open_source(path)?, path)
}

/// Read a headerless file of interleaved PCM (`enc`, `channels` channels at
/// `sample_rate_hz`; what the CLI's `--raw` reads) into planar raw-valued channels. A size
/// that is not a whole number of sample frames, or a non-finite sample, is an error naming
/// the file.
pub fn read_raw_audio(
    path: impl AsRef<Path>,
    enc: RawEncoding,
    channels: usize,
    sample_rate_hz: u32,
) -> Result<Audio> {
    let path = path.as_ref();
    // Whatever the path is (a FIFO too): read whole, a NaN an error.
    read_all(
        &mut open_raw_file(path, enc, channels, sample_rate_hz)?.as_file(),
        path,
    )
}

/// A headerless PCM file opened for reading (the CLI's `--raw` on a path). A regular file
/// is read as a file ([`RawSource::as_file`]): a size that is not a whole number of sample
/// frames, or a non-finite sample, is an error naming it. A FIFO or device is read as a
/// stream.
pub fn open_raw_file(
    path: impl AsRef<Path>,
    enc: RawEncoding,
    channels: usize,
    sample_rate_hz: u32,
) -> Result<RawSource<std::io::BufReader<std::fs::File>>> {
    let path = path.as_ref();
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    let src = RawSource::new(
        std::io::BufReader::with_capacity(1 << 20, file),
        enc,
        channels,
        sample_rate_hz,
        path,
    )?;
    if !meta.is_file() {
        return Ok(src);
    }
    let (len, fb) = (meta.len(), (enc.bytes() * channels) as u64);
    if len % fb != 0 {
        return Err(Error::format(
            path,
            format!(
                "{len} bytes is not a whole number of sample frames of {channels} channels × {} bytes ({} frames and {} bytes): \
                 is the channel count or the encoding right?",
                enc.bytes(),
                len / fb,
                len % fb
            ),
        ));
    }
    Ok(src.as_file())
}

fn read_all(src: &mut dyn AudioSource, path: &Path) -> Result<Audio> {
    let fmt = src.format();
    let nch = fmt.channels;
    let mut channels: Vec<Vec<f32>> = vec![Vec::new(); nch];
    let mut buf = Vec::new();
    while src.read_interleaved(65536, &mut buf)? > 0 {
        for (i, v) in buf.iter().enumerate() {
            channels[i % nch].push(*v);
        }
    }
    if channels.first().map_or(0, Vec::len) == 0 {
        return Err(Error::format(path, "no audio frames (zero samples)"));
    }
    Ok(Audio {
        sample_rate_hz: fmt.sample_rate_hz,
        channels,
    })
}

#[cfg(test)]
pub(crate) mod tests;

#[cfg(test)]
mod raw_tests {
    use super::*;

    /// A raw file reads as the same samples as the WAV holding them; a size that is not a
    /// whole number of frames and a non-finite sample are errors naming the file.
    #[test]
    fn a_raw_file_reads_as_its_wav_and_bad_ones_are_named() {
        let d = tests::temp_dir("raw");
        let frames: Vec<[i16; 3]> = (0..500)
            .map(|i| [i as i16 * 7, -(i as i16), 32767 - i as i16])
            .collect();
        let (wav, raw) = (d.join("a.wav"), d.join("a.s16"));
        let spec = hound::WavSpec {
            channels: 3,
            sample_rate: 16000,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        let mut w = hound::WavWriter::create(&wav, spec).unwrap();
        frames.iter().flatten().for_each(|&s| w.write_sample(s).unwrap());
        w.finalize().unwrap();
        let bytes: Vec<u8> = frames.iter().flatten().flat_map(|s| s.to_le_bytes()).collect();
        std::fs::write(&raw, &bytes).unwrap();
        let enc: RawEncoding = "s16le".parse().unwrap();
        assert_eq!(
            read_raw_audio(&raw, enc, 3, 16000).unwrap(),
            read_audio(&wav).unwrap()
        );
        // Seven channels: 3000 bytes is 214 frames of 14 bytes and 4 over.
        let e = read_raw_audio(&raw, enc, 7, 16000).unwrap_err().to_string();
        assert!(
            e.contains("a.s16") && e.contains("(214 frames and 4 bytes)"),
            "{e}"
        );
        let f: Vec<u8> = [1.0f32, f32::NAN, 2.0, 3.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let nan = d.join("nan.f32");
        std::fs::write(&nan, f).unwrap();
        let e = read_raw_audio(&nan, RawEncoding::F32le, 2, 8000)
            .unwrap_err()
            .to_string();
        assert!(e.contains("nan.f32") && e.contains("NaN"), "{e}");
        let e = read_raw_audio(d.join("none.raw"), enc, 1, 8000)
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.raw"), "{e}");
        assert!("s16be"
            .parse::<RawEncoding>()
            .unwrap_err()
            .to_string()
            .contains("s16le"));
        std::fs::remove_dir_all(&d).unwrap();
    }
}
