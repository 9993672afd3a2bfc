//! Live outputs: the browser view (`--serve`, checked in headless Chromium and with plain
//! WebSocket clients) and ODAS's SSL/SST messages (`--odas-ssl`, `--odas-sst`) decoded by a
//! receiver that restarts mid-run.

mod common;

use common::webdriver::Browser;
use common::{bin, int16, s16le};
use serde_json::Value;
use soundloc::audio::{Audio, SampleFormat};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStderr, Command, Stdio};
use std::time::{Duration, Instant};

fn tmp(name: &str) -> PathBuf {
    common::tmp("cli-live", name)
}

fn ring_scene(repeat: usize) -> (Audio, PathBuf, PathBuf) {
    common::ring_scene("cli-live", "", repeat)
}

/// A running `soundloc … --serve 127.0.0.1:0` and the address it printed.
struct Served {
    child: Child,
    addr: String,
    err: BufReader<ChildStderr>,
}

impl Served {
    fn start(args: &[&str]) -> Served {
        let mut child = bin()
            .args(args)
            .args(["--serve", "127.0.0.1:0"])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut err = BufReader::new(child.stderr.take().unwrap());
        let mut line = String::new();
        let addr = loop {
            line.clear();
            assert!(err.read_line(&mut line).unwrap() > 0, "soundloc exited early");
            if let Some(rest) = line.trim().strip_prefix("soundloc: live view at http://") {
                break rest.trim_end_matches('/').to_string();
            }
        };
        Served { child, addr, err }
    }

    /// Wait until stderr says the input has ended.
    fn wait_input_end(&mut self) {
        let mut line = String::new();
        loop {
            line.clear();
            assert!(
                self.err.read_line(&mut line).unwrap() > 0,
                "soundloc exited early"
            );
            if line.contains("the input has ended") {
                return;
            }
        }
    }

    /// Ctrl-C; the exit status must be success.
    fn stop(mut self) {
        let ok = Command::new("kill")
            .args(["-INT", &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(ok.success());
        let status = self.child.wait().unwrap();
        let mut rest = String::new();
        self.err.read_to_string(&mut rest).unwrap();
        assert!(status.success(), "{rest}");
    }
}

fn angle_diff(a: f64, b: f64) -> f64 {
    ((a - b + 180.0).rem_euclid(360.0) - 180.0).abs()
}

fn browser_or_skip(test: &str) -> Option<Browser> {
    match Browser::start() {
        Ok(b) => Some(b),
        Err(e) => {
            println!("SKIPPED {test}: no headless browser ({e}); scripts/test.sh installs chromium and chromium-driver");
            None
        }
    }
}

/// The colour-map position (0..1) of the canvas pixel at (x, y), or -1 when it is not a
/// colour-map colour (background, marker).
const PIXEL_LEVEL: &str = r#"
const level = (id, x, y) => {
  const p = document.getElementById(id).getContext("2d").getImageData(Math.round(x), Math.round(y), 1, 1).data;
  if (p[3] === 0) return -1;
  const cm = window.soundlocView.hello.colormap;
  let best = -1, bd = 1e9;
  cm.forEach((c, i) => { const d = Math.abs(c[0]-p[0]) + Math.abs(c[1]-p[1]) + Math.abs(c[2]-p[2]); if (d < bd) { bd = d; best = i; } });
  return bd <= 12 ? best / (cm.length - 1) : -1;
};
"#;

#[test]
fn browser_shows_the_ring_peaks_at_the_right_azimuths() {
    let test = "browser_shows_the_ring_peaks_at_the_right_azimuths";
    let Some(browser) = browser_or_skip(test) else {
        return;
    };
    let (_, geo, wav) = ring_scene(1);
    let geo = geo.to_str().unwrap();
    let mut s = Served::start(&[
        "localize",
        wav.to_str().unwrap(),
        "--geometry",
        geo,
        "--grid",
        "ring:5",
        "--period",
        "10",
        "--device",
        "cpu",
        "--track",
        "--min-src-interval",
        "30",
    ]);
    s.wait_input_end();
    browser.goto(&format!("http://{}/", s.addr)).unwrap();
    // The page replays the finished run: wait for its last result and spectrum.
    browser
        .wait_for(
            "const v = window.soundlocView; return v.results >= 20 && v.spectrum !== null && v.status !== null && v.status.finished && v.ringAt !== undefined;",
            Duration::from_secs(30),
        )
        .unwrap();
    let shot = Path::new(env!("CARGO_TARGET_TMPDIR")).join("live-view-ring.png");
    browser.screenshot(&shot).unwrap();
    println!("screenshot: {}", shot.display());
    // The peaks table (from the DOM): both talkers, with track ids.
    let rows = browser
        .exec("return [...document.querySelectorAll('#peaks tbody tr')].map(r => [Number(r.dataset.azimuth), r.dataset.id === undefined ? null : Number(r.dataset.id)]);")
        .unwrap();
    let rows: Vec<(f64, Option<i64>)> = rows
        .as_array()
        .unwrap()
        .iter()
        .map(|r| (r[0].as_f64().unwrap(), r[1].as_i64()))
        .collect();
    for truth in [30.0, -120.0] {
        assert!(
            rows.iter()
                .any(|(az, id)| angle_diff(*az, truth) <= 5.0 && id.is_some()),
            "no tracked peak near {truth}°: {rows:?}"
        );
    }
    // The canvas: at the talkers' azimuths the ring reaches far out in bright colours; 90°
    // and more away from both it stays near the centre.
    let probe = |az: f64, f: f64| -> f64 {
        let v = browser
            .exec(&format!(
                "{PIXEL_LEVEL} const [x, y] = window.soundlocView.ringAt({az}, {f}); return level('map', x, y);"
            ))
            .unwrap();
        v.as_f64().unwrap()
    };
    for truth in [30.0, -120.0] {
        let l = probe(truth, 0.6);
        assert!(l >= 0.6, "ring at {truth}°, 60 % radius: colour level {l}");
    }
    for empty in [120.0, -30.0] {
        let l = probe(empty, 0.6);
        assert!(
            l < 0.0,
            "ring at {empty}° should not reach 60 % radius (level {l})"
        );
    }
    // The waterfall has drawn columns (its newest column is not background).
    let wf = browser
        .exec("const c = document.getElementById('waterfall'); const p = c.getContext('2d').getImageData(c.width - 1, c.height / 2, 1, 1).data; return p[3];")
        .unwrap();
    assert_eq!(wf.as_i64(), Some(255));
    s.stop();
}

#[test]
fn browser_sky_map_puts_the_sphere_talkers_where_they_are() {
    let test = "browser_sky_map_puts_the_sphere_talkers_where_they_are";
    let Some(browser) = browser_or_skip(test) else {
        return;
    };
    let scene = soundloc::demo::sphere60_drone(10.0, 642, 3).unwrap();
    let audio = int16(scene.render());
    let geo = tmp("sphere60.toml");
    std::fs::write(&geo, scene.geometry.to_toml_string()).unwrap();
    let wav = tmp("sphere60.wav");
    audio.write_wav(&wav, SampleFormat::Int16).unwrap();
    let mut s = Served::start(&[
        "localize",
        wav.to_str().unwrap(),
        "--geometry",
        geo.to_str().unwrap(),
        "--grid",
        "sphere:642",
        "--noise-range",
        "0:1",
        "--period",
        "25",
        "--device",
        "cpu",
    ]);
    s.wait_input_end();
    browser.goto(&format!("http://{}/", s.addr)).unwrap();
    browser
        .wait_for(
            "const v = window.soundlocView; return v.spectrum !== null && v.skyAt !== undefined && v.status !== null && v.status.finished;",
            Duration::from_secs(60),
        )
        .unwrap();
    let shot = Path::new(env!("CARGO_TARGET_TMPDIR")).join("live-view-sphere.png");
    browser.screenshot(&shot).unwrap();
    println!("screenshot: {}", shot.display());
    let grid = browser
        .exec("return window.soundlocView.hello.grid.kind;")
        .unwrap();
    assert_eq!(grid, "sphere");
    let rows = browser
        .exec("return [...document.querySelectorAll('#peaks tbody tr')].map(r => [Number(r.dataset.azimuth), Number(r.dataset.elevation)]);")
        .unwrap();
    let unit = |az: f64, el: f64| {
        let (a, e) = (az.to_radians(), el.to_radians());
        [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()]
    };
    let sep = |p: [f64; 3], q: [f64; 3]| {
        (p[0] * q[0] + p[1] * q[1] + p[2] * q[2])
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    };
    for (az, el) in [(40.0, 20.0), (-100.0, -10.0)] {
        let near = rows
            .as_array()
            .unwrap()
            .iter()
            .any(|r| sep(unit(r[0].as_f64().unwrap(), r[1].as_f64().unwrap()), unit(az, el)) <= 10.0);
        assert!(near, "no peak in the table near ({az}°, {el}°): {rows}");
    }
    let probe = |az: f64, el: f64| -> f64 {
        browser
            .exec(&format!(
                "{PIXEL_LEVEL} const [x, y] = window.soundlocView.skyAt({az}, {el}); return level('map', x, y);"
            ))
            .unwrap()
            .as_f64()
            .unwrap()
    };
    // At each detected talker (inside its hollow marker): bright. Far from both: dark.
    for r in rows.as_array().unwrap() {
        let (az, el) = (r[0].as_f64().unwrap(), r[1].as_f64().unwrap());
        let l = probe(az, el);
        assert!(l >= 0.6, "sky map at the peak ({az}°, {el}°): colour level {l}");
    }
    for (az, el) in [(150.0, 60.0), (-20.0, -70.0)] {
        let l = probe(az, el);
        assert!(
            (0.0..0.5).contains(&l),
            "sky map at ({az}°, {el}°): colour level {l}"
        );
    }
    s.stop();
}

type Ws = tungstenite::WebSocket<tungstenite::stream::MaybeTlsStream<TcpStream>>;

fn ws_connect(addr: &str) -> Ws {
    let (ws, _) = tungstenite::connect(format!("ws://{addr}/ws")).unwrap();
    ws
}

#[test]
fn several_pages_at_once_and_a_stalled_one_never_stalls_the_engine() {
    let (_, geo, wav) = ring_scene(2);
    let plain = bin()
        .args([
            "localize",
            wav.to_str().unwrap(),
            "--geometry",
            geo.to_str().unwrap(),
        ])
        .args(["--grid", "ring:1", "--period", "1", "--device", "cpu", "-q"])
        .output()
        .unwrap();
    assert!(plain.status.success());
    let want = String::from_utf8(plain.stdout).unwrap().lines().count();
    // Paced at real time so that the pages connect before the results flow.
    let mut s = Served::start(&[
        "localize",
        wav.to_str().unwrap(),
        "--geometry",
        geo.to_str().unwrap(),
        "--grid",
        "ring:1",
        "--period",
        "1",
        "--device",
        "cpu",
        "--realtime",
    ]);
    let mut reader = ws_connect(&s.addr);
    let stalled = TcpStream::connect(&s.addr).unwrap();
    // A WebSocket handshake, then never a byte read.
    write!(
        &stalled,
        "GET /ws HTTP/1.1\r\nHost: {}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
        s.addr
    )
    .unwrap();
    let t = Instant::now();
    let (mut results, mut spectra, mut finished) = (0usize, 0usize, false);
    let mut hello = None;
    while !finished {
        match reader.read().unwrap() {
            tungstenite::Message::Text(t) => {
                let v: Value = serde_json::from_str(t.as_str()).unwrap();
                match v["type"].as_str().unwrap() {
                    "hello" => hello = Some(v),
                    "result" => results += 1,
                    "status" => finished = v["finished"] == Value::Bool(true),
                    other => panic!("unknown message type {other}"),
                }
            }
            tungstenite::Message::Binary(b) => {
                assert_eq!(&b[..4], b"SLSP");
                assert_eq!(b.len(), 28 + 4 * 360);
                spectra += 1;
            }
            _ => {}
        }
    }
    let wall = t.elapsed();
    let hello = hello.expect("hello first");
    assert_eq!(hello["grid"]["azimuth_deg"].as_array().unwrap().len(), 360);
    // What runs, as stderr says it (the room default: not plain "sevd"), beside the name.
    assert_eq!(hello["algorithm"], "sevd");
    assert_eq!(hello["label"], "normmusic (subspace 4, coherence, refined)");
    assert_eq!(results, want, "the reading page gets every result");
    // Spectra are thinned to 50 per second of audio: one every other 10 ms result.
    assert!(
        spectra.abs_diff(results / 2) <= 2,
        "{spectra} spectra for {results} results"
    );
    // Real time: 6 s of audio take about 6 s, stalled page or not.
    assert!(wall < Duration::from_secs(40), "{wall:?}");
    s.wait_input_end();
    drop(stalled);
    s.stop();
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
        assert!(ts > last_ts || last_ts == 0, "timeStamps increase");
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
        .args(["--grid", "ring:5", "--period", "10", "--device", "cpu", "-q"])
        .arg("--odas-ssl")
        .arg(&untracked)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        std::fs::read_to_string(&untracked).unwrap() == std::fs::read_to_string(&fssl).unwrap(),
        "SSL with --track differs from SSL without it"
    );
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
    assert!(run(&["--odas-ssl", "/no/such/dir/ssl.json"]).contains("/no/such/dir"));
    // An address with a typo is refused, not written to a file of that name.
    for bad in ["localhost:9000x", "localhost:9001 ", "127.0.0.1:"] {
        let e = run(&["--odas-ssl", bad]);
        assert!(e.contains("neither HOST:PORT nor a file name"), "{bad:?}: {e}");
        assert!(!Path::new(bad).exists(), "{bad:?} written");
    }
    let busy = TcpListener::bind("127.0.0.1:0").unwrap();
    let e = run(&["--serve", &busy.local_addr().unwrap().to_string()]);
    assert!(e.contains("--serve") && e.contains("cannot listen"), "{e}");
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
