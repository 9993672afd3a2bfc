//! Network and ODAS outputs: SSL/SST messages (`--odas-ssl`, `--odas-sst`) decoded by a
//! receiver that restarts mid-run, live-output options checked before any work, and a
//! HARK stream whose receiver is absent. (The browser view: `cli_live.rs`.)

mod common;

use common::{bin, s16le};
use serde_json::Value;
use soundloc::audio::Audio;
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::Duration;

fn tmp(name: &str) -> PathBuf {
    common::tmp("cli-odas-out", name)
}

fn ring_scene(repeat: usize) -> (Audio, PathBuf, PathBuf) {
    common::ring_scene("cli-odas-out", "", repeat)
}

fn angle_diff(a: f64, b: f64) -> f64 {
    ((a - b + 180.0).rem_euclid(360.0) - 180.0).abs()
}

/// Split an ODAS message stream the way odas_web does (on `}\n{`), returning whole
/// messages (text) and the unfinished rest.
fn odas_messages(buf: &mut String) -> Vec<String> {
    let mut out = Vec::new();
    while let Some(end) = buf.find("\n}\n") {
        let msg: String = buf.drain(..end + 3).collect();
        out.push(msg);
    }
    out
}

fn check_number(text: &str) -> f64 {
    // ODAS prints %1.3f: an optional sign, digits, a point, exactly three decimals.
    let t = text.trim();
    let body = t.strip_prefix('-').unwrap_or(t);
    let (int, frac) = body
        .split_once('.')
        .unwrap_or_else(|| panic!("{t:?} has no decimals"));
    assert!(
        !int.is_empty() && int.bytes().all(|b| b.is_ascii_digit()),
        "{t:?}"
    );
    assert!(
        frac.len() == 3 && frac.bytes().all(|b| b.is_ascii_digit()),
        "{t:?} is not %1.3f"
    );
    t.parse().unwrap()
}

/// Decode one SSL or SST message field by field; returns (timeStamp, entries).
fn decode_odas(msg: &str, sst: bool, slots: usize) -> (u64, Vec<Value>) {
    assert!(msg.starts_with("{\n    \"timeStamp\": "), "{msg:?}");
    let v: Value = serde_json::from_str(msg).unwrap_or_else(|e| panic!("{e}: {msg:?}"));
    let ts = v["timeStamp"].as_u64().expect("unsigned timeStamp");
    let src = v["src"].as_array().unwrap().clone();
    assert_eq!(src.len(), slots, "{msg}");
    let lines: Vec<&str> = msg
        .lines()
        .filter(|l| l.trim_start().starts_with("{ \""))
        .collect();
    assert_eq!(lines.len(), slots, "one line per entry: {msg}");
    for (e, line) in src.iter().zip(lines) {
        let keys: Vec<&str> = e.as_object().unwrap().keys().map(|k| k.as_str()).collect();
        let mut want = if sst {
            vec!["activity", "id", "tag", "x", "y", "z"]
        } else {
            vec!["E", "x", "y", "z"]
        };
        want.sort_unstable();
        let mut got = keys.clone();
        got.sort_unstable();
        assert_eq!(got, want);
        // Every float as %1.3f in the text.
        for field in line
            .split(", ")
            .filter(|f| !f.contains("\"id\"") && !f.contains("\"tag\""))
        {
            let num = field
                .rsplit(": ")
                .next()
                .unwrap()
                .trim_end_matches(" },")
                .trim_end_matches(" }");
            check_number(num);
        }
        let (x, y, z) = (
            e["x"].as_f64().unwrap(),
            e["y"].as_f64().unwrap(),
            e["z"].as_f64().unwrap(),
        );
        let level = e[if sst { "activity" } else { "E" }].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&level), "{e}");
        let norm = (x * x + y * y + z * z).sqrt();
        let empty = if sst {
            e["id"] == 0
        } else {
            level == 0.0 && norm == 0.0
        };
        if empty {
            assert_eq!((x, y, z, level), (0.0, 0.0, 0.0, 0.0), "{e}");
            if sst {
                assert_eq!(e["tag"], "");
            }
        } else {
            assert!((norm - 1.0).abs() < 0.004, "unit vector: {e}");
            if sst {
                assert_eq!(e["tag"], "dynamic");
                assert!(e["id"].as_u64().unwrap() >= 1);
            }
        }
    }
    (ts, src)
}

fn azimuth(e: &Value) -> f64 {
    e["y"]
        .as_f64()
        .unwrap()
        .atan2(e["x"].as_f64().unwrap())
        .to_degrees()
}

/// Accept a connection and read ODAS messages until `n` arrived (or the deadline).
fn read_messages(l: &TcpListener, n: usize) -> (TcpStream, Vec<String>) {
    let (c, _) = l.accept().unwrap();
    c.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let mut buf = String::new();
    let mut msgs = Vec::new();
    let mut chunk = [0u8; 4096];
    let mut r = &c;
    while msgs.len() < n {
        let k = r.read(&mut chunk).unwrap();
        assert!(k > 0, "connection closed after {} messages", msgs.len());
        buf.push_str(std::str::from_utf8(&chunk[..k]).unwrap());
        msgs.extend(odas_messages(&mut buf));
    }
    (c, msgs)
}

#[test]
fn odas_ssl_and_sst_reach_a_receiver_that_restarts() {
    let (audio, geo, wav) = ring_scene(2);
    let ssl = TcpListener::bind("127.0.0.1:0").unwrap();
    let sst = TcpListener::bind("127.0.0.1:0").unwrap();
    let (ssl_port, sst_port) = (ssl.local_addr().unwrap().port(), sst.local_addr().unwrap().port());
    let mut child = bin()
        .args(["localize", "-"])
        .args(common::RAW_S16_RING)
        .arg("--geometry")
        .arg(&geo)
        .args([
            "--grid",
            "ring:5",
            "--period",
            "10",
            "--window-type",
            "past",
            "--device",
            "cpu",
            "--track",
        ])
        .args(["--min-src-interval", "30", "--odas-pots", "3"])
        .arg("--odas-ssl")
        .arg(format!("127.0.0.1:{ssl_port}"))
        .arg("--odas-sst")
        .arg(format!("tcp:127.0.0.1:{sst_port}"))
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let n = audio.channels[0].len();
    stdin.write_all(&s16le(&audio, 0..n / 2)).unwrap();
    stdin.flush().unwrap();
    let (ssl_conn, first) = read_messages(&ssl, 20);
    let (_sst_conn, tracks) = read_messages(&sst, 20);
    let (mut last_ts, mut talking) = (0, 0);
    for m in &first {
        let (ts, src) = decode_odas(m, false, 3);
        // From 1, as ODAS counts hops (its sinks take a 0 for "no message"), increasing.
        assert!(
            ts > last_ts,
            "timeStamps start at 1 and increase: {ts} after {last_ts}"
        );
        last_ts = ts;
        // Strongest first, and once the talkers speak (1 s, frame 100; the PAST window
        // is 50 frames) the strongest is one of them.
        let e: Vec<f64> = src.iter().map(|e| e["E"].as_f64().unwrap()).collect();
        assert!(e.windows(2).all(|w| w[0] >= w[1]), "{e:?}");
        if ts < 160 {
            continue;
        }
        talking += 1;
        let az = azimuth(&src[0]);
        assert!(
            angle_diff(az, 30.0) <= 6.0 || angle_diff(az, -120.0) <= 6.0,
            "strongest at {az}°"
        );
    }
    assert!(talking >= 3, "{talking} messages while talking");
    let mut ids = std::collections::BTreeSet::new();
    for m in &tracks {
        let (_, src) = decode_odas(m, true, 4);
        ids.extend(
            src.iter()
                .filter(|e| e["id"] != 0)
                .map(|e| e["id"].as_u64().unwrap()),
        );
    }
    assert!(!ids.is_empty(), "tracked sources appear in SST");
    // The SSL receiver restarts: localization goes on, messages meanwhile are dropped,
    // and the new server gets the later ones.
    drop(ssl_conn);
    drop(ssl);
    stdin.write_all(&s16le(&audio, n / 2..3 * n / 4)).unwrap();
    stdin.flush().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let ssl = TcpListener::bind(("127.0.0.1", ssl_port)).unwrap();
    let feeder = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(500));
        stdin.write_all(&s16le(&audio, 3 * n / 4..n)).unwrap();
        drop(stdin);
    });
    let (_c, later) = read_messages(&ssl, 5);
    let (ts, _) = decode_odas(&later[0], false, 3);
    assert!(ts > last_ts, "after the restart: timeStamp {ts} > {last_ts}");
    feeder.join().unwrap();
    let status = child.wait().unwrap();
    let mut err = String::new();
    child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    assert!(status.success(), "{err}");
    assert!(err.contains("ODAS SSL: reconnected"), "{err}");
    assert!(err.contains("ODAS SSL") && err.contains("dropped"), "{err}");

    // The same messages into files: one SSL and one SST message per result.
    let (fssl, fsst) = (tmp("ssl.json"), tmp("sst.json"));
    let o = bin()
        .args([
            "localize",
            wav.to_str().unwrap(),
            "--geometry",
            geo.to_str().unwrap(),
        ])
        .args([
            "--grid", "ring:5", "--period", "10", "--device", "cpu", "--track", "-q",
        ])
        .arg("--odas-ssl")
        .arg(&fssl)
        .arg("--odas-sst")
        .arg(&fsst)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let results = String::from_utf8(o.stdout).unwrap().lines().count();
    let mut text = std::fs::read_to_string(&fssl).unwrap();
    let msgs = odas_messages(&mut text);
    assert!(text.is_empty());
    assert_eq!(msgs.len(), results);
    msgs.iter().for_each(|m| drop(decode_odas(m, false, 4)));
    let mut text = std::fs::read_to_string(&fsst).unwrap();
    assert_eq!(odas_messages(&mut text).len(), results);
    // SSL is each window's own peaks (ODAS's potential sources), not the tracks: the
    // same bytes without --track (it carried the tracker's held-over sources before).
    let untracked = tmp("ssl-untracked.json");
    let o = bin()
        .args([
            "localize",
            wav.to_str().unwrap(),
            "--geometry",
            geo.to_str().unwrap(),
        ])
        .args(["--grid", "ring:5", "--period", "10", "--device", "cpu"])
        .arg("--odas-ssl")
        .arg(&untracked)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        std::fs::read_to_string(&untracked).unwrap() == std::fs::read_to_string(&fssl).unwrap(),
        "SSL with --track differs from SSL without it"
    );
    // Two peaks per result in four pots: the note says the other two are zeros and how
    // to fill them; with --max-peaks 4 they are the windows' next peaks, where the
    // spectrum has that many local maxima.
    assert!(
        err.contains("the other 2 are zeros") && err.contains("--max-peaks 4"),
        "{err}"
    );
    let filled = tmp("ssl-filled.json");
    let o = bin()
        .args([
            "localize",
            wav.to_str().unwrap(),
            "--geometry",
            geo.to_str().unwrap(),
        ])
        .args([
            "--grid",
            "ring:5",
            "--period",
            "10",
            "--device",
            "cpu",
            "--max-peaks",
            "4",
        ])
        .arg("--odas-ssl")
        .arg(&filled)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && !err.contains("are zeros"), "{err}");
    let energies = |path: &Path| -> Vec<Vec<f64>> {
        let mut text = std::fs::read_to_string(path).unwrap();
        let msgs = odas_messages(&mut text);
        msgs.iter()
            .map(|m| {
                decode_odas(m, false, 4)
                    .1
                    .iter()
                    .map(|e| e["E"].as_f64().unwrap())
                    .collect()
            })
            .collect()
    };
    let (two, four) = (energies(&untracked), energies(&filled));
    assert_eq!(two.len(), four.len());
    for (a, b) in two.iter().zip(&four) {
        assert_eq!(a[..2], b[..2], "the strongest two are the same");
        assert!(a[2..].iter().all(|&e| e == 0.0));
    }
    // A window whose spectrum has only two local maxima keeps the zeros.
    assert!(four.iter().filter(|e| e[2] > 0.0).count() >= 5, "{four:?}");
}

#[test]
fn live_output_options_are_checked_before_any_work() {
    let (_, geo, wav) = ring_scene(1);
    let run = |extra: &[&str]| {
        let o = bin()
            .args([
                "localize",
                wav.to_str().unwrap(),
                "--geometry",
                geo.to_str().unwrap(),
                "--grid",
                "ring:5",
            ])
            .args(extra)
            .output()
            .unwrap();
        assert!(!o.status.success());
        assert!(o.stdout.is_empty(), "nothing computed");
        String::from_utf8(o.stderr).unwrap()
    };
    assert!(run(&["--odas-sst", "127.0.0.1:9000"]).contains("--odas-sst needs --track"));
    assert!(run(&["--odas-ssl", "127.0.0.1:9001", "--odas-pots", "0"]).contains("--odas-pots"));
    // Slot counts for an output that is not asked for are named, not ignored.
    assert!(run(&["--odas-pots", "3"]).contains("--odas-ssl"));
    assert!(run(&["--track", "--odas-tracks", "3"]).contains("--odas-sst"));
    assert!(run(&["--odas-ssl", "/no/such/dir/ssl.json"]).contains("/no/such/dir"));
    // An address with a typo is refused, not written to a file of that name.
    for bad in ["localhost:9000x", "localhost:9001 ", "127.0.0.1:"] {
        let e = run(&["--odas-ssl", bad]);
        assert!(e.contains("neither HOST:PORT nor a file name"), "{bad:?}: {e}");
        assert!(!Path::new(bad).exists(), "{bad:?} written");
    }
    // Half an address too (it wrote a file named 9001 until 2026-12-02).
    for bad in ["9001", "localhost", "127.0.0.1"] {
        let e = run(&["--odas-ssl", bad]);
        assert!(e.contains("half an address, not HOST:PORT"), "{bad:?}: {e}");
        assert!(!Path::new(bad).exists(), "{bad:?} written");
    }
    // A bare port for the HARK stream (it connected to the "host" 5530, 0.0.21.154).
    let e = run(&["--hark-stream", "5530"]);
    assert!(
        e.contains("a port without a host") && e.contains("127.0.0.1:5530"),
        "{e}"
    );
    let busy = TcpListener::bind("127.0.0.1:0").unwrap();
    let e = run(&["--serve", &busy.local_addr().unwrap().to_string()]);
    assert!(e.contains("--serve") && e.contains("cannot listen"), "{e}");
    // A malformed one names the accepted form, before anything is loaded or noted.
    let e = run(&["--serve", "abc"]);
    assert!(
        e.contains("--serve abc: cannot listen (expected [HOST:]PORT"),
        "{e}"
    );
    assert!(
        !e.contains("room default") && !e.contains("noise source"),
        "said after the preamble: {e}"
    );
}

#[test]
fn an_absent_hark_receiver_never_fails_the_run() {
    let (_, geo, wav) = ring_scene(1);
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let o = bin()
        .args([
            "localize",
            wav.to_str().unwrap(),
            "--geometry",
            geo.to_str().unwrap(),
        ])
        .args(["--grid", "ring:5", "--period", "10", "--device", "cpu"])
        .arg("--hark-stream")
        .arg(format!("127.0.0.1:{port}"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let results = String::from_utf8(o.stdout).unwrap().lines().count();
    assert!(results > 10);
    assert!(err.contains("not reachable"), "{err}");
    assert!(
        err.contains(&format!("HARK stream: {results} of {results} messages")) && err.contains("dropped"),
        "{err}"
    );
}
