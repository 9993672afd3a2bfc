//! Unit tests of the atomic output files.
use super::*;

pub(crate) fn temp_dir(tag: &str) -> PathBuf {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let d = std::env::temp_dir().join(format!("soundloc-atomic-{tag}-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn temporary_names_are_read_back_and_others_are_not() {
    let name = temporary_name(std::ffi::OsStr::new("rec.take1.jsonl"), 4321, 7, ".png");
    assert_eq!(name, ".rec.take1.jsonl.4321-7.tmp.png");
    assert_eq!(temporary_pid(name.to_str().unwrap()), Some("4321"));
    let plain = temporary_name(std::ffi::OsStr::new("a"), 1, 0, "");
    assert_eq!(temporary_pid(plain.to_str().unwrap()), Some("1"));
    for other in [
        "rec.jsonl",
        "rec.4321-7.tmp",
        ".rec.4321-.tmp",
        ".rec.x1-7.tmp",
        ".rec.4321-7",
        ".rec.43a1-7.tmp",
    ] {
        assert_eq!(temporary_pid(other), None, "{other}");
    }
    // `stale_temporaries` on such names: cli_batch.rs (leftovers of killed runs).
}

#[test]
fn outputs_may_not_replace_inputs_or_each_other() {
    let d = temp_dir("check");
    let input = d.join("in.wav");
    std::fs::write(&input, b"RIFF").unwrap();
    let link = d.join("link.wav");
    #[cfg(unix)]
    std::os::unix::fs::symlink(&input, &link).unwrap();
    let ins = [(input.as_path(), "the input")];
    // The input itself, by another spelling, and through a link.
    let dotted = d.join(".").join("in.wav");
    for out in [&input, &dotted] {
        let e = check_outputs(&[(out, "--output")], &ins).unwrap_err().to_string();
        assert!(
            e.contains("would overwrite the input") && e.contains("--output"),
            "{e}"
        );
    }
    #[cfg(unix)]
    assert!(check_outputs(&[(&link, "--log-xml")], &ins).is_err());
    // Two outputs on one (not yet existing) path.
    let out = d.join("out.jsonl");
    let e = check_outputs(&[(&out, "--output"), (&out, "--log-xml")], &ins)
        .unwrap_err()
        .to_string();
    assert!(e.contains("name the same file"), "{e}");
    // Distinct files pass; devices may repeat (nothing is replaced there).
    let other = d.join("out.xml");
    check_outputs(&[(&out, "--output"), (&other, "--log-xml")], &ins).unwrap();
    #[cfg(unix)]
    check_outputs(
        &[
            (Path::new("/dev/null"), "--output"),
            (Path::new("/dev/null"), "--log-xml"),
        ],
        &[(Path::new("/dev/null"), "the input")],
    )
    .unwrap();
    assert_eq!(std::fs::read(&input).unwrap(), b"RIFF");
}

#[test]
fn commit_places_file_and_leaves_no_temp() {
    let d = temp_dir("commit");
    let target = d.join("out.txt");
    let mut f = AtomicFile::create(&target).unwrap();
    f.write_all(b"hello").unwrap();
    assert!(!target.exists(), "target must not appear before commit");
    f.commit().unwrap();
    assert_eq!(std::fs::read(&target).unwrap(), b"hello");
    assert_eq!(entries(&d), vec!["out.txt".to_string()]);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn drop_without_commit_keeps_old_content() {
    let d = temp_dir("drop");
    let target = d.join("out.txt");
    std::fs::write(&target, b"old").unwrap();
    {
        let mut f = AtomicFile::create(&target).unwrap();
        f.write_all(b"new but abandoned").unwrap();
    }
    assert_eq!(std::fs::read(&target).unwrap(), b"old");
    assert_eq!(entries(&d), vec!["out.txt".to_string()]);
    // A failing closure leaves nothing either.
    let r = write_atomically(d.join("x.bin"), |w| {
        w.write_all(b"partial")?;
        Err(io::Error::other("boom"))
    });
    assert!(r.is_err());
    assert_eq!(entries(&d), vec!["out.txt".to_string()]);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn replaces_existing_and_suffix_is_kept() {
    let d = temp_dir("suffix");
    let target = d.join("plot.dat");
    std::fs::write(&target, b"old").unwrap();
    let f = AtomicFile::create_with_suffix(&target, ".png").unwrap();
    assert!(f.temp_path().to_string_lossy().ends_with(".png"));
    std::fs::write(f.temp_path(), b"by path").unwrap();
    f.commit().unwrap();
    assert_eq!(std::fs::read(&target).unwrap(), b"by path");
    std::fs::remove_dir_all(&d).unwrap();
}

/// A replaced file keeps its mode (0600 stays private, 0664 group-writable), written as a
/// stream or by path; a new file gets the mode any new file gets there. Until 2026-12-08
/// every replaced output became 0644 (found by a user sweep).
#[cfg(unix)]
#[test]
fn a_replaced_file_keeps_its_mode() {
    use std::os::unix::fs::PermissionsExt;
    let d = temp_dir("mode");
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    for m in [0o600, 0o664, 0o640] {
        let target = d.join(format!("out{m:o}.jsonl"));
        std::fs::write(&target, b"old").unwrap();
        std::fs::set_permissions(&target, std::fs::Permissions::from_mode(m)).unwrap();
        write_atomically(&target, |f| f.write_all(b"new")).unwrap();
        assert_eq!(
            (std::fs::read(&target).unwrap(), mode(&target)),
            (b"new".to_vec(), m)
        );
        let f = AtomicFile::create_with_suffix(&target, ".png").unwrap();
        std::fs::write(f.temp_path(), b"by path").unwrap();
        f.commit().unwrap();
        assert_eq!(mode(&target), m);
    }
    // Not the setuid/setgid bits (cp without -p drops them too).
    let target = d.join("suid.jsonl");
    std::fs::write(&target, b"old").unwrap();
    std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o6750)).unwrap();
    write_atomically(&target, |f| f.write_all(b"new")).unwrap();
    assert_eq!(
        std::fs::metadata(&target).unwrap().permissions().mode() & 0o7777,
        0o750
    );
    let fresh = d.join("fresh.jsonl");
    write_atomically(&fresh, |f| f.write_all(b"x")).unwrap();
    let plain = d.join("plain");
    std::fs::File::create(&plain).unwrap();
    assert_eq!(mode(&fresh), mode(&plain));
    std::fs::remove_dir_all(&d).unwrap();
}

/// `-o /dev/stdout | cat`, `-o >(wc -l)`: a magic link to an anonymous pipe, whose
/// link text (`pipe:[N]`) names no file.
#[cfg(unix)]
#[test]
fn an_anonymous_pipe_through_proc_fd_is_written() {
    use std::io::Read;
    use std::os::fd::AsRawFd;
    let (mut reader, writer) = std::io::pipe().unwrap();
    let path = format!("/proc/self/fd/{}", writer.as_raw_fd());
    if !Path::new(&path).exists() {
        println!("SKIPPED an_anonymous_pipe_through_proc_fd_is_written: no /proc/self/fd");
        return;
    }
    let mut f = AtomicFile::create(&path).unwrap();
    f.write_all(b"through the pipe").unwrap();
    f.commit().unwrap();
    drop(writer);
    let mut got = String::new();
    reader.read_to_string(&mut got).unwrap();
    assert_eq!(got, "through the pipe");
    // Written by name (a PNG through its own temporary file): refused, named.
    let (_r, w) = std::io::pipe().unwrap();
    let path = format!("/proc/self/fd/{}", w.as_raw_fd());
    let e = AtomicFile::create_with_suffix(&path, ".png").unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
}

#[test]
fn special_files_are_written_in_place_and_links_followed() {
    // /dev/null stays a device.
    let mut f = AtomicFile::create("/dev/null").unwrap();
    f.write_all(b"discarded").unwrap();
    f.commit().unwrap();
    assert!(!std::fs::metadata("/dev/null").unwrap().is_file());
    // A full disk is an error at commit.
    if Path::new("/dev/full").exists() {
        let mut f = AtomicFile::create("/dev/full").unwrap();
        let w = f.write_all(&[0u8; 1 << 16]);
        assert!(w.is_err() || f.commit().is_err());
    }
    // A symlink: its target is replaced, the link stays.
    let d = temp_dir("links");
    let real = d.join("real.txt");
    std::fs::write(&real, b"old").unwrap();
    let link = d.join("link.txt");
    std::os::unix::fs::symlink("real.txt", &link).unwrap();
    write_atomically(&link, |w| w.write_all(b"new")).unwrap();
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert_eq!(std::fs::read(&real).unwrap(), b"new");
    // A FIFO: the reader gets the bytes; the FIFO stays a FIFO.
    let fifo = d.join("pipe");
    let ok = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .map(|s| s.success());
    if ok.unwrap_or(false) {
        let p = fifo.clone();
        let reader = std::thread::spawn(move || std::fs::read(p).unwrap());
        write_atomically(&fifo, |w| w.write_all(b"through the pipe")).unwrap();
        assert_eq!(reader.join().unwrap(), b"through the pipe");
        assert!(!std::fs::metadata(&fifo).unwrap().is_file());
    }
    // A directory is an error.
    assert!(AtomicFile::create(&d).is_err());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn missing_directory_is_an_error_naming_the_file() {
    let e = AtomicFile::create("/nonexistent-dir-soundloc/x.txt").unwrap_err();
    assert!(e.to_string().contains("x.txt"), "{e}");
}
