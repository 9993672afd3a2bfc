//! Stage 5 — peaks: local maxima of the broadband spectrum.
//!
//! A grid point is a peak when its power is strictly greater than every neighbour's (on a
//! ring: left and right, wrapping in azimuth; on a 3-D grid: the grid's neighbour table,
//! e.g. the one a TF zip stores). Peaks whose azimuth, wrapped into (MIN_DEG, MIN_DEG+360],
//! lies in [MIN_DEG, MAX_DEG] are kept, sorted by power (strongest first), and the top
//! MAXNUM_OUT_PEAKS are output (−1 = NUM_SOURCE, 0 = all).

pub mod refine;

use crate::array::Grid;
use crate::backend::Peak;
use crate::config::LocalizeConfig;
use crate::{Error, Result};

/// The neighbour relation in CSR form, the azimuth mask and the output count — plain
/// arrays a GPU kernel can take as they are.
#[derive(Debug, Clone, PartialEq)]
pub struct PeakTable {
    /// `neighbors[offsets[d] .. offsets[d+1]]` are the neighbours of direction d.
    pub offsets: Vec<u32>,
    /// Neighbour indices.
    pub neighbors: Vec<u32>,
    /// Whether direction d's azimuth is inside [MIN_DEG, MAX_DEG].
    pub azimuth_ok: Vec<bool>,
    /// How many peaks to output (usize::MAX = all).
    pub max_out: usize,
}

impl PeakTable {
    /// Build from the grid's neighbour relation and the config's azimuth range.
    pub fn new(grid: &Grid, config: &LocalizeConfig) -> Result<Self> {
        let d = grid.len();
        if grid.neighbors.len() != d {
            return Err(Error::Config(format!(
                "direction grid has {} points but {} neighbour lists",
                d,
                grid.neighbors.len()
            )));
        }
        for (i, nb) in grid.neighbors.iter().enumerate() {
            if let Some(&j) = nb.iter().find(|&&j| j >= d) {
                return Err(Error::Config(format!(
                    "direction {i} lists neighbour {j}, but the grid has {d} points"
                )));
            }
        }
        // Points given twice (a grid from `linspace(…, endpoint=True)`, whose last azimuth
        // is its first): one point, the first of them, whose neighbours are all of theirs.
        // The others never peak; two equal values would otherwise each stop the other
        // being a strict maximum, and the strongest source would vanish.
        let first = coincident_first(grid);
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); d];
        for (i, nb) in grid.neighbors.iter().enumerate() {
            let l = &mut lists[first[i]];
            for &j in nb {
                // A neighbour given twice is one neighbour, its first copy.
                let j = first[j] as u32;
                if j as usize != first[i] && !l.contains(&j) {
                    l.push(j);
                }
            }
        }
        let mut offsets = Vec::with_capacity(d + 1);
        let mut neighbors = Vec::new();
        offsets.push(0u32);
        for l in &lists {
            neighbors.extend_from_slice(l);
            offsets.push(neighbors.len() as u32);
        }
        let azimuth_ok = (0..d)
            .map(|i| first[i] == i && azimuth_in_range(grid.azimuth_deg(i), config.min_deg, config.max_deg))
            .collect();
        Ok(PeakTable {
            offsets,
            neighbors,
            azimuth_ok,
            max_out: config.peaks_out(),
        })
    }

    /// Neighbours of direction `d`.
    pub fn neighbors_of(&self, d: usize) -> &[u32] {
        &self.neighbors[self.offsets[d] as usize..self.offsets[d + 1] as usize]
    }
}

/// For every grid point, the first point with the same direction (itself when it is the
/// first): unit vectors within 1e-9 of each other are one direction. Points are compared
/// along the coordinate that spreads them most, sorted: O(D log D) for any usual grid.
pub(crate) fn coincident_first(grid: &Grid) -> Vec<usize> {
    const TOL: f64 = 1e-9;
    let d = grid.len();
    let u: Vec<[f64; 3]> = (0..d).map(|i| grid.unit(i)).collect();
    let spread = |k: usize| {
        let (lo, hi) = u.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p[k]), b.max(p[k]))
        });
        hi - lo
    };
    let k = (0..3)
        .max_by(|&a, &b| spread(a).total_cmp(&spread(b)))
        .unwrap_or(0);
    let mut order: Vec<usize> = (0..d).collect();
    order.sort_by(|&a, &b| u[a][k].total_cmp(&u[b][k]).then(a.cmp(&b)));
    // Union-find, each set's root its lowest index: chains (a ≈ b ≈ c, a and c further
    // apart than TOL) are one point.
    let mut parent: Vec<usize> = (0..d).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for (n, &i) in order.iter().enumerate() {
        for &j in &order[n + 1..] {
            if u[j][k] - u[i][k] > TOL {
                break;
            }
            if (0..3).all(|c| (u[i][c] - u[j][c]).abs() <= TOL) {
                let (a, b) = (root(&mut parent, i), root(&mut parent, j));
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    (0..d).map(|i| root(&mut parent, i)).collect()
}

/// Whether `az` (degrees), wrapped into (min, min + 360], lies in [min, max].
pub fn azimuth_in_range(az: f64, min_deg: f64, max_deg: f64) -> bool {
    let mut a = az;
    while a <= min_deg {
        a += 360.0;
    }
    while a > min_deg + 360.0 {
        a -= 360.0;
    }
    a >= min_deg && a <= max_deg
}

/// Whether direction `d` is a local maximum of `db`.
#[inline]
pub fn is_local_max<V: Copy + Into<f64>>(db: &[V], table: &PeakTable, d: usize) -> bool {
    let v: f64 = db[d].into();
    table.neighbors_of(d).iter().all(|&j| v > db[j as usize].into())
}

/// Peaks of one spectrum (any values monotone in power, e.g. dB), strongest first.
pub fn find_peaks<V: Copy + Into<f64>>(db: &[V], table: &PeakTable) -> Vec<Peak> {
    let candidates = (0..db.len()).filter(|&d| table.azimuth_ok[d] && is_local_max(db, table, d));
    select(
        candidates.map(|d| Peak {
            dir: d,
            power_db: db[d].into(),
        }),
        table.max_out,
    )
}

/// Sort candidates by power (ties by index) and keep the top `max_out`.
pub fn select(candidates: impl Iterator<Item = Peak>, max_out: usize) -> Vec<Peak> {
    let mut v: Vec<Peak> = candidates.collect();
    v.sort_by(|a, b| b.power_db.total_cmp(&a.power_db).then(a.dir.cmp(&b.dir)));
    v.truncate(max_out);
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::array::GridKind;

    fn ring(n: usize) -> Grid {
        Grid {
            points: (0..n)
                .map(|i| {
                    let a = (i as f64 * 360.0 / n as f64).to_radians();
                    [a.cos(), a.sin(), 0.0]
                })
                .collect(),
            kind: GridKind::Ring,
            neighbors: (0..n).map(|i| vec![(i + n - 1) % n, (i + 1) % n]).collect(),
        }
    }

    #[test]
    fn ring_peaks_wrap_and_sort() {
        let g = ring(8);
        let cfg = LocalizeConfig {
            max_peaks: 0,
            ..Default::default()
        };
        let t = PeakTable::new(&g, &cfg).unwrap();
        //            0    1    2    3    4    5    6    7
        let db = [5.0, 1.0, 2.0, 3.0, 1.0, 1.0, 1.0, 4.0f64];
        let p = find_peaks(&db, &t);
        // 0 beats its wrapped neighbour 7; 3 is a local max; plateau 4-6 gives nothing.
        assert_eq!(p.iter().map(|p| p.dir).collect::<Vec<_>>(), vec![0, 3]);
        let cfg2 = LocalizeConfig {
            max_peaks: 1,
            ..Default::default()
        };
        assert_eq!(find_peaks(&db, &PeakTable::new(&g, &cfg2).unwrap()).len(), 1);
    }

    /// A direction given twice (the last point of a `linspace(0, 360, n + 1)` ring is its
    /// first; a TF file listing one twice) is one point: the first of them peaks, with the
    /// neighbours of both, and the copy never does. Before, the two equal values stopped
    /// each other, and the strongest peak was lost.
    #[test]
    fn a_direction_given_twice_is_one_point() {
        let mut g = ring(8);
        g.points.push(g.points[0]);
        g.points[8][1] += 1e-12; // the rounding of cos/sin(360°)
        let n = 9;
        g.neighbors = (0..n).map(|i| vec![(i + n - 1) % n, (i + 1) % n]).collect();
        let cfg = LocalizeConfig {
            max_peaks: 0,
            ..Default::default()
        };
        let t = PeakTable::new(&g, &cfg).unwrap();
        let mut nb = t.neighbors_of(0).to_vec();
        nb.sort();
        assert_eq!(nb, vec![1, 7]);
        assert!(!t.azimuth_ok[8] && t.azimuth_ok[0]);
        //            0    1    2    3    4    5    6    7    8 (= 0)
        let db = [5.0, 1.0, 2.0, 3.0, 1.0, 1.0, 1.0, 4.0, 5.0f64];
        let p = find_peaks(&db, &t);
        assert_eq!(p.iter().map(|p| p.dir).collect::<Vec<_>>(), vec![0, 3]);
        // Not where 7 is above it.
        let db = [5.0, 1.0, 2.0, 3.0, 1.0, 1.0, 1.0, 6.0, 5.0f64];
        assert_eq!(
            find_peaks(&db, &t).iter().map(|p| p.dir).collect::<Vec<_>>(),
            vec![7, 3]
        );
        // A copy in the middle of the list, and three copies of one point.
        let mut g = ring(6);
        g.points.insert(3, g.points[2]);
        g.points.push(g.points[2]);
        g.neighbors = vec![
            vec![6, 1],
            vec![0, 2],
            vec![1, 3],
            vec![2, 4],
            vec![3, 5],
            vec![4, 6],
            vec![5, 0],
            vec![],
        ];
        let t = PeakTable::new(&g, &cfg).unwrap();
        let first = coincident_first(&g);
        assert_eq!(first, vec![0, 1, 2, 2, 4, 5, 6, 2]);
        let db = [0.0, 1.0, 9.0, 9.0, 2.0, 1.0, 0.5, 9.0f64];
        assert_eq!(
            find_peaks(&db, &t).iter().map(|p| p.dir).collect::<Vec<_>>(),
            vec![2]
        );
        // A grid without copies is left as it was.
        let g = ring(8);
        assert_eq!(coincident_first(&g), (0..8).collect::<Vec<_>>());
        // A chain: 0 and 2 are 1.6e-9 apart, each within 1e-9 of 1; one point.
        let mut g = ring(4);
        g.points = vec![
            [1.0, 1.6e-9, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.8e-9, 0.0],
            [0.0, 1.0, 0.0],
        ];
        assert_eq!(coincident_first(&g), vec![0, 0, 0, 3]);
        // A neighbour listed through two copies counts once (refinement fits each once).
        let mut g = ring(8);
        g.points.push(g.points[1]);
        g.neighbors.push(vec![0, 2]);
        g.neighbors[0].push(8);
        let t = PeakTable::new(&g, &cfg).unwrap();
        let mut nb = t.neighbors_of(0).to_vec();
        nb.sort();
        assert_eq!(nb, vec![1, 7]);
    }

    #[test]
    fn azimuth_filter_wraps_into_min_plus_360() {
        assert!(azimuth_in_range(180.0, -180.0, 180.0));
        assert!(azimuth_in_range(-90.0, -180.0, 180.0));
        assert!(azimuth_in_range(350.0, -30.0, 30.0)); // = -10
        assert!(!azimuth_in_range(40.0, -30.0, 30.0));
        assert!(azimuth_in_range(270.0, 0.0, 300.0));
        assert!(!azimuth_in_range(-45.0, 0.0, 300.0)); // = 315
        let g = ring(8);
        let cfg = LocalizeConfig {
            min_deg: 0.0,
            max_deg: 100.0,
            max_peaks: 0,
            ..Default::default()
        };
        let t = PeakTable::new(&g, &cfg).unwrap();
        let db = [5.0, 1.0, 2.0, 3.0, 1.0, 1.0, 1.0, 4.0f64];
        // Direction 0 (az 0) is excluded: (0, 360] wraps 0 to 360 > 100.
        assert_eq!(
            find_peaks(&db, &t).iter().map(|p| p.dir).collect::<Vec<_>>(),
            Vec::<usize>::new()
        );
    }
}
