//! HARK interoperability: noise correlation matrices (text pair and zip). (Source-location
//! logs and the HarkDataStreamSender protocol: `hark_logs.rs`.)

use std::path::{Path, PathBuf};

use num_complex::Complex;
use rand::{Rng, SeedableRng};
use soundloc::formats::hark_zip;
use soundloc::formats::noise_cm::{self, Expected, NoiseCm};

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
    // A .zip name that holds no zip is a bad zip (it was taken for a text pair's real
    // part: "cannot derive the imaginary-part file name").
    let z = re.with_file_name("k.zip");
    std::fs::write(&z, b"").unwrap();
    let e = NoiseCm::load(&z, Expected::default()).unwrap_err().to_string();
    assert!(
        e.contains("k.zip: empty file, not a noise correlation zip"),
        "{e}"
    );
    std::fs::write(&z, b"0.1 0.2\n").unwrap();
    let e = NoiseCm::load(&z, Expected::default()).unwrap_err().to_string();
    assert!(e.contains("k.zip: not a zip file"), "{e}");
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
