//! A spec resolved against its transfer functions: the analysis, the microphones used,
//! K (from a recording, a correlation file or the caller), the stream's options, and the
//! plan and engine built from them.

use super::{ArraySpec, LocalizerSpec, NoiseSource};
use crate::array::TransferFunctions;
use crate::backend::DeviceChoice;
use crate::config::LocalizeConfig;
use crate::engine::{make_backend, Engine, StreamOptions, TrackingSpec};
use crate::input::ChannelMap;
use crate::noise::policy::InitialNoise;
use crate::noise::NoiseMatrices;
use crate::plan::Plan;
use crate::real::Real;
use crate::{Error, Result};
use std::path::Path;
use std::sync::Arc;

/// What a spec resolves to once its transfer functions are in memory: the analysis, the
/// TFs of the microphones used, a stream's options (K, updates, tracking, channel map)
/// and the notes to show.
pub(crate) struct Prepared {
    pub config: LocalizeConfig,
    pub tf: TransferFunctions,
    pub options: StreamOptions,
    pub notes: Vec<String>,
    /// The file K was read from (a noise recording or correlation file), for messages.
    pub noise_file: Option<std::path::PathBuf>,
}

/// Resolve `spec` against transfer functions of all microphones (before
/// `spec.channels`) and, optionally, K (`noise`, replacing `spec.noise`).
pub(crate) fn prepare(
    spec: &LocalizerSpec,
    tf: TransferFunctions,
    noise: Option<NoiseMatrices>,
) -> Result<Prepared> {
    let full_mics = tf.num_mics;
    let tf = if spec.channels.is_empty() {
        tf
    } else {
        tf.select_channels(&spec.channels)?
    };
    let (analysis, note) = spec.resolved_analysis(tf.num_mics);
    let algorithm = analysis.algorithm;
    let config = LocalizeConfig {
        sample_rate_hz: tf.sample_rate_hz,
        ..analysis
    };
    let channels = spec.channel_map(full_mics)?;
    let mut notes: Vec<String> = note.into_iter().collect();
    notes.extend(zero_bins_note(&tf, config.bin_range()));
    let noise_file = match (&noise, &spec.noise) {
        (None, NoiseSource::Recording { path } | NoiseSource::CorrelationFile { path })
            if algorithm.uses_noise() =>
        {
            Some(path.clone())
        }
        _ => None,
    };
    let initial_noise = match (noise, &spec.noise) {
        _ if !algorithm.uses_noise() => InitialNoise::Given(None),
        (Some(k), _) => InitialNoise::Given(Some(k)),
        (None, NoiseSource::None) => InitialNoise::Given(None),
        (None, NoiseSource::Range { start_s, end_s }) => InitialNoise::Range(*start_s, *end_s),
        (None, NoiseSource::Recording { path }) => InitialNoise::Given(Some(noise_from_recording(
            path,
            &config,
            &channels,
            spec.resample,
        )?)),
        (None, NoiseSource::CorrelationFile { path }) => {
            use crate::formats::noise_cm::{Expected, NoiseCm};
            let expected = Expected {
                num_mics: None,
                nfft: Some(config.nfft),
            };
            let cm = NoiseCm::load(path, expected)?;
            // K of the whole array with --channels picking some of it: their sub-matrices.
            let cm = if cm.num_mics == tf.num_mics {
                cm
            } else if !spec.channels.is_empty() && cm.num_mics == full_mics {
                cm.select_channels(&spec.channels, path)?
            } else {
                let whole = if spec.channels.is_empty() {
                    String::new()
                } else {
                    format!(" (or the array's {full_mics} before the channel selection)")
                };
                return Err(Error::Mismatch(format!(
                    "{}: {m} × {m} matrices, expected {} microphones{whole}",
                    path.display(),
                    tf.num_mics,
                    m = cm.num_mics
                )));
            };
            InitialNoise::Given(Some(cm.to_noise_matrices(config.bin_range())?))
        }
    };
    match &spec.noise {
        NoiseSource::CorrelationFile { path } if algorithm.uses_noise() && !spec.invert_channels.is_empty() => {
            notes.push(format!(
                "the inverted channels are negated in the audio, not in {}: its K must come from audio with the same channels inverted (soundloc noisecm --invert-channels)",
                path.display()
            ))
        }
        _ => {}
    }
    // Online updates without a K to start from: the first windows are not whitened.
    if algorithm.uses_noise() && matches!(initial_noise, InitialNoise::Given(None)) {
        let before = match &spec.noise_update {
            crate::noise::policy::NoiseUpdate::Segments(s) => s
                .iter()
                .map(|&(_, end)| end)
                .min_by(f64::total_cmp)
                .map(|end| format!("until the first noise segment ends ({end} s)")),
            crate::noise::policy::NoiseUpdate::Preceding { frames, gap } => Some(format!(
                "in the first {:.2} s (windows with fewer than {} frames before them)",
                ((frames + gap) * config.hop) as f64 / config.sample_rate_hz as f64,
                frames + gap
            )),
            crate::noise::policy::NoiseUpdate::Fixed => None,
        };
        if let Some(before) = before {
            notes.push(format!(
                "{before} windows are localized with K = I (no whitening), so their powers are on \
                 another scale than later windows' and loud noise shows as peaks there; a noise \
                 source to start from (--noise-range, --noise, --noise-cm) whitens them too"
            ));
        }
    }
    if !algorithm.uses_noise() && spec.noise != NoiseSource::None {
        notes.push(format!("{} ignores the noise matrix", algorithm.name()));
    }
    // Diagonal loading acts on K; without one (or with an algorithm that takes none) it
    // changes nothing.
    if config.diagonal_loading > 0.0
        && (!algorithm.uses_noise()
            || (spec.noise == NoiseSource::None
                && matches!(spec.noise_update, crate::noise::policy::NoiseUpdate::Fixed)))
    {
        notes.push(format!(
            "the diagonal loading ({}) acts on the noise matrix K, and this run has none: it changes nothing",
            config.diagonal_loading
        ));
    }
    // R of fewer frames than microphones has rank below M: its smallest eigenvalues are
    // zeros, not noise, and the noise subspace holds directions the window never saw.
    if config.window < tf.num_mics && !matches!(algorithm, crate::config::Algorithm::SrpPhat) {
        notes.push(format!(
            "warning: a window of {} frames gives R of rank {} at most, below the {} microphones: the \
             subspace methods need more frames than microphones (--window, window= in Python; HARK's 50)",
            config.window, config.window, tf.num_mics
        ));
    }
    let nyquist = config.sample_rate_hz as f64 / 2.0;
    if config.upper_freq_hz > nyquist {
        notes.push(format!(
            "the band's upper edge {} Hz is above the Nyquist frequency ({nyquist} Hz at {} Hz): the band ends there",
            config.upper_freq_hz, config.sample_rate_hz
        ));
    }
    if config.hop > config.nfft {
        notes.push(format!(
            "the hop ({} samples) is longer than the frame ({}): the samples between frames are not analysed",
            config.hop, config.nfft
        ));
    }
    // The frame sizes the CLI and Python choose for free-field TFs at another rate than
    // 16 kHz (HARK's durations), said once so that a user comparing with HARK's sample
    // counts knows.
    let fs = config.sample_rate_hz;
    if matches!(spec.array, ArraySpec::FreeField { .. })
        && fs != 16000
        && (config.nfft, config.hop) == crate::config::frame_sizes_for_rate(fs)
    {
        notes.push(format!(
            "at {fs} Hz the frames are {} samples with a hop of {} (32 ms and 10 ms, as HARK's 512 and \
             160 at 16 kHz; others: --fft-length/--hop, nfft=/hop= in Python)",
            config.nfft, config.hop
        ));
    }
    // Free-field TFs only: measured ones carry the body's scattering, which breaks the
    // mirror symmetry.
    if matches!(spec.array, ArraySpec::FreeField { .. }) && tf.mic_positions.len() == tf.num_mics {
        let reportable: Vec<[f64; 3]> = (0..tf.grid.len())
            .filter(|&i| {
                crate::peaks::azimuth_in_range(tf.grid.azimuth_deg(i), config.min_deg, config.max_deg)
            })
            .map(|i| tf.grid.points[i])
            .collect();
        notes.extend(crate::array::geometry::mirror_note(
            &tf.mic_positions,
            &reportable,
        ));
    }
    // A tracker threshold that no peak of a normalised spectrum can reach would drop
    // every result without a word (HARK thresholds are tuned on SEVD's scale).
    if let (Some(t), Some(ceiling)) = (&spec.tracking, crate::plan::normalized_power_ceiling_db(&config)?) {
        if t.tracker.thresh_db > ceiling {
            return Err(Error::Config(format!(
                "tracker threshold {} dB: with every bin normalised (NormMUSIC{}) the power never \
                 exceeds {ceiling:.1} dB here, so no source would pass; lower the threshold, or name \
                 the algorithm (e.g. --algorithm sevd) for HARK's scale",
                t.tracker.thresh_db,
                if spec.algorithm.is_none() && !spec.noise_given() {
                    ", the room default"
                } else {
                    ""
                }
            )));
        }
    }
    let room_default = spec.algorithm.is_none() && !spec.noise_given();
    // The tracker gate needs each window's source count; SRP-PHAT and the approximate
    // mode estimate none, so a gate asked for would pass every peak without a word.
    let uncounted = if config.subspace_tracking {
        "the approximate mode (--subspace-tracking, subspace_tracking=True)"
    } else {
        config.algorithm.name()
    };
    let active_only = spec.tracking.as_ref().map(|t| t.active_only);
    if active_only == Some(Some(true)) && !config.counts_sources() {
        return Err(Error::Config(format!(
            "the tracker's active-only gate feeds each window's num_active strongest peaks, \
             but {uncounted} estimates no source count (num_active): leave the gate off and \
             set the tracker threshold above the noise-only windows' power"
        )));
    }
    if active_only == Some(None) && room_default && !config.counts_sources() {
        notes.push(format!(
            "the tracker sees every peak: {uncounted} estimates no source count (num_active), \
             so the room default's gate (silence starts no tracks) is off and noise peaks can \
             start tracks"
        ));
    }
    // Outside the room default the tracker takes every peak (HARK's rule); with THRESH at
    // its default 0 dB every noise peak then starts a track (15 ids for one talker in a
    // user's sweep with a noise range), so say what to set.
    if let Some(t) = spec.tracking.as_ref() {
        if t.active_only.is_none() && !room_default && t.tracker.thresh_db == 0.0 {
            let gate = if config.counts_sources() {
                ", or turn on the gate that feeds each window's num_active strongest peaks \
                 (--active-only, track_active_only=True in Python)"
            } else {
                ""
            };
            let confirmed = spec.algorithm.is_none() && t.tracker.confirm_frames != Some(0);
            let which = if confirmed {
                "noise peaks that stay over the confirmation (--confirm) start tracks too"
            } else {
                "noise peaks start tracks too"
            };
            notes.push(format!(
                "the tracker takes every peak at THRESH 0 dB, as HARK's does, so {which}: set the \
                 tracker threshold (--thresh, tracker_thresh_db=) above the power of the windows \
                 without a talker{gate}"
            ));
        }
    }
    // A new source's confirmation (not in HARK): over one window length in the defaults
    // (no algorithm named), off for a named algorithm.
    let confirm = if spec.algorithm.is_none() {
        config.window
    } else {
        0
    };
    let tracking = spec.tracking.map(|t| TrackingSpec {
        active_only: Some(t.active_only.unwrap_or(room_default && config.counts_sources())),
        tracker: crate::tracking::TrackerConfig {
            confirm_frames: Some(t.tracker.confirm_frames.unwrap_or(confirm)),
            ..t.tracker
        },
        ..t
    });
    let options = StreamOptions {
        initial_noise,
        noise_update: spec.noise_update.clone(),
        tracking,
        channels,
        want_spectrum: spec.spectrum,
    };
    Ok(Prepared {
        config,
        tf,
        options,
        notes,
        noise_file,
    })
}

/// A warning when some used bins hold transfer functions of zero for every direction and
/// microphone (a TF file made for a narrower band, zero-filled by `write_tf`): they add
/// nothing to the spectrum, and the band the user asked for is not the band analysed.
fn zero_bins_note(tf: &TransferFunctions, used: std::ops::Range<usize>) -> Option<String> {
    let have = tf.bins();
    let zero: Vec<usize> = used
        .clone()
        .filter(|b| have.contains(b))
        .filter(|&b| {
            (0..tf.grid.len()).all(|d| (0..tf.num_mics).all(|m| tf.get(d, m, b) == Default::default()))
        })
        .collect();
    let (&lo, &hi) = (zero.first()?, zero.last()?);
    Some(format!(
        "warning: the transfer functions are zero for every direction in {} of the {} used bins \
         (between {:.0} and {:.0} Hz): those bins add nothing to the spectrum; narrow the band to \
         the TFs' (--freq-range, freq_range=) or give TFs for it",
        zero.len(),
        used.len(),
        tf.bin_hz(lo),
        tf.bin_hz(hi)
    ))
}

pub(crate) fn engine<T: Real>(
    config: &LocalizeConfig,
    tf: &TransferFunctions,
    spec: &LocalizerSpec,
    options: StreamOptions,
    noise_file: Option<&Path>,
) -> Result<Engine<T>> {
    let device = spec.device;
    let k = match &options.initial_noise {
        InitialNoise::Given(k) => k.as_ref(),
        InitialNoise::Range(..) => None,
    };
    let plan = Arc::new(plan_for::<T>(config, tf, k, noise_file)?);
    tracing::debug!(
        "plan ready: {} bins, {} directions",
        plan.num_bins(),
        plan.num_dirs
    );
    // Compiled GPU kernels are kept where the prepared TFs are (none with the cache off).
    let backend = make_backend(plan.clone(), device, spec.tf_cache.dir().as_deref())?;
    tracing::debug!("backend ready: {}", backend.device_name());
    let mut e = Engine::new(plan, backend, options)?;
    e.set_cpu_fallback(device == DeviceChoice::Auto);
    Ok(e)
}

/// The plan for `config`, `tf` and K `k`; where K was read from `noise_file` (a noise
/// recording or correlation file), an error with K names that file.
pub(crate) fn plan_for<T: Real>(
    config: &LocalizeConfig,
    tf: &TransferFunctions,
    k: Option<&NoiseMatrices>,
    noise_file: Option<&Path>,
) -> Result<Plan<T>> {
    Plan::<T>::new(config, tf, k).map_err(|e| match (e, noise_file) {
        (
            Error::Numerical {
                stage: "noise",
                message,
            },
            Some(path),
        ) if k.is_some() => Error::Numerical {
            stage: "noise",
            message: format!("{}: {message}", path.display()),
        },
        (e, _) => e,
    })
}

/// A plan error about the transfer functions (a zero or non-finite direction) names the
/// file they came from, where `spec` read them from one.
pub(crate) fn name_tf_file(spec: &LocalizerSpec, e: Error) -> Error {
    match (e, &spec.array) {
        (
            Error::Numerical {
                stage: "plan",
                message,
            },
            ArraySpec::TransferFunctions { path },
        ) => Error::Numerical {
            stage: "plan",
            message: format!("{}: {message}", path.display()),
        },
        (e, _) => e,
    }
}

/// K from a noise recording, through the input's channel map.
fn noise_from_recording(
    path: &Path,
    config: &LocalizeConfig,
    channels: &ChannelMap,
    resample: bool,
) -> Result<NoiseMatrices> {
    let ctx = |e: Error| Error::Mismatch(format!("{}: {e}", path.display()));
    let mut audio = crate::audio::read_audio(path)?;
    if resample && audio.sample_rate_hz != config.sample_rate_hz {
        audio = crate::audio::resample::resample_audio(&audio, config.sample_rate_hz).map_err(ctx)?;
    }
    let idx = channels.resolve(audio.num_channels()).map_err(ctx)?;
    let mut picked: Vec<Vec<f32>> = idx.iter().map(|&c| audio.channels[c].clone()).collect();
    channels.invert(&idx, &mut picked);
    crate::noise::estimate(config, audio.sample_rate_hz, &picked, None).map_err(ctx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::array::grid::GridSpec;
    use crate::formats::noise_cm::NoiseCm;
    use num_complex::Complex;

    /// A noise-CM file of the whole array with `channels` picking some microphones: K is
    /// their sub-matrices (rows and columns in the selection's order); a file of another
    /// size is refused, naming it.
    #[test]
    fn a_whole_array_noise_file_gives_the_selected_channels_sub_matrices() {
        let geo = crate::array::Geometry::circle(8, 0.0365, 0.0);
        let grid = crate::array::Grid::ring(30.0, 0.0, 1.0);
        let tf = crate::array::freefield::free_field(&geo, &grid, 512, 16000, 0..257, 343.0).unwrap();
        // Hermitian, diagonally dominant: K_k(i, j) = (10 + k) δ_ij + 0.01 (i + j) + 0.01 i (i − j) √−1.
        let k_of = |m: usize| -> NoiseCm {
            let mut data = Vec::new();
            for k in 0..257 {
                for i in 0..m {
                    for j in 0..m {
                        let d = if i == j { 10.0 + k as f64 } else { 0.0 };
                        data.push(Complex::new(
                            d + 0.01 * (i + j) as f64,
                            0.01 * (i as f64 - j as f64),
                        ));
                    }
                }
            }
            NoiseCm::new(m, 512, data).unwrap()
        };
        let dir = crate::audio::tests::temp_dir("prepare-cm");
        let whole = dir.join("K8.zip");
        k_of(8).write_zip(&whole).unwrap();
        let mut spec = LocalizerSpec::free_field(
            geo.mics.clone(),
            GridSpec::Ring {
                step_deg: 30.0,
                elevation_deg: 0.0,
            },
        );
        spec.channels = vec![6, 1, 3];
        spec.noise = NoiseSource::CorrelationFile { path: whole.clone() };
        let p = prepare(&spec, tf.clone(), None).unwrap();
        // (The zip holds f32: compare with the file as read.)
        let read = NoiseCm::load(&whole, Default::default()).unwrap();
        let want = read
            .select_channels(&[6, 1, 3], &whole)
            .unwrap()
            .to_noise_matrices(p.config.bin_range())
            .unwrap();
        assert!(matches!(&p.options.initial_noise, InitialNoise::Given(Some(k)) if *k == want));
        // Entry (0, 1) of the selection is the file's (6, 1).
        let k0 = &want.data[..9];
        assert!((k0[1] - Complex::new(0.07, 0.05)).norm() < 1e-8, "{}", k0[1]);
        // A file of neither size: refused, named.
        let five = dir.join("K5.zip");
        k_of(5).write_zip(&five).unwrap();
        spec.noise = NoiseSource::CorrelationFile { path: five.clone() };
        let e = prepare(&spec, tf, None).err().expect("5 × 5 refused").to_string();
        assert!(
            e.contains(&five.display().to_string())
                && e.contains("5 × 5 matrices, expected 3 microphones (or the array's 8"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A direction whose transfer function is zero in every used bin is refused at
    /// planning, naming the file the transfer functions came from.
    #[test]
    fn a_zero_direction_is_refused_naming_the_tf_file() {
        let geo = crate::array::Geometry::circle(8, 0.0365, 0.0);
        let grid = crate::array::Grid::ring(30.0, 0.0, 1.0);
        let mut tf = crate::array::freefield::free_field(&geo, &grid, 512, 16000, 0..257, 343.0).unwrap();
        let dir = crate::audio::tests::temp_dir("prepare-zero-tf");
        let good = dir.join("good.zip");
        crate::formats::hark_zip::write_tf_zip(&tf, &good).unwrap();
        let mut spec = LocalizerSpec::from_tf(&good);
        spec.device = DeviceChoice::Cpu;
        spec.tf_cache = crate::array::tf_cache::TfCache::Off;
        crate::Localizer::new(&spec).unwrap();
        // Direction 3 silenced in every bin ([dir][mic][bin] layout).
        let block = tf.num_mics * tf.num_bins;
        tf.data[3 * block..4 * block].fill(Complex::new(0.0, 0.0));
        let zero = dir.join("zero.zip");
        crate::formats::hark_zip::write_tf_zip(&tf, &zero).unwrap();
        spec.array = ArraySpec::TransferFunctions { path: zero.clone() };
        let e = crate::Localizer::new(&spec).err().expect("refused").to_string();
        assert!(
            e.contains(&zero.display().to_string()) && e.contains("direction 3 is zero in every used bin"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Used bins whose transfer functions are zero for every direction (a TF file made
    /// for a narrower band, zero-filled) are a warning naming how many and where; none
    /// for complete TFs.
    #[test]
    fn used_bins_without_transfer_functions_are_a_warning() {
        let geo = crate::array::Geometry::circle(8, 0.0365, 0.0);
        let grid = crate::array::Grid::ring(30.0, 0.0, 1.0);
        let mut tf = crate::array::freefield::free_field(&geo, &grid, 512, 16000, 0..257, 343.0).unwrap();
        let mut spec = LocalizerSpec::from_tf(std::path::Path::new("unused.zip"));
        spec.device = DeviceChoice::Cpu;
        let p = prepare(&spec, tf.clone(), None).unwrap();
        assert!(
            !p.notes.iter().any(|n| n.contains("transfer functions are zero")),
            "{:?}",
            p.notes
        );
        // Bins 50.. zero for every direction and microphone ([dir][mic][bin] layout).
        for row in tf.data.chunks_mut(tf.num_bins) {
            row[50..].fill(Complex::new(0.0, 0.0));
        }
        let p = prepare(&spec, tf, None).unwrap();
        // The default band 500–2800 Hz at 16 kHz, N 512: bins 16..89, of which 50..89.
        let n: Vec<&String> = p
            .notes
            .iter()
            .filter(|n| n.contains("transfer functions are zero"))
            .collect();
        assert_eq!(n.len(), 1, "{:?}", p.notes);
        assert!(
            n[0].starts_with("warning: ")
                && n[0].contains("in 39 of the 73 used bins (between 1562 and 2750 Hz)"),
            "{}",
            n[0]
        );
    }
}
