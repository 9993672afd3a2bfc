//! Old binary transfer functions "HGTF" (HARK ≤ 2.0: `*_loc.dat`, `*.tff`), read only.
//!
//! Little-endian, RIFF-like (decoded from kinect_loc.dat):
//!
//! ```text
//! "HARK" u32 size-of-rest "HGTF"
//! "fmt " u32 size   u16 major, u16 minor, i32 format id (0 undefined, 1 M2PG =
//!                   localization, 2 GTF = separation, 3 SM), i32 nmic, i32 nfft,
//!                   i32 impulse length, i32 fs (Hz), nmic × 3 f32 mic positions (m)
//! "M2PG" u32 size   u16 major, u16 minor, i32 Nd, i32 Nr, Nd·Nr × 3 f32 source
//!                   positions [direction][range], then complex f32 (re, im) ordered
//!                   [direction][range][mic][bin], bins 0..nfft/2+1
//! "SPEC" u32 size   free text (date, author): skipped
//! ```
//!
//! Chunks are found by tag, so their order and unknown chunks do not matter. The number
//! of bins is decoded from the chunk size and must equal nfft/2 + 1. A file with several
//! ranges (Nr > 1, distances) yields **range 0 only**: its positions and TFs. The grid is a
//! [`crate::array::GridKind::Ring`] when the positions form one (kinect_loc.dat: 72
//! directions from −180° counter-clockwise), else irregular with 6 nearest neighbours.

use crate::array::{Grid, TransferFunctions};
use crate::{Error, Result};
use num_complex::Complex;
use std::path::Path;

/// True when `bytes` start with `HARK....HGTF`.
pub fn looks_like_hgtf(bytes: &[u8]) -> bool {
    bytes.len() >= 12 && &bytes[..4] == b"HARK" && &bytes[8..12] == b"HGTF"
}

fn i32_at(b: &[u8], o: usize) -> i32 {
    i32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}
fn f32_at(b: &[u8], o: usize) -> f32 {
    f32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}

/// Read an HGTF file from disk.
pub fn read_hgtf_file(path: &Path) -> Result<TransferFunctions> {
    let bytes = super::read_bounded(path, super::MAX_HGTF_BYTES, "HGTF file")?;
    read_hgtf(&bytes, path)
}

/// Parse HGTF bytes (range 0 of the M2PG chunk). Errors name `path_for_errors` and the
/// chunk: wrong magic, truncation, sizes that disagree with the header counts, a format
/// other than M2PG, non-finite values.
pub fn read_hgtf(bytes: &[u8], path_for_errors: &Path) -> Result<TransferFunctions> {
    let fail = |m: String| Error::format(path_for_errors, m);
    if !looks_like_hgtf(bytes) {
        return Err(fail(format!(
            "not an HGTF file: expected \"HARK\" <size> \"HGTF\", found {:?}",
            String::from_utf8_lossy(&bytes[..bytes.len().min(12)])
        )));
    }
    let declared = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) as usize;
    if declared + 8 > bytes.len() {
        return Err(fail(format!(
            "truncated: header says {} bytes, the file has {}",
            declared + 8,
            bytes.len()
        )));
    }
    let end = declared + 8;
    // Collect chunks.
    let mut fmt: Option<&[u8]> = None;
    let mut m2pg: Option<&[u8]> = None;
    let mut other_kinds: Vec<String> = Vec::new();
    let mut off = 12;
    while off < end {
        if off + 8 > end {
            return Err(fail(format!("truncated chunk header at byte {off}")));
        }
        let tag = String::from_utf8_lossy(&bytes[off..off + 4]).to_string();
        let size =
            u32::from_le_bytes([bytes[off + 4], bytes[off + 5], bytes[off + 6], bytes[off + 7]]) as usize;
        let body_start = off + 8;
        let body_end = body_start.saturating_add(size);
        if body_end > end {
            return Err(fail(format!(
                "chunk {tag:?} at byte {off}: needs {size} bytes, only {} left (truncated)",
                end - body_start
            )));
        }
        let body = &bytes[body_start..body_end];
        match tag.as_str() {
            "fmt " => fmt = Some(body),
            "M2PG" => m2pg = Some(body),
            _ => other_kinds.push(tag),
        }
        off = body_end;
    }
    let fmt = fmt.ok_or_else(|| fail("no \"fmt \" chunk".into()))?;
    if fmt.len() < 24 {
        return Err(fail(format!(
            "\"fmt \" chunk: {} bytes, need at least 24",
            fmt.len()
        )));
    }
    let format_id = i32_at(fmt, 4);
    let nmic = i32_at(fmt, 8);
    let nfft = i32_at(fmt, 12);
    let fs = i32_at(fmt, 20);
    if format_id != 1 {
        let what = match format_id {
            0 => "undefined",
            2 => "GTF (separation)",
            3 => "SM",
            _ => "unknown",
        };
        return Err(fail(format!(
            "format id {format_id} ({what}): only M2PG (1, localization) transfer functions are supported"
        )));
    }
    if nmic <= 0 || nfft < 2 || fs <= 0 {
        return Err(fail(format!(
            "\"fmt \" chunk: implausible nmic {nmic}, nfft {nfft}, fs {fs}"
        )));
    }
    let (nmic, nfft) = (nmic as usize, nfft as usize);
    if fmt.len() < 24 + 12 * nmic {
        return Err(fail(format!(
            "\"fmt \" chunk: {} bytes, need {} for {nmic} microphone positions",
            fmt.len(),
            24 + 12 * nmic
        )));
    }
    let mic_positions: Vec<[f64; 3]> = (0..nmic)
        .map(|m| {
            let o = 24 + 12 * m;
            [
                f32_at(fmt, o) as f64,
                f32_at(fmt, o + 4) as f64,
                f32_at(fmt, o + 8) as f64,
            ]
        })
        .collect();
    let body = m2pg.ok_or_else(|| {
        fail(format!(
            "no \"M2PG\" (localization TF) chunk (chunks found: fmt{})",
            other_kinds.iter().map(|t| format!(", {t:?}")).collect::<String>()
        ))
    })?;
    if body.len() < 12 {
        return Err(fail(format!(
            "\"M2PG\" chunk: {} bytes, need at least 12",
            body.len()
        )));
    }
    let nd = i32_at(body, 4);
    let nr = i32_at(body, 8);
    if nd <= 0 || nr <= 0 {
        return Err(fail(format!(
            "\"M2PG\" chunk: implausible {nd} directions × {nr} ranges"
        )));
    }
    let (nd, nr) = (nd as usize, nr as usize);
    // Checked: the counts come from the file; their product must not wrap.
    let too_big = || {
        fail(format!("\"M2PG\" chunk: {nd} directions × {nr} ranges × {nmic} mics × nfft {nfft} cannot fit in the file"))
    };
    let pos_bytes = nd
        .checked_mul(nr)
        .and_then(|x| x.checked_mul(12))
        .ok_or_else(too_big)?;
    if body.len().saturating_sub(12) < pos_bytes {
        return Err(fail(format!(
            "\"M2PG\" chunk: {} bytes, too short for {nd} × {nr} source positions",
            body.len()
        )));
    }
    let data_bytes = body.len() - 12 - pos_bytes;
    let per_bin = nd
        .checked_mul(nr)
        .and_then(|x| x.checked_mul(nmic))
        .and_then(|x| x.checked_mul(8))
        .ok_or_else(too_big)?;
    let nbins = nfft / 2 + 1;
    if per_bin.checked_mul(nbins) != Some(data_bytes) {
        return Err(fail(format!(
            "\"M2PG\" chunk: {data_bytes} bytes of TF data, expected {} ({nd} directions × {nr} ranges × {nmic} mics × {nbins} bins × 8){}",
            per_bin as u128 * nbins as u128,
            if data_bytes % per_bin == 0 {
                format!(", i.e. {} bins instead of nfft/2+1", data_bytes / per_bin)
            } else {
                String::new()
            }
        )));
    }
    let points: Vec<[f64; 3]> = (0..nd)
        .map(|d| {
            let o = 12 + (d * nr) * 12;
            [
                f32_at(body, o) as f64,
                f32_at(body, o + 4) as f64,
                f32_at(body, o + 8) as f64,
            ]
        })
        .collect();
    let grid = Grid::from_points(points).map_err(|e| fail(format!("\"M2PG\" positions: {e}")))?;
    let data_start = 12 + pos_bytes;
    let mut data = Vec::with_capacity(nd * nmic * nbins);
    for d in 0..nd {
        // Range 0 of direction d.
        let base = data_start + (d * nr) * nmic * nbins * 8;
        for m in 0..nmic {
            for k in 0..nbins {
                let o = base + (m * nbins + k) * 8;
                let c = Complex::new(f32_at(body, o), f32_at(body, o + 4));
                if !(c.re.is_finite() && c.im.is_finite()) {
                    return Err(fail(format!(
                        "non-finite value {c} at direction {d}, mic {m}, bin {k}"
                    )));
                }
                data.push(c);
            }
        }
    }
    Ok(TransferFunctions {
        nfft,
        sample_rate_hz: fs as u32,
        grid,
        mic_positions,
        num_mics: nmic,
        first_bin: 0,
        num_bins: nbins,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small synthetic HGTF: 2 mics, nfft 4 (3 bins), 4 directions on a ring, 2 ranges.
    pub(crate) fn synth() -> Vec<u8> {
        let (nmic, nfft, nd, nr) = (2usize, 4usize, 4usize, 2usize);
        let nbins = nfft / 2 + 1;
        let mut fmt = Vec::new();
        fmt.extend_from_slice(&1u16.to_le_bytes());
        fmt.extend_from_slice(&0u16.to_le_bytes());
        for v in [1i32, nmic as i32, nfft as i32, 16, 16000] {
            fmt.extend_from_slice(&v.to_le_bytes());
        }
        for v in [0.1f32, 0.0, 0.0, -0.1, 0.0, 0.0] {
            fmt.extend_from_slice(&v.to_le_bytes());
        }
        let mut m2 = Vec::new();
        m2.extend_from_slice(&1u16.to_le_bytes());
        m2.extend_from_slice(&0u16.to_le_bytes());
        m2.extend_from_slice(&(nd as i32).to_le_bytes());
        m2.extend_from_slice(&(nr as i32).to_le_bytes());
        for d in 0..nd {
            for r in 0..nr {
                let a = (90.0 * d as f64).to_radians();
                let rr = 1.0 + r as f64;
                for v in [rr * a.cos(), rr * a.sin(), 0.0] {
                    m2.extend_from_slice(&(v as f32).to_le_bytes());
                }
            }
        }
        for d in 0..nd {
            for r in 0..nr {
                for m in 0..nmic {
                    for k in 0..nbins {
                        let re = (1000 * d + 100 * r + 10 * m + k) as f32;
                        m2.extend_from_slice(&re.to_le_bytes());
                        m2.extend_from_slice(&(-re).to_le_bytes());
                    }
                }
            }
        }
        let mut body = Vec::new();
        body.extend_from_slice(b"HGTF");
        for (tag, c) in [
            (b"fmt ", &fmt),
            (b"M2PG", &m2),
            (b"SPEC", &b"2011/12/07".to_vec()),
        ] {
            body.extend_from_slice(tag);
            body.extend_from_slice(&(c.len() as u32).to_le_bytes());
            body.extend_from_slice(c);
        }
        let mut out = b"HARK".to_vec();
        out.extend_from_slice(&(body.len() as u32).to_le_bytes());
        out.extend_from_slice(&body);
        out
    }

    #[test]
    fn reads_range_zero() {
        let tf = read_hgtf(&synth(), Path::new("x_loc.dat")).unwrap();
        assert_eq!((tf.num_mics, tf.num_dirs(), tf.nfft, tf.num_bins), (2, 4, 4, 3));
        assert_eq!(tf.sample_rate_hz, 16000);
        assert_eq!(tf.get(2, 1, 2), Complex::new(2012.0, -2012.0));
        assert_eq!(tf.get(3, 0, 0), Complex::new(3000.0, -3000.0));
        assert!((tf.grid.radius_m(1) - 1.0).abs() < 1e-6, "range 0 positions");
        assert_eq!(tf.grid.kind, crate::array::GridKind::Ring);
        assert!((tf.mic_positions[1][0] + 0.1).abs() < 1e-7);
    }

    #[test]
    fn malformed() {
        let p = Path::new("x_loc.dat");
        let good = synth();
        let e = |b: &[u8]| read_hgtf(b, p).unwrap_err().to_string();
        let mut bad = good.clone();
        bad[8..12].copy_from_slice(b"RIFF");
        assert!(e(&bad).starts_with("x_loc.dat: not an HGTF file"), "{}", e(&bad));
        assert!(
            e(&good[..good.len() - 5]).contains("truncated"),
            "{}",
            e(&good[..good.len() - 5])
        );
        assert!(e(&good[..6]).contains("not an HGTF"));
        // Declared sizes consistent but one bin missing in M2PG: fix up sizes.
        let mut bad = good.clone();
        bad[24] = 3; // format id byte (fmt body starts at 20; format id at +4)
        assert!(e(&bad).contains("format id 3"), "{}", e(&bad));
        let mut bad = good.clone();
        bad[32..36].copy_from_slice(&6i32.to_le_bytes()); // nfft 4 -> 6 (4 bins)
        assert!(e(&bad).contains("i.e. 3 bins instead of nfft/2+1"), "{}", e(&bad));
        // Counts whose product wraps past 2^64 (842443544 × 1824726041 × 12 = 2^64 + 32):
        // an error, never a small wrapped size that passes the checks.
        let mut bad = good.clone();
        bad[80..84].copy_from_slice(&842_443_544i32.to_le_bytes());
        bad[84..88].copy_from_slice(&1_824_726_041i32.to_le_bytes());
        let msg = e(&bad);
        assert!(msg.contains("cannot fit in the file"), "{msg}");
        // NaN value.
        // NaN in range 0 (read) is an error; header 12 + fmt 8+48 + M2PG header 8+12 +
        // 4×2 positions × 12 = 184 is direction 0, mic 0, bin 0.
        let mut bad = good;
        bad[184..188].copy_from_slice(&f32::NAN.to_le_bytes());
        let msg = e(&bad);
        assert!(msg.starts_with("x_loc.dat: non-finite value"), "{msg}");
        assert!(msg.ends_with("at direction 0, mic 0, bin 0"), "{msg}");
    }
}
