//! HARK interoperability, results: source-location logs (text and XML) and the
//! HarkDataStreamSender protocol. (Noise correlation matrices: `hark_interop.rs`.)

use std::io::Read;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use soundloc::formats::source_log::{self, SourceLogFormat};
use soundloc::output::hark_stream::{self, HarkStreamSender};
use soundloc::{LocalizationResult, Source};

/// A fresh, empty temporary folder for one test.
fn tmp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("soundloc-hark-logs-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create temp dir");
    d
}

fn err_text<T: std::fmt::Debug>(r: soundloc::Result<T>) -> String {
    format!("{:#}", r.expect_err("expected an error"))
}

// ------------------------------------------------------------- source-location logs ---

fn src(id: Option<i64>, x: f64, y: f64, z: f64) -> Source {
    Source {
        id,
        grid_index: 3,
        azimuth_deg: y.atan2(x).to_degrees(),
        elevation_deg: z.atan2((x * x + y * y).sqrt()).to_degrees(),
        x,
        y,
        z,
        power_db: 27.5,
        held: false,
    }
}

fn log_results() -> Vec<LocalizationResult> {
    vec![
        LocalizationResult {
            num_active: None,
            frame: 0,
            time_s: 0.0,
            sources: vec![],
        },
        LocalizationResult {
            num_active: None,
            frame: 50,
            time_s: 0.5,
            sources: vec![
                src(Some(0), 0.9659258262890683, 0.25881904510252074, 0.0),
                src(None, -0.5, -0.5, 0.6),
            ],
        },
        LocalizationResult {
            num_active: None,
            frame: 100,
            time_s: 1.0,
            sources: vec![
                src(Some(12), 1e-7, -0.3333333333333333, -0.94),
                src(Some(3), -1.0, 0.0, 0.0),
            ],
        },
    ]
}

fn check_log_round_trip(back: &[LocalizationResult], orig: &[LocalizationResult]) {
    assert_eq!(back.len(), orig.len());
    for (b, o) in back.iter().zip(orig) {
        assert_eq!(b.frame, o.frame);
        assert!((b.time_s - o.time_s).abs() < 1e-12);
        assert_eq!(b.sources.len(), o.sources.len());
        for (bs, os) in b.sources.iter().zip(&o.sources) {
            assert_eq!((bs.id, bs.x, bs.y, bs.z), (os.id, os.x, os.y, os.z));
            assert!((bs.azimuth_deg - os.azimuth_deg).abs() < 1e-9);
            assert!((bs.elevation_deg - os.elevation_deg).abs() < 1e-9);
            assert!(bs.power_db.is_nan(), "power is not in the format");
        }
    }
}

#[test]
fn source_log_text_round_trip() {
    let d = tmp_dir("log-text");
    let p = d.join("loc.txt");
    let orig = log_results();
    source_log::write_text(&p, &orig).expect("write");
    let text = std::fs::read_to_string(&p).unwrap();
    assert_eq!(text.lines().next(), Some("0"));
    assert!(text
        .lines()
        .nth(1)
        .unwrap()
        .starts_with("50 0 0.9659258262890683 0.25881904510252074 0 -1 -0.5"));
    assert_eq!(source_log::detect(&text), SourceLogFormat::Text);
    check_log_round_trip(&source_log::read(&p, 0.01).expect("read"), &orig);
    // Azimuth of (−1, 0, 0) is +180, not −180.
    assert_eq!(
        source_log::read(&p, 0.01).unwrap()[2].sources[1].azimuth_deg,
        180.0
    );
}

#[test]
fn source_log_xml_round_trip() {
    let d = tmp_dir("log-xml");
    let p = d.join("loc.xml");
    let orig = log_results();
    source_log::write(&p, &orig, SourceLogFormat::Xml).expect("write");
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.starts_with("<hark_xml version=\"1.3\">"));
    assert!(text.contains("<positions type=\"localization\" frame=\"50\" coordinate=\"cartesian\">"));
    assert!(text.contains("id=\"-1\"/>"));
    assert_eq!(source_log::detect(&text), SourceLogFormat::Xml);
    check_log_round_trip(&source_log::read(&p, 0.01).expect("read"), &orig);
}

/// The streaming writer (a live run's log) writes what the whole-run writer does, and
/// reads back to the same results.
#[test]
fn source_log_writer_streams_the_same_log() {
    let orig = log_results();
    for format in [SourceLogFormat::Text, SourceLogFormat::Xml] {
        let mut w = source_log::SourceLogWriter::new(Vec::new(), format).unwrap();
        for r in &orig {
            w.write(r).unwrap();
        }
        let streamed = String::from_utf8(w.finish().unwrap()).unwrap();
        let whole = match format {
            SourceLogFormat::Text => source_log::to_text(&orig),
            SourceLogFormat::Xml => source_log::to_xml(&orig),
        };
        assert_eq!(streamed, whole);
        let back = match format {
            SourceLogFormat::Text => source_log::parse_text(&streamed, Path::new("s.log"), 0.01),
            SourceLogFormat::Xml => source_log::parse_xml(&streamed, Path::new("s.xml"), 0.01),
        };
        check_log_round_trip(&back.unwrap(), &orig);
    }
}

#[test]
fn source_log_text_errors_name_file_and_line() {
    let d = tmp_dir("log-bad");
    let cases: &[(&str, &str)] = &[
        (
            "0 1 1.0 0.0 0.0\n\n10 1 1.0 0.0\n",
            "line 3: expected groups of 4",
        ),
        (
            "0\n-3 1 1 0 0\n",
            "line 2: frame count is not a non-negative integer",
        ),
        ("0 1.5 1 0 0\n", "line 1: source 0: id is not an integer"),
        (
            "# header\n0 1 1 0 0 2 1 NaN 0\n",
            "line 2: source 1: y is not finite",
        ),
        ("0 1 1 0 zz\n", "line 1: source 0: z is not a number"),
    ];
    for (i, (content, want)) in cases.iter().enumerate() {
        let p = d.join(format!("bad{i}.txt"));
        std::fs::write(&p, content).unwrap();
        let msg = err_text(source_log::read(&p, 0.01));
        assert!(
            msg.contains(&format!("bad{i}.txt")) && msg.contains(want),
            "{msg}"
        );
    }
    let xml_cases: &[(&str, &str)] = &[
        (
            "<hark_xml><positions frame=\"1\"><position x=\"1\" y=\"0\"/></positions></hark_xml>",
            "missing z",
        ),
        (
            "<hark_xml><positions frame=\"1\"><position x=\"1\" y=\"nan\" z=\"0\"/></positions></hark_xml>",
            "y is not a finite number",
        ),
        (
            "<hark_xml><positions><position x=\"1\" y=\"0\" z=\"0\"/></positions></hark_xml>",
            "no frame attribute",
        ),
        (
            "<hark_xml><positions frame=\"2\" coordinate=\"polar\"></positions></hark_xml>",
            "not supported",
        ),
        ("<hark_xml><positions frame=\"2\"></hark_xml>", "XML line"),
        ("<other/>", "no <hark_xml>"),
    ];
    for (i, (content, want)) in xml_cases.iter().enumerate() {
        let p = d.join(format!("bad{i}.xml"));
        std::fs::write(&p, content).unwrap();
        let msg = err_text(source_log::read(&p, 0.01));
        assert!(
            msg.contains(&format!("bad{i}.xml")) && msg.contains(want),
            "{msg}"
        );
    }
    let msg = err_text(source_log::read(&d.join("absent.txt"), 0.01));
    assert!(msg.contains("absent.txt"), "{msg}");
}

// ---------------------------------------------------------- HarkDataStreamSender ---

#[derive(Debug, PartialEq)]
struct Decoded {
    flags: i32,
    advance: i32,
    count: i32,
    pad: [u8; 4],
    tv_sec: i64,
    tv_usec: i64,
    sources: Vec<(i32, f32, f32, f32, f32)>,
}

fn i32_le(b: &[u8], o: usize) -> i32 {
    i32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}
fn f32_le(b: &[u8], o: usize) -> f32 {
    f32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}
fn i64_le(b: &[u8], o: usize) -> i64 {
    i64::from_le_bytes(b[o..o + 8].try_into().unwrap())
}

/// Decodes messages from `bytes` independently of the library's encoder.
fn decode_all(bytes: &[u8]) -> Vec<Decoded> {
    let mut out = Vec::new();
    let mut o = 0;
    while o < bytes.len() {
        let n = i32_le(bytes, o + 32) as usize;
        let sources = (0..n)
            .map(|s| {
                let b = o + 36 + 20 * s;
                (
                    i32_le(bytes, b),
                    f32_le(bytes, b + 4),
                    f32_le(bytes, b + 8),
                    f32_le(bytes, b + 12),
                    f32_le(bytes, b + 16),
                )
            })
            .collect();
        out.push(Decoded {
            flags: i32_le(bytes, o),
            advance: i32_le(bytes, o + 4),
            count: i32_le(bytes, o + 8),
            pad: bytes[o + 12..o + 16].try_into().unwrap(),
            tv_sec: i64_le(bytes, o + 16),
            tv_usec: i64_le(bytes, o + 24),
            sources,
        });
        o += 36 + 20 * n;
    }
    out
}

/// A receiver on an ephemeral port that accepts one connection, reads until the sender
/// closes or `expect_bytes` arrived, and stops by itself after 10 s at most.
fn spawn_receiver(expect_bytes: usize) -> (u16, std::thread::JoinHandle<Vec<u8>>) {
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = listener.local_addr().unwrap().port();
    listener.set_nonblocking(true).unwrap();
    let h = std::thread::spawn(move || {
        let deadline = Instant::now() + Duration::from_secs(10);
        let mut conn = loop {
            match listener.accept() {
                Ok((c, _)) => break c,
                Err(_) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(5)),
                Err(_) => return Vec::new(),
            }
        };
        conn.set_nonblocking(false).unwrap();
        conn.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let mut buf = Vec::new();
        let mut chunk = [0u8; 4096];
        while buf.len() < expect_bytes && Instant::now() < deadline {
            match conn.read(&mut chunk) {
                Ok(0) | Err(_) => break,
                Ok(n) => buf.extend_from_slice(&chunk[..n]),
            }
        }
        buf
    });
    (port, h)
}

#[test]
fn hark_stream_sends_header_and_src_info() {
    let results = log_results();
    let expect = 3 * 36 + 4 * 20;
    let (port, h) = spawn_receiver(expect);
    let mut s = HarkStreamSender::connect(&format!("127.0.0.1:{port}"), 160).expect("connect");
    s.send_with_timestamp(&results[1], 50, 1_700_000_000, 123_456)
        .expect("send");
    s.send_with_timestamp(&results[0], 0, 1_700_000_001, 0)
        .expect("send");
    let before = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs() as i64;
    s.send(&results[2], 100).expect("send");
    drop(s);
    let bytes = h.join().expect("receiver");
    assert_eq!(bytes.len(), expect);
    let d = decode_all(&bytes);
    assert_eq!(d.len(), 3);
    for (m, (r, count)) in d
        .iter()
        .zip([(&results[1], 50), (&results[0], 0), (&results[2], 100)])
    {
        assert_eq!(m.flags, 0x4, "SRC_INFO only");
        assert_eq!(m.advance, 160);
        assert_eq!(m.count, count);
        assert_eq!(m.pad, [0; 4]);
        assert_eq!(m.sources.len(), r.sources.len());
        for (got, s) in m.sources.iter().zip(&r.sources) {
            let want = (
                s.id.map_or(-1, |i| i as i32),
                s.x as f32,
                s.y as f32,
                s.z as f32,
                s.power_db as f32,
            );
            assert_eq!(*got, want);
        }
    }
    assert_eq!((d[0].tv_sec, d[0].tv_usec), (1_700_000_000, 123_456));
    assert_eq!((d[1].tv_sec, d[1].tv_usec), (1_700_000_001, 0));
    assert!((d[2].tv_sec - before).abs() <= 2 && (0..1_000_000).contains(&d[2].tv_usec));
    // The library's encoder agrees with the header size constants.
    let mut buf = Vec::new();
    hark_stream::encode(&results[1], 160, 50, 1, 2, &mut buf).unwrap();
    assert_eq!(
        buf.len(),
        hark_stream::HEADER_BYTES + 4 + 2 * hark_stream::SRC_INFO_BYTES
    );
}

#[test]
fn hark_stream_errors_are_clear() {
    // An address that does not resolve is an error at once; an absent receiver is not
    // (see hark_stream_survives_an_absent_and_restarting_receiver).
    let msg = err_text(HarkStreamSender::connect("127.0.0.1:notaport", 160));
    assert!(msg.contains("127.0.0.1:notaport"), "{msg}");
    // An id that does not fit HARK's int.
    let mut r = log_results().remove(1);
    r.sources[0].id = Some(1 << 40);
    let mut buf = Vec::new();
    let msg = err_text(hark_stream::encode(&r, 160, 0, 0, 0, &mut buf));
    assert!(msg.contains("does not fit"), "{msg}");
    assert!(buf.is_empty(), "nothing appended on error");
}
