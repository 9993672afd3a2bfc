//! A cache of prepared transfer functions: the used bins of a TF zip, stored compactly
//! (raw little-endian f32) so the next run with the same file and bins reads tens of MB
//! instead of inflating hundreds.
//!
//! - **Key.** Content, not path: a 64-bit FNV-1a hash of the zip's central-directory
//!   records (name, CRC-32, size) of every entry that is read (all but the separation
//!   TFs), the kept bins, N and fs, and the cache format version. A changed TF file changes
//!   its CRCs, so a stale entry is never hit; copying the file elsewhere still hits.
//!   The key is what the zip *declares* (its directory), not a hash of every byte, which
//!   would cost reading the whole file on every run: a copy damaged after its entry was
//!   stored (directory intact, data not) still hits and gives the data its CRCs describe,
//!   checked when the entry was built. `--no-cache` or `tf inspect --verify` reads the
//!   file itself (and names a damaged entry).
//! - **Entry.** `DIR/tf-<key>.bin`: magic `SLTFCACHE1\n`, a u64 header length, a JSON
//!   header (key, shape, grid, microphone positions, CRC-32 of the data), the data
//!   `[direction][mic][bin]` as (re, im) f32 pairs. Nothing is trusted blindly: magic, key,
//!   shape and the data CRC are checked; any mismatch is a miss and the entry is rebuilt.
//! - **Writing** is atomic (a temporary file in the same folder, then a rename), so
//!   concurrent runs never see half an entry; the last writer wins with identical bytes.
//!   A cache folder that cannot be created or written is not an error: the run goes on
//!   uncached and says so.
//! - **Size.** After storing an entry, the folder's entries (`tf-*.bin` and the GPU's
//!   `cuda-*.bin`) are held to [`max_bytes`] (`$SOUNDLOC_CACHE_MAX_MB`, default 2048 MB,
//!   0 = no limit) by deleting the least recently used ones ([`prune`]; a hit refreshes its
//!   entry's modification time). Never the entry just stored, and nothing else in the folder.
//! - **Where.** [`TfCache::Default`]: `$SOUNDLOC_CACHE_DIR`, else `$XDG_CACHE_HOME/soundloc`,
//!   else `$HOME/.cache/soundloc`; [`TfCache::Dir`] names one; [`TfCache::Off`] bypasses it.

use super::{Grid, TransferFunctions};
use crate::formats::zip_archive::ZipReader;
use crate::Result;
use num_complex::Complex;
use std::io::{Read, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Where prepared transfer functions are cached.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TfCache {
    /// The default folder (see the [module docs](self)).
    #[default]
    Default,
    /// No cache: always read the file.
    Off,
    /// This folder.
    Dir(PathBuf),
}

impl TfCache {
    /// The folder, or None when off (or no default can be found).
    pub fn dir(&self) -> Option<PathBuf> {
        match self {
            TfCache::Off => None,
            TfCache::Dir(d) => Some(d.clone()),
            TfCache::Default => {
                let env = |k: &str| std::env::var_os(k).filter(|v| !v.is_empty()).map(PathBuf::from);
                env("SOUNDLOC_CACHE_DIR")
                    .or_else(|| env("XDG_CACHE_HOME").map(|d| d.join("soundloc")))
                    .or_else(|| env("HOME").map(|d| d.join(".cache").join("soundloc")))
            }
        }
    }
}

/// What the cache did for one load.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CacheOutcome {
    /// Read from this entry.
    Hit(PathBuf),
    /// Not there (or stale, or corrupt: the reason): read the file and stored this entry.
    Stored(PathBuf, Option<String>),
    /// Read the file; the entry could not be stored (why).
    NotStored(String),
    /// The cache was off or does not apply (not a zip).
    Bypassed,
}

impl CacheOutcome {
    /// A note for the user, when there is something to say.
    pub fn note(&self) -> Option<String> {
        match self {
            CacheOutcome::Hit(p) => Some(format!("transfer functions from the cache ({})", p.display())),
            CacheOutcome::Stored(p, why) => Some(format!(
                "transfer functions: the used bins cached in {}{}",
                p.display(),
                why.as_ref().map(|w| format!(" ({w})")).unwrap_or_default()
            )),
            CacheOutcome::NotStored(why) => Some(format!("transfer functions not cached: {why}")),
            CacheOutcome::Bypassed => None,
        }
    }
}

const MAGIC: &[u8; 11] = b"SLTFCACHE1\n";
const VERSION: u32 = 1;

#[derive(serde::Serialize, serde::Deserialize)]
struct Header {
    key: String,
    nfft: usize,
    sample_rate_hz: u32,
    grid: Grid,
    mic_positions: Vec<[f64; 3]>,
    num_mics: usize,
    first_bin: usize,
    num_bins: usize,
    data_crc32: u32,
}

/// 64-bit FNV-1a over `bytes`, continuing from `h` (start: [`FNV_START`]).
pub(crate) fn fnv1a(h: &mut u64, bytes: &[u8]) {
    for &b in bytes {
        *h ^= b as u64;
        *h = h.wrapping_mul(0x100_0000_01b3);
    }
}

/// The FNV-1a offset basis.
pub(crate) const FNV_START: u64 = 0xcbf2_9ce4_8422_2325;

/// Write `parts` to `file` in `dir` (created if need be) atomically
/// ([`AtomicFile`](crate::output::atomic::AtomicFile)), so concurrent readers never see
/// half an entry. No fsync: a torn entry after a crash fails its checksum and is rebuilt.
pub(crate) fn write_atomic(dir: &Path, file: &Path, parts: &[&[u8]]) -> std::io::Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(std::io::Error::other(
            "the cache directory is a file, not a folder",
        ));
    }
    std::fs::create_dir_all(dir)?;
    let io = |e: crate::Error| std::io::Error::other(e.to_string());
    let mut f = crate::output::atomic::AtomicFile::create(file).map_err(io)?;
    for p in parts {
        f.write_all(p)?;
    }
    f.commit_unsynced().map_err(io)
}

/// The content key of TF zip `path` read with `want` (N, fs, bins).
pub fn key(path: &Path, want: &Option<(usize, u32, Range<usize>)>) -> Result<String> {
    let mut zr = ZipReader::open(path)?;
    let mut h = FNV_START;
    fnv1a(
        &mut h,
        format!("soundloc tf cache v{VERSION} {want:?}").as_bytes(),
    );
    let mut names = zr.names();
    names.retain(|n| !n.contains("/separation/"));
    names.sort();
    for n in names {
        let (crc, size) = zr.crc_and_size(&n)?;
        fnv1a(&mut h, n.as_bytes());
        fnv1a(&mut h, &crc.to_le_bytes());
        fnv1a(&mut h, &size.to_le_bytes());
    }
    Ok(format!("{h:016x}"))
}

/// Read entry `file` if it is a valid entry for `key`.
fn read_entry(file: &Path, key: &str) -> std::result::Result<TransferFunctions, String> {
    let mut f = std::fs::File::open(file).map_err(|e| e.to_string())?;
    let mut magic = [0u8; 11];
    f.read_exact(&mut magic).map_err(|_| "truncated".to_string())?;
    if &magic != MAGIC {
        return Err("not a cache entry".into());
    }
    let mut len = [0u8; 8];
    f.read_exact(&mut len).map_err(|_| "truncated".to_string())?;
    let len = u64::from_le_bytes(len);
    if len > 1 << 30 {
        return Err("corrupt header length".into());
    }
    let mut head = vec![0u8; len as usize];
    f.read_exact(&mut head).map_err(|_| "truncated".to_string())?;
    let h: Header = serde_json::from_slice(&head).map_err(|e| format!("corrupt header: {e}"))?;
    if h.key != key {
        return Err("key mismatch".into());
    }
    let n = h
        .grid
        .len()
        .checked_mul(h.num_mics)
        .and_then(|v| v.checked_mul(h.num_bins))
        .filter(|&v| v <= 1 << 28)
        .ok_or("corrupt shape")?;
    let mut raw = Vec::with_capacity(n * 8);
    f.take(n as u64 * 8 + 1)
        .read_to_end(&mut raw)
        .map_err(|e| e.to_string())?;
    if raw.len() != n * 8 {
        return Err(format!("{} data bytes, expected {}", raw.len(), n * 8));
    }
    if crc32fast::hash(&raw) != h.data_crc32 {
        return Err("data checksum mismatch".into());
    }
    let data: Vec<Complex<f32>> = raw
        .chunks_exact(8)
        .map(|c| {
            Complex::new(
                f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                f32::from_le_bytes([c[4], c[5], c[6], c[7]]),
            )
        })
        .collect();
    let tf = TransferFunctions {
        nfft: h.nfft,
        sample_rate_hz: h.sample_rate_hz,
        grid: h.grid,
        mic_positions: h.mic_positions,
        num_mics: h.num_mics,
        first_bin: h.first_bin,
        num_bins: h.num_bins,
        data,
    };
    tf.validate().map_err(|e| e.to_string())?;
    Ok(tf)
}

fn write_entry(dir: &Path, file: &Path, key: &str, tf: &TransferFunctions) -> std::io::Result<()> {
    let mut raw = Vec::with_capacity(tf.data.len() * 8);
    for c in &tf.data {
        raw.extend_from_slice(&c.re.to_le_bytes());
        raw.extend_from_slice(&c.im.to_le_bytes());
    }
    let h = Header {
        key: key.to_string(),
        nfft: tf.nfft,
        sample_rate_hz: tf.sample_rate_hz,
        grid: tf.grid.clone(),
        mic_positions: tf.mic_positions.clone(),
        num_mics: tf.num_mics,
        first_bin: tf.first_bin,
        num_bins: tf.num_bins,
        data_crc32: crc32fast::hash(&raw),
    };
    let head = serde_json::to_vec(&h)?;
    write_atomic(
        dir,
        file,
        &[MAGIC, &(head.len() as u64).to_le_bytes(), &head, &raw],
    )
}

/// Load the TFs of zip `path` through the cache: `read` does the real read on a miss.
pub fn load_cached(
    path: &Path,
    want: &Option<(usize, u32, Range<usize>)>,
    cache: &TfCache,
    read: impl FnOnce() -> Result<TransferFunctions>,
) -> Result<(TransferFunctions, CacheOutcome)> {
    let Some(dir) = cache.dir() else {
        return Ok((read()?, CacheOutcome::Bypassed));
    };
    let key = key(path, want)?;
    let file = dir.join(format!("tf-{key}.bin"));
    let why = if file.exists() {
        match read_entry(&file, &key) {
            Ok(tf) => {
                touch(&file);
                return Ok((tf, CacheOutcome::Hit(file)));
            }
            Err(e) => Some(format!("the old entry was unusable: {e}; rebuilt")),
        }
    } else {
        None
    };
    let tf = read()?;
    let outcome = match write_entry(&dir, &file, &key, &tf) {
        Ok(()) => {
            prune(&dir, &file, max_bytes());
            CacheOutcome::Stored(file, why)
        }
        Err(e) => CacheOutcome::NotStored(format!("{}: {e}", dir.display())),
    };
    Ok((tf, outcome))
}

/// The cache's size limit in bytes: `$SOUNDLOC_CACHE_MAX_MB` megabytes (10⁶ bytes; 2048
/// when unset or not a whole number). `None` (no limit) for 0.
pub fn max_bytes() -> Option<u64> {
    let mb = std::env::var("SOUNDLOC_CACHE_MAX_MB")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .unwrap_or(2048);
    (mb > 0).then(|| mb.saturating_mul(1_000_000))
}

/// Mark `file` as just used (its modification time := now), so [`prune`] keeps it longest.
/// A read-only cache simply keeps the old time.
pub(crate) fn touch(file: &Path) {
    if let Ok(f) = std::fs::File::options().append(true).open(file) {
        let _ = f.set_modified(std::time::SystemTime::now());
    }
}

/// Is `name` a cache entry [`prune`] may delete: `tf-<key>.bin` or `cuda-<key>.bin`?
fn is_entry(name: &str) -> bool {
    let key = name
        .strip_suffix(".bin")
        .and_then(|n| n.strip_prefix("tf-").or_else(|| n.strip_prefix("cuda-")));
    key.is_some_and(|k| !k.is_empty() && k.bytes().all(|b| b.is_ascii_hexdigit()))
}

/// Delete the least recently used entries of cache folder `dir` (by modification time,
/// oldest first) until their total size is at most `max` bytes, keeping `keep` (the entry
/// just stored). Only entries ([`is_entry`]) are counted or deleted; an entry that cannot
/// be deleted is skipped. Returns the number deleted. `max` None: nothing is deleted.
pub fn prune(dir: &Path, keep: &Path, max: Option<u64>) -> usize {
    let Some(max) = max else { return 0 };
    let Ok(read) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut entries: Vec<(std::time::SystemTime, u64, PathBuf)> = read
        .flatten()
        .filter(|e| e.file_name().to_str().is_some_and(is_entry))
        .filter_map(|e| {
            let m = e.metadata().ok().filter(|m| m.is_file())?;
            Some((m.modified().ok()?, m.len(), e.path()))
        })
        .collect();
    let mut total: u64 = entries.iter().map(|e| e.1).sum();
    entries.sort();
    let mut removed = 0;
    for (_, len, path) in entries {
        if total <= max {
            break;
        }
        if path == keep {
            continue;
        }
        if std::fs::remove_file(&path).is_ok() {
            total -= len;
            removed += 1;
        }
    }
    removed
}
