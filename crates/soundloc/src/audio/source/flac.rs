//! FLAC (16- and 24-bit), decoded frame by frame with claxon.

use super::{check_finite, AudioFormat, AudioSource};
use crate::{Error, Result};
use std::io::{ErrorKind, Read};
use std::path::{Path, PathBuf};

/// A FLAC stream, decoded frame by frame.
pub struct FlacSource<R: Read> {
    reader: claxon::FlacReader<R>,
    info: claxon::metadata::StreamInfo,
    name: PathBuf,
    /// Decoded frames not yet delivered, interleaved.
    pending: Vec<f32>,
    at: usize,
    block: Vec<i32>,
    frames_read: u64,
    ended: bool,
    /// The truncation found at the end, returned once the frames before it are delivered.
    cut: Option<Error>,
}

impl<R: Read + Send> FlacSource<R> {
    /// Parse the metadata.
    pub fn new(r: R, name: &Path) -> Result<Self> {
        let reader = claxon::FlacReader::new(r).map_err(|e| flac_err(name, e))?;
        let info = reader.streaminfo();
        if !matches!(info.bits_per_sample, 16 | 24) {
            return Err(Error::format(
                name,
                format!(
                    "unsupported bit depth: {}-bit FLAC (supported: 8-, 16-, 24-, 32-bit integer and 32-, 64-bit float WAV; 16- and 24-bit FLAC)",
                    info.bits_per_sample
                ),
            ));
        }
        if info.sample_rate == 0 {
            return Err(Error::format(name, "FLAC stream declares a sample rate of 0 Hz"));
        }
        Ok(FlacSource {
            reader,
            info,
            name: name.to_path_buf(),
            pending: Vec::new(),
            at: 0,
            block: Vec::new(),
            frames_read: 0,
            ended: false,
            cut: None,
        })
    }
}

fn flac_err(name: &Path, e: claxon::Error) -> Error {
    match e {
        claxon::Error::IoError(io) if io.kind() == ErrorKind::UnexpectedEof => Error::truncated(
            name,
            "truncated FLAC file: it ends inside a frame (an interrupted copy or download)",
        ),
        claxon::Error::IoError(io) => Error::io(name, io),
        other => Error::format(name, format!("bad FLAC file: {other}")),
    }
}

impl<R: Read + Send> AudioSource for FlacSource<R> {
    fn format(&self) -> AudioFormat {
        AudioFormat {
            sample_rate_hz: self.info.sample_rate,
            channels: self.info.channels as usize,
            total_frames: self.info.samples,
        }
    }
    fn name(&self) -> &Path {
        &self.name
    }
    fn read_interleaved(&mut self, max_frames: usize, buf: &mut Vec<f32>) -> Result<usize> {
        buf.clear();
        let nch = self.info.channels as usize;
        while self.pending.len() - self.at < max_frames.max(1) * nch && !self.ended {
            let read = {
                let mut blocks = self.reader.blocks();
                blocks.read_next_or_eof(std::mem::take(&mut self.block))
            };
            let frame = match read {
                Ok(frame) => frame,
                Err(e) => {
                    self.ended = true;
                    self.cut = Some(flac_err(&self.name, e));
                    break;
                }
            };
            let Some(block) = frame else {
                self.ended = true;
                // STREAMINFO's total (0 = unknown, which claxon reports as None): a stream
                // that ends at a frame boundary before it was cut short, not a short file.
                let decoded = self.frames_read + ((self.pending.len() - self.at) / nch) as u64;
                if let Some(total) = self.info.samples.filter(|&t| t > decoded) {
                    self.cut = Some(Error::truncated(
                        &self.name,
                        format!(
                            "truncated FLAC file: its header declares {total} samples per channel, the frames hold {decoded}: the file was cut short (an interrupted copy or download)"
                        ),
                    ));
                }
                break;
            };
            if block.channels() as usize != nch {
                return Err(Error::format(
                    &self.name,
                    format!(
                        "FLAC frame has {} channels, stream header says {nch}",
                        block.channels()
                    ),
                ));
            }
            self.pending.drain(..self.at);
            self.at = 0;
            for i in 0..block.duration() {
                for c in 0..nch as u32 {
                    self.pending.push(block.sample(c, i) as f32);
                }
            }
            self.block = block.into_buffer();
        }
        let n = ((self.pending.len() - self.at) / nch).min(max_frames.max(1));
        // The frames before a cut first, then the error (as WAV).
        if n == 0 {
            if let Some(e) = self.cut.take() {
                return Err(e);
            }
        }
        buf.extend_from_slice(&self.pending[self.at..self.at + n * nch]);
        self.at += n * nch;
        check_finite(&self.name, buf, nch, self.frames_read, None)?;
        self.frames_read += n as u64;
        Ok(n)
    }
}
