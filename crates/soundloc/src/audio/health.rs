//! Checks of a stream's channels as they arrive: dead, clipping and polarity-inverted
//! microphones. Each finding is a warning note, given once per stream, naming the input
//! channel (0-based, as in the file or device); the results are not changed.
//!
//! - **Constant / silent.** Every sample of a channel equal to its first (all channels:
//!   the input is silent or DC only).
//! - **Dead.** A channel whose RMS about its mean is more than [`DEAD_DB`] below the
//!   median channel's (an unplugged or broken microphone leaves sensor or cable noise).
//!   Near-field sources (rotors a few cm away) make level differences of 10–15 dB, not 30.
//! - **Nearly silent.** Integer samples (16/24/32-bit files and devices) whose median
//!   channel's RMS is below one quantisation step: the channels are mostly rounding, so a
//!   live microphone a little quieter than the others reads as constant or far below
//!   them. One note for the input instead of dead-microphone notes.
//! - **Clipping.** More than [`CLIP_FRACTION`] of a channel's samples at the format's full
//!   scale (±32767/32768 int16, ±8388607/8 int24, ±2³¹ int32, ±1.0 float): the flat tops
//!   make the correlations wrong.
//! - **Polarity.** For any sound field, two microphones d apart see every wave with a
//!   delay |τ| ≤ d/c, so at f the cross-spectrum's real part is positive when
//!   2πf·d/c < π/2 (each wave adds |S|²·g_i·g_j·cos 2πfτ > 0; uncorrelated noise adds 0).
//!   A channel whose lowest used bins are *anti*correlated with its close neighbours'
//!   (median ρ below −[`POLARITY_RHO`]) while the other close pairs correlate (median
//!   above +[`POLARITY_RHO`]) is wired or converted with its sign flipped: every MUSIC or
//!   SRP direction is then wrong. ρ_ij = Σ Re(X_i X_j*) / √(Σ|X_i|² Σ|X_j|²) over the STFT
//!   frames the engine makes anyway. The pairs and bins come from the steering vectors
//!   (measured TFs or free field): at the lowest used bin f₀ the largest phase between
//!   microphones i and j over all directions, φ_ij, bounds their delay,
//!   τ_ij = φ_ij / (2π f₀). With τ_c the median over microphones of their nearest pair's
//!   τ, the pairs with τ_ij ≤ 2τ_c and φ_ij ≤ π/3 are compared in the used bins up to
//!   1/(4 τ_max) (phases ≤ π/2; at most 16 bins), on the first [`DECIDE_SECONDS`] to
//!   [`BAND_SECONDS`] of frames.
//! - **Gains** (where the caller asks: [`ChannelHealth::with_gain_check`]). Channels whose
//!   power in the used bins (summed over the STFT frames) departs from the transfer
//!   functions' by [`gains::GAIN_DB`] or more ([`gains`]).

pub mod gains;

use crate::real::{Real, C};

/// A channel this far below the median channel's RMS (dB) is reported dead.
pub const DEAD_DB: f64 = 30.0;
/// A channel with more than this fraction of its samples at full scale is clipping.
pub const CLIP_FRACTION: f64 = 1e-3;
/// The polarity test's correlation threshold (see the module docs).
pub const POLARITY_RHO: f64 = 0.3;
/// Seconds of each stream the polarity test reads at most (the other checks read
/// everything); it stops after [`DECIDE_SECONDS`] once the close pairs without the
/// flagged microphones correlate above [`COHERENT_RHO`] (the field carried the band).
pub const BAND_SECONDS: f64 = 30.0;
/// See [`BAND_SECONDS`].
pub const DECIDE_SECONDS: f64 = 10.0;
/// See [`BAND_SECONDS`].
pub const COHERENT_RHO: f64 = 0.5;
/// Frames needed before the polarity test says anything (seconds).
const MIN_BAND_SECONDS: f64 = 1.0;
/// A push of at least this many samples (all channels) takes the levels in parallel.
const PAR_MIN_SAMPLES: usize = 1 << 15;
/// Bins the polarity test reads at most.
const MAX_TEST_BINS: usize = 16;
/// Non-zero samples per channel read to tell integer input (quantisation steps of 1)
/// from float.
const INTEGRAL_SAMPLES: u64 = 1 << 16;

/// What the polarity test compares ([`close_pairs`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ClosePairs {
    /// Microphone pairs (i < j).
    pub pairs: Vec<(usize, usize)>,
    /// The used bins read: `first .. first + bins` (indices among the used bins).
    pub first: usize,
    /// See `first`.
    pub bins: usize,
    /// Their frequencies, lowest and highest, Hz.
    pub band_hz: (f64, f64),
}

/// Running checks of one stream's channels (see the module docs).
#[derive(Debug, Clone)]
pub struct ChannelHealth {
    /// Input channel of each microphone, for the notes.
    inputs: Vec<usize>,
    levels: Vec<Level>,
    samples: u64,
    /// Samples before the checks speak ahead of the end ([`DECIDE_SECONDS`]).
    early: u64,
    coh: Option<Coherence>,
    /// Notes given: dead, clipping, polarity (per microphone), silent and nearly silent
    /// (the whole input).
    said: Vec<[bool; 3]>,
    said_silent: bool,
    said_quiet: bool,
    /// The gains check's expected relative powers per microphone (None: no check), and
    /// whether it has spoken.
    expected: Option<Vec<f64>>,
    said_gains: bool,
    /// With the gains check: Σ |X_m|² over the used bins of every frame, per microphone
    /// (the band the expected powers are taken over), and the frames summed.
    band_power: Vec<f64>,
    band_frames: usize,
}

/// One channel's running level, peak and constancy.
#[derive(Debug, Clone, Default)]
struct Level {
    /// The first sample, and whether a later one differed.
    first: Option<f32>,
    varies: bool,
    sum: f64,
    sum2: f64,
    /// Largest |x| (full-scale values folded to one, see `fold`) and how often it came.
    peak: f32,
    at_peak: u64,
    /// Whether a sample with a fractional part came among the first [`INTEGRAL_SAMPLES`]
    /// non-zero ones (`read` of them seen; digital silence tells nothing).
    fractional: bool,
    read: u64,
}

impl Level {
    fn take(&mut self, x: &[f32]) {
        if !self.fractional && self.read < INTEGRAL_SAMPLES {
            for v in x.iter().filter(|&&v| v != 0.0) {
                self.read += 1;
                if v.fract() != 0.0 {
                    self.fractional = true;
                }
                if self.fractional || self.read >= INTEGRAL_SAMPLES {
                    break;
                }
            }
        }
        if !self.varies {
            if let Some(&x0) = x.first() {
                let v0 = *self.first.get_or_insert(x0);
                self.varies = x.iter().any(|&v| v != v0);
            }
        }
        // f32 partial sums in eight lanes per call (a few thousand samples), f64 across
        // calls; the peak and how often it comes in a second pass where it may change.
        let (mut s8, mut q8, mut m8) = ([0.0f32; 8], [0.0f32; 8], [0.0f32; 8]);
        let chunks = x.chunks_exact(8);
        let tail = chunks.remainder();
        for b in chunks {
            for k in 0..8 {
                s8[k] += b[k];
                q8[k] += b[k] * b[k];
                m8[k] = m8[k].max(b[k].abs());
            }
        }
        let s: f32 = s8.iter().sum::<f32>() + tail.iter().sum::<f32>();
        let s2: f32 = q8.iter().sum::<f32>() + tail.iter().map(|v| v * v).sum::<f32>();
        // fold is monotone on integer values: the largest folded value is the largest's fold.
        let top = fold(
            tail.iter()
                .fold(m8.iter().fold(0.0f32, |a, &b| a.max(b)), |a, &v| a.max(v.abs())),
        );
        if top >= self.peak {
            if top > self.peak {
                (self.peak, self.at_peak) = (top, 0);
            }
            let pk = self.peak;
            self.at_peak += x.iter().filter(|&&v| fold(v.abs()) == pk).count() as u64;
        }
        self.sum += s as f64;
        self.sum2 += s2 as f64;
    }
}

/// The polarity test's sums (see the module docs).
#[derive(Debug, Clone)]
struct Coherence {
    at: ClosePairs,
    cross: Vec<f64>,
    power: Vec<f64>,
    /// Frames summed, frames to sum at most (lowered once decided), frames per second.
    frames: usize,
    max_frames: usize,
    rate: f64,
}

/// Fold the full-scale values of each format onto one: 32768 → 32767, 2²³ → 2²³ − 1
/// (−32768 and 32767 are both int16 full scale).
fn fold(a: f32) -> f32 {
    if a == 32768.0 {
        32767.0
    } else if a == 8_388_608.0 {
        8_388_607.0
    } else {
        a
    }
}

/// Whether `peak` (folded) is a format's full scale; ±1.0 only for samples with
/// fractional parts (float formats: integer samples at ±1 are one quantisation step).
fn full_scale(peak: f32, fractional: bool) -> bool {
    peak == 32767.0 || peak == 8_388_607.0 || peak == 2_147_483_648.0 || (peak == 1.0 && fractional)
}

/// The pairs of microphones close enough for the polarity test and the bins to read,
/// from the steering vectors of the used bin `first` (`steer[dir · m + mic]`, at `f0_hz`;
/// `bin_hz` apart, `num_bins` used bins). None when the array gives no usable pairs
/// (identical steering gives no delays; every pair's phase at f₀ beyond π/3).
pub fn close_pairs<T: Real>(
    steer: &[C<T>],
    m: usize,
    first: usize,
    num_bins: usize,
    f0_hz: f64,
    bin_hz: f64,
) -> Option<ClosePairs> {
    if m < 2 || f0_hz <= 0.0 || steer.len() < m || !steer.len().is_multiple_of(m) || first >= num_bins {
        return None;
    }
    // cos φ_ij = min over directions of Re(a_i a_j*) / (|a_i| |a_j|).
    let mut mincos = vec![1.0f64; m * m];
    let mut v = vec![(0.0f64, 0.0f64); m];
    for a in steer.chunks_exact(m) {
        for (w, z) in v.iter_mut().zip(a) {
            let (re, im) = (z.re.to_f64(), z.im.to_f64());
            let n = re.hypot(im);
            *w = if n > 0.0 { (re / n, im / n) } else { (0.0, 0.0) };
        }
        for i in 0..m {
            for j in i + 1..m {
                let c = v[i].0 * v[j].0 + v[i].1 * v[j].1;
                let k = &mut mincos[i * m + j];
                if c < *k {
                    *k = c;
                }
            }
        }
    }
    let phi = |i: usize, j: usize| mincos[i.min(j) * m + i.max(j)].clamp(-1.0, 1.0).acos();
    let limit = std::f64::consts::FRAC_PI_3;
    let mut nearest: Vec<f64> = (0..m)
        .filter_map(|i| {
            (0..m)
                .filter(|&j| j != i)
                .map(|j| phi(i, j))
                .filter(|&p| p <= limit)
                .min_by(f64::total_cmp)
        })
        .collect();
    if nearest.len() < m.div_ceil(2) {
        return None;
    }
    nearest.sort_by(f64::total_cmp);
    let pc = nearest[nearest.len() / 2];
    if pc < 1e-3 {
        return None;
    }
    let pairs: Vec<(usize, usize)> = (0..m)
        .flat_map(|i| (i + 1..m).map(move |j| (i, j)))
        .filter(|&(i, j)| {
            let p = phi(i, j);
            p <= 2.0 * pc && p <= limit
        })
        .collect();
    let top = pairs.iter().map(|&(i, j)| phi(i, j)).fold(0.0, f64::max);
    // Phases grow with frequency: ≤ π/2 up to f₀ · (π/2) / φ_max.
    let f_top = f0_hz * std::f64::consts::FRAC_PI_2 / top.max(1e-12);
    let bins = ((((f_top - f0_hz) / bin_hz).floor() as usize) + 1)
        .min(MAX_TEST_BINS)
        .min(num_bins - first);
    (!pairs.is_empty()).then(|| ClosePairs {
        pairs,
        first,
        bins,
        band_hz: (f0_hz, f0_hz + (bins - 1) as f64 * bin_hz),
    })
}

impl ChannelHealth {
    /// Checks for microphones fed by input channels `inputs` at `fs` Hz; `pairs` from
    /// [`close_pairs`] (None: no polarity test), frames `hop` samples apart.
    pub fn new(inputs: Vec<usize>, fs: f64, hop: usize, pairs: Option<ClosePairs>) -> Self {
        let m = inputs.len();
        let rate = fs / hop.max(1) as f64;
        let coh = pairs.map(|at| Coherence {
            cross: vec![0.0; at.pairs.len()],
            power: vec![0.0; m],
            at,
            frames: 0,
            max_frames: (BAND_SECONDS * rate).ceil() as usize,
            rate,
        });
        ChannelHealth {
            levels: vec![Level::default(); m],
            samples: 0,
            early: (DECIDE_SECONDS * fs).ceil() as u64,
            coh,
            said: vec![[false; 3]; m],
            said_silent: false,
            said_quiet: false,
            expected: None,
            said_gains: false,
            band_power: vec![0.0; m],
            band_frames: 0,
            inputs,
        }
    }

    /// Also check the channels' gains against `expected` relative powers per microphone
    /// ([`gains`]; from [`crate::plan::Plan::expected_levels`]); once per stream.
    pub fn with_gain_check(mut self, expected: Vec<f64>) -> Self {
        self.expected = (expected.len() == self.inputs.len()).then_some(expected);
        self
    }

    /// Take the next samples of every microphone (`chans[mic]`, equal lengths).
    pub fn observe(&mut self, chans: &[&[f32]]) {
        let n = chans.first().map_or(0, |c| c.len());
        let m = self.levels.len().min(chans.len());
        if n * m >= PAR_MIN_SAMPLES {
            use rayon::prelude::*;
            self.levels[..m]
                .par_iter_mut()
                .zip(chans[..m].par_iter())
                .for_each(|(l, x)| l.take(x));
        } else {
            for (l, x) in self.levels.iter_mut().zip(chans) {
                l.take(x);
            }
        }
        self.samples += n as u64;
    }

    /// Take new STFT frames, `[frame][used bin][mic]` with `num_bins` used bins.
    pub fn observe_frames<T: Real>(&mut self, frames: &[C<T>], num_bins: usize) {
        let m = self.inputs.len();
        if self.expected.is_some() && num_bins > 0 && m > 0 && !self.said_gains {
            for bin in frames.chunks_exact(m) {
                for (p, z) in self.band_power.iter_mut().zip(bin) {
                    let (re, im) = (z.re.to_f64(), z.im.to_f64());
                    *p += re * re + im * im;
                }
            }
            self.band_frames += frames.len() / (num_bins * m);
        }
        let Some(c) = &mut self.coh else { return };
        if c.frames >= c.max_frames || num_bins == 0 || m == 0 {
            return;
        }
        let (b0, nb) = (c.at.first, c.at.bins);
        for f in frames.chunks_exact(num_bins * m) {
            if c.frames >= c.max_frames {
                break;
            }
            c.frames += 1;
            let Some(x) = f.get(b0 * m..(b0 + nb) * m) else {
                return;
            };
            for bin in x.chunks_exact(m) {
                for (p, z) in c.power.iter_mut().zip(bin) {
                    let (re, im) = (z.re.to_f64(), z.im.to_f64());
                    *p += re * re + im * im;
                }
                for (s, &(i, j)) in c.cross.iter_mut().zip(&c.at.pairs) {
                    let (a, b) = (bin[i], bin[j]);
                    *s += a.re.to_f64() * b.re.to_f64() + a.im.to_f64() * b.im.to_f64();
                }
            }
        }
        // Enough once the field has carried the band coherently for DECIDE_SECONDS.
        if c.frames as f64 >= DECIDE_SECONDS * c.rate && c.assess().is_some_and(|(_, o)| o > COHERENT_RHO) {
            c.max_frames = c.frames;
        }
    }

    /// Notes not given yet about what was seen so far: at the end of a stream
    /// (`end`), or any time before it (a live stream's checks then speak once
    /// [`DECIDE_SECONDS`] are in and the polarity test is done, see [`BAND_SECONDS`]).
    pub fn notes(&mut self, end: bool) -> Vec<String> {
        let mut notes = Vec::new();
        let m = self.inputs.len();
        if self.samples == 0 || m == 0 {
            return notes;
        }
        // Ahead of the end only once DECIDE_SECONDS are in and the polarity test is done: a
        // channel silent for the first moments of a recording is not yet a dead one.
        let band_done = self.coh.as_ref().is_none_or(|c| c.frames >= c.max_frames);
        let ready = end || (band_done && self.samples >= self.early);
        if !ready {
            return notes;
        }
        if self.levels.iter().all(|l| !l.varies) {
            if end && !self.said_silent {
                self.said_silent = true;
                let v = self
                    .levels
                    .iter()
                    .filter_map(|l| l.first)
                    .fold(0.0f32, |a, b| a.max(b.abs()));
                notes.push(if v == 0.0 {
                    "warning: the input is silent (every sample is 0): the reported directions mean nothing".into()
                } else {
                    "warning: every channel is constant (DC only, no sound in the analysed band): the reported directions mean nothing".into()
                });
            }
            return notes;
        }
        let n = self.samples as f64;
        let rms: Vec<f64> = self
            .levels
            .iter()
            .map(|l| {
                let mean = l.sum / n;
                (l.sum2 / n - mean * mean).max(0.0).sqrt()
            })
            .collect();
        let mut sorted = rms.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[m / 2];
        let leave_out = "leave it out with the TF channel selection (--channels, channels= in Python)";
        let integral = self.levels.iter().all(|l| !l.fractional);
        // Integer samples under one quantisation step: rounding, not microphones, sets the
        // levels (module docs).
        if integral && median < 1.0 {
            if !self.said_quiet {
                self.said_quiet = true;
                let flat: Vec<String> = (0..m)
                    .filter(|&c| !self.levels[c].varies)
                    .map(|c| self.inputs[c].to_string())
                    .collect();
                let flat = match flat.len() {
                    0 => String::new(),
                    1 => format!(" (input channel {} reads constant)", flat[0]),
                    _ => format!(" (input channels {} read constant)", flat.join(", ")),
                };
                notes.push(format!(
                    "warning: the input is nearly silent: the median channel's RMS is {median:.2} in the samples' integer units, below one quantisation step, so the channels are mostly rounding{flat} and the directions are unreliable; raise the input gain"
                ));
            }
        } else {
            for (c, &level) in rms.iter().enumerate() {
                if self.said[c][0] {
                    continue;
                }
                let what = if !self.levels[c].varies {
                    Some("is constant".to_string())
                } else if median > 0.0 && level < median * 10f64.powf(-DEAD_DB / 20.0) {
                    Some(format!(
                        "is {:.0} dB below the median channel",
                        20.0 * (median / level.max(f64::MIN_POSITIVE)).log10()
                    ))
                } else {
                    None
                };
                if let Some(w) = what {
                    self.said[c][0] = true;
                    notes.push(format!(
                        "warning: input channel {} (0-based) {w}: a dead or unplugged microphone? It adds only noise to every direction and makes the source count (num_active) and tracks unreliable; {leave_out}",
                        self.inputs[c]
                    ));
                }
            }
            if let Some(expected) = self.expected.as_ref().filter(|_| !self.said_gains) {
                self.said_gains = true;
                // The used bins' power where frames came (the band `expected` covers),
                // else the samples' (a stream shorter than one frame).
                let power: Vec<f64> = if self.band_frames > 0 {
                    self.band_power.clone()
                } else {
                    rms.iter().map(|r| r * r).collect()
                };
                let skip: Vec<bool> = (0..m).map(|c| self.said[c][0]).collect();
                notes.extend(gains::gain_note(&power, expected, &self.inputs, &skip));
            }
        }
        let clipped: Vec<usize> = (0..m)
            .filter(|&c| {
                !self.said[c][1]
                    && full_scale(self.levels[c].peak, !integral)
                    && self.levels[c].at_peak as f64 > CLIP_FRACTION * n
                    && self.levels[c].varies
            })
            .collect();
        if !clipped.is_empty() {
            let worst = clipped
                .iter()
                .map(|&c| self.levels[c].at_peak as f64 / n)
                .fold(0.0, f64::max);
            for &c in &clipped {
                self.said[c][1] = true;
            }
            let names: Vec<String> = clipped.iter().map(|&c| self.inputs[c].to_string()).collect();
            notes.push(format!(
                "warning: input channel{} {} (0-based) clip: up to {:.2} % of the samples at full scale (±{}): the correlations and directions suffer; lower the input gain",
                if clipped.len() > 1 { "s" } else { "" },
                names.join(", "),
                100.0 * worst,
                self.levels[clipped[0]].peak
            ));
        }
        if let Some(b) = &self.coh {
            for (c, rho) in b.inverted() {
                if !self.said[c][2] {
                    self.said[c][2] = true;
                    notes.push(format!(
                        "warning: input channel {} (0-based) looks polarity-inverted: at {:.0}-{:.0} Hz it is anticorrelated with its close neighbours (median correlation {rho:.2}; any sound field gives a positive one there): every direction will be wrong; fix its wiring, or negate it: --invert-channels {c} (invert_channels=[{c}] in Python)",
                        self.inputs[c], b.at.band_hz.0, b.at.band_hz.1, c = self.inputs[c]
                    ));
                }
            }
        }
        notes
    }
}

impl Coherence {
    /// The microphones whose median correlation with their close neighbours is below
    /// −[`POLARITY_RHO`], and the median correlation of the pairs without them; None
    /// before [`MIN_BAND_SECONDS`].
    fn assess(&self) -> Option<(Vec<(usize, f64)>, f64)> {
        if (self.frames as f64) < MIN_BAND_SECONDS * self.rate {
            return None;
        }
        let m = self.power.len();
        let rho: Vec<f64> = self
            .at
            .pairs
            .iter()
            .zip(&self.cross)
            .map(|(&(i, j), &s)| {
                let p = (self.power[i] * self.power[j]).sqrt();
                if p > 0.0 {
                    s / p
                } else {
                    0.0
                }
            })
            .collect();
        let median = |mut v: Vec<f64>| -> Option<f64> {
            if v.is_empty() {
                return None;
            }
            v.sort_by(f64::total_cmp);
            let h = v.len() / 2;
            Some(if v.len() % 2 == 1 {
                v[h]
            } else {
                0.5 * (v[h - 1] + v[h])
            })
        };
        let flagged: Vec<(usize, f64)> = (0..m)
            .filter_map(|c| {
                let mine = self
                    .at
                    .pairs
                    .iter()
                    .zip(&rho)
                    .filter(|((i, j), _)| *i == c || *j == c)
                    .map(|(_, &r)| r)
                    .collect();
                median(mine).filter(|&r| r < -POLARITY_RHO).map(|r| (c, r))
            })
            .collect();
        // The other close pairs must correlate: the field carries the low band coherently.
        let others = self
            .at
            .pairs
            .iter()
            .zip(&rho)
            .filter(|((i, j), _)| !flagged.iter().any(|&(c, _)| c == *i || c == *j))
            .map(|(_, &r)| r)
            .collect();
        Some((flagged, median(others).unwrap_or(0.0)))
    }

    /// Microphones that look polarity-inverted (fewer than half, the other close pairs
    /// correlating), with their median correlation.
    fn inverted(&self) -> Vec<(usize, f64)> {
        match self.assess() {
            Some((f, others)) if !f.is_empty() && 2 * f.len() < self.power.len() && others > POLARITY_RHO => {
                f
            }
            _ => Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests;
