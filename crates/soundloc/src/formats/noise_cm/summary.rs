//! Per-bin trace, eigenvalues and conditioning of a [`NoiseCm`] (what
//! `soundloc noisecm inspect` prints; see the [parent module docs](super)).

use num_complex::Complex;

use super::NoiseCm;

impl NoiseCm {
    /// Per-bin trace, eigenvalue range and condition number (see the module docs).
    pub fn summary(&self) -> NoiseCmSummary {
        let m = self.num_mics;
        let bins: Vec<BinStats> = (0..self.num_bins()).map(|k| bin_stats(self.get(k), m)).collect();
        let finite_cond: Vec<f64> = bins
            .iter()
            .map(|b| b.condition)
            .filter(|c| c.is_finite())
            .collect();
        let traces: Vec<f64> = bins.iter().map(|b| b.trace).collect();
        NoiseCmSummary {
            num_mics: m,
            nfft: self.nfft,
            num_bins: self.num_bins(),
            not_positive_definite: bins.iter().filter(|b| !b.condition.is_finite()).count(),
            near_singular: bins
                .iter()
                .filter(|b| (NEAR_SINGULAR..f64::INFINITY).contains(&b.condition))
                .count(),
            trace_min: traces.iter().copied().fold(f64::INFINITY, f64::min),
            trace_median: median(&traces),
            trace_max: traces.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            condition_median: median(&finite_cond),
            worst_bin: bins
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.condition.total_cmp(&b.1.condition))
                .map_or(0, |(k, _)| k),
            bins,
        }
    }
}

/// A condition number from which K is singular to rounding as far as whitening goes: the
/// plan refuses such a K where its Cholesky factor shows a channel that combines others
/// to twelve digits (a pivot L_ii² ≤ 10⁻¹² K_ii, which needs this condition or more).
pub const NEAR_SINGULAR: f64 = 1e12;

/// One bin's numbers in a [`NoiseCmSummary`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BinStats {
    /// Trace of K_k (real part): the total noise power over the microphones.
    pub trace: f64,
    /// Smallest eigenvalue of the Hermitian part of K_k.
    pub min_eigenvalue: f64,
    /// Largest eigenvalue of the Hermitian part of K_k.
    pub max_eigenvalue: f64,
    /// λ_max / λ_min; infinite when λ_min ≤ 0 (not positive definite).
    #[serde(serialize_with = "finite_or_null")]
    pub condition: f64,
}

/// What `soundloc noisecm inspect` prints: shape and per-bin conditioning of a [`NoiseCm`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct NoiseCmSummary {
    /// Microphones (channels) M.
    pub num_mics: usize,
    /// FFT length N.
    pub nfft: usize,
    /// Bins, N/2 + 1.
    pub num_bins: usize,
    /// Bins whose K is not positive definite.
    pub not_positive_definite: usize,
    /// Positive definite bins with a condition number of at least [`NEAR_SINGULAR`].
    pub near_singular: usize,
    /// Smallest trace over the bins.
    pub trace_min: f64,
    /// Median trace.
    pub trace_median: f64,
    /// Largest trace.
    pub trace_max: f64,
    /// Median condition number over the positive definite bins (NaN when there are none).
    #[serde(serialize_with = "finite_or_null")]
    pub condition_median: f64,
    /// The bin with the largest condition number.
    pub worst_bin: usize,
    /// Per bin, index = bin.
    pub bins: Vec<BinStats>,
}

impl std::fmt::Display for NoiseCmSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "microphones      {}", self.num_mics)?;
        writeln!(f, "nfft             {}", self.nfft)?;
        writeln!(
            f,
            "bins             {} (0..={})",
            self.num_bins,
            self.num_bins - 1
        )?;
        writeln!(
            f,
            "trace            {:.4e} … {:.4e} (median {:.4e})",
            self.trace_min, self.trace_max, self.trace_median
        )?;
        writeln!(
            f,
            "condition        median {:.4e}, worst {:.4e} at bin {}",
            self.condition_median,
            self.bins.get(self.worst_bin).map_or(f64::NAN, |b| b.condition),
            self.worst_bin
        )?;
        writeln!(f, "not pos. def.    {} bin(s)", self.not_positive_definite)?;
        writeln!(
            f,
            "cond >= 1e12     {} bin(s) (singular to rounding where a channel combines others: \
             refused for localization)",
            self.near_singular
        )
    }
}

fn finite_or_null<S: serde::Serializer>(v: &f64, s: S) -> std::result::Result<S::Ok, S::Error> {
    if v.is_finite() {
        s.serialize_f64(*v)
    } else {
        s.serialize_none()
    }
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// Trace and eigenvalues of the Hermitian part of one bin's K.
fn bin_stats(k: &[Complex<f64>], m: usize) -> BinStats {
    let h = faer::Mat::<faer::c64>::from_fn(m, m, |i, j| (k[i * m + j] + k[j * m + i].conj()) * 0.5);
    let trace = (0..m).map(|i| k[i * m + i].re).sum();
    let (lo, hi) = match h.self_adjoint_eigenvalues(faer::Side::Lower) {
        // Sorted in nondecreasing order.
        Ok(ev) if !ev.is_empty() => (ev[0], ev[ev.len() - 1]),
        _ => (f64::NAN, f64::NAN),
    };
    let condition = if lo > 0.0 { hi / lo } else { f64::INFINITY };
    BinStats {
        trace,
        min_eigenvalue: lo,
        max_eigenvalue: hi,
        condition,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_reports_conditioning() {
        let mut cm = NoiseCm::identity(2, 8);
        // Bin 1: diag(4, 1) → condition 4; bin 2: rank one → not positive definite.
        cm.data[4] = Complex::new(4.0, 0.0);
        for v in &mut cm.data[8..12] {
            *v = Complex::new(1.0, 0.0);
        }
        let s = cm.summary();
        assert_eq!((s.num_mics, s.nfft, s.num_bins), (2, 8, 5));
        assert!((s.bins[1].condition - 4.0).abs() < 1e-12);
        assert!((s.bins[1].trace - 5.0).abs() < 1e-12);
        assert!(!s.bins[2].condition.is_finite());
        assert_eq!((s.not_positive_definite, s.worst_bin, s.near_singular), (1, 2, 0));
        assert!((s.condition_median - 1.0).abs() < 1e-12);
        let text = s.to_string();
        assert!(text.contains("not pos. def.    1 bin"), "{text}");
        assert!(text.contains("cond >= 1e12     0 bin"), "{text}");
        // Bin 3: diag(1, 1e-13), positive definite but singular to rounding.
        cm.data[15] = Complex::new(1e-13, 0.0);
        let s = cm.summary();
        assert_eq!((s.not_positive_definite, s.near_singular), (1, 1));
        assert!(s.to_string().contains("cond >= 1e12     1 bin"));
        let json = serde_json::to_string(&s).unwrap();
        assert!(json.contains("\"condition\":null"), "{json}");
    }
}
