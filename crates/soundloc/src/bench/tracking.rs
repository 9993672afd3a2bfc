//! How far the approximate mode ([`crate::subspace::tracking`]) is from the exact path,
//! and how much faster it is: the same simulated scenes of the accuracy study
//! ([`super::accuracy::scene`]: talkers in a room, rotor noise 25 cm from the array) run
//! through both, PERIOD as given, on the CPU in f32.
//!
//! Reported: the dB spectra's difference (RMS, 99th percentile and maximum over every
//! window and direction), the share of windows whose strongest peak is the same grid
//! direction, each path's share of talker-windows within 5°, and each path's compute time.

use super::accuracy::{scene, Condition, StudyArray};
use crate::config::{Algorithm, LocalizeConfig, WindowType};
use crate::demo::localize_scene;
use crate::{backend::DeviceChoice, Result};

/// The figures.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Agreement {
    /// Array of the scenes.
    pub array: StudyArray,
    /// Algorithm.
    pub algorithm: Algorithm,
    /// PERIOD in frames.
    pub period: usize,
    /// Scenes run.
    pub scenes: usize,
    /// Windows compared.
    pub windows: usize,
    /// RMS of the dB spectra's difference over every window and direction.
    pub rms_db: f64,
    /// 99th percentile of |difference|, dB.
    pub p99_db: f64,
    /// Maximum |difference|, dB.
    pub max_db: f64,
    /// Share of windows whose strongest peak is the same direction.
    pub same_top_peak: f64,
    /// Share of talker-windows within 5°: exact path.
    pub hits_exact: f64,
    /// Same, approximate mode.
    pub hits_tracked: f64,
    /// Seconds of the exact path's runs, all scenes (each: free-field TFs, K, plan, engine).
    pub seconds_exact: f64,
    /// Same, approximate mode.
    pub seconds_tracked: f64,
    /// Decomposition stage alone, ms per window: exact path.
    pub decomposition_ms_exact: f64,
    /// Same, approximate mode.
    pub decomposition_ms_tracked: f64,
}

/// The scenes compared: two talkers, each RT60 of the study at SNR 0 dB, seeds from
/// `seed0` (`per_cell` per condition).
pub fn conditions() -> Vec<Condition> {
    [0.0, 0.2, 0.4, 0.6]
        .into_iter()
        .map(|rt60_s| Condition {
            rt60_s,
            talkers: 2,
            snr_db: 0.0,
        })
        .collect()
}

/// Run both paths on the scenes and compare.
pub fn agreement(
    array: StudyArray,
    algorithm: Algorithm,
    period: usize,
    seed0: u64,
    per_cell: usize,
) -> Result<Agreement> {
    let mut diffs: Vec<f64> = Vec::new();
    let (mut windows, mut same, mut scenes) = (0usize, 0usize, 0usize);
    let (mut hits_e, mut hits_t, mut pairs) = (0.0, 0.0, 0usize);
    let (mut sec_e, mut sec_t, mut dec_e, mut dec_t) = (0.0, 0.0, 0.0, 0.0);
    for (ci, c) in conditions().into_iter().enumerate() {
        for s in 0..per_cell as u64 {
            let sc = scene(array, c, seed0 + ci as u64 * 1000 + s)?;
            let audio = sc.render();
            let base = LocalizeConfig {
                algorithm,
                period,
                window_type: WindowType::Past,
                max_peaks: c.talkers as i64,
                ..LocalizeConfig::default()
            };
            let tracked_cfg = LocalizeConfig {
                subspace_tracking: true,
                ..base.clone()
            };
            let t = std::time::Instant::now();
            let exact = localize_scene::<f32>(&sc, &audio, &base, DeviceChoice::Cpu)?;
            sec_e += t.elapsed().as_secs_f64();
            let t = std::time::Instant::now();
            let tracked = localize_scene::<f32>(&sc, &audio, &tracked_cfg, DeviceChoice::Cpu)?;
            sec_t += t.elapsed().as_secs_f64();
            dec_e += exact.stage_times.decomposition_ms;
            dec_t += tracked.stage_times.decomposition_ms;
            let (Some(se), Some(st)) = (&exact.spectrum, &tracked.spectrum) else {
                return Err(crate::Error::Config("the scenes' spectra were not kept".into()));
            };
            diffs.extend(se.db.iter().zip(&st.db).map(|(a, b)| (a - b).abs() as f64));
            for (a, b) in exact.results.iter().zip(&tracked.results) {
                windows += 1;
                let top = |r: &crate::LocalizationResult| r.sources.first().map(|s| s.grid_index);
                same += (top(a) == top(b)) as usize;
            }
            let (ee, et) = (sc.score(&exact.results, 5.0), sc.score(&tracked.results, 5.0));
            let n = ee.windows * c.talkers;
            hits_e += ee.hit_rate * n as f64;
            hits_t += et.hit_rate * n as f64;
            pairs += n;
            scenes += 1;
        }
    }
    diffs.sort_by(f64::total_cmp);
    let q = |p: f64| diffs[((diffs.len() - 1) as f64 * p).round() as usize];
    let rms = (diffs.iter().map(|d| d * d).sum::<f64>() / diffs.len() as f64).sqrt();
    Ok(Agreement {
        array,
        algorithm,
        period,
        scenes,
        windows,
        rms_db: rms,
        p99_db: q(0.99),
        max_db: q(1.0),
        same_top_peak: same as f64 / windows.max(1) as f64,
        hits_exact: hits_e / pairs.max(1) as f64,
        hits_tracked: hits_t / pairs.max(1) as f64,
        seconds_exact: sec_e,
        seconds_tracked: sec_t,
        decomposition_ms_exact: dec_e / windows.max(1) as f64,
        decomposition_ms_tracked: dec_t / windows.max(1) as f64,
    })
}
