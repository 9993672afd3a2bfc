//! Why a noise matrix K has no Cholesky factor, in words a user can act on.

use faer::{c64, Mat};

/// Why K (Hermitian, scaled) has no Cholesky factor, naming the channels (0-based, of
/// those in use) where the cause is one: silent ones (K_ii ≤ [`crate::correlation::SILENT`] · max K_jj: a
/// dead microphone) and pairs that carry one signal (|K_ij|² ≥ (1 − 10⁻⁹) K_ii K_jj: a
/// duplicated channel, unless all pairs do, as with one noise frame); a negative power
/// (not a correlation matrix); otherwise the likely causes are listed (too few frames,
/// one coherent source, channels that combine others: checking for them would cost a
/// decomposition of K for a message).
pub(super) fn not_positive_definite(k: &Mat<c64>) -> String {
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
            "is not positive definite: channel{s} {} (0-based, of those in use) {are} silent \
             in the noise (a dead or unplugged microphone?); leave {} out with the TF channel selection \
             (--channels, channels=[...])",
            list(&silent),
            if silent.len() == 1 { "it" } else { "them" }
        );
    }
    // A pair of channels with coherence 1, unless every pair has it (a K of rank one:
    // one noise frame, not a duplicated channel).
    let coherent = |i: usize, j: usize| k[(i, j)].norm_sqr() >= (1.0 - 1e-9) * d[i] * d[j];
    let pairs = || (0..m).flat_map(|j| (0..j).map(move |i| (i, j)));
    if let Some((i, j)) = pairs().find(|&(i, j)| coherent(i, j)) {
        if !pairs().all(|(i, j)| coherent(i, j)) {
            return format!(
                "is not positive definite: channels {i} and {j} (0-based, of those in use) \
                 carry the same signal (a duplicated channel?); leave one out with the TF \
                 channel selection (--channels, channels=[...])"
            );
        }
    }
    "is not positive definite (too few noise frames for the channel count, one coherent \
     noise source, or channels that are combinations of others?); give more noise frames or \
     use diagonal loading"
        .to_string()
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
        for frames in [1, 3] {
            let few = k_of(6, frames, |_| {});
            assert!(few.llt(Side::Lower).is_err());
            let e = not_positive_definite(&few);
            assert!(e.contains("too few noise frames"), "{frames}: {e}");
        }
    }
}
