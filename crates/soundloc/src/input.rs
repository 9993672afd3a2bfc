//! Audio in, as the engine sees it: views of sample blocks in any layout ([`Block`]) and
//! the map from input channels to microphones ([`ChannelMap`]).
//!
//! A block is borrowed, never copied before the STFT needs it: interleaved frames (what
//! sound cards, WAV files and raw PCM streams give), channels-first contiguous arrays
//! (numpy `(channels, samples)`), or one vector per channel. Samples are raw values (see
//! [`crate::audio`]).

use crate::{Error, Result};
use std::ops::Range;

/// The most audio, in seconds, that a reader falling behind live input hands to one push:
/// blocks queued behind the one at hand go into the same push, so their windows run as one
/// batch (the CLI's live inputs — pipes, sockets, `listen` — and `bench --stream --paced`;
/// files are read in fixed blocks, so their batches never depend on timing).
pub const CATCH_UP_S: f64 = 1.0;

/// Frames per tile when an interleaved block is split into channels.
const TILE: usize = 256;

/// Samples from which a block is checked and transposed on every core (≈ 1 MB: below it a
/// hand-off to the thread pool costs more than it saves).
const PAR_SAMPLES: usize = 1 << 18;

/// Frames `data` (interleaved, `ch` channels) into `outs[k]` ← channel `idx[k]`, in tiles
/// of [`TILE`] frames (the tile stays in cache while every channel takes its samples).
fn transpose(data: &[f32], ch: usize, idx: &[usize], outs: &mut [&mut [f32]]) {
    let n = data.len() / ch.max(1);
    for t0 in (0..n).step_by(TILE) {
        let t1 = (t0 + TILE).min(n);
        let tile = &data[t0 * ch..t1 * ch];
        for (&c, o) in idx.iter().zip(outs.iter_mut()) {
            for (x, frame) in o[t0..t1].iter_mut().zip(tile.chunks_exact(ch)) {
                *x = frame[c];
            }
        }
    }
}

/// A block of multichannel samples.
#[derive(Debug, Clone, Copy)]
pub enum Block<'a> {
    /// `data[n * channels + c]` is sample n of channel c.
    Interleaved {
        /// The samples.
        data: &'a [f32],
        /// Number of channels.
        channels: usize,
    },
    /// `data[c * samples + n]` is sample n of channel c (channels first, contiguous).
    ChannelsFirst {
        /// The samples.
        data: &'a [f32],
        /// Number of channels.
        channels: usize,
    },
    /// One slice per channel, equal lengths.
    Planar(&'a [Vec<f32>]),
}

impl<'a> Block<'a> {
    /// Number of channels.
    pub fn channels(&self) -> usize {
        match self {
            Block::Interleaved { channels, .. } | Block::ChannelsFirst { channels, .. } => *channels,
            Block::Planar(p) => p.len(),
        }
    }

    /// The block's frames appended to `out`, interleaved (a copy only where the layout is
    /// another).
    pub fn append_interleaved(&self, out: &mut Vec<f32>) -> Result<()> {
        let n = self.samples()?;
        match *self {
            Block::Interleaved { data, .. } => out.extend_from_slice(data),
            Block::ChannelsFirst { data, channels } => {
                out.extend((0..n).flat_map(|i| (0..channels).map(move |c| data[c * n + i])))
            }
            Block::Planar(p) => out.extend((0..n).flat_map(|i| p.iter().map(move |c| c[i]))),
        }
        Ok(())
    }

    /// Frames `range` of the block (a consistent one: [`Block::samples`]): interleaved
    /// data is sliced, the other layouts copied into `scratch` interleaved. For pushing a
    /// long block in pieces; the pieces' results equal the whole block's.
    pub fn range<'b>(&self, range: Range<usize>, scratch: &'b mut Vec<f32>) -> Block<'b>
    where
        'a: 'b,
    {
        let channels = self.channels();
        match *self {
            Block::Interleaved { data, .. } => Block::Interleaved {
                data: &data[range.start * channels..range.end * channels],
                channels,
            },
            Block::ChannelsFirst { data, .. } => {
                let n = data.len() / channels;
                scratch.clear();
                scratch.extend(range.flat_map(|i| (0..channels).map(move |c| data[c * n + i])));
                Block::Interleaved {
                    data: &scratch[..],
                    channels,
                }
            }
            Block::Planar(p) => {
                scratch.clear();
                scratch.extend(range.flat_map(|i| p.iter().map(move |c| c[i])));
                Block::Interleaved {
                    data: &scratch[..],
                    channels,
                }
            }
        }
    }

    /// Samples per channel; an error when the layout is inconsistent (a length that is not
    /// a multiple of the channel count, channels of different lengths, no channel).
    pub fn samples(&self) -> Result<usize> {
        let bad = |m: String| Err(Error::Mismatch(format!("audio block: {m}")));
        match self {
            Block::Interleaved { data, channels } | Block::ChannelsFirst { data, channels } => {
                if *channels == 0 {
                    return bad("0 channels".into());
                }
                if data.len() % channels != 0 {
                    return bad(format!(
                        "{} samples are not a whole number of {channels}-channel frames",
                        data.len()
                    ));
                }
                Ok(data.len() / channels)
            }
            Block::Planar(p) => {
                let Some(first) = p.first() else {
                    return bad("0 channels".into());
                };
                if let Some((c, ch)) = p.iter().enumerate().find(|(_, c)| c.len() != first.len()) {
                    return bad(format!(
                        "channel {c} has {} samples, channel 0 has {}",
                        ch.len(),
                        first.len()
                    ));
                }
                Ok(first.len())
            }
        }
    }

    /// Sample `frame` of channel `c` (both in range).
    pub fn at(&self, frame: usize, c: usize) -> f32 {
        match *self {
            Block::Interleaved { data, channels } => data[frame * channels + c],
            Block::ChannelsFirst { data, channels } => data[c * (data.len() / channels) + frame],
            Block::Planar(p) => p[c][frame],
        }
    }

    /// The first frame (and its input channel) among channels `idx` where `bad` holds,
    /// or `None`: a branch-free pass first (it vectorises), the position only when
    /// something is wrong.
    pub fn find(&self, idx: &[usize], bad: impl Fn(f32) -> bool + Sync) -> Option<(usize, usize)> {
        let n = self.samples().ok()?;
        let any1 = |xs: &[f32]| xs.iter().fold(false, |b, &v| b | bad(v));
        // A large block (a file's) is checked on every core: one pass over it is bound by
        // memory, not by the comparisons.
        let any = |xs: &[f32]| {
            if xs.len() < PAR_SAMPLES {
                any1(xs)
            } else {
                use rayon::prelude::*;
                xs.par_chunks(PAR_SAMPLES / 4).any(any1)
            }
        };
        match *self {
            Block::Interleaved { data, channels } => {
                if !any(data) {
                    return None;
                }
                data.chunks_exact(channels)
                    .enumerate()
                    .find_map(|(i, f)| idx.iter().find(|&&c| bad(f[c])).map(|&c| (i, c)))
            }
            Block::ChannelsFirst { .. } | Block::Planar(_) => {
                let chan = |c: usize| match *self {
                    Block::ChannelsFirst { data, .. } => &data[c * n..(c + 1) * n],
                    Block::Planar(p) => &p[c][..],
                    Block::Interleaved { .. } => unreachable!(),
                };
                idx.iter()
                    .filter(|&&c| any(chan(c)))
                    .filter_map(|&c| chan(c).iter().position(|&v| bad(v)).map(|i| (i, c)))
                    .min()
            }
        }
    }

    /// Append samples `range` of channels `idx[k]` to `outs[k]`, for every k. Interleaved
    /// blocks are transposed in tiles of [`TILE`] frames (the tile stays in cache while
    /// every channel takes its samples): ~8× faster than a strided pass per channel at
    /// 60 channels.
    pub fn extend_channels(&self, idx: &[usize], range: Range<usize>, outs: &mut [Vec<f32>]) {
        assert_eq!(idx.len(), outs.len(), "one output per channel index");
        let Block::Interleaved { data, channels } = self else {
            for (&c, out) in idx.iter().zip(outs.iter_mut()) {
                self.extend_channel(c, range.clone(), out);
            }
            return;
        };
        let (ch, n) = (*channels, range.len());
        let data = &data[range.start * ch..range.end * ch];
        let mut dst: Vec<&mut [f32]> = outs
            .iter_mut()
            .map(|o| {
                let b = o.len();
                o.resize(b + n, 0.0);
                &mut o[b..]
            })
            .collect();
        if data.len() < PAR_SAMPLES || rayon::current_num_threads() < 2 {
            transpose(data, ch, idx, &mut dst);
            return;
        }
        // A large block on every core, each taking a run of whole tiles of frames into
        // its part of every channel.
        use rayon::prelude::*;
        let parts = rayon::current_num_threads().min(n.div_ceil(TILE));
        let per = n.div_ceil(parts).div_ceil(TILE) * TILE;
        let mut split: Vec<Vec<&mut [f32]>> = (0..n.div_ceil(per))
            .map(|_| Vec::with_capacity(dst.len()))
            .collect();
        for d in dst {
            for (p, part) in d.chunks_mut(per).enumerate() {
                split[p].push(part);
            }
        }
        split.into_par_iter().enumerate().for_each(|(p, mut d)| {
            let f0 = p * per;
            let f1 = (f0 + per).min(n);
            transpose(&data[f0 * ch..f1 * ch], ch, idx, &mut d);
        });
    }

    /// Append samples `range` of channel `c` to `out`.
    pub fn extend_channel(&self, c: usize, range: Range<usize>, out: &mut Vec<f32>) {
        match self {
            Block::Interleaved { data, channels } => {
                out.extend(
                    data[range.start * channels..range.end * channels]
                        .iter()
                        .skip(c)
                        .step_by(*channels),
                );
            }
            Block::ChannelsFirst { data, channels } => {
                let n = data.len() / channels;
                out.extend_from_slice(&data[c * n + range.start..c * n + range.end]);
            }
            Block::Planar(p) => out.extend_from_slice(&p[c][range]),
        }
    }
}

/// Which input channels feed which microphone: HARK's ChannelSelector (`input_channels`,
/// applied first) and TF_CHANNEL_SELECTION (`tf_channels`: microphones of the transfer
/// functions kept; applied to the input too when, after the first step, it has the
/// transfer functions' full channel count).
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct ChannelMap {
    /// Input channels kept, in order (empty = all).
    pub input_channels: Vec<usize>,
    /// Transfer-function channels kept (empty = all).
    pub tf_channels: Vec<usize>,
    /// Microphones of the transfer functions before `tf_channels`.
    pub full_mics: usize,
    /// Microphones after `tf_channels` (what the engine computes with).
    pub mics: usize,
    /// A capture device's layout from the array file (an ODAS configuration), used when
    /// `input_channels` is empty: see [`RawMapping`].
    #[serde(default)]
    pub raw: Option<RawMapping>,
    /// Input channels whose samples are negated as they arrive (a microphone wired or
    /// converted with its polarity inverted); each must feed a microphone.
    #[serde(default)]
    pub inverted: Vec<usize>,
}

/// A capture device's channel layout, as an ODAS configuration gives it (`raw.nChannels`
/// and `mapping.map`): an input of `channels` channels (the device's own, e.g. the 6 of a
/// ReSpeaker USB array) is reduced to the microphones `map` (0-based input channels, in
/// the array file's microphone order); an input that already holds exactly the
/// microphones, in that order, is taken as it is.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMapping {
    /// Channels the device delivers.
    pub channels: usize,
    /// The input channel of each microphone, 0-based.
    pub map: Vec<usize>,
}

impl RawMapping {
    /// Check the layout against an array of `mics` microphones: one map entry per
    /// microphone, each a channel the device has, none twice.
    pub fn validate(&self, mics: usize) -> Result<()> {
        let bad = |m: String| Err(Error::Config(format!("device channel map: {m}")));
        if self.map.len() != mics {
            return bad(format!(
                "it maps {} channels but the array has {mics} microphones",
                self.map.len()
            ));
        }
        if let Some(&c) = self.map.iter().find(|&&c| c >= self.channels) {
            return bad(format!(
                "channel {c} (0-based) does not exist on a {}-channel device",
                self.channels
            ));
        }
        if let Some((c, first, again)) = repeated(&self.map) {
            return bad(format!(
                "channel {c} feeds microphones {first} and {again} (each channel one microphone)"
            ));
        }
        Ok(())
    }
}

impl ChannelMap {
    /// Every input channel is a microphone, in order.
    pub fn identity(mics: usize) -> Self {
        ChannelMap {
            input_channels: Vec::new(),
            tf_channels: Vec::new(),
            full_mics: mics,
            mics,
            raw: None,
            inverted: Vec::new(),
        }
    }

    /// The microphones (positions in `idx`, as [`resolve`](Self::resolve) gives it) whose
    /// input channel is inverted.
    pub fn inverted_mics(&self, idx: &[usize]) -> Vec<usize> {
        (0..idx.len())
            .filter(|&m| self.inverted.contains(&idx[m]))
            .collect()
    }

    /// Negate the inverted microphones' samples in `mics` (one channel per microphone, in
    /// the order of `idx`).
    pub fn invert(&self, idx: &[usize], mics: &mut [Vec<f32>]) {
        self.invert_last(idx, mics, usize::MAX);
    }

    /// [`invert`](Self::invert) on the last `n` samples of each channel only (those just
    /// appended to a stream's buffers).
    pub fn invert_last(&self, idx: &[usize], mics: &mut [Vec<f32>], n: usize) {
        for m in self.inverted_mics(idx) {
            let from = mics[m].len().saturating_sub(n);
            mics[m][from..].iter_mut().for_each(|v| *v = -*v);
        }
    }

    /// For an input of `n` channels: the input channel of each microphone, or an error
    /// saying what does not fit.
    pub fn resolve(&self, n: usize) -> Result<Vec<usize>> {
        let mut idx: Vec<usize> = if self.input_channels.is_empty() {
            match &self.raw {
                Some(r) if n == r.channels => r.map.clone(),
                // The microphones themselves, all of them or the TF selection's.
                Some(r)
                    if n != r.map.len() && (self.tf_channels.is_empty() || n != self.tf_channels.len()) =>
                {
                    let selected = match self.tf_channels.len() {
                        0 => String::new(),
                        k => format!(", or the {k} that --channels selects"),
                    };
                    return Err(Error::Mismatch(format!(
                        "has {n} channels; the array file maps {} of a {}-channel device's channels to its microphones \
                         (mapping.map), so give the device's {} channels, or {} holding the microphones in the file's order{selected} \
                         (or pick them: --input-channels, input_channels=[...] in Python)",
                        r.map.len(),
                        r.channels,
                        r.channels,
                        r.map.len()
                    )));
                }
                _ => (0..n).collect(),
            }
        } else {
            if let Some(&c) = self.input_channels.iter().find(|&&c| c >= n) {
                return Err(Error::Mismatch(format!(
                    "input channel {c} does not exist: the audio has {n} channels (0-based: 0..={})",
                    n.saturating_sub(1)
                )));
            }
            // One channel feeding two microphones makes every correlation matrix singular.
            if let Some((c, first, again)) = repeated(&self.input_channels) {
                return Err(Error::Mismatch(format!(
                    "input channel {c} is selected twice (positions {first} and {again} of the input-channel list)"
                )));
            }
            self.input_channels.clone()
        };
        // What the input gives: its channels, or those --input-channels picks from them.
        let gives = |k: usize| {
            if self.input_channels.is_empty() {
                format!("has {k} channels")
            } else {
                format!("has {n} channels, of which --input-channels (input_channels=) picks {k}")
            }
        };
        if !self.tf_channels.is_empty() && idx.len() != self.tf_channels.len() {
            if idx.len() != self.full_mics {
                return Err(Error::Mismatch(format!(
                    "{}; --channels selects {} of the transfer functions' {} microphones, so it takes an input of {} (pick the input's channels: --input-channels, input_channels=[...] in Python)",
                    gives(idx.len()),
                    self.tf_channels.len(),
                    self.full_mics,
                    self.full_mics
                )));
            }
            idx = self.tf_channels.iter().map(|&c| idx[c]).collect();
        }
        if idx.len() != self.mics {
            return Err(Error::Mismatch(format!(
                "{}, but the transfer functions have {} microphones (pick {} input channels: --input-channels, input_channels=[...] in Python)",
                gives(idx.len()),
                self.mics,
                self.mics
            )));
        }
        if let Some(&c) = self.inverted.iter().find(|c| !idx.contains(c)) {
            return Err(Error::Mismatch(format!(
                "input channel {c} is to be inverted, but it feeds no microphone (the microphones' input channels, 0-based: {})",
                idx.iter().map(|c| c.to_string()).collect::<Vec<_>>().join(", ")
            )));
        }
        Ok(idx)
    }
}

/// The first index of `indices` that repeats an earlier one: (index, its first position,
/// the repeat's position).
pub fn repeated(indices: &[usize]) -> Option<(usize, usize, usize)> {
    indices.iter().enumerate().find_map(|(k, c)| {
        indices[..k]
            .iter()
            .position(|x| x == c)
            .map(|first| (*c, first, k))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_range_of_any_layout_is_the_same_interleaved_piece() {
        let planar = vec![vec![1.0, 2.0, 3.0, 4.0], vec![10.0, 20.0, 30.0, 40.0]];
        let inter = [1.0, 10.0, 2.0, 20.0, 3.0, 30.0, 4.0, 40.0];
        let first = [1.0, 2.0, 3.0, 4.0, 10.0, 20.0, 30.0, 40.0];
        for b in [
            Block::Planar(&planar),
            Block::Interleaved {
                data: &inter,
                channels: 2,
            },
            Block::ChannelsFirst {
                data: &first,
                channels: 2,
            },
        ] {
            let mut scratch = Vec::new();
            let piece = b.range(1..3, &mut scratch);
            assert_eq!(piece.samples().unwrap(), 2);
            let mut got = Vec::new();
            piece.append_interleaved(&mut got).unwrap();
            assert_eq!(got, [2.0, 20.0, 3.0, 30.0]);
        }
    }

    #[test]
    fn layouts_give_the_same_channels() {
        let planar = vec![vec![1.0, 2.0, 3.0], vec![10.0, 20.0, 30.0]];
        let inter = [1.0, 10.0, 2.0, 20.0, 3.0, 30.0];
        let first = [1.0, 2.0, 3.0, 10.0, 20.0, 30.0];
        for b in [
            Block::Planar(&planar),
            Block::Interleaved {
                data: &inter,
                channels: 2,
            },
            Block::ChannelsFirst {
                data: &first,
                channels: 2,
            },
        ] {
            assert_eq!((b.channels(), b.samples().unwrap()), (2, 3));
            let mut v = Vec::new();
            b.extend_channel(1, 1..3, &mut v);
            assert_eq!(v, vec![20.0, 30.0]);
            let mut vs = vec![vec![-1.0], Vec::new()];
            b.extend_channels(&[1, 0], 0..3, &mut vs);
            assert_eq!(vs, vec![vec![-1.0, 10.0, 20.0, 30.0], vec![1.0, 2.0, 3.0]]);
        }
        // Tiles: many channels and more frames than a tile, every channel in any order.
        let (ch, n) = (7usize, 3 * TILE + 5);
        let inter: Vec<f32> = (0..ch * n).map(|i| i as f32).collect();
        let b = Block::Interleaved {
            data: &inter,
            channels: ch,
        };
        let idx = [6, 0, 3, 3];
        let mut outs = vec![Vec::new(); idx.len()];
        b.extend_channels(&idx, 2..n - 1, &mut outs);
        for (o, &c) in outs.iter().zip(&idx) {
            let want: Vec<f32> = (2..n - 1).map(|f| (f * ch + c) as f32).collect();
            assert_eq!(o, &want, "channel {c}");
        }
        assert!(Block::Interleaved {
            data: &inter[..5],
            channels: 2
        }
        .samples()
        .is_err());
        assert!(Block::Planar(&[vec![1.0], vec![]]).samples().is_err());
    }

    /// Blocks above [`PAR_SAMPLES`] are transposed and checked on every core: the same
    /// channels, and the first bad sample, as the serial pass (the part boundaries are
    /// not tile-aligned with the range's start, and the channel count is odd).
    #[test]
    fn large_blocks_are_transposed_and_checked_in_parallel_alike() {
        let (ch, n) = (13usize, PAR_SAMPLES / 13 * 3 + 77);
        let inter: Vec<f32> = (0..ch * n).map(|i| (i % 1_000_003) as f32).collect();
        let b = Block::Interleaved {
            data: &inter,
            channels: ch,
        };
        let idx = [12, 0, 5, 5, 7];
        let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
        let mut outs = vec![vec![-1.0f32; 3]; idx.len()];
        pool.install(|| b.extend_channels(&idx, 5..n - 2, &mut outs));
        for (o, &c) in outs.iter().zip(&idx) {
            assert_eq!(o.len(), 3 + n - 7, "channel {c}");
            assert_eq!(&o[..3], &[-1.0; 3]);
            for (k, f) in (5..n - 2).enumerate() {
                assert_eq!(o[3 + k], inter[f * ch + c], "channel {c} frame {f}");
            }
        }
        let bad = |v: f32| v.is_nan() | (v.abs() > 1e9);
        assert_eq!(pool.install(|| b.find(&idx, bad)), None);
        let mut dirty = inter.clone();
        let at = (n - 10) * ch + 7; // frame n − 10, channel 7
        dirty[at] = f32::NAN;
        dirty[(n - 3) * ch + 12] = f32::INFINITY; // later
        dirty[(n / 2) * ch + 1] = f32::NAN; // channel 1 is not taken
        let d = Block::Interleaved {
            data: &dirty,
            channels: ch,
        };
        assert_eq!(pool.install(|| d.find(&idx, bad)), Some((n - 10, 7)));
        assert_eq!(d.find(&idx, bad), Some((n - 10, 7)));
    }

    #[test]
    fn channel_map_selects_input_then_tf_channels() {
        let m = ChannelMap {
            input_channels: vec![1, 2, 3, 4],
            tf_channels: vec![0, 2],
            full_mics: 4,
            mics: 2,
            raw: None,
            inverted: Vec::new(),
        };
        assert_eq!(m.resolve(5).unwrap(), vec![1, 3]);
        assert!(m.resolve(3).unwrap_err().to_string().contains("input channel 3"));
        let twice = ChannelMap {
            input_channels: vec![1, 2, 1, 4],
            ..m.clone()
        };
        let e = twice.resolve(5).unwrap_err().to_string();
        assert!(
            e.contains("input channel 1 is selected twice (positions 0 and 2"),
            "{e}"
        );
        let m = ChannelMap {
            input_channels: vec![],
            tf_channels: vec![0, 2],
            full_mics: 4,
            mics: 2,
            raw: None,
            inverted: Vec::new(),
        };
        assert_eq!(m.resolve(2).unwrap(), vec![0, 1]);
        assert_eq!(m.resolve(4).unwrap(), vec![0, 2]);
        assert!(m.resolve(3).unwrap_err().to_string().contains("has 3 channels"));
        let e = ChannelMap::identity(8).resolve(4).unwrap_err().to_string();
        assert!(e.contains("4 channels") && e.contains("8 microphones"), "{e}");
    }

    /// An ODAS-style device layout: the device's 6 channels are reduced to the 4
    /// microphones; 4 channels are the microphones already; anything else is named; an
    /// explicit input-channel list wins.
    #[test]
    fn a_device_layout_maps_the_devices_channels_only() {
        let m = ChannelMap {
            raw: Some(RawMapping {
                channels: 6,
                map: vec![1, 2, 3, 4],
            }),
            ..ChannelMap::identity(4)
        };
        assert_eq!(m.resolve(6).unwrap(), vec![1, 2, 3, 4]);
        assert_eq!(m.resolve(4).unwrap(), vec![0, 1, 2, 3]);
        let e = m.resolve(5).unwrap_err().to_string();
        assert!(
            e.contains("has 5 channels") && e.contains("4 of a 6-channel device"),
            "{e}"
        );
        let chosen = ChannelMap {
            input_channels: vec![5, 4, 3, 2],
            ..m.clone()
        };
        assert_eq!(chosen.resolve(6).unwrap(), vec![5, 4, 3, 2]);
        // TF_CHANNEL_SELECTION still applies after the device map.
        let sel = ChannelMap {
            tf_channels: vec![0, 3],
            mics: 2,
            ..m
        };
        assert_eq!(sel.resolve(6).unwrap(), vec![1, 4]);
        // An input of just the selected microphones is taken as it is, as without a map.
        assert_eq!(sel.resolve(2).unwrap(), vec![0, 1]);
        assert_eq!(sel.resolve(4).unwrap(), vec![0, 3]);
        let e = sel.resolve(3).unwrap_err().to_string();
        assert!(e.contains("or the 2 that --channels selects"), "{e}");
    }
}
