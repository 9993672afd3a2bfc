//! Inputs that stop short: senders one after another on `tcp-listen:… --keep-listening`
//! make one run (a sender of another format is refused without ending it; Ctrl-C ends it
//! with every output complete), and recordings cut short (an error for a file unless
//! `--allow-truncated`, a warning for a stream; either way the audio before the cut).

mod common;

use common::bin;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const OPTS: [&str; 8] = [
    "--grid",
    "ring:5",
    "--window-type",
    "past",
    "--period",
    "10",
    "--device",
    "cpu",
];

fn from_file(wav: &Path, geo: &Path) -> String {
    let o = bin()
        .arg("localize")
        .arg(wav)
        .arg("--geometry")
        .arg(geo)
        .args(OPTS)
        .arg("-q")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

/// Read stderr lines until one contains `what`; returns all read.
fn until(err: &mut impl BufRead, what: &str) -> String {
    let mut all = String::new();
    let t = Instant::now();
    loop {
        let mut line = String::new();
        assert!(err.read_line(&mut line).unwrap() > 0, "soundloc exited: {all}");
        all.push_str(&line);
        if line.contains(what) {
            return all;
        }
        assert!(t.elapsed() < Duration::from_secs(60), "{all}");
    }
}

/// A JSON result line without its frame number and time (what the audio decides).
fn content(line: &str) -> (u64, f64, String) {
    let v: serde_json::Value = serde_json::from_str(line).unwrap();
    let mut o = v.as_object().unwrap().clone();
    let frame = o.remove("frame").unwrap().as_u64().unwrap();
    let time = o
        .remove("time_s")
        .map(|t| t.as_f64().unwrap())
        .unwrap_or(f64::NAN);
    (frame, time, serde_json::Value::Object(o).to_string())
}

#[test]
fn senders_one_after_another_make_one_run_with_true_times() {
    let (_, geo, wav) = common::ring_scene("cli-interrupted", "", 1);
    let want = from_file(&wav, &geo);
    let want: Vec<_> = want.lines().map(content).collect();
    assert!(want.len() > 10);
    let dir = common::tmp("cli-interrupted", "run");
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("results.jsonl");
    let mut child = common::bin_for_ctrl_c()
        .args([
            "localize",
            "tcp-listen:127.0.0.1:0",
            "--keep-listening",
            "--geometry",
        ])
        .arg(&geo)
        .args(OPTS)
        .arg("-o")
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let said = until(&mut err, "waiting for a sender on tcp:");
    let mut seen = String::new();
    let port: u16 = said.trim().rsplit(':').next().unwrap().parse().unwrap();
    let bytes = std::fs::read(&wav).unwrap();
    // A refused sender's writes may fail (soundloc hangs up after its header).
    let send = |data: &[u8]| {
        let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
        data.chunks(9000).try_for_each(|c| s.write_all(c)).is_ok()
    };
    // The first sender, the whole scene.
    assert!(send(&bytes));
    seen += &until(&mut err, "the sender closed; waiting for the next one");
    // A sender of another channel count is refused; the run goes on.
    let stereo = dir.join("stereo.wav");
    let mut two = soundloc::audio::Audio {
        sample_rate_hz: 16000,
        channels: vec![vec![0.0; 16000]; 2],
    };
    two.channels[0][100] = 1000.0;
    two.write_wav(&stereo, soundloc::audio::SampleFormat::Int16)
        .unwrap();
    send(&std::fs::read(&stereo).unwrap());
    until(
        &mut err,
        "refused: it sends 2 channels at 16000 Hz, this run's input is 8 channels",
    );
    // A sender that connects and sends nothing.
    drop(TcpStream::connect(("127.0.0.1", port)).unwrap());
    seen += &until(&mut err, "waiting for the next sender");
    // The scene again, at least 0.4 s after the first one ended.
    std::thread::sleep(Duration::from_millis(400));
    assert!(send(&bytes));
    seen += &until(&mut err, "the sender closed; waiting for the next one");
    let ok = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let status = child.wait().unwrap();
    let mut rest = String::new();
    err.read_to_string(&mut rest).unwrap();
    let rest = seen + &rest;
    assert!(status.success(), "{rest}");
    assert!(rest.contains("between two senders"), "{rest}");
    assert!(!rest.contains("lost"), "a pause is not lost audio: {rest}");
    let got: Vec<_> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(content)
        .collect();
    // The first sender's results are the file's; the second's are the same directions,
    // later by the first sender's audio and the pause between them.
    assert_eq!(got.len(), 2 * want.len(), "{rest}");
    assert_eq!(&got[..want.len()], &want[..]);
    let scene_s = 3.0;
    let (f0, t0) = (got[want.len()].0 - want[0].0, got[want.len()].1 - want[0].1);
    assert!(
        t0 >= scene_s + 0.4 && t0 < scene_s + 30.0,
        "second sender {t0} s later"
    );
    for (g, w) in got[want.len()..].iter().zip(&want) {
        assert_eq!(g.2, w.2, "the second sender's results are the file's");
        assert_eq!(g.0 - w.0, f0, "frames keep their spacing");
        assert!((g.1 - w.1 - t0).abs() < 1e-6, "times keep their spacing");
    }
    // --keep-listening belongs to tcp-listen:.
    let o = bin()
        .arg("localize")
        .arg(&wav)
        .arg("--keep-listening")
        .arg("--geometry")
        .arg(&geo)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--keep-listening is for a tcp-listen: input"));
}

#[test]
fn a_recording_cut_short_is_an_error_or_localized_up_to_the_cut() {
    let (audio, geo, wav) = common::ring_scene("cli-interrupted", "cut-", 1);
    let dir = common::tmp("cli-interrupted", "cut");
    std::fs::create_dir_all(&dir).unwrap();
    // The file cut 1.7 s (and half a frame) into its 3 s; its twin holds those 1.7 s whole.
    let bytes = std::fs::read(&wav).unwrap();
    let header = bytes.len() - audio.num_samples() * 16;
    let kept = 27200;
    let cut = dir.join("cut.wav");
    std::fs::write(&cut, &bytes[..header + kept * 16 + 5]).unwrap();
    let twin = dir.join("twin.wav");
    let mut short = audio.clone();
    for c in &mut short.channels {
        c.truncate(kept);
    }
    short
        .write_wav(&twin, soundloc::audio::SampleFormat::Int16)
        .unwrap();
    let want = from_file(&twin, &geo);
    assert!(want.lines().count() > 5);
    let run = |input: &Path, extra: &[&str], stdin: Option<&Path>| {
        let out = dir.join("out.jsonl");
        std::fs::write(&out, "old\n").unwrap();
        let mut cmd = bin();
        cmd.arg("localize")
            .arg(input)
            .arg("--geometry")
            .arg(&geo)
            .args(OPTS);
        cmd.args(extra).arg("-o").arg(&out);
        if let Some(p) = stdin {
            // A pipe, not a redirected file: what a recorder stopped early gives.
            let mut child = cmd.stdin(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
            let mut w = child.stdin.take().unwrap();
            let data = std::fs::read(p).unwrap();
            let t = std::thread::spawn(move || {
                let _ = w.write_all(&data);
            });
            let o = child.wait_with_output().unwrap();
            t.join().unwrap();
            (o, std::fs::read_to_string(&out).unwrap())
        } else {
            let o = cmd.output().unwrap();
            (o, std::fs::read_to_string(&out).unwrap())
        }
    };
    // A file: an error naming the file, the loss and the way out; -o keeps its old content.
    let (o, kept_out) = run(&cut, &[], None);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cut.wav: truncated WAV file") && err.contains("--allow-truncated"),
        "{err}"
    );
    assert_eq!(kept_out, "old\n");
    // With --allow-truncated: the audio before the cut, as its whole twin gives, and a warning.
    for quiet in [false, true] {
        let extra: &[&str] = if quiet {
            &["--allow-truncated", "-q"]
        } else {
            &["--allow-truncated"]
        };
        let (o, got) = run(&cut, extra, None);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert!(
            err.contains("warning: ") && err.contains("the 1.70 s before the cut are localized"),
            "{err}"
        );
        assert_eq!(got, want);
    }
    // A pipe cut short (a recorder stopped early): the same, without the flag.
    let (o, got) = run(Path::new("-"), &[], Some(&cut));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("truncated WAV file"), "{err}");
    assert_eq!(got, want);
}
