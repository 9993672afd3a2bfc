//! One vocabulary across subcommands (old spellings kept as aliases), options that do not
//! apply refused instead of ignored.

mod common;

use common::bin;
use std::path::PathBuf;
use std::process::Stdio;

fn tmp(name: &str) -> PathBuf {
    common::tmp("cli-vocab", name)
}

/// An 8-mic ring recording (two talkers), its geometry and a TF zip of it, in files of
/// the test's own (tests run in parallel).
fn scene(test: &str) -> (PathBuf, PathBuf, PathBuf) {
    let (_, geo, wav) = common::ring_scene("cli-vocab", &format!("{test}-"), 1);
    let tf = tmp(&format!("{test}-ring8.zip"));
    let o = bin()
        .args([
            "tf",
            "make",
            "--geometry",
            geo.to_str().unwrap(),
            "--grid",
            "ring:5",
            "--grid-radius",
            "2",
            "-o",
        ])
        .arg(&tf)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (wav, geo, tf)
}

fn fails_with(args: &[&str], must: &[&str]) {
    let o = bin().args(args).output().unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
    assert!(o.stdout.is_empty(), "nothing computed: {args:?}");
    for m in must {
        assert!(e.contains(m), "{args:?} should say {m:?}: {e}");
    }
}

#[test]
fn grid_options_with_a_tf_file_are_refused_not_ignored() {
    let (wav, _, tf) = scene("grid_options_with_a_tf_file_are_refused_not_ignored");
    let (w, t) = (wav.to_str().unwrap(), tf.to_str().unwrap());
    for opt in [
        ["--grid", "ring:10"],
        ["--grid-radius", "3"],
        ["--speed-of-sound", "340"],
    ] {
        fails_with(&["localize", w, "--tf", t, opt[0], opt[1]], &["--tf", opt[0]]);
    }
    // Without them it runs.
    let o = bin().args(["localize", w, "--tf", t, "-q"]).output().unwrap();
    assert!(o.status.success());
}

/// --resample converts to the TF file's rate; free-field transfer functions (--geometry)
/// are made at the input's rate, so there it converts only a --noise recording: without
/// one it would do nothing, and is refused.
#[test]
fn resample_with_a_geometry_and_no_noise_is_refused_not_ignored() {
    let (wav, geo, _) = scene("resample_with_a_geometry_and_no_noise_is_refused_not_ignored");
    let (w, g) = (wav.to_str().unwrap(), geo.to_str().unwrap());
    fails_with(
        &["localize", w, "--geometry", g, "--grid", "ring:5", "--resample"],
        &["--resample with --geometry converts only a --noise recording"],
    );
    let o = bin()
        .args([
            "localize",
            w,
            "--geometry",
            g,
            "--grid",
            "ring:5",
            "--resample",
            "--noise",
            w,
            "-q",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn old_and_new_spellings_give_the_same_files() {
    let (wav, geo, tf) = scene("old_and_new_spellings_give_the_same_files");
    let w = wav.to_str().unwrap();
    // noisecm make: --window-function / --input-channels, formerly --window / --channels.
    let (new, old) = (tmp("k_new.zip"), tmp("k_old.zip"));
    for (out, args) in [
        (
            &new,
            [
                "--window-function",
                "hamming",
                "--input-channels",
                "0,1,2,3,4,5,6,7",
            ],
        ),
        (&old, ["--window", "hamming", "--channels", "0,1,2,3,4,5,6,7"]),
    ] {
        let o = bin()
            .args(["noisecm", "make", w, "--range", "0:1", "-o"])
            .arg(out)
            .args(args)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let inspect = |p: &PathBuf| {
        bin()
            .args(["noisecm", "inspect", "--json"])
            .arg(p)
            .output()
            .unwrap()
            .stdout
    };
    let strip = |v: Vec<u8>| {
        let mut j: serde_json::Value = serde_json::from_slice(&v).unwrap();
        j.as_object_mut().unwrap().remove("file");
        j
    };
    assert_eq!(strip(inspect(&new)), strip(inspect(&old)));
    // tf make: --grid-radius, formerly --radius.
    let old_tf = tmp("ring8_old.zip");
    let o = bin()
        .args([
            "tf",
            "make",
            "--geometry",
            geo.to_str().unwrap(),
            "--grid",
            "ring:5",
            "--radius",
            "2",
            "-o",
        ])
        .arg(&old_tf)
        .output()
        .unwrap();
    assert!(o.status.success());
    let desc = |p: &PathBuf| {
        bin()
            .args(["tf", "inspect", "--verify", "--json"])
            .arg(p)
            .output()
            .unwrap()
            .stdout
    };
    let (a, b) = (strip(desc(&tf)), strip(desc(&old_tf)));
    assert_eq!(a, b);
    assert!((a["radius_min_m"].as_f64().unwrap() - 2.0).abs() < 1e-9, "{a}");
}

#[test]
fn noise_cm_text_pairs_are_named_and_found() {
    let (wav, geo, _) = scene("noise_cm_text_pairs_are_named_and_found");
    let w = wav.to_str().unwrap();
    // --format text with a .zip name: refused, nothing written.
    let z = tmp("k.zip");
    fails_with(
        &[
            "noisecm",
            "make",
            w,
            "--range",
            "0:1",
            "--format",
            "text",
            "-o",
            z.to_str().unwrap(),
        ],
        &["k.zip", "--format zip"],
    );
    assert!(!z.exists() && !tmp("k_r.zip").exists());
    // A pair under names that do not pair up: the error says how to give both, and that works.
    let k = tmp("K");
    let o = bin()
        .args(["noisecm", "make", w, "--range", "0:1", "-o", k.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success());
    let (re, im) = (tmp("K_r"), tmp("K_i"));
    let (odd_re, odd_im) = (tmp("real-part.txt"), tmp("imag-part.txt"));
    std::fs::copy(&re, &odd_re).unwrap();
    std::fs::copy(&im, &odd_im).unwrap();
    fails_with(&["noisecm", "inspect", odd_re.to_str().unwrap()], &["REAL,IMAG"]);
    let pair = format!("{},{}", odd_re.display(), odd_im.display());
    let a = bin().args(["noisecm", "inspect", &pair]).output().unwrap();
    let b = bin().args(["noisecm", "inspect"]).arg(&re).output().unwrap();
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    let body = |v: &[u8]| {
        String::from_utf8_lossy(v)
            .lines()
            .skip(1)
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(body(&a.stdout), body(&b.stdout));
    // The same pair is accepted by localize --noise-cm.
    let o = bin()
        .args([
            "localize",
            w,
            "--geometry",
            geo.to_str().unwrap(),
            "--grid",
            "ring:5",
            "-q",
            "--noise-cm",
            &pair,
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `-q` drops the notes and the progress bar, not the warnings that make the results
/// worthless: a silent input says so (it printed nothing, exit 0, until 2026-12-02).
#[test]
fn quiet_still_prints_warnings() {
    let (_, geo, _) = scene("quiet_warnings");
    let mut child = bin()
        .args([
            "localize",
            "-",
            "--raw",
            "s16le",
            "--raw-channels",
            "8",
            "--rate",
            "16000",
        ])
        .args(["--geometry", geo.to_str().unwrap(), "-q"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    std::io::Write::write_all(&mut stdin, &vec![0u8; 16000 * 8 * 2]).unwrap();
    drop(stdin);
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("warning: the input is silent"), "{err}");
    assert!(!err.contains("room default"), "a note with -q: {err}");
}

/// The command-line fuzzer's findings (FUZZING.md): an FFT length of 2⁶⁴−1 aborted on
/// allocation, and a geometry "file" that is an endless device (`/dev/full` through a link)
/// was read forever. Both are clear errors naming what is wrong, exit 2, nothing written.
#[test]
fn absurd_fft_lengths_and_endless_files_are_clear_errors() {
    let (wav, geo, _) = scene("fuzzfind");
    let out = tmp("fuzzfind-K.zip");
    fails_with(
        &[
            "noisecm",
            "make",
            wav.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--range",
            "0:0.3",
            "--fft-length",
            "18446744073709551615",
        ],
        &["FFT length", "65536"],
    );
    assert!(!out.exists());
    fails_with(
        &[
            "localize",
            wav.to_str().unwrap(),
            "--geometry",
            geo.to_str().unwrap(),
            "--fft-length",
            "1048576",
        ],
        &["FFT length"],
    );
    let link = tmp("fuzzfind-dev-full.toml");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink("/dev/full", &link).unwrap();
    fails_with(
        &[
            "localize",
            wav.to_str().unwrap(),
            "--geometry",
            link.to_str().unwrap(),
            "-q",
        ],
        &["fuzzfind-dev-full.toml", "too large for a geometry file"],
    );
}

/// `--coherence` and `--no-coherence` are plain switches (a following input is not taken
/// as their value), the last one wins, and the summary line says what ran: the room
/// default normalises unless told not to; a named algorithm does only when asked.
#[test]
fn coherence_switches_say_what_ran() {
    let (wav, geo, _) = scene("coherence_switches_say_what_ran");
    let (w, g) = (wav.to_str().unwrap(), geo.to_str().unwrap());
    let summary = |args: &[&str]| {
        let o = bin().args(args).output().unwrap();
        let e = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{args:?}: {e}");
        e.lines()
            .find(|l| l.contains(" results from "))
            .unwrap_or_else(|| panic!("{args:?}: no summary line in {e}"))
            .to_string()
    };
    let s = summary(&["localize", w, "--geometry", g]);
    assert!(s.contains("normmusic (subspace 4, coherence, refined)"), "{s}");
    let s = summary(&["localize", "--no-coherence", w, "--geometry", g]);
    assert!(s.contains("normmusic (subspace 4, refined)"), "{s}");
    let s = summary(&["localize", "--no-coherence", "--coherence", w, "--geometry", g]);
    assert!(s.contains("coherence, refined"), "{s}");
    let s = summary(&[
        "localize",
        "--coherence",
        w,
        "--geometry",
        g,
        "--algorithm",
        "sevd",
    ]);
    assert!(s.contains("sevd (coherence)"), "{s}");
    let s = summary(&["localize", w, "--geometry", g, "--algorithm", "sevd"]);
    assert!(!s.contains("coherence"), "{s}");
    // Refinement and per-bin normalisation switch the same way, also in the room default.
    let s = summary(&[
        "localize",
        "--no-refine",
        "--no-normalize-bins",
        w,
        "--geometry",
        g,
    ]);
    assert!(s.contains("sevd (subspace 4, coherence)"), "{s}");
    let s = summary(&["localize", "--no-refine", "--refine", w, "--geometry", g]);
    assert!(s.contains("normmusic (subspace 4, coherence, refined)"), "{s}");
    let s = summary(&["localize", w, "--geometry", g, "--algorithm", "sevd", "--refine"]);
    assert!(s.contains("sevd (refined)"), "{s}");
    // The spectrum's numerator: geometric in the robust default, spec §5's raw for a named
    // gevd, either on request; refused by the algorithms it does not apply to.
    let noise = ["--noise-range", "0:0.5"];
    let s = summary(&[&["localize", w, "--geometry", g][..], &noise].concat());
    assert!(
        s.contains("gevd (subspace 4, geometric numerator, refined)"),
        "{s}"
    );
    let s = summary(
        &[
            &["localize", w, "--geometry", g, "--numerator", "raw"][..],
            &noise,
        ]
        .concat(),
    );
    assert!(s.contains("gevd (subspace 4, refined)"), "{s}");
    let s = summary(
        &[
            &["localize", w, "--geometry", g, "--algorithm", "gevd"][..],
            &noise,
        ]
        .concat(),
    );
    assert!(s.contains("gevd on cpu"), "{s}");
    let args = ["--algorithm", "gevd", "--numerator", "whitened"];
    let s = summary(&[&["localize", w, "--geometry", g][..], &args, &noise].concat());
    assert!(s.contains("gevd (whitened numerator)"), "{s}");
    for alg in ["gsvd", "sevd", "srp-phat"] {
        let o = bin()
            .args([
                "localize",
                w,
                "--geometry",
                g,
                "--numerator",
                "geometric",
                "--algorithm",
                alg,
            ])
            .args(noise)
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{alg}: {e}");
        assert!(
            e.contains("numerator is defined for the textbook gevd"),
            "{alg}: {e}"
        );
        assert!(o.stdout.is_empty(), "{alg}: no work before the error");
    }
    // Options SRP-PHAT has no use for are named, not ignored.
    for opt in [
        &["--coherence"][..],
        &["--subspace-dim", "3"],
        &["--denominator", "unsquared"],
    ] {
        let o = bin()
            .args(["localize", w, "--geometry", g, "--algorithm", "srp-phat"])
            .args(opt)
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{opt:?}: {e}");
        assert!(
            e.contains("would change nothing") && e.contains(opt[0]),
            "{opt:?}: {e}"
        );
        assert!(o.stdout.is_empty());
    }
}

/// `tf make` with positions in a frame whose origin lies outside the array (room
/// coordinates) says that the directions are seen from the centroid and writes the moved
/// positions; localizing with that file or with the geometry gives the same directions.
#[test]
fn an_array_in_room_coordinates_is_seen_from_its_centroid() {
    let (wav, geo, tf) = scene("an_array_in_room_coordinates");
    let text = std::fs::read_to_string(&geo).unwrap();
    let g: soundloc::array::Geometry = soundloc::array::Geometry::from_toml_str(&text, &geo).unwrap();
    let room = soundloc::array::Geometry {
        mics: g
            .mics
            .iter()
            .map(|p| [p[0] + 3.0, p[1] + 2.5, p[2] + 1.2])
            .collect(),
    };
    let room_geo = tmp("room.toml");
    std::fs::write(&room_geo, room.to_toml_string()).unwrap();
    let room_tf = tmp("room.zip");
    let o = bin()
        .args([
            "tf",
            "make",
            "--grid",
            "ring:5",
            "--grid-radius",
            "2",
            "--geometry",
        ])
        .arg(&room_geo)
        .arg("-o")
        .arg(&room_tf)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && e.contains("directions are seen from the centroid"),
        "{e}"
    );
    // (frame, rank, azimuth) of every reported source; the moved positions differ from
    // the centred ones by rounding only.
    let azimuths = |args: &[&std::ffi::OsStr]| -> Vec<(u64, u64, f64)> {
        let o = bin()
            .arg("localize")
            .arg(&wav)
            .args(args)
            .args(["-q", "--format", "csv"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect::<Vec<&str>>())
            // Rows of windows without sources (empty rank) hold no direction.
            .filter(|f| !f[2].is_empty())
            .map(|f| {
                (
                    f[0].parse().unwrap(),
                    f[2].parse().unwrap(),
                    f[4].parse().unwrap(),
                )
            })
            .collect()
    };
    let same = |a: Vec<(u64, u64, f64)>, b: Vec<(u64, u64, f64)>| {
        a.len() == b.len()
            && a.iter()
                .zip(&b)
                .all(|(x, y)| x.0 == y.0 && x.1 == y.1 && (x.2 - y.2).abs() < 0.01)
    };
    let want = azimuths(&["--tf".as_ref(), tf.as_os_str()]);
    assert!(want.len() > 3, "{want:?}");
    let got = azimuths(&["--tf".as_ref(), room_tf.as_os_str()]);
    assert!(same(got.clone(), want.clone()), "{got:?} vs {want:?}");
    let flags = ["--grid-radius", "2", "--algorithm", "sevd", "--geometry"];
    let mut args: Vec<&std::ffi::OsStr> = flags.iter().map(|f| f.as_ref()).collect();
    args.push(room_geo.as_os_str());
    let mut centred: Vec<&std::ffi::OsStr> = flags.iter().map(|f| f.as_ref()).collect();
    centred.push(geo.as_os_str());
    let (a, b) = (azimuths(&args), azimuths(&centred));
    assert!(same(a.clone(), b.clone()), "{a:?} vs {b:?}");
}

/// An empty input name is named as such, not as a file called "".
#[test]
fn an_empty_input_name_is_a_clear_error() {
    fails_with(
        &["localize", "", "--geometry", "x.toml"],
        &["the input's name is empty"],
    );
}
