//! The study's variants: the configurations compared, one change at a time.

use super::scenes::StudyArray;
use crate::config::{Algorithm, LocalizeConfig, Numerator};
use crate::localizer::ONSET_FRAMES;

/// A named configuration to compare.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Variant {
    /// Short name for the table.
    pub name: String,
    /// The configuration (its `max_peaks` is set per scene to the talker count).
    pub config: LocalizeConfig,
}

/// The variants of the study: the textbook GEVD and HARK's algorithms as they are, then
/// one change at a time and the promising combinations.
pub fn variants(period: usize) -> Vec<Variant> {
    let base = LocalizeConfig {
        algorithm: Algorithm::Gevd,
        period,
        ..Default::default()
    };
    let v = |name: &str, f: &dyn Fn(&mut LocalizeConfig)| {
        let mut c = base.clone();
        f(&mut c);
        Variant {
            name: name.into(),
            config: c,
        }
    };
    vec![
        v("gevd (textbook, Ns=2)", &|_| {}),
        v("sevd", &|c| c.algorithm = Algorithm::Sevd),
        v("gsvd (HARK)", &|c| c.algorithm = Algorithm::Gsvd),
        v("gevd-hark", &|c| c.algorithm = Algorithm::GevdHark),
        v("srp-phat", &|c| c.algorithm = Algorithm::SrpPhat),
        v("normmusic (sevd)", &|c| {
            c.algorithm = Algorithm::Sevd;
            c.normalize_bins = true
        }),
        v("gevd Ns=1", &|c| c.num_sources = 1),
        v("gevd Ns=3", &|c| c.num_sources = 3),
        v("gevd Ns=4", &|c| c.num_sources = 4),
        v("gevd no eigen weight", &|c| c.eigenvalue_weight = false),
        v("gevd normalized bins", &|c| c.normalize_bins = true),
        v("gevd 300-4000 Hz", &|c| {
            c.lower_freq_hz = 300.0;
            c.upper_freq_hz = 4000.0
        }),
        v("gevd 1000-4000 Hz", &|c| {
            c.lower_freq_hz = 1000.0;
            c.upper_freq_hz = 4000.0
        }),
        v("gevd Ns=3 normalized", &|c| {
            c.num_sources = 3;
            c.normalize_bins = true
        }),
        v("gevd Ns=3 normalized 300-4000", &|c| {
            c.num_sources = 3;
            c.normalize_bins = true;
            c.lower_freq_hz = 300.0;
            c.upper_freq_hz = 4000.0
        }),
        v("gevd Ns=3 W=25", &|c| {
            c.num_sources = 3;
            c.window = 25
        }),
        v("gevd Ns=3 W=100", &|c| {
            c.num_sources = 3;
            c.window = 100
        }),
        v("gevd Ns=3 no eigen weight", &|c| {
            c.num_sources = 3;
            c.eigenvalue_weight = false
        }),
        v("gevd Ns=3 loading 1e-2", &|c| {
            c.num_sources = 3;
            c.diagonal_loading = 1e-2
        }),
        v("gevd subspace 4 refined", &|c| {
            c.subspace_dim = Some(4);
            c.refine = true
        }),
        v("gevd normalized refined", &|c| {
            c.normalize_bins = true;
            c.refine = true
        }),
    ]
}

/// [`variants`], plus the robust default (its signal subspace depends on the array:
/// [`crate::localizer::robust_subspace_dim`]), other subspace sizes (the ring's 8
/// microphones allow at most 7), and the robust default with longer windows, another
/// band, no eigenvalue weight; with coherence normalisation alone and with other bands,
/// per-bin normalisation, and diagonal loading of K (the imperfect-array comparisons of
/// docs/accuracy.md).
pub fn variants_for(array: StudyArray, period: usize) -> Vec<Variant> {
    let mut vs = variants(period);
    let base = vs[0].config.clone();
    let dims: &[usize] = match array {
        StudyArray::Ring8 => &[5, 6],
        StudyArray::Sphere60 => &[6, 8, 12, 16, 20, 24, 30],
        StudyArray::Ring4 => &[1, 3],
    };
    // Every "robust …" variant is the robust default as it runs (the geometric numerator
    // since 2026-11-29) with one change; "robust raw numerator" changes the numerator.
    let mut push = |name: String, f: &dyn Fn(&mut LocalizeConfig)| {
        let mut c = base.clone();
        c.refine = true;
        if name.starts_with("robust") {
            c.numerator = Numerator::Geometric;
        }
        // Onset weighting (2026-12-03) in the current default's rows only: the other
        // "robust …" rows keep the change they were measured with.
        if name.starts_with("robust default") || name.starts_with("robust onset") {
            c.onset_frames = ONSET_FRAMES;
        }
        f(&mut c);
        vs.push(Variant { name, config: c });
    };
    let mics = array.num_mics();
    let robust = crate::localizer::robust_subspace_dim(base.num_sources, mics);
    // The robust default before 2026-12-01 (max(num_sources + 2, M/2), below M): on
    // arrays of fewer than 8 microphones it differs from today's.
    let former = (base.num_sources + 2).max(mics / 2).min(mics - 1);
    if former != robust {
        push(format!("robust former subspace ({former} refined)"), &|c| {
            c.subspace_dim = Some(former)
        });
    }
    push(format!("robust default (subspace {robust} refined)"), &|c| {
        c.subspace_dim = Some(robust)
    });
    // Onset weighting (docs/accuracy.md, "Onset weighting"): the robust default before
    // 2026-12-03 had none.
    push("robust no onset".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.onset_frames = 0
    });
    // The robust default with a window twice HARK's (docs/accuracy.md, "Onset weighting":
    // a latency trade, not the default).
    push("robust onset W=100".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.window = 100
    });
    push("robust onset 20".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.onset_frames = 20
    });
    // The spectrum's numerator (docs/accuracy.md, "The spectrum's numerator"): the robust
    // default before 2026-11-29 (raw ‖a‖²), the whitened ‖a_w‖², and the textbook GEVD
    // with the geometric one.
    push(
        format!("robust raw numerator (subspace {robust} refined)"),
        &|c| {
            c.subspace_dim = Some(robust);
            c.numerator = Numerator::Raw
        },
    );
    push("robust whitened numerator".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.numerator = Numerator::Whitened
    });
    push("gevd geometric numerator".into(), &|c| {
        c.refine = false;
        c.numerator = Numerator::Geometric
    });
    for &dim in dims {
        push(format!("gevd subspace {dim} refined"), &|c| {
            c.subspace_dim = Some(dim)
        });
    }
    push("robust W=100".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.window = 100
    });
    push("robust W=150".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.window = 150
    });
    push("robust W=100 400-3500 Hz".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.window = 100;
        c.lower_freq_hz = 400.0;
        c.upper_freq_hz = 3500.0
    });
    push("robust no eigen weight".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.eigenvalue_weight = false
    });
    push(format!("robust coherence (subspace {robust})"), &|c| {
        c.subspace_dim = Some(robust);
        c.coherence = true
    });
    push("robust 1000-4000 Hz".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.lower_freq_hz = 1000.0;
        c.upper_freq_hz = 4000.0
    });
    for (lo, hi) in [
        (700.0, 2800.0),
        (1000.0, 2800.0),
        (1000.0, 3500.0),
        (800.0, 4000.0),
        (1000.0, 4000.0),
        (1200.0, 4000.0),
    ] {
        push(format!("robust coherence {lo}-{hi} Hz"), &|c| {
            c.subspace_dim = Some(robust);
            c.coherence = true;
            c.lower_freq_hz = lo;
            c.upper_freq_hz = hi
        });
    }
    push("robust coherence normalized".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.coherence = true;
        c.normalize_bins = true
    });
    push("robust normalized".into(), &|c| {
        c.subspace_dim = Some(robust);
        c.normalize_bins = true
    });
    for loading in [1e-4, 1e-3, 3e-3, 1e-2] {
        push(format!("robust loading {loading:e}"), &|c| {
            c.subspace_dim = Some(robust);
            c.diagonal_loading = loading
        });
        push(format!("robust coherence loading {loading:e}"), &|c| {
            c.subspace_dim = Some(robust);
            c.coherence = true;
            c.diagonal_loading = loading
        });
    }
    valid_for(vs, mics)
}

/// The variants an array of `mics` microphones can run: fewer sources and signal vectors
/// than microphones (the 4-mic ring drops "Ns=4").
fn valid_for(mut vs: Vec<Variant>, mics: usize) -> Vec<Variant> {
    vs.retain(|v| v.config.num_sources < mics && v.config.subspace_dim.is_none_or(|d| d < mics));
    vs
}

/// The variants for scenes without a noise recording ([`super::StudyNoise::Room`]): the plain
/// MUSIC family and SRP-PHAT, which need no K — HARK's SEVD as it is (the default
/// without a noise source until the room default), then larger signal subspaces,
/// refinement, NormMUSIC, the room default itself — and,
/// for reference, the robust default of a user who does have a noise-only second.
pub fn variants_without_noise(array: StudyArray, period: usize) -> Vec<Variant> {
    let base = LocalizeConfig {
        algorithm: Algorithm::Sevd,
        period,
        ..Default::default()
    };
    let mut vs = Vec::new();
    // The defaults as they run (with onset weighting since 2026-12-03).
    let mut push = |name: String, f: &dyn Fn(&mut LocalizeConfig)| {
        let mut c = base.clone();
        if name.starts_with("room default coherence") || name.starts_with("room default onset") {
            c.onset_frames = ONSET_FRAMES;
        }
        f(&mut c);
        vs.push(Variant { name, config: c });
    };
    let mics = array.num_mics();
    let dims: &[usize] = match array {
        StudyArray::Ring8 => &[3, 4, 5, 6],
        StudyArray::Sphere60 => &[4, 8, 12, 16, 20, 30, 45],
        StudyArray::Ring4 => &[1, 3],
    };
    push("sevd (Ns=2)".into(), &|_| {});
    push("sevd refined".into(), &|c| c.refine = true);
    for &dim in dims {
        push(format!("sevd subspace {dim} refined"), &|c| {
            c.subspace_dim = Some(dim);
            c.refine = true
        });
    }
    push("sevd no eigen weight".into(), &|c| c.eigenvalue_weight = false);
    push("normmusic".into(), &|c| c.normalize_bins = true);
    push("normmusic refined".into(), &|c| {
        c.normalize_bins = true;
        c.refine = true
    });
    for &dim in dims {
        push(format!("normmusic subspace {dim} refined"), &|c| {
            c.normalize_bins = true;
            c.subspace_dim = Some(dim);
            c.refine = true
        });
    }
    push("srp-phat".into(), &|c| c.algorithm = Algorithm::SrpPhat);
    push("srp-phat refined".into(), &|c| {
        c.algorithm = Algorithm::SrpPhat;
        c.refine = true
    });
    let room = crate::localizer::room_subspace_dim(base.num_sources, mics);
    push(
        format!("room default (normmusic subspace {room} refined)"),
        &|c| {
            c.normalize_bins = true;
            c.subspace_dim = Some(room);
            c.refine = true
        },
    );
    push(
        format!("room default coherence (normmusic subspace {room} refined)"),
        &|c| {
            c.normalize_bins = true;
            c.subspace_dim = Some(room);
            c.refine = true;
            c.coherence = true
        },
    );
    push(
        format!("room default no onset (coherence normmusic subspace {room} refined)"),
        &|c| {
            c.normalize_bins = true;
            c.subspace_dim = Some(room);
            c.refine = true;
            c.coherence = true;
            c.onset_frames = 0
        },
    );
    push(
        format!("room default onset 20 (coherence normmusic subspace {room} refined)"),
        &|c| {
            c.normalize_bins = true;
            c.subspace_dim = Some(room);
            c.refine = true;
            c.coherence = true;
            c.onset_frames = 20
        },
    );
    push(format!("sevd subspace {room} coherence refined"), &|c| {
        c.subspace_dim = Some(room);
        c.refine = true;
        c.coherence = true
    });
    let robust = crate::localizer::robust_subspace_dim(base.num_sources, mics);
    push(
        format!("gevd robust default, K from 0-1 s (subspace {robust})"),
        &|c| {
            c.algorithm = Algorithm::Gevd;
            c.subspace_dim = Some(robust);
            c.refine = true;
            c.numerator = Numerator::Geometric
        },
    );
    valid_for(vs, mics)
}
