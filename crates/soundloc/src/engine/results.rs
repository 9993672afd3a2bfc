//! From a backend's batch output to results: grid peaks to sources (refined when asked),
//! tracking, spectrum rows.

use super::{Engine, Output, SpectrumTable};
use crate::backend::{BatchOutput, WindowSpec};
use crate::real::Real;
use crate::result::{LocalizationResult, Source};
use crate::Result;

impl<T: Real> Engine<T> {
    /// Turn rows `at ..` of `batch` (the output for `windows`) into results: peaks,
    /// refinement, tracking, spectrum rows.
    pub(super) fn deliver(
        &mut self,
        windows: &[WindowSpec],
        batch: &BatchOutput,
        at: usize,
        out: &mut Output,
    ) -> Result<()> {
        self.windows_run += windows.len();
        self.last_start = windows.last().map(|w| w.start);
        let want = self.options.want_spectrum;
        let refine = self.plan.config.refine;
        let (nd, nb) = (self.plan.num_dirs, self.plan.num_bins());
        let mut released = 0;
        for (i, w) in windows.iter().enumerate() {
            let wi = at + i;
            let peaks = &batch.peaks[wi];
            let mut r = LocalizationResult {
                num_active: batch.source_count.get(wi).map(|&c| c as usize),
                frame: self.report_frame(w.frame),
                time_s: self.frame_time(w.frame),
                sources: peaks
                    .iter()
                    .map(|p| {
                        let mut s = source(&self.plan.grid, p.dir, p.power_db);
                        if refine {
                            let db = &batch.spectrum_db[wi * nd..(wi + 1) * nd];
                            let range = (self.plan.config.min_deg, self.plan.config.max_deg);
                            refine_source(&mut s, &self.plan.grid, &self.plan.peak_table, db, range);
                        }
                        s
                    })
                    .collect(),
            };
            if let Some(t) = &mut self.tracker {
                // Where asked (TrackingSpec::active_only), a window feeds its strongest
                // `num_active` peaks: none when judged noise-only.
                let tracked = match r.num_active {
                    Some(n) if self.track_active_only && n < r.sources.len() => {
                        t.update(&LocalizationResult {
                            sources: r.sources[..n].to_vec(),
                            ..r.clone()
                        })
                    }
                    _ => t.update(&r),
                };
                out.track_starts.extend(t.take_started());
                let untracked = std::mem::replace(&mut r, tracked);
                if let Some(p) = &mut out.peaks {
                    p.push(untracked);
                }
            }
            match &mut self.extender {
                Some(e) => {
                    let done = e.push(r);
                    released += done.len();
                    out.results.extend(done);
                }
                None => out.results.push(r),
            }
        }
        if want {
            let n = windows.len();
            let stamps: Vec<(usize, f64)> = windows
                .iter()
                .map(|w| (self.report_frame(w.frame), self.frame_time(w.frame)))
                .collect();
            // With the interval extender, rows wait with their results (held rows first).
            let t = match self.extender {
                Some(_) => self.held_rows.get_or_insert_with(|| SpectrumTable::empty(nd, nb)),
                None => out.spectrum.get_or_insert_with(|| SpectrumTable::empty(nd, nb)),
            };
            t.db.extend_from_slice(&batch.spectrum_db[at * nd..(at + n) * nd]);
            t.bin_weight
                .extend_from_slice(&batch.bin_weight[at * nb..(at + n) * nb]);
            for (frame, time_s) in stamps {
                t.frames.push(frame);
                t.times_s.push(time_s);
            }
            if let Some(held) = self.held_rows.as_mut().filter(|_| released > 0) {
                out.spectrum
                    .get_or_insert_with(|| SpectrumTable::empty(nd, nb))
                    .append(held.take_front(released));
            }
        }
        Ok(())
    }
}

/// Move `s` (a grid peak) to its refined direction ([`crate::peaks::refine`]); the grid
/// index stays; x/y/z become the refined unit vector. A refined azimuth outside
/// MIN_DEG…MAX_DEG (`range`, a peak at the range's edge leaning beyond it) keeps the grid
/// direction: peaks are reported within the range asked for.
pub fn refine_source(
    s: &mut Source,
    grid: &crate::array::Grid,
    table: &crate::peaks::PeakTable,
    db: &[f32],
    (min_deg, max_deg): (f64, f64),
) {
    let r = crate::peaks::refine::refine(grid, table, db, s.grid_index);
    if !crate::peaks::azimuth_in_range(r.azimuth_deg, min_deg, max_deg) {
        return;
    }
    s.azimuth_deg = r.azimuth_deg;
    s.elevation_deg = r.elevation_deg;
    [s.x, s.y, s.z] = r.unit;
}

/// A result source for grid direction `dir`: unit direction vector, azimuth, elevation.
pub fn source(grid: &crate::array::Grid, dir: usize, power_db: f64) -> Source {
    let [x, y, z] = grid.unit(dir);
    Source {
        id: None,
        grid_index: dir,
        azimuth_deg: grid.azimuth_deg(dir),
        elevation_deg: grid.elevation_deg(dir),
        x,
        y,
        z,
        power_db,
        held: false,
    }
}
