//! Sub-grid refinement of a peak: the reported direction is the maximum of a quadratic
//! fitted to the dB spectrum at the peak and its grid neighbours, so results are not
//! quantised to the grid step.
//!
//! Let u₀ be the peak's unit vector and y_j = dB_j − dB_peak (≤ 0) the neighbours' values.
//!
//! - **Neighbours on the peak's own elevation** (a ring, or a ring of a multi-ring
//!   grid whose neighbours lie left and right): a parabola in azimuth,
//!   y(s) = g·s + h·s²/2 through the neighbours' azimuth offsets s_j (degrees, wrapped),
//!   least squares when there are more than two; the peak moves to s* = −g/h.
//! - **Otherwise** (sphere grids, HARK multi-ring grids): each neighbour is mapped to the
//!   tangent plane at u₀ by the logarithmic map, t_j = θ_j·(its direction in the plane)
//!   with θ_j the angle to u₀, and y(t) = gᵀt + ½ tᵀHt is fitted by least squares (five
//!   unknowns, so at least five neighbours); the peak moves to t* = −H⁻¹g when H is
//!   negative definite, and back onto the sphere with the exponential map
//!   u = cos‖t*‖·u₀ + sin‖t*‖·t*/‖t*‖.
//!
//! The step is limited to 0.6 of the mean neighbour distance (the true maximum of a
//! local peak lies in the grid cell around it); where the fit is degenerate (too few
//! neighbours, a flat or saddle-shaped fit) the grid direction is kept.

use super::PeakTable;
use crate::array::geometry::{cross, dot};
use crate::array::grid::RING_ELEVATION_TOLERANCE_DEG;
use crate::array::Grid;

/// Fraction of the mean neighbour distance the refined direction may move.
pub const MAX_STEP_FRACTION: f64 = 0.6;

/// A refined direction: unit vector, azimuth and elevation in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    /// Unit vector.
    pub unit: [f64; 3],
    /// Azimuth in degrees, atan2(y, x), in (−180, 180].
    pub azimuth_deg: f64,
    /// Elevation in degrees from the x-y plane.
    pub elevation_deg: f64,
}

impl Refined {
    fn from_unit(u: [f64; 3]) -> Refined {
        let n = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
        let u = [u[0] / n, u[1] / n, u[2] / n];
        let mut az = u[1].atan2(u[0]).to_degrees();
        if az <= -180.0 {
            az += 360.0;
        }
        Refined {
            unit: u,
            azimuth_deg: az,
            elevation_deg: u[2].atan2((u[0] * u[0] + u[1] * u[1]).sqrt()).to_degrees(),
        }
    }
}

fn wrap180(a: f64) -> f64 {
    let mut a = a % 360.0;
    if a > 180.0 {
        a -= 360.0;
    } else if a <= -180.0 {
        a += 360.0;
    }
    a
}

/// Refine the peak at direction `dir` of the spectrum `db` (one value per direction).
pub fn refine<V: Copy + Into<f64>>(grid: &Grid, table: &PeakTable, db: &[V], dir: usize) -> Refined {
    let keep = Refined {
        unit: grid.unit(dir),
        azimuth_deg: grid.azimuth_deg(dir),
        elevation_deg: grid.elevation_deg(dir),
    };
    let nbrs = table.neighbors_of(dir);
    if nbrs.is_empty() {
        return keep;
    }
    let y0: f64 = db[dir].into();
    let ys: Vec<f64> = nbrs.iter().map(|&j| db[j as usize].into() - y0).collect();
    if ys.iter().any(|y| !y.is_finite()) || !y0.is_finite() {
        return keep;
    }
    // Neighbours on the peak's own ring (within the tolerance that makes a grid a ring:
    // measured transfer functions, HARK's among them, jitter by hundredths of a degree).
    let same_ring = nbrs
        .iter()
        .all(|&j| (grid.elevation_deg(j as usize) - keep.elevation_deg).abs() < RING_ELEVATION_TOLERANCE_DEG);
    if same_ring && keep.elevation_deg.abs() < 89.9 {
        let ss: Vec<f64> = nbrs
            .iter()
            .map(|&j| wrap180(grid.azimuth_deg(j as usize) - keep.azimuth_deg))
            .collect();
        return match parabola_max(&ss, &ys) {
            Some(s) => {
                let az = wrap180(keep.azimuth_deg + s);
                let (a, e) = (az.to_radians(), keep.elevation_deg.to_radians());
                Refined {
                    unit: [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()],
                    azimuth_deg: if az <= -180.0 { az + 360.0 } else { az },
                    elevation_deg: keep.elevation_deg,
                }
            }
            None => keep,
        };
    }
    let u0 = keep.unit;
    // Tangent basis at u0.
    let helper = if u0[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let e1 = normalize(cross(helper, u0));
    let e2 = cross(u0, e1);
    let ts: Vec<[f64; 2]> = nbrs
        .iter()
        .map(|&j| {
            let v = grid.unit(j as usize);
            let c = dot(u0, v).clamp(-1.0, 1.0);
            let theta = c.acos();
            let p = [v[0] - c * u0[0], v[1] - c * u0[1], v[2] - c * u0[2]];
            let pn = dot(p, p).sqrt();
            if pn < 1e-12 {
                [0.0, 0.0]
            } else {
                [theta * dot(p, e1) / pn, theta * dot(p, e2) / pn]
            }
        })
        .collect();
    let Some(t) = quadratic_max(&ts, &ys) else {
        return keep;
    };
    let th = (t[0] * t[0] + t[1] * t[1]).sqrt();
    if th < 1e-12 {
        return keep;
    }
    let dirv = [
        (t[0] * e1[0] + t[1] * e2[0]) / th,
        (t[0] * e1[1] + t[1] * e2[1]) / th,
        (t[0] * e1[2] + t[1] * e2[2]) / th,
    ];
    Refined::from_unit([
        th.cos() * u0[0] + th.sin() * dirv[0],
        th.cos() * u0[1] + th.sin() * dirv[1],
        th.cos() * u0[2] + th.sin() * dirv[2],
    ])
}

/// Maximum of y(s) = g·s + h·s²/2 fitted to (s_j, y_j), clamped to
/// [`MAX_STEP_FRACTION`] of the mean |s_j|. None when h ≥ 0 or the fit is degenerate.
fn parabola_max(ss: &[f64], ys: &[f64]) -> Option<f64> {
    // Normal equations for (g, h) with basis (s, s²/2).
    let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (&s, &y) in ss.iter().zip(ys) {
        let q = s * s / 2.0;
        a11 += s * s;
        a12 += s * q;
        a22 += q * q;
        b1 += s * y;
        b2 += q * y;
    }
    let det = a11 * a22 - a12 * a12;
    if det.is_nan() || det.abs() <= 1e-12 * (a11 * a22).max(1e-300) {
        return None;
    }
    let g = (b1 * a22 - b2 * a12) / det;
    let h = (a11 * b2 - a12 * b1) / det;
    if h.is_nan() || h >= 0.0 {
        return None;
    }
    let limit = MAX_STEP_FRACTION * ss.iter().map(|s| s.abs()).sum::<f64>() / ss.len() as f64;
    Some((-g / h).clamp(-limit, limit))
}

/// Maximum of y(t) = gᵀt + ½tᵀHt fitted to (t_j, y_j) in the plane, clamped to
/// [`MAX_STEP_FRACTION`] of the mean ‖t_j‖. None with fewer than five points or when H
/// is not negative definite.
fn quadratic_max(ts: &[[f64; 2]], ys: &[f64]) -> Option<[f64; 2]> {
    if ts.len() < 5 {
        return None;
    }
    // Unknowns (g1, g2, h11, h12, h22), basis (t1, t2, t1²/2, t1·t2, t2²/2).
    let mut a = [[0.0f64; 5]; 5];
    let mut b = [0.0f64; 5];
    for (t, &y) in ts.iter().zip(ys) {
        let f = [t[0], t[1], t[0] * t[0] / 2.0, t[0] * t[1], t[1] * t[1] / 2.0];
        for i in 0..5 {
            for j in 0..5 {
                a[i][j] += f[i] * f[j];
            }
            b[i] += f[i] * y;
        }
    }
    let x = solve5(a, b)?;
    let (g1, g2, h11, h12, h22) = (x[0], x[1], x[2], x[3], x[4]);
    let det = h11 * h22 - h12 * h12;
    if !(h11 < 0.0 && det > 0.0) {
        return None;
    }
    // t* = −H⁻¹ g.
    let mut t = [-(h22 * g1 - h12 * g2) / det, -(h11 * g2 - h12 * g1) / det];
    let limit = MAX_STEP_FRACTION * ts.iter().map(|t| (t[0] * t[0] + t[1] * t[1]).sqrt()).sum::<f64>()
        / ts.len() as f64;
    let n = (t[0] * t[0] + t[1] * t[1]).sqrt();
    if !n.is_finite() {
        return None;
    }
    if n > limit {
        t = [t[0] * limit / n, t[1] * limit / n];
    }
    Some(t)
}

/// Gaussian elimination with partial pivoting; None when singular.
fn solve5(mut a: [[f64; 5]; 5], mut b: [f64; 5]) -> Option<[f64; 5]> {
    let scale = a.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    if scale.is_nan() || scale <= 0.0 {
        return None;
    }
    for c in 0..5 {
        let p = (c..5).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-12 * scale {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        let pivot = a[c];
        for r in c + 1..5 {
            let f = a[r][c] / pivot[c];
            for (x, p) in a[r].iter_mut().zip(&pivot).skip(c) {
                *x -= f * p;
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = [0.0f64; 5];
    for c in (0..5).rev() {
        let s: f64 = (c + 1..5).map(|k| a[c][k] * x[k]).sum();
        x[c] = (b[c] - s) / a[c][c];
    }
    Some(x)
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::LocalizeConfig;

    fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
        dot(a, b).clamp(-1.0, 1.0).acos().to_degrees()
    }

    /// A smooth peak exp(−θ²/2σ²) in dB around `truth`, sampled on the grid.
    fn field(grid: &Grid, truth: [f64; 3], sigma_deg: f64) -> Vec<f64> {
        (0..grid.len())
            .map(|i| {
                let th = angle(grid.unit(i), truth);
                20.0 * (-(th * th) / (2.0 * sigma_deg * sigma_deg)).exp()
            })
            .collect()
    }

    #[test]
    fn ring_peak_moves_between_grid_points() {
        let g = Grid::ring(5.0, 0.0, 1.0);
        let t = PeakTable::new(&g, &LocalizeConfig::default()).unwrap();
        for truth_az in [31.3, -118.2, 179.0, -178.6] {
            let a: f64 = f64::to_radians(truth_az);
            let db = field(&g, [a.cos(), a.sin(), 0.0], 12.0);
            let peak = (0..g.len()).max_by(|&i, &j| db[i].total_cmp(&db[j])).unwrap();
            let r = refine(&g, &t, &db, peak);
            let err = wrap180(r.azimuth_deg - truth_az).abs();
            assert!(
                err < 5.0 / 4.0,
                "az {truth_az}: refined {} (grid {})",
                r.azimuth_deg,
                g.azimuth_deg(peak)
            );
            assert!(err < wrap180(g.azimuth_deg(peak) - truth_az).abs() + 1e-9);
            assert_eq!(r.elevation_deg, 0.0);
        }
    }

    #[test]
    fn measured_rings_with_jittered_elevations_refine_too() {
        // HARK's tamago TFs: a 5° ring whose elevations vary by ~0.01° point to point.
        let pts: Vec<[f64; 3]> = (0..72)
            .map(|i| {
                let a = (i as f64 * 5.0).to_radians();
                let e = (16.7 + 0.01 * ((i * 7919) % 5) as f64 - 0.02).to_radians();
                [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()]
            })
            .collect();
        let g = Grid::from_points(pts).unwrap();
        let t = PeakTable::new(&g, &LocalizeConfig::default()).unwrap();
        for truth_az in [31.3, -118.2, 62.4] {
            let (a, e) = (f64::to_radians(truth_az), 16.7f64.to_radians());
            let db = field(&g, [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()], 12.0);
            let peak = (0..g.len()).max_by(|&i, &j| db[i].total_cmp(&db[j])).unwrap();
            let r = refine(&g, &t, &db, peak);
            let err = wrap180(r.azimuth_deg - truth_az).abs();
            assert!(err < 5.0 / 4.0, "az {truth_az}: refined {}", r.azimuth_deg);
            assert!(
                err < wrap180(g.azimuth_deg(peak) - truth_az).abs() - 0.5,
                "az {truth_az}: not moved"
            );
        }
    }

    #[test]
    fn sphere_peak_moves_between_grid_points() {
        let g = Grid::sphere(2522, 1.0);
        let t = PeakTable::new(&g, &LocalizeConfig::default()).unwrap();
        let step = (4.0 * std::f64::consts::PI / 2522.0).sqrt().to_degrees();
        let mut worst: f64 = 0.0;
        let mut worst_grid: f64 = 0.0;
        for (az, el) in [
            (40.3, 21.1),
            (-100.7, -9.2),
            (12.0, 75.5),
            (170.2, -44.4),
            (-33.3, 3.3),
        ] {
            let u = crate::demo::unit_from_az_el(az, el);
            let db = field(&g, u, 15.0);
            let peak = (0..g.len()).max_by(|&i, &j| db[i].total_cmp(&db[j])).unwrap();
            let r = refine(&g, &t, &db, peak);
            worst = worst.max(angle(r.unit, u));
            worst_grid = worst_grid.max(angle(g.unit(peak), u));
        }
        assert!(
            worst < step / 4.0,
            "refined error {worst}° (grid step {step}°, grid error {worst_grid}°)"
        );
    }

    #[test]
    fn degenerate_fits_keep_the_grid_direction() {
        let g = Grid::sphere(100, 1.0);
        let t = PeakTable::new(&g, &LocalizeConfig::default()).unwrap();
        // A single spike: whatever the fit, the step stays inside the grid cell.
        let mut db = vec![0.0f64; g.len()];
        db[7] = 10.0;
        let r = refine(&g, &t, &db, 7);
        let nb = t.neighbors_of(7);
        let mean = nb
            .iter()
            .map(|&j| angle(g.unit(7), g.unit(j as usize)))
            .sum::<f64>()
            / nb.len() as f64;
        assert!(angle(r.unit, g.unit(7)) <= MAX_STEP_FRACTION * mean + 1e-9);
        // A flat ridge on a ring (left = right = centre − 1 dB): stays on the grid point.
        let ring = Grid::ring(10.0, 0.0, 1.0);
        let tr = PeakTable::new(&ring, &LocalizeConfig::default()).unwrap();
        let mut dr = vec![0.0f64; ring.len()];
        dr[4] = 1.0;
        let r = refine(&ring, &tr, &dr, 4);
        assert!((r.azimuth_deg - ring.azimuth_deg(4)).abs() < 1e-9);
        // Non-finite values: kept.
        db[3] = f64::NAN;
        let r = refine(&g, &t, &db, 3);
        assert_eq!(r.unit, g.unit(3));
    }
}
