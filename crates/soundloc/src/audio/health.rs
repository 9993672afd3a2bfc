//! Checks of a stream's channels as they arrive: dead, clipping and polarity-inverted
//! microphones. Each finding is a warning note, given once per stream, naming the input
//! channel (0-based, as in the file or device); the results are not changed.
//!
//! - **Constant / silent.** Every sample of a channel equal to its first (all channels:
//!   the input is silent or DC only).
//! - **Dead.** A channel whose RMS about its mean is more than [`DEAD_DB`] below the
//!   median channel's (an unplugged or broken microphone leaves sensor or cable noise).
//!   Near-field sources (rotors a few cm away) make level differences of 10–15 dB, not 30.
//! - **Clipping.** More than [`CLIP_FRACTION`] of a channel's samples at the format's full
//!   scale (±32767/32768 int16, ±8388607/8 int24, ±2³¹ int32, ±1.0 float): the flat tops
//!   make the correlations wrong.
//! - **Polarity.** For any sound field, two microphones d apart see every wave with a
//!   delay |τ| ≤ d/c, so below f the cross-spectrum's real part is positive when
//!   2πf·d/c < π/2 (each wave adds |S|²·g_i·g_j·cos 2πfτ > 0; uncorrelated noise adds 0).
//!   A channel whose low band is *anti*correlated with its close neighbours (median
//!   correlation below −[`POLARITY_RHO`]) while the other close pairs correlate
//!   (median above +[`POLARITY_RHO`]) is wired or converted with its sign flipped: every
//!   MUSIC or SRP direction is then wrong. The pairs and the band come from the steering
//!   vectors (measured TFs or free field): at the lowest used bin f₀ the largest phase
//!   between microphones i and j over all directions, φ_ij, bounds their delay,
//!   τ_ij = φ_ij / (2π f₀). With τ_c the median over microphones of their nearest pair's
//!   τ, the pairs with τ_ij ≤ 2τ_c are compared below f_c = 1/(16 τ_c) (phases ≤ π/4 at
//!   f_c), on the first [`DECIDE_SECONDS`]–[`BAND_SECONDS`] of audio: a DC blocker (20 Hz), block sums of D samples
//!   (rate ≥ 8 f_c, D = ⌊fs / 8f_c⌋) and two second-order Butterworth low-pass sections at
//!   f_c.

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
/// The polarity test's products take every PRODUCT_STEP-th filtered block.
const PRODUCT_STEP: usize = 4;
/// Seconds of filtered signal skipped at the start (the filters' transients).
const SETTLE_SECONDS: f64 = 0.2;
/// Low-band signal needed before the polarity test says anything (seconds).
const MIN_BAND_SECONDS: f64 = 1.0;

/// Running checks of one stream's channels (see the module docs).
#[derive(Debug, Clone)]
pub struct ChannelHealth {
    /// Input channel of each microphone, for the notes.
    inputs: Vec<usize>,
    fs: f64,
    first: Vec<Option<f32>>,
    varies: Vec<bool>,
    sum: Vec<f64>,
    sum2: Vec<f64>,
    /// Largest |x| (full-scale values folded to one, see `fold`) and how often it came.
    peak: Vec<f32>,
    at_peak: Vec<u64>,
    samples: u64,
    band: Option<Band>,
    /// Notes given: dead, clipping, polarity (per microphone), silent (the whole input).
    said: Vec<[bool; 3]>,
    said_silent: bool,
}

/// The polarity test's low band (see the module docs). Single precision, the
/// microphones side by side (`[block][mic]`), so that the filters run in vector lanes.
#[derive(Debug, Clone)]
struct Band {
    fc_hz: f64,
    /// Samples per block sum.
    d: usize,
    /// Samples of the current block summed so far (the same for every channel).
    fill: usize,
    acc: Vec<f32>,
    /// Per microphone: DC blocker (x₋₁, y₋₁), two biquads (z₁, z₂ each).
    state: [Vec<f32>; 6],
    blocker: f32,
    /// b0, b1, b2, a1, a2 of the low-pass section (a0 = 1).
    lp: [f32; 5],
    /// The current call's block sums, then filtered values, `[block][mic]`.
    rows: Vec<f32>,
    pairs: Vec<(usize, usize)>,
    cross: Vec<f64>,
    power: Vec<f64>,
    /// Blocks seen, blocks skipped at the start, blocks the test reads at most.
    blocks: usize,
    settle: usize,
    max_blocks: usize,
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

/// Whether `peak` (folded) is a format's full scale.
fn full_scale(peak: f32) -> bool {
    peak == 32767.0 || peak == 8_388_607.0 || peak == 2_147_483_648.0 || peak == 1.0
}

/// The pairs of microphones close enough for the polarity test and its band edge f_c
/// (Hz), from the steering vectors of one bin at `f0_hz`: `steer[dir · m + mic]`. None
/// when the array gives no usable pairs (a pair's phase beyond 0.8π at f₀ is not
/// trusted; identical steering gives no delays; f_c would be below 100 Hz).
pub fn close_pairs<T: Real>(
    steer: &[C<T>],
    m: usize,
    f0_hz: f64,
    fs: f64,
) -> Option<(Vec<(usize, usize)>, f64)> {
    if m < 2 || f0_hz <= 0.0 || steer.len() < m || !steer.len().is_multiple_of(m) {
        return None;
    }
    // cos φ_ij = min over directions of Re(a_i a_j*) / (|a_i| |a_j|).
    let mut mincos = vec![1.0f64; m * m];
    for a in steer.chunks_exact(m) {
        let v: Vec<(f64, f64, f64)> = a
            .iter()
            .map(|z| {
                let (re, im) = (z.re.to_f64(), z.im.to_f64());
                let n = re.hypot(im);
                (re, im, if n > 0.0 { 1.0 / n } else { 0.0 })
            })
            .collect();
        for i in 0..m {
            for j in i + 1..m {
                let c = (v[i].0 * v[j].0 + v[i].1 * v[j].1) * v[i].2 * v[j].2;
                let k = &mut mincos[i * m + j];
                if c < *k {
                    *k = c;
                }
            }
        }
    }
    let tau = |i: usize, j: usize| -> Option<f64> {
        let (a, b) = (i.min(j), i.max(j));
        let phi = mincos[a * m + b].clamp(-1.0, 1.0).acos();
        (phi <= 0.8 * std::f64::consts::PI).then(|| phi / (2.0 * std::f64::consts::PI * f0_hz))
    };
    let mut nearest: Vec<f64> = (0..m)
        .filter_map(|i| {
            (0..m)
                .filter(|&j| j != i)
                .filter_map(|j| tau(i, j))
                .min_by(f64::total_cmp)
        })
        .collect();
    if nearest.len() < m.div_ceil(2) {
        return None;
    }
    nearest.sort_by(f64::total_cmp);
    let tc = nearest[nearest.len() / 2];
    if tc < 1e-6 {
        return None;
    }
    let fc = (1.0 / (16.0 * tc)).min(1000.0).min(fs / 8.0);
    if fc < 100.0 {
        return None;
    }
    let pairs: Vec<(usize, usize)> = (0..m)
        .flat_map(|i| (i + 1..m).map(move |j| (i, j)))
        .filter(|&(i, j)| tau(i, j).is_some_and(|t| t <= 2.0 * tc))
        .collect();
    (!pairs.is_empty()).then_some((pairs, fc))
}

impl ChannelHealth {
    /// Checks for microphones fed by input channels `inputs` at `fs` Hz; `pairs` from
    /// [`close_pairs`] (None: no polarity test).
    pub fn new(inputs: Vec<usize>, fs: f64, pairs: Option<(Vec<(usize, usize)>, f64)>) -> Self {
        let m = inputs.len();
        let band = pairs.map(|(pairs, fc_hz)| {
            let d = ((fs / (8.0 * fc_hz)).floor() as usize).max(1);
            let rate = fs / d as f64;
            // RBJ low-pass, Q = 1/√2 (two in a row: fourth order, −24 dB per octave).
            let w0 = 2.0 * std::f64::consts::PI * fc_hz / rate;
            let alpha = w0.sin() / std::f64::consts::SQRT_2;
            let cw = w0.cos();
            let a0 = 1.0 + alpha;
            let b0 = (1.0 - cw) / 2.0 / a0;
            let n = pairs.len();
            Band {
                fc_hz,
                d,
                fill: 0,
                acc: vec![0.0; m],
                state: std::array::from_fn(|_| vec![0.0; m]),
                blocker: (-2.0 * std::f64::consts::PI * 20.0 / rate).exp() as f32,
                lp: [b0, 2.0 * b0, b0, -2.0 * cw / a0, (1.0 - alpha) / a0].map(|v| v as f32),
                rows: Vec::new(),
                pairs,
                cross: vec![0.0; n],
                power: vec![0.0; m],
                blocks: 0,
                settle: (SETTLE_SECONDS * rate).ceil() as usize,
                max_blocks: (BAND_SECONDS * rate).ceil() as usize,
            }
        });
        ChannelHealth {
            fs,
            first: vec![None; m],
            varies: vec![false; m],
            sum: vec![0.0; m],
            sum2: vec![0.0; m],
            peak: vec![0.0; m],
            at_peak: vec![0; m],
            samples: 0,
            band,
            said: vec![[false; 3]; m],
            said_silent: false,
            inputs,
        }
    }

    /// Take the next samples of every microphone (`chans[mic]`, equal lengths).
    pub fn observe(&mut self, chans: &[&[f32]]) {
        let n = chans.first().map_or(0, |c| c.len());
        for (c, x) in chans.iter().enumerate().take(self.inputs.len()) {
            if !self.varies[c] {
                if let Some(&x0) = x.first() {
                    let v0 = *self.first[c].get_or_insert(x0);
                    self.varies[c] = x.iter().any(|&v| v != v0);
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
            let (mut pk, mut at) = (self.peak[c], self.at_peak[c]);
            if top >= pk {
                if top > pk {
                    (pk, at) = (top, 0);
                }
                at += x.iter().filter(|&&v| fold(v.abs()) == pk).count() as u64;
            }
            self.sum[c] += s as f64;
            self.sum2[c] += s2 as f64;
            self.peak[c] = pk;
            self.at_peak[c] = at;
        }
        self.samples += n as u64;
        if let Some(b) = &mut self.band {
            b.observe(chans, self.fs);
        }
    }

    /// Notes not given yet about what was seen so far: at the end of a stream
    /// (`end`), or any time before it (a live stream's checks then speak once the
    /// polarity test is done, see [`BAND_SECONDS`]).
    pub fn notes(&mut self, end: bool) -> Vec<String> {
        let mut notes = Vec::new();
        let m = self.inputs.len();
        if self.samples == 0 || m == 0 {
            return notes;
        }
        let band_done = self.band.as_ref().is_none_or(|b| b.blocks >= b.max_blocks);
        if !end && !band_done {
            return notes;
        }
        if self.varies.iter().all(|v| !v) {
            if end && !self.said_silent {
                self.said_silent = true;
                let v = self.first.iter().flatten().fold(0.0f32, |a, b| a.max(b.abs()));
                notes.push(if v == 0.0 {
                    "warning: the input is silent (every sample is 0): the reported directions mean nothing".into()
                } else {
                    "warning: every channel is constant (DC only, no sound in the analysed band): the reported directions mean nothing".into()
                });
            }
            return notes;
        }
        let n = self.samples as f64;
        let rms: Vec<f64> = (0..m)
            .map(|c| {
                let mean = self.sum[c] / n;
                (self.sum2[c] / n - mean * mean).max(0.0).sqrt()
            })
            .collect();
        let mut sorted = rms.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[m / 2];
        let leave_out = "leave it out with the TF channel selection (--channels, channels= in Python)";
        for (c, &level) in rms.iter().enumerate() {
            if self.said[c][0] {
                continue;
            }
            let what = if !self.varies[c] {
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
                    "warning: input channel {} (0-based) {w}: a dead or unplugged microphone? It adds only noise to every direction; {leave_out}",
                    self.inputs[c]
                ));
            }
        }
        let clipped: Vec<usize> = (0..m)
            .filter(|&c| {
                !self.said[c][1]
                    && full_scale(self.peak[c])
                    && self.at_peak[c] as f64 > CLIP_FRACTION * n
                    && self.varies[c]
            })
            .collect();
        if !clipped.is_empty() {
            let worst = clipped
                .iter()
                .map(|&c| self.at_peak[c] as f64 / n)
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
                self.peak[clipped[0]]
            ));
        }
        if let Some(b) = &self.band {
            for (c, rho) in b.inverted(self.fs) {
                if !self.said[c][2] {
                    self.said[c][2] = true;
                    notes.push(format!(
                        "warning: input channel {} (0-based) looks polarity-inverted: below {:.0} Hz it is anticorrelated with its close neighbours (median correlation {rho:.2}; any sound field gives a positive one there): every direction will be wrong; fix its wiring or negate that channel in the recording",
                        self.inputs[c], b.fc_hz
                    ));
                }
            }
        }
        notes
    }
}

impl Band {
    fn observe(&mut self, chans: &[&[f32]], fs: f64) {
        let m = self.acc.len();
        if self.blocks >= self.max_blocks || chans.len() < m {
            return;
        }
        let n = chans.first().map_or(0, |c| c.len());
        let d = self.d;
        if self.fill + n < d {
            for (a, x) in self.acc.iter_mut().zip(chans) {
                *a += x.iter().sum::<f32>();
            }
            self.fill += n;
            return;
        }
        // Block sums: the open block, then whole ones; the rest opens the next.
        let s0 = d - self.fill;
        let k = (n - s0) / d;
        let (nb, rest) = (1 + k, s0 + k * d);
        self.rows.clear();
        self.rows.resize(nb * m, 0.0);
        for (c, x) in chans.iter().enumerate().take(m) {
            self.rows[c] = self.acc[c] + x[..s0].iter().sum::<f32>();
            for (i, b) in x[s0..rest].chunks_exact(d).enumerate() {
                self.rows[(i + 1) * m + c] = b.iter().sum();
            }
            self.acc[c] = x[rest..].iter().sum();
        }
        self.fill = n - rest;
        // DC blocker and the two low-pass sections (transposed direct form II), every
        // microphone at once.
        let [b0, b1, b2, a1, a2] = self.lp;
        let r = self.blocker;
        let [x1, y1, s1, s2, s3, s4] = &mut self.state;
        let (x1, y1, s1, s2, s3, s4) = (
            &mut x1[..m],
            &mut y1[..m],
            &mut s1[..m],
            &mut s2[..m],
            &mut s3[..m],
            &mut s4[..m],
        );
        for row in self.rows.chunks_exact_mut(m) {
            for c in 0..m {
                let v = row[c];
                let y0 = v - x1[c] + r * y1[c];
                x1[c] = v;
                y1[c] = y0;
                let u = b0 * y0 + s1[c];
                s1[c] = b1 * y0 - a1 * u + s2[c];
                s2[c] = b2 * y0 - a2 * u;
                let w = b0 * u + s3[c];
                s3[c] = b1 * u - a1 * w + s4[c];
                s4[c] = b2 * u - a2 * w;
                row[c] = w;
            }
        }
        // Sums over the blocks after the settling ones, up to the test's length.
        let lo = self.settle.saturating_sub(self.blocks).min(nb);
        let hi = (self.max_blocks - self.blocks).min(nb);
        self.blocks += hi;
        if lo >= hi {
            return;
        }
        // A pair at a time in registers (single-precision sums over one call's blocks),
        // every PRODUCT_STEP-th block: at 8 f_c the band is sampled 4 times over, so the
        // sums lose little and cost a quarter.
        let rows = &self.rows[lo * m..hi * m];
        for (x, &(i, j)) in self.cross.iter_mut().zip(&self.pairs) {
            *x += rows
                .chunks_exact(m)
                .step_by(PRODUCT_STEP)
                .map(|r| r[i] * r[j])
                .sum::<f32>() as f64;
        }
        let mut power = vec![0.0f32; m];
        for row in rows.chunks_exact(m).step_by(PRODUCT_STEP) {
            for (p, &v) in power.iter_mut().zip(row) {
                *p += v * v;
            }
        }
        for (a, b) in self.power.iter_mut().zip(power) {
            *a += b as f64;
        }
        // Enough once the field has carried the band coherently for DECIDE_SECONDS.
        if self.read_s(fs) >= DECIDE_SECONDS && self.assess(fs).is_some_and(|(_, o)| o > COHERENT_RHO) {
            self.max_blocks = self.blocks;
        }
    }

    /// Seconds of low band summed so far.
    fn read_s(&self, fs: f64) -> f64 {
        self.blocks.saturating_sub(self.settle) as f64 * self.d as f64 / fs
    }

    /// The microphones whose median correlation with their close neighbours is below
    /// −[`POLARITY_RHO`], and the median correlation of the pairs without them; None
    /// before [`MIN_BAND_SECONDS`].
    fn assess(&self, fs: f64) -> Option<(Vec<(usize, f64)>, f64)> {
        if self.read_s(fs) < MIN_BAND_SECONDS {
            return None;
        }
        let m = self.power.len();
        let rho: Vec<f64> = self
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
    fn inverted(&self, fs: f64) -> Vec<(usize, f64)> {
        match self.assess(fs) {
            Some((f, others)) if !f.is_empty() && 2 * f.len() < self.power.len() && others > POLARITY_RHO => {
                f
            }
            _ => Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests;
