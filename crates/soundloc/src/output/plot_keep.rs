//! What a spectrum plot ([`super::plot`]) keeps of a run, in bounded memory: a live
//! session of any length can be plotted at its end.
//!
//! Rows (one per result: its time and dB spectrum) and results' peaks arrive as they come,
//! in the same order, each sequence at its own pace. Both are kept in **groups** of `g`
//! consecutive results (g = 1 at first): a group's spectrum is the elementwise maximum of
//! its rows, its time the first row's, its peaks the union of its results' peaks (one per
//! track id and 0.1° of azimuth, the strongest; at most [`MAX_GROUP_PEAKS`] of them, the
//! strongest). When a new group would make more than
//! `max_groups`, neighbouring groups merge pairwise and g doubles. Group k always holds the
//! results k·g … k·g + g − 1 of its sequence, so rows and peaks stay aligned however they
//! arrive.
//!
//! The plot bins its time axis into at most its width in pixels of groups of consecutive
//! results by the same maximum ([`super::plot`]), so with `max_groups` at least twice that
//! width the picture is the whole run's up to one pixel column in where a group starts.

use super::plot::SpectrumPlot;
use crate::engine::SpectrumTable;
use crate::result::LocalizationResult;

/// Memory the spectrum groups may take, bytes (f32 per direction and group).
pub const MAX_SPECTRUM_BYTES: usize = 32 << 20;
/// Fewest groups kept before merging, whatever the grid: several times the plot's width.
pub const MIN_GROUPS: usize = 4096;
/// Most groups kept before merging (small grids): 14 per pixel column of the picture.
pub const MAX_GROUPS: usize = 16384;
/// Most peaks a group keeps (the strongest).
pub const MAX_GROUP_PEAKS: usize = 16;

/// Peaks of one group: (azimuth °, power dB, track id).
type Peaks = Vec<(f64, f64, Option<i64>)>;

/// A run's plot data, decimated by maxima to stay within a bound (see the module docs).
#[derive(Debug, Clone)]
pub struct PlotKeep {
    num_dirs: usize,
    max_groups: usize,
    /// Results per complete group (a power of two).
    group: usize,
    times_s: Vec<f64>,
    db: Vec<f32>,
    /// Rows in the last spectrum group.
    rows_in_last: usize,
    peaks: Vec<Peaks>,
    /// Results in the last peaks group.
    results_in_last: usize,
}

impl PlotKeep {
    /// For a grid of `num_dirs` directions: at most [`MAX_SPECTRUM_BYTES`] / (4 ·
    /// `num_dirs`) groups, within [`MIN_GROUPS`] … [`MAX_GROUPS`].
    pub fn new(num_dirs: usize) -> Self {
        let n = (MAX_SPECTRUM_BYTES / (4 * num_dirs.max(1))).clamp(MIN_GROUPS, MAX_GROUPS);
        Self::with_max_groups(num_dirs, n)
    }

    /// With an explicit bound on the groups (rounded up to an even number, at least 2).
    pub fn with_max_groups(num_dirs: usize, max_groups: usize) -> Self {
        PlotKeep {
            num_dirs,
            max_groups: max_groups.max(2).next_multiple_of(2),
            group: 1,
            times_s: Vec::new(),
            db: Vec::new(),
            rows_in_last: 0,
            peaks: Vec::new(),
            results_in_last: 0,
        }
    }

    /// Results per group now (1 until the first merge).
    pub fn group(&self) -> usize {
        self.group
    }

    /// The most groups it keeps.
    pub fn max_groups(&self) -> usize {
        self.max_groups
    }

    /// Groups kept now (spectrum rows).
    pub fn len(&self) -> usize {
        self.times_s.len()
    }

    /// Whether no spectrum row has been kept.
    pub fn is_empty(&self) -> bool {
        self.times_s.is_empty()
    }

    /// Takes the next spectrum rows.
    pub fn add_rows(&mut self, t: &SpectrumTable) {
        let d = self.num_dirs;
        for (i, &time) in t.times_s.iter().enumerate() {
            let row = &t.db[i * d..(i + 1) * d];
            if self.rows_in_last > 0 && self.rows_in_last < self.group {
                let n = self.db.len();
                self.db[n - d..]
                    .iter_mut()
                    .zip(row)
                    .for_each(|(a, &b)| *a = a.max(b));
                self.rows_in_last += 1;
                continue;
            }
            if self.times_s.len() == self.max_groups {
                self.merge();
            }
            if self.times_s.is_empty() {
                // The whole bound at once: growing by doubling would pass it.
                self.times_s.reserve_exact(self.max_groups);
                self.db.reserve_exact(self.max_groups * d);
            }
            self.times_s.push(time);
            self.db.extend_from_slice(row);
            self.rows_in_last = 1;
        }
    }

    /// Takes the next results' peaks.
    pub fn add_results(&mut self, results: &[LocalizationResult]) {
        for r in results {
            let new: Peaks = r
                .sources
                .iter()
                .map(|s| (s.azimuth_deg, s.power_db, s.id))
                .collect();
            if self.results_in_last > 0 && self.results_in_last < self.group {
                if let Some(last) = self.peaks.last_mut() {
                    union(last, new);
                }
                self.results_in_last += 1;
                continue;
            }
            if self.peaks.len() == self.max_groups {
                self.merge();
            }
            if self.peaks.is_empty() {
                self.peaks.reserve_exact(self.max_groups);
            }
            self.peaks.push(new);
            self.results_in_last = 1;
        }
    }

    /// Merges neighbouring groups pairwise and doubles the group size. Called by the
    /// sequence that reached the bound first, with its last group complete; the other
    /// sequence is at or before the same result, so its groups merge the same way.
    fn merge(&mut self) {
        let d = self.num_dirs;
        let g = self.group;
        // In place (group k takes groups 2k and 2k + 1): the buffers never grow past the
        // bound, and no copy of them is made.
        let rows = self.times_s.len();
        for k in 0..rows.div_ceil(2) {
            self.times_s[k] = self.times_s[2 * k];
            for j in 0..d {
                let a = self.db[2 * k * d + j];
                let b = self.db.get((2 * k + 1) * d + j).copied().unwrap_or(a);
                self.db[k * d + j] = a.max(b);
            }
        }
        self.times_s.truncate(rows.div_ceil(2));
        self.db.truncate(rows.div_ceil(2) * d);
        // The last group's fill in the new size: a complete pair, or one group alone.
        if rows.is_multiple_of(2) && rows > 0 {
            self.rows_in_last += g;
        }
        let n = self.peaks.len();
        for k in 0..n.div_ceil(2) {
            let mut a = std::mem::take(&mut self.peaks[2 * k]);
            if let Some(b) = self.peaks.get_mut(2 * k + 1) {
                union(&mut a, std::mem::take(b));
            }
            self.peaks[k] = a;
        }
        self.peaks.truncate(n.div_ceil(2));
        if n.is_multiple_of(2) && n > 0 {
            self.results_in_last += g;
        }
        self.group = 2 * g;
    }

    /// The plot of what was kept.
    pub fn plot(self, azimuth_deg: Vec<f64>, elevation_deg: Vec<f64>, title: String) -> SpectrumPlot {
        SpectrumPlot {
            times_s: self.times_s,
            azimuth_deg,
            elevation_deg,
            db: self.db,
            peak_ids: self
                .peaks
                .iter()
                .map(|g| g.iter().map(|p| p.2).collect())
                .collect(),
            peaks: self
                .peaks
                .into_iter()
                .map(|g| g.into_iter().map(|p| (p.0, p.1)).collect())
                .collect(),
            truth_azimuths_deg: Vec::new(),
            title,
        }
    }
}

/// Adds `new` to `acc`: one peak per track id and 0.1° of azimuth, the strongest; then
/// the [`MAX_GROUP_PEAKS`] strongest (ties: the earlier).
fn union(acc: &mut Peaks, new: Peaks) {
    let key = |p: &(f64, f64, Option<i64>)| ((p.0 * 10.0).round() as i64, p.2);
    for p in new {
        match acc.iter_mut().find(|q| key(q) == key(&p)) {
            Some(q) if p.1 > q.1 => *q = p,
            Some(_) => {}
            None => acc.push(p),
        }
    }
    if acc.len() > MAX_GROUP_PEAKS {
        acc.sort_by(|a, b| b.1.total_cmp(&a.1));
        acc.truncate(MAX_GROUP_PEAKS);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::result::Source;
    use rand::{Rng, SeedableRng};

    fn table(times: &[f64], db: &[f32], d: usize) -> SpectrumTable {
        SpectrumTable {
            frames: (0..times.len()).collect(),
            times_s: times.to_vec(),
            num_dirs: d,
            db: db.to_vec(),
            num_bins: 0,
            bin_weight: Vec::new(),
        }
    }

    fn result(i: usize, az: f64, id: Option<i64>) -> LocalizationResult {
        LocalizationResult {
            num_active: None,
            frame: i,
            time_s: i as f64 * 0.01,
            sources: vec![Source {
                id,
                grid_index: 0,
                azimuth_deg: az,
                elevation_deg: 0.0,
                x: 0.0,
                y: 0.0,
                z: 0.0,
                power_db: i as f64,
                held: false,
            }],
        }
    }

    /// Rows and results arriving in chunks of their own sizes, merged as they come, equal
    /// the whole run grouped at the final group size: each group's maximum, first time and
    /// peak union; within the bound; aligned.
    #[test]
    fn merged_groups_equal_the_whole_run_grouped() {
        let d = 3;
        let mut rng = rand::rngs::StdRng::seed_from_u64(4);
        for (n, max_groups) in [
            (5usize, 8usize),
            (8, 8),
            (9, 8),
            (1000, 6),
            (1237, 10),
            (4099, 64),
        ] {
            let times: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
            let db: Vec<f32> = (0..n * d).map(|_| rng.gen_range(0.0..20.0)).collect();
            let results: Vec<LocalizationResult> = (0..n)
                .map(|i| result(i, [10.0, -40.0, 10.0, 95.5][i % 4], Some((i / 300) as i64)))
                .collect();
            let mut k = PlotKeep::with_max_groups(d, max_groups);
            let (mut r, mut p) = (0, 0);
            while r < n || p < n {
                if r < n && (p >= n || rng.gen_bool(0.5)) {
                    let m = rng.gen_range(1..=7).min(n - r);
                    k.add_rows(&table(&times[r..r + m], &db[r * d..(r + m) * d], d));
                    r += m;
                } else {
                    let m = rng.gen_range(1..=7).min(n - p);
                    k.add_results(&results[p..p + m]);
                    p += m;
                }
            }
            let g = k.group();
            assert!(g.is_power_of_two());
            assert!(k.len() <= max_groups.next_multiple_of(2), "{n} {max_groups}");
            assert_eq!(k.len(), n.div_ceil(g), "{n} {max_groups} {g}");
            if n <= max_groups {
                assert_eq!(g, 1);
            }
            let plot = k.plot(vec![0.0; d], Vec::new(), String::new());
            assert_eq!(plot.peaks.len(), plot.times_s.len());
            for (c, chunk) in (0..n).collect::<Vec<_>>().chunks(g).enumerate() {
                assert_eq!(plot.times_s[c], times[chunk[0]]);
                for j in 0..d {
                    let want = chunk.iter().map(|&i| db[i * d + j]).fold(f32::MIN, f32::max);
                    assert_eq!(plot.db[c * d + j], want);
                }
                // The union: one peak per (azimuth, id), the strongest (the latest here).
                let mut want: Vec<(i64, Option<i64>, f64)> = Vec::new();
                for &i in chunk {
                    let s = &results[i].sources[0];
                    let key = ((s.azimuth_deg * 10.0).round() as i64, s.id);
                    match want.iter_mut().find(|w| (w.0, w.1) == key) {
                        Some(w) => w.2 = w.2.max(s.power_db),
                        None => want.push((key.0, key.1, s.power_db)),
                    }
                }
                let mut got: Vec<(i64, Option<i64>, f64)> = plot.peaks[c]
                    .iter()
                    .zip(&plot.peak_ids[c])
                    .map(|(p, id)| ((p.0 * 10.0).round() as i64, *id, p.1))
                    .collect();
                got.sort_by(|a, b| a.partial_cmp(b).unwrap());
                want.sort_by(|a, b| a.partial_cmp(b).unwrap());
                assert_eq!(got, want, "group {c}");
            }
        }
    }

    /// A group keeps its MAX_GROUP_PEAKS strongest peaks: results with peaks at ever new
    /// azimuths keep the memory bounded.
    #[test]
    fn a_group_keeps_its_strongest_peaks() {
        let mut k = PlotKeep::with_max_groups(1, 4);
        let results: Vec<LocalizationResult> = (0..400)
            .map(|i| result(i, i as f64 * 0.7 - 150.0, None))
            .collect();
        k.add_results(&results);
        k.add_rows(&table(&vec![0.0; 400], &vec![0.0; 400], 1));
        assert_eq!((k.len(), k.group()), (4, 128));
        let plot = k.plot(vec![0.0], Vec::new(), String::new());
        for (c, g) in plot.peaks.iter().enumerate() {
            let end = ((c + 1) * 128).min(400);
            let mut want: Vec<f64> = (end.saturating_sub(MAX_GROUP_PEAKS).max(c * 128)..end)
                .map(|i| i as f64)
                .collect();
            let mut got: Vec<f64> = g.iter().map(|p| p.1).collect();
            got.sort_by(f64::total_cmp);
            want.sort_by(f64::total_cmp);
            assert_eq!(got, want, "group {c}");
        }
    }

    /// A long live run's picture: an hour at PERIOD 1 (360 000 results, two peaks each at
    /// random azimuths) through the default bound still shows its spectrum: peaks are
    /// dots, not marks whose white outlines covered four fifths of the picture.
    #[test]
    fn a_long_run_plot_shows_its_spectrum() {
        let d = 72;
        let mut k = PlotKeep::new(d);
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        for c in 0..360 {
            let n = 1000;
            let times: Vec<f64> = (0..n).map(|i| (c * n + i) as f64 * 0.01).collect();
            let db: Vec<f32> = (0..n * d).map(|_| rng.gen_range(15.0..17.0)).collect();
            k.add_rows(&table(&times, &db, d));
            let results: Vec<LocalizationResult> = (0..n)
                .map(|i| {
                    let mut r = result(c * n + i, rng.gen_range(-180.0..180.0), None);
                    r.sources.push(r.sources[0].clone());
                    r.sources[1].azimuth_deg = rng.gen_range(-180.0..180.0);
                    r
                })
                .collect();
            k.add_results(&results);
        }
        assert!(k.len() <= k.max_groups());
        let az: Vec<f64> = (0..d).map(|j| -180.0 + 5.0 * j as f64).collect();
        let dir = std::env::temp_dir().join(format!("soundloc-plot-keep-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("long.png");
        super::super::plot::plot_spectrum(&path, &k.plot(az, Vec::new(), "long".into())).unwrap();
        let decoder = png::Decoder::new(std::fs::File::open(&path).unwrap());
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        let px = &buf[..info.buffer_size()];
        let white = px.chunks(3).filter(|p| p == &[255, 255, 255]).count() as f64 / (px.len() / 3) as f64;
        // The margins, axes and colour bar's surround are white: about a fifth.
        assert!(white < 0.3, "{:.0}% white", 100.0 * white);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The default bound: a grid's spectrum groups stay within MAX_SPECTRUM_BYTES (or
    /// MIN_GROUPS for the largest grids).
    #[test]
    fn the_default_bound_follows_the_grid() {
        assert_eq!(PlotKeep::new(72).max_groups(), MAX_GROUPS);
        assert_eq!(PlotKeep::new(1261).max_groups(), MAX_SPECTRUM_BYTES / (4 * 1261));
        assert_eq!(PlotKeep::new(100_000).max_groups(), MIN_GROUPS);
        let mut k = PlotKeep::new(2522);
        let row = vec![1.0f32; 2522];
        let times = [0.0];
        for _ in 0..3 * k.max_groups() + 5 {
            k.add_rows(&table(&times, &row, 2522));
        }
        assert!(k.len() * 2522 * 4 <= MAX_SPECTRUM_BYTES.max(MIN_GROUPS * 2522 * 4));
        assert_eq!(k.group(), 4);
        assert!(k.db.capacity() <= k.max_groups() * 2522);
    }
}
