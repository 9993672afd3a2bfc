//! Plots of the MUSIC spectrum over time: a heat map of power in dB, time (x, seconds)
//! against azimuth (y, degrees, −180..180), with detected peaks as markers, true
//! directions as dashed lines and a colour bar.
//!
//! For a grid with several elevations (a sphere), each azimuth bin of
//! [`AZIMUTH_BIN_DEG`] degrees shows the **maximum over all directions in the bin**
//! (all elevations); a bin that holds no grid direction takes the value of the nearest
//! non-empty bin (circularly), so a 5° ring shows as 5° stripes. When there are more
//! results than about one per horizontal pixel, neighbouring results are merged by
//! maximum. The colour scale (viridis) runs from the smallest to the largest finite dB
//! value.
//!
//! Text uses the embedded DejaVu Sans font (`assets/DejaVuSans.ttf`, Bitstream Vera
//! licence, see `assets/DejaVuSans-LICENSE.txt`); no system font is looked up. The
//! format is SVG when the path ends in `.svg` (any case), PNG otherwise. The file is
//! written atomically.

use super::atomic::AtomicFile;
use super::style;
use crate::{Error, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::OnceLock;

pub use super::style::AZIMUTH_BIN_DEG;

/// Image size in pixels (width, height).
pub const PLOT_SIZE: (u32, u32) = (1200, 600);

const FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";

/// What to draw: a dB spectrum `[result][direction]` and its annotations.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SpectrumPlot {
    /// Time of each result in seconds (one per row of `db`), ascending.
    pub times_s: Vec<f64>,
    /// Azimuth of each grid direction in degrees (one per column of `db`).
    pub azimuth_deg: Vec<f64>,
    /// Elevation of each grid direction in degrees (same length as `azimuth_deg`, or
    /// empty when all are 0).
    pub elevation_deg: Vec<f64>,
    /// Power in dB, row-major: rows = results, columns = directions.
    pub db: Vec<f32>,
    /// Detected peaks per result: (azimuth in degrees, power in dB). Empty, or one list
    /// per result.
    pub peaks: Vec<Vec<(f64, f64)>>,
    /// Track id of each peak (same shape as `peaks`), or empty when untracked. A tracked
    /// peak takes its id's colour ([`style::track_rgb`]).
    pub peak_ids: Vec<Vec<Option<i64>>>,
    /// True source azimuths in degrees, drawn as dashed horizontal lines.
    pub truth_azimuths_deg: Vec<f64>,
    /// Title above the plot.
    pub title: String,
}

/// The heat map after binning: `values[col * bins + bin]`, column `col` spanning
/// `edges[col] .. edges[col + 1]` seconds, bin `b` spanning azimuths
/// −180 + b·Δ .. −180 + (b + 1)·Δ.
#[derive(Debug, Clone, PartialEq)]
struct HeatMap {
    edges: Vec<f64>,
    bins: usize,
    values: Vec<f32>,
    lo: f32,
    hi: f32,
}

use super::style::wrap_azimuth_deg as wrap_az;

fn validate(p: &SpectrumPlot) -> Result<()> {
    let (r, d) = (p.times_s.len(), p.azimuth_deg.len());
    if r == 0 || d == 0 {
        return Err(Error::TooShort(format!(
            "plot: nothing to draw ({r} results, {d} directions)"
        )));
    }
    if !p.elevation_deg.is_empty() && p.elevation_deg.len() != d {
        return Err(Error::Mismatch(format!(
            "plot: {} elevations for {d} azimuths",
            p.elevation_deg.len()
        )));
    }
    if p.db.len() != r * d {
        return Err(Error::Mismatch(format!(
            "plot: spectrum has {} values, expected {r} results × {d} directions = {}",
            p.db.len(),
            r * d
        )));
    }
    if !p.peaks.is_empty() && p.peaks.len() != r {
        return Err(Error::Mismatch(format!(
            "plot: {} peak lists for {r} results",
            p.peaks.len()
        )));
    }
    if !p.peak_ids.is_empty()
        && (p.peak_ids.len() != p.peaks.len()
            || p.peak_ids.iter().zip(&p.peaks).any(|(i, k)| i.len() != k.len()))
    {
        return Err(Error::Mismatch(
            "plot: peak ids must have the shape of the peaks".into(),
        ));
    }
    if p.times_s.iter().any(|t| !t.is_finite()) || p.azimuth_deg.iter().any(|a| !a.is_finite()) {
        return Err(Error::Mismatch("plot: times and azimuths must be finite".into()));
    }
    if p.times_s.windows(2).any(|w| w[1] <= w[0]) {
        return Err(Error::Mismatch(
            "plot: result times must be strictly increasing".into(),
        ));
    }
    Ok(())
}

fn heat_map(p: &SpectrumPlot, max_cols: usize) -> HeatMap {
    let (r, d) = (p.times_s.len(), p.azimuth_deg.len());
    let bins = style::azimuth_bins();
    let bin_of: Vec<usize> = p.azimuth_deg.iter().map(|&a| style::azimuth_bin(a)).collect();
    // Nearest occupied bin for every bin (circular).
    let mut occupied = vec![false; bins];
    bin_of.iter().for_each(|&b| occupied[b] = true);
    let source: Vec<usize> = (0..bins)
        .map(|b| {
            (0..=bins / 2)
                .flat_map(|k| [(b + k) % bins, (b + bins - k) % bins])
                .find(|&c| occupied[c])
                .unwrap_or(b)
        })
        .collect();
    // Time columns: groups of consecutive results.
    let group = r.div_ceil(max_cols.max(1));
    let cols = r.div_ceil(group);
    let dt_last = if r > 1 {
        p.times_s[r - 1] - p.times_s[r - 2]
    } else {
        1.0
    };
    let mut edges: Vec<f64> = (0..cols).map(|c| p.times_s[c * group]).collect();
    edges.push(p.times_s[r - 1] + dt_last);
    let mut values = vec![f32::NEG_INFINITY; cols * bins];
    for row in 0..r {
        let col = row / group;
        let dst = &mut values[col * bins..(col + 1) * bins];
        for (j, &b) in bin_of.iter().enumerate() {
            let v = p.db[row * d + j];
            if v.is_finite() && v > dst[b] {
                dst[b] = v;
            }
        }
    }
    for col in 0..cols {
        let row: Vec<f32> = values[col * bins..(col + 1) * bins].to_vec();
        for b in 0..bins {
            values[col * bins + b] = row[source[b]];
        }
    }
    let (lo, hi) = style::db_range(values.iter().copied());
    HeatMap {
        edges,
        bins,
        values,
        lo,
        hi,
    }
}

fn colour(v: f32, lo: f32, hi: f32) -> RGBColor {
    let [r, g, b] = style::db_rgb(v, lo, hi);
    RGBColor(r, g, b)
}

/// The peak groups (track ids, `None` = untracked) that get a legend entry: all of them
/// when there are at most [`LEGEND_ENTRIES`]; otherwise the untracked peaks and the ids
/// with the most peaks (ties: the lower id), one entry fewer to leave room for "+N
/// shorter sources". `groups` is sorted; so is the answer.
fn legend_groups(marks: &[(Option<i64>, (f64, f64))], groups: &[Option<i64>]) -> Vec<Option<i64>> {
    if groups.len() <= LEGEND_ENTRIES {
        return groups.to_vec();
    }
    let count = |g: &Option<i64>| marks.iter().filter(|m| m.0 == *g).count();
    let mut ranked: Vec<(usize, Option<i64>)> = groups
        .iter()
        .filter(|g| g.is_some())
        .map(|g| (count(g), *g))
        .collect();
    ranked.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut out: Vec<Option<i64>> = groups.iter().filter(|g| g.is_none()).copied().collect();
    let room = LEGEND_ENTRIES - 1 - out.len();
    out.extend(ranked.into_iter().take(room).map(|r| r.1));
    out.sort_unstable();
    out
}

/// Legend entries for peak groups, at most (with "+N shorter sources" as the last).
const LEGEND_ENTRIES: usize = 8;

fn register_font() -> Result<()> {
    static DONE: OnceLock<bool> = OnceLock::new();
    let ok = *DONE.get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(Error::format(
            "assets/DejaVuSans.ttf",
            "the embedded font could not be loaded",
        ))
    }
}

/// The azimuth axis, −180..180 degrees, with ticks every 45°.
struct AzimuthAxis;

impl plotters::coord::ranged1d::Ranged for AzimuthAxis {
    type ValueType = f64;
    type FormatOption = plotters::coord::ranged1d::DefaultFormatting;
    fn range(&self) -> std::ops::Range<f64> {
        -180.0..180.0
    }
    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let f = (value + 180.0) / 360.0;
        limit.0 + (f * (limit.1 - limit.0) as f64).round() as i32
    }
    fn key_points<Hint: plotters::coord::ranged1d::KeyPointHint>(&self, _hint: Hint) -> Vec<f64> {
        (-4..=4).map(|k| k as f64 * 45.0).collect()
    }
}

type DrawResult<E> = std::result::Result<(), DrawingAreaErrorKind<E>>;

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    p: &SpectrumPlot,
    hm: &HeatMap,
) -> DrawResult<DB::ErrorType> {
    root.fill(&WHITE)?;
    let title = if p.title.is_empty() {
        "MUSIC spectrum"
    } else {
        p.title.as_str()
    };
    let root = root.titled(title, (FAMILY, 22))?;
    let (main, bar) = root.split_horizontally(root.dim_in_pixel().0.saturating_sub(130));
    let (t0, t1) = (hm.edges[0], hm.edges[hm.edges.len() - 1]);
    let multi_el = p
        .elevation_deg
        .iter()
        .any(|&e| (e - p.elevation_deg[0]).abs() > 1e-9);
    let y_desc = if multi_el {
        "azimuth (deg), max over elevation"
    } else {
        "azimuth (deg)"
    };

    let mut chart = ChartBuilder::on(&main)
        .margin(10)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(t0..t1, AzimuthAxis)?;
    let int_fmt = |v: &f64| format!("{v:.0}");
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("time (s)")
        .y_desc(y_desc)
        .y_label_formatter(&int_fmt)
        .label_style((FAMILY, 14))
        .axis_desc_style((FAMILY, 16))
        .draw()?;
    let bins = hm.bins;
    let cols = hm.edges.len() - 1;
    // One rectangle per run of equal colour within a column (keeps SVG files small).
    let mut cells = Vec::new();
    for c in 0..cols {
        let mut b = 0;
        while b < bins {
            let col = colour(hm.values[c * bins + b], hm.lo, hm.hi);
            let mut e = b + 1;
            while e < bins && colour(hm.values[c * bins + e], hm.lo, hm.hi) == col {
                e += 1;
            }
            let y0 = -180.0 + b as f64 * AZIMUTH_BIN_DEG;
            let y1 = -180.0 + e as f64 * AZIMUTH_BIN_DEG;
            cells.push(Rectangle::new(
                [(hm.edges[c], y0), (hm.edges[c + 1], y1)],
                col.filled(),
            ));
            b = e;
        }
    }
    chart.draw_series(cells)?;
    let dash = RGBColor(255, 255, 255).stroke_width(2);
    for (k, &az) in p.truth_azimuths_deg.iter().enumerate() {
        let az = wrap_az(az);
        let s = chart.draw_series(DashedLineSeries::new(vec![(t0, az), (t1, az)], 10, 6, dash))?;
        if k == 0 {
            s.label("true direction").legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], RGBColor(120, 120, 120).stroke_width(2))
            });
        }
    }
    let half_dt = |i: usize| {
        if p.times_s.len() > 1 {
            let j = if i + 1 < p.times_s.len() { i } else { i - 1 };
            (p.times_s[j + 1] - p.times_s[j]) / 2.0
        } else {
            (t1 - t0) / 2.0
        }
    };
    // Peaks, coloured by track id (untracked ones red), as in the live view.
    let mut marks: Vec<(Option<i64>, (f64, f64))> = Vec::new();
    for (i, list) in p.peaks.iter().enumerate() {
        let t = p.times_s[i] + half_dt(i);
        for (k, &(az, _)) in list.iter().enumerate() {
            if az.is_finite() {
                let id = p.peak_ids.get(i).and_then(|ids| ids.get(k).copied().flatten());
                marks.push((id, (t, wrap_az(az))));
            }
        }
    }
    let mut groups: Vec<Option<i64>> = marks.iter().map(|m| m.0).collect();
    groups.sort_unstable();
    groups.dedup();
    let listed = legend_groups(&marks, &groups);
    // A long run's peaks, drawn as marks, would cover its spectrum: past four per pixel
    // column on average they are dots without the outline.
    let (radius, outline) = if marks.len() > 4 * PLOT_SIZE.0 as usize {
        (1, false)
    } else {
        (3, true)
    };
    for g in &groups {
        let [r, gr, b] = g.map_or(style::PEAK_RGB, style::track_rgb);
        let c = RGBColor(r, gr, b);
        let pts: Vec<(f64, f64)> = marks.iter().filter(|m| m.0 == *g).map(|m| m.1).collect();
        let s = chart.draw_series(pts.iter().map(|&q| Circle::new(q, radius, c.filled())))?;
        if listed.contains(g) {
            let label = g.map_or("detected peak".to_string(), |id| format!("source {id}"));
            s.label(label)
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, c.filled()));
        }
        if outline {
            let ring = if g.is_some() { BLACK } else { WHITE };
            chart.draw_series(pts.iter().map(|&q| Circle::new(q, 3, ring.stroke_width(1))))?;
        }
    }
    if groups.len() > listed.len() {
        let more = groups.len() - listed.len();
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())?
            .label(format!(
                "+{more} shorter source{}",
                if more == 1 { "" } else { "s" }
            ))
            .legend(|(x, y)| EmptyElement::at((x, y)));
    }
    if !marks.is_empty() || !p.truth_azimuths_deg.is_empty() {
        chart
            .configure_series_labels()
            .label_font((FAMILY, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()?;
    }

    // Colour bar.
    let mut cb = ChartBuilder::on(&bar)
        .margin_top(10)
        .margin_bottom(55)
        .margin_right(10)
        .y_label_area_size(70)
        .build_cartesian_2d(0f64..1f64, hm.lo as f64..hm.hi as f64)?;
    let db_fmt = |v: &f64| {
        if hm.hi - hm.lo >= 5.0 {
            format!("{v:.0}")
        } else {
            format!("{v:.2}")
        }
    };
    cb.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc("power (dB)")
        .y_labels(8)
        .y_label_formatter(&db_fmt)
        .label_style((FAMILY, 14))
        .axis_desc_style((FAMILY, 16))
        .draw()?;
    let steps = 128;
    let (lo, hi) = (hm.lo as f64, hm.hi as f64);
    cb.draw_series((0..steps).map(|i| {
        let a = lo + (hi - lo) * i as f64 / steps as f64;
        let b = lo + (hi - lo) * (i + 1) as f64 / steps as f64;
        Rectangle::new(
            [(0.0, a), (1.0, b)],
            colour(((a + b) / 2.0) as f32, hm.lo, hm.hi).filled(),
        )
    }))?;
    root.present()?;
    Ok(())
}

/// Draw `plot` to `path`: SVG when the path ends in `.svg`, PNG otherwise
/// ([`PLOT_SIZE`] pixels), atomically.
pub fn plot_spectrum(path: impl AsRef<Path>, plot: &SpectrumPlot) -> Result<()> {
    let path = path.as_ref();
    validate(plot)?;
    register_font()?;
    let perr = |e: String| Error::io(path, std::io::Error::other(format!("drawing: {e}")));
    let svg = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    if svg {
        let hm = heat_map(plot, 300);
        let mut text = String::new();
        {
            let root = SVGBackend::with_string(&mut text, PLOT_SIZE).into_drawing_area();
            draw(root, plot, &hm).map_err(|e| perr(e.to_string()))?;
        }
        super::atomic::write_atomically(path, |f| std::io::Write::write_all(f, text.as_bytes()))
    } else {
        let hm = heat_map(plot, PLOT_SIZE.0 as usize);
        // The image encoder picks the format from the extension: give the temporary
        // file a `.png` one.
        let file = AtomicFile::create_with_suffix(path, ".png")?;
        {
            let root = BitMapBackend::new(file.temp_path(), PLOT_SIZE).into_drawing_area();
            draw(root, plot, &hm).map_err(|e| perr(e.to_string()))?;
        }
        file.commit()
    }
}

#[cfg(test)]
mod tests;
