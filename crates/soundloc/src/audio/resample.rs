//! Sample-rate conversion of interleaved multichannel audio, for recordings and live
//! devices at another rate than the transfer functions (a 48 kHz sound card, a 16 kHz
//! HARK TF): `soundloc localize --resample`, `soundloc listen --resample`.
//!
//! Band-limited FFT resampling (rubato's synchronous [`rubato::Fft`]: the spectrum of each
//! chunk extended or truncated and multiplied by a Blackman–Harris anti-aliasing filter).
//! The converter's own delay is removed, so output sample n lies at time n / rate_out of
//! the input's clock, and a stream of n input frames gives exactly ⌈n · out / in⌉ output
//! frames. The input is cut into fixed chunks internally, so the output does not depend on
//! how the input was split into blocks (a file read whole, piped in, or captured live gives
//! the same samples, bit for bit).

use super::Audio;
use crate::{Error, Result};
use rubato::audioadapter_buffers::direct::InterleavedSlice;
use rubato::{Fft, FixedSync, Indexing, Resampler as _};

/// Input frames per chunk the converter aims for (rubato rounds to its FFT size).
const CHUNK_IN: usize = 1024;
/// The largest upsampling ratio accepted (a 1 kHz recording has nothing to localize at
/// 16 kHz; the limit keeps a hostile header from asking for gigabytes).
const MAX_UPSAMPLING: u64 = 16;
/// Frames per FFT block, and samples (input and output chunk, all channels), one
/// conversion step may hold: rates with a small common factor (44 101 Hz to 16 000 Hz)
/// need long blocks, and the converter keeps several buffers of each size.
const MAX_FFT_FRAMES: usize = 1 << 18;
const MAX_CHUNK_SAMPLES: usize = 1 << 24;

/// A streaming sample-rate converter (see the [module docs](self)).
pub struct Resampler {
    fft: Fft<f32>,
    channels: usize,
    rate_in: u32,
    rate_out: u32,
    /// Interleaved input not yet converted (fewer than one chunk's frames).
    pending: Vec<f32>,
    /// One chunk's interleaved output (scratch).
    chunk: Vec<f32>,
    /// Output frames still to drop (the converter's delay).
    delay_left: usize,
    /// Input frames so far, gaps included (the input's clock).
    frames_in: u64,
    /// Output frames so far, emitted or skipped for gaps (the output's clock).
    frames_out: u64,
    finished: bool,
}

impl Resampler {
    /// A converter from `rate_in` to `rate_out` Hz for `channels` channels.
    pub fn new(rate_in: u32, rate_out: u32, channels: usize) -> Result<Self> {
        if rate_in == 0 || rate_out == 0 || channels == 0 {
            return Err(Error::Config(format!(
                "resampling {rate_in} Hz to {rate_out} Hz with {channels} channels: rates and channels must be positive"
            )));
        }
        // A chunk of an even number of the smallest whole periods (rate_in / gcd input
        // frames): the FFT sizes are then even, and the delay (half of each) a whole number
        // of samples on both sides — with odd sizes the output would lag half an input
        // sample.
        if rate_out as u64 > MAX_UPSAMPLING * rate_in as u64 {
            return Err(Error::Config(format!(
                "resampling {rate_in} Hz to {rate_out} Hz: more than {MAX_UPSAMPLING}x upsampling (the input holds nothing above {} Hz to localize)",
                rate_in / 2
            )));
        }
        let g = gcd(rate_in, rate_out);
        let min_in = (rate_in / g) as usize;
        let periods = CHUNK_IN.div_ceil(min_in).next_multiple_of(2);
        let fft_in = periods * min_in;
        let fft_out = periods * (rate_out / g) as usize;
        if fft_in.max(fft_out) > MAX_FFT_FRAMES || (fft_in + fft_out) * channels > MAX_CHUNK_SAMPLES {
            return Err(Error::Config(format!(
                "resampling {rate_in} Hz to {rate_out} Hz with {channels} channels: the rates have {g} Hz as greatest common factor, which needs blocks of {fft_in} input frames (at most {MAX_FFT_FRAMES} frames per block and {MAX_CHUNK_SAMPLES} samples over all channels are allowed)"
            )));
        }
        let fft = Fft::<f32>::new(
            rate_in as usize,
            rate_out as usize,
            periods * min_in,
            channels,
            FixedSync::Both,
        )
        .map_err(|e| Error::Config(format!("resampling {rate_in} Hz to {rate_out} Hz: {e}")))?;
        let delay_left = fft.output_delay();
        let chunk = vec![0.0; fft.output_frames_max() * channels];
        Ok(Resampler {
            fft,
            channels,
            rate_in,
            rate_out,
            pending: Vec::new(),
            chunk,
            delay_left,
            frames_in: 0,
            frames_out: 0,
            finished: false,
        })
    }

    /// Input rate, Hz.
    pub fn rate_in(&self) -> u32 {
        self.rate_in
    }

    /// Output rate, Hz.
    pub fn rate_out(&self) -> u32 {
        self.rate_out
    }

    /// Output frames for `frames` input frames: ⌈frames · out / in⌉.
    pub fn output_frames(&self, frames: u64) -> u64 {
        ((frames as u128 * self.rate_out as u128).div_ceil(self.rate_in as u128)) as u64
    }

    /// Convert an interleaved block (any number of whole frames), appending the output
    /// frames that are ready to `out` (interleaved).
    pub fn process(&mut self, data: &[f32], out: &mut Vec<f32>) -> Result<()> {
        if self.finished {
            return Err(Error::State("resampler: input after the end".into()));
        }
        if !data.len().is_multiple_of(self.channels) {
            return Err(Error::Mismatch(format!(
                "resampler: {} samples are not a whole number of {}-channel frames",
                data.len(),
                self.channels
            )));
        }
        self.frames_in += (data.len() / self.channels) as u64;
        let need = self.fft.input_frames_next() * self.channels;
        let mut data = data;
        // Top up a partial chunk first; then whole chunks straight from `data`.
        if !self.pending.is_empty() {
            let take = (need - self.pending.len()).min(data.len());
            self.pending.extend_from_slice(&data[..take]);
            data = &data[take..];
            if self.pending.len() < need {
                return Ok(());
            }
            let chunk = std::mem::take(&mut self.pending);
            self.convert(&chunk, None, out)?;
            self.pending = chunk;
            self.pending.clear();
        }
        let mut chunks = data.chunks_exact(need);
        for c in &mut chunks {
            self.convert(c, None, out)?;
        }
        self.pending.extend_from_slice(chunks.remainder());
        Ok(())
    }

    /// The input skipped `frames` frames (live input that fell behind): the stretch before
    /// the gap is finished (its last samples appended to `out`), the converter restarts,
    /// and the number of output frames to skip is returned — so that the next stretch
    /// starts at output frame ⌈(input frames so far, gaps included) · out / in⌉ and result
    /// times stay true (within one output sample, never accumulating over gaps).
    pub fn gap(&mut self, frames: u64, out: &mut Vec<f32>) -> Result<u64> {
        if self.finished {
            return Err(Error::State("resampler: input after the end".into()));
        }
        self.end_stretch(out)?;
        self.frames_in += frames;
        let skip = self.output_frames(self.frames_in) - self.frames_out;
        self.frames_out += skip;
        self.fft.reset();
        self.delay_left = self.fft.output_delay();
        Ok(skip)
    }

    /// The input ended: append the remaining output (the converter's delay drained), so
    /// that the stream's output, gaps included, holds exactly [`Resampler::output_frames`]
    /// of its input.
    pub fn finish(&mut self, out: &mut Vec<f32>) -> Result<()> {
        if self.finished {
            return Ok(());
        }
        self.end_stretch(out)?;
        self.finished = true;
        Ok(())
    }

    /// Drain the current stretch up to output frame ⌈frames_in · out / in⌉.
    fn end_stretch(&mut self, out: &mut Vec<f32>) -> Result<()> {
        let total = self.output_frames(self.frames_in);
        let pending = std::mem::take(&mut self.pending);
        let mut partial = pending.len() / self.channels;
        let mut zeros = pending;
        zeros.resize(self.fft.input_frames_next() * self.channels, 0.0);
        while self.frames_out < total {
            self.convert(&zeros, Some(partial), out)?;
            if partial > 0 {
                zeros.iter_mut().for_each(|x| *x = 0.0);
                partial = 0;
            }
        }
        let extra = (self.frames_out - total) as usize * self.channels;
        out.truncate(out.len() - extra);
        self.frames_out = total;
        zeros.clear();
        self.pending = zeros;
        Ok(())
    }

    /// One chunk (`partial`: only its first frames are input, the rest silence).
    fn convert(&mut self, chunk: &[f32], partial: Option<usize>, out: &mut Vec<f32>) -> Result<()> {
        let ch = self.channels;
        let n_in = self.fft.input_frames_next();
        let n_out = self.fft.output_frames_next();
        let err = |e: &dyn std::fmt::Display| Error::Numerical {
            stage: "resample",
            message: e.to_string(),
        };
        let input = InterleavedSlice::new(chunk, ch, n_in).map_err(|e| err(&e))?;
        let mut output = InterleavedSlice::new_mut(&mut self.chunk, ch, n_out).map_err(|e| err(&e))?;
        let indexing = partial.map(|p| Indexing::new().partial_len(p));
        let (_, produced) = self
            .fft
            .process_into_buffer(&input, &mut output, indexing.as_ref())
            .map_err(|e| err(&e))?;
        let drop = self.delay_left.min(produced);
        self.delay_left -= drop;
        out.extend_from_slice(&self.chunk[drop * ch..produced * ch]);
        self.frames_out += (produced - drop) as u64;
        Ok(())
    }
}

fn gcd(mut a: u32, mut b: u32) -> u32 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// A whole recording at `rate_hz` (a copy of `audio` when it already is).
pub fn resample_audio(audio: &Audio, rate_hz: u32) -> Result<Audio> {
    if audio.sample_rate_hz == rate_hz {
        return Ok(audio.clone());
    }
    let ch = audio.num_channels();
    let n = audio.num_samples();
    let mut rs = Resampler::new(audio.sample_rate_hz, rate_hz, ch)?;
    let mut inter = Vec::with_capacity(n * ch);
    crate::input::Block::Planar(&audio.channels).append_interleaved(&mut inter)?;
    let mut out = Vec::new();
    rs.process(&inter, &mut out)?;
    rs.finish(&mut out)?;
    let frames = out.len() / ch.max(1);
    let channels = (0..ch)
        .map(|c| (0..frames).map(|i| out[i * ch + c]).collect())
        .collect();
    Ok(Audio {
        sample_rate_hz: rate_hz,
        channels,
    })
}
