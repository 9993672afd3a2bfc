//! The live view's messages (what `soundloc … --serve` sends to browsers over a WebSocket).
//! The server only moves these bytes; what they say is decided here.
//!
//! Text messages are JSON objects with a `type`:
//!
//! - `hello` (first, once per client): the grid (`azimuth_deg`, `elevation_deg` per
//!   direction, `kind` `"ring"` when all directions share one elevation to within
//!   [`RING_TOLERANCE_DEG`], else `"sphere"`),
//!   the run (`source`, `algorithm` (its name, e.g. `sevd`), `label` (what runs, for people:
//!   e.g. `normmusic (subspace 4, coherence, refined)`), `device`, `sample_rate_hz`, `hop`,
//!   `latency_ms`: the
//!   algorithmic latency, the window's look-ahead plus one frame) and the look from
//!   [`super::style`] (`colormap`: 256 RGB triples, `track_colours`, `peak_colour`,
//!   `azimuth_bin_deg`, `scale_results`).
//! - `result`: one localization result, its JSON line as `soundloc localize` writes it
//!   (`frame`, `time_s`, `num_active` when estimated, `sources` with `azimuth_deg`,
//!   `elevation_deg`, `x`, `y`, `z`, `power_db`, `grid_index`, `id` when tracked, `held: true`
//!   for a tracked source carried through a pause, not observed).
//! - `status` (about twice a second): `audio_s` localized, `rtf` (compute time / audio
//!   time), `compute_ms` (the last block's), `lost_s` (live input dropped while behind),
//!   `view_dropped` (messages this client missed because it read too slowly), `finished`.
//!
//! Binary messages carry one spectrum (little-endian, 28-byte header, so the f32 values are
//! 4-byte aligned for a `Float32Array`):
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | 4 bytes | magic `SLSP` |
//! | 4 | u32 | version, 1 |
//! | 8 | u64 | result frame c |
//! | 16 | f32 | time of the result, s |
//! | 20 | u32 | number of directions D |
//! | 24 | u32 | reserved, 0 |
//! | 28 | f32 × D | power in dB per direction, grid order |

use super::style;
use crate::result::LocalizationResult;
use serde_json::json;

/// Magic of a binary spectrum message.
pub const SPECTRUM_MAGIC: &[u8; 4] = b"SLSP";
/// Size of the binary spectrum header in bytes.
pub const SPECTRUM_HEADER_BYTES: usize = 28;

/// What the `hello` message says about the run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunInfo {
    /// Name of the input (file, `standard input`, device...).
    pub source: String,
    /// Algorithm name (e.g. `gevd`).
    pub algorithm: String,
    /// What runs, for people ([`crate::LocalizeConfig::label`]).
    pub label: String,
    /// Compute device (e.g. `cpu`, `cuda:0 (NVIDIA H100)`).
    pub device: String,
    /// Sampling rate, Hz.
    pub sample_rate_hz: u32,
    /// Frame shift, samples.
    pub hop: usize,
    /// Algorithmic latency, ms.
    pub latency_ms: f64,
}

/// Directions whose elevations all lie within this of the first are a ring (one
/// elevation): measured transfer functions' rings vary by a few hundredths of a degree
/// (HARK's tamago zip: 30.957°–30.969°), and a sky map of them would draw rows never scanned.
pub const RING_TOLERANCE_DEG: f64 = 0.5;

/// The `hello` message for a grid of `azimuth_deg` / `elevation_deg` directions.
pub fn hello(info: &RunInfo, azimuth_deg: &[f64], elevation_deg: &[f64]) -> String {
    let ring = elevation_deg
        .first()
        .is_none_or(|e0| elevation_deg.iter().all(|e| (e - e0).abs() < RING_TOLERANCE_DEG));
    json!({
        "type": "hello",
        "version": 1,
        "source": info.source,
        "algorithm": info.algorithm,
        "label": info.label,
        "device": info.device,
        "sample_rate_hz": info.sample_rate_hz,
        "hop": info.hop,
        "latency_ms": info.latency_ms,
        "grid": {
            "kind": if ring { "ring" } else { "sphere" },
            "azimuth_deg": azimuth_deg,
            "elevation_deg": elevation_deg,
        },
        "colormap": style::colormap_table(256),
        "track_colours": style::track_palette(),
        "peak_colour": style::PEAK_RGB,
        "azimuth_bin_deg": style::AZIMUTH_BIN_DEG,
        "scale_results": style::LIVE_SCALE_RESULTS,
    })
    .to_string()
}

/// The `result` message of one result: its JSON line ([`super::jsonl::to_json_line`],
/// the same fields and rules as `soundloc localize`'s output) with `"type": "result"` first.
pub fn result(r: &LocalizationResult) -> String {
    let line = super::jsonl::to_json_line(r);
    // The line is a JSON object: "{" then its fields.
    match line.strip_prefix('{') {
        Some(fields) => format!("{{\"type\":\"result\",{fields}"),
        None => json!({"type": "result"}).to_string(),
    }
}

/// How the run is going, for the `status` message.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Status {
    /// Audio localized so far, s.
    pub audio_s: f64,
    /// Compute time / audio time so far.
    pub rtf: f64,
    /// Compute time of the last block, ms.
    pub compute_ms: f64,
    /// Live audio dropped while behind, s.
    pub lost_s: f64,
    /// Messages this client missed (filled in per client by the server).
    pub view_dropped: u64,
    /// The input has ended (the view stays until the server stops).
    pub finished: bool,
}

/// The `status` message.
pub fn status(s: &Status) -> String {
    json!({
        "type": "status",
        "audio_s": s.audio_s,
        "rtf": s.rtf,
        "compute_ms": s.compute_ms,
        "lost_s": s.lost_s,
        "view_dropped": s.view_dropped,
        "finished": s.finished,
    })
    .to_string()
}

/// The binary spectrum message: `db` (one value per direction) of result `frame` at
/// `time_s`.
pub fn spectrum(frame: usize, time_s: f64, db: &[f32]) -> Vec<u8> {
    let mut b = Vec::with_capacity(SPECTRUM_HEADER_BYTES + 4 * db.len());
    b.extend_from_slice(SPECTRUM_MAGIC);
    b.extend_from_slice(&1u32.to_le_bytes());
    b.extend_from_slice(&(frame as u64).to_le_bytes());
    b.extend_from_slice(&(time_s as f32).to_le_bytes());
    b.extend_from_slice(&(db.len() as u32).to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes());
    for v in db {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::result::Source;

    #[test]
    fn hello_says_ring_or_sphere_and_carries_the_style() {
        let info = RunInfo {
            source: "x.wav".into(),
            algorithm: "gevd".into(),
            label: "gevd (subspace 4, refined)".into(),
            device: "cpu".into(),
            sample_rate_hz: 16000,
            hop: 160,
            latency_ms: 500.0,
        };
        let v: serde_json::Value = serde_json::from_str(&hello(&info, &[0.0, 90.0], &[0.0, 0.0])).unwrap();
        assert_eq!(v["grid"]["kind"], "ring");
        assert_eq!(v["colormap"].as_array().unwrap().len(), 256);
        assert_eq!(v["colormap"][255], json!(style::colormap(1.0)));
        let v: serde_json::Value = serde_json::from_str(&hello(&info, &[0.0, 90.0], &[0.0, 30.0])).unwrap();
        assert_eq!(v["grid"]["kind"], "sphere");
        // A measured ring's elevations wander by hundredths of a degree (HARK's tamago zip).
        let v: serde_json::Value =
            serde_json::from_str(&hello(&info, &[0.0, 90.0, 180.0], &[30.957, 30.969, 30.96])).unwrap();
        assert_eq!(v["grid"]["kind"], "ring");
        let v: serde_json::Value = serde_json::from_str(&hello(&info, &[0.0, 90.0], &[0.0, 0.6])).unwrap();
        assert_eq!(v["grid"]["kind"], "sphere");
        assert_eq!(v["azimuth_bin_deg"], 2.0);
    }

    #[test]
    fn result_and_spectrum_encode_what_they_are_given() {
        let r = LocalizationResult {
            num_active: None,
            frame: 7,
            time_s: 0.07,
            sources: vec![Source {
                id: Some(3),
                grid_index: 1,
                azimuth_deg: 90.0,
                elevation_deg: 0.0,
                x: 0.0,
                y: 1.0,
                z: 0.0,
                power_db: 12.5,
                held: false,
            }],
        };
        let v: serde_json::Value = serde_json::from_str(&result(&r)).unwrap();
        assert_eq!(v["type"], "result");
        assert_eq!(v["sources"][0]["id"], 3);
        assert!(v["sources"][0].get("held").is_none() && v.get("num_active").is_none());
        let mut h = r.clone();
        h.sources[0].held = true;
        h.num_active = Some(0);
        let v: serde_json::Value = serde_json::from_str(&result(&h)).unwrap();
        assert_eq!(
            (v["sources"][0]["held"].clone(), v["num_active"].clone()),
            (json!(true), json!(0))
        );
        assert_eq!(v["sources"][0]["azimuth_deg"], 90.0);
        // Beyond "type", the fields are the JSON line's.
        let mut line: serde_json::Value =
            serde_json::from_str(&super::super::jsonl::to_json_line(&h)).unwrap();
        line["type"] = json!("result");
        assert_eq!(
            serde_json::from_str::<serde_json::Value>(&result(&h)).unwrap(),
            line
        );
        let b = spectrum(7, 0.5, &[1.0, -2.5]);
        assert_eq!(&b[..4], SPECTRUM_MAGIC);
        assert_eq!(b.len(), SPECTRUM_HEADER_BYTES + 8);
        assert_eq!(u64::from_le_bytes(b[8..16].try_into().unwrap()), 7);
        assert_eq!(f32::from_le_bytes(b[16..20].try_into().unwrap()), 0.5);
        assert_eq!(u32::from_le_bytes(b[20..24].try_into().unwrap()), 2);
        assert_eq!(f32::from_le_bytes(b[32..36].try_into().unwrap()), -2.5);
    }
}
