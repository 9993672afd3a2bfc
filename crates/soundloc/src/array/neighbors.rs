//! Neighbour relations of grid points for the peak search: a ring's left and right
//! neighbours, and on a sphere the k nearest points by angle, made symmetric.

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
