//! Array description and HARK file formats against the real files in `../shared/data`
//! (read in place, never copied) and against malformed inputs.
//!
//! Reference numbers below were read independently with Python's `zipfile` + `struct`
//! (printed with `%.9g`, which round-trips f32 exactly).
// Reference values are printed from the files with more digits than f32 holds.
#![allow(clippy::excessive_precision)]

use num_complex::Complex;
use soundloc::array::freefield::{free_field, DEFAULT_SPEED_OF_SOUND_M_S};
use soundloc::array::grid::GridSpec;
use soundloc::array::{Geometry, Grid, GridKind, TransferFunctions};
use soundloc::formats::hark_mat::{read_mat, write_mat, MatData};
use soundloc::formats::hark_zip::{
    container_root, read_tf_zip, read_zip_entries, write_tf_zip, write_zip_entries,
};
use soundloc::formats::xml;
use std::io::Write;
use std::path::{Path, PathBuf};

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data");

/// The data folder, or `None` after saying so on stderr.
fn data(test: &str) -> Option<PathBuf> {
    let d = PathBuf::from(DATA);
    if d.is_dir() {
        Some(d)
    } else {
        let _ = writeln!(std::io::stderr(), "SKIPPED {test}: ../shared/data not found");
        None
    }
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("soundloc-array-files-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn c(re: f32, im: f32) -> Complex<f32> {
    Complex::new(re, im)
}

fn err_text<T: std::fmt::Debug>(r: soundloc::Result<T>) -> String {
    r.unwrap_err().to_string()
}

#[test]
fn real_tamago_rectf_loads() {
    let Some(d) = data("real_tamago_rectf_loads") else {
        return;
    };
    let tf = TransferFunctions::load(&d.join("tamago_rectf.zip")).unwrap();
    assert_eq!(
        (tf.num_dirs(), tf.num_mics, tf.num_bins, tf.first_bin),
        (72, 8, 257, 0)
    );
    assert_eq!((tf.nfft, tf.sample_rate_hz), (512, 16000));
    // Values (localization/tfDDDDD.mat, [mic][bin]).
    assert_eq!(tf.get(0, 0, 0), c(0.507357776, 0.0));
    assert_eq!(tf.get(0, 3, 100), c(0.999952793, -0.132301316));
    assert_eq!(tf.get(0, 7, 256), c(0.583639085, 0.0));
    assert_eq!(tf.get(35, 5, 40), c(0.0320083126, -0.191540435));
    assert_eq!(tf.get(71, 2, 17), c(0.411062896, -0.406949759));
    // Grid: id 0 at -180° (stored y="-0.000", reported as +180), counter-clockwise, ring.
    assert_eq!(tf.grid.kind, GridKind::Ring);
    assert!((tf.grid.azimuth_deg(0) - 180.0).abs() < 0.05);
    assert!((tf.grid.azimuth_deg(1) + 175.0).abs() < 0.05);
    assert!(tf.grid.azimuth_deg(36).abs() < 0.05);
    assert!((tf.grid.elevation_deg(5) - 30.96).abs() < 0.02);
    let mut n0 = tf.grid.neighbors[0].clone();
    n0.sort();
    assert_eq!(n0, vec![1, 71]);
    // Placeholder mic positions are kept as found (mics 3..7 identical).
    assert_eq!(tf.mic_positions.len(), 8);
    assert_eq!(tf.mic_positions[1], [0.985, 0.174, 0.0]);
    assert_eq!(tf.mic_positions[7], [0.866, 0.5, 0.0]);
    let s = tf.summary();
    assert_eq!((s.num_mics, s.num_dirs, s.end_bin), (8, 72, 257));
    assert!(s.neighbor_relation.contains("left/right"));
}

#[test]
fn real_tamago_geotf_loads() {
    let Some(d) = data("real_tamago_geotf_loads") else {
        return;
    };
    let tf = TransferFunctions::load(&d.join("tamago_geotf.zip")).unwrap();
    assert_eq!((tf.num_dirs(), tf.num_mics, tf.num_bins), (72, 8, 257));
    assert_eq!(tf.get(10, 2, 50), c(-0.917358696, -0.398061544));
    assert_eq!(tf.get(71, 7, 256), c(-0.264697224, 0.964331567));
    assert_eq!(tf.get(0, 0, 1), c(0.851235271, -0.524784267));
    // HARKTOOL5 order: id 0 at 0°, +5° per id, id 71 at -5°; elevation 16.7°, 1 m.
    assert_eq!(tf.grid.kind, GridKind::Ring);
    for (i, want) in [(0, 0.0), (1, 5.0), (36, 180.0), (71, -5.0)] {
        assert!((tf.grid.azimuth_deg(i) - want).abs() < 0.01, "dir {i}");
    }
    assert!((tf.grid.elevation_deg(20) - 16.7).abs() < 0.01);
    assert!((tf.grid.radius_m(20) - 1.0).abs() < 1e-3);
    assert_eq!(tf.mic_positions[1], [0.0258, 0.0258, 0.0]);
    assert_eq!(tf.mic_positions[4], [-0.0365, 0.0, 0.0]);
}

#[test]
fn real_kinect_hgtf_loads() {
    let Some(d) = data("real_kinect_hgtf_loads") else {
        return;
    };
    let tf = TransferFunctions::load(&d.join("kinect_loc.dat")).unwrap();
    assert_eq!((tf.num_dirs(), tf.num_mics, tf.num_bins), (72, 4, 257));
    assert_eq!((tf.nfft, tf.sample_rate_hz), (512, 16000));
    assert_eq!(tf.get(0, 0, 0), c(8.48202035e-05, 0.0));
    assert_eq!(tf.get(17, 3, 100), c(-0.0642460808, -0.0137327313));
    assert_eq!(tf.get(71, 1, 256), c(0.000540243462, 0.0));
    assert_eq!(tf.get(36, 2, 40), c(0.0824145675, -0.0305127501));
    assert_eq!(tf.grid.kind, GridKind::Ring);
    assert!((tf.grid.azimuth_deg(0) - 180.0).abs() < 0.01);
    assert!(tf.grid.azimuth_deg(36).abs() < 0.01);
    assert!((tf.grid.elevation_deg(3) - 16.7).abs() < 0.01);
    assert_eq!(tf.grid.neighbors[0], vec![71, 1]);
}

/// HARK's geometric-TF conventions, from tamago_geotf.zip: |a| = 1, phase = −2π f r_m / c
/// with r_m the source-to-mic distance, c = 343 m/s.
#[test]
fn free_field_matches_tamago_geotf() {
    let Some(d) = data("free_field_matches_tamago_geotf") else {
        return;
    };
    let file = TransferFunctions::load(&d.join("tamago_geotf.zip")).unwrap();

    // (a) With the file's own (4-decimal) positions: equal within 1e-4 absolute
    // (the file is f32; we measured 2.6e-5).
    let geo = Geometry::new(file.mic_positions.clone(), Path::new("microphones.xml")).unwrap();
    let ours = free_field(&geo, &file.grid, 512, 16000, 0..257, DEFAULT_SPEED_OF_SOUND_M_S).unwrap();
    let max_diff = ours
        .data
        .iter()
        .zip(&file.data)
        .map(|(a, b)| (a - b).norm())
        .fold(0f32, f32::max);
    assert!(max_diff < 1e-4, "max |ours - file| = {max_diff}");

    // (b) From the built-ins (exact circle and ring): phase within 0.02 rad (the file's
    // positions are rounded to 0.1 mm), magnitude within 1e-5.
    let geo = Geometry::circle(8, 0.0365, 0.0);
    let grid = Grid::ring(5.0, 16.7, 1.0);
    let ours = free_field(&geo, &grid, 512, 16000, 0..257, 343.0).unwrap();
    let mut max_phase = 0f32;
    let mut max_mag = 0f32;
    for (a, b) in ours.data.iter().zip(&file.data) {
        max_phase = max_phase.max((a * b.conj()).arg().abs());
        max_mag = max_mag.max((a.norm() - b.norm()).abs());
    }
    assert!(max_phase < 0.02, "max phase error {max_phase} rad");
    assert!(max_mag < 1e-5, "max magnitude error {max_mag}");

    // The opposite sign convention or another speed of sound is clearly rejected.
    let conj_err = ours
        .data
        .iter()
        .zip(&file.data)
        .map(|(a, b)| (a.conj() * b.conj()).arg().abs())
        .fold(0f32, f32::max);
    assert!(conj_err > 1.0);
    let c340 = free_field(&geo, &grid, 512, 16000, 0..257, 340.0).unwrap();
    let e340 = c340
        .data
        .iter()
        .zip(&file.data)
        .map(|(a, b)| (a * b.conj()).arg().abs())
        .fold(0f32, f32::max);
    assert!(e340 > 0.5, "340 m/s should not fit: {e340}");
    // Nearer mic ⇒ more positive phase: direction 0 (+x), bin 1, mic 0 vs mic 4.
    assert!(file.get(0, 0, 1).arg() > file.get(0, 4, 1).arg());
    assert!(ours.get(0, 0, 1).arg() > ours.get(0, 4, 1).arg());
}

#[test]
fn tf_zip_round_trip_and_layout() {
    // Ring: computed TFs -> zip -> identical TransferFunctions.
    let geo = Geometry::circle(8, 0.0365, 0.0);
    let tf = free_field(&geo, &Grid::ring(5.0, 16.7, 1.0), 512, 16000, 0..257, 343.0).unwrap();
    let p = tmp("ring.zip");
    write_tf_zip(&tf, &p).unwrap();
    let back = TransferFunctions::load(&p).unwrap();
    assert_eq!(back, tf);

    // Sphere: numbers, points and neighbours identical; the kind reads back as Irregular
    // (the zip stores no kind).
    let sph = free_field(
        &Geometry::sphere(6, 0.1),
        &Grid::sphere(200, 1.5),
        64,
        8000,
        0..33,
        343.0,
    )
    .unwrap();
    let p2 = tmp("sphere.zip");
    write_tf_zip(&sph, &p2).unwrap();
    let back = read_tf_zip(&p2).unwrap();
    assert_eq!(back.data, sph.data);
    assert_eq!(back.grid.points, sph.grid.points);
    assert_eq!(back.grid.neighbors, sph.grid.neighbors);
    assert_eq!(back.grid.kind, GridKind::Irregular);
    assert_eq!(back.mic_positions, sph.mic_positions);
    assert_eq!((back.nfft, back.sample_rate_hz), (64, 8000));

    // Separation = conjugate of localization.
    let entries = read_zip_entries(&p).unwrap();
    let loc = read_mat(
        &entries["transferFunction/localization/tf00007.mat"],
        Path::new("l"),
    )
    .unwrap();
    let sep = read_mat(
        &entries["transferFunction/separation/tf00007.mat"],
        Path::new("s"),
    )
    .unwrap();
    let (loc, sep) = (
        loc.into_complex(Path::new("l")).unwrap(),
        sep.into_complex(Path::new("s")).unwrap(),
    );
    assert!(loc.iter().zip(&sep).all(|(a, b)| a.conj() == *b));

    // Restricted bins cannot be written as a TF zip.
    let part = tf.restrict_bins(16..89).unwrap();
    assert!(err_text(write_tf_zip(&part, &tmp("part.zip"))).contains("257 bins"));
    // Nothing the readers would refuse is written: no sampling rate, a non-finite value.
    let mut no_rate = tf.clone();
    no_rate.sample_rate_hz = 0;
    let msg = err_text(write_tf_zip(&no_rate, &tmp("no-rate.zip")));
    assert!(
        msg.contains("no-rate.zip") && msg.contains("sampling rate"),
        "{msg}"
    );
    let mut nan = tf.clone();
    nan.data[7].im = f32::NAN;
    let msg = err_text(write_tf_zip(&nan, &tmp("nan.zip")));
    assert!(
        msg.contains("nan.zip") && msg.contains("value 7 is not finite"),
        "{msg}"
    );
    assert!(!tmp("no-rate.zip").exists() && !tmp("nan.zip").exists());

    let Some(d) = data("tf_zip_round_trip_and_layout") else {
        return;
    };
    // Layout: same entry names as HARKTOOL5's file (which adds a README).
    let real = read_zip_entries(&d.join("tamago_geotf.zip")).unwrap();
    let mut real_names: Vec<&String> = real.keys().filter(|k| !k.ends_with("README")).collect();
    let mut our_names: Vec<&String> = entries.keys().collect();
    real_names.sort();
    our_names.sort();
    assert_eq!(our_names, real_names);
    // XML shape: same element paths and attribute names.
    fn shape(e: &xml::Element, prefix: &str, out: &mut std::collections::BTreeSet<String>) {
        let path = format!("{prefix}/{}", e.name);
        let mut attrs: Vec<&str> = e.attrs.iter().map(|(n, _)| n.as_str()).collect();
        attrs.sort();
        out.insert(format!("{path}[{}]", attrs.join(",")));
        for ch in &e.children {
            shape(ch, &path, out);
        }
    }
    for name in ["transferFunction/source.xml", "transferFunction/microphones.xml"] {
        let (mut a, mut b) = Default::default();
        shape(
            &xml::parse(&String::from_utf8_lossy(&real[name])).unwrap(),
            "",
            &mut a,
        );
        shape(
            &xml::parse(&String::from_utf8_lossy(&entries[name])).unwrap(),
            "",
            &mut b,
        );
        assert_eq!(a, b, "{name}");
    }
    assert_eq!(
        entries["transferFunction/whatisthis.txt"],
        real["transferFunction/whatisthis.txt"]
    );

    // A real file read and rewritten reads back identically.
    let geotf = TransferFunctions::load(&d.join("tamago_geotf.zip")).unwrap();
    let p3 = tmp("geotf-rewritten.zip");
    write_tf_zip(&geotf, &p3).unwrap();
    assert_eq!(TransferFunctions::load(&p3).unwrap(), geotf);
}

#[test]
fn mat_bytes_round_trip_real() {
    let Some(d) = data("mat_bytes_round_trip_real") else {
        return;
    };
    let entries = read_zip_entries(&d.join("tamago_rectf.zip")).unwrap();
    let mut n = 0;
    for (name, bytes) in entries.iter().filter(|(k, _)| k.ends_with(".mat")).take(20) {
        let m = read_mat(bytes, Path::new(name)).unwrap();
        assert_eq!((m.rows, m.cols, m.type_name.as_str()), (8, 257, "complex"));
        assert_eq!(&write_mat(&m), bytes, "{name}");
        n += 1;
    }
    assert_eq!(n, 20);
    let m = MatData::complex(
        2,
        2,
        vec![c(1.0, 2.0), c(-3.0, 0.5), c(0.0, -0.0), c(1e-30, 1e30)],
    );
    assert_eq!(read_mat(&write_mat(&m), Path::new("x.mat")).unwrap(), m);
}

/// Build a TF zip from a valid one with one entry replaced (None = removed).
fn tampered(base: &Path, name: &str, replace: Option<Vec<u8>>, out: &str) -> PathBuf {
    let mut entries: Vec<(String, Vec<u8>)> = read_zip_entries(base).unwrap().into_iter().collect();
    entries.retain(|(n, _)| n != name);
    if let Some(b) = replace {
        entries.push((name.to_string(), b));
    }
    let p = tmp(out);
    write_zip_entries(&p, &entries).unwrap();
    p
}

#[test]
fn malformed_tf_zips() {
    let tf = free_field(
        &Geometry::circle(8, 0.0365, 0.0),
        &Grid::ring(5.0, 16.7, 1.0),
        512,
        16000,
        0..257,
        343.0,
    )
    .unwrap();
    let good = tmp("good.zip");
    write_tf_zip(&tf, &good).unwrap();
    let bytes = std::fs::read(&good).unwrap();

    // Truncated zip.
    let p = tmp("tf-truncated.zip");
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.starts_with(&format!("{}: not a readable zip archive", p.display())),
        "{e}"
    );

    // No whatisthis.txt.
    let p = tampered(&good, "transferFunction/whatisthis.txt", None, "tf-nowhat.zip");
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.contains("tf-nowhat.zip") && e.contains("no whatisthis.txt"),
        "{e}"
    );

    // A correlation-matrix container is not a TF zip.
    let p = tampered(
        &good,
        "transferFunction/whatisthis.txt",
        Some(b"correlation matrix\n".to_vec()),
        "tf-cm.zip",
    );
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.contains("tf-cm.zip") && e.contains("\"correlation matrix\""),
        "{e}"
    );
    let entries = read_zip_entries(&p).unwrap();
    assert_eq!(
        container_root(&entries, &p).unwrap(),
        ("transferFunction/".into(), "correlation matrix".into())
    );

    // Short .mat: the message names the zip, the entry, and both sizes.
    let name = "transferFunction/localization/tf00003.mat";
    let short = bytes_of(&good, name)[..1200].to_vec();
    let p = tampered(&good, name, Some(short), "tf.zip");
    let e = err_text(TransferFunctions::load(&p));
    assert_eq!(
        e,
        format!(
            "{}: {name}: expected 16524 bytes, found 1200 (complex 8 × 257)",
            p.display()
        )
    );

    // Wrong magic in a .mat.
    let mut bad = bytes_of(&good, name);
    bad[..7].copy_from_slice(b"HARK0.0");
    let p = tampered(&good, name, Some(bad), "tf-magic.zip");
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.contains("tf-magic.zip: transferFunction/localization/tf00003.mat: not a HARK .mat file"),
        "{e}"
    );

    // NaN value.
    let mut bad = bytes_of(&good, name);
    let o = 76 + 8 * (2 * 257 + 17);
    bad[o..o + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let p = tampered(&good, name, Some(bad), "tf-nan.zip");
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.contains("tf-nan.zip: transferFunction/localization/tf00003.mat: non-finite value"),
        "{e}"
    );
    assert!(e.ends_with("at mic 2, bin 17"), "{e}");

    // Missing direction.
    let p = tampered(
        &good,
        "transferFunction/localization/tf00071.mat",
        None,
        "tf-missing.zip",
    );
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.contains("tf-missing.zip") && e.contains("missing entry transferFunction/localization/tf00071.mat"),
        "{e}"
    );

    // Wrong shape (7 mics in one direction).
    let m = MatData::complex(7, 257, vec![c(1.0, 0.0); 7 * 257]);
    let p = tampered(&good, name, Some(write_mat(&m)), "tf-shape.zip");
    let e = err_text(TransferFunctions::load(&p));
    assert!(e.contains("tf00003.mat: expected a 8 × 257 matrix"), "{e}");

    // Broken source.xml and bad neighbour ids.
    let p = tampered(
        &good,
        "transferFunction/source.xml",
        Some(b"<hark_xml><config><nfft>512</nfft></confi>".to_vec()),
        "tf-xml.zip",
    );
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.contains("tf-xml.zip: transferFunction/source.xml: XML line 1"),
        "{e}"
    );
    let src = String::from_utf8(bytes_of(&good, "transferFunction/source.xml")).unwrap();
    let src = src.replace("ids=\"5;4;6;\"", "ids=\"5;4;99;\"");
    let p = tampered(
        &good,
        "transferFunction/source.xml",
        Some(src.into_bytes()),
        "tf-nb.zip",
    );
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.contains("tf-nb.zip: transferFunction/source.xml") && e.contains("\"99\""),
        "{e}"
    );

    // Neither zip nor HGTF.
    let p = tmp("tf-junk.bin");
    std::fs::write(&p, b"just some text").unwrap();
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.contains("tf-junk.bin: not a HARK transfer-function zip or HGTF file (starts with \"just som\")"),
        "{e}"
    );
    // Bytes that are not text are shown escaped, one notation throughout.
    std::fs::write(&p, b"RIFF\xc4\x03\x05\x00WAVE").unwrap();
    let e = err_text(TransferFunctions::load(&p));
    assert!(e.ends_with("(starts with \"RIFF\\xc4\\x03\\x05\\x00\")"), "{e}");
}

fn bytes_of(zip: &Path, name: &str) -> Vec<u8> {
    read_zip_entries(zip).unwrap().remove(name).unwrap()
}

#[test]
fn malformed_hgtf() {
    let Some(d) = data("malformed_hgtf") else {
        return;
    };
    let bytes = std::fs::read(d.join("kinect_loc.dat")).unwrap();
    let p = tmp("kinect-truncated_loc.dat");
    std::fs::write(&p, &bytes[..bytes.len() - 3000]).unwrap();
    let e = err_text(TransferFunctions::load(&p));
    assert!(e.starts_with(&format!("{}: truncated", p.display())), "{e}");
    let mut bad = bytes.clone();
    bad[8..12].copy_from_slice(b"XXXX");
    let p = tmp("kinect-magic_loc.dat");
    std::fs::write(&p, &bad).unwrap();
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.contains("kinect-magic_loc.dat: not a HARK transfer-function zip or HGTF file"),
        "{e}"
    );
    let e = err_text(soundloc::formats::hgtf::read_hgtf(&bad, Path::new("k_loc.dat")));
    assert!(e.starts_with("k_loc.dat: not an HGTF file"), "{e}");
    // NaN in the data (direction 0, mic 0, bin 5): M2PG body at 100, data after 12 + 72·12.
    let mut bad = bytes;
    let o = 100 + 12 + 72 * 12 + 5 * 8;
    bad[o..o + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let p = tmp("kinect-nan_loc.dat");
    std::fs::write(&p, &bad).unwrap();
    let e = err_text(TransferFunctions::load(&p));
    assert!(
        e.contains("kinect-nan_loc.dat: non-finite value") && e.ends_with("direction 0, mic 0, bin 5"),
        "{e}"
    );
}

#[test]
fn zip_entries_write_is_atomic() {
    // Own folder: other tests write zips (and their temporaries) in parallel.
    let dir = tmp("atomic");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("atomic.zip");
    write_zip_entries(&p, &[("a/".into(), vec![]), ("a/x.txt".into(), b"one".to_vec())]).unwrap();
    write_zip_entries(&p, &[("a/x.txt".into(), b"two".to_vec())]).unwrap();
    assert_eq!(read_zip_entries(&p).unwrap()["a/x.txt"], b"two");
    // Into a missing folder: error naming the file, nothing left behind.
    let bad = dir.join("no-such-dir").join("out.zip");
    let e = err_text(write_zip_entries(&bad, &[("x".into(), vec![1])]));
    assert!(e.contains("no-such-dir"), "{e}");
    // Rename onto a non-empty folder fails after the temporary was written: the
    // temporary is removed and the folder untouched.
    let target = dir.join("occupied");
    std::fs::create_dir_all(&target).unwrap();
    std::fs::write(target.join("keep"), b"k").unwrap();
    let e = err_text(write_zip_entries(&target, &[("x".into(), vec![1])]));
    assert!(e.contains("occupied"), "{e}");
    assert_eq!(std::fs::read(target.join("keep")).unwrap(), b"k");
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty());
}

#[test]
fn geometry_files() {
    let p = tmp("ring8.toml");
    std::fs::write(&p, Geometry::circle(8, 0.0365, 0.0).to_toml_string()).unwrap();
    assert_eq!(Geometry::load(&p).unwrap(), Geometry::circle(8, 0.0365, 0.0));
    std::fs::write(&p, "mics = [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0.1, 0.1]]\n").unwrap();
    assert_eq!(
        err_text(Geometry::load(&p)),
        format!("{}: mic 3: expected 3 coordinates, found 2", p.display())
    );
    std::fs::write(
        &p,
        "[[mic]]\nx = 0.1\ny = 0.0\n[[mic]]\nx = 0.1\ny = 0.0\nz = 0.0\n",
    )
    .unwrap();
    assert!(err_text(Geometry::load(&p)).ends_with("mic 1: same position as mic 0 ([0.1, 0.0, 0.0])"));
    std::fs::write(&p, "mics = [[nan, 0, 0]]\n").unwrap();
    assert!(err_text(Geometry::load(&p)).contains("mic 0: position [NaN, 0.0, 0.0] is not finite"));
    std::fs::write(&p, "mics = [[0.1, 0, 0], [0, 1e300, 0]]\n").unwrap();
    let msg = err_text(Geometry::load(&p));
    assert!(
        msg.starts_with(&format!("{}: mic 1: position", p.display())) && msg.contains("beyond"),
        "{msg}"
    );
}

#[test]
fn grid_specs_and_sphere_neighbours() {
    let g = "sphere:2522".parse::<GridSpec>().unwrap().build(1.0);
    assert_eq!(g.len(), 2522);
    assert!(g.neighbors_symmetric());
    // Mean spacing √(4π/2522) ≈ 4.04°: every neighbour within 2× that.
    assert!(g.max_neighbor_angle_deg() < 8.1, "{}", g.max_neighbor_angle_deg());
    assert!(g.neighbors.iter().all(|l| l.len() >= 6));
    let r = "ring:5:16.7".parse::<GridSpec>().unwrap().build(1.0);
    assert_eq!(r.len(), 72);
    assert_eq!(r.neighbors[0], vec![71, 1]);
    assert!("ring:7".parse::<GridSpec>().is_err());
}
