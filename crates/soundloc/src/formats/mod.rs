//! File formats robot-audition users already have (HARK's; ODAS's configuration text), read
//! and written.
//! Layouts: `shared/spec/hark-formats.md`.

use crate::{Error, Result};
use std::path::Path;

pub mod hark_mat;
pub mod hark_zip;
pub mod hgtf;
pub mod libconfig;
pub mod noise_cm;
pub mod source_log;
pub mod tf_zip_read;
pub mod xml;
pub mod zip_archive;

/// Largest geometry TOML read (bytes).
pub const MAX_GEOMETRY_BYTES: u64 = 16 << 20;
/// Largest text file of a noise correlation pair read (bytes).
pub const MAX_NOISE_TEXT_BYTES: u64 = 256 << 20;
/// Largest source-location log read (bytes).
pub const MAX_SOURCE_LOG_BYTES: u64 = 1 << 30;
/// Largest HGTF file read (bytes): the TF values allowed plus its header.
pub const MAX_HGTF_BYTES: u64 = (crate::array::MAX_TF_VALUES as u64) * 8 + (1 << 20);

/// The whole of `path` when it holds at most `max` bytes. A larger file — or an endless
/// device such as `/dev/zero` or `/dev/full`, which never reaches an end — is an error
/// naming the file, after reading at most `max + 1` bytes.
pub fn read_bounded(path: &Path, max: u64, what: &str) -> Result<Vec<u8>> {
    use std::io::Read;
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut buf = Vec::new();
    f.take(max + 1)
        .read_to_end(&mut buf)
        .map_err(|e| Error::io(path, e))?;
    if buf.len() as u64 > max {
        return Err(Error::format(
            path,
            format!("more than {} MiB: too large for a {what}", max >> 20),
        ));
    }
    Ok(buf)
}

/// [`read_bounded`] as UTF-8 text.
pub fn read_text_bounded(path: &Path, max: u64, what: &str) -> Result<String> {
    String::from_utf8(read_bounded(path, max, what)?)
        .map_err(|e| Error::format(path, format!("not UTF-8 text: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An endless device is refused after max + 1 bytes instead of read forever.
    #[test]
    fn endless_and_oversized_files_are_refused_by_name() {
        let e = read_bounded(Path::new("/dev/zero"), 1 << 20, "geometry file").unwrap_err();
        assert!(
            e.to_string().contains("/dev/zero") && e.to_string().contains("too large"),
            "{e}"
        );
        let dir = std::env::temp_dir().join(format!("soundloc-bounded-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("g.toml");
        std::fs::write(&p, vec![b'#'; 2048]).unwrap();
        assert_eq!(read_bounded(&p, 2048, "x").unwrap().len(), 2048);
        assert!(read_bounded(&p, 2047, "x").is_err());
        std::fs::write(&p, [0xffu8, 0xfe]).unwrap();
        assert!(read_text_bounded(&p, 10, "x")
            .unwrap_err()
            .to_string()
            .contains("UTF-8"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
