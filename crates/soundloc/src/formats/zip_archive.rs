//! Reading zip entries safely and in parallel.
//!
//! [`ZipReader`] opens an archive once (one read of the central directory) and hands out
//! cheap clones — every clone reads the same open file with positioned reads (`pread`), so
//! rayon workers inflate different entries at the same time without reopening anything.
//! Every entry is read through one budgeted path ([`ZipReader::read`]): no entry over
//! [`MAX_ENTRY_BYTES`], none over 1 MiB that inflates more than [`MAX_RATIO`] times its
//! compressed size (a zip bomb), never more bytes than its header declares, and callers
//! check a whole selection against [`MAX_TOTAL_BYTES`] before reading it
//! ([`ZipReader::check_total`]). Inflation uses flate2's zlib-rs backend.

use crate::formats::hark_zip::entry_path;
use crate::{Error, Result};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Largest entry we agree to inflate (bytes); protects against corrupt size fields.
pub const MAX_ENTRY_BYTES: u64 = 1 << 30;
/// Largest total we agree to inflate from one archive (bytes): a 60-mic, 2522-direction
/// TF set of 257 bins is 0.6 GiB.
pub const MAX_TOTAL_BYTES: u64 = 8 << 30;
/// Largest inflated / compressed ratio accepted for an entry over 1 MiB: HARK's matrices
/// compress a few times at most; a zip bomb a thousandfold.
pub const MAX_RATIO: u64 = 200;

/// A file read with positioned reads: clones share the open file, each with its own
/// position.
#[derive(Clone)]
struct SharedFile {
    file: Arc<File>,
    pos: u64,
    len: u64,
}

impl Read for SharedFile {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.file.read_at(buf, self.pos)?;
        self.pos += n as u64;
        Ok(n)
    }
}

impl Seek for SharedFile {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        let p = match to {
            SeekFrom::Start(p) => Some(p),
            SeekFrom::End(d) => self.len.checked_add_signed(d),
            SeekFrom::Current(d) => self.pos.checked_add_signed(d),
        };
        self.pos =
            p.ok_or_else(|| std::io::Error::new(std::io::ErrorKind::InvalidInput, "seek before the start"))?;
        Ok(self.pos)
    }
}

/// An open zip archive; clone it per thread (see the [module docs](self)).
#[derive(Clone)]
pub struct ZipReader {
    archive: zip::ZipArchive<SharedFile>,
    path: PathBuf,
}

impl ZipReader {
    /// Open `path` and read its central directory.
    pub fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        let f = SharedFile {
            file: Arc::new(file),
            pos: 0,
            len,
        };
        let archive = zip::ZipArchive::new(f).map_err(|e| {
            Error::format(
                path,
                format!("not a readable zip archive (truncated or corrupt?): {e}"),
            )
        })?;
        Ok(ZipReader {
            archive,
            path: path.to_path_buf(),
        })
    }

    /// The archive's file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Names of the file entries (directories left out), in archive order.
    pub fn names(&self) -> Vec<String> {
        self.archive
            .file_names()
            .filter(|n| !n.ends_with('/'))
            .map(str::to_string)
            .collect()
    }

    /// Whether the archive has an entry `name`.
    pub fn contains(&self, name: &str) -> bool {
        self.archive.index_for_name(name).is_some()
    }

    /// The declared inflated size of entry `name`.
    pub fn size(&mut self, name: &str) -> Result<u64> {
        let f = self
            .archive
            .by_name(name)
            .map_err(|e| Error::format(entry_path(&self.path, name), format!("cannot be read: {e}")))?;
        Ok(f.size())
    }

    /// The CRC-32 and declared inflated size of entry `name` (from the central directory;
    /// nothing is inflated).
    pub fn crc_and_size(&mut self, name: &str) -> Result<(u32, u64)> {
        let f = self
            .archive
            .by_name(name)
            .map_err(|e| Error::format(entry_path(&self.path, name), format!("cannot be read: {e}")))?;
        Ok((f.crc32(), f.size()))
    }

    /// Fail when `names` together would inflate to more than [`MAX_TOTAL_BYTES`].
    pub fn check_total<'a>(&mut self, names: impl IntoIterator<Item = &'a str>) -> Result<()> {
        let mut total = 0u64;
        for n in names {
            total = total.saturating_add(self.size(n)?);
            if total > MAX_TOTAL_BYTES {
                return Err(Error::format(
                    &self.path,
                    format!("the archive inflates to more than {MAX_TOTAL_BYTES} bytes: refused"),
                ));
            }
        }
        Ok(())
    }

    /// Inflate entry `name` into `buf` (replacing its content), within the per-entry
    /// limits of the [module docs](self).
    pub fn read_into(&mut self, name: &str, buf: &mut Vec<u8>) -> Result<()> {
        let path = &self.path;
        let f = self
            .archive
            .by_name(name)
            .map_err(|e| Error::format(entry_path(path, name), format!("cannot be read (corrupt?): {e}")))?;
        let (size, packed) = (f.size(), f.compressed_size());
        let bad = |m: String| Err(Error::format(entry_path(path, name), m));
        if size > MAX_ENTRY_BYTES {
            return bad(format!(
                "entry claims {size} bytes, more than the {MAX_ENTRY_BYTES} allowed"
            ));
        }
        if size > 1 << 20 && size / packed.max(1) > MAX_RATIO {
            return bad(format!(
                "entry inflates {packed} bytes into {size} ({}×): refused as a zip bomb",
                size / packed.max(1)
            ));
        }
        buf.clear();
        buf.reserve(size.min(1 << 24) as usize);
        f.take(size + 1)
            .read_to_end(buf)
            .map_err(|e| Error::format(entry_path(path, name), format!("corrupt zip entry: {e}")))?;
        if buf.len() as u64 != size {
            return bad(format!(
                "entry inflates to {} bytes, its header says {size}",
                buf.len()
            ));
        }
        Ok(())
    }

    /// Inflate entry `name`.
    pub fn read(&mut self, name: &str) -> Result<Vec<u8>> {
        let mut b = Vec::new();
        self.read_into(name, &mut b)?;
        Ok(b)
    }
}
