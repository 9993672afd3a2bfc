//! CLI tests for the HARK file commands: `soundloc tf inspect|make`, `soundloc noisecm
//! make|inspect`, and a made TF zip plus noise matrix read back by `soundloc localize`.
//! They run the built binary.

use soundloc::audio::{Audio, SampleFormat};
use soundloc::formats::noise_cm::{Expected, NoiseCm};
use soundloc::WindowFunction;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_soundloc");
const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data");

/// Run the binary; (exit code, stdout, stderr).
fn run(args: &[&str]) -> (i32, String, String) {
    let Output {
        status,
        stdout,
        stderr,
    } = Command::new(BIN).args(args).output().expect("run soundloc");
    let (out, err) = (
        String::from_utf8_lossy(&stdout).into_owned(),
        String::from_utf8_lossy(&stderr).into_owned(),
    );
    assert!(!err.contains("panicked"), "soundloc {args:?} panicked:\n{err}");
    (status.code().unwrap_or(-1), out, err)
}

/// Run and require success; stdout.
fn ok(args: &[&str]) -> String {
    let (code, out, err) = run(args);
    assert_eq!(code, 0, "soundloc {args:?} failed:\n{err}\n{out}");
    out
}

/// Run and require failure; stderr.
fn fails(args: &[&str]) -> String {
    let (code, out, err) = run(args);
    assert_ne!(code, 0, "soundloc {args:?} succeeded:\n{out}");
    err
}

/// A fresh temporary folder for one test.
fn tmp(test: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("soundloc-cli-hark-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The shared HARK files, or None after writing a SKIPPED line.
fn data(test: &str) -> Option<PathBuf> {
    let d = PathBuf::from(DATA);
    if d.is_dir() {
        Some(d)
    } else {
        let _ = writeln!(std::io::stderr(), "SKIPPED {test}: ../shared/data not found");
        None
    }
}

/// Every line fragment of `want` appears in `text`.
fn assert_mentions(text: &str, want: &[&str]) {
    for w in want {
        assert!(text.contains(w), "missing {w:?}:\n{text}");
    }
}

fn json(out: &str) -> serde_json::Value {
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("not JSON ({e}):\n{out}"))
}

/// Deterministic 4-channel noise WAV (int16 range), partly correlated across channels.
fn noise_wav(path: &Path, seconds: f64) -> Audio {
    let fs = 16000u32;
    let n = (seconds * fs as f64) as usize;
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut rnd = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 2000.0
    };
    let mut ch: Vec<Vec<f32>> = (0..4).map(|_| Vec::with_capacity(n)).collect();
    for _ in 0..n {
        let common = rnd();
        for c in ch.iter_mut() {
            c.push((0.5 * common + rnd()).round() as f32);
        }
    }
    let audio = Audio::new(fs, ch).unwrap();
    audio.write_wav(path, SampleFormat::Int16).unwrap();
    audio
}

#[test]
fn tf_make_then_inspect_round_trip() {
    let d = tmp("tfmake");
    let zip = d.join("c8.zip");
    let out = ok(&[
        "tf",
        "make",
        "--builtin",
        "circle8",
        "--grid",
        "ring:5",
        "-o",
        s(&zip),
    ]);
    assert!(out.contains("8 mics, 72 directions"), "{out}");
    let text = ok(&["tf", "inspect", s(&zip)]);
    assert_mentions(
        &text,
        &[
            "microphones      8",
            "directions       72 (ring)",
            "nfft             512",
            "bins             0..257",
        ],
    );
    let j = json(&ok(&["tf", "inspect", "--json", s(&zip)]));
    assert_eq!(
        (j["num_mics"].as_u64(), j["num_dirs"].as_u64()),
        (Some(8), Some(72))
    );
    assert_eq!(
        (j["nfft"].as_u64(), j["end_bin"].as_u64()),
        (Some(512), Some(257))
    );
    assert_eq!(j["grid_kind"], "ring");
    assert!((j["radius_max_m"].as_f64().unwrap() - 1.0).abs() < 1e-6);

    // Sphere array, sphere grid, other FFT size and rate, 2 m radius.
    let zip = d.join("s60.zip");
    ok(&[
        "tf",
        "make",
        "--builtin",
        "sphere60",
        "--grid",
        "sphere:100",
        "--radius",
        "2",
        "--fft-length",
        "256",
        "--sample-rate",
        "8000",
        "-o",
        s(&zip),
    ]);
    let j = json(&ok(&["tf", "inspect", "--json", s(&zip)]));
    assert_eq!(
        (j["num_mics"].as_u64(), j["num_dirs"].as_u64()),
        (Some(60), Some(100))
    );
    assert_eq!(
        (j["end_bin"].as_u64(), j["sample_rate_hz"].as_u64()),
        (Some(129), Some(8000))
    );
    assert!((j["radius_min_m"].as_f64().unwrap() - 2.0).abs() < 1e-6);

    // A geometry file, a ring above the array plane.
    let geo = d.join("square.toml");
    std::fs::write(
        &geo,
        "mics = [[0.05, 0, 0], [0, 0.05, 0], [-0.05, 0, 0], [0, -0.05, 0]]\n",
    )
    .unwrap();
    let zip = d.join("sq.zip");
    ok(&[
        "tf",
        "make",
        "--geometry",
        s(&geo),
        "--grid",
        "ring:90:10",
        "-o",
        s(&zip),
    ]);
    let j = json(&ok(&["tf", "inspect", "--json", s(&zip)]));
    assert_eq!(
        (j["num_mics"].as_u64(), j["num_dirs"].as_u64()),
        (Some(4), Some(4))
    );
    assert!((j["elevation_min_deg"].as_f64().unwrap() - 10.0).abs() < 1e-6);
    assert_eq!(j["mic_positions"][1][1].as_f64(), Some(0.05));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn tf_inspect_hark_files() {
    let Some(data) = data("tf_inspect_hark_files") else {
        return;
    };
    let rectf = data.join("tamago_rectf.zip");
    let text = ok(&["tf", "inspect", s(&rectf)]);
    assert!(
        text.contains("microphones      8") && text.contains("directions       72"),
        "{text}"
    );
    let j = json(&ok(&["tf", "inspect", "--json", s(&rectf)]));
    assert_eq!(
        (j["num_mics"].as_u64(), j["num_dirs"].as_u64()),
        (Some(8), Some(72))
    );
    assert_eq!(
        j["end_bin"]
            .as_u64()
            .map(|e| e - j["first_bin"].as_u64().unwrap()),
        Some(257)
    );
    let j = json(&ok(&["tf", "inspect", "--json", s(&data.join("kinect_loc.dat"))]));
    assert_eq!(
        (j["num_mics"].as_u64(), j["num_dirs"].as_u64()),
        (Some(4), Some(72))
    );
    assert_eq!(
        (j["nfft"].as_u64(), j["end_bin"].as_u64()),
        (Some(512), Some(257))
    );
}

/// `noisecm make`'s frames follow the recording's rate as `localize --geometry`'s and
/// `tf make`'s do (32 ms / 10 ms: 1536 / 480 at 48 kHz; it was 512 / 160 at any rate, so
/// a 48 kHz user's K did not fit the 48 kHz TFs), the summary names the rate, and the
/// input checks run: a dead channel is named, and the not-positive-definite warning
/// points at it.
#[test]
fn noisecm_make_frames_follow_the_rate_and_the_input_is_checked() {
    let d = tmp("cmrate");
    let wav16 = d.join("noise16.wav");
    let audio = noise_wav(&wav16, 1.0);
    let wav48 = d.join("noise48.wav");
    let mut dead = audio.channels.clone();
    dead[3].iter_mut().for_each(|v| *v = 0.0);
    Audio::new(48000, audio.channels.clone())
        .unwrap()
        .write_wav(&wav48, SampleFormat::Int16)
        .unwrap();
    let k48 = d.join("k48.zip");
    let out = ok(&["noisecm", "make", s(&wav48), "-o", s(&k48)]);
    assert!(out.contains("nfft 1536 at 48000 Hz"), "{out}");
    let cm = NoiseCm::load(&k48, Expected::default()).unwrap();
    assert_eq!((cm.nfft, cm.num_bins()), (1536, 769));
    let (want, frames) =
        NoiseCm::estimate(&audio.channels, 48000, 1536, 480, WindowFunction::Conj, None).unwrap();
    // The zip holds single precision (HARK's format).
    let top = want.data.iter().map(|z| z.norm()).fold(0.0, f64::max);
    let err = cm
        .data
        .iter()
        .zip(&want.data)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(
        cm.data.len() == want.data.len() && err < 1e-6 * top,
        "{err} of {top}"
    );
    assert!(out.contains(&format!("{frames} frames")), "{out}");
    let wav_dead = d.join("dead.wav");
    Audio::new(16000, dead)
        .unwrap()
        .write_wav(&wav_dead, SampleFormat::Int16)
        .unwrap();
    let (code, _, err) = run(&["noisecm", "make", s(&wav_dead), "-o", s(&d.join("kd.zip"))]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("input channel 3 (0-based) is constant"), "{err}");
    assert!(
        err.contains("not positive definite") && err.contains("see the channel warnings above"),
        "{err}"
    );
    // -o rec.wav wrote a text pair named rec_r.wav / rec_i.wav.
    let e = fails(&["noisecm", "make", s(&wav16), "-o", s(&d.join("rec.wav"))]);
    assert!(e.contains("-o names the noise matrix, not audio"), "{e}");
    assert!(!d.join("rec_r.wav").exists());
}

#[test]
fn noisecm_make_text_and_zip_load_back() {
    let d = tmp("cmmake");
    let wav = d.join("noise.wav");
    let audio = noise_wav(&wav, 1.0);

    // Text pair from `-o K`: K_r and K_i, every bin, the same numbers as the library.
    let out = ok(&["noisecm", "make", s(&wav), "-o", s(&d.join("K"))]);
    let (re, im) = (d.join("K_r"), d.join("K_i"));
    assert!(out.contains(s(&re)) && out.contains(s(&im)), "{out}");
    let cm = NoiseCm::load(
        &re,
        Expected {
            num_mics: Some(4),
            nfft: Some(512),
        },
    )
    .unwrap();
    assert_eq!((cm.num_mics, cm.num_bins()), (4, 257));
    let (want, frames) =
        NoiseCm::estimate(&audio.channels, 16000, 512, 160, WindowFunction::Conj, None).unwrap();
    assert_eq!(frames, (16000 - 512) / 160 + 1);
    assert!(out.contains(&format!("{frames} frames")), "{out}");
    assert_eq!(cm, want);

    // Zip, two channels, a range, another window and FFT size.
    let zip = d.join("k.zip");
    ok(&[
        "noisecm",
        "make",
        s(&wav),
        "-o",
        s(&zip),
        "--channels",
        "0,2",
        "--range",
        "0.25:0.75",
        "--fft-length",
        "256",
        "--hop",
        "128",
        "--window",
        "hamming",
    ]);
    let cm = NoiseCm::load(&zip, Expected::default()).unwrap();
    assert_eq!((cm.num_mics, cm.nfft, cm.num_bins()), (2, 256, 129));

    // --invert-channels: K of the audio with that input channel negated; -q: nothing on
    // stdout. An inverted channel that is not kept is named.
    let inv = d.join("Kinv");
    let out = ok(&[
        "noisecm",
        "make",
        s(&wav),
        "-o",
        s(&inv),
        "--invert-channels",
        "1",
        "-q",
    ]);
    assert!(out.is_empty(), "{out}");
    let mut negated = audio.channels.clone();
    negated[1].iter_mut().for_each(|v| *v = -*v);
    let (want, _) = NoiseCm::estimate(&negated, 16000, 512, 160, WindowFunction::Conj, None).unwrap();
    assert_eq!(
        NoiseCm::load(&d.join("Kinv_r"), Expected::default()).unwrap(),
        want
    );
    let e = fails(&[
        "noisecm",
        "make",
        s(&wav),
        "-o",
        s(&inv),
        "--channels",
        "0,2",
        "--invert-channels",
        "1",
    ]);
    assert!(
        e.contains("input channel 1 is to be inverted, but it feeds no microphone"),
        "{e}"
    );

    // Inspect both.
    let text = ok(&["noisecm", "inspect", s(&re)]);
    assert_mentions(
        &text,
        &[
            "microphones      4",
            "nfft             512",
            "bins             257",
            "not pos. def.    0 bin",
        ],
    );
    let j = json(&ok(&["noisecm", "inspect", "--json", s(&zip)]));
    assert_eq!(
        (j["num_mics"].as_u64(), j["num_bins"].as_u64()),
        (Some(2), Some(129))
    );
    assert_eq!(j["bins"].as_array().map(Vec::len), Some(129));
    let rows = ok(&["noisecm", "inspect", "--bins", s(&zip)]);
    assert!(rows.lines().count() >= 129, "{rows}");
    let _ = std::fs::remove_dir_all(&d);
}

/// A drone scene (talkers at 30° and −120° from 1 s on, rotors throughout): a TF zip and a
/// noise matrix made by the CLI, read back by `soundloc localize` with GEVD.
#[test]
fn localize_reads_made_tf_and_noise_cm() {
    let d = tmp("e2e");
    let scene = soundloc::demo::ring8_drone(-5.0, 2).unwrap();
    let wav = d.join("drone.wav");
    scene.render().write_wav(&wav, SampleFormat::Float32).unwrap();
    let zip = d.join("c8.zip");
    ok(&[
        "tf",
        "make",
        "--builtin",
        "circle8",
        "--grid",
        "ring:5",
        "-o",
        s(&zip),
    ]);
    ok(&[
        "noisecm",
        "make",
        s(&wav),
        "--range",
        "0:1",
        "-o",
        s(&d.join("K")),
    ]);
    let jsonl = d.join("out.jsonl");
    ok(&[
        "localize",
        s(&wav),
        "--tf",
        s(&zip),
        "--noise-cm",
        s(&d.join("K_r")),
        "--algorithm",
        "gevd",
        "--device",
        "cpu",
        "--format",
        "jsonl",
        "-o",
        s(&jsonl),
    ]);
    let text = std::fs::read_to_string(&jsonl).unwrap();
    let (mut windows, mut hits) = (0, 0);
    for line in text.lines() {
        let r = json(line);
        if r["time_s"].as_f64().unwrap() < 1.0 {
            continue;
        }
        windows += 1;
        let az: Vec<f64> = r["sources"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|s| s["azimuth_deg"].as_f64())
            .collect();
        for want in [30.0, -120.0] {
            if az.iter().any(|a| (a - want).abs() <= 5.0) {
                hits += 1;
            }
        }
    }
    assert!(windows >= 3, "{text}");
    assert_eq!(hits, 2 * windows, "{text}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn bad_inputs_fail_with_a_message_naming_the_file() {
    let d = tmp("bad");
    let missing = d.join("missing.zip");
    let e = fails(&["tf", "inspect", s(&missing)]);
    assert!(e.contains("missing.zip"), "{e}");

    let corrupt = d.join("corrupt.zip");
    std::fs::write(&corrupt, b"PK\x03\x04 this is not really a zip").unwrap();
    let e = fails(&["tf", "inspect", s(&corrupt)]);
    assert!(e.contains("corrupt.zip") && e.contains("zip"), "{e}");
    let e = fails(&["noisecm", "inspect", s(&corrupt)]);
    assert!(e.contains("corrupt.zip"), "{e}");

    let wav = d.join("noise.wav");
    noise_wav(&wav, 0.5);
    let e = fails(&["tf", "inspect", s(&wav)]);
    assert!(
        e.contains("noise.wav") && e.contains("not a HARK transfer-function"),
        "{e}"
    );

    // A TF zip is not a noise matrix, and a lone text file has no imaginary part.
    let zip = d.join("c8.zip");
    ok(&[
        "tf",
        "make",
        "--builtin",
        "circle8",
        "--grid",
        "ring:30",
        "-o",
        s(&zip),
    ]);
    let e = fails(&["noisecm", "inspect", s(&zip)]);
    assert!(e.contains("c8.zip"), "{e}");
    let lone = d.join("lone_r.dat");
    std::fs::write(&lone, "1 0 0 1\n1 0 0 1\n").unwrap();
    let e = fails(&["noisecm", "inspect", s(&lone)]);
    assert!(e.contains("lone_r.dat") && e.contains("imaginary"), "{e}");

    // tf make: bad grid, missing geometry, no array, no grid.
    let out = d.join("x.zip");
    let e = fails(&[
        "tf",
        "make",
        "--builtin",
        "circle8",
        "--grid",
        "ring:7",
        "-o",
        s(&out),
    ]);
    assert!(e.contains("ring:7") && e.contains("divide 360"), "{e}");
    let e = fails(&[
        "tf",
        "make",
        "--geometry",
        s(&d.join("nope.toml")),
        "--grid",
        "ring:5",
        "-o",
        s(&out),
    ]);
    assert!(e.contains("nope.toml"), "{e}");
    fails(&["tf", "make", "--grid", "ring:5", "-o", s(&out)]);
    fails(&["tf", "make", "--builtin", "circle8", "-o", s(&out)]);
    let e = fails(&[
        "tf",
        "make",
        "--builtin",
        "circle8",
        "--grid",
        "ring:5",
        "--radius",
        "0",
        "-o",
        s(&out),
    ]);
    assert!(e.contains("--grid-radius"), "{e}");
    assert!(!out.exists());
    // Outputs that cannot be files: a folder, a file in a missing folder (both commands).
    for args in [
        &["tf", "make", "--builtin", "circle8", "--grid", "ring:5", "-o"][..],
        &["noisecm", "make", s(&wav), "-o"][..],
    ] {
        let e = fails(&[args, &[s(&d)]].concat());
        assert!(e.contains("-o: is a directory"), "{e}");
        let e = fails(&[args, &[s(&d.join("nodir").join("K.zip"))]].concat());
        assert!(e.contains("nodir does not exist"), "{e}");
    }

    // noisecm make: missing input, range past the end, bad range, bad channel.
    let e = fails(&["noisecm", "make", s(&d.join("none.wav")), "-o", s(&d.join("K"))]);
    assert!(e.contains("none.wav"), "{e}");
    let e = fails(&[
        "noisecm",
        "make",
        s(&wav),
        "--range",
        "10:11",
        "-o",
        s(&d.join("K")),
    ]);
    assert!(e.contains("noise.wav") && e.contains("after the end"), "{e}");
    let e = fails(&[
        "noisecm",
        "make",
        s(&wav),
        "--range",
        "2:1",
        "-o",
        s(&d.join("K")),
    ]);
    assert!(e.contains("START:END"), "{e}");
    let e = fails(&[
        "noisecm",
        "make",
        s(&wav),
        "--channels",
        "0,7",
        "-o",
        s(&d.join("K")),
    ]);
    assert!(e.contains("noise.wav") && e.contains("channel 7"), "{e}");
    assert!(!d.join("K_r").exists());
    let _ = std::fs::remove_dir_all(&d);
}

/// SIGTERM while `tf make` writes its zip: the process dies of the signal (as it would
/// without a handler), having deleted its temporary file; the file it was replacing keeps
/// its old content.
#[cfg(unix)]
#[test]
fn a_terminated_write_leaves_no_temporary_file_and_the_old_target() {
    let d = tmp("sigterm");
    let out = d.join("big.zip");
    std::fs::write(&out, b"old content").unwrap();
    let temps = || -> Vec<String> {
        std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".big.zip."))
            .collect()
    };
    // A few tries: the write (~60 MB, over a second here) must still be running when the
    // signal comes.
    for grid in ["sphere:2000", "sphere:8000"] {
        let mut child = Command::new(BIN)
            .args([
                "tf",
                "make",
                "--builtin",
                "circle8",
                "--grid",
                grid,
                "-o",
                s(&out),
            ])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let start = std::time::Instant::now();
        while temps().is_empty() && child.try_wait().unwrap().is_none() && start.elapsed().as_secs() < 60 {
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        if child.try_wait().unwrap().is_some() {
            std::fs::write(&out, b"old content").unwrap();
            continue;
        }
        let killed = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let status = child.wait().unwrap();
        if status.success() {
            // It finished before the signal arrived: try a larger grid.
            std::fs::write(&out, b"old content").unwrap();
            continue;
        }
        use std::os::unix::process::ExitStatusExt;
        assert_eq!(status.signal(), Some(libc::SIGTERM), "{status:?}");
        assert!(temps().is_empty(), "{:?}", temps());
        assert_eq!(std::fs::read(&out).unwrap(), b"old content");
        // A signal its parent set to be ignored (nohup) stays ignored: the write finishes.
        let mut child = Command::new("sh")
            .arg("-c")
            .arg(format!(
                "trap '' HUP; exec '{BIN}' tf make --builtin circle8 --grid sphere:500 -o '{}'",
                s(&out)
            ))
            .stdout(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let start = std::time::Instant::now();
        while temps().is_empty() && child.try_wait().unwrap().is_none() && start.elapsed().as_secs() < 60 {
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        let _ = Command::new("kill")
            .args(["-HUP", &child.id().to_string()])
            .status();
        assert!(child.wait().unwrap().success());
        assert!(std::fs::read(&out).unwrap().starts_with(b"PK"));
        return;
    }
    println!("SKIPPED a_terminated_write_leaves_no_temporary_file_and_the_old_target: every write finished before the signal");
}
