//! Why a noise matrix K has no Cholesky factor, in words a user can act on.

use faer::{c64, Mat, MatRef, Side};

/// A pivot L_ii² of K's Cholesky factor at most this fraction of K_ii: channel i is a
/// combination of the channels before it to twelve digits.
const PIVOT_FLOOR: f64 = 1e-12;

/// An eigenvalue of K at most this fraction of its largest is a null value.
const NULL: f64 = 1e-10;

/// K (Hermitian, scaled) passed its Cholesky factorisation `l` only through rounding: a
/// pivot L_ii² ≤ [`PIVOT_FLOOR`] · K_ii (a duplicated or summed channel that rounding
/// left barely positive; whitening would magnify rounding a millionfold in amplitude).
/// Returns [`not_positive_definite`]'s diagnosis then.
pub(super) fn numerically_singular(k: &Mat<c64>, l: MatRef<'_, c64>) -> Option<String> {
    let weak = (0..k.nrows()).any(|i| l[(i, i)].re.powi(2) <= PIVOT_FLOOR * k[(i, i)].re);
    weak.then(|| diagnose(k, "is singular to rounding"))
}

/// Why K (Hermitian, scaled) has no Cholesky factor, naming the channels (0-based, of
/// those in use) where the cause is one: silent ones (K_ii ≤ [`crate::correlation::SILENT`] · max K_jj: a
/// dead microphone) and pairs that carry one signal (|K_ij|² ≥ (1 − 10⁻⁹) K_ii K_jj: a
/// duplicated channel, unless all pairs do, as with one noise frame); a negative power
/// or eigenvalue (not a correlation matrix); channels that are linearly dependent (K
/// has one null vector, and it involves some channels only: one of them combines the
/// others); else K's rank (too few frames, one coherent source).
pub(super) fn not_positive_definite(k: &Mat<c64>) -> String {
    diagnose(k, "is not positive definite")
}

/// [`not_positive_definite`]'s diagnosis, `head` saying what K is.
fn diagnose(k: &Mat<c64>, head: &str) -> String {
    use crate::correlation::SILENT;
    let m = k.nrows();
    let d: Vec<f64> = (0..m).map(|i| k[(i, i)].re).collect();
    let top = d.iter().copied().fold(0.0f64, f64::max);
    let list = |v: &[usize]| v.iter().map(|c| c.to_string()).collect::<Vec<_>>().join(", ");
    if let Some(i) = (0..m).find(|&i| d[i] < 0.0) {
        return format!(
            "is not a correlation matrix: channel {i} (0-based, of those in use) has a negative \
             power"
        );
    }
    let silent: Vec<usize> = (0..m).filter(|&i| d[i] <= SILENT * top).collect();
    if !silent.is_empty() {
        let (s, are) = if silent.len() == 1 {
            ("", "is")
        } else {
            ("s", "are")
        };
        return format!(
            "{head}: channel{s} {} (0-based, of those in use) {are} silent \
             in the noise (a dead or unplugged microphone?); leave {} out with the TF channel selection \
             (--channels, channels=[...])",
            list(&silent),
            if silent.len() == 1 { "it" } else { "them" }
        );
    }
    let pairs = || (0..m).flat_map(|j| (0..j).map(move |i| (i, j)));
    if let Some((i, j)) = pairs().find(|&(i, j)| k[(i, j)].norm_sqr() > (1.0 + 1e-9) * d[i] * d[j]) {
        return format!(
            "is not a correlation matrix: |K_ij| of channels {i} and {j} (0-based, of those in \
             use) exceeds √(K_ii K_jj)"
        );
    }
    // A pair of channels with coherence 1, unless every pair has it (a K of rank one:
    // one noise frame, not a duplicated channel).
    let coherent = |i: usize, j: usize| k[(i, j)].norm_sqr() >= (1.0 - 1e-9) * d[i] * d[j];
    if let Some((i, j)) = pairs().find(|&(i, j)| coherent(i, j)) {
        if !pairs().all(|(i, j)| coherent(i, j)) {
            return format!(
                "{head}: channels {i} and {j} (0-based, of those in use) \
                 carry the same signal (a duplicated channel?); leave one out with the TF \
                 channel selection (--channels, channels=[...])"
            );
        }
    }
    // K's null vectors: which channels combine (K v = 0 ⇔ Σ_i v_i x_i = 0 in every frame).
    let Ok(evd) = k.self_adjoint_eigen(Side::Lower) else {
        return format!("{head}, and its eigendecomposition failed (non-finite values?)");
    };
    let (u, lam) = (evd.U(), evd.S());
    let top = (0..m).map(|i| lam[i].re).fold(0.0f64, f64::max);
    if let Some(i) = (0..m).find(|&i| lam[i].re < -NULL * top) {
        return format!(
            "is not a correlation matrix: it has a negative eigenvalue ({:.1e} of the largest); \
             was it estimated from recordings?",
            lam[i].re / top
        );
    }
    let null: Vec<usize> = (0..m).filter(|&i| lam[i].re <= NULL * top).collect();
    if let [n] = null[..] {
        let v: Vec<f64> = (0..m).map(|i| u[(i, n)].norm()).collect();
        let vmax = v.iter().copied().fold(0.0f64, f64::max);
        let involved: Vec<usize> = (0..m).filter(|&i| v[i] >= 1e-3 * vmax).collect();
        if involved.len() < m {
            return format!(
                "{head}: channels {} (0-based, of those in use) are linearly \
                 dependent in the noise (one is a combination of the others: a summed, bridged \
                 or mis-wired channel?); leave one of them out with the TF channel selection \
                 (--channels, channels=[...]), or, for noise-free synthetic input, use diagonal \
                 loading (--diagonal-loading, diagonal_loading= in Python)",
                list(&involved)
            );
        }
    }
    format!(
        "{head}: it has rank {} of {m} (too few noise frames for the channel \
         count, at least {m} and better {}, one coherent noise source, or a channel that \
         combines all the others?); give more noise frames or use diagonal loading \
         (--diagonal-loading, diagonal_loading= in Python)",
        m - null.len().max(1),
        10 * m
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// K of `frames` random snapshots of `m` channels, with `edit` applied to each.
    fn k_of(m: usize, frames: usize, edit: impl Fn(&mut [c64])) -> Mat<c64> {
        let mut seed = 5u64;
        let mut rnd = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut k = Mat::<c64>::zeros(m, m);
        let mut x = vec![c64::new(0.0, 0.0); m];
        for _ in 0..frames {
            for v in x.iter_mut() {
                *v = c64::new(rnd(), rnd());
            }
            edit(&mut x);
            for i in 0..m {
                for j in 0..m {
                    k[(i, j)] += x[i] * x[j].conj();
                }
            }
        }
        k
    }

    /// Each cause is named with its channels, and a matrix of that cause indeed has no
    /// Cholesky factor.
    #[test]
    fn silent_and_duplicated_channels_and_too_few_frames_are_told_apart() {
        use faer::Side;
        let dead = k_of(6, 100, |x| x[3] = c64::new(0.0, 0.0));
        assert!(dead.llt(Side::Lower).is_err());
        let e = not_positive_definite(&dead);
        assert!(
            e.contains("channel 3 (0-based, of those in use) is silent"),
            "{e}"
        );
        let two = k_of(6, 100, |x| {
            x[1] = c64::new(0.0, 0.0);
            x[4] = c64::new(0.0, 0.0);
        });
        assert!(not_positive_definite(&two).contains("channels 1, 4 (0-based, of those in use) are silent"));
        let dup = k_of(6, 100, |x| x[5] = x[2] * c64::new(0.0, -2.0));
        assert!(dup.llt(Side::Lower).is_err());
        let e = not_positive_definite(&dup);
        assert!(
            e.contains("channels 2 and 5 (0-based, of those in use) carry the same signal"),
            "{e}"
        );
        let mut neg = k_of(6, 100, |_| {});
        neg[(2, 2)].re = -1.0;
        assert!(
            not_positive_definite(&neg).contains("channel 2 (0-based, of those in use) has a negative power")
        );
        for frames in [1, 3, 5] {
            let few = k_of(6, frames, |_| {});
            assert!(few.llt(Side::Lower).is_err());
            let e = not_positive_definite(&few);
            assert!(
                e.contains(&format!("it has rank {frames} of 6 (too few noise frames")),
                "{frames}: {e}"
            );
        }
        // A channel that sums two others: the three are named, whether rounding leaves K
        // without a factor or (checked the same way) with a pivot at rounding level.
        let summed = k_of(6, 100, |x| x[4] = x[0] * c64::new(0.3, 0.1) + x[3] * 0.7);
        let e = not_positive_definite(&summed);
        assert!(
            e.contains("channels 0, 3, 4 (0-based, of those in use) are linearly dependent"),
            "{e}"
        );
        // Rounding leaves this one a factor (it passed unnoticed before), and a channel
        // that combines others to seven digits is caught the same way.
        let l = summed.llt(Side::Lower).expect("rounding leaves a factor");
        let why = numerically_singular(&summed, l.L()).expect("caught");
        assert_eq!(
            why,
            e.replace("is not positive definite", "is singular to rounding")
        );
        let near = k_of(6, 100, |x| {
            x[4] = x[0] * c64::new(0.3, 0.1) + x[3] * 0.7 + x[4] * 1e-7
        });
        let why = numerically_singular(&near, near.llt(Side::Lower).unwrap().L());
        assert!(why.is_some_and(|w| w.contains("channels 0, 3, 4")));
        let fine = k_of(6, 100, |x| {
            x[4] = x[0] * c64::new(0.3, 0.1) + x[3] * 0.7 + x[4] * 1e-3
        });
        assert_eq!(
            numerically_singular(&fine, fine.llt(Side::Lower).unwrap().L()),
            None
        );
        // Not correlation matrices: every pair within |K_ij|² < K_ii K_jj, but the sum of
        // the channels has a negative power; then a pair beyond it.
        let mut indefinite = Mat::<c64>::from_fn(6, 6, |i, j| c64::new(if i == j { 1.0 } else { -0.5 }, 0.0));
        assert!(indefinite.llt(Side::Lower).is_err());
        let e = not_positive_definite(&indefinite);
        assert!(
            e.contains("has a negative eigenvalue (-1.0e0 of the largest)"),
            "{e}"
        );
        indefinite[(4, 1)] = c64::new(0.0, 2.0);
        indefinite[(1, 4)] = c64::new(0.0, -2.0);
        let e = not_positive_definite(&indefinite);
        assert!(
            e.contains("|K_ij| of channels 1 and 4 (0-based, of those in use) exceeds"),
            "{e}"
        );
    }
}
