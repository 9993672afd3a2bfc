//! The defaults when no algorithm is named, chosen by the accuracy study
//! (`soundloc bench --accuracy`, docs/accuracy.md): the robust GEVD with a noise source,
//! the room default (NormMUSIC) without one. A named algorithm runs exactly as HARK's.

use super::{LocalizerSpec, NoiseSource};
use crate::config::{Algorithm, LocalizeConfig, Numerator};
use crate::noise::policy::NoiseUpdate;

impl LocalizerSpec {
    /// Whether a noise source or an online update is given.
    pub fn noise_given(&self) -> bool {
        self.noise != NoiseSource::None || self.noise_update != NoiseUpdate::Fixed
    }

    /// The algorithm that runs, and a note when a named one runs without its K. The
    /// defaults' own note comes from [`LocalizerSpec::resolved_analysis`], which knows the
    /// array's size.
    pub fn resolved_algorithm(&self) -> (Algorithm, Option<String>) {
        match self.algorithm {
            Some(a) if a.uses_noise() && !self.noise_given() => (
                a,
                Some(format!("{} without a noise source: K = identity", a.name())),
            ),
            Some(a) => (a, None),
            None if self.noise_given() => (Algorithm::Gevd, None),
            None => (Algorithm::Sevd, None),
        }
    }

    /// The analysis that runs for an array of `num_mics` microphones: `analysis` with the
    /// resolved algorithm and, when no algorithm is named, the settings the accuracy study
    /// chose (`soundloc bench --accuracy`, docs/accuracy.md):
    /// - with a noise source (the robust default): the textbook GEVD with a signal subspace
    ///   of max(`num_sources`, ⌊M/2⌋) dimensions ([`robust_subspace_dim`]) — reverberation
    ///   and the rotors' residue take dimensions of their own, the more the larger the
    ///   array, while half of them stay for the noise subspace — the numerator ‖a‖·‖a_w‖ ([`Numerator::Geometric`]: a loud noise source
    ///   that K describes is not left in the spectrum at full strength) and sub-grid
    ///   refinement;
    /// - without one (the room default): NormMUSIC, the SEVD with every bin's spectrum
    ///   normalised to a maximum of 1, with a signal subspace of min(M/2, round(2√M))
    ///   dimensions ([`room_subspace_dim`]), coherence normalisation
    ///   ([`LocalizeConfig::coherence`]: real arrays' gain mismatch cancels) unless
    ///   `coherence` says otherwise, and sub-grid refinement.
    ///
    /// An explicit `subspace_dim` is kept. An algorithm named explicitly runs as asked
    /// (HARK-faithful). On 2 microphones the default `num_sources` (2) becomes 1 for the
    /// MUSIC family (one signal dimension is all they leave), with a note.
    pub fn resolved_analysis(&self, num_mics: usize) -> (LocalizeConfig, Option<String>) {
        let (algorithm, note) = self.resolved_algorithm();
        let mut c = LocalizeConfig {
            algorithm,
            ..self.analysis.clone()
        };
        // Two microphones leave MUSIC one signal dimension: HARK's NUM_SOURCE default (2)
        // becomes 1 there, with a note, instead of refusing the run (any other count is
        // the user's and is checked by the plan).
        let pair =
            num_mics == 2 && c.num_sources == LocalizeConfig::default().num_sources && c.algorithm.is_music();
        if pair {
            c.num_sources = 1;
        }
        let pair_note = pair.then(|| {
            "2 microphones: MUSIC resolves one source, so one peak per window is reported \
             (--num-sources 1, num_sources=1 in Python; srp-phat reports more)"
                .to_string()
        });
        let (analysis, note) = self.resolved_defaults(c, num_mics, note);
        let note = match (note, pair_note) {
            (Some(a), Some(b)) => Some(format!("{a}; {b}")),
            (a, b) => a.or(b),
        };
        (analysis, note)
    }

    /// [`LocalizerSpec::resolved_analysis`] after the algorithm and the source count.
    fn resolved_defaults(
        &self,
        mut c: LocalizeConfig,
        num_mics: usize,
        note: Option<String>,
    ) -> (LocalizeConfig, Option<String>) {
        let (named, noise) = (self.algorithm.is_some(), self.noise_given());
        c.coherence = self.coherence.unwrap_or(c.coherence || (!named && !noise));
        if !named {
            if c.subspace_dim.is_none() {
                let ns = if noise {
                    robust_subspace_dim(c.num_sources, num_mics)
                } else {
                    room_subspace_dim(c.num_sources, num_mics)
                };
                if ns < num_mics && ns != c.num_sources {
                    c.subspace_dim = Some(ns);
                }
            }
            c.normalize_bins |= !noise;
            c.refine = true;
            if noise {
                c.numerator = Numerator::Geometric;
            }
        }
        c.normalize_bins = self.normalize_bins.unwrap_or(c.normalize_bins);
        c.refine = self.refine.unwrap_or(c.refine);
        c.numerator = self.numerator.unwrap_or(c.numerator);
        let preceding = matches!(self.noise_update, NoiseUpdate::Preceding { .. });
        if !named && !preceding && c.algorithm != Algorithm::SrpPhat {
            c.onset_frames = super::ONSET_FRAMES;
        }
        c.onset_frames = self.onset_frames.unwrap_or(c.onset_frames);
        if !named {
            let refined = if c.refine {
                "sub-grid refinement"
            } else {
                "no sub-grid refinement"
            };
            // The note says what runs: the subspace actually used, and for NormMUSIC the
            // power scale (tracker thresholds tuned on SEVD's do not carry over).
            let dim = c.signal_dim();
            let coherence = if c.coherence {
                "coherence normalisation (the microphones' gain mismatch cancels; off: --no-coherence, coherence=False in Python)"
            } else {
                "no coherence normalisation"
            };
            let onset = if c.onset_frames > 0 {
                format!(
                    ", onset weighting over {} frames (each frame counts by how much of its power \
                     is new, so reverberation counts less; off: --onset 0, onset_frames=0 in Python)",
                    c.onset_frames
                )
            } else {
                ", no onset weighting".to_string()
            };
            let note = if noise {
                // Coherence stays opt-in here (docs/accuracy.md, "Imperfect arrays in rotor
                // noise"): the note says when to turn it on.
                let gains = if c.coherence {
                    "coherence normalisation (the steering vectors take K's channel levels)"
                } else {
                    "no coherence normalisation (microphones whose gains differ from the \
                     transfer functions', e.g. an uncalibrated array with free-field ones \
                     from its geometry: --coherence)"
                };
                let normalised = if c.normalize_bins {
                    ", every bin's spectrum normalised (NormMUSIC's scale)"
                } else {
                    ""
                };
                let numerator = match c.numerator {
                    Numerator::Geometric => {
                        "the numerator ‖a‖·‖a_w‖ (a loud noise source that K holds stays below the \
                         talkers instead of standing out at its own strength; spec §5's ‖a‖²: \
                         --numerator raw)"
                    }
                    Numerator::Whitened => "the whitened numerator ‖a_w‖²",
                    Numerator::Raw => "spec §5's numerator ‖a‖²",
                };
                format!(
                    "a noise source was given: using the robust default, the textbook GEVD with a \
                     signal subspace of {dim} of {num_mics} (max(--num-sources, M/2) unless \
                     --subspace-dim){normalised}, {numerator}, {gains}{onset} and {refined} (HARK's: \
                     name --algorithm)"
                )
            } else {
                let music = if c.normalize_bins {
                    "NormMUSIC (SEVD with every bin's spectrum normalised; powers on its scale, \
                     at most 10·log10(bins + 1) dB)"
                } else {
                    "the SEVD without per-bin normalisation (powers on MUSIC's scale)"
                };
                format!(
                    "no noise source: using the room default, {music} with a \
                     signal subspace of {dim} of {num_mics} (min(M/2, round(2√M)) unless \
                     --subspace-dim), {coherence}{onset} and {refined} (HARK's plain SEVD: \
                     --algorithm sevd; with a noise source, the GEVD)"
                )
            };
            return (c, Some(note));
        }
        (c, note)
    }
}

/// The robust default's signal-subspace dimension for `num_sources` reported sources on
/// `num_mics` microphones: max(num_sources, ⌊M/2⌋), below M.
///
/// Half the array: on the 60-mic sphere the accuracy study's tuning seeds kept gaining up
/// to M/2 = 30 (docs/accuracy.md, "the subspace grows with the array"). Until 2026-12-01
/// the rule was max(num_sources + 2, M/2), which on arrays of 4–6 microphones left a
/// single noise vector (3 of 4, 5 of 6 for three talkers) and near-random directions in
/// reverberant rooms with a point or diffuse noise source (a user-style sweep with
/// pyroomacoustics scenes: 4-mic arrays 5–40 % of talker-windows within 10°, against
/// 25–65 % with ⌊M/2⌋; docs/accuracy.md, "Small arrays").
pub fn robust_subspace_dim(num_sources: usize, num_mics: usize) -> usize {
    (num_mics / 2)
        .max(num_sources)
        .min(num_mics.saturating_sub(1))
        .max(num_sources)
}

/// The default's signal-subspace dimension without a noise source (NormMUSIC) for
/// `num_sources` reported sources on `num_mics` microphones: min(M/2, round(2√M)), at
/// least `num_sources`, below M. Chosen on the room study's tuning seeds with arrays
/// that differ from their model (`soundloc bench --accuracy --scene room
/// --position-error-mm 0.5 --gain-error-db 0.5`, docs/accuracy.md): 4 of 8 on the 3.65 cm
/// ring (6 was better with a perfect array but collapsed with an imperfect one, as on the
/// real 8-channel recording), 15 of 60 on the 10 cm sphere.
pub fn room_subspace_dim(num_sources: usize, num_mics: usize) -> usize {
    let d = (2.0 * (num_mics as f64).sqrt()).round() as usize;
    d.min(num_mics / 2)
        .max(num_sources)
        .min(num_mics.saturating_sub(1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::array::grid::GridSpec;

    /// The robust default's subspace: half the array (at least num_sources, below M),
    /// so small arrays keep half their dimensions for the noise; a named algorithm or an
    /// explicit --subspace-dim is left alone.
    #[test]
    fn the_robust_subspace_grows_with_the_array() {
        assert_eq!(robust_subspace_dim(2, 8), 4);
        assert_eq!(robust_subspace_dim(3, 8), 4);
        assert_eq!(robust_subspace_dim(5, 8), 5);
        assert_eq!(robust_subspace_dim(2, 60), 30);
        assert_eq!(robust_subspace_dim(2, 16), 8);
        assert_eq!(robust_subspace_dim(1, 2), 1);
        assert_eq!(robust_subspace_dim(1, 4), 2);
        assert_eq!(robust_subspace_dim(2, 4), 2);
        assert_eq!(robust_subspace_dim(3, 4), 3);
        assert_eq!(robust_subspace_dim(3, 6), 3);
        let mut spec = LocalizerSpec::free_field(vec![[0.0; 3]; 60], GridSpec::Sphere { n: 100 });
        spec.noise = NoiseSource::Range {
            start_s: 0.0,
            end_s: 1.0,
        };
        let (c, note) = spec.resolved_analysis(60);
        assert_eq!(
            (c.algorithm, c.subspace_dim, c.refine, c.coherence),
            (Algorithm::Gevd, Some(30), true, false)
        );
        let note = note.unwrap();
        assert!(note.contains("M/2"));
        assert!(
            note.contains("no coherence normalisation")
                && note.contains("uncalibrated array")
                && note.contains("--coherence)"),
            "coherence stays opt-in with a noise source, and the note says when to turn it on: {note}"
        );
        spec.coherence = Some(true);
        let (c, note) = spec.resolved_analysis(60);
        assert!(c.coherence && note.unwrap().contains("K's channel levels"));
        assert_eq!(
            c.label(),
            "gevd (subspace 30, coherence, geometric numerator, refined)"
        );
        spec.coherence = None;
        assert_eq!(c.numerator, Numerator::Geometric);
        spec.numerator = Some(Numerator::Raw);
        let (c, note) = spec.resolved_analysis(60);
        assert!(c.numerator.is_raw() && note.unwrap().contains("spec §5's numerator ‖a‖²"));
        spec.numerator = None;
        spec.analysis.subspace_dim = Some(6);
        assert_eq!(spec.resolved_analysis(60).0.subspace_dim, Some(6));
        spec.analysis.subspace_dim = None;
        spec.algorithm = Some(Algorithm::Gevd);
        let (c, _) = spec.resolved_analysis(60);
        assert_eq!(
            (c.subspace_dim, c.refine, c.numerator),
            (None, false, Numerator::Raw),
            "named algorithms run as asked"
        );
    }

    /// Without a noise source and no algorithm named: NormMUSIC, min(M/2, round(2√M))
    /// signal dimensions (at least num_sources), coherence normalisation (unless turned
    /// off), refined; `--algorithm sevd` is HARK's plain SEVD.
    #[test]
    fn the_room_default_is_normmusic_with_a_larger_subspace() {
        assert_eq!(room_subspace_dim(2, 8), 4);
        assert_eq!(room_subspace_dim(1, 8), 4);
        assert_eq!(room_subspace_dim(2, 60), 15);
        assert_eq!(room_subspace_dim(2, 16), 8);
        assert_eq!(room_subspace_dim(2, 6), 3);
        assert_eq!(room_subspace_dim(2, 4), 2);
        assert_eq!(room_subspace_dim(3, 4), 3);
        assert_eq!(room_subspace_dim(1, 2), 1);
        let mut spec = LocalizerSpec::free_field(vec![[0.0; 3]; 8], GridSpec::Sphere { n: 100 });
        let (c, note) = spec.resolved_analysis(8);
        assert_eq!(
            (
                c.algorithm,
                c.subspace_dim,
                c.normalize_bins,
                c.refine,
                c.coherence
            ),
            (Algorithm::Sevd, Some(4), true, true, true)
        );
        let note = note.unwrap();
        assert!(note.contains("NormMUSIC") && note.contains("off: --no-coherence"));
        assert_eq!(c.label(), "normmusic (subspace 4, coherence, refined)");
        spec.coherence = Some(false);
        let (c, note) = spec.resolved_analysis(8);
        assert!(!c.coherence && note.unwrap().contains("no coherence normalisation"));
        assert_eq!(c.label(), "normmusic (subspace 4, refined)");
        spec.coherence = None;
        // Refinement and per-bin normalisation turned off by name, also in the default
        // (its SEVD's powers on MUSIC's scale); the note says so.
        spec.refine = Some(false);
        spec.normalize_bins = Some(false);
        let (c, note) = spec.resolved_analysis(8);
        assert_eq!(
            (c.refine, c.normalize_bins, c.subspace_dim),
            (false, false, Some(4))
        );
        assert_eq!(c.label(), "sevd (subspace 4, coherence)");
        let note = note.unwrap();
        assert!(
            note.contains("without per-bin normalisation") && note.contains("no sub-grid refinement"),
            "{note}"
        );
        spec.refine = None;
        spec.normalize_bins = None;
        assert_eq!(spec.resolved_analysis(60).0.subspace_dim, Some(15));
        spec.analysis.subspace_dim = Some(3);
        let (c, note) = spec.resolved_analysis(8);
        assert_eq!(c.subspace_dim, Some(3));
        assert!(
            note.unwrap().contains("3 of 8"),
            "the note names the subspace used"
        );
        spec.analysis.subspace_dim = None;
        spec.algorithm = Some(Algorithm::Sevd);
        let (c, note) = spec.resolved_analysis(8);
        assert_eq!(
            (c.subspace_dim, c.normalize_bins, c.refine, c.coherence, note),
            (None, false, false, false, None),
            "a named algorithm runs as asked"
        );
        assert_eq!(c.label(), "sevd");
        spec.refine = Some(true);
        assert!(
            spec.resolved_analysis(8).0.refine,
            "asked for, refinement goes with any algorithm"
        );
        spec.refine = None;
        spec.coherence = Some(true);
        assert_eq!(
            spec.resolved_analysis(8).0.label(),
            "sevd (coherence)",
            "asked for by name, coherence goes with any algorithm"
        );
    }
}
