//! ODAS-compatible JSON messages, so odas_web and odas_ros read soundloc unchanged
//! (`spec/odas-json.md`; layout as ODAS's `snk_pots.c` / `snk_tracks.c` print it).
//!
//! - **SSL** (potential sources, ODAS sink "pots"): one message per result with exactly
//!   `pots` entries (ODAS's `nPots`, default 4), strongest first; when a result has fewer
//!   peaks the rest are zeros (`x = y = z = E = 0`). A result has at most `--max-peaks`
//!   peaks (`num_sources` by default), fewer where its spectrum has fewer local maxima.
//! - **SST** (tracked sources, sink "tracks"): `tracks` slots (`nTracks`, default 4). A
//!   track keeps its slot while it lives; a new track takes the first free slot; an empty
//!   slot is `id 0, tag "", zeros`. Tracks beyond the slots (the weakest) are left out.
//!
//! Field mapping:
//!
//! | ODAS | soundloc |
//! |---|---|
//! | `timeStamp` | c + 1 for the result frame c (0-based STFT frame index): ODAS counts hops from 1 (`src_hops.c` increments its counter before the first hop), and its sinks treat a zero time stamp as no message |
//! | `x, y, z` | unit vector of the source's azimuth and elevation (`%1.3f`) |
//! | `E` (SSL) | [`energy`]: P̄ / (P̄ + 1) = 1 − 10^(−dB/10) for the MUSIC power dB = 10·log10(P̄ + 1), in [0, 1) and increasing with power |
//! | `id` (SST) | soundloc's track id + 1 (ODAS reserves 0 for an empty slot; ids must be ≥ 0) |
//! | `tag` (SST) | `"dynamic"` (ODAS's tag for tracked sources) |
//! | `activity` (SST) | [`energy`] of the track's current power |
//!
//! Each message is the text below (newline-terminated, 4-space indents), the layout
//! odas_web's stream splitter (`}\n{`) expects:
//!
//! ```text
//! {
//!     "timeStamp": 12,
//!     "src": [
//!         { "x": 0.707, "y": 0.707, "z": 0.000, "E": 0.998 },
//!         { "x": 0.000, "y": 0.000, "z": 0.000, "E": 0.000 }
//!     ]
//! }
//! ```

use crate::result::{LocalizationResult, Source};
use std::fmt::Write;

/// ODAS's default number of potential sources per SSL message.
pub const DEFAULT_POTS: usize = 4;
/// ODAS's default number of track slots per SST message.
pub const DEFAULT_TRACKS: usize = 4;

/// The ODAS energy of a MUSIC power in dB (10·log10(P̄ + 1)): P̄ / (P̄ + 1), in [0, 1).
pub fn energy(power_db: f64) -> f64 {
    if power_db.is_nan() {
        return 0.0;
    }
    (1.0 - 10f64.powf(-power_db / 10.0)).clamp(0.0, 1.0)
}

/// The unit vector (x, y, z) of a source's azimuth and elevation.
pub fn unit_vector(s: &Source) -> [f64; 3] {
    let (az, el) = (s.azimuth_deg.to_radians(), s.elevation_deg.to_radians());
    [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]
}

/// `%1.3f` of `v`, with a negative zero printed as `0.000`.
fn f3(out: &mut String, v: f64) {
    let v = if v.is_finite() { v } else { 0.0 };
    let r = (v * 1000.0).round() / 1000.0;
    let _ = write!(out, "{:.3}", if r == 0.0 { 0.0 } else { r });
}

fn open(out: &mut String, time_stamp: usize) {
    let _ = write!(out, "{{\n    \"timeStamp\": {time_stamp},\n    \"src\": [\n");
}

fn close(out: &mut String) {
    out.push_str("    ]\n}\n");
}

/// Append the SSL message of `result` with `pots` entries.
pub fn write_ssl(result: &LocalizationResult, pots: usize, out: &mut String) {
    open(out, result.frame + 1);
    for k in 0..pots {
        let (v, e) = match result.sources.get(k) {
            Some(s) => (unit_vector(s), energy(s.power_db)),
            None => ([0.0; 3], 0.0),
        };
        out.push_str("        { \"x\": ");
        f3(out, v[0]);
        out.push_str(", \"y\": ");
        f3(out, v[1]);
        out.push_str(", \"z\": ");
        f3(out, v[2]);
        out.push_str(", \"E\": ");
        f3(out, e);
        out.push_str(if k + 1 < pots { " },\n" } else { " }\n" });
    }
    close(out);
}

/// SST slots: which track id sits in which slot, kept from result to result.
#[derive(Debug, Clone)]
pub struct SstSlots {
    slots: Vec<Option<i64>>,
}

impl SstSlots {
    /// `tracks` empty slots.
    pub fn new(tracks: usize) -> Self {
        SstSlots {
            slots: vec![None; tracks],
        }
    }

    /// Append the SST message of `result` (its tracked sources; untracked ones are
    /// ignored), updating the slots.
    pub fn write(&mut self, result: &LocalizationResult, out: &mut String) {
        let live: Vec<&Source> = result
            .sources
            .iter()
            .filter(|s| s.id.is_some_and(|id| id >= 0))
            .collect();
        // Free the slots of tracks that ended, then place new tracks (strongest first).
        for slot in &mut self.slots {
            if slot.is_some_and(|id| !live.iter().any(|s| s.id == Some(id))) {
                *slot = None;
            }
        }
        for s in &live {
            if !self.slots.contains(&s.id) {
                if let Some(free) = self.slots.iter_mut().find(|x| x.is_none()) {
                    *free = s.id;
                }
            }
        }
        open(out, result.frame + 1);
        let n = self.slots.len();
        for (k, slot) in self.slots.iter().enumerate() {
            let src = slot.and_then(|id| live.iter().find(|s| s.id == Some(id)));
            match src {
                Some(s) => {
                    let v = unit_vector(s);
                    let _ = write!(
                        out,
                        "        {{ \"id\": {}, \"tag\": \"dynamic\", \"x\": ",
                        s.id.unwrap_or(0) + 1
                    );
                    f3(out, v[0]);
                    out.push_str(", \"y\": ");
                    f3(out, v[1]);
                    out.push_str(", \"z\": ");
                    f3(out, v[2]);
                    out.push_str(", \"activity\": ");
                    f3(out, energy(s.power_db));
                }
                None => out.push_str(
                    "        { \"id\": 0, \"tag\": \"\", \"x\": 0.000, \"y\": 0.000, \"z\": 0.000, \"activity\": 0.000",
                ),
            }
            out.push_str(if k + 1 < n { " },\n" } else { " }\n" });
        }
        close(out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn src(id: Option<i64>, az: f64, el: f64, db: f64) -> Source {
        Source {
            id,
            grid_index: 0,
            azimuth_deg: az,
            elevation_deg: el,
            x: 0.0,
            y: 0.0,
            z: 0.0,
            power_db: db,
            held: false,
        }
    }

    fn result(frame: usize, sources: Vec<Source>) -> LocalizationResult {
        LocalizationResult {
            num_active: None,
            frame,
            time_s: 0.0,
            sources,
        }
    }

    #[test]
    fn ssl_has_odas_layout_fixed_entries_and_unit_vectors() {
        let r = result(
            11,
            vec![src(None, 45.0, 0.0, 30.0), src(None, -90.0, 30.0, 3.0103)],
        );
        let mut s = String::new();
        write_ssl(&r, 3, &mut s);
        // Frame 11 (0-based) is ODAS's hop 12.
        assert_eq!(
            s,
            "{\n    \"timeStamp\": 12,\n    \"src\": [\n\
             \x20       { \"x\": 0.707, \"y\": 0.707, \"z\": 0.000, \"E\": 0.999 },\n\
             \x20       { \"x\": 0.000, \"y\": -0.866, \"z\": 0.500, \"E\": 0.500 },\n\
             \x20       { \"x\": 0.000, \"y\": 0.000, \"z\": 0.000, \"E\": 0.000 }\n    ]\n}\n"
        );
        let v: serde_json::Value = serde_json::from_str(&s).unwrap();
        assert_eq!(v["src"].as_array().unwrap().len(), 3);
    }

    #[test]
    fn energy_maps_power_into_the_unit_interval() {
        assert_eq!(energy(0.0), 0.0);
        assert!((energy(10.0) - 0.9).abs() < 1e-12);
        assert_eq!(energy(-5.0), 0.0);
        assert_eq!(energy(f64::NAN), 0.0);
        assert!(energy(1e6) <= 1.0);
    }

    #[test]
    fn sst_slots_keep_their_track_and_free_when_it_ends() {
        let mut slots = SstSlots::new(2);
        let parse = |s: &str| serde_json::from_str::<serde_json::Value>(s).unwrap();
        let ids = |v: &serde_json::Value| -> Vec<i64> {
            v["src"]
                .as_array()
                .unwrap()
                .iter()
                .map(|e| e["id"].as_i64().unwrap())
                .collect()
        };
        let mut s = String::new();
        slots.write(&result(1, vec![src(Some(0), 10.0, 0.0, 20.0)]), &mut s);
        assert_eq!(ids(&parse(&s)), vec![1, 0]);
        assert_eq!(parse(&s)["src"][1]["tag"], "");
        s.clear();
        // Track 5 is stronger now but track 0 keeps slot 0.
        slots.write(
            &result(
                2,
                vec![src(Some(5), 90.0, 0.0, 30.0), src(Some(0), 12.0, 0.0, 10.0)],
            ),
            &mut s,
        );
        let v = parse(&s);
        assert_eq!(ids(&v), vec![1, 6]);
        assert_eq!(v["src"][1]["tag"], "dynamic");
        assert_eq!(v["src"][1]["y"].as_f64().unwrap(), 1.0);
        s.clear();
        // Track 0 ends; 7 takes its slot; a third track finds no slot; untracked ignored.
        slots.write(
            &result(
                3,
                vec![
                    src(Some(5), 90.0, 0.0, 30.0),
                    src(Some(7), 0.0, 0.0, 9.0),
                    src(Some(8), 0.0, 0.0, 8.0),
                    src(None, 0.0, 0.0, 50.0),
                ],
            ),
            &mut s,
        );
        assert_eq!(ids(&parse(&s)), vec![8, 6]);
    }
}
