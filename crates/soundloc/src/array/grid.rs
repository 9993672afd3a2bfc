//! Candidate directions (the search grid) and their neighbour relation.
//!
//! A grid point is a position in metres (HARK stores the measurement position, e.g. a
//! source 1 m away); its direction is the unit vector p/|p|, azimuth = atan2(y, x) in
//! (−180°, 180°], elevation = atan2(z, √(x² + y²)).
//!
//! - [`Grid::ring`]`(step, elevation, r)`: n = round(360/step) points at azimuths
//!   0, 360/n, 2·360/n, … (counter-clockwise from +x toward +y), all at one elevation,
//!   radius r. This is the order of HARKTOOL5's geometric TFs (tamago_geotf.zip: id 0 at
//!   0°, id 1 at 5°, …, id 36 at 180°, id 71 at −5°). Older measured sets start at −180°
//!   (tamago_rectf.zip and kinect_loc.dat: id 0 at −180°, id 36 at 0°) — also
//!   counter-clockwise. Neighbours: left and right, wrapping (HARK's `<neighbors>` for
//!   both files say the same).
//! - [`Grid::sphere`]`(n, r)`: a Fibonacci lattice over the full sphere,
//!   z_i = 1 − (2i + 1)/n, azimuth_i = i·π(3 − √5); neighbours: the 6 nearest points by
//!   angle, made symmetric (j ∈ N(i) ⇔ i ∈ N(j)), so most points have 6–8. Mean spacing
//!   is about √(4π/n) rad (4.0° at n = 2522).
//! - [`Grid::with_neighbors`]: any points with an explicit table.

pub(crate) use super::neighbors::angle_between;
use super::neighbors::{is_ring_order, norm, unit};
pub use super::neighbors::{nearest_neighbors, ring_neighbors, with_every_quarter};
use crate::{Error, Result};
use std::fmt;
use std::str::FromStr;

/// How the grid points are arranged; decides the peak search's neighbour relation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GridKind {
    /// One ring at a fixed elevation, sorted by azimuth; neighbours are left/right (wrapping).
    Ring,
    /// Points over the (half- or full) sphere with an explicit neighbour table.
    Sphere,
    /// Any other set of points with an explicit neighbour table (e.g. from a TF zip).
    Irregular,
}

impl fmt::Display for GridKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            GridKind::Ring => "ring",
            GridKind::Sphere => "sphere",
            GridKind::Irregular => "irregular",
        })
    }
}

/// Candidate source directions.
///
/// `points[i]` is the position of direction i as stored in the TF (not necessarily a unit
/// vector: HARK stores the measurement position, e.g. 1 m away). `neighbors[i]` lists the
/// neighbours of i (never i itself) used by the peak search.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Grid {
    /// Positions in metres (or unit vectors), one per direction.
    pub points: Vec<[f64; 3]>,
    /// The arrangement.
    pub kind: GridKind,
    /// Neighbour indices per direction, without the point itself.
    pub neighbors: Vec<Vec<usize>>,
}

/// Number of nearest points (by angle) taken as neighbours of a sphere or table-less
/// irregular grid, before symmetrisation.
pub const SPHERE_NEIGHBORS: usize = 6;

/// How far (times its farthest of the [`SPHERE_NEIGHBORS`] nearest) a point of a grid
/// given as points looks for a neighbour in a quarter those miss
/// ([`super::neighbors::with_every_quarter`]): a 1° × 10° product grid's next ring.
pub const QUARTER_REACH: f64 = 4.0;

/// Points whose elevations differ by less than this (degrees) count as one ring (HARK
/// files store 3–4 decimals: tamago_rectf's ring spans 30.96°–30.97°).
pub const RING_ELEVATION_TOLERANCE_DEG: f64 = 0.5;

impl Grid {
    /// Number of directions.
    pub fn len(&self) -> usize {
        self.points.len()
    }
    /// True when there are no directions.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
    /// Azimuth of direction `i` in degrees, atan2(y, x), in (-180, 180].
    pub fn azimuth_deg(&self, i: usize) -> f64 {
        let [x, y, _] = self.points[i];
        let a = y.atan2(x).to_degrees();
        // atan2(-0.0, -1) is -180 (HARK files write y="-0.000"): fold into (-180, 180].
        if a <= -180.0 {
            a + 360.0
        } else {
            a
        }
    }
    /// Elevation of direction `i` in degrees from the x-y plane.
    pub fn elevation_deg(&self, i: usize) -> f64 {
        let [x, y, z] = self.points[i];
        z.atan2((x * x + y * y).sqrt()).to_degrees()
    }
    /// Unit vector of direction `i`.
    pub fn unit(&self, i: usize) -> [f64; 3] {
        unit(self.points[i])
    }
    /// Distance of point `i` from the origin (metres).
    pub fn radius_m(&self, i: usize) -> f64 {
        norm(self.points[i])
    }

    /// A ring of n = round(360/`step_deg`) points (at least 1) at elevation
    /// `elevation_deg`, radius `radius_m`, azimuths 0, 360/n, … counter-clockwise (the
    /// HARKTOOL5 order); neighbours left/right with wrap. A `step_deg` that does not divide
    /// 360 is rounded to one that does ([`GridSpec`] rejects it instead).
    pub fn ring(step_deg: f64, elevation_deg: f64, radius_m: f64) -> Grid {
        let n = if step_deg.is_finite() && step_deg > 0.0 {
            ((360.0 / step_deg).round() as usize).max(1)
        } else {
            1
        };
        let el = elevation_deg.to_radians();
        let points = (0..n)
            .map(|i| {
                let az = (360.0 * i as f64 / n as f64).to_radians();
                [
                    radius_m * el.cos() * az.cos(),
                    radius_m * el.cos() * az.sin(),
                    radius_m * el.sin(),
                ]
            })
            .collect();
        Grid {
            points,
            kind: GridKind::Ring,
            neighbors: ring_neighbors(n),
        }
    }

    /// `n_points` directions over the full sphere (Fibonacci lattice, see the module
    /// docs) at radius `radius_m`, with a symmetric 6-nearest neighbour table.
    pub fn sphere(n_points: usize, radius_m: f64) -> Grid {
        Self::of_units(super::geometry::fibonacci_sphere(n_points), radius_m)
    }

    /// The upper half (z > 0, elevation above 0°) of a Fibonacci lattice of 2·`n_points`
    /// directions: `n_points` directions for an array lying in the horizontal plane, whose
    /// mirror images below it give the same spectrum in free field.
    pub fn hemisphere(n_points: usize, radius_m: f64) -> Grid {
        let mut units = super::geometry::fibonacci_sphere(2 * n_points);
        units.retain(|u| u[2] > 0.0);
        Self::of_units(units, radius_m)
    }

    /// A sphere-kind grid of unit directions `units` at `radius_m`, with a symmetric
    /// [`SPHERE_NEIGHBORS`]-nearest neighbour table.
    fn of_units(units: Vec<[f64; 3]>, radius_m: f64) -> Grid {
        let neighbors = nearest_neighbors(&units, SPHERE_NEIGHBORS);
        Grid {
            points: units
                .into_iter()
                .map(|u| [u[0] * radius_m, u[1] * radius_m, u[2] * radius_m])
                .collect(),
            kind: GridKind::Sphere,
            neighbors,
        }
    }

    /// A grid with an explicit neighbour table. Checks that there is one list per point,
    /// that every index is in range and that every point is finite and not at the origin;
    /// a point listed as its own neighbour and repeated entries are dropped (HARK's tables
    /// list each point first).
    pub fn with_neighbors(points: Vec<[f64; 3]>, kind: GridKind, neighbors: Vec<Vec<usize>>) -> Result<Grid> {
        let n = points.len();
        if neighbors.len() != n {
            return Err(Error::Mismatch(format!(
                "grid: {} neighbour lists for {n} points",
                neighbors.len()
            )));
        }
        for (i, p) in points.iter().enumerate() {
            if p.iter().any(|v| !v.is_finite()) || norm(*p) == 0.0 {
                return Err(Error::Mismatch(format!(
                    "grid: point {i} {p:?} is not a usable direction (non-finite or at the origin)"
                )));
            }
        }
        let mut clean = Vec::with_capacity(n);
        for (i, list) in neighbors.into_iter().enumerate() {
            let mut out: Vec<usize> = Vec::with_capacity(list.len());
            for j in list {
                if j >= n {
                    return Err(Error::Mismatch(format!(
                        "grid: point {i} lists neighbour {j}, but there are only {n} points"
                    )));
                }
                if j != i && !out.contains(&j) {
                    out.push(j);
                }
            }
            clean.push(out);
        }
        Ok(Grid {
            points,
            kind,
            neighbors: clean,
        })
    }

    /// A grid from points alone (e.g. an HGTF file, which stores no neighbour table):
    /// [`GridKind::Ring`] with left/right neighbours when [`Grid::is_ring_order`] holds
    /// with those neighbours, else [`GridKind::Irregular`] with the symmetric 6-nearest
    /// table.
    pub fn from_points(points: Vec<[f64; 3]>) -> Result<Grid> {
        let n = points.len();
        let ring = ring_neighbors(n);
        if is_ring_order(&points, &ring) {
            return Grid::with_neighbors(points, GridKind::Ring, ring);
        }
        let units: Vec<[f64; 3]> = points.iter().map(|p| unit(*p)).collect();
        let nb = with_every_quarter(&units, SPHERE_NEIGHBORS, QUARTER_REACH);
        Grid::with_neighbors(points, GridKind::Irregular, nb)
    }

    /// A grid from points and a stored table (e.g. a TF zip): [`GridKind::Ring`] when the
    /// table is exactly left/right in the stored order and [`Grid::is_ring_order`] holds,
    /// else [`GridKind::Irregular`] with the table as given.
    pub fn from_table(points: Vec<[f64; 3]>, neighbors: Vec<Vec<usize>>) -> Result<Grid> {
        let g = Grid::with_neighbors(points, GridKind::Irregular, neighbors)?;
        let ring = ring_neighbors(g.len());
        let same = g.neighbors.iter().zip(&ring).all(|(a, b)| {
            let mut a = a.clone();
            let mut b = b.clone();
            a.sort_unstable();
            b.sort_unstable();
            a == b
        });
        if same && is_ring_order(&g.points, &g.neighbors) {
            Ok(Grid {
                kind: GridKind::Ring,
                ..g
            })
        } else {
            Ok(g)
        }
    }

    /// True when all points share one elevation (within 0.5°) and consecutive points step
    /// around the circle in one direction, by equal steps, covering 360° exactly once.
    pub fn is_ring_order(&self) -> bool {
        is_ring_order(&self.points, &self.neighbors)
    }

    /// A one-line description of the neighbour relation, for summaries, e.g.
    /// `left/right in azimuth, wrapping (72-point ring)` or
    /// `table: 6–8 neighbours per point (mean 6.4)`.
    pub fn neighbor_relation(&self) -> String {
        if self.kind == GridKind::Ring {
            return format!("left/right in azimuth, wrapping ({}-point ring)", self.len());
        }
        let counts: Vec<usize> = self.neighbors.iter().map(|v| v.len()).collect();
        let min = counts.iter().copied().min().unwrap_or(0);
        let max = counts.iter().copied().max().unwrap_or(0);
        let mean = if counts.is_empty() {
            0.0
        } else {
            counts.iter().sum::<usize>() as f64 / counts.len() as f64
        };
        if min == max {
            format!("table: {min} neighbours per point")
        } else {
            format!("table: {min}–{max} neighbours per point (mean {mean:.1})")
        }
    }

    /// Largest angle (degrees) between a point and one of its neighbours.
    pub fn max_neighbor_angle_deg(&self) -> f64 {
        let mut m: f64 = 0.0;
        for (i, list) in self.neighbors.iter().enumerate() {
            for &j in list {
                m = m.max(angle_between(self.unit(i), self.unit(j)).to_degrees());
            }
        }
        m
    }

    /// True when `j ∈ neighbors[i] ⇔ i ∈ neighbors[j]` for all pairs.
    pub fn neighbors_symmetric(&self) -> bool {
        self.neighbors
            .iter()
            .enumerate()
            .all(|(i, l)| l.iter().all(|&j| self.neighbors[j].contains(&i)))
    }

    /// (min, max) azimuth and (min, max) elevation over all points, degrees.
    pub fn angle_ranges_deg(&self) -> Option<((f64, f64), (f64, f64))> {
        if self.is_empty() {
            return None;
        }
        let mut az = (f64::INFINITY, f64::NEG_INFINITY);
        let mut el = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..self.len() {
            let a = self.azimuth_deg(i);
            let e = self.elevation_deg(i);
            az = (az.0.min(a), az.1.max(a));
            el = (el.0.min(e), el.1.max(e));
        }
        Some((az, el))
    }
}

/// A grid as written on the command line: `ring:STEP_DEG[:ELEV_DEG]` (elevation default
/// 0), `sphere:N` or `hemisphere:N`. [`GridSpec::build`] makes the [`Grid`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum GridSpec {
    /// A ring every `step_deg` degrees (must divide 360) at `elevation_deg`.
    Ring {
        /// Azimuth step, degrees.
        step_deg: f64,
        /// Elevation, degrees in [−90, 90].
        elevation_deg: f64,
    },
    /// A full-sphere Fibonacci lattice of `n` points (n ≥ 2).
    Sphere {
        /// Number of points.
        n: usize,
    },
    /// The upper hemisphere (elevation > 0°) of `n` points ([`Grid::hemisphere`]): for
    /// planar arrays lying horizontally.
    Hemisphere {
        /// Number of points.
        n: usize,
    },
}

impl GridSpec {
    /// Check the limits [`FromStr`] checks (for specs that arrive through serde).
    pub fn validate(&self) -> Result<()> {
        self.to_string().parse::<GridSpec>().map(|_| ())
    }

    /// The grid, with points at `radius_m` from the origin.
    pub fn build(&self, radius_m: f64) -> Grid {
        match *self {
            GridSpec::Ring {
                step_deg,
                elevation_deg,
            } => Grid::ring(step_deg, elevation_deg, radius_m),
            GridSpec::Sphere { n } => Grid::sphere(n, radius_m),
            GridSpec::Hemisphere { n } => Grid::hemisphere(n, radius_m),
        }
    }
}

impl FromStr for GridSpec {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        let bad = |why: &str| {
            Error::Config(format!(
                "grid {s:?}: {why} (expected ring:STEP_DEG[:ELEV_DEG], sphere:N or hemisphere:N, e.g. ring:5, ring:5:16.7, sphere:2522, hemisphere:1261)"
            ))
        };
        let parts: Vec<&str> = s.trim().split(':').map(str::trim).collect();
        match parts.as_slice() {
            ["ring", step, rest @ ..] if rest.len() <= 1 => {
                let step_deg: f64 = step
                    .parse()
                    .map_err(|_| bad("the step must be a number of degrees"))?;
                if !(step_deg.is_finite() && step_deg > 0.0 && step_deg <= 360.0) {
                    return Err(bad("the step must be in (0, 360] degrees"));
                }
                if step_deg < super::MIN_RING_STEP_DEG {
                    return Err(bad(&format!(
                        "the step must be at least {} degrees ({} directions)",
                        super::MIN_RING_STEP_DEG,
                        (360.0 / super::MIN_RING_STEP_DEG).round()
                    )));
                }
                let n = 360.0 / step_deg;
                if (n - n.round()).abs() > 1e-6 {
                    return Err(bad("the step must divide 360 degrees"));
                }
                let elevation_deg: f64 = match rest.first() {
                    Some(e) => e
                        .parse()
                        .map_err(|_| bad("the elevation must be a number of degrees"))?,
                    None => 0.0,
                };
                if !(elevation_deg.is_finite() && elevation_deg.abs() < 90.0) {
                    return Err(bad(
                        "the elevation must be in (-90, 90) degrees (at ±90 every direction of a ring is the same point)",
                    ));
                }
                Ok(GridSpec::Ring {
                    step_deg,
                    elevation_deg,
                })
            }
            [kind @ ("sphere" | "hemisphere"), n] => {
                let n: usize = n.parse().map_err(|_| bad("N must be a whole number of points"))?;
                if !(2..=super::MAX_DIRECTIONS).contains(&n) {
                    return Err(bad(&format!("N must be between 2 and {}", super::MAX_DIRECTIONS)));
                }
                Ok(if *kind == "sphere" {
                    GridSpec::Sphere { n }
                } else {
                    GridSpec::Hemisphere { n }
                })
            }
            _ => Err(bad("unknown form")),
        }
    }
}

impl fmt::Display for GridSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GridSpec::Ring {
                step_deg,
                elevation_deg,
            } => {
                if *elevation_deg == 0.0 {
                    write!(f, "ring:{step_deg}")
                } else {
                    write!(f, "ring:{step_deg}:{elevation_deg}")
                }
            }
            GridSpec::Sphere { n } => write!(f, "sphere:{n}"),
            GridSpec::Hemisphere { n } => write!(f, "hemisphere:{n}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `hemisphere:N`: N directions above the horizontal plane, which a planar array lying
    /// flat cannot tell from their mirror images (so the full sphere gets a note and the
    /// hemisphere none); parsed, printed and built like `sphere:N`.
    #[test]
    fn hemisphere_grid_is_the_upper_half_and_silences_the_mirror_note() {
        let spec: GridSpec = "hemisphere:500".parse().unwrap();
        assert_eq!(spec, GridSpec::Hemisphere { n: 500 });
        assert_eq!(spec.to_string().parse::<GridSpec>().unwrap(), spec);
        let g = spec.build(2.0);
        assert_eq!(g.len(), 500);
        assert_eq!(g.kind, GridKind::Sphere);
        assert!((0..g.len()).all(|i| g.elevation_deg(i) > 0.0 && (g.radius_m(i) - 2.0).abs() < 1e-12));
        // The upper half of the 1000-point lattice, in its order.
        let full = Grid::sphere(1000, 2.0);
        assert_eq!(g.points[..], full.points[..500]);
        assert!(g.neighbors_symmetric() && (0..g.len()).all(|i| g.neighbors[i].len() >= SPHERE_NEIGHBORS));
        let ring = super::super::Geometry::circle(8, 0.0365, 0.0);
        assert!(super::super::geometry::mirror_note(&ring.mics, &full.points).is_some());
        assert_eq!(super::super::geometry::mirror_note(&ring.mics, &g.points), None);
        assert!("hemisphere:1".parse::<GridSpec>().is_err());
        assert!("hemisphere:x".parse::<GridSpec>().is_err());
    }

    #[test]
    fn ring_order_and_neighbors() {
        let g = Grid::ring(5.0, 16.7, 1.0);
        assert_eq!(g.len(), 72);
        assert_eq!(g.kind, GridKind::Ring);
        assert!((g.azimuth_deg(0) - 0.0).abs() < 1e-9);
        assert!((g.azimuth_deg(1) - 5.0).abs() < 1e-9);
        assert!((g.azimuth_deg(36) - 180.0).abs() < 1e-9);
        assert!((g.azimuth_deg(71) + 5.0).abs() < 1e-9);
        assert!((g.elevation_deg(10) - 16.7).abs() < 1e-9);
        assert!((g.radius_m(3) - 1.0).abs() < 1e-12);
        assert_eq!(g.neighbors[0], vec![71, 1]);
        assert_eq!(g.neighbors[71], vec![70, 0]);
        assert!(g.neighbors_symmetric());
        assert!(g.is_ring_order());
        assert!((g.max_neighbor_angle_deg() - 5.0 * 16.7f64.to_radians().cos()).abs() < 0.01);
        assert_eq!(
            g.neighbor_relation(),
            "left/right in azimuth, wrapping (72-point ring)"
        );
        // From points alone, the same ring is recognised.
        let g2 = Grid::from_points(g.points.clone()).unwrap();
        assert_eq!(g2, g);
        // -180 start (the rectf order) is a ring too; -0.0 y folds to +180.
        let mut pts = g.points.clone();
        pts.rotate_left(36);
        pts[0][1] = -0.0;
        let g3 = Grid::from_points(pts).unwrap();
        assert_eq!(g3.kind, GridKind::Ring);
        assert_eq!(g3.azimuth_deg(0), 180.0);
        // Tiny rings.
        assert_eq!(Grid::ring(180.0, 0.0, 1.0).neighbors, vec![vec![1], vec![0]]);
        assert_eq!(Grid::ring(360.0, 0.0, 1.0).neighbors, vec![Vec::<usize>::new()]);
    }

    #[test]
    fn sphere_2522() {
        let g = Grid::sphere(2522, 1.0);
        assert_eq!(g.len(), 2522);
        assert_eq!(g.kind, GridKind::Sphere);
        assert!(g.neighbors_symmetric());
        let spacing = (4.0 * std::f64::consts::PI / 2522.0).sqrt().to_degrees();
        let max = g.max_neighbor_angle_deg();
        assert!(
            max < 2.0 * spacing,
            "max neighbour angle {max}° vs spacing {spacing}°"
        );
        for (i, l) in g.neighbors.iter().enumerate() {
            assert!(l.len() >= 6 && l.len() <= 12, "point {i}: {} neighbours", l.len());
            assert!(!l.contains(&i));
        }
        // Brute-force check of the pruned search on a smaller lattice.
        let s = Grid::sphere(300, 1.0);
        let units: Vec<_> = (0..300).map(|i| s.unit(i)).collect();
        for i in (0..300).step_by(7) {
            let mut d: Vec<(f64, usize)> = (0..300)
                .filter(|&j| j != i)
                .map(|j| (angle_between(units[i], units[j]), j))
                .collect();
            d.sort_by(|a, b| a.partial_cmp(b).unwrap());
            for &(_, j) in &d[..6] {
                assert!(s.neighbors[i].contains(&j), "point {i} misses {j}");
            }
        }
        // Full coverage: elevations span nearly ±90°.
        let ((_, _), (el_lo, el_hi)) = g.angle_ranges_deg().unwrap();
        assert!(el_lo < -88.0 && el_hi > 88.0);
        assert!(!Grid::from_points(g.points.clone()).unwrap().is_ring_order());
    }

    #[test]
    fn with_neighbors_validates() {
        let pts = vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]];
        let g = Grid::with_neighbors(
            pts.clone(),
            GridKind::Irregular,
            vec![vec![0, 1, 1], vec![0], vec![]],
        )
        .unwrap();
        assert_eq!(g.neighbors[0], vec![1]);
        let e = Grid::with_neighbors(pts.clone(), GridKind::Irregular, vec![vec![5], vec![], vec![]])
            .unwrap_err()
            .to_string();
        assert_eq!(e, "grid: point 0 lists neighbour 5, but there are only 3 points");
        assert!(Grid::with_neighbors(pts.clone(), GridKind::Irregular, vec![]).is_err());
        let mut bad = pts;
        bad[1] = [f64::NAN, 0.0, 0.0];
        assert!(Grid::with_neighbors(bad, GridKind::Irregular, vec![vec![]; 3]).is_err());
    }

    #[test]
    fn grid_spec_strings() {
        for s in ["ring:5", "ring:5:16.7", "sphere:2522", "ring:2.5:-30"] {
            let g: GridSpec = s.parse().unwrap();
            assert_eq!(g.to_string(), s);
        }
        assert_eq!(
            "ring:5:16.7".parse::<GridSpec>().unwrap(),
            GridSpec::Ring {
                step_deg: 5.0,
                elevation_deg: 16.7
            }
        );
        assert_eq!("sphere:2522".parse::<GridSpec>().unwrap().build(1.0).len(), 2522);
        assert_eq!("ring:10".parse::<GridSpec>().unwrap().build(2.0).len(), 36);
        for bad in [
            "ring:7",
            "ring:0",
            "ring:x",
            "ring:5:100",
            "ring:5:90",
            "ring:5:-90",
            "sphere:1",
            "sphere:x",
            "cube:3",
            "ring:5:1:2",
        ] {
            let e = bad.parse::<GridSpec>().unwrap_err().to_string();
            assert!(e.contains(bad), "{e}");
        }
    }
}
