//! NumPy `.npy` files of 2-D little-endian `f32` arrays (e.g. the dB spectrum,
//! rows = results, columns = grid directions).
//!
//! Layout (NPY format version 1.0): the magic `\x93NUMPY`, version bytes `1 0`, a
//! little-endian u16 header length H, then H bytes of ASCII header
//! `{'descr': '<f4', 'fortran_order': False, 'shape': (rows, cols), }` padded with spaces
//! and ended by `\n` so that 10 + H is a multiple of 64; then rows·cols `f32` values in
//! row-major (C) order, little-endian. `numpy.load` reads it as `float32` of shape
//! `(rows, cols)`.

use crate::{Error, Result};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::path::Path;

const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// A 2-D `f32` array in row-major order, as read from a `.npy` file.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyF32 {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// rows·cols values, row-major.
    pub data: Vec<f32>,
}

/// The complete NPY v1.0 preamble (magic, version, length, padded header) for a
/// `(rows, cols)` little-endian `f32` C-order array; its length is a multiple of 64.
pub fn npy_header(rows: usize, cols: usize) -> Vec<u8> {
    npy_header_at_least(rows, cols, 0)
}

/// [`npy_header`] padded with spaces to at least `min_total` bytes (still a multiple of
/// 64): a header rewritten in place once the row count is known keeps its length.
fn npy_header_at_least(rows: usize, cols: usize, min_total: usize) -> Vec<u8> {
    let dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({rows}, {cols}), }}");
    // 10 bytes before the header text; the text ends with '\n'.
    let unpadded = (10 + dict.len() + 1).max(min_total);
    let total = unpadded.div_ceil(64) * 64;
    let header_len = total - 10;
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    // A 2-D shape's dict is far below 65535 bytes.
    out.extend_from_slice(&(header_len as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.resize(total - 1, b' ');
    out.push(b'\n');
    out
}

/// Write a `(rows, cols)` f32 array to `w`; `data.len()` must be rows·cols.
pub fn write_npy_f32<W: Write>(mut w: W, rows: usize, cols: usize, data: &[f32]) -> io::Result<()> {
    if rows.checked_mul(cols) != Some(data.len()) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "npy: shape ({rows}, {cols}) needs {} values, got {}",
                rows.saturating_mul(cols),
                data.len()
            ),
        ));
    }
    w.write_all(&npy_header(rows, cols))?;
    let mut buf = Vec::with_capacity(data.len().min(1 << 16) * 4);
    for chunk in data.chunks(1 << 16) {
        buf.clear();
        for v in chunk {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        w.write_all(&buf)?;
    }
    Ok(())
}

/// An `.npy` written a row at a time, for arrays too big to hold (an hour's spectrum on a
/// fine grid): the header is written first with room for any row count and rewritten
/// with the real one by [`finish`](Self::finish). The bytes equal [`write_npy_f32`]'s
/// but for the header's padding.
#[derive(Debug)]
pub struct NpyRowWriter<W: Write + Seek> {
    w: W,
    cols: usize,
    rows: usize,
    header_len: usize,
    buf: Vec<u8>,
}

impl<W: Write + Seek> NpyRowWriter<W> {
    /// Start an array of `cols` columns (≥ 1) at `w`'s current position 0.
    pub fn new(mut w: W, cols: usize) -> io::Result<Self> {
        if cols == 0 {
            return Err(io::Error::new(io::ErrorKind::InvalidInput, "npy: 0 columns"));
        }
        let header = npy_header(usize::MAX, cols);
        w.write_all(&header)?;
        Ok(NpyRowWriter {
            w,
            cols,
            rows: 0,
            header_len: header.len(),
            buf: Vec::new(),
        })
    }

    /// Append whole rows (`values.len()` a multiple of the columns).
    pub fn push(&mut self, values: &[f32]) -> io::Result<()> {
        if !values.len().is_multiple_of(self.cols) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("npy: {} values are not whole rows of {}", values.len(), self.cols),
            ));
        }
        self.buf.clear();
        self.buf.extend(values.iter().flat_map(|v| v.to_le_bytes()));
        self.w.write_all(&self.buf)?;
        self.rows += values.len() / self.cols;
        Ok(())
    }

    /// Rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Write the real shape into the header; the writer, positioned at the end.
    pub fn finish(mut self) -> io::Result<W> {
        let header = npy_header_at_least(self.rows, self.cols, self.header_len);
        debug_assert_eq!(header.len(), self.header_len);
        self.w.seek(SeekFrom::Start(0))?;
        self.w.write_all(&header)?;
        self.w.seek(SeekFrom::End(0))?;
        Ok(self.w)
    }
}

/// Write a `(rows, cols)` f32 array to `path`, atomically.
pub fn write_npy_f32_file(path: impl AsRef<Path>, rows: usize, cols: usize, data: &[f32]) -> Result<()> {
    super::atomic::write_atomically(path, |f| write_npy_f32(f, rows, cols, data))
}

fn dict_value<'a>(dict: &'a str, key: &str) -> Option<&'a str> {
    let k = format!("'{key}':");
    let start = dict.find(&k)? + k.len();
    let rest = dict[start..].trim_start();
    let end = if rest.starts_with('(') {
        rest.find(')')? + 1
    } else {
        rest.find([',', '}'])?
    };
    Some(rest[..end].trim())
}

/// Read a 2-D little-endian f32 C-order array from `r`; `name` is used in error messages.
pub fn read_npy_f32<R: Read>(mut r: R, name: &Path) -> Result<NpyF32> {
    let bad = |m: String| Error::format(name, m);
    let mut pre = [0u8; 8];
    r.read_exact(&mut pre)
        .map_err(|_| bad("not an .npy file (too short)".into()))?;
    if &pre[..6] != MAGIC {
        return Err(bad("not an .npy file (bad magic)".into()));
    }
    let header_len = match pre[6] {
        1 => {
            let mut b = [0u8; 2];
            r.read_exact(&mut b).map_err(|e| Error::io(name, e))?;
            u16::from_le_bytes(b) as usize
        }
        2 | 3 => {
            let mut b = [0u8; 4];
            r.read_exact(&mut b).map_err(|e| Error::io(name, e))?;
            u32::from_le_bytes(b) as usize
        }
        v => return Err(bad(format!("unsupported .npy version {v}.{}", pre[7]))),
    };
    let mut header = vec![0u8; header_len];
    r.read_exact(&mut header)
        .map_err(|_| bad("truncated .npy header".into()))?;
    let dict = String::from_utf8_lossy(&header);
    let descr = dict_value(&dict, "descr").ok_or_else(|| bad("header has no 'descr'".into()))?;
    if descr != "'<f4'" {
        return Err(bad(format!("dtype {descr} is not little-endian float32 '<f4'")));
    }
    let fortran =
        dict_value(&dict, "fortran_order").ok_or_else(|| bad("header has no 'fortran_order'".into()))?;
    if fortran != "False" {
        return Err(bad("Fortran-order arrays are not supported".into()));
    }
    let shape = dict_value(&dict, "shape").ok_or_else(|| bad("header has no 'shape'".into()))?;
    let dims: Vec<usize> = shape
        .trim_start_matches('(')
        .trim_end_matches(')')
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<usize>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| bad(format!("bad shape {shape}")))?;
    let [rows, cols] = dims[..] else {
        return Err(bad(format!("shape {shape} is not 2-D")));
    };
    let n = rows
        .checked_mul(cols)
        .ok_or_else(|| bad(format!("shape {shape} too large")))?;
    let mut bytes = Vec::new();
    r.read_to_end(&mut bytes).map_err(|e| Error::io(name, e))?;
    if bytes.len() != n * 4 {
        return Err(bad(format!(
            "shape ({rows}, {cols}) needs {} data bytes, file has {}",
            n * 4,
            bytes.len()
        )));
    }
    let data = bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(NpyF32 { rows, cols, data })
}

/// Read a 2-D f32 `.npy` file.
pub fn read_npy_f32_file(path: impl AsRef<Path>) -> Result<NpyF32> {
    let path = path.as_ref();
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    read_npy_f32(io::BufReader::new(f), path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_written_one_at_a_time_read_back_as_the_whole_array() {
        let data: Vec<f32> = (0..7 * 5).map(|i| i as f32 * 0.5 - 3.0).collect();
        for pieces in [&[7][..], &[1, 2, 4], &[0, 3, 0, 4]] {
            let mut w = NpyRowWriter::new(io::Cursor::new(Vec::new()), 5).unwrap();
            let mut at = 0;
            for &n in pieces {
                w.push(&data[at * 5..(at + n) * 5]).unwrap();
                at += n;
            }
            assert_eq!(w.rows(), 7);
            let bytes = w.finish().unwrap().into_inner();
            assert_eq!(bytes.len() % 4, 0);
            let a = read_npy_f32(&bytes[..], Path::new("rows.npy")).unwrap();
            assert_eq!((a.rows, a.cols), (7, 5));
            assert_eq!(a.data, data);
        }
        // No rows: a (0, 5) array.
        let w = NpyRowWriter::new(io::Cursor::new(Vec::new()), 5).unwrap();
        let a = read_npy_f32(&w.finish().unwrap().into_inner()[..], Path::new("e.npy")).unwrap();
        assert_eq!((a.rows, a.cols, a.data.len()), (0, 5, 0));
        let mut w = NpyRowWriter::new(io::Cursor::new(Vec::new()), 5).unwrap();
        assert!(w.push(&data[..4]).is_err());
    }

    #[test]
    fn exact_header_bytes() {
        let h = npy_header(3, 4);
        let mut expected = Vec::new();
        expected.extend_from_slice(b"\x93NUMPY\x01\x00");
        expected.extend_from_slice(&118u16.to_le_bytes());
        let dict = b"{'descr': '<f4', 'fortran_order': False, 'shape': (3, 4), }";
        expected.extend_from_slice(dict);
        expected.resize(127, b' ');
        expected.push(b'\n');
        assert_eq!(h, expected);
        assert_eq!(h.len(), 128);
        for (r, c) in [(0, 0), (1, 1), (123456, 2522), (usize::MAX / 8, 7)] {
            let h = npy_header(r, c);
            assert_eq!(h.len() % 64, 0);
            assert_eq!(*h.last().unwrap(), b'\n');
            assert_eq!(u16::from_le_bytes([h[8], h[9]]) as usize, h.len() - 10);
        }
    }

    #[test]
    fn round_trip() {
        let data: Vec<f32> = (0..12).map(|i| i as f32 * 0.5 - 2.0).collect();
        let mut buf = Vec::new();
        write_npy_f32(&mut buf, 3, 4, &data).unwrap();
        assert_eq!(buf.len(), 128 + 48);
        assert_eq!(&buf[128..132], &(-2.0f32).to_le_bytes());
        let a = read_npy_f32(&buf[..], Path::new("mem")).unwrap();
        assert_eq!(
            a,
            NpyF32 {
                rows: 3,
                cols: 4,
                data
            }
        );
    }

    #[test]
    fn errors() {
        assert!(write_npy_f32(Vec::new(), 2, 2, &[1.0; 3]).is_err());
        let e = read_npy_f32(&b"hello world"[..], Path::new("x.npy")).unwrap_err();
        assert!(e.to_string().contains("x.npy"), "{e}");
        let mut buf = Vec::new();
        write_npy_f32(&mut buf, 2, 2, &[1.0; 4]).unwrap();
        buf.pop();
        let e = read_npy_f32(&buf[..], Path::new("t.npy")).unwrap_err();
        assert!(e.to_string().contains("data bytes"), "{e}");
    }

    #[test]
    fn file_round_trip() {
        let d = std::env::temp_dir().join(format!("soundloc-npy-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("s.npy");
        write_npy_f32_file(&p, 2, 3, &[1.0, 2.0, 3.0, 4.0, 5.0, f32::NAN]).unwrap();
        let a = read_npy_f32_file(&p).unwrap();
        assert_eq!((a.rows, a.cols), (2, 3));
        assert!(a.data[5].is_nan());
        std::fs::remove_dir_all(&d).unwrap();
    }
}
