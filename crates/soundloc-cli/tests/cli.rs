//! The `soundloc` binary end to end: the real recording, the demo, and bad input (clear
//! error naming the problem, non-zero exit, no panic, nothing half-written).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_soundloc"))
}

fn data() -> Option<PathBuf> {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data"));
    p.join("jinsei.wav").exists().then_some(p)
}

fn skipped(test: &str) {
    let _ = writeln!(std::io::stderr(), "SKIPPED {test}: ../shared/data not found");
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("soundloc-cli-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// `soundloc localize INPUT --tf <data>/tamago_rectf.zip EXTRA...`.
/// `soundloc localize INPUT --tf d/TF EXTRA…`.
fn localize_tf(d: &Path, input: &Path, tf: &str, extra: &[&str]) -> Output {
    bin()
        .arg("localize")
        .arg(input)
        .arg("--tf")
        .arg(d.join(tf))
        .args(extra)
        .output()
        .unwrap()
}

fn localize_rectf(d: &Path, input: &Path, extra: &[&str]) -> Output {
    localize_tf(d, input, "tamago_rectf.zip", extra)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Fails with a clear message, exit code 2, no panic.
fn assert_clean_failure(o: &Output, must_contain: &[&str]) {
    let e = stderr(o);
    assert!(!o.status.success(), "expected failure, got success; stderr: {e}");
    assert_eq!(o.status.code(), Some(2), "stderr: {e}");
    assert!(!e.contains("panicked"), "panic: {e}");
    for s in must_contain {
        assert!(e.contains(s), "stderr should mention {s:?}: {e}");
    }
}

/// Write a WAV (int16) with `channels` channels of `secs` seconds of a deterministic signal.
fn write_wav(path: &Path, channels: u16, rate: u32, secs: f64, nan: bool) {
    let n = (secs * rate as f64) as usize;
    if nan {
        let spec = hound::WavSpec {
            channels,
            sample_rate: rate,
            bits_per_sample: 32,
            sample_format: hound::SampleFormat::Float,
        };
        let mut w = hound::WavWriter::create(path, spec).unwrap();
        for i in 0..n {
            for c in 0..channels {
                let v = if i == 5000 && c == 1 {
                    f32::NAN
                } else {
                    ((i * (c as usize + 1)) as f32 * 0.01).sin()
                };
                w.write_sample(v).unwrap();
            }
        }
        w.finalize().unwrap();
    } else {
        let spec = hound::WavSpec {
            channels,
            sample_rate: rate,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        let mut w = hound::WavWriter::create(path, spec).unwrap();
        let mut s: u32 = 12345;
        for _ in 0..n {
            for _ in 0..channels {
                s = s.wrapping_mul(1103515245).wrapping_add(12345);
                w.write_sample(((s >> 16) as i16) / 8).unwrap();
            }
        }
        w.finalize().unwrap();
    }
}

#[test]
fn jinsei_with_measured_tf_finds_one_dominant_talker() {
    let Some(d) = data() else {
        return skipped("jinsei_with_measured_tf_finds_one_dominant_talker");
    };
    let jinsei = d.join("jinsei.wav");
    let base = ["--num-sources", "1", "--period", "10", "-q", "--device", "cpu"];
    let o = localize_rectf(&d, &jinsei, &base);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    let az: Vec<f64> = text
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            v["sources"][0]["azimuth_deg"].as_f64().unwrap()
        })
        .collect();
    // 1.28 s → 112 frames → windows at c = 0, 10, …, 60 (FUTURE, W = 50): 7 or more results.
    assert!(az.len() >= 7, "{} results", az.len());
    let (s, c) = az.iter().fold((0.0, 0.0), |(s, c), a| {
        (s + a.to_radians().sin(), c + a.to_radians().cos())
    });
    let mean = s.atan2(c).to_degrees();
    for a in &az {
        let d = ((a - mean + 540.0) % 360.0 - 180.0).abs();
        assert!(d <= 15.0, "azimuth {a} is {d}° from the mean {mean} of {az:?}");
    }
    // The talker is in front of the array (between -10° and 30°), with the geometric TF too.
    assert!((-10.0..=30.0).contains(&mean), "mean azimuth {mean}");
    let o = localize_tf(
        &d,
        &jinsei,
        "tamago_geotf.zip",
        &[&base[..], &["--format", "csv"]].concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    let mut lines = text.lines();
    assert!(lines.next().unwrap().starts_with("frame,time_s,rank"));
    // Rows of windows without sources (empty rank) hold no direction.
    for l in lines.filter(|l| l.split(',').nth(2) != Some("")) {
        let az: f64 = l.split(',').nth(4).unwrap().parse().unwrap();
        let d = ((az - mean + 540.0) % 360.0 - 180.0).abs();
        assert!(d <= 20.0, "geometric TF: azimuth {az} vs measured-TF mean {mean}");
    }
}

#[test]
fn spectrum_and_plot_files_are_written() {
    let Some(d) = data() else {
        return skipped("spectrum_and_plot_files_are_written");
    };
    let (npy, png, out) = (tmp("spec.npy"), tmp("plot.png"), tmp("res.jsonl"));
    let o = bin()
        .args(["localize", "-q", "--device", "cpu"])
        .arg(d.join("jinsei.wav"))
        .arg("--tf")
        .arg(d.join("tamago_rectf.zip"))
        .arg("--spectrum")
        .arg(&npy)
        .arg("--plot")
        .arg(&png)
        .arg("--output")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stdout.is_empty(), "results went to --output, not stdout");
    let spec = soundloc::output::npy::read_npy_f32_file(&npy).unwrap();
    let results = soundloc::output::jsonl::read_jsonl_file(&out).unwrap();
    assert_eq!(spec.rows, results.len());
    assert_eq!(spec.cols, 72);
    // The reported power is the spectrum's value at the reported direction.
    for (i, r) in results.iter().enumerate() {
        let s = &r.sources[0];
        assert!((spec.data[i * 72 + s.grid_index] as f64 - s.power_db).abs() < 1e-3);
    }
    assert!(std::fs::metadata(&png).unwrap().len() > 1000);
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(format!("{}.json", npy.display())).unwrap()).unwrap();
    assert_eq!(meta["azimuth_deg"].as_array().unwrap().len(), 72);
    // The room default's scale is named as it ran, not as the SEVD it is built on.
    let label = meta["analysis"].as_str().unwrap();
    assert!(
        label.starts_with("normmusic (") && label.contains("coherence"),
        "{meta}"
    );
    assert!(meta["description"].as_str().unwrap().contains(label), "{meta}");
}

#[test]
fn demo_runs_without_files() {
    let dir = tmp("demo");
    let o = bin()
        .args(["demo", "--scene", "ring8", "--device", "cpu", "--out-dir"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("gevd       found 100%"), "{text}");
    assert!(text.contains("true talkers: 30/0  -120/0"), "{text}");
    let plot = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("plot: "))
        .expect("a plot path on stdout");
    assert!(Path::new(plot).exists());
}

#[test]
fn wrong_channel_count_for_the_tf() {
    let Some(d) = data() else {
        return skipped("wrong_channel_count_for_the_tf");
    };
    let w = tmp("four.wav");
    write_wav(&w, 4, 16000, 1.0, false);
    let o = localize_rectf(&d, &w, &[]);
    assert_clean_failure(&o, &["4 channels", "8 microphones"]);
}

#[test]
fn sample_rate_mismatch() {
    let Some(d) = data() else {
        return skipped("sample_rate_mismatch");
    };
    let w = tmp("rate.wav");
    write_wav(&w, 8, 48000, 1.0, false);
    let o = localize_rectf(&d, &w, &[]);
    assert_clean_failure(&o, &["48000 Hz", "16000 Hz"]);
}

#[test]
fn empty_and_too_short_files() {
    let Some(d) = data() else {
        return skipped("empty_and_too_short_files");
    };
    let empty = tmp("empty.wav");
    std::fs::write(&empty, b"").unwrap();
    let o = localize_rectf(&d, &empty, &[]);
    assert_clean_failure(&o, &["empty.wav"]);
    let short = tmp("short.wav");
    write_wav(&short, 8, 16000, 0.2, false);
    let o = localize_rectf(&d, &short, &[]);
    assert_clean_failure(&o, &["needs at least"]);
}

#[test]
fn nan_samples() {
    let Some(d) = data() else {
        return skipped("nan_samples");
    };
    let w = tmp("nan.wav");
    write_wav(&w, 8, 16000, 1.0, true);
    let o = localize_rectf(&d, &w, &[]);
    assert_clean_failure(&o, &["nan.wav", "NaN"]);
}

#[test]
fn num_sources_must_be_below_the_mic_count() {
    let Some(d) = data() else {
        return skipped("num_sources_must_be_below_the_mic_count");
    };
    let o = bin()
        .args(["localize", "--num-sources", "8"])
        .arg(d.join("jinsei.wav"))
        .arg("--tf")
        .arg(d.join("tamago_rectf.zip"))
        .output()
        .unwrap();
    assert_clean_failure(&o, &["num-sources", "8 microphones"]);
}

#[test]
fn truncated_or_corrupt_zip() {
    let Some(d) = data() else {
        return skipped("truncated_or_corrupt_zip");
    };
    let bytes = std::fs::read(d.join("tamago_rectf.zip")).unwrap();
    let trunc = tmp("trunc.zip");
    std::fs::write(&trunc, &bytes[..bytes.len() / 3]).unwrap();
    let o = bin()
        .arg("localize")
        .arg(d.join("jinsei.wav"))
        .arg("--tf")
        .arg(&trunc)
        .output()
        .unwrap();
    assert_clean_failure(&o, &["trunc.zip"]);
    let junk = tmp("junk.zip");
    std::fs::write(&junk, b"this is not a zip file at all, sorry").unwrap();
    let o = bin()
        .arg("localize")
        .arg(d.join("jinsei.wav"))
        .arg("--tf")
        .arg(&junk)
        .output()
        .unwrap();
    assert_clean_failure(&o, &["junk.zip"]);
}

#[test]
fn unreadable_paths() {
    let o = bin()
        .args(["localize", "/nonexistent/rec.wav", "--tf", "/nonexistent/tf.zip"])
        .output()
        .unwrap();
    assert_clean_failure(&o, &["/nonexistent/rec.wav"]);
    let Some(d) = data() else {
        return skipped("unreadable_paths");
    };
    let o = bin()
        .arg("localize")
        .arg(d.join("jinsei.wav"))
        .args(["--tf", "/nonexistent/tf.zip"])
        .output()
        .unwrap();
    assert_clean_failure(&o, &["/nonexistent/tf.zip"]);
}

#[test]
fn failed_run_leaves_no_output_file() {
    let Some(d) = data() else {
        return skipped("failed_run_leaves_no_output_file");
    };
    let out = tmp("never.jsonl");
    let _ = std::fs::remove_file(&out);
    let o = bin()
        .args(["localize", "--num-sources", "9"])
        .arg(d.join("jinsei.wav"))
        .arg("--tf")
        .arg(d.join("tamago_rectf.zip"))
        .arg("--output")
        .arg(&out)
        .output()
        .unwrap();
    assert_clean_failure(&o, &[]);
    assert!(!out.exists());
    let leftovers: Vec<_> = std::fs::read_dir(out.parent().unwrap())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("never"))
        .collect();
    assert!(leftovers.is_empty(), "temp files left: {leftovers:?}");
}

/// Sizes the benchmark cannot build, and counts of zero, are refused before any work
/// (they aborted on a failed allocation, or printed NaN figures).
#[test]
fn bench_refuses_sizes_it_cannot_build() {
    for (args, want) in [
        (
            vec!["--mics", "100000"],
            "--mics 100000: must be between 2 and 1024",
        ),
        (vec!["--mics", "1"], "--mics 1: must be between 2 and 1024"),
        (vec!["--accuracy", "--scenes", "0"], "--scenes 0: give at least 1"),
        (
            vec!["--directions", "1000000"],
            "--directions 1000000: must be between 2",
        ),
        (
            vec!["--mics", "1024", "--directions", "100000"],
            "more than this benchmark builds",
        ),
        (vec!["--stream", "--seconds", "nan"], "--seconds NaN"),
        (vec!["--stream", "--streams", "0"], "--streams 0"),
        (vec!["--batch", "0"], "--batch 0"),
        (vec!["--repeats", "0"], "--repeats 0"),
        // Options of another mode are refused, not ignored (the kernel benchmark printed
        // its usual table for --period 5 or --array ring4 until 2026-12-02).
        (vec!["--period", "5"], "--stream"),
        (vec!["--seconds", "2"], "--stream"),
        (vec!["--scenes", "1"], "--accuracy"),
        (vec!["--array", "ring4"], "--stream"),
        // ... also beside another mode (clap's `requires` let these through).
        (vec!["--stream", "--scenes", "1"], "--scenes"),
        (vec!["--stream", "--split", "tune"], "--split"),
        (vec!["--accuracy", "--seconds", "2"], "--seconds"),
        (vec!["--accuracy", "--streams", "2"], "--streams"),
    ] {
        let o = bin().arg("bench").args(&args).output().unwrap();
        assert_clean_failure(&o, &[want]);
    }
}

#[test]
fn demo_refuses_an_snr_it_cannot_render() {
    for snr in ["200", "nan", "-1e6"] {
        let o = bin().args(["demo", "--snr", snr]).output().unwrap();
        assert_clean_failure(&o, &["--snr", "between -60 and 60 dB"]);
    }
}

/// An input that ends before its first byte (an empty pipe, a peer that hangs up at
/// once) says so, rather than calling itself an empty file.
#[test]
fn an_empty_stream_says_no_data() {
    let geo = tmp("empty-stream.toml");
    std::fs::write(
        &geo,
        "mics = [[0.05, 0, 0], [-0.05, 0, 0], [0, 0.05, 0], [0, -0.05, 0]]\n",
    )
    .unwrap();
    let o = bin()
        .args(["localize", "-", "--grid", "ring:5", "--geometry"])
        .arg(&geo)
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap();
    assert_clean_failure(&o, &["no data: the input ended before its first byte"]);
}

#[test]
fn cuda_without_a_gpu_is_a_clear_error() {
    let o = bin()
        .args([
            "bench",
            "--device",
            "cuda",
            "--mics",
            "8",
            "--directions",
            "72",
            "--repeats",
            "1",
            "--batch",
            "1",
        ])
        .output()
        .unwrap();
    if o.status.success() {
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED cuda_without_a_gpu_is_a_clear_error: a usable GPU is present"
        );
        return;
    }
    assert_clean_failure(&o, &["device"]);
}

/// The drone scene written to a WAV, a geometric TF zip from `tf make`, then `localize`
/// with K from a time range and from online segments: the textbook GEVD (the default when
/// noise is given) finds both talkers in every window after they start.
#[test]
fn noisy_recording_with_noise_range_and_online_segments() {
    let scene = soundloc::demo::ring8_drone(-10.0, 1).unwrap();
    let wav = tmp("drone.wav");
    scene
        .render()
        .write_wav(&wav, soundloc::audio::SampleFormat::Float32)
        .unwrap();
    let zip = tmp("circle8.zip");
    let o = bin()
        .args([
            "tf",
            "make",
            "--builtin",
            "circle8",
            "--grid",
            "ring:5",
            "-q",
            "-o",
        ])
        .arg(&zip)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(o.stdout.is_empty(), "-q: no summary");
    for noise in [["--noise-range", "0:1"], ["--noise-segments", "0:1"]] {
        let o = bin()
            .arg("localize")
            .arg(&wav)
            .arg("--tf")
            .arg(&zip)
            .args(noise)
            .args(["--device", "cpu"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stderr(&o).contains("textbook GEVD"), "{}", stderr(&o));
        let results = soundloc::output::jsonl::read_jsonl(&o.stdout[..], Path::new("stdout")).unwrap();
        let after: Vec<_> = results.iter().filter(|r| r.time_s >= 1.0).collect();
        assert!(after.len() >= 3);
        for r in after {
            let mut az: Vec<i64> = r.sources.iter().map(|s| s.azimuth_deg.round() as i64).collect();
            az.sort();
            assert_eq!(az, vec![-120, 30], "{noise:?} at {} s: {az:?}", r.time_s);
        }
    }
}

/// A dead microphone in the drone scene makes K singular: the error names it (exit 2), and
/// leaving it out with --channels finds both talkers with the other seven.
#[test]
fn a_dead_microphone_is_named_and_can_be_left_out() {
    let scene = soundloc::demo::ring8_drone(-10.0, 1).unwrap();
    let mut audio = scene.render();
    audio.channels[5].fill(0.0);
    let wav = tmp("dead5.wav");
    audio
        .write_wav(&wav, soundloc::audio::SampleFormat::Float32)
        .unwrap();
    let geo = tmp("dead5-ring8.toml");
    std::fs::write(&geo, scene.geometry.to_toml_string()).unwrap();
    let run = |extra: &[&str]| {
        bin()
            .arg("localize")
            .arg(&wav)
            .arg("--geometry")
            .arg(&geo)
            .args(["--grid", "ring:5", "--noise-range", "0:1", "--device", "cpu"])
            .args(extra)
            .output()
            .unwrap()
    };
    assert_clean_failure(
        &run(&[]),
        &["channel 5 (0-based, of those in use) is silent", "--channels"],
    );
    let o = run(&["--channels", "0,1,2,3,4,6,7"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let results = soundloc::output::jsonl::read_jsonl(&o.stdout[..], Path::new("stdout")).unwrap();
    let after: Vec<_> = results.iter().filter(|r| r.time_s >= 1.0).collect();
    assert!(after.len() >= 3);
    for r in after {
        for talker in [-120.0, 30.0] {
            let near = r
                .sources
                .iter()
                .map(|s| (s.azimuth_deg - talker).abs())
                .fold(f64::MAX, f64::min);
            assert!(near <= 5.0, "talker {talker}° at {} s: {:?}", r.time_s, r.sources);
        }
    }
}

#[test]
fn input_channel_selector_drops_extra_channels() {
    let Some(d) = data() else {
        return skipped("input_channel_selector_drops_extra_channels");
    };
    // A 9-channel file: the 8 array channels of jinsei.wav plus a silent reference channel.
    let a = soundloc::audio::read_audio(d.join("jinsei.wav")).unwrap();
    let mut ch = a.channels.clone();
    ch.insert(0, vec![0.0; a.num_samples()]);
    let nine = soundloc::audio::Audio::new(a.sample_rate_hz, ch).unwrap();
    let w = tmp("nine.wav");
    nine.write_wav(&w, soundloc::audio::SampleFormat::Int16).unwrap();
    let tf = d.join("tamago_rectf.zip");
    let o = bin()
        .arg("localize")
        .arg(&w)
        .arg("--tf")
        .arg(&tf)
        .output()
        .unwrap();
    assert_clean_failure(&o, &["9 channels"]);
    let o = bin()
        .arg("localize")
        .arg(&w)
        .arg("--tf")
        .arg(&tf)
        .args(["--input-channels", "1,2,3,4,5,6,7,8", "-q", "--device", "cpu"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let direct = bin()
        .arg("localize")
        .arg(d.join("jinsei.wav"))
        .arg("--tf")
        .arg(&tf)
        .args(["-q", "--device", "cpu"])
        .output()
        .unwrap();
    assert_eq!(
        o.stdout, direct.stdout,
        "selected channels must give the original file's results"
    );
}

/// A recording with one channel's sign flipped: the input checks name it and the option
/// they name (`--invert-channels`) gives the original file's results, with the flipped
/// file as its own noise recording too.
#[test]
fn invert_channels_undoes_a_flipped_channel() {
    let Some(d) = data() else {
        return skipped("invert_channels_undoes_a_flipped_channel");
    };
    let a = soundloc::audio::read_audio(d.join("jinsei.wav")).unwrap();
    let mut ch = a.channels.clone();
    ch[5].iter_mut().for_each(|v| *v = -*v);
    let flipped = tmp("flipped.wav");
    soundloc::audio::Audio::new(a.sample_rate_hz, ch)
        .unwrap()
        .write_wav(&flipped, soundloc::audio::SampleFormat::Int16)
        .unwrap();
    let tf = d.join("tamago_rectf.zip");
    let run = |wav: &Path, extra: &[&str]| {
        bin()
            .arg("localize")
            .arg(wav)
            .arg("--tf")
            .arg(&tf)
            .arg("--noise")
            .arg(wav)
            .args(["--device", "cpu", "--period", "25"])
            .args(extra)
            .output()
            .unwrap()
    };
    let plain = run(&flipped, &[]);
    assert!(plain.status.success(), "{}", stderr(&plain));
    assert!(
        stderr(&plain).contains("input channel 5 (0-based) looks polarity-inverted")
            && stderr(&plain).contains("--invert-channels 5"),
        "{}",
        stderr(&plain)
    );
    let fixed = run(&flipped, &["--invert-channels", "5"]);
    assert!(fixed.status.success(), "{}", stderr(&fixed));
    assert!(!stderr(&fixed).contains("polarity"), "{}", stderr(&fixed));
    let direct = run(&d.join("jinsei.wav"), &[]);
    assert!(!direct.stdout.is_empty());
    assert_eq!(
        fixed.stdout, direct.stdout,
        "the inverted channel must give the original results"
    );
    assert_ne!(plain.stdout, direct.stdout);
    // A noise-CM file is taken as it is, and the run says so.
    let cm = tmp("flipped-k.zip");
    let made = bin()
        .args(["noisecm", "make", "-q", "--invert-channels", "5", "-o"])
        .arg(&cm)
        .arg(&flipped)
        .output()
        .unwrap();
    assert!(made.status.success(), "{}", stderr(&made));
    let o = bin()
        .arg("localize")
        .arg(&flipped)
        .arg("--tf")
        .arg(&tf)
        .arg("--noise-cm")
        .arg(&cm)
        .args(["--device", "cpu", "--period", "25", "--invert-channels", "5"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("negated in the audio, not in"),
        "{}",
        stderr(&o)
    );
    let o = run(&flipped, &["--invert-channels", "8"]);
    assert_clean_failure(
        &o,
        &["input channel 8 is to be inverted, but it feeds no microphone"],
    );
}
