//! Stage 1 — STFT (HARK MultiFFT): samples → [`Spectra`] `[frame][bin][mic]`.
//!
//! Frame f covers samples [f·hop, f·hop + N); it is multiplied by the analysis window and
//! transformed with a real FFT, X_k = Σ_n w_n x_n e^{−j2πkn/N}, **unscaled**. Only the used
//! bins are kept. The number of frames is ⌊(L − N)/hop⌋ + 1 for L ≥ N samples.
//!
//! Windows (n = 0..N): CONJ (HARK's default; a square-root window whose squares overlap
//! to one), HAMMING 0.54 − 0.46·cos(2πn/(N−1)), HANNING 0.5 − 0.5·cos(2πn/(N−1)),
//! RECTANGLE 1.

use crate::backend::Spectra;
use crate::config::WindowFunction;
use crate::real::{Real, C};
use crate::{Error, Result};
use rayon::prelude::*;
use realfft::{RealFftPlanner, RealToComplex};
use std::ops::Range;
use std::sync::Arc;

/// The analysis window of length `n`.
///
/// CONJ, for i in 0..n: x = 4i/n folded into [0, 1] (x ∈ [1,2) → 2−x, flipped;
/// [2,3) → x−2, flipped; [3,4) → 4−x), x ← 1.9979·x, w = (0.5 − 0.5·cos x)², w ← 1 − w
/// if flipped, w ← √w.
pub fn window_function<T: Real>(kind: WindowFunction, n: usize) -> Vec<T> {
    let nn = n as f64;
    let denom = (n.max(2) - 1) as f64;
    (0..n)
        .map(|i| {
            let w = match kind {
                WindowFunction::Conj => {
                    let x = 4.0 * i as f64 / nn;
                    let (x, flipped) = if x < 1.0 {
                        (x, false)
                    } else if x < 2.0 {
                        (2.0 - x, true)
                    } else if x < 3.0 {
                        (x - 2.0, true)
                    } else {
                        (4.0 - x, false)
                    };
                    let x = 1.9979 * x;
                    let mut w = (0.5 - 0.5 * x.cos()).powi(2);
                    if flipped {
                        w = 1.0 - w;
                    }
                    w.sqrt()
                }
                WindowFunction::Hamming => {
                    0.54 - 0.46 * (2.0 * std::f64::consts::PI * i as f64 / denom).cos()
                }
                WindowFunction::Hanning => 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / denom).cos(),
                WindowFunction::Rectangle => 1.0,
            };
            T::of_f64(w)
        })
        .collect()
}

/// Largest FFT length N accepted (HARK uses 512; 65 536 is 4 s at 16 kHz).
pub const MAX_NFFT: usize = 1 << 16;

/// Fewer transforms than this in one call run on the calling thread (a few µs each at the
/// usual sizes: less than a hand-off to the thread pool costs).
const SERIAL_MAX_TRANSFORMS: usize = 16;

/// A prepared STFT: FFT plan, window and used bins.
pub struct Stft<T: Real> {
    nfft: usize,
    hop: usize,
    bins: Range<usize>,
    window: Vec<T>,
    fft: Arc<dyn RealToComplex<T>>,
}

impl<T: Real> Stft<T> {
    /// Prepare an N-point STFT with the given hop, window and kept bins.
    pub fn new(nfft: usize, hop: usize, window: WindowFunction, bins: Range<usize>) -> Result<Self> {
        if nfft > MAX_NFFT {
            return Err(Error::Config(format!(
                "STFT: N = {nfft} exceeds the largest supported FFT length, {MAX_NFFT}"
            )));
        }
        if nfft < 2 || hop == 0 || bins.is_empty() || bins.end > nfft / 2 + 1 {
            return Err(Error::Config(format!(
                "STFT: invalid N = {nfft}, hop = {hop}, bins {}..{}",
                bins.start, bins.end
            )));
        }
        let fft = RealFftPlanner::<T>::new().plan_fft_forward(nfft);
        Ok(Stft {
            nfft,
            hop,
            bins,
            window: window_function(window, nfft),
            fft,
        })
    }

    /// Number of complete frames in `num_samples` samples.
    pub fn num_frames(&self, num_samples: usize) -> usize {
        if num_samples < self.nfft {
            0
        } else {
            (num_samples - self.nfft) / self.hop + 1
        }
    }

    /// Transform every complete frame of `channels` (planar, equal lengths).
    pub fn process(&self, channels: &[Vec<f32>]) -> Result<Spectra<T>> {
        let len = channels.first().map_or(0, |c| c.len());
        self.process_frames(channels, 0..self.num_frames(len))
    }

    /// Transform frames `frames` only (frame f of the result is STFT frame
    /// `frames.start + f`): bounded memory on long recordings.
    pub fn process_frames(&self, channels: &[Vec<f32>], frames: Range<usize>) -> Result<Spectra<T>> {
        let m = channels.len();
        let len = channels.first().map_or(0, |c| c.len());
        if m == 0 || channels.iter().any(|c| c.len() != len) {
            return Err(Error::Mismatch(
                "STFT: channels must be non-empty and of equal length".into(),
            ));
        }
        if frames.end > self.num_frames(len) {
            return Err(Error::Mismatch(format!(
                "STFT: frames {}..{} asked, the signal has {}",
                frames.start,
                frames.end,
                self.num_frames(len)
            )));
        }
        let mut out = Spectra::zeros(frames.len(), self.bins.len(), m);
        self.transform(channels, frames.start * self.hop, &mut out.data);
        Ok(out)
    }

    /// Transform consecutive frames into `dst` (`[frame][bin][mic]`, as many frames as it
    /// holds): frame f starts at sample `first_sample + f·hop` of every channel, which must
    /// hold the frame's N samples. Frames are independent, so the values do not depend on
    /// how a signal is cut into calls.
    fn transform(&self, channels: &[Vec<f32>], first_sample: usize, dst: &mut [C<T>]) {
        let m = channels.len();
        let nb = self.bins.len();
        let frame_len = nb * m;
        let frames = dst.len() / frame_len.max(1);
        if frames * m < SERIAL_MAX_TRANSFORMS {
            // A few transforms (a small array's push): a hand-off to the thread pool would
            // cost more than they do.
            let (mut inp, mut spec, mut scratch) = (
                self.fft.make_input_vec(),
                self.fft.make_output_vec(),
                self.fft.make_scratch_vec(),
            );
            for (f, dst) in dst.chunks_mut(frame_len.max(1)).enumerate() {
                self.frame_into(
                    channels,
                    first_sample + f * self.hop,
                    (&mut inp, &mut spec, &mut scratch),
                    dst,
                );
            }
            return;
        }
        if frames < 2 * rayon::current_num_threads() && m >= 8 {
            // Few frames (a live stream's push): spread the channels over the cores
            // instead, through a [frame][mic][bin] buffer.
            let mut tmp = vec![C::new(T::zero(), T::zero()); dst.len()];
            tmp.par_chunks_mut(nb.max(1))
                .with_min_len(4)
                .enumerate()
                .for_each_init(
                    || {
                        (
                            self.fft.make_input_vec(),
                            self.fft.make_output_vec(),
                            self.fft.make_scratch_vec(),
                        )
                    },
                    |(inp, spec, scratch), (i, out)| {
                        let (f, mic) = (i / m, i % m);
                        let off = first_sample + f * self.hop;
                        for (j, v) in inp.iter_mut().enumerate() {
                            *v = T::of_f64(channels[mic][off + j] as f64) * self.window[j];
                        }
                        let _ = self.fft.process_with_scratch(inp, spec, scratch);
                        out.copy_from_slice(&spec[self.bins.clone()]);
                    },
                );
            for f in 0..frames {
                for mic in 0..m {
                    let src = &tmp[(f * m + mic) * nb..(f * m + mic + 1) * nb];
                    for (b, v) in src.iter().enumerate() {
                        dst[f * frame_len + b * m + mic] = *v;
                    }
                }
            }
            return;
        }
        dst.par_chunks_mut(frame_len.max(1)).enumerate().for_each_init(
            || {
                (
                    self.fft.make_input_vec(),
                    self.fft.make_output_vec(),
                    self.fft.make_scratch_vec(),
                )
            },
            |(inp, spec, scratch), (f, dst)| {
                self.frame_into(channels, first_sample + f * self.hop, (inp, spec, scratch), dst);
            },
        );
    }

    /// One frame starting at sample `off` of every channel into `dst` (`[bin][mic]`).
    fn frame_into(
        &self,
        channels: &[Vec<f32>],
        off: usize,
        (inp, spec, scratch): (&mut [T], &mut [C<T>], &mut [C<T>]),
        dst: &mut [C<T>],
    ) {
        let m = channels.len();
        for (mic, ch) in channels.iter().enumerate() {
            for (i, v) in inp.iter_mut().enumerate() {
                *v = T::of_f64(ch[off + i] as f64) * self.window[i];
            }
            // Lengths come from this plan's own buffers: cannot fail.
            let _ = self.fft.process_with_scratch(inp, spec, scratch);
            for (b, k) in self.bins.clone().enumerate() {
                dst[b * m + mic] = spec[k];
            }
        }
    }

    /// FFT length N in samples.
    pub fn nfft(&self) -> usize {
        self.nfft
    }

    /// Frame advance in samples.
    pub fn hop(&self) -> usize {
        self.hop
    }

    /// The kept bins.
    pub fn bins(&self) -> Range<usize> {
        self.bins.clone()
    }
}

/// The streaming STFT: a sample ring per channel in front of a [`Stft`]. Samples arrive
/// in blocks of any length; every frame whose N samples have arrived is transformed once,
/// into a [`FrameRing`], and samples no later frame needs are dropped. Frame f covers
/// samples [f·hop, f·hop + N) counted from the first sample pushed, so the frames equal
/// [`Stft::process`] of the whole signal bit for bit.
pub struct StftStream<T: Real> {
    stft: Stft<T>,
    /// Planar samples; `buf[c][0]` is absolute sample `buf_start`.
    buf: Vec<Vec<f32>>,
    buf_start: usize,
    /// Samples received per channel.
    received: usize,
    /// Next frame to transform.
    next_frame: usize,
}

impl<T: Real> StftStream<T> {
    /// A stream over `num_channels` channels.
    pub fn new(stft: Stft<T>, num_channels: usize) -> Self {
        StftStream {
            stft,
            buf: vec![Vec::new(); num_channels],
            buf_start: 0,
            received: 0,
            next_frame: 0,
        }
    }

    /// The STFT.
    pub fn stft(&self) -> &Stft<T> {
        &self.stft
    }

    /// Samples received per channel since the start (or the last reset).
    pub fn samples_received(&self) -> usize {
        self.received
    }

    /// Frames transformed so far.
    pub fn frames_done(&self) -> usize {
        self.next_frame
    }

    /// Append n samples to every channel: `fill` extends each channel's buffer by n.
    pub fn append(&mut self, n: usize, fill: impl FnOnce(&mut [Vec<f32>])) {
        let before = self.buf.first().map_or(0, Vec::len);
        fill(&mut self.buf);
        debug_assert!(self.buf.iter().all(|b| b.len() == before + n));
        self.received += n;
    }

    /// The buffered samples of every channel with the absolute index of the first, for
    /// stages that read samples (the noise estimate over a time range).
    pub fn buffered(&self) -> (usize, &[Vec<f32>]) {
        (self.buf_start, &self.buf)
    }

    /// Transform every complete frame into `ring`, then drop the samples no later frame
    /// needs except those at or after `keep_from` (an absolute sample index). Returns the
    /// number of new frames.
    pub fn frames_into(&mut self, ring: &mut FrameRing<T>, keep_from: usize) -> usize {
        let hop = self.stft.hop;
        let total = self.stft.num_frames(self.received);
        let new = total.saturating_sub(self.next_frame);
        if new > 0 {
            let dst = ring.grow(new);
            self.stft
                .transform(&self.buf, self.next_frame * hop - self.buf_start, dst);
            self.next_frame = total;
        }
        let drop_to = (self.next_frame * hop).min(keep_from).min(self.received);
        if drop_to > self.buf_start {
            let k = drop_to - self.buf_start;
            for b in &mut self.buf {
                b.drain(..k);
            }
            self.buf_start = drop_to;
        }
        new
    }

    /// Forget every sample and frame: the next sample pushed is sample 0 again.
    pub fn reset(&mut self) {
        for b in &mut self.buf {
            b.clear();
        }
        self.buf_start = 0;
        self.received = 0;
        self.next_frame = 0;
    }
}

/// The most recent STFT frames of a stream, `[frame][bin][mic]`: absolute frames
/// `first .. first + spectra.num_frames`. Frames are appended at the end and dropped
/// from the front once no window or noise estimate needs them.
#[derive(Debug, Clone)]
pub struct FrameRing<T: Real> {
    first: usize,
    spectra: Spectra<T>,
}

impl<T: Real> FrameRing<T> {
    /// An empty ring for frames of `num_bins` × `num_mics`.
    pub fn new(num_bins: usize, num_mics: usize) -> Self {
        FrameRing {
            first: 0,
            spectra: Spectra::zeros(0, num_bins, num_mics),
        }
    }

    /// Absolute index of the first frame held.
    pub fn first(&self) -> usize {
        self.first
    }

    /// One past the absolute index of the last frame held (= frames received).
    pub fn end(&self) -> usize {
        self.first + self.spectra.num_frames
    }

    /// The frames held (frame 0 of it is absolute frame [`first`](Self::first)).
    pub fn spectra(&self) -> &Spectra<T> {
        &self.spectra
    }

    /// The frames held, to change in place (the correlation's onset weighting).
    pub(crate) fn spectra_mut(&mut self) -> &mut Spectra<T> {
        &mut self.spectra
    }

    /// Append `n` zeroed frames and return them for filling.
    pub(crate) fn grow(&mut self, n: usize) -> &mut [C<T>] {
        let fl = self.spectra.num_bins * self.spectra.num_mics;
        let old = self.spectra.data.len();
        self.spectra.data.resize(old + n * fl, czero());
        self.spectra.num_frames += n;
        &mut self.spectra.data[old..]
    }

    /// Let go of the frames before absolute frame `frame`. They are removed once they
    /// are at least as many as those kept (and at least 64), so a stream that drops one
    /// frame per push moves each frame O(1) times instead of the whole ring every push;
    /// until then they stay readable and [`first`](Self::first) does not move.
    pub fn drop_before(&mut self, frame: usize) {
        let k = frame.min(self.end()).saturating_sub(self.first);
        if k > 0 && (k >= 64 || k == self.spectra.num_frames) && 2 * k >= self.spectra.num_frames {
            let fl = self.spectra.num_bins * self.spectra.num_mics;
            self.spectra.data.drain(..k * fl);
            self.spectra.num_frames -= k;
            self.first += k;
        }
    }

    /// Forget every frame; the next frame is frame 0.
    pub fn reset(&mut self) {
        self.spectra.data.clear();
        self.spectra.num_frames = 0;
        self.first = 0;
    }
}

/// Convenience: a complex zero.
pub fn czero<T: Real>() -> C<T> {
    C::new(T::zero(), T::zero())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conj_window_is_a_square_root_partition_of_unity() {
        // The CONJ window's squares at half-frame overlap sum to ~1 (it is HARK's
        // "conjugate" window); also symmetric-ish, 0 at the start, 1 at N/2.
        let n = 512;
        let w = window_function::<f64>(WindowFunction::Conj, n);
        assert!(w[0].abs() < 1e-12);
        assert!((w[n / 2] - 1.0).abs() < 1e-12);
        for i in 0..n / 2 {
            let s = w[i].powi(2) + w[i + n / 2].powi(2);
            assert!((s - 1.0).abs() < 2e-3, "i = {i}: {s}");
        }
    }

    fn check_tone<T: Real>() {
        // A cosine at bin 20 with amplitude 1000 under a rectangular window gives
        // |X_20| = 1000·N/2 (unscaled FFT) and phase 0 at frame 0.
        let n = 512;
        let k0 = 20;
        let len = 4000;
        let x: Vec<f32> = (0..len)
            .map(|i| (1000.0 * (2.0 * std::f64::consts::PI * k0 as f64 * i as f64 / n as f64).cos()) as f32)
            .collect();
        let stft = Stft::<T>::new(n, 160, WindowFunction::Rectangle, 16..89).unwrap();
        let s = stft.process(&[x.clone(), x]).unwrap();
        assert_eq!(s.num_frames, (len - n) / 160 + 1);
        let z = s.frame_bin(0, k0 - 16)[1];
        assert!((z.re.to_f64() - 256000.0).abs() < 256000.0 * 1e-5, "{z:?}");
        assert!(z.im.to_f64().abs() < 1.0);
        let other = s.frame_bin(0, 30 - 16)[0];
        assert!(other.norm().to_f64() < 1.0);
    }

    #[test]
    fn streamed_frames_equal_the_whole_signal_in_any_block_sizes() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let len = 9000;
        let x: Vec<Vec<f32>> = (0..3)
            .map(|_| (0..len).map(|_| rng.gen_range(-1000.0f32..1000.0)).collect())
            .collect();
        let mk = || Stft::<f32>::new(512, 160, WindowFunction::Conj, 16..89).unwrap();
        let whole = mk().process(&x).unwrap();
        let mut stream = StftStream::new(mk(), 3);
        let mut ring = FrameRing::new(73, 3);
        let mut got = Vec::new();
        let mut pos = 0;
        while pos < len {
            let n = rng.gen_range(1..700).min(len - pos);
            stream.append(n, |bufs| {
                for (c, b) in bufs.iter_mut().enumerate() {
                    b.extend_from_slice(&x[c][pos..pos + n]);
                }
            });
            pos += n;
            stream.frames_into(&mut ring, usize::MAX);
            // Keep only the newest frames: the ring drops from the front.
            got.extend_from_slice(&ring.spectra().data);
            ring.drop_before(ring.end());
        }
        assert_eq!(stream.frames_done(), whole.num_frames);
        assert!(got == whole.data, "streamed frames differ");
    }

    #[test]
    fn tone_lands_in_its_bin_unscaled_f32() {
        check_tone::<f32>();
    }
    #[test]
    fn tone_lands_in_its_bin_unscaled_f64() {
        check_tone::<f64>();
    }
}
