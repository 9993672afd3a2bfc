//! Audio sources that deliver interleaved blocks as they arrive: WAV and FLAC from files
//! or pipes, and raw PCM (a sound card's or a network peer's bytes). A source never needs
//! to seek, so standard input and sockets work as well as files.
//!
//! **WAV**: RIFF chunks are walked in order; `fmt ` must precede `data`. RF64 and BW64
//! (WAV past 4 GiB) are read too: their `ds64` chunk gives the data's 64-bit size. PCM 8-bit
//! (unsigned; delivered as value − 128), 16/24/32-bit integer, and 32/64-bit IEEE float
//! (64-bit is what numpy's `scipy.io.wavfile.write` writes for float64 arrays), also as
//! WAVE_FORMAT_EXTENSIBLE. Samples keep their raw values (a 24-bit sample is not rescaled
//! to 16 bits). A `data` size of 0 or
//! ≥ 0x7FFF_F000 is a streaming placeholder (what `arecord` and other pipes write before
//! they know the length): the data then runs to the end of the input. Otherwise the data
//! ends at its declared size, and a file that ends earlier is an error ([`Error::Truncated`],
//! after the whole frames before the cut: a caller may keep those). An
//! incomplete trailing frame is dropped.
//!
//! **FLAC**: 16- and 24-bit, decoded frame by frame; a stream that ends before the total
//! its STREAMINFO declares is an error ("truncated"), as is one cut inside a frame.
//!
//! **Raw**: interleaved `u8`, little-endian `s16le`, `s24le`, `s32le`, `f32le` or
//! `f64le` frames; a trailing partial frame at the end of the input is dropped.
//!
//! Every block is checked for non-finite samples; the error names the source, the sample
//! (0-based, counted from the start) and the channel.

mod flac;
mod wav;
pub use flac::FlacSource;
pub use wav::WavSource;

use crate::{Error, Result};
use std::io::{BufReader, ErrorKind, Read};
use std::path::{Path, PathBuf};

/// What a source delivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AudioFormat {
    /// Sampling rate in Hz.
    pub sample_rate_hz: u32,
    /// Channels per frame.
    pub channels: usize,
    /// Frames in all, when the source knows it (a file's header).
    pub total_frames: Option<u64>,
}

/// A source of interleaved raw-valued samples (see the [module docs](self)).
pub trait AudioSource: Send {
    /// Rate, channels, length if known.
    fn format(&self) -> AudioFormat;
    /// The name used in messages (a path, `-` for stdin, `tcp:…`).
    fn name(&self) -> &Path;
    /// Read up to `max_frames` frames into `buf` (cleared first), interleaved; returns the
    /// number of frames, 0 at the end of the input. Blocks until at least one frame or the
    /// end has arrived.
    fn read_interleaved(&mut self, max_frames: usize, buf: &mut Vec<f32>) -> Result<usize>;
    /// Things the user should know about the input so far (e.g. it ended inside a frame);
    /// each note is returned once.
    fn take_notes(&mut self) -> Vec<String> {
        Vec::new()
    }
    /// Frames of real time that passed with no input at all before the block just read
    /// (a listening input between one sender and the next), counted once: the reader
    /// keeps later results at their true times. 0 for every source that never pauses.
    fn take_pause(&mut self) -> u64 {
        0
    }
}

/// Open a WAV or FLAC file, recognised by its first bytes.
pub fn open_source(path: &Path) -> Result<Box<dyn AudioSource>> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    open_reader(BufReader::new(file), path, true)
}

/// A WAV or FLAC stream from any reader (a file, stdin, a socket), recognised by its first
/// bytes; `name` is used in messages.
pub fn open_stream<R: Read + Send + 'static>(r: R, name: &Path) -> Result<Box<dyn AudioSource>> {
    open_reader(r, name, false)
}

fn open_reader<R: Read + Send + 'static>(
    mut r: R,
    name: &Path,
    greedy: bool,
) -> Result<Box<dyn AudioSource>> {
    let mut magic = [0u8; 4];
    let got = read_full(&mut r, &mut magic).map_err(|e| Error::io(name, e))?;
    if got == 0 {
        let what = if greedy {
            "empty file"
        } else {
            "no data: the input ended before its first byte"
        };
        return Err(Error::format(name, what));
    }
    let r = std::io::Cursor::new(magic[..got].to_vec()).chain(r);
    if got == 4 && matches!(&magic, b"RIFF" | b"RF64" | b"BW64") {
        Ok(Box::new(WavSource::new(r, name, greedy)?))
    } else if got == 4 && &magic == b"fLaC" {
        Ok(Box::new(FlacSource::new(r, name)?))
    } else {
        let shown: String = magic[..got]
            .iter()
            .map(|&b| if b.is_ascii_graphic() { b as char } else { '.' })
            .collect();
        Err(Error::format(
            name,
            format!(
                "not a WAV (RIFF/WAVE) or FLAC file (starts with \"{shown}\"); headerless PCM needs its encoding, channels and rate named (a localize input: --raw, --raw-channels, --rate)"
            ),
        ))
    }
}

/// The largest sample magnitude a stream (a pipe, a socket) delivers as it is; beyond it
/// a sample is a glitch, replaced by 0 like a non-finite one. It is what single-precision
/// correlations hold ([`crate::real::Real::MAX_SAMPLE`]), far beyond any converter's range.
pub const MAX_STREAM_SAMPLE: f32 = 1e14;

/// Read until `buf` is full or the end; returns the bytes read.
fn read_full<R: Read + ?Sized>(r: &mut R, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(k) => got += k,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// `raw`: the bytes `buf` was decoded from and their encoding, to tell a float64 sample
/// beyond f32's range (infinite once read) from an infinite one.
fn check_finite(
    name: &Path,
    buf: &[f32],
    channels: usize,
    first_frame: u64,
    raw: Option<(&[u8], RawEncoding)>,
) -> Result<()> {
    if let Some(i) = buf.iter().position(|v| !v.is_finite()) {
        let wide = match raw {
            Some((b, RawEncoding::F64le)) => b
                .get(i * 8..i * 8 + 8)
                .map(|b| f64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
                .filter(|v| v.is_finite()),
            _ => None,
        };
        let (what, tail) = match wide {
            Some(v) => (
                format!("{v:e}"),
                format!(
                    ", beyond the range of the 32-bit floats soundloc reads samples into (±{:e}); scale the recording down",
                    f32::MAX
                ),
            ),
            None if buf[i].is_nan() => ("NaN".to_string(), String::new()),
            None => ("infinite".to_string(), String::new()),
        };
        return Err(Error::format(
            name,
            format!(
                "sample {} of channel {} is {what} (0-based){tail}",
                first_frame + (i / channels) as u64,
                i % channels
            ),
        ));
    }
    Ok(())
}

/// Sample encodings of raw PCM and WAV data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RawEncoding {
    /// 8-bit unsigned (WAV's 8-bit PCM), delivered as value − 128.
    U8,
    /// 16-bit signed little-endian.
    S16le,
    /// 24-bit signed little-endian (3 bytes).
    S24le,
    /// 32-bit signed little-endian.
    S32le,
    /// 32-bit IEEE float little-endian.
    F32le,
    /// 64-bit IEEE float little-endian (converted to 32-bit float).
    F64le,
}

impl std::str::FromStr for RawEncoding {
    type Err = Error;
    /// `u8`, `s16le`, `s24le`, `s32le`, `f32le` or `f64le` (the CLI's `--raw` names).
    fn from_str(s: &str) -> Result<Self> {
        Ok(match s {
            "u8" => RawEncoding::U8,
            "s16le" => RawEncoding::S16le,
            "s24le" => RawEncoding::S24le,
            "s32le" => RawEncoding::S32le,
            "f32le" => RawEncoding::F32le,
            "f64le" => RawEncoding::F64le,
            _ => {
                return Err(Error::Config(format!(
                    "raw encoding {s:?}: expected u8, s16le, s24le, s32le, f32le or f64le"
                )))
            }
        })
    }
}

impl RawEncoding {
    /// Bytes per sample.
    pub fn bytes(self) -> usize {
        match self {
            RawEncoding::U8 => 1,
            RawEncoding::S16le => 2,
            RawEncoding::S24le => 3,
            RawEncoding::S32le | RawEncoding::F32le => 4,
            RawEncoding::F64le => 8,
        }
    }

    fn decode(self, b: &[u8]) -> f32 {
        match self {
            RawEncoding::U8 => b[0] as f32 - 128.0,
            RawEncoding::S16le => i16::from_le_bytes([b[0], b[1]]) as f32,
            RawEncoding::S24le => (i32::from_le_bytes([0, b[0], b[1], b[2]]) >> 8) as f32,
            RawEncoding::S32le => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
            RawEncoding::F32le => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            RawEncoding::F64le => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32,
        }
    }
}

/// Frames of PCM bytes from a reader, decoded in blocks (shared by WAV and raw).
struct PcmReader<R> {
    r: R,
    enc: RawEncoding,
    channels: usize,
    /// Bytes of data left (None = to the end of the input).
    left: Option<u64>,
    bytes: Vec<u8>,
    /// Bytes of a partial frame carried to the next read.
    carry: usize,
    frames_read: u64,
    ended: bool,
    /// Fill whole blocks (files) rather than return what has arrived (pipes, sockets).
    greedy: bool,
    notes: Vec<String>,
    /// The truncation found with whole frames still to deliver: returned by the next read,
    /// so a cut file yields the same frames, then the same error, whatever its block size.
    cut: Option<Error>,
    /// Non-finite samples of a stream (not greedy) replaced by 0 so far.
    non_finite: u64,
}

impl<R: Read> PcmReader<R> {
    fn read(
        &mut self,
        name: &Path,
        max_frames: usize,
        buf: &mut Vec<f32>,
        truncated_is_error: bool,
    ) -> Result<usize> {
        buf.clear();
        if let Some(e) = self.cut.take() {
            return Err(e);
        }
        let fb = self.enc.bytes() * self.channels;
        let target = max_frames.max(1) * fb;
        let limit = match self.left {
            Some(l) => target.min(self.carry + l.min(usize::MAX as u64 / 2) as usize),
            None => target,
        };
        self.bytes.resize(limit.max(self.carry), 0);
        let mut have = self.carry;
        // Until one whole frame is here (greedy: until `limit`), or the data ends.
        while (have < fb || self.greedy) && have < limit && !self.ended {
            match self.r.read(&mut self.bytes[have..limit]) {
                Ok(0) => self.ended = true,
                Ok(k) => {
                    have += k;
                    if let Some(l) = &mut self.left {
                        *l -= k as u64;
                    }
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(Error::io(name, e)),
            }
        }
        match self.left {
            Some(0) => self.ended = true,
            Some(l) if self.ended && truncated_is_error => {
                let e = Error::truncated(
                    name,
                    format!(
                        "truncated WAV file: {l} bytes ({} samples per channel) of the audio data \
                         its header declares are missing: the file was cut short (an interrupted \
                         copy or download)",
                        l / fb as u64
                    ),
                );
                if have < fb {
                    return Err(e);
                }
                self.cut = Some(e);
            }
            _ => {}
        }
        let frames = have / fb;
        let used = frames * fb;
        buf.reserve(frames * self.channels);
        for s in self.bytes[..used].chunks_exact(self.enc.bytes()) {
            buf.push(self.enc.decode(s));
        }
        if let Err(e) = check_finite(
            name,
            buf,
            self.channels,
            self.frames_read,
            Some((&self.bytes[..used], self.enc)),
        ) {
            // A file is refused (it can be fixed and read again); a live stream is not
            // ended for a glitch: its non-finite samples become 0, which keeps every later
            // result at its time.
            if self.greedy {
                return Err(e);
            }
            let bad = buf.iter().filter(|v| !v.is_finite()).count() as u64;
            buf.iter_mut().filter(|v| !v.is_finite()).for_each(|v| *v = 0.0);
            if self.non_finite == 0 {
                self.notes.push(format!(
                    "warning: {e}: this stream's non-finite samples are replaced by 0 (the windows \
                     holding them are less reliable); a count follows at its end"
                ));
            }
            self.non_finite += bad;
        }
        // A stream's finite samples beyond what any converter gives (s32 reaches 2.1e9) are
        // glitches too: an uninitialised buffer, or another encoding than --raw names.
        if !self.greedy {
            if let Some(i) = buf.iter().position(|v| v.abs() > MAX_STREAM_SAMPLE) {
                if self.non_finite == 0 {
                    self.notes.push(format!(
                        "warning: {}: sample {} of channel {} is {:e}, beyond ±{MAX_STREAM_SAMPLE:e} (is the \
                         encoding the sender's? --raw names it): this stream's samples beyond that and \
                         non-finite ones are replaced by 0 (the windows holding them are less reliable); a \
                         count follows at its end",
                        name.display(),
                        self.frames_read + (i / self.channels) as u64,
                        i % self.channels,
                        buf[i]
                    ));
                }
                let bad = buf.iter_mut().filter(|v| v.abs() > MAX_STREAM_SAMPLE);
                self.non_finite += bad.map(|v| *v = 0.0).count() as u64;
            }
        }
        self.bytes.copy_within(used..have, 0);
        self.carry = have - used;
        if self.ended && frames == 0 && self.carry > 0 {
            self.notes.push(format!(
                "{}: the input ended inside a sample frame (one sample of every channel): the last {} of {fb} bytes ignored",
                name.display(),
                self.carry
            ));
            self.carry = 0;
        }
        self.frames_read += frames as u64;
        if self.ended && frames == 0 && self.non_finite > 0 {
            self.notes.push(format!(
                "{}: {} non-finite or out-of-range samples were replaced by 0 in all",
                name.display(),
                self.non_finite
            ));
            self.non_finite = 0;
        }
        Ok(frames)
    }
}

/// Headerless interleaved PCM (see the [module docs](self)).
pub struct RawSource<R> {
    pcm: PcmReader<NoHeader<R>>,
    rate: u32,
    name: PathBuf,
}

/// A reader that refuses a stream starting with a container's header ([`container`]).
/// The first 12 bytes are checked at the first read, not when the source is made: a live
/// stream's first bytes may come only after the caller has set everything else up.
struct NoHeader<R> {
    r: R,
    head: [u8; 12],
    /// Bytes of `head` read so far / handed on.
    got: usize,
    given: usize,
    checked: bool,
}

impl<R: Read> Read for NoHeader<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if !self.checked {
            self.got = read_full(&mut self.r, &mut self.head)?;
            self.checked = true;
            if let Some(what) = container(&self.head[..self.got]) {
                return Err(std::io::Error::new(
                    ErrorKind::InvalidData,
                    format!(
                        "the input starts with {what}, but raw input is headerless PCM: drop --raw, \
                         --raw-channels and --rate (the header gives them)"
                    ),
                ));
            }
        }
        if self.given < self.got {
            let n = buf.len().min(self.got - self.given);
            buf[..n].copy_from_slice(&self.head[self.given..self.given + n]);
            self.given += n;
            return Ok(n);
        }
        self.r.read(buf)
    }
}

/// What a stream's first bytes say it is, when they are a WAV (RIFF, RF64, BW64) or FLAC
/// header: read as raw PCM, a header would shift every sample (a WAV's 44 bytes are 22
/// samples of s16le: an 8-channel stream's channels rotate by 6) and give wrong
/// directions without a word.
fn container(head: &[u8]) -> Option<&'static str> {
    let riff =
        head.len() >= 12 && matches!(&head[..4], b"RIFF" | b"RF64" | b"BW64") && &head[8..12] == b"WAVE";
    if riff {
        Some("a WAV header (RIFF…WAVE)")
    } else if head.starts_with(b"fLaC") {
        Some("a FLAC header (fLaC)")
    } else {
        None
    }
}

impl<R: Read + Send> RawSource<R> {
    /// `channels` channels at `sample_rate_hz`, encoded as `enc`.
    pub fn new(r: R, enc: RawEncoding, channels: usize, sample_rate_hz: u32, name: &Path) -> Result<Self> {
        if channels == 0 || channels > 4096 {
            return Err(Error::Config(format!(
                "raw input: {channels} channels (need 1 to 4096)"
            )));
        }
        if sample_rate_hz == 0 {
            return Err(Error::Config(
                "raw input: the sample rate must be positive".into(),
            ));
        }
        Ok(RawSource {
            pcm: PcmReader {
                r: NoHeader {
                    r,
                    head: [0; 12],
                    got: 0,
                    given: 0,
                    checked: false,
                },
                enc,
                channels,
                left: None,
                bytes: Vec::new(),
                carry: 0,
                frames_read: 0,
                ended: false,
                greedy: false,
                notes: Vec::new(),
                cut: None,
                non_finite: 0,
            },
            rate: sample_rate_hz,
            name: name.to_path_buf(),
        })
    }
}

impl<R: Read + Send> RawSource<R> {
    /// Read as a file, not a stream: whole blocks, and a non-finite sample is an error
    /// naming it (a stream's become 0 with a warning, so that a glitch does not end it).
    pub fn as_file(mut self) -> Self {
        self.pcm.greedy = true;
        self
    }
}

impl<R: Read + Send> AudioSource for RawSource<R> {
    fn format(&self) -> AudioFormat {
        AudioFormat {
            sample_rate_hz: self.rate,
            channels: self.pcm.channels,
            total_frames: None,
        }
    }
    fn name(&self) -> &Path {
        &self.name
    }
    fn read_interleaved(&mut self, max_frames: usize, buf: &mut Vec<f32>) -> Result<usize> {
        self.pcm.read(&self.name, max_frames, buf, false)
    }
    fn take_notes(&mut self) -> Vec<String> {
        std::mem::take(&mut self.pcm.notes)
    }
}
