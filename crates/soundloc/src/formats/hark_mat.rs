//! HARK's matrix binary `.mat` (HARK ≥ 2.1), as found inside transfer-function and
//! correlation-matrix zips.
//!
//! Layout (little-endian):
//!
//! | bytes | content |
//! |---|---|
//! | 0..32 | ASCII `HARK1.3`, space padded |
//! | 32..64 | type name `complex`, `float32` or `int32`, space padded |
//! | 64..68 | i32 ndim (2; 1 is accepted on reading as a 1 × n row) |
//! | 68..68+4·ndim | i32 dimensions: rows, cols |
//! | then | rows × cols values, row-major; `complex` = (re, im) f32 pairs, 8 bytes |
//!
//! A localization TF of M microphones at N-point FFT is a `complex` M × (N/2 + 1) matrix:
//! 8 × 257 → 76 + 8·257·8 = 16524 bytes.

use crate::{Error, Result};
use num_complex::Complex;
use std::path::Path;

/// The magic string at byte 0.
pub const MAT_MAGIC: &str = "HARK1.3";
/// Bytes of a 2-D header (magic, type, ndim, rows, cols).
pub const MAT_HEADER_BYTES: usize = 76;

/// The values of a matrix, row-major.
#[derive(Debug, Clone, PartialEq)]
pub enum MatValues {
    /// `complex`: (re, im) f32 pairs.
    Complex(Vec<Complex<f32>>),
    /// `float32`.
    Float32(Vec<f32>),
    /// `int32`.
    Int32(Vec<i32>),
}

impl MatValues {
    /// The HARK type name of this variant (`complex`, `float32`, `int32`).
    pub fn type_name(&self) -> &'static str {
        match self {
            MatValues::Complex(_) => "complex",
            MatValues::Float32(_) => "float32",
            MatValues::Int32(_) => "int32",
        }
    }
    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            MatValues::Complex(v) => v.len(),
            MatValues::Float32(v) => v.len(),
            MatValues::Int32(v) => v.len(),
        }
    }
    /// True when there are no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Bytes per value in the file.
    pub fn element_bytes(&self) -> usize {
        match self {
            MatValues::Complex(_) => 8,
            _ => 4,
        }
    }
}

/// A matrix read from or to be written to a `.mat` file.
#[derive(Debug, Clone, PartialEq)]
pub struct MatData {
    /// The type name as found in the file (trimmed). On writing, the name of `data`'s
    /// variant is written instead ([`MatValues::type_name`]), so the two cannot disagree.
    pub type_name: String,
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// rows × cols values, row-major.
    pub data: MatValues,
}

impl MatData {
    /// A complex matrix (`data.len()` should be rows × cols).
    pub fn complex(rows: usize, cols: usize, data: Vec<Complex<f32>>) -> Self {
        MatData {
            type_name: "complex".into(),
            rows,
            cols,
            data: MatValues::Complex(data),
        }
    }
    /// The complex values, or an error naming `path_for_errors` when the matrix has
    /// another type.
    pub fn into_complex(self, path_for_errors: &Path) -> Result<Vec<Complex<f32>>> {
        match self.data {
            MatValues::Complex(v) => Ok(v),
            other => Err(Error::format(
                path_for_errors,
                format!("expected a complex matrix, found {}", other.type_name()),
            )),
        }
    }
}

fn padded(s: &str) -> [u8; 32] {
    let mut b = [b' '; 32];
    for (d, c) in b.iter_mut().zip(s.bytes()) {
        *d = c;
    }
    b
}

fn i32_at(bytes: &[u8], off: usize) -> Option<i32> {
    let b = bytes.get(off..off + 4)?;
    Some(i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

fn f32_at(b: &[u8], off: usize) -> f32 {
    f32::from_le_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]])
}

fn header_text(b: &[u8]) -> String {
    String::from_utf8_lossy(b)
        .trim_end_matches([' ', '\0'])
        .to_string()
}

/// Parse a `.mat` file's bytes. Errors name `path_for_errors` (for an entry of a zip pass
/// e.g. `tf.zip: transferFunction/localization/tf00003.mat`) and say what is wrong:
/// wrong magic, unknown type, bad dimensions, or a size that does not match the header
/// (`expected 16524 bytes, found 1200`).
pub fn read_mat(bytes: &[u8], path_for_errors: &Path) -> Result<MatData> {
    let fail = |m: String| Error::format(path_for_errors, m);
    if bytes.len() < 68 {
        return Err(fail(format!(
            "too short for a HARK .mat header: {} bytes (need at least {MAT_HEADER_BYTES})",
            bytes.len()
        )));
    }
    let magic = header_text(&bytes[..32]);
    if magic != MAT_MAGIC {
        return Err(fail(format!(
            "not a HARK .mat file: expected magic \"{MAT_MAGIC}\", found {:?}",
            String::from_utf8_lossy(&bytes[..7.min(bytes.len())])
        )));
    }
    let type_name = header_text(&bytes[32..64]);
    let ndim = i32_at(bytes, 64).unwrap_or(0);
    let dims: Vec<i64> = match ndim {
        1 | 2 => {
            let n = ndim as usize;
            let mut d = Vec::with_capacity(n);
            for i in 0..n {
                match i32_at(bytes, 68 + 4 * i) {
                    Some(v) => d.push(v as i64),
                    None => {
                        return Err(fail(format!(
                            "truncated header: {} bytes, dimensions missing",
                            bytes.len()
                        )))
                    }
                }
            }
            d
        }
        other => {
            return Err(fail(format!(
                "unsupported number of dimensions {other} (expected 2)"
            )))
        }
    };
    if let Some(bad) = dims.iter().find(|&&d| d < 0) {
        return Err(fail(format!("negative dimension {bad}")));
    }
    let (rows, cols) = if dims.len() == 2 {
        (dims[0] as usize, dims[1] as usize)
    } else {
        (1, dims[0] as usize)
    };
    let header = 68 + 4 * dims.len();
    let elem = match type_name.as_str() {
        "complex" => 8usize,
        "float32" | "float" | "int32" | "int" => 4,
        other => {
            return Err(fail(format!(
                "unknown matrix type {other:?} (expected complex, float32 or int32)"
            )))
        }
    };
    let expected = rows
        .checked_mul(cols)
        .and_then(|n| n.checked_mul(elem))
        .and_then(|n| n.checked_add(header));
    let expected = match expected {
        Some(e) => e,
        None => return Err(fail(format!("dimensions {rows} × {cols} are too large"))),
    };
    if bytes.len() != expected {
        return Err(fail(format!(
            "expected {expected} bytes, found {} ({type_name} {rows} × {cols})",
            bytes.len()
        )));
    }
    let body = &bytes[header..];
    let n = rows * cols;
    let data = match type_name.as_str() {
        "complex" => MatValues::Complex(
            (0..n)
                .map(|i| Complex::new(f32_at(body, 8 * i), f32_at(body, 8 * i + 4)))
                .collect(),
        ),
        "float32" | "float" => MatValues::Float32((0..n).map(|i| f32_at(body, 4 * i)).collect()),
        _ => MatValues::Int32((0..n).map(|i| i32_at(body, 4 * i).unwrap_or(0)).collect()),
    };
    Ok(MatData {
        type_name,
        rows,
        cols,
        data,
    })
}

/// Serialise a matrix (2-D header). The type name written is that of `m.data`'s variant.
/// `m.data.len()` should equal rows × cols; the values are written as they are.
pub fn write_mat(m: &MatData) -> Vec<u8> {
    let mut out = Vec::with_capacity(MAT_HEADER_BYTES + m.data.len() * m.data.element_bytes());
    out.extend_from_slice(&padded(MAT_MAGIC));
    out.extend_from_slice(&padded(m.data.type_name()));
    out.extend_from_slice(&2i32.to_le_bytes());
    out.extend_from_slice(&(m.rows as i32).to_le_bytes());
    out.extend_from_slice(&(m.cols as i32).to_le_bytes());
    match &m.data {
        MatValues::Complex(v) => {
            for c in v {
                out.extend_from_slice(&c.re.to_le_bytes());
                out.extend_from_slice(&c.im.to_le_bytes());
            }
        }
        MatValues::Float32(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
        MatValues::Int32(v) => v.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes())),
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("tf.zip: transferFunction/localization/tf00003.mat")
    }

    #[test]
    fn round_trip_all_types() {
        let c = MatData::complex(
            2,
            3,
            (0..6)
                .map(|i| Complex::new(i as f32 * 0.5, -(i as f32)))
                .collect(),
        );
        let b = write_mat(&c);
        assert_eq!(b.len(), 76 + 6 * 8);
        assert_eq!(&b[..8], b"HARK1.3 ");
        assert_eq!(&b[32..40], b"complex ");
        assert_eq!(read_mat(&b, p()).unwrap(), c);
        let f = MatData {
            type_name: "float32".into(),
            rows: 1,
            cols: 2,
            data: MatValues::Float32(vec![1.5, f32::MIN_POSITIVE]),
        };
        assert_eq!(read_mat(&write_mat(&f), p()).unwrap(), f);
        let i = MatData {
            type_name: "int32".into(),
            rows: 3,
            cols: 1,
            data: MatValues::Int32(vec![-1, 0, i32::MAX]),
        };
        assert_eq!(read_mat(&write_mat(&i), p()).unwrap(), i);
        // 8 × 257 is 16524 bytes, as the spec says.
        let tf = MatData::complex(8, 257, vec![Complex::new(0.0, 0.0); 8 * 257]);
        assert_eq!(write_mat(&tf).len(), 16524);
    }

    #[test]
    fn malformed() {
        let good = write_mat(&MatData::complex(8, 257, vec![Complex::new(1.0, 0.0); 8 * 257]));
        let e = read_mat(&good[..1200], p()).unwrap_err().to_string();
        assert_eq!(
            e,
            "tf.zip: transferFunction/localization/tf00003.mat: expected 16524 bytes, found 1200 (complex 8 × 257)"
        );
        let mut bad = good.clone();
        bad[..7].copy_from_slice(b"HARK9.9");
        let e = read_mat(&bad, p()).unwrap_err().to_string();
        assert!(e.contains("tf00003.mat") && e.contains("magic"), "{e}");
        let mut bad = good.clone();
        bad[32..39].copy_from_slice(b"double ");
        let e = read_mat(&bad, p()).unwrap_err().to_string();
        assert!(e.contains("unknown matrix type"), "{e}");
        let e = read_mat(&good[..40], p()).unwrap_err().to_string();
        assert!(e.contains("too short"), "{e}");
        let mut bad = good.clone();
        bad[64..68].copy_from_slice(&3i32.to_le_bytes());
        assert!(read_mat(&bad, p())
            .unwrap_err()
            .to_string()
            .contains("dimensions 3"));
        let mut long = good;
        long.push(0);
        assert!(read_mat(&long, p())
            .unwrap_err()
            .to_string()
            .contains("expected 16524 bytes, found 16525"));
    }
}
