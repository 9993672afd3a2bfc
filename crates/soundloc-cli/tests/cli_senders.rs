//! `soundloc localize tcp-listen:… --keep-listening`: senders one after another make one
//! run; a sender of another format is refused without ending it; Ctrl-C ends it with
//! every output complete.

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
    let (_, geo, wav) = common::ring_scene("cli-senders", "", 1);
    let want = from_file(&wav, &geo);
    let want: Vec<_> = want.lines().map(content).collect();
    assert!(want.len() > 10);
    let dir = common::tmp("cli-senders", "run");
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
    let port: u16 = said.trim().rsplit(':').next().unwrap().parse().unwrap();
    let bytes = std::fs::read(&wav).unwrap();
    // A refused sender's writes may fail (soundloc hangs up after its header).
    let send = |data: &[u8]| {
        let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
        data.chunks(9000).try_for_each(|c| s.write_all(c)).is_ok()
    };
    // The first sender, the whole scene.
    assert!(send(&bytes));
    until(&mut err, "the sender closed; waiting for the next one");
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
    until(&mut err, "waiting for the next sender");
    // The scene again, at least 0.4 s after the first one ended.
    std::thread::sleep(Duration::from_millis(400));
    assert!(send(&bytes));
    until(&mut err, "the sender closed; waiting for the next one");
    let ok = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let status = child.wait().unwrap();
    let mut rest = String::new();
    err.read_to_string(&mut rest).unwrap();
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
