//! HARK interoperability: noise correlation matrices (text pair and zip), source-location
//! logs (text and XML), and the HarkDataStreamSender protocol.

use std::io::Read;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use num_complex::Complex;
use rand::{Rng, SeedableRng};
use soundloc::formats::hark_zip;
use soundloc::formats::noise_cm::{self, Expected, NoiseCm};
use soundloc::formats::source_log::{self, SourceLogFormat};
use soundloc::output::hark_stream::{self, HarkStreamSender};
use soundloc::{LocalizationResult, Source};

/// A fresh, empty temporary folder for one test.
fn tmp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("soundloc-hark-interop-{}-{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("create temp dir");
    d
}

/// Random Hermitian positive semi-definite matrices (Σ v vᴴ), scaled like PCM powers.
fn random_cm(m: usize, nfft: usize, seed: u64) -> NoiseCm {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let bins = nfft / 2 + 1;
    let mut data = vec![Complex::new(0.0, 0.0); bins * m * m];
    for k in 0..bins {
        for _ in 0..m + 2 {
            let v: Vec<Complex<f64>> = (0..m)
                .map(|_| Complex::new(rng.gen_range(-300.0..300.0), rng.gen_range(-300.0..300.0)))
                .collect();
            for i in 0..m {
                for j in 0..m {
                    data[k * m * m + i * m + j] += v[i] * v[j].conj();
                }
            }
        }
    }
    NoiseCm::new(m, nfft, data).expect("valid shape")
}

fn err_text<T: std::fmt::Debug>(r: soundloc::Result<T>) -> String {
    format!("{:#}", r.expect_err("expected an error"))
}

// ---------------------------------------------------------------- noise correlation ---

#[test]
fn noise_cm_text_pair_round_trip_is_exact() {
    let d = tmp_dir("cm-text");
    let cm = random_cm(4, 16, 1);
    let (re, im) = (d.join("noise_r.dat"), d.join("noise_i.dat"));
    cm.write_text_pair(&re, &im).expect("write");
    let text = std::fs::read_to_string(&re).expect("read back");
    assert_eq!(text.lines().count(), 9, "one line per bin");
    assert!(
        text.lines().all(|l| l.split(' ').count() == 16),
        "M² numbers per line"
    );
    // Column i·M + j of line k is Re K_k(i, j).
    let v: f64 = text
        .lines()
        .nth(3)
        .unwrap()
        .split(' ')
        .nth(4 + 2)
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(v, cm.get(3)[6].re);
    let back = NoiseCm::load(
        &re,
        Expected {
            num_mics: Some(4),
            nfft: Some(16),
        },
    )
    .expect("load");
    assert_eq!(back, cm);
    assert_eq!(back.num_bins(), 9);
    assert!(back.try_get(9).is_none());
    let explicit = NoiseCm::read_text_pair(&re, &im, Expected::default()).expect("pair");
    assert_eq!(explicit, cm);
    // A recording given in its place is named as one.
    let wav = re.with_file_name("noise.wav");
    soundloc::audio::Audio::new(16000, vec![vec![0.1; 160]; 4])
        .unwrap()
        .write_wav(&wav, soundloc::audio::SampleFormat::Int16)
        .unwrap();
    let e = NoiseCm::load(&wav, Expected::default()).unwrap_err().to_string();
    assert!(
        e.contains("noise.wav: a recording (WAV/FLAC), not a noise correlation matrix"),
        "{e}"
    );
}

#[test]
fn noise_cm_zip_round_trip_in_single_precision() {
    let d = tmp_dir("cm-zip");
    let cm = random_cm(3, 32, 2);
    let p = d.join("noise.zip");
    cm.write_zip(&p).expect("write zip");
    let entries = hark_zip::read_zip_entries(&p).expect("entries");
    assert_eq!(
        std::str::from_utf8(&entries["correlationMatrix/whatisthis.txt"]).unwrap(),
        "correlation matrix"
    );
    assert!(entries.contains_key("correlationMatrix/localization/cm00016.mat"));
    let back = NoiseCm::load(
        &p,
        Expected {
            num_mics: Some(3),
            nfft: Some(32),
        },
    )
    .expect("load zip");
    assert_eq!((back.num_mics, back.nfft), (3, 32));
    for (a, b) in back.data.iter().zip(&cm.data) {
        assert!((a - b).norm() <= 1e-6 * b.norm().max(1.0), "{a} vs {b}");
    }
}

#[test]
fn noise_cm_zip_reader_tolerates_folder_and_file_names() {
    let d = tmp_dir("cm-zip-names");
    let cm = NoiseCm::identity(2, 4);
    // Another root folder, matrices named tf%05d.mat straight under it, no XML at all.
    let mut e = vec![(
        "noiseCM/whatisthis.txt".to_string(),
        b"correlation matrix\n".to_vec(),
    )];
    for k in 0..3 {
        let (_, bytes) = cm
            .zip_entries()
            .unwrap()
            .into_iter()
            .find(|(n, _)| n.ends_with(&format!("cm{k:05}.mat")))
            .unwrap();
        e.push((format!("noiseCM/tf{k:05}.mat"), bytes));
    }
    let p = d.join("odd.zip");
    hark_zip::write_zip_entries(&p, &e).expect("write");
    assert_eq!(NoiseCm::load(&p, Expected::default()).expect("load"), cm);
}

#[test]
fn imaginary_file_is_found_by_hark_naming() {
    let c = |s: &str| {
        noise_cm::imag_path_candidates(Path::new(s))
            .into_iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
    };
    assert_eq!(c("d/noise_r.dat"), vec!["d/noise_i.dat"]);
    assert_eq!(c("cmr.dat"), vec!["cmi.dat"]);
    assert_eq!(c("cm_real.txt"), vec!["cm_imag.txt"]);
    assert_eq!(c("cm.real"), vec!["cm.imag"]);
    assert_eq!(c("cm_re.txt"), vec!["cm_im.txt"]);
    assert_eq!(c("NOISE_R.DAT"), vec!["NOISE_I.DAT"]);
    assert!(c("noise.dat").is_empty());
    let d = tmp_dir("cm-noname");
    let p = d.join("noise.dat");
    std::fs::write(&p, "1 0 0 1\n1 0 0 1\n").unwrap();
    let msg = err_text(NoiseCm::load(&p, Expected::default()));
    assert!(
        msg.contains("noise.dat") && msg.contains("give both as REAL,IMAG"),
        "{msg}"
    );
    let p = d.join("cm_r.dat");
    std::fs::write(&p, "1 0 0 1\n1 0 0 1\n").unwrap();
    let msg = err_text(NoiseCm::load(&p, Expected::default()));
    assert!(msg.contains("cm_i.dat") && msg.contains("not found"), "{msg}");
}

/// Writes a valid 2-mic, nfft-8 pair, lets `edit` change the (real, imag) texts, and
/// returns the load error text.
fn broken_pair(tag: &str, expected: Expected, edit: impl Fn(&mut String, &mut String)) -> String {
    let d = tmp_dir(tag);
    let (re, im) = (d.join("cm_r.txt"), d.join("cm_i.txt"));
    random_cm(2, 8, 3).write_text_pair(&re, &im).unwrap();
    let mut r = std::fs::read_to_string(&re).unwrap();
    let mut i = std::fs::read_to_string(&im).unwrap();
    edit(&mut r, &mut i);
    std::fs::write(&re, r).unwrap();
    std::fs::write(&im, i).unwrap();
    err_text(NoiseCm::load(&re, expected))
}

#[test]
fn noise_cm_text_errors_name_file_and_line() {
    // Truncated: the last line of the imaginary part cut in the middle.
    let msg = broken_pair("cm-trunc", Expected::default(), |_, i| {
        let cut = i.trim_end().rfind(' ').unwrap();
        i.truncate(cut);
    });
    assert!(
        msg.contains("cm_i.txt") && msg.contains("line 5") && msg.contains("expected 4"),
        "{msg}"
    );
    // A missing line (bin count) against the expected nfft.
    let msg = broken_pair(
        "cm-lines",
        Expected {
            num_mics: None,
            nfft: Some(8),
        },
        |r, _| {
            let n = r.trim_end().rfind('\n').unwrap();
            r.truncate(n + 1);
        },
    );
    assert!(
        msg.contains("cm_r.txt") && msg.contains("4 lines, expected 5"),
        "{msg}"
    );
    // Wrong channel count.
    let msg = broken_pair(
        "cm-mics",
        Expected {
            num_mics: Some(3),
            nfft: None,
        },
        |_, _| {},
    );
    assert!(
        msg.contains("cm_r.txt") && msg.contains("line 1") && msg.contains("3 microphones"),
        "{msg}"
    );
    // Not M² columns.
    let msg = broken_pair("cm-cols", Expected::default(), |r, _| {
        *r = r.lines().map(|l| format!("{l} 1.0\n")).collect();
    });
    assert!(
        msg.contains("cm_r.txt") && msg.contains("line 1") && msg.contains("not M²"),
        "{msg}"
    );
    // NaN.
    let msg = broken_pair("cm-nan", Expected::default(), |_, i| {
        let mut lines: Vec<String> = i.lines().map(String::from).collect();
        let mut toks: Vec<&str> = lines[2].split(' ').collect();
        toks[1] = "NaN";
        lines[2] = toks.join(" ");
        *i = lines.join("\n") + "\n";
    });
    assert!(
        msg.contains("cm_i.txt") && msg.contains("line 3, column 2") && msg.contains("not finite"),
        "{msg}"
    );
    // Not a number.
    let msg = broken_pair("cm-word", Expected::default(), |r, _| {
        *r = r.replacen(' ', " x1 ", 1);
    });
    assert!(
        msg.contains("cm_r.txt") && msg.contains("line 1, column 2") && msg.contains("not a number"),
        "{msg}"
    );
    // Non-Hermitian: K(0, 1) changed in the real part of bin 3 only.
    let msg = broken_pair("cm-herm", Expected::default(), |r, _| {
        let mut lines: Vec<String> = r.lines().map(String::from).collect();
        let mut toks: Vec<String> = lines[3].split(' ').map(String::from).collect();
        let v: f64 = toks[1].parse().unwrap();
        toks[1] = format!("{:e}", v + 1e5);
        lines[3] = toks.join(" ");
        *r = lines.join("\n") + "\n";
    });
    assert!(
        msg.contains("cm_r.txt") && msg.contains("line 4 (bin 3") && msg.contains("not Hermitian"),
        "{msg}"
    );
    // Real and imaginary files of different sizes.
    let msg = broken_pair("cm-sizes", Expected::default(), |_, i| {
        let first = i.lines().next().unwrap().to_owned();
        i.push_str(&first);
        i.push('\n');
    });
    assert!(
        msg.contains("cm_i.txt") && msg.contains("6 lines") && msg.contains("cm_r.txt"),
        "{msg}"
    );
    // Empty file.
    let msg = broken_pair("cm-empty", Expected::default(), |r, _| r.clear());
    assert!(msg.contains("cm_r.txt") && msg.contains("empty"), "{msg}");
}

#[test]
fn noise_cm_zip_errors_name_the_file() {
    let d = tmp_dir("cm-zip-bad");
    let good = d.join("good.zip");
    random_cm(2, 8, 4).write_zip(&good).unwrap();
    // A K the readers would refuse is not written, in either format.
    let mut nan = random_cm(2, 8, 4);
    nan.data[4 + 2 + 1].re = f64::NAN; // M = 2: bin 1, row 1, column 1
    let msg = err_text(nan.write_zip(&d.join("nan.zip")));
    assert!(
        msg.contains("nan.zip") && msg.contains("K at bin 1: K(1, 1) = NaN") && msg.contains("is not finite"),
        "{msg}"
    );
    let msg = err_text(nan.write_text_pair(&d.join("nan_r"), &d.join("nan_i")));
    assert!(msg.contains("nan_r") && msg.contains("not finite"), "{msg}");
    assert!(!d.join("nan.zip").exists() && !d.join("nan_r").exists());
    // Truncated archive.
    let bytes = std::fs::read(&good).unwrap();
    let cut = d.join("cut.zip");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let msg = err_text(NoiseCm::load(&cut, Expected::default()));
    assert!(msg.contains("cut.zip"), "{msg}");
    // Wrong expectations.
    let msg = err_text(NoiseCm::load(
        &good,
        Expected {
            num_mics: Some(4),
            nfft: None,
        },
    ));
    assert!(msg.contains("good.zip") && msg.contains("4 microphones"), "{msg}");
    let msg = err_text(NoiseCm::load(
        &good,
        Expected {
            num_mics: None,
            nfft: Some(16),
        },
    ));
    assert!(msg.contains("good.zip") && msg.contains("expected 9"), "{msg}");
    // A transfer-function zip is refused.
    let mut e = random_cm(2, 8, 4).zip_entries().unwrap();
    e[1].1 = b"transfer function".to_vec();
    let tf = d.join("tf.zip");
    hark_zip::write_zip_entries(&tf, &e).unwrap();
    let msg = err_text(NoiseCm::load(&tf, Expected::default()));
    assert!(
        msg.contains("tf.zip") && msg.contains("transfer function"),
        "{msg}"
    );
    // Non-Hermitian and missing bin.
    let mut cm = random_cm(2, 8, 4);
    cm.data[2 * 4 + 1] += Complex::new(0.0, 5000.0);
    let mut e = cm.zip_entries().unwrap();
    let nh = d.join("nh.zip");
    hark_zip::write_zip_entries(&nh, &e).unwrap();
    let msg = err_text(NoiseCm::load(&nh, Expected::default()));
    assert!(
        msg.contains("nh.zip") && msg.contains("cm00002.mat") && msg.contains("not Hermitian"),
        "{msg}"
    );
    e.retain(|(n, _)| !n.ends_with("cm00001.mat"));
    let gap = d.join("gap.zip");
    hark_zip::write_zip_entries(&gap, &e).unwrap();
    let msg = err_text(NoiseCm::load(&gap, Expected::default()));
    assert!(
        msg.contains("gap.zip") && msg.contains("bin 1 is missing"),
        "{msg}"
    );
}

#[test]
fn noise_cm_validate_rejects_nan_and_bad_shape() {
    let mut cm = NoiseCm::identity(2, 8);
    assert!(cm.validate(Path::new("x")).is_ok());
    cm.data[5] = Complex::new(f64::NAN, 0.0);
    let msg = cm.validate(Path::new("mem.cm")).unwrap_err().to_string();
    assert!(
        msg.contains("mem.cm") && msg.contains("bin 1") && msg.contains("not finite"),
        "{msg}"
    );
    assert!(NoiseCm::new(2, 8, vec![Complex::new(0.0, 0.0); 19]).is_err());
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
