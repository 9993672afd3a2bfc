//! Limits on what array files may cost: zip bombs, sizes a file lies about, and grids or
//! arrays too large to build are clear errors naming the file, never an abort.

use soundloc::array::freefield::free_field;
use soundloc::array::grid::GridSpec;
use soundloc::array::{Geometry, Grid, TransferFunctions};
use soundloc::formats::hark_zip::{read_zip_entries, write_tf_zip, write_zip_entries};
use std::path::{Path, PathBuf};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("soundloc-tf-limits-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn err_text<T: std::fmt::Debug>(r: soundloc::Result<T>) -> String {
    r.unwrap_err().to_string()
}

#[test]
fn zip_bombs_and_lying_sizes_are_refused() {
    // 64 MiB of zeros deflate ~1000×: refused before inflating.
    let p = tmp("bomb.zip");
    write_zip_entries(
        &p,
        &[
            ("transferFunction/".into(), Vec::new()),
            (
                "transferFunction/whatisthis.txt".into(),
                b"transfer function".to_vec(),
            ),
            ("transferFunction/zeros.mat".into(), vec![0u8; 64 << 20]),
        ],
    )
    .unwrap();
    let e = err_text(read_zip_entries(&p));
    assert!(e.contains("bomb.zip") && e.contains("zip bomb"), "{e}");
    // A TF load inflates only the entries it needs: the bomb is never touched.
    let e = err_text(TransferFunctions::load(&p));
    assert!(e.contains("missing entry transferFunction/source.xml"), "{e}");
    // A TF zip whose <nfft> is absurd: an error naming the matrix, no giant reservation.
    let tf = free_field(
        &Geometry::circle(4, 0.05, 0.0),
        &Grid::ring(30.0, 0.0, 1.0),
        512,
        16000,
        0..257,
        343.0,
    )
    .unwrap();
    let base = tmp("nfft-base.zip");
    write_tf_zip(&tf, &base).unwrap();
    let mut entries: Vec<(String, Vec<u8>)> = read_zip_entries(&base).unwrap().into_iter().collect();
    for (name, bytes) in entries.iter_mut() {
        if name.ends_with("source.xml") {
            let t = String::from_utf8(bytes.clone())
                .unwrap()
                .replace("<nfft>512</nfft>", "<nfft>4294967296</nfft>");
            assert!(t.contains("4294967296"));
            *bytes = t.into_bytes();
        }
    }
    let huge = tmp("huge_nfft.zip");
    write_zip_entries(&huge, &entries).unwrap();
    let e = err_text(TransferFunctions::load(&huge));
    assert!(e.contains("huge_nfft.zip") && e.contains("tf00000.mat"), "{e}");
    // A localization matrix that is a bomb: refused before inflating, naming it.
    let mut bomb: Vec<(String, Vec<u8>)> = read_zip_entries(&base).unwrap().into_iter().collect();
    for (name, bytes) in bomb.iter_mut() {
        if name.ends_with("localization/tf00003.mat") {
            *bytes = vec![0u8; 64 << 20];
        }
    }
    let p = tmp("tf_bomb.zip");
    write_zip_entries(&p, &bomb).unwrap();
    let e = err_text(TransferFunctions::load(&p));
    assert!(e.contains("tf00003.mat") && e.contains("zip bomb"), "{e}");
}

#[test]
fn size_and_cost_limits_are_clear_errors() {
    for (spec, want) in [
        ("ring:0.001", "at least 0.1 degrees"),
        ("sphere:1000000", "between 2 and 100000"),
        ("sphere:1", "between 2 and 100000"),
    ] {
        let e = spec.parse::<GridSpec>().unwrap_err().to_string();
        assert!(e.contains(want), "{spec}: {e}");
    }
    let mics: Vec<[f64; 3]> = (0..2000).map(|i| [i as f64 * 0.01, 0.0, 0.0]).collect();
    let e = Geometry::new(mics, Path::new("big.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("big.toml") && e.contains("2000 microphones") && e.contains("1024"),
        "{e}"
    );
    // 60 mics × 100 000 directions × 257 bins: refused before anything is built.
    let g = Geometry::sphere(60, 0.1);
    let e = err_text(free_field(
        &g,
        &Grid::sphere(100_000, 1.0),
        512,
        16000,
        0..257,
        343.0,
    ));
    assert!(e.contains("more than the 268435456 allowed"), "{e}");
    // A serde spec is checked like a parsed one.
    assert!(GridSpec::Ring {
        step_deg: 0.001,
        elevation_deg: 0.0
    }
    .validate()
    .is_err());
}
