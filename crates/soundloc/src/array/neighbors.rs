//! Neighbour relations of grid points for the peak search: a ring's left and right
//! neighbours, and on a sphere the k nearest points by angle, made symmetric; for grids
//! a user gives, also the nearest point in each quarter around a point that those miss
//! (a product grid's coarse axis).

use super::grid::RING_ELEVATION_TOLERANCE_DEG;

/// Left/right neighbours of an n-point ring in stored order: [i−1, i+1] mod n.
pub fn ring_neighbors(n: usize) -> Vec<Vec<usize>> {
    (0..n)
        .map(|i| {
            let mut v = Vec::with_capacity(2);
            if n > 1 {
                v.push((i + n - 1) % n);
                let r = (i + 1) % n;
                if !v.contains(&r) {
                    v.push(r);
                }
            }
            v
        })
        .collect()
}

pub(super) fn is_ring_order(points: &[[f64; 3]], neighbors: &[Vec<usize>]) -> bool {
    let n = points.len();
    if n < 3 || neighbors.len() != n {
        return false;
    }
    let el = |p: [f64; 3]| p[2].atan2((p[0] * p[0] + p[1] * p[1]).sqrt()).to_degrees();
    let e0 = el(points[0]);
    if points
        .iter()
        .any(|p| (el(*p) - e0).abs() > RING_ELEVATION_TOLERANCE_DEG || (p[0] == 0.0 && p[1] == 0.0))
    {
        return false;
    }
    // Signed azimuth steps between consecutive points, each wrapped into (-180, 180].
    let step = 360.0 / n as f64;
    let az = |p: [f64; 3]| p[1].atan2(p[0]).to_degrees();
    let steps: Vec<f64> = (0..n)
        .map(|i| {
            let mut d = az(points[(i + 1) % n]) - az(points[i]);
            while d > 180.0 {
                d -= 360.0;
            }
            while d <= -180.0 {
                d += 360.0;
            }
            d
        })
        .collect();
    let tol = (0.2 * step).min(1.0);
    let ccw = steps.iter().all(|d| (d - step).abs() < tol);
    let cw = steps.iter().all(|d| (d + step).abs() < tol);
    ccw || cw
}

pub(super) fn norm(p: [f64; 3]) -> f64 {
    (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()
}

pub(super) fn unit(p: [f64; 3]) -> [f64; 3] {
    let r = norm(p);
    if r > 0.0 {
        [p[0] / r, p[1] / r, p[2] / r]
    } else {
        [1.0, 0.0, 0.0]
    }
}

/// Angle between two unit vectors, radians.
pub(crate) fn angle_between(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    d.clamp(-1.0, 1.0).acos()
}

/// For unit vectors, the `k` nearest by angle of each point, then symmetrised (union).
/// Sorted by polar angle so the search scans outward and stops once the polar-angle gap
/// alone exceeds the current k-th best (angle(a, b) ≥ |θ_a − θ_b|).
pub fn nearest_neighbors(units: &[[f64; 3]], k: usize) -> Vec<Vec<usize>> {
    let n = units.len();
    let k = k.min(n.saturating_sub(1));
    let theta: Vec<f64> = units.iter().map(|u| u[2].clamp(-1.0, 1.0).acos()).collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| theta[a].total_cmp(&theta[b]));
    let mut rank = vec![0usize; n];
    for (r, &i) in order.iter().enumerate() {
        rank[i] = r;
    }
    let mut lists: Vec<Vec<usize>> = vec![Vec::new(); n];
    if k == 0 {
        return lists;
    }
    for i in 0..n {
        // best: (angle, index), kept sorted ascending, at most k long.
        let mut best: Vec<(f64, usize)> = Vec::with_capacity(k + 1);
        let consider = |j: usize, best: &mut Vec<(f64, usize)>| {
            let a = angle_between(units[i], units[j]);
            if best.len() < k || a < best[best.len() - 1].0 {
                let pos = best.partition_point(|&(b, bj)| (b, bj) < (a, j));
                best.insert(pos, (a, j));
                best.truncate(k);
            }
        };
        let r = rank[i];
        let (mut lo, mut hi) = (r, r + 1);
        loop {
            let bound = if best.len() < k {
                f64::INFINITY
            } else {
                best[k - 1].0
            };
            let down = if lo > 0 { Some(order[lo - 1]) } else { None };
            let up = if hi < n { Some(order[hi]) } else { None };
            let down_ok = down.filter(|&j| (theta[i] - theta[j]).abs() <= bound);
            let up_ok = up.filter(|&j| (theta[j] - theta[i]).abs() <= bound);
            if down_ok.is_none() && up_ok.is_none() {
                break;
            }
            if let Some(j) = down_ok {
                consider(j, &mut best);
                lo -= 1;
            }
            if let Some(j) = up_ok {
                consider(j, &mut best);
                hi += 1;
            }
        }
        lists[i] = best.into_iter().map(|(_, j)| j).collect();
    }
    // Symmetrise.
    let mut sym = lists.clone();
    for (i, l) in lists.iter().enumerate() {
        for &j in l {
            if !sym[j].contains(&i) {
                sym[j].push(i);
            }
        }
    }
    for l in &mut sym {
        l.sort_unstable();
    }
    sym
}

/// Quarters around a point, centred on its east, north, west and south (the tangent
/// plane's directions of growing azimuth and of growing elevation).
const QUARTERS: usize = 4;

/// The tangent plane's east and north at unit vector `u`.
fn frame_at(u: [f64; 3]) -> [[f64; 3]; 2] {
    let r = (u[0] * u[0] + u[1] * u[1]).sqrt();
    // East: z × u normalised (at a pole, any horizontal direction: x's).
    let east = if r > 1e-12 {
        [-u[1] / r, u[0] / r, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let north = [
        u[1] * east[2] - u[2] * east[1],
        u[2] * east[0] - u[0] * east[2],
        u[0] * east[1] - u[1] * east[0],
    ];
    [east, north]
}

/// The quarter (0 east, 1 north, 2 west, 3 south) in which unit vector `v` lies seen
/// from the point whose [`frame_at`] is `frame`, or None when they coincide.
fn quarter(frame: [[f64; 3]; 2], v: [f64; 3]) -> Option<usize> {
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (x, y) = (dot(v, frame[0]), dot(v, frame[1]));
    if x == 0.0 && y == 0.0 {
        return None;
    }
    let phi = y.atan2(x).to_degrees() + 45.0;
    Some((phi.rem_euclid(360.0) / 90.0) as usize % QUARTERS)
}

/// The symmetric k-nearest neighbours of `units` ([`nearest_neighbors`]) completed so that each
/// point also has its nearest point in every quarter around it (see [`quarter`]) that its
/// list misses, if one lies within `reach` times its farthest listed neighbour (or the
/// median of those over the grid, if larger); then
/// symmetrised. On a product grid (fine in azimuth, coarse in elevation) the k nearest
/// all lie along the point's own ring, and without this every point of a ridge across the
/// rings would count as a peak. Grids whose k nearest already surround each point (a
/// Fibonacci lattice's hexagons leave no quarter empty) are unchanged.
pub fn with_every_quarter(units: &[[f64; 3]], k: usize, reach: f64) -> Vec<Vec<usize>> {
    let mut lists = nearest_neighbors(units, k);
    let n = units.len();
    let theta: Vec<f64> = units.iter().map(|u| u[2].clamp(-1.0, 1.0).acos()).collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| theta[a].total_cmp(&theta[b]));
    // Each point's farthest listed neighbour, and their median: the grid's spacing (near
    // a product grid's poles a ring's points are much closer than its rings).
    let far: Vec<f64> = (0..n)
        .map(|i| {
            lists[i]
                .iter()
                .map(|&j| angle_between(units[i], units[j]))
                .fold(0.0, f64::max)
        })
        .collect();
    let mut sorted = far.clone();
    sorted.sort_by(f64::total_cmp);
    let typical = sorted.get(n / 2).copied().unwrap_or(0.0);
    let mut added: Vec<(usize, usize)> = Vec::new();
    for i in 0..n {
        let frame = frame_at(units[i]);
        let mut have = [false; QUARTERS];
        for &j in &lists[i] {
            if let Some(q) = quarter(frame, units[j]) {
                have[q] = true;
            }
        }
        let limit = reach * far[i].max(typical);
        if have.iter().all(|&h| h) || limit == 0.0 {
            continue;
        }
        // Candidates: polar angles within `limit` (angle(a, b) ≥ |θ_a − θ_b|).
        let lo = order.partition_point(|&j| theta[j] < theta[i] - limit);
        let mut best: [Option<(f64, usize)>; QUARTERS] = [None; QUARTERS];
        for &j in order[lo..].iter().take_while(|&&j| theta[j] <= theta[i] + limit) {
            let a = angle_between(units[i], units[j]);
            if j == i || a > limit {
                continue;
            }
            if let Some(q) = quarter(frame, units[j]).filter(|&q| !have[q]) {
                if best[q].is_none_or(|(b, bj)| (a, j) < (b, bj)) {
                    best[q] = Some((a, j));
                }
            }
        }
        added.extend(best.iter().flatten().map(|&(_, j)| (i, j)));
    }
    for (i, j) in added {
        for (a, b) in [(i, j), (j, i)] {
            if !lists[a].contains(&b) {
                lists[a].push(b);
            }
        }
    }
    for l in &mut lists {
        l.sort_unstable();
    }
    lists
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(az_deg: f64, colat_deg: f64) -> [f64; 3] {
        let (a, c) = (az_deg.to_radians(), colat_deg.to_radians());
        [c.sin() * a.cos(), c.sin() * a.sin(), c.cos()]
    }

    /// pyroomacoustics' azimuth × colatitude grid (2° × 4°, a user's `dim=3` call): the 6
    /// nearest of a point lie on its own ring; completed, every point also has the points
    /// above and below it (so a ridge across the rings is not a row of peaks), and its
    /// list still holds its 6 nearest.
    #[test]
    fn a_product_grids_points_see_the_rings_above_and_below() {
        let (n_az, n_col) = (180, 45);
        let mut units = Vec::new();
        for c in 0..n_col {
            for a in 0..n_az {
                units.push(dir(-180.0 + 2.0 * a as f64, 2.0 + 4.0 * c as f64));
            }
        }
        let near = nearest_neighbors(&units, 6);
        let full = with_every_quarter(&units, 6, 4.0);
        let idx = |a: usize, c: usize| c * n_az + a % n_az;
        let mut missing_before = 0;
        for c in 1..n_col - 1 {
            for a in 0..n_az {
                let i = idx(a, c);
                for j in [idx(a, c - 1), idx(a, c + 1)] {
                    assert!(full[i].contains(&j), "point {i} lacks {j}: {:?}", full[i]);
                    missing_before += usize::from(!near[i].contains(&j));
                }
                assert!(near[i].iter().all(|j| full[i].contains(j)));
            }
        }
        // Without the completion, 6120 of those 15 480 were missing.
        assert!(missing_before > n_az * (n_col - 2) / 2, "{missing_before}");
        // Symmetric.
        for (i, l) in full.iter().enumerate() {
            assert!(l.iter().all(|&j| full[j].contains(&i)));
        }
    }

    /// The built-in Fibonacci lattices already surround every point with their 6
    /// nearest: the completion changes nothing there.
    #[test]
    fn a_fibonacci_lattice_is_unchanged() {
        for n in [200, 2522] {
            let units = crate::array::geometry::fibonacci_sphere(n);
            assert_eq!(
                with_every_quarter(&units, 6, 4.0),
                nearest_neighbors(&units, 6),
                "{n}"
            );
        }
    }
}
