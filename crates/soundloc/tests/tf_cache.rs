//! Reading only the used bins of a TF zip, and the prepared-TF cache: hit, miss, stale,
//! corrupt, unwritable, concurrent — each gives the right transfer functions.

use soundloc::array::freefield::free_field;
use soundloc::array::tf_cache::{CacheOutcome, TfCache};
use soundloc::array::{Geometry, Grid, TransferFunctions};
use soundloc::formats::hark_zip::{inspect_tf_zip, write_tf_zip};
use std::path::{Path, PathBuf};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("soundloc-tf-cache-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn make_zip(path: &Path, radius_m: f64) -> TransferFunctions {
    let tf = free_field(
        &Geometry::sphere(12, 0.08),
        &Grid::sphere(200, radius_m),
        512,
        16000,
        0..257,
        343.0,
    )
    .unwrap();
    write_tf_zip(&tf, path).unwrap();
    tf
}

const WANT: (usize, u32, std::ops::Range<usize>) = (512, 16000, 16..88);

#[test]
fn used_bin_read_equals_the_full_read_on_those_bins() {
    let p = tmp("partial.zip");
    let written = make_zip(&p, 1.0);
    let full = TransferFunctions::load(&p).unwrap();
    assert!(full.data == written.data && full.grid.points == written.grid.points);
    let part = TransferFunctions::load_bins(&p, Some(WANT)).unwrap();
    assert_eq!(part, full.restrict_bins(16..88).unwrap());
    assert_eq!((part.first_bin, part.num_bins), (16, 72));
    // A config that does not fit the file (other N or rate): all bins, the plan decides.
    for other in [
        (1024, 16000, 16..88),
        (512, 48000, 16..88),
        (512, 16000, 200..300),
    ] {
        assert_eq!(TransferFunctions::load_bins(&p, Some(other)).unwrap(), full);
    }
    // The quick description equals the full one.
    assert_eq!(inspect_tf_zip(&p).unwrap(), full.summary());
}

fn load(p: &Path, dir: &Path) -> (TransferFunctions, CacheOutcome) {
    TransferFunctions::load_cached(p, Some(WANT), &TfCache::Dir(dir.to_path_buf())).unwrap()
}

fn entries(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.sort();
    v
}

#[test]
fn cache_hit_miss_stale_corrupt_and_unwritable() {
    let p = tmp("cached.zip");
    let dir = tmp("cache");
    make_zip(&p, 1.0);
    let want = TransferFunctions::load_bins(&p, Some(WANT)).unwrap();

    // Miss: read the zip, store one entry.
    let (tf, o) = load(&p, &dir);
    assert_eq!(tf, want);
    let entry = match o {
        CacheOutcome::Stored(e, None) => e,
        other => panic!("{other:?}"),
    };
    assert_eq!(entries(&dir), vec![entry.clone()], "no temporary file left");
    // Hit: the same content, from the entry; a copy of the zip elsewhere hits too.
    let (tf, o) = load(&p, &dir);
    assert_eq!(tf, want);
    assert_eq!(o, CacheOutcome::Hit(entry.clone()));
    let copy = tmp("copy-of-cached.zip");
    std::fs::copy(&p, &copy).unwrap();
    assert_eq!(load(&copy, &dir).1, CacheOutcome::Hit(entry.clone()));
    // Other bins: another entry.
    let other =
        TransferFunctions::load_cached(&p, Some((512, 16000, 20..40)), &TfCache::Dir(dir.clone())).unwrap();
    assert!(matches!(other.1, CacheOutcome::Stored(..)));
    assert_eq!(other.0.num_bins, 20);

    // Corrupt: one flipped data byte, then a truncated entry: rebuilt, right answer.
    let mut bytes = std::fs::read(&entry).unwrap();
    let n = bytes.len();
    bytes[n - 5] ^= 0x40;
    std::fs::write(&entry, &bytes).unwrap();
    let (tf, o) = load(&p, &dir);
    assert_eq!(tf, want);
    match o {
        CacheOutcome::Stored(e, Some(why)) => {
            assert_eq!(e, entry);
            assert!(why.contains("checksum"), "{why}");
        }
        other => panic!("{other:?}"),
    }
    std::fs::write(&entry, &bytes[..n / 2]).unwrap();
    let (tf, o) = load(&p, &dir);
    assert_eq!(tf, want);
    assert!(matches!(o, CacheOutcome::Stored(_, Some(_))), "{o:?}");
    assert!(matches!(load(&p, &dir).1, CacheOutcome::Hit(_)));

    // Stale: the TF file changes (other radius): a different key, the new content.
    make_zip(&p, 2.0);
    let changed = TransferFunctions::load(&p).unwrap();
    let (tf, o) = load(&p, &dir);
    assert_eq!(tf, changed.restrict_bins(16..88).unwrap());
    assert_ne!(tf, want);
    assert!(
        matches!(o, CacheOutcome::Stored(ref e, None) if *e != entry),
        "{o:?}"
    );

    // Unwritable: a cache "folder" below a regular file cannot be created: the run goes
    // on with the right answer and says why.
    let blocker = tmp("not-a-dir");
    std::fs::write(&blocker, b"x").unwrap();
    let (tf, o) =
        TransferFunctions::load_cached(&p, Some(WANT), &TfCache::Dir(blocker.join("cache"))).unwrap();
    assert_eq!(tf, changed.restrict_bins(16..88).unwrap());
    assert!(
        matches!(o, CacheOutcome::NotStored(ref w) if w.contains("not-a-dir")),
        "{o:?}"
    );
    // Off: never touches a folder.
    let (tf, o) = TransferFunctions::load_cached(&p, Some(WANT), &TfCache::Off).unwrap();
    assert_eq!(o, CacheOutcome::Bypassed);
    assert_eq!(tf.num_bins, 72);
}

#[test]
fn concurrent_cold_loads_agree_and_leave_one_valid_entry() {
    let p = tmp("concurrent.zip");
    let dir = tmp("cache-concurrent");
    make_zip(&p, 1.0);
    let want = TransferFunctions::load_bins(&p, Some(WANT)).unwrap();
    let got: Vec<TransferFunctions> = std::thread::scope(|s| {
        let hs: Vec<_> = (0..4).map(|_| s.spawn(|| load(&p, &dir).0)).collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert!(got.iter().all(|t| *t == want));
    let e = entries(&dir);
    assert_eq!(e.len(), 1, "one entry, no temporary files: {e:?}");
    assert!(matches!(load(&p, &dir).1, CacheOutcome::Hit(_)));
}

#[test]
fn prune_deletes_least_recently_used_entries_only() {
    use soundloc::array::tf_cache::prune;
    use std::time::{Duration, SystemTime};
    let dir = tmp("cache-prune");
    std::fs::create_dir_all(&dir).unwrap();
    let t0 = SystemTime::now() - Duration::from_secs(3600);
    // Four 1000-byte entries, oldest first, and two files that are not entries.
    let names = [
        "tf-00000000000000a1.bin",
        "cuda-00000000000000b2.bin",
        "tf-00000000000000c3.bin",
        "tf-00000000000000d4.bin",
    ];
    for (i, n) in names.iter().enumerate() {
        let f = dir.join(n);
        std::fs::write(&f, vec![0u8; 1000]).unwrap();
        let h = std::fs::File::options().append(true).open(&f).unwrap();
        h.set_modified(t0 + Duration::from_secs(60 * i as u64)).unwrap();
    }
    std::fs::write(dir.join("notes.txt"), vec![0u8; 5000]).unwrap();
    std::fs::write(dir.join("tf-notahexkey.bin"), vec![0u8; 5000]).unwrap();
    // The oldest is the one just stored: it is kept, the next two oldest go.
    let keep = dir.join(names[0]);
    assert_eq!(prune(&dir, &keep, Some(2000)), 2);
    let mut left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(left, vec!["notes.txt", names[0], names[3], "tf-notahexkey.bin"]);
    // No limit, or under it: nothing goes.
    assert_eq!(prune(&dir, &keep, None), 0);
    assert_eq!(prune(&dir, &keep, Some(2000)), 0);
}

#[test]
fn a_cache_hit_refreshes_its_entry_so_pruning_keeps_it() {
    use soundloc::array::tf_cache::prune;
    use std::time::{Duration, SystemTime};
    let p = tmp("lru.zip");
    let dir = tmp("cache-lru");
    make_zip(&p, 1.0);
    let entry = match load(&p, &dir).1 {
        CacheOutcome::Stored(e, None) => e,
        other => panic!("{other:?}"),
    };
    let old = SystemTime::now() - Duration::from_secs(7200);
    std::fs::File::options()
        .append(true)
        .open(&entry)
        .unwrap()
        .set_modified(old)
        .unwrap();
    // A newer unrelated entry.
    let newer = dir.join("tf-00000000000000ff.bin");
    std::fs::write(&newer, vec![0u8; 100]).unwrap();
    std::fs::File::options()
        .append(true)
        .open(&newer)
        .unwrap()
        .set_modified(old + Duration::from_secs(60))
        .unwrap();
    assert!(matches!(load(&p, &dir).1, CacheOutcome::Hit(_)));
    assert!(std::fs::metadata(&entry).unwrap().modified().unwrap() > old + Duration::from_secs(3600));
    // Room for one of the two: the one just used stays.
    let size = std::fs::metadata(&entry).unwrap().len();
    assert_eq!(prune(&dir, &dir.join("none"), Some(size)), 1);
    assert!(entry.exists() && !newer.exists());
}
