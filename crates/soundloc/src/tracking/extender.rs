//! HARK's SourceIntervalExtender (see the [module docs](super)).

use std::collections::{HashSet, VecDeque};

use super::{sort_strongest_first, IntervalExtenderConfig};
use crate::result::{LocalizationResult, Source};

/// Streaming SourceIntervalExtender: [`push`](Self::push) results in increasing frame
/// order; a result is released once a result more than `PREROLL_LENGTH` frames later has
/// arrived (or at [`finish`](Self::finish)). Sources without an id pass through unchanged
/// and are never extended.
#[derive(Debug, Clone)]
pub struct IntervalExtender {
    cfg: IntervalExtenderConfig,
    pending: VecDeque<LocalizationResult>,
    seen: HashSet<i64>,
}

impl IntervalExtender {
    /// An empty extender.
    pub fn new(cfg: IntervalExtenderConfig) -> Self {
        IntervalExtender {
            cfg,
            pending: VecDeque::new(),
            seen: HashSet::new(),
        }
    }

    /// Adds one result; returns the results that are now final (possibly none).
    pub fn push(&mut self, result: LocalizationResult) -> Vec<LocalizationResult> {
        let f = result.frame;
        let p = self.cfg.preroll_length;
        for s in &result.sources {
            let Some(id) = s.id else { continue };
            if !self.seen.insert(id) {
                continue;
            }
            // First appearance at frame f: emit in pending results with frame in [f-P, f).
            for r in self.pending.iter_mut() {
                if r.frame < f
                    && r.frame.saturating_add(p) >= f
                    && !r.sources.iter().any(|x| x.id == Some(id))
                {
                    // Not observed there: marked held, as a carried source is.
                    r.sources.push(Source {
                        held: true,
                        ..s.clone()
                    });
                    sort_strongest_first(&mut r.sources);
                }
            }
        }
        self.pending.push_back(result);
        let mut out = Vec::new();
        while let Some(front) = self.pending.front() {
            // No later result (frame > f) can reach back to it: r.frame + P ≤ f.
            if front.frame.saturating_add(p) <= f {
                if let Some(r) = self.pending.pop_front() {
                    out.push(r);
                }
            } else {
                break;
            }
        }
        out
    }

    /// Releases every pending result.
    pub fn finish(&mut self) -> Vec<LocalizationResult> {
        self.pending.drain(..).collect()
    }

    /// Forgets pending results and seen ids.
    pub fn reset(&mut self) {
        self.pending.clear();
        self.seen.clear();
    }
}

/// SourceIntervalExtender on a whole run (results in increasing frame order): each source
/// first seen at frame f also appears in the results with frame in [f − PREROLL_LENGTH, f).
pub fn extend(results: &[LocalizationResult], cfg: IntervalExtenderConfig) -> Vec<LocalizationResult> {
    let mut ex = IntervalExtender::new(cfg);
    let mut out = Vec::with_capacity(results.len());
    for r in results {
        out.extend(ex.push(r.clone()));
    }
    out.extend(ex.finish());
    out
}
