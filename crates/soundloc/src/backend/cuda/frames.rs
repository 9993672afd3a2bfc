//! Where each stream's STFT frames live on the device between calls (host bookkeeping
//! only; the bytes move in `mod.rs`).
//!
//! One device buffer, the arena, holds frames `[frame][bin][mic]`. A kept stream
//! ([`StreamId::is_kept`]) owns a region of it that holds its frames `first .. end`; a
//! call that needs frames `lo .. hi` of that stream uploads only `end .. hi` when the region
//! still holds `lo` and has room — at PERIOD 1, one frame per window instead of W. When the
//! region is too small the stream gets a new one (twice its need); when it runs past the
//! region's end it is refilled from its start. Regions are handed out bottom-up; when the
//! arena is full every region is forgotten (those frames go up again) and, if one call
//! needs more than the arena holds, it grows. Frames of one-off jobs get a region for the
//! call only. The frames on the device are a cache: the host always gives every frame a
//! window reads, so a miss costs an upload, never a wrong result.

use crate::backend::StreamId;
use std::collections::HashMap;
use std::ops::Range;

/// Smallest region for a kept stream, in frames.
const MIN_ROOM: usize = 64;

#[derive(Debug, Clone, Copy)]
struct Region {
    /// Arena frame of stream frame `first`.
    pos: usize,
    /// Frames reserved.
    room: usize,
    first: usize,
    end: usize,
}

/// Frames to upload: stream frames `frames` of job `job` to arena frame `at` onwards.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Upload {
    pub job: usize,
    pub at: usize,
    pub frames: Range<usize>,
}

/// Where a call's jobs are.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct Placement {
    /// Per job, the arena frame of its stream frame `lo` (its lowest needed frame).
    pub base: Vec<usize>,
    /// Per job, `lo`.
    pub lo: Vec<usize>,
    /// What goes up, in this order.
    pub uploads: Vec<Upload>,
    /// Frames the arena must hold for this call: when larger than its capacity, the
    /// caller grows it (contents lost; every job here already uploads in full).
    pub arena_frames: usize,
}

/// The arena's bookkeeping.
#[derive(Debug, Default)]
pub(crate) struct FrameArena {
    /// Capacity in frames.
    cap: usize,
    /// First free frame.
    top: usize,
    regions: HashMap<StreamId, Region>,
}

impl FrameArena {
    /// The device buffer holds `frames` frames: set at the start, and after a
    /// [`place`](Self::place) that asked for more (its regions were laid out for the grown
    /// buffer and stay).
    pub fn set_capacity(&mut self, frames: usize) {
        self.cap = frames;
    }

    /// Forget every region (e.g. the buffer was reallocated).
    pub fn forget(&mut self) {
        self.regions.clear();
        self.top = 0;
    }

    /// Give up `stream`'s region (its space is reused once the regions above it are gone,
    /// or when the arena starts over).
    pub fn release(&mut self, stream: StreamId) {
        self.regions.remove(&stream);
        self.top = self.regions.values().map(|g| g.pos + g.room).max().unwrap_or(0);
    }

    /// Frames on the device for `stream` now: `first .. end`.
    #[cfg(test)]
    pub fn held(&self, stream: StreamId) -> Option<Range<usize>> {
        self.regions.get(&stream).map(|r| r.first..r.end)
    }

    /// Place jobs needing stream frames `needs[j]` (`.0` the stream, `.1` the range).
    pub fn place(&mut self, needs: &[(StreamId, Range<usize>)]) -> Placement {
        if let Some(p) = self.try_place(needs) {
            return p;
        }
        // Full: forget everything and lay this call out from the bottom.
        self.forget();
        if let Some(p) = self.try_place(needs) {
            return p;
        }
        // Larger than the arena: the caller grows it to what a fresh layout needs.
        let need: usize = needs.iter().map(|(s, r)| room_for(*s, r)).sum();
        self.cap = need;
        self.forget();
        self.try_place(needs).unwrap_or_default()
    }

    fn try_place(&mut self, needs: &[(StreamId, Range<usize>)]) -> Option<Placement> {
        let mut p = Placement::default();
        let mut seen = std::collections::HashSet::new();
        let mut top = self.top;
        let mut changed: Vec<(StreamId, Region)> = Vec::new();
        for (j, (stream, r)) in needs.iter().enumerate() {
            let (lo, hi) = (r.start, r.end.max(r.start));
            // A stream named twice in one call: the second is one-off (its frames must
            // not overwrite what the first's windows read).
            let kept = stream.is_kept() && seen.insert(*stream);
            let old = kept.then(|| self.regions.get(stream).copied()).flatten();
            match old {
                Some(g) if g.room >= hi - lo => {
                    let mut g = g;
                    if g.first <= lo && lo <= g.end && hi - g.first <= g.room {
                        if hi > g.end {
                            p.uploads.push(Upload {
                                job: j,
                                at: g.pos + (g.end - g.first),
                                frames: g.end..hi,
                            });
                            g.end = hi;
                        }
                    } else {
                        p.uploads.push(Upload {
                            job: j,
                            at: g.pos,
                            frames: lo..hi,
                        });
                        g.first = lo;
                        g.end = hi;
                    }
                    p.base.push(g.pos + (lo - g.first));
                    changed.push((*stream, g));
                }
                _ => {
                    let room = if kept { room_for(*stream, r) } else { hi - lo };
                    if top + room > self.cap {
                        return None;
                    }
                    let g = Region {
                        pos: top,
                        room,
                        first: lo,
                        end: hi,
                    };
                    top += room;
                    p.uploads.push(Upload {
                        job: j,
                        at: g.pos,
                        frames: lo..hi,
                    });
                    p.base.push(g.pos);
                    if kept {
                        changed.push((*stream, g));
                    }
                }
            }
            p.lo.push(lo);
        }
        // One-off regions are free again after the call; kept ones stay.
        let kept_top = changed
            .iter()
            .map(|(_, g)| g.pos + g.room)
            .chain(self.regions.values().map(|g| g.pos + g.room))
            .max()
            .unwrap_or(0);
        for (s, g) in changed {
            self.regions.insert(s, g);
        }
        p.arena_frames = top.max(self.cap);
        self.top = kept_top;
        Some(p)
    }
}

fn room_for(stream: StreamId, r: &Range<usize>) -> usize {
    let n = r.end.saturating_sub(r.start);
    if stream.is_kept() {
        (2 * n).max(MIN_ROOM)
    } else {
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sliding_stream_uploads_only_new_frames() {
        let mut a = FrameArena::default();
        a.set_capacity(1000);
        let s = StreamId::fresh();
        let p = a.place(&[(s, 0..50)]);
        assert_eq!(
            p.uploads,
            vec![Upload {
                job: 0,
                at: 0,
                frames: 0..50
            }]
        );
        assert_eq!(p.base, vec![0]);
        // PERIOD 1: the next window needs 1..51, only frame 50 goes up.
        let p = a.place(&[(s, 1..51)]);
        assert_eq!(
            p.uploads,
            vec![Upload {
                job: 0,
                at: 50,
                frames: 50..51
            }]
        );
        assert_eq!(p.base, vec![1]);
        // Past the region's room (100 frames): refilled from its start.
        for k in 2..=50 {
            let p = a.place(&[(s, k..k + 50)]);
            assert_eq!(p.uploads.len(), 1);
            assert_eq!(p.uploads[0].frames, k + 49..k + 50);
        }
        let p = a.place(&[(s, 51..101)]);
        assert_eq!(
            p.uploads,
            vec![Upload {
                job: 0,
                at: 0,
                frames: 51..101
            }]
        );
        assert_eq!(p.base, vec![0]);
        assert_eq!(a.held(s), Some(51..101));
    }

    #[test]
    fn streams_keep_their_regions_and_one_offs_reuse_space() {
        let mut a = FrameArena::default();
        a.set_capacity(400);
        let (s1, s2) = (StreamId::fresh(), StreamId::fresh());
        let p = a.place(&[(s1, 0..50), (s2, 10..60), (StreamId::ONCE, 0..30)]);
        assert_eq!(p.base, vec![0, 100, 200]);
        assert_eq!(p.uploads.len(), 3);
        let p = a.place(&[(StreamId::ONCE, 0..30), (s2, 11..61), (s1, 1..51)]);
        assert_eq!(p.base, vec![200, 101, 1]);
        assert_eq!(
            p.uploads,
            vec![
                Upload {
                    job: 0,
                    at: 200,
                    frames: 0..30
                },
                Upload {
                    job: 1,
                    at: 150,
                    frames: 60..61
                },
                Upload {
                    job: 2,
                    at: 50,
                    frames: 50..51
                },
            ]
        );
        // The same stream twice in one call: the second gets its own frames.
        let p = a.place(&[(s1, 2..52), (s1, 0..50)]);
        assert_eq!(p.uploads[0].frames, 51..52);
        assert_eq!(p.uploads[1].frames, 0..50);
        assert_ne!(p.base[1], p.base[0]);
    }

    #[test]
    fn a_released_stream_gives_its_space_back() {
        let mut a = FrameArena::default();
        a.set_capacity(1000);
        let (s1, s2) = (StreamId::fresh(), StreamId::fresh());
        a.place(&[(s1, 0..50), (s2, 0..50)]);
        a.release(s2);
        assert_eq!(a.held(s2), None);
        // s2's space (frames 100..200) is the next region handed out.
        let p = a.place(&[(StreamId::fresh(), 0..50)]);
        assert_eq!(p.base, vec![100]);
        assert_eq!(a.held(s1), Some(0..50));
    }

    #[test]
    fn a_full_arena_starts_over_and_a_large_call_grows_it() {
        let mut a = FrameArena::default();
        a.set_capacity(300);
        let streams: Vec<StreamId> = (0..4).map(|_| StreamId::fresh()).collect();
        for s in &streams[..2] {
            a.place(&[(*s, 0..50)]);
        }
        assert!(a.held(streams[0]).is_some());
        // Two more regions of 100 do not fit after the first two (300): start over.
        let p = a.place(&[(streams[2], 0..50), (streams[3], 0..50)]);
        assert_eq!(p.base, vec![0, 100]);
        assert_eq!(a.held(streams[0]), None);
        assert_eq!(p.arena_frames, 300);
        // One call needing 2 × 2 × 400 frames: the arena must grow.
        let p = a.place(&[(streams[0], 0..400), (streams[1], 0..400)]);
        assert_eq!(p.arena_frames, 1600);
        assert_eq!(p.base, vec![0, 800]);
        assert!(p.uploads.iter().all(|u| u.frames == (0..400)));
    }
}
