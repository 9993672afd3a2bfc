//! The live view in the browser (`--serve`), checked in headless Chromium and with plain
//! WebSocket clients. (ODAS and HARK network outputs: `cli_odas_out.rs`.)

mod common;

use common::webdriver::Browser;
use common::{bin, int16};
use serde_json::Value;
use soundloc::audio::{Audio, SampleFormat};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
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
        // A fixed port, as users give it: the address check before the run must leave it
        // free for the run's own server (it held it until 2026-12-03, and a fixed
        // --serve port failed with "Address already in use").
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let mut child = common::bin_for_ctrl_c()
            .args(args)
            .args(["--serve", &format!("127.0.0.1:{port}")])
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
    // The server gone: the page says so and fades the last picture (drawn at a third of
    // full opacity over the page's background).
    s.stop();
    browser
        .wait_for(
            "return !window.soundlocView.connected && document.getElementById('status').textContent.startsWith('disconnected');",
            Duration::from_secs(10),
        )
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let alpha = browser
        .exec("const [x, y] = window.soundlocView.ringAt(30, 0.6); return document.getElementById('map').getContext('2d').getImageData(Math.round(x), Math.round(y), 1, 1).data[3];")
        .unwrap();
    let alpha = alpha.as_i64().unwrap();
    assert!(
        (1..200).contains(&alpha),
        "ring at 30° after the server stopped: alpha {alpha} (not faded)"
    );
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
        // Spec §5's numerator: the darkest background of the robust default's spectra.
        // The map's colours span the last results' range, noise-only windows included;
        // the geometric numerator lifts the talk windows' floor (their own contrast,
        // peak over median, 17–21 dB here against 23–25 with the raw one) to mid-range.
        "--numerator",
        "raw",
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
    // Plain HTTP: HEAD is GET without the body; other methods are 405 with Allow; a
    // WebSocket request from another site's page (Origin ≠ Host) is refused, one from the
    // view's own page is upgraded.
    let head = http(&s.addr, &format!("HEAD / HTTP/1.1\r\nHost: {}\r\n\r\n", s.addr));
    assert!(head.starts_with("HTTP/1.1 200 OK"), "{head}");
    assert!(
        head.contains("Content-Length: ") && head.ends_with("\r\n\r\n"),
        "{head}"
    );
    let post = http(
        &s.addr,
        &format!("POST / HTTP/1.1\r\nHost: {}\r\nContent-Length: 0\r\n\r\n", s.addr),
    );
    assert!(
        post.starts_with("HTTP/1.1 405") && post.contains("Allow: GET, HEAD"),
        "{post}"
    );
    let upgrade = |origin: &str| {
        http(
            &s.addr,
            &format!(
                "GET /ws HTTP/1.1\r\nHost: {a}\r\nOrigin: {origin}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
                a = s.addr
            ),
        )
    };
    let foreign = upgrade("http://evil.example");
    assert!(
        foreign.starts_with("HTTP/1.1 403") && foreign.contains("Origin differs from Host"),
        "{foreign}"
    );
    let own = upgrade(&format!("http://{}", s.addr));
    assert!(own.starts_with("HTTP/1.1 101"), "{own}");
    s.stop();
}

/// Send `request` and read the answer until the server closes or 2 s pass (a WebSocket
/// stays open: its upgrade head is what arrived by then).
fn http(addr: &str, request: &str) -> String {
    let mut c = TcpStream::connect(addr).unwrap();
    c.write_all(request.as_bytes()).unwrap();
    c.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    while let Ok(n) = c.read(&mut buf) {
        if n == 0 {
            break;
        }
        got.extend_from_slice(&buf[..n]);
        if got.starts_with(b"HTTP/1.1 101") && got.windows(4).any(|w| w == b"\r\n\r\n") {
            break;
        }
    }
    String::from_utf8_lossy(&got).into_owned()
}
