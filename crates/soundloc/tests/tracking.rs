//! SourceTracker, SourceIntervalExtender and summaries on synthetic peak sequences.

use rand::{Rng, SeedableRng};
use soundloc::tracking::{
    extend, summarize, summarize_with_starts, IntervalExtender, IntervalExtenderConfig, SourceTracker,
    TrackStart, TrackerConfig,
};
use soundloc::{LocalizationResult, Source};

fn peak(az_deg: f64, el_deg: f64, power_db: f64) -> Source {
    let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
    Source {
        id: None,
        grid_index: 0,
        azimuth_deg: az_deg,
        elevation_deg: el_deg,
        x: el.cos() * az.cos(),
        y: el.cos() * az.sin(),
        z: el.sin(),
        power_db,
        held: false,
    }
}

fn result(frame: usize, sources: Vec<Source>) -> LocalizationResult {
    LocalizationResult {
        num_active: None,
        frame,
        time_s: frame as f64 * 0.01,
        sources,
    }
}

/// Id of the output source nearest (in azimuth/elevation) to (az, el), if within 1e-9.
fn id_at(r: &LocalizationResult, az: f64, el: f64) -> Option<i64> {
    r.sources
        .iter()
        .find(|s| (s.azimuth_deg - az).abs() < 1e-9 && (s.elevation_deg - el).abs() < 1e-9)
        .and_then(|s| s.id)
}

fn ids(r: &LocalizationResult) -> Vec<i64> {
    let mut v: Vec<i64> = r.sources.iter().filter_map(|s| s.id).collect();
    v.sort();
    v
}

#[test]
fn moving_source_keeps_its_id() {
    let mut t = SourceTracker::new(TrackerConfig {
        min_id: 7,
        ..TrackerConfig::with_thresh(20.0)
    });
    for f in 0..120 {
        let az = -100.0 + 2.0 * f as f64;
        let out = t.update(&result(f, vec![peak(az, 10.0, 30.0)]));
        assert_eq!(out.sources.len(), 1, "frame {f}");
        assert_eq!(out.sources[0].id, Some(7), "frame {f}");
        assert_eq!(out.sources[0].azimuth_deg, az);
        assert_eq!(out.frame, f);
    }
}

#[test]
fn new_source_gets_next_id() {
    let mut t = SourceTracker::new(TrackerConfig::with_thresh(20.0));
    for f in 0..60 {
        let mut s = vec![peak(0.0, 0.0, 30.0)];
        if f >= 30 {
            s.push(peak(90.0, 0.0, 35.0));
        }
        let out = t.update(&result(f, s));
        assert_eq!(id_at(&out, 0.0, 0.0), Some(0));
        if f >= 30 {
            assert_eq!(id_at(&out, 90.0, 0.0), Some(1));
            // Strongest first.
            assert_eq!(out.sources[0].id, Some(1));
        } else {
            assert_eq!(out.sources.len(), 1);
        }
    }
}

#[test]
fn source_ends_after_pause_length_without_peaks() {
    let cfg = TrackerConfig::with_thresh(20.0); // PAUSE_LENGTH 800 = 80 frames
    let mut t = SourceTracker::new(cfg);
    for f in 0..10 {
        t.update(&result(f, vec![peak(45.0, 0.0, 30.0 + f as f64)]));
    }
    // Last peak at frame 9: carried at its last position and power through frame 89,
    // marked held; the summary ends at its last observation.
    let mut run = Vec::new();
    for f in 10..=89 {
        let out = t.update(&result(f, vec![]));
        assert_eq!(out.sources.len(), 1, "frame {f}");
        assert_eq!(out.sources[0].id, Some(0));
        assert_eq!(out.sources[0].azimuth_deg, 45.0);
        assert_eq!(out.sources[0].power_db, 39.0);
        assert!(out.sources[0].held, "frame {f}");
        run.push(out);
    }
    let line = soundloc::output::jsonl::to_json_line(&run[0]);
    assert!(line.contains("\"held\":true"), "{line}");
    assert_eq!(soundloc::output::jsonl::from_json_line(&line).unwrap(), run[0]);
    let mut t2 = SourceTracker::new(cfg);
    let observed: Vec<LocalizationResult> = (0..10)
        .map(|f| t2.update(&result(f, vec![peak(45.0, 0.0, 30.0 + f as f64)])))
        .collect();
    assert!(observed.iter().all(|r| !r.sources[0].held));
    let line = soundloc::output::jsonl::to_json_line(&observed[0]);
    assert!(!line.contains("held"), "{line}");
    let sum = summarize(&[observed, run].concat());
    assert_eq!(
        (
            sum.len(),
            sum[0].start_frame,
            sum[0].end_frame,
            sum[0].num_results
        ),
        (1, 0, 9, 10)
    );
    let out = t.update(&result(90, vec![]));
    assert!(out.sources.is_empty(), "ended at frame 90: {out:?}");
    assert_eq!(t.num_alive(), 0);
    // Same direction again: a new source, new id (ids are never reused).
    let out = t.update(&result(100, vec![peak(45.0, 0.0, 30.0)]));
    assert_eq!(ids(&out), vec![1]);
    // reset() restarts ids at MIN_ID.
    t.reset();
    let out = t.update(&result(101, vec![peak(45.0, 0.0, 30.0)]));
    assert_eq!(ids(&out), vec![0]);
}

#[test]
fn pause_length_counts_stft_frames_between_results() {
    // Results every 50 frames (PERIOD 50): a miss costs 500.
    let mut t = SourceTracker::new(TrackerConfig::with_thresh(0.0));
    t.update(&result(0, vec![peak(0.0, 0.0, 30.0)]));
    assert_eq!(t.update(&result(50, vec![])).sources.len(), 1); // 800 - 500 = 300
    assert!(t.update(&result(100, vec![])).sources.is_empty()); // 300 - 500 < 0
}

#[test]
fn a_gap_shorter_than_pause_length_keeps_the_id() {
    let mut t = SourceTracker::new(TrackerConfig::with_thresh(20.0));
    for f in 0..200 {
        let s = if (50..100).contains(&f) {
            vec![]
        } else {
            vec![peak(-30.0 + 0.1 * f as f64, 0.0, 30.0)]
        };
        let out = t.update(&result(f, s));
        assert_eq!(ids(&out), vec![0], "frame {f}");
    }
}

#[test]
fn threshold_gates_starts_and_matches() {
    let mut t = SourceTracker::new(TrackerConfig::with_thresh(20.0));
    // Below THRESH: never starts a source and never appears.
    let out = t.update(&result(0, vec![peak(0.0, 0.0, 19.99)]));
    assert!(out.sources.is_empty());
    // Exactly THRESH is accepted (power >= THRESH).
    let out = t.update(&result(1, vec![peak(0.0, 0.0, 20.0)]));
    assert_eq!(ids(&out), vec![0]);
    // Weak peaks at the same place do not sustain it: it is carried (last power 20) and ends.
    for f in 2..=81 {
        let out = t.update(&result(f, vec![peak(1.0, 0.0, 5.0)]));
        assert_eq!(out.sources.len(), 1, "frame {f}");
        assert_eq!(out.sources[0].power_db, 20.0);
        assert_eq!(out.sources[0].azimuth_deg, 0.0);
    }
    assert!(t
        .update(&result(82, vec![peak(1.0, 0.0, 5.0)]))
        .sources
        .is_empty());
    // NaN power never passes.
    assert!(t
        .update(&result(83, vec![peak(50.0, 0.0, f64::NAN)]))
        .sources
        .is_empty());
}

#[test]
fn near_duplicate_peaks_start_one_source() {
    let mut t = SourceTracker::new(TrackerConfig::with_thresh(0.0));
    let out = t.update(&result(0, vec![peak(10.0, 0.0, 30.0), peak(15.0, 0.0, 31.0)]));
    assert_eq!(out.sources.len(), 1);
    assert_eq!(out.sources[0].azimuth_deg, 15.0, "the strongest peak starts it");
    // Just inside MIN_SRC_INTERVAL of the source: dropped; just outside: a new source.
    let out = t.update(&result(1, vec![peak(15.0, 0.0, 30.0), peak(34.99, 0.0, 30.0)]));
    assert_eq!(ids(&out), vec![0]);
    let out = t.update(&result(2, vec![peak(15.0, 0.0, 30.0), peak(35.01, 0.0, 30.0)]));
    assert_eq!(ids(&out), vec![0, 1]);
}

#[test]
fn a_peak_is_claimed_by_the_closest_source_only() {
    let mut t = SourceTracker::new(TrackerConfig::with_thresh(0.0));
    let out = t.update(&result(0, vec![peak(0.0, 0.0, 30.0), peak(30.0, 0.0, 30.0)]));
    assert_eq!(id_at(&out, 0.0, 0.0), Some(0));
    assert_eq!(id_at(&out, 30.0, 0.0), Some(1));
    // Peak at 16° is 16° from source 0 and 14° from source 1: source 1 claims it; source 0
    // is carried at 0°; the peak at 50° (34° from source 1's new place) starts source 2.
    let out = t.update(&result(1, vec![peak(16.0, 0.0, 30.0), peak(50.0, 0.0, 30.0)]));
    assert_eq!(id_at(&out, 16.0, 0.0), Some(1));
    assert_eq!(id_at(&out, 0.0, 0.0), Some(0));
    assert_eq!(id_at(&out, 50.0, 0.0), Some(2));
    assert_eq!(out.sources.len(), 3);
}

#[test]
fn crossing_paths_at_distinct_speeds_keep_ids() {
    // A moves along the equator at 3°/frame, B along the azimuth-0 meridian at 2°/frame;
    // their paths cross at (0°, 0°), A passes there at frame 20, B at frame 30. They come
    // within MIN_SRC_INTERVAL (about 17° apart around frame 24).
    let mut t = SourceTracker::new(TrackerConfig::with_thresh(20.0));
    let mut min_sep = f64::INFINITY;
    for f in 0..=60usize {
        let (a_az, b_el) = (-60.0 + 3.0 * f as f64, -60.0 + 2.0 * f as f64);
        let (a, b) = (peak(a_az, 0.0, 30.0), peak(0.0, b_el, 28.0));
        let dot = a.x * b.x + a.y * b.y + a.z * b.z;
        min_sep = min_sep.min(dot.clamp(-1.0, 1.0).acos().to_degrees());
        let out = t.update(&result(f, vec![a, b]));
        assert_eq!(id_at(&out, a_az, 0.0), Some(0), "frame {f}: {out:?}");
        assert_eq!(id_at(&out, 0.0, b_el), Some(1), "frame {f}: {out:?}");
        assert_eq!(out.sources.len(), 2);
    }
    assert!(
        min_sep < 20.0,
        "the test must bring them within MIN_SRC_INTERVAL: {min_sep}"
    );
}

/// Head-on on one circle: A at −40 + 4t, B at 40 − 2t (crossing between frames 13 and 14).
fn head_on(t: &mut SourceTracker) -> Vec<(Option<i64>, Option<i64>)> {
    (0..=30usize)
        .map(|f| {
            let (a, b) = (-40.0 + 4.0 * f as f64, 40.0 - 2.0 * f as f64);
            let out = t.update(&result(f, vec![peak(a, 0.0, 30.0), peak(b, 0.0, 25.0)]));
            (id_at(&out, a, 0.0), id_at(&out, b, 0.0))
        })
        .collect()
}

#[test]
fn head_on_crossing_bounces_without_motion_model() {
    // Documented HARK behaviour: proximity matching keeps ids in angular order.
    let got = head_on(&mut SourceTracker::new(TrackerConfig::with_thresh(20.0)));
    for (f, &(a, b)) in got.iter().enumerate() {
        let want = if f <= 13 {
            (Some(0), Some(1))
        } else {
            (Some(1), Some(0))
        };
        assert_eq!((a, b), want, "frame {f}");
    }
}

#[test]
fn head_on_crossing_keeps_ids_with_motion_prediction() {
    let mut t = SourceTracker::new(TrackerConfig::with_thresh(20.0)).with_motion_prediction(true);
    for (f, &(a, b)) in head_on(&mut t).iter().enumerate() {
        assert_eq!((a, b), (Some(0), Some(1)), "frame {f}");
    }
}

#[test]
fn exact_crossing_merged_peak_one_claims_other_carried() {
    // A at −40 + 4t, B at 44 − 2t meet at 16° at frame 14, where the peak finder gives a
    // single peak. With prediction, both predict 16° (tie → lower id claims it), B is
    // carried at its frame-13 position (18°) and re-acquired at frame 15 on its own path.
    let mut t = SourceTracker::new(TrackerConfig::with_thresh(20.0)).with_motion_prediction(true);
    for f in 0..=30usize {
        let (a, b) = (-40.0 + 4.0 * f as f64, 44.0 - 2.0 * f as f64);
        let peaks = if f == 14 {
            vec![peak(16.0, 0.0, 33.0)]
        } else {
            vec![peak(a, 0.0, 30.0), peak(b, 0.0, 25.0)]
        };
        let out = t.update(&result(f, peaks));
        if f == 14 {
            assert_eq!(id_at(&out, 16.0, 0.0), Some(0));
            assert_eq!(id_at(&out, 18.0, 0.0), Some(1), "carried at its last position");
        } else {
            assert_eq!(
                (id_at(&out, a, 0.0), id_at(&out, b, 0.0)),
                (Some(0), Some(1)),
                "frame {f}"
            );
        }
    }
}

#[test]
fn random_peaks_never_repeat_an_id_within_a_result() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let mut t = SourceTracker::new(TrackerConfig::with_thresh(10.0));
    for f in 0..500 {
        let n = rng.gen_range(0..5);
        let peaks = (0..n)
            .map(|_| {
                peak(
                    rng.gen_range(-180.0..180.0),
                    rng.gen_range(-30.0..30.0),
                    rng.gen_range(0.0..40.0),
                )
            })
            .collect();
        let out = t.update(&result(f, peaks));
        let mut v = ids(&out);
        let len = v.len();
        v.dedup();
        assert_eq!(v.len(), len, "frame {f}");
        assert_eq!(len, out.sources.len(), "every output source has an id");
        assert!(out.sources.windows(2).all(|w| w[0].power_db >= w[1].power_db));
    }
}

fn onset_run() -> Vec<LocalizationResult> {
    // Results every 10 frames; source 0 from frame 0; source 1 first seen at frame 100.
    (0..20usize)
        .map(|i| {
            let f = 10 * i;
            let mut s = vec![Source {
                id: Some(0),
                ..peak(0.0, 0.0, 30.0)
            }];
            if f >= 100 {
                s.push(Source {
                    id: Some(1),
                    ..peak(90.0, 0.0, 20.0 + i as f64)
                });
            }
            s.sort_by(|a, b| b.power_db.total_cmp(&a.power_db));
            result(f, s)
        })
        .collect()
}

#[test]
fn interval_extender_shifts_onset_by_preroll() {
    let run = onset_run();
    let out = extend(&run, IntervalExtenderConfig::default()); // PREROLL_LENGTH 50
    assert_eq!(out.len(), run.len());
    for r in &out {
        let has1 = r.sources.iter().find(|s| s.id == Some(1));
        if r.frame >= 50 {
            let s = has1.unwrap_or_else(|| panic!("frame {}: {r:?}", r.frame));
            if r.frame < 100 {
                // Emitted at its first position and power, marked held (not observed).
                assert_eq!(s.power_db, 30.0);
                assert_eq!(s.azimuth_deg, 90.0);
                assert!(s.held);
            } else {
                assert!(!s.held);
            }
        } else {
            assert!(has1.is_none(), "frame {}", r.frame);
        }
        assert!(r.sources.iter().any(|s| s.id == Some(0)));
        assert!(r.sources.windows(2).all(|w| w[0].power_db >= w[1].power_db));
    }
    // Source 0 exists from the start: nothing to extend before frame 0.
    assert_eq!(out[0].sources.len(), 1);
    // The summary starts source 1 where it was observed, as without the extender.
    let (with, without) = (summarize(&out), summarize(&run));
    assert_eq!(with, without);
}

#[test]
fn streaming_extender_delays_by_preroll_and_matches_batch() {
    let run = onset_run();
    let mut ex = IntervalExtender::new(IntervalExtenderConfig { preroll_length: 50 });
    let mut streamed = Vec::new();
    for r in &run {
        let newest = r.frame;
        for o in ex.push(r.clone()) {
            // Final once the result at its frame + P is in: no later one reaches back to it.
            assert!(
                o.frame + 50 <= newest,
                "released too early: {} at {newest}",
                o.frame
            );
            streamed.push(o);
        }
        // Everything at or before newest − P has been released (none waits a period more).
        assert!(streamed.last().map_or(newest < 50, |o| o.frame + 50 >= newest));
    }
    streamed.extend(ex.finish());
    assert_eq!(
        streamed,
        extend(&run, IntervalExtenderConfig { preroll_length: 50 })
    );
    let none = extend(&run, IntervalExtenderConfig { preroll_length: 0 });
    assert_eq!(none, run);
}

#[test]
fn summary_reports_interval_mean_direction_and_power() {
    let mut run = Vec::new();
    for i in 0..11usize {
        // Source 3 sweeps from 170° through 180° to −170°: the mean of unit vectors is 180°.
        let az = 170.0 + 2.0 * i as f64;
        let az = if az > 180.0 { az - 360.0 } else { az };
        let mut s = vec![Source {
            id: Some(3),
            ..peak(az, 10.0, 20.0 + i as f64)
        }];
        if i >= 5 {
            s.push(Source {
                id: Some(1),
                ..peak(-90.0, -5.0, 12.0)
            });
        }
        s.push(peak(0.0, 0.0, 99.0)); // untracked: ignored
        run.push(result(100 + 50 * i, s));
    }
    let sum = summarize(&run);
    assert_eq!(sum.len(), 2);
    let (a, b) = (&sum[0], &sum[1]);
    assert_eq!(
        (a.id, a.start_frame, a.end_frame, a.num_results),
        (1, 350, 600, 6)
    );
    assert!((a.start_s - 3.5).abs() < 1e-12 && (a.end_s - 6.0).abs() < 1e-12);
    assert!((a.mean_azimuth_deg + 90.0).abs() < 1e-9 && (a.mean_elevation_deg + 5.0).abs() < 1e-9);
    assert_eq!(
        (b.id, b.start_frame, b.end_frame, b.num_results),
        (3, 100, 600, 11)
    );
    assert!(
        (b.mean_azimuth_deg.abs() - 180.0).abs() < 1e-9,
        "{}",
        b.mean_azimuth_deg
    );
    // The elevations' own mean: a spread in azimuth does not lift it (the mean 3-D unit
    // vector's elevation would be 10.08°, above every elevation seen).
    assert!(
        (b.mean_elevation_deg - 10.0).abs() < 1e-9,
        "{}",
        b.mean_elevation_deg
    );
    assert_eq!(b.max_power_db, 30.0);
    let json = serde_json::to_string(&sum).expect("serialize");
    assert!(json.contains("\"mean_azimuth_deg\""));
}

#[test]
fn tracker_config_defaults_and_validation() {
    let c = TrackerConfig::default();
    assert_eq!(
        (c.pause_length, c.min_src_interval_deg, c.min_id),
        (800.0, 20.0, 0)
    );
    assert_eq!(IntervalExtenderConfig::default().preroll_length, 50);
    assert!(c.validate().is_ok());
    let bad = TrackerConfig {
        pause_length: -1.0,
        ..c
    };
    assert!(bad.validate().unwrap_err().to_string().contains("PAUSE_LENGTH"));
    let bad = TrackerConfig {
        thresh_db: f64::NAN,
        ..c
    };
    assert!(bad.validate().unwrap_err().to_string().contains("THRESH"));
    // Ids leave as 32-bit integers: a MIN_ID near i32's or i64's end is refused up front.
    for min_id in [2_147_483_647, i64::MAX, i64::MIN, -2_000_000_000] {
        let bad = TrackerConfig { min_id, ..c };
        assert!(
            bad.validate().unwrap_err().to_string().contains("MIN_ID"),
            "{min_id}"
        );
    }
    // −1 marks "no id" in HARK's logs and stream and in Python's arrays: ids start at 0.
    for min_id in [-1, -5] {
        let e = TrackerConfig { min_id, ..c }.validate().unwrap_err().to_string();
        assert!(e.contains("MIN_ID") && e.contains("−1"), "{min_id}: {e}");
    }
    assert!(TrackerConfig { min_id: 0, ..c }.validate().is_ok());
}

/// MIN_SRC_INTERVAL (20°) against peaks exactly four 5° grid steps apart: the angle
/// between the unit vectors comes out a hair below or above 20° depending on the azimuth,
/// and the id must not. A talker stepping 20° every result gets a new id at every step,
/// wherever on the ring.
#[test]
fn a_step_of_exactly_min_src_interval_is_the_same_everywhere_on_the_ring() {
    let grid = soundloc::array::Grid::ring(5.0, 0.0, 1.0);
    let at = |g: usize| {
        let p = grid.points[g];
        Source {
            grid_index: g,
            x: p[0],
            y: p[1],
            z: p[2],
            ..peak(p[1].atan2(p[0]).to_degrees(), 0.0, 30.0)
        }
    };
    let mut wobbly = 0;
    for start in 0..72 {
        let mut t = SourceTracker::new(TrackerConfig::default());
        let mut ids = Vec::new();
        for k in 0..4 {
            let (g, next) = ((start + 4 * k) % 72, (start + 4 * k + 4) % 72);
            let (p, q) = (grid.points[g], grid.points[next]);
            let cos = (p[0] * q[0] + p[1] * q[1] + p[2] * q[2]).clamp(-1.0, 1.0);
            wobbly += (cos.acos().to_degrees() != 20.0) as usize;
            let out = t.update(&result(50 * k, vec![at(g)]));
            ids.push(out.sources.iter().find(|s| s.grid_index == g).and_then(|s| s.id));
        }
        assert_eq!(ids, vec![Some(0), Some(1), Some(2), Some(3)], "start {start}");
    }
    assert!(wobbly > 0, "the rounding this test is about did not occur");
}

fn confirming(frames: usize) -> SourceTracker {
    SourceTracker::new(TrackerConfig {
        confirm_frames: Some(frames),
        ..TrackerConfig::default()
    })
}

/// Confirmation: a steady source at PERIOD 10 with confirm_frames 50 is tentative (not
/// output) until it has been seen over 50 frames, then keeps id MIN_ID; a blip seen in
/// three results only never gets an id and uses none up.
#[test]
fn confirmation_holds_back_new_sources_until_seen_over_its_frames() {
    let mut t = confirming(50);
    for f in (0..50).step_by(10) {
        let mut peaks = vec![peak(30.0, 0.0, 10.0)];
        if f <= 20 {
            peaks.push(peak(-120.0, 0.0, 12.0));
        }
        let out = t.update(&result(f, peaks));
        assert!(out.sources.is_empty(), "frame {f}: {:?}", out.sources);
        assert_eq!(t.num_alive(), 0);
    }
    for f in (50..200).step_by(10) {
        let out = t.update(&result(f, vec![peak(30.0, 0.0, 10.0)]));
        assert_eq!(ids(&out), vec![0], "frame {f}");
        assert!(!out.sources[0].held);
    }
    // Confirmation off (0, and the default None): the first sighting has an id at once,
    // and the blip takes one.
    for cfg in [Some(0), None] {
        let mut hark = SourceTracker::new(TrackerConfig {
            confirm_frames: cfg,
            ..TrackerConfig::default()
        });
        let out = hark.update(&result(0, vec![peak(30.0, 0.0, 10.0), peak(-120.0, 0.0, 12.0)]));
        assert_eq!(ids(&out), vec![0, 1]);
    }
}

/// The tracker tells when it first saw each source it gives an id: with confirmation the
/// tentative sighting (50 frames before the first result with the id), without it that
/// result's own; a blip that never got an id is not told. The summary's `first_seen_*`
/// is that sighting, `start_*` the first result with the id; both the same from bare
/// results (`summarize`).
#[test]
fn the_tracker_tells_each_sources_first_sighting_and_the_summary_keeps_it() {
    let mut t = confirming(50);
    let (mut run, mut starts) = (Vec::new(), Vec::new());
    for f in (20..300).step_by(10) {
        let mut peaks = vec![peak(30.0, 0.0, 10.0)];
        if f <= 40 {
            peaks.push(peak(-120.0, 0.0, 12.0)); // a blip: three sightings
        }
        if f >= 100 {
            peaks.push(peak(90.0, 0.0, 8.0)); // a second source from frame 100
        }
        run.push(t.update(&result(f, peaks)));
        starts.extend(t.take_started());
    }
    assert_eq!(
        starts,
        vec![
            TrackStart {
                id: 0,
                frame: 20,
                time_s: 0.2
            },
            TrackStart {
                id: 1,
                frame: 100,
                time_s: 1.0
            },
        ]
    );
    assert!(t.take_started().is_empty(), "taken once");
    let s = summarize_with_starts(&run, &starts);
    assert_eq!(s.len(), 2);
    assert_eq!((s[0].id, s[0].first_seen_frame, s[0].start_frame), (0, 20, 70));
    assert!((s[0].first_seen_s - 0.2).abs() < 1e-12 && (s[0].start_s - 0.7).abs() < 1e-12);
    assert_eq!((s[1].id, s[1].first_seen_frame, s[1].start_frame), (1, 100, 150));
    for b in summarize(&run) {
        assert_eq!((b.first_seen_frame, b.first_seen_s), (b.start_frame, b.start_s));
    }
    // Without confirmation the sighting is the first result with the id.
    let mut hark = confirming(0);
    hark.update(&result(5, vec![peak(30.0, 0.0, 10.0)]));
    assert_eq!(
        hark.take_started(),
        vec![TrackStart {
            id: 0,
            frame: 5,
            time_s: 0.05
        }]
    );
    // Started, not taken, then reset: forgotten with the tracks.
    hark.update(&result(6, vec![peak(30.0, 0.0, 10.0), peak(-120.0, 0.0, 10.0)]));
    hark.reset();
    assert!(hark.take_started().is_empty());
}

/// A tentative source must be seen again within confirm_frames, or at the very next result
/// when results are further apart (PERIOD 50 with confirm_frames 25): seen at 0 and 50 it is
/// confirmed at 50; missed at one result, it starts over.
#[test]
fn confirmation_across_results_further_apart_than_its_frames() {
    let mut t = confirming(25);
    assert!(t.update(&result(0, vec![peak(0.0, 0.0, 5.0)])).sources.is_empty());
    assert_eq!(ids(&t.update(&result(50, vec![peak(2.0, 0.0, 5.0)]))), vec![0]);

    let mut t = confirming(25);
    assert!(t
        .update(&result(0, vec![peak(90.0, 0.0, 5.0)]))
        .sources
        .is_empty());
    assert!(t.update(&result(50, vec![])).sources.is_empty());
    // Seen again at 100: a new sighting, not a confirmation.
    assert!(t
        .update(&result(100, vec![peak(90.0, 0.0, 5.0)]))
        .sources
        .is_empty());
    assert_eq!(ids(&t.update(&result(150, vec![peak(90.0, 0.0, 5.0)]))), vec![0]);

    // Within the frames, a missed result is allowed: PERIOD 10, confirm 50, seen at 0, 30
    // and 50 (missed at 10, 20 and 40).
    let mut t = confirming(50);
    for (f, seen) in [(0, true), (10, false), (20, false), (30, true), (40, false)] {
        let p = if seen { vec![peak(-45.0, 0.0, 5.0)] } else { vec![] };
        assert!(t.update(&result(f, p)).sources.is_empty(), "frame {f}");
    }
    assert_eq!(ids(&t.update(&result(50, vec![peak(-45.0, 0.0, 5.0)]))), vec![0]);
}

/// At a gap in the input (`Engine::skip` calls `drop_tentative`) a tentative source starts
/// over, a confirmed one stays: seen at 0 and 10 before the gap and at 20 after it, the
/// source is not confirmed at 20 (it is without the gap) but at 40, 20 frames after its
/// new first sighting.
#[test]
fn a_gap_forgets_tentative_sources_only() {
    let mut t = confirming(20);
    assert_eq!(
        ids(&t.update(&result(0, vec![peak(60.0, 0.0, 5.0)]))),
        Vec::<i64>::new()
    );
    assert_eq!(
        ids(&t.update(&result(10, vec![peak(60.0, 0.0, 5.0)]))),
        Vec::<i64>::new()
    );
    let mut no_gap = t.clone();
    assert_eq!(
        ids(&no_gap.update(&result(20, vec![peak(60.0, 0.0, 5.0)]))),
        vec![0]
    );
    t.drop_tentative();
    assert_eq!(
        ids(&t.update(&result(20, vec![peak(60.0, 0.0, 5.0)]))),
        Vec::<i64>::new()
    );
    assert_eq!(
        ids(&t.update(&result(30, vec![peak(60.0, 0.0, 5.0)]))),
        Vec::<i64>::new()
    );
    assert_eq!(ids(&t.update(&result(40, vec![peak(60.0, 0.0, 5.0)]))), vec![0]);
    // A confirmed source outlives the gap and keeps its id.
    t.drop_tentative();
    assert_eq!(ids(&t.update(&result(50, vec![peak(61.0, 0.0, 5.0)]))), vec![0]);
}

/// A confirmed source claims its peak before a tentative one does, the two never share a
/// peak, and a confirmed source's PAUSE_LENGTH is unchanged by confirmation; with the
/// interval extender the confirmed source is copied back over PREROLL_LENGTH, so its onset
/// is not lost.
#[test]
fn confirmation_with_pause_and_preroll() {
    let mut t = confirming(20);
    let mut out = Vec::new();
    for f in (0..=40).step_by(10) {
        out.push(t.update(&result(f, vec![peak(60.0, 0.0, 5.0)])));
    }
    assert_eq!(ids(&out[2]), vec![0]);
    // Silent from 50: carried (held) until PAUSE_LENGTH 800 = 80 frames have run out.
    for f in (50..=120).step_by(10) {
        let r = t.update(&result(f, vec![]));
        assert_eq!(ids(&r), vec![0], "frame {f}");
        assert!(r.sources[0].held);
    }
    assert!(t.update(&result(130, vec![])).sources.is_empty());
    let extended = extend(&out, IntervalExtenderConfig { preroll_length: 50 });
    for r in &extended {
        assert_eq!(ids(r), vec![0], "frame {}", r.frame);
    }
    assert!(extended[0].sources[0].held && extended[1].sources[0].held);
}

/// A peak within MIN_SRC_INTERVAL of a confirmed source and of a tentative one goes to
/// the confirmed source even where the tentative one is closer: a source being confirmed
/// does not take the peak of one already reported (which would then be carried, held, at
/// its old direction while the peak went unreported).
#[test]
fn a_confirmed_source_keeps_a_peak_a_tentative_one_is_closer_to() {
    let mut t = confirming(20);
    for f in (0..=20).step_by(10) {
        t.update(&result(f, vec![peak(60.0, 0.0, 5.0)]));
    }
    // A second source appears at 90°: tentative (30° from the first).
    let r = t.update(&result(30, vec![peak(60.0, 0.0, 5.0), peak(90.0, 0.0, 5.0)]));
    assert_eq!(ids(&r), vec![0]);
    // One peak at 76°: 16° from the confirmed source, 14° from the tentative one.
    let r = t.update(&result(40, vec![peak(76.0, 0.0, 5.0)]));
    assert_eq!(ids(&r), vec![0]);
    let s = &r.sources[0];
    assert!(!s.held && s.azimuth_deg == 76.0, "{s:?}");
    // Without confirmation both are sources and the closer one takes the peak (HARK's rule).
    let mut t = SourceTracker::new(TrackerConfig::default());
    t.update(&result(0, vec![peak(60.0, 0.0, 5.0), peak(90.0, 0.0, 5.0)]));
    let r = t.update(&result(10, vec![peak(76.0, 0.0, 5.0)]));
    let fresh: Vec<&Source> = r.sources.iter().filter(|s| !s.held).collect();
    assert_eq!(fresh.len(), 1);
    assert_eq!((fresh[0].id, fresh[0].azimuth_deg), (Some(1), 76.0));
}

/// A run whose sources were all tentative (a --confirm longer than the input) says so
/// (the engine turns it into a note); once one is confirmed, or without confirmation, not.
#[test]
fn a_run_with_no_confirmed_source_is_told() {
    let mut t = confirming(20);
    t.update(&result(0, vec![peak(60.0, 0.0, 5.0), peak(150.0, 0.0, 5.0)]));
    t.update(&result(10, vec![peak(60.0, 0.0, 5.0)]));
    assert_eq!(t.none_confirmed(), Some(2));
    t.update(&result(20, vec![peak(60.0, 0.0, 5.0)]));
    assert_eq!(t.none_confirmed(), None);
    t.reset();
    assert_eq!(t.none_confirmed(), None);
    let mut hark = SourceTracker::new(TrackerConfig::default());
    hark.update(&result(0, vec![peak(60.0, 0.0, 5.0)]));
    assert_eq!(hark.none_confirmed(), None);
}

/// Confirmation needs a matching angle: with MIN_SRC_INTERVAL 0 no later peak could
/// confirm a new source, so every id would silently be lost; refused, naming the fix.
#[test]
fn confirmation_with_a_zero_interval_is_refused() {
    let c = TrackerConfig {
        min_src_interval_deg: 0.0,
        confirm_frames: Some(50),
        ..TrackerConfig::default()
    };
    let e = c.validate().unwrap_err().to_string();
    assert!(e.contains("MIN_SRC_INTERVAL") && e.contains("--confirm 0"), "{e}");
    assert!(TrackerConfig {
        confirm_frames: Some(0),
        ..c
    }
    .validate()
    .is_ok());
}
