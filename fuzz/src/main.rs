//! AFL harness over soundloc's file readers: `soundloc-afl TARGET`, TARGET a target of
//! `soundloc-fuzz` (wav, flac, tf-zip, hgtf, noise-cm-zip, noise-cm-text, geometry,
//! source-log), or a zip target with `@entries` (tf-zip@entries, noise-cm-zip@entries).
//!
//! Each input AFL gives is written to a file named as the target's reader expects
//! (`input.wav`, `tf_loc.dat`, `K_r` beside its `K_i`, ...) and read with the same
//! function the CLI uses. An error is a refusal, which is fine; a panic aborts the process,
//! which AFL counts as a crash. With `@entries` the input is one entry of the target's seed
//! zip (first byte: which entry; the rest: its content), zipped again with valid CRCs, so
//! that AFL reaches the XML and matrix parsers behind the container instead of the CRC check.
//!
//! The files live in `$SOUNDLOC_AFL_TMP` (else `/dev/shm`, else the system temporary
//! folder), in a folder of this process's own. Everything runs on one thread (one rayon
//! worker, this thread). `soundloc-afl --write-seeds DIR` writes the
//! seed corpora (`DIR/<target>/`).

use std::path::PathBuf;

fn main() {
    // One thread, and no worker threads at all: AFL forks this process after the set-up
    // below, and a fork keeps only the calling thread, so a rayon pool started before it
    // (the seeds are made with rayon) would leave the TF zip reader waiting for workers
    // that do not exist in the child. The calling thread is the pool's only worker.
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .use_current_thread()
        .build_global()
        .expect("the rayon pool");
    let mut args = std::env::args().skip(1);
    let name = args.next().unwrap_or_else(|| {
        eprintln!("usage: soundloc-afl TARGET | soundloc-afl --write-seeds DIR");
        std::process::exit(2)
    });
    if name == "--write-seeds" {
        let dir = PathBuf::from(args.next().unwrap_or_else(|| "seeds".into()));
        let n = soundloc_fuzz::write_seeds(&dir).expect("writing the seeds");
        println!("{n} seed files in {}", dir.display());
        return;
    }
    let (base, entries) = match name.strip_suffix("@entries") {
        Some(b) => (b, true),
        None => (name.as_str(), false),
    };
    let target = soundloc_fuzz::target(base).unwrap_or_else(|| {
        eprintln!("soundloc-afl: no target {base}");
        std::process::exit(2)
    });
    let zip = if entries {
        match target.zip_seeds().first() {
            Some(z) => z.clone(),
            None => {
                eprintln!("soundloc-afl: {base} is not a zip target");
                std::process::exit(2)
            }
        }
    } else {
        Vec::new()
    };
    let tmp = std::env::var_os("SOUNDLOC_AFL_TMP")
        .map(PathBuf::from)
        .or_else(|| {
            let shm = PathBuf::from("/dev/shm");
            shm.is_dir().then_some(shm)
        })
        .unwrap_or_else(std::env::temp_dir);
    let dir = tmp.join(format!("soundloc-afl-{base}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary folder");
    for (file, bytes) in target.companions() {
        std::fs::write(dir.join(file), bytes).expect("companion file");
    }
    let path = dir.join(target.file_name);
    afl::fuzz!(|data: &[u8]| {
        if entries {
            if !soundloc_fuzz::zip_with_entry(&path, &zip, data) {
                return;
            }
        } else {
            std::fs::write(&path, data).expect("input file");
        }
        let _ = target.read(&path);
    });
}
