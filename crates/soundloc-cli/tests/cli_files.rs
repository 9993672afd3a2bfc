//! `soundloc localize` on files: an input at another rate than the TFs (`--resample`),
//! and outputs that never replace an input or each other.

mod common;

use common::{bin, spawn_piped};
use std::io::Write;
use std::path::{Path, PathBuf};

const OPTS: [&str; 9] = [
    "--grid",
    "ring:5",
    "--window-type",
    "past",
    "--period",
    "10",
    "--device",
    "cpu",
    "-q",
];

fn tmp(name: &str) -> PathBuf {
    common::tmp("cli-files", name)
}

/// A fresh folder `name` of this test process.
fn tmp_dir(name: &str) -> PathBuf {
    let dir = tmp(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn scene() -> (soundloc::audio::Audio, PathBuf, PathBuf) {
    common::ring_scene("cli-files", "", 1)
}

/// Azimuths of each result line's sources.
fn azimuths(jsonl: &str) -> Vec<Vec<f64>> {
    jsonl
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            v["sources"]
                .as_array()
                .unwrap()
                .iter()
                .map(|s| s["azimuth_deg"].as_f64().unwrap())
                .collect()
        })
        .collect()
}

/// Free-field TFs at 48 kHz: without --fft-length/--hop the frames are HARK's 32 ms and
/// 10 ms there (1536 and 480 samples, said in a note), so a result still comes every 0.5 s
/// at PERIOD 50 and the talkers are found as at 16 kHz; given sizes are kept.
#[test]
fn geometry_frames_keep_harks_durations_at_48_khz() {
    let (audio, geo, wav16) = scene();
    let a48 = soundloc::audio::resample::resample_audio(&audio, 48000).unwrap();
    let wav48 = tmp("ring8-48k-frames.wav");
    a48.write_wav(&wav48, soundloc::audio::SampleFormat::Float32)
        .unwrap();
    let run = |wav: &Path, extra: &[&str]| {
        let o = bin()
            .arg("localize")
            .arg(wav)
            .arg("--geometry")
            .arg(&geo)
            .args(["--grid", "ring:5", "--device", "cpu"])
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (
            String::from_utf8(o.stdout).unwrap(),
            String::from_utf8(o.stderr).unwrap(),
        )
    };
    let times = |jsonl: &str| -> Vec<f64> {
        jsonl
            .lines()
            .map(|l| {
                serde_json::from_str::<serde_json::Value>(l).unwrap()["time_s"]
                    .as_f64()
                    .unwrap()
            })
            .collect()
    };
    let (out48, err48) = run(&wav48, &[]);
    assert!(
        err48.contains("at 48000 Hz the frames are 1536 samples with a hop of 480"),
        "{err48}"
    );
    let (given, _) = run(&wav48, &["--fft-length", "1536", "--hop", "480", "-q"]);
    assert_eq!(out48, given);
    let (out16, err16) = run(&wav16, &[]);
    assert!(!err16.contains("the frames are"), "{err16}");
    assert_eq!(times(&out48), times(&out16));
    assert!(times(&out48).len() >= 3 && times(&out48)[1] == 0.5);
    let near = |a: f64, b: f64| ((a - b + 540.0) % 360.0 - 180.0).abs() <= 5.0;
    let both = |r: &Vec<f64>| [30.0, -120.0].iter().all(|&t| r.iter().any(|&a| near(a, t)));
    let (got, want) = (azimuths(&out48), azimuths(&out16));
    let hits = |rows: &Vec<Vec<f64>>| rows.iter().filter(|r| both(r)).count();
    assert!(
        hits(&want) * 10 >= want.len() * 5,
        "the 16 kHz run itself: {want:?}"
    );
    assert!(
        hits(&got) >= hits(&want),
        "48 kHz {got:?} against 16 kHz {want:?}"
    );
    // HARK's sample counts, given: kept (a result every 50 × 160 samples).
    let (hark, err) = run(&wav48, &["--fft-length", "512", "--hop", "160"]);
    assert!(!err.contains("the frames are"), "{err}");
    assert!((times(&hark)[1] - 8000.0 / 48000.0).abs() < 1e-9);
    // A TF zip made for 1536-point frames at 48 kHz: its FFT length and a hop of 160/512
    // of it, with no --fft-length (it was an error naming --fft-length 1536): the same
    // results as the free-field run.
    let tf48 = tmp("ring8-48k-frames.zip");
    let o = bin()
        .args([
            "tf",
            "make",
            "--grid",
            "ring:5",
            "--sample-rate",
            "48000",
            "--fft-length",
            "1536",
            "-q",
        ])
        .arg("--geometry")
        .arg(&geo)
        .arg("-o")
        .arg(&tf48)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = bin()
        .arg("localize")
        .arg(&wav48)
        .arg("--tf")
        .arg(&tf48)
        .args(["--device", "cpu", "-q", "--no-cache"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(String::from_utf8(o.stdout).unwrap(), out48);
}

#[test]
fn resample_converts_a_48_khz_input_and_noise_recording() {
    let (audio, geo, wav16) = scene();
    let tf = tmp("ring8-16k.zip");
    let o = bin()
        .args(["tf", "make", "--grid", "ring:5", "--geometry"])
        .arg(&geo)
        .arg("-o")
        .arg(&tf)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let a48 = soundloc::audio::resample::resample_audio(&audio, 48000).unwrap();
    let wav48 = tmp("ring8-48k.wav");
    a48.write_wav(&wav48, soundloc::audio::SampleFormat::Float32)
        .unwrap();
    let opts = ["--window-type", "past", "--period", "10", "--device", "cpu", "-q"];
    let run = |wav: &Path, extra: &[&str]| {
        bin()
            .arg("localize")
            .arg(wav)
            .arg("--tf")
            .arg(&tf)
            .args(opts)
            .args(extra)
            .output()
            .unwrap()
    };
    // Without --resample: a clear error naming the file and both rates.
    let o = run(&wav48, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && o.stdout.is_empty(), "{err}");
    assert!(
        err.contains("ring8-48k.wav")
            && err.contains("48000 Hz")
            && err.contains("16000 Hz")
            && err.contains("--resample"),
        "{err}"
    );
    // With it: as many results as the 16 kHz original, the talkers where they are.
    let o16 = run(&wav16, &[]);
    assert!(o16.status.success(), "{}", String::from_utf8_lossy(&o16.stderr));
    let o48 = run(&wav48, &["--resample"]);
    assert!(o48.status.success(), "{}", String::from_utf8_lossy(&o48.stderr));
    let (want, got) = (
        azimuths(&String::from_utf8(o16.stdout).unwrap()),
        azimuths(&String::from_utf8(o48.stdout).unwrap()),
    );
    assert_eq!(got.len(), want.len());
    let near = |a: f64, b: f64| ((a - b + 540.0) % 360.0 - 180.0).abs() <= 5.0;
    let both = |r: &Vec<f64>| [30.0, -120.0].iter().all(|&t| r.iter().any(|&a| near(a, t)));
    let n_want = want.iter().filter(|r| both(r)).count();
    let n_got = got.iter().filter(|r| both(r)).count();
    assert!(n_want * 10 >= want.len() * 7, "the 16 kHz run itself: {want:?}");
    assert!(
        n_got + 1 >= n_want,
        "48 kHz resampled: {n_got} vs {n_want} of {} windows: {got:?}",
        got.len()
    );
    // Piped in odd-sized pieces: the same lines as from the file (block-size independent).
    let mut child = spawn_piped(
        bin()
            .args(["localize", "-", "--tf"])
            .arg(&tf)
            .args(opts)
            .arg("--resample"),
    );
    let mut stdin = child.stdin.take().unwrap();
    let bytes = std::fs::read(&wav48).unwrap();
    let writer = std::thread::spawn(move || {
        for c in bytes.chunks(4099) {
            stdin.write_all(c).unwrap();
        }
    });
    let o = child.wait_with_output().unwrap();
    writer.join().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(azimuths(&String::from_utf8(o.stdout).unwrap()), got);
    // A 48 kHz noise recording for K is converted too (and refused without --resample).
    let o = run(&wav16, &["--noise", wav48.to_str().unwrap()]);
    assert!(!o.status.success(), "a 48 kHz noise recording without --resample");
    assert!(String::from_utf8_lossy(&o.stderr).contains("48000 Hz"));
    let o = run(
        &wav48,
        &[
            "--resample",
            "--noise",
            wav48.to_str().unwrap(),
            "--algorithm",
            "gevd",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(azimuths(&String::from_utf8(o.stdout).unwrap()).len(), want.len());
}

#[test]
fn outputs_never_replace_inputs_or_each_other() {
    let (_, geo, wav) = scene();
    let dir = tmp_dir("noclobber");
    let rec = dir.join("in.wav");
    std::fs::copy(&wav, &rec).unwrap();
    let link = dir.join("link.wav");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(&rec, &link).unwrap();
    let (rec_bytes, geo_bytes) = (std::fs::read(&rec).unwrap(), std::fs::read(&geo).unwrap());
    let out = dir.join("out.jsonl");
    let side_dir = dir.join("spec.npy.json");
    std::fs::create_dir_all(&side_dir).unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    for (flags, want) in [
        (vec!["-o".to_string(), s(&rec)], "would overwrite the input"),
        (
            vec!["--log-xml".to_string(), s(&link)],
            "would overwrite the input",
        ),
        (
            vec!["--spectrum".to_string(), s(&geo)],
            "would overwrite the input",
        ),
        (
            vec!["-o".to_string(), s(&out), "--log-xml".to_string(), s(&out)],
            "name the same file",
        ),
        (
            vec!["--spectrum".to_string(), s(&dir.join("spec.npy"))],
            "is a directory",
        ),
        (
            vec!["--plot".to_string(), "/dev/null".to_string()],
            "--plot (an image written by name): not a regular file",
        ),
        (
            vec!["--spectrum".to_string(), "/dev/null".to_string()],
            "not a regular file (a pipe or device)",
        ),
    ] {
        let o = bin()
            .arg("localize")
            .arg(&rec)
            .arg("--geometry")
            .arg(&geo)
            .args(OPTS)
            .args(&flags)
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flags:?}: {e}");
        assert!(e.contains(want), "{flags:?}: {e}");
        assert!(o.stdout.is_empty(), "{flags:?}: no work before the error");
    }
    assert!(!out.exists() && !dir.join("spec.npy").exists());
    assert_eq!(std::fs::read(&rec).unwrap(), rec_bytes);
    assert_eq!(std::fs::read(&geo).unwrap(), geo_bytes);
    // batch: a result named like one of the recordings, and tf make over its geometry.
    let bdir = dir.join("b");
    std::fs::create_dir_all(&bdir).unwrap();
    let named = bdir.join("a.jsonl");
    std::fs::copy(&wav, &named).unwrap();
    let o = bin()
        .args(["batch", "--overwrite", "--out-dir"])
        .arg(&bdir)
        .arg(&named)
        .arg("--geometry")
        .arg(&geo)
        .args(OPTS)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("would overwrite the input"), "{e}");
    assert_eq!(std::fs::read(&named).unwrap(), rec_bytes);
    let o = bin()
        .args(["tf", "make", "--grid", "ring:5", "--geometry"])
        .arg(&geo)
        .arg("-o")
        .arg(&geo)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(&geo).unwrap(), geo_bytes);
}

#[test]
fn outputs_never_replace_a_noise_cm_pair() {
    let (audio, geo, wav) = scene();
    let dir = tmp_dir("noclobber-cm");
    // K from the first second, written as a text pair K_r / K_i.
    let o = bin()
        .args(["noisecm", "make"])
        .arg(&wav)
        .args(["--range", "0:1", "--format", "text", "-o"])
        .arg(dir.join("K"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(audio.num_channels() == 8);
    let imag = std::fs::read(dir.join("K_i")).unwrap();
    for cm in [dir.join("K_r"), dir.join("K")] {
        let o = bin()
            .arg("localize")
            .arg(&wav)
            .arg("--geometry")
            .arg(&geo)
            .arg("--noise-cm")
            .arg(&cm)
            .args(OPTS)
            .arg("--log-text")
            .arg(dir.join("K_i"))
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{cm:?}: {e}");
        assert!(e.contains("would overwrite the input"), "{cm:?}: {e}");
    }
    assert_eq!(std::fs::read(dir.join("K_i")).unwrap(), imag);
}

/// A read-only output file is refused, not replaced by the rename that writes outputs
/// (`tf make` replaced a `chmod 444` TF zip, as root or not).
#[test]
fn read_only_outputs_are_not_replaced() {
    let (_, geo, wav) = scene();
    let dir = tmp_dir("read-only-out");
    let zip = dir.join("tf.zip");
    let csv = dir.join("out.csv");
    for f in [&zip, &csv] {
        std::fs::write(f, b"keep me").unwrap();
        let mut perm = std::fs::metadata(f).unwrap().permissions();
        perm.set_readonly(true);
        std::fs::set_permissions(f, perm).unwrap();
    }
    let tf = bin()
        .args(["tf", "make", "--geometry"])
        .arg(&geo)
        .args(["--grid", "ring:5", "-o"])
        .arg(&zip)
        .output()
        .unwrap();
    let loc = bin()
        .arg("localize")
        .arg(&wav)
        .arg("--geometry")
        .arg(&geo)
        .args(OPTS)
        .arg("-o")
        .arg(&csv)
        .output()
        .unwrap();
    for (o, f) in [(tf, &zip), (loc, &csv)] {
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{f:?}: {e}");
        assert!(
            e.contains("read-only") && e.contains(&*f.to_string_lossy()),
            "{e}"
        );
        assert!(!e.contains("panicked"), "{e}");
        assert_eq!(std::fs::read(f).unwrap(), b"keep me");
    }
}

/// `-o -` is stdout, as without `-o` (also with the recording on stdin); "-" for any
/// other output is refused, not written as a file named "-".
#[test]
fn dash_output_is_stdout_and_other_dash_outputs_are_refused() {
    let (_, geo, wav) = scene();
    let dir = tmp_dir("dash-out");
    let run = |extra: &[&str]| {
        bin()
            .current_dir(&dir)
            .arg("localize")
            .arg(&wav)
            .arg("--geometry")
            .arg(&geo)
            .args(OPTS)
            .args(extra)
            .output()
            .unwrap()
    };
    let plain = run(&[]);
    assert!(plain.status.success());
    assert!(!plain.stdout.is_empty());
    let dash = run(&["-o", "-"]);
    assert!(dash.status.success(), "{}", String::from_utf8_lossy(&dash.stderr));
    assert_eq!(dash.stdout, plain.stdout);
    let mut child = spawn_piped(
        bin()
            .current_dir(&dir)
            .args(["localize", "-", "--geometry"])
            .arg(&geo)
            .args(OPTS)
            .args(["-o", "-"]),
    );
    child
        .stdin
        .take()
        .unwrap()
        .write_all(&std::fs::read(&wav).unwrap())
        .unwrap();
    let piped = child.wait_with_output().unwrap();
    assert!(
        piped.status.success(),
        "{}",
        String::from_utf8_lossy(&piped.stderr)
    );
    assert_eq!(piped.stdout, plain.stdout);
    for flag in ["--log-text", "--odas-ssl", "--spectrum"] {
        let o = run(&[flag, "-"]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flag}: {e}");
        assert!(e.contains("\"-\" names no file here"), "{flag}: {e}");
    }
    assert!(!dir.join("-").exists());
}
