//! Atomic file replacement: nothing half-written is ever left at the target path.
//!
//! [`AtomicFile::create`] opens a new, uniquely named hidden temporary file in the target's
//! own directory (so the final rename never crosses file systems). Writes go to it;
//! [`AtomicFile::commit`] flushes, syncs and renames it over the target in one step. An
//! `AtomicFile` dropped without `commit` (an error, a panic, an early return) deletes its
//! temporary file, and the target keeps its previous content, or stays absent.
//!
//! Every writer in [`crate::output`] and [`crate::audio::Audio::write_wav`] goes through it.
//!
//! Targets that are not regular files are never replaced: a symbolic link is followed (the
//! file it points to is replaced, the link stays); a device, FIFO or socket (`/dev/null`,
//! `/dev/stdout`, a named pipe another program reads) is written directly, since renaming
//! over it would destroy it (and leave a FIFO's reader waiting forever). A write error
//! there (a full disk, `/dev/full`) is reported by `commit`.

use crate::{Error, Result};
use std::fs::{File, OpenOptions};
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// The temporary files being written now (for [`remove_temporary_files`]).
static LIVE: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn live() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Delete every temporary file an [`AtomicFile`] of this process is writing now, leaving
/// the targets as they were. For a signal handler that is about to end the process
/// (SIGTERM, Ctrl-C) without unwinding, which would otherwise leave them behind. The
/// registry stays locked afterwards, so no other thread creates or renames one before the
/// process ends: call it only on the way out.
pub fn remove_temporary_files() {
    let mut l = live();
    for t in l.drain(..) {
        let _ = std::fs::remove_file(t);
    }
    std::mem::forget(l);
}

/// Temporary files in `dir` that [`AtomicFile`] made for a process that no longer runs
/// (killed where no handler could remove them, e.g. by SIGKILL): `.<name>.<pid>-<n>.tmp…`
/// whose process is gone. Found on Linux (through `/proc`); elsewhere none are reported.
/// They are listed, not deleted: a writer in another PID namespace (a container sharing
/// the folder) looks dead from here.
pub fn stale_temporaries(dir: &Path) -> Vec<PathBuf> {
    if !cfg!(target_os = "linux") {
        return Vec::new();
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut stale: Vec<PathBuf> = entries
        .flatten()
        .filter(|e| {
            let name = e.file_name();
            let Some(name) = name.to_str() else { return false };
            temporary_pid(name).is_some_and(|pid| !Path::new("/proc").join(pid).exists())
        })
        .map(|e| e.path())
        .collect();
    stale.sort();
    stale
}

/// The name of [`AtomicFile`]'s temporary file for the target file name `name`:
/// `.<name>.<pid>-<n>.tmp<suffix>`. [`temporary_pid`] reads it back.
fn temporary_name(name: &std::ffi::OsStr, pid: u32, n: u64, suffix: &str) -> std::ffi::OsString {
    let mut temp_name = std::ffi::OsString::from(".");
    temp_name.push(name);
    temp_name.push(format!(".{pid}-{n}.tmp{suffix}"));
    temp_name
}

/// The writer's process id (decimal digits) in a name made by [`temporary_name`], or
/// `None` for any other name.
fn temporary_pid(file_name: &str) -> Option<&str> {
    let (head, _) = file_name.strip_prefix('.')?.rsplit_once(".tmp")?;
    let (_, id) = head.rsplit_once('.')?;
    let (pid, n) = id.split_once('-')?;
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    (digits(pid) && digits(n)).then_some(pid)
}

/// A file being written that appears at its target path only on [`commit`](Self::commit).
///
/// Implements [`Write`] and [`Seek`] (buffered), so it can be handed to any writer,
/// including `hound::WavWriter`.
#[derive(Debug)]
pub struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    file: Option<BufWriter<File>>,
    /// The replaced file's permission bits, given to the new one at `commit`.
    keep_mode: Option<std::fs::Permissions>,
}

impl AtomicFile {
    /// Start writing `path`: creates `.<name>.<pid>-<n>.tmp` next to it.
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        Self::create_with_suffix(path, "")
    }

    /// Like [`create`](Self::create), with `suffix` appended to the temporary file's name
    /// (e.g. `".png"` for a library that picks the format from the extension).
    pub fn create_with_suffix(path: impl AsRef<Path>, suffix: &str) -> Result<Self> {
        let path = path.as_ref();
        // A file replaced keeps its permission bits (a private 0600 file stays private, a
        // shared 0664 one group-writable; not setuid, setgid or sticky), given at commit so
        // that writers by path can open the temporary file; a new one gets the umask's, as
        // with any tool.
        let mut keep_mode = None;
        // The kernel follows links here, magic ones too (/dev/stdout, /dev/fd/N → a pipe,
        // whose link text `pipe:[N]` names no file).
        if let Ok(meta) = std::fs::metadata(path) {
            if meta.is_file() {
                keep_mode = Some(permission_bits(meta.permissions()));
            }
            // A rename would replace a file its owner made read-only (even as root): refuse,
            // as `cp` does for other users.
            if meta.is_file() && meta.permissions().readonly() {
                return Err(Error::io(
                    path,
                    io::Error::new(
                        io::ErrorKind::PermissionDenied,
                        "is read-only: not replaced (make it writable or remove it first)",
                    ),
                ));
            }
            if !meta.is_file() {
                if meta.is_dir() {
                    return Err(Error::io(
                        path,
                        io::Error::new(io::ErrorKind::InvalidInput, "is a directory"),
                    ));
                }
                if !suffix.is_empty() {
                    return Err(Error::io(
                        path,
                        io::Error::new(
                            io::ErrorKind::InvalidInput,
                            "not a regular file (this output is written by name)",
                        ),
                    ));
                }
                // A device, FIFO or socket: write it directly.
                let f = OpenOptions::new()
                    .write(true)
                    .open(path)
                    .map_err(|e| Error::io(path, e))?;
                return Ok(AtomicFile {
                    target: path.to_path_buf(),
                    temp: PathBuf::new(),
                    file: Some(BufWriter::new(f)),
                    keep_mode: None,
                });
            }
        }
        let target = resolve_links(path);
        let name = target.file_name().ok_or_else(|| {
            Error::io(
                &target,
                io::Error::new(io::ErrorKind::InvalidInput, "not a file path"),
            )
        })?;
        let dir = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let pid = std::process::id();
        // A few attempts in case a stale temporary file with the same name exists.
        let mut last_err = None;
        for _ in 0..16 {
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let temp = dir.join(temporary_name(name, pid, n, suffix));
            // Created and registered under the lock: a signal between the two cannot
            // leave it behind.
            let mut registry = live();
            match OpenOptions::new().write(true).create_new(true).open(&temp) {
                Ok(f) => {
                    registry.push(temp.clone());
                    return Ok(AtomicFile {
                        target,
                        temp,
                        file: Some(BufWriter::new(f)),
                        keep_mode,
                    });
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last_err = Some(e),
                Err(e) if e.kind() == io::ErrorKind::NotFound && !dir.is_dir() => {
                    return Err(Error::io(
                        &target,
                        io::Error::new(
                            io::ErrorKind::NotFound,
                            format!("the directory {} does not exist", dir.display()),
                        ),
                    ))
                }
                Err(e) => return Err(Error::io(&target, e)),
            }
        }
        Err(Error::io(
            &target,
            last_err.unwrap_or_else(|| io::Error::other("cannot create a temporary file")),
        ))
    }

    /// The path the file will have after `commit`.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Whether the target is a device, FIFO or socket, written in place: such a target
    /// cannot seek, so a writer that needs to seek builds its bytes first.
    pub fn is_special(&self) -> bool {
        self.temp.as_os_str().is_empty()
    }

    /// The temporary file's path (for libraries that insist on writing by path; whatever
    /// they write there is what `commit` moves into place).
    pub fn temp_path(&self) -> &Path {
        &self.temp
    }

    /// Flush, sync to disk and rename over the target (a special file: flush only).
    pub fn commit(self) -> Result<()> {
        self.finish(true)
    }

    /// As [`commit`](Self::commit) without the sync to disk: for caches whose entries
    /// carry their own checksum (a torn entry after a crash fails it and is rebuilt).
    pub fn commit_unsynced(self) -> Result<()> {
        self.finish(false)
    }

    fn finish(mut self, sync: bool) -> Result<()> {
        let direct = self.temp.as_os_str().is_empty();
        if let Some(w) = self.file.take() {
            let f = w
                .into_inner()
                .map_err(|e| Error::io(&self.target, e.into_error()))?;
            if direct {
                return Ok(());
            }
            if sync {
                f.sync_all().map_err(|e| Error::io(&self.target, e))?;
            }
        }
        if let Some(mode) = self.keep_mode.take() {
            // Best effort: a file system that refuses chmod (some network and FAT
            // mounts) still gets its output, with the default mode.
            let _ = std::fs::set_permissions(&self.temp, mode);
        }
        // Under the registry's lock, as a signal's clean-up takes it.
        let mut registry = live();
        std::fs::rename(&self.temp, &self.target).map_err(|e| Error::io(&self.target, e))?;
        // Renamed: nothing left to clean up.
        registry.retain(|t| *t != self.temp);
        drop(registry);
        self.temp = PathBuf::new();
        Ok(())
    }

    fn inner(&mut self) -> io::Result<&mut BufWriter<File>> {
        self.file
            .as_mut()
            .ok_or_else(|| io::Error::other("atomic file already closed"))
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.inner()?.write(buf)
    }
    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.inner()?.write_all(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner()?.flush()
    }
}

impl Seek for AtomicFile {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.inner()?.seek(pos)
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        drop(self.file.take());
        if !self.temp.as_os_str().is_empty() {
            let mut registry = live();
            let _ = std::fs::remove_file(&self.temp);
            registry.retain(|t| *t != self.temp);
        }
    }
}

/// `p` without the setuid, setgid and sticky bits (as `cp` without `-p` leaves them).
fn permission_bits(p: std::fs::Permissions) -> std::fs::Permissions {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::Permissions::from_mode(p.mode() & 0o777)
    }
    #[cfg(not(unix))]
    {
        p
    }
}

/// The file a path names after following symbolic links (a dangling link: the path it
/// points to, relative to the link's directory).
fn resolve_links(path: &Path) -> PathBuf {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => match std::fs::read_link(&p) {
                Ok(t) if t.is_absolute() => p = t,
                Ok(t) => p = p.parent().map_or(t.clone(), |d| d.join(&t)),
                Err(_) => break,
            },
            _ => break,
        }
    }
    p
}

/// What a path names, for comparing outputs with inputs and with each other: links
/// resolved and the directory made absolute. `None` for what is not a regular file
/// (a device or FIFO is written in place, replacing nothing).
fn identity(path: &Path) -> Option<PathBuf> {
    // The kernel follows links here, magic ones too (/dev/stdout → a pipe).
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file()) {
        return None;
    }
    let t = resolve_links(path);
    match std::fs::metadata(&t) {
        Ok(m) if !m.is_file() => return None,
        Ok(_) => return std::fs::canonicalize(&t).ok(),
        Err(_) => {}
    }
    let name = t.file_name()?;
    let dir = match t.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    Some(
        std::fs::canonicalize(dir)
            .unwrap_or_else(|_| dir.to_path_buf())
            .join(name),
    )
}

/// Checks, before any work, that `path` can be an output: not a folder, and in a folder
/// that exists. `what` names the option for the message.
pub fn check_output_path(path: &Path, what: &str) -> Result<()> {
    let bad =
        |kind: io::ErrorKind, msg: String| Error::io(path, io::Error::new(kind, format!("{what}: {msg}")));
    if path.as_os_str().is_empty() {
        return Err(Error::Config(format!("{what}: the file name is empty")));
    }
    // "-" is stdin for inputs; as an output it would be a file named "-".
    if path.as_os_str() == "-" {
        return Err(Error::Config(format!(
            "{what} -: \"-\" names no file here (stdout is for localize's results: -o - or no -o); name a file"
        )));
    }
    if path.is_dir() {
        return Err(bad(
            io::ErrorKind::InvalidInput,
            "is a directory; name a file".into(),
        ));
    }
    if let Some(d) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        if d.exists() && !d.is_dir() {
            return Err(bad(
                io::ErrorKind::InvalidInput,
                format!("{} is a file, not a folder", d.display()),
            ));
        }
        if !d.is_dir() {
            return Err(bad(
                io::ErrorKind::NotFound,
                format!("the directory {} does not exist", d.display()),
            ));
        }
    }
    Ok(())
}

/// Refuses, before any work, outputs that would replace one of the run's inputs or each
/// other. Both lists hold `(path, what)` pairs, `what` naming the option or role for the
/// message. Writing results over the recording or the transfer functions they come from
/// would destroy them; two outputs on one path would keep only the last.
pub fn check_outputs(outputs: &[(&Path, &str)], inputs: &[(&Path, &str)]) -> Result<()> {
    use std::collections::HashMap;
    let ins: HashMap<PathBuf, (&Path, &str)> = inputs
        .iter()
        .filter_map(|&(p, w)| identity(p).map(|k| (k, (p, w))))
        .collect();
    let mut seen: HashMap<PathBuf, (&Path, &str)> = HashMap::new();
    for &(p, what) in outputs {
        let Some(k) = identity(p) else { continue };
        if let Some((ip, iw)) = ins.get(&k) {
            return Err(Error::Config(format!(
                "{}: {what} would overwrite the input {} ({iw}): name another file",
                p.display(),
                ip.display()
            )));
        }
        if let Some((op, ow)) = seen.get(&k) {
            return Err(Error::Config(format!(
                "{}: {what} and {ow} ({}) name the same file",
                p.display(),
                op.display()
            )));
        }
        seen.insert(k, (p, what));
    }
    Ok(())
}

/// Write `path` atomically with `f`, which receives the open temporary file.
pub fn write_atomically<F>(path: impl AsRef<Path>, f: F) -> Result<()>
where
    F: FnOnce(&mut AtomicFile) -> io::Result<()>,
{
    let mut file = AtomicFile::create(path)?;
    if let Err(e) = f(&mut file) {
        return Err(Error::io(file.target().to_path_buf(), e));
    }
    file.commit()
}

#[cfg(test)]
mod tests;
