//! Output writers through the public API: JSON lines, CSV, .npy and plots from one set of
//! results, written to files atomically.

use soundloc::output::csv::{write_csv_file, CSV_HEADER};
use soundloc::output::jsonl::{read_jsonl_file, write_jsonl_file};
use soundloc::output::npy::{read_npy_f32_file, write_npy_f32_file};
use soundloc::output::plot::{plot_spectrum, SpectrumPlot};
use soundloc::{LocalizationResult, Source};

fn results() -> Vec<LocalizationResult> {
    (0..5)
        .map(|c| LocalizationResult {
            num_active: None,
            frame: c * 50,
            time_s: c as f64 * 0.5,
            sources: (0..c % 3)
                .map(|k| {
                    let az = (30.0 + 90.0 * k as f64).to_radians();
                    Source {
                        id: if k == 0 { Some(c as i64) } else { None },
                        grid_index: 6 + 18 * k,
                        azimuth_deg: az.to_degrees(),
                        elevation_deg: 0.0,
                        x: az.cos(),
                        y: az.sin(),
                        z: 0.0,
                        power_db: 25.0 - k as f64,
                        held: false,
                    }
                })
                .collect(),
        })
        .collect()
}

#[test]
fn all_writers_produce_consistent_files() {
    let d = std::env::temp_dir().join(format!("soundloc-it-out-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let rs = results();

    write_jsonl_file(d.join("r.jsonl"), &rs).unwrap();
    assert_eq!(read_jsonl_file(d.join("r.jsonl")).unwrap(), rs);

    write_csv_file(d.join("r.csv"), &rs).unwrap();
    let csv = std::fs::read_to_string(d.join("r.csv")).unwrap();
    // One row per source, and one for a result without sources.
    let rows: usize = rs.iter().map(|r| r.sources.len().max(1)).sum();
    assert_eq!(csv.lines().next(), Some(CSV_HEADER));
    assert_eq!(csv.lines().count(), 1 + rows);

    let (n, dirs) = (rs.len(), 72);
    let db: Vec<f32> = (0..n * dirs)
        .map(|i| ((i % dirs) as f32 * 0.3).sin() * 10.0 + 10.0)
        .collect();
    write_npy_f32_file(d.join("s.npy"), n, dirs, &db).unwrap();
    let a = read_npy_f32_file(d.join("s.npy")).unwrap();
    assert_eq!((a.rows, a.cols, &a.data), (n, dirs, &db));

    let plot = SpectrumPlot {
        times_s: rs.iter().map(|r| r.time_s).collect(),
        azimuth_deg: (0..dirs)
            .map(|k| k as f64 * 5.0 - if k > 36 { 360.0 } else { 0.0 })
            .collect(),
        elevation_deg: vec![0.0; dirs],
        db,
        peaks: rs
            .iter()
            .map(|r| r.sources.iter().map(|s| (s.azimuth_deg, s.power_db)).collect())
            .collect(),
        peak_ids: Vec::new(),
        truth_azimuths_deg: vec![30.0, 120.0],
        title: "integration".into(),
    };
    plot_spectrum(d.join("s.png"), &plot).unwrap();
    plot_spectrum(d.join("s.svg"), &plot).unwrap();
    assert!(std::fs::read_to_string(d.join("s.svg"))
        .unwrap()
        .contains("time (s)"));

    // Exactly the six files, no temporaries.
    let mut names: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["r.csv", "r.jsonl", "s.npy", "s.png", "s.svg"]);
    std::fs::remove_dir_all(&d).unwrap();
}

/// Zips (transfer functions, noise matrices) are written like every other output: a pipe
/// or device in place, never replaced by a regular file; a full device, a folder or a
/// missing folder is an error naming the file.
#[cfg(unix)]
#[test]
fn zips_write_devices_and_pipes_in_place_and_refuse_folders() {
    use soundloc::formats::hark_zip::{read_zip_entries, write_zip_entries};
    use soundloc::output::atomic::check_output_path;
    let d = std::env::temp_dir().join(format!("soundloc-it-zip-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let entries = vec![
        ("k/".to_string(), Vec::new()),
        ("k/a.txt".to_string(), b"first entry".to_vec()),
        (
            "k/b.bin".to_string(),
            (0..5000u32).map(|i| (i * 7 % 251) as u8).collect(),
        ),
    ];
    // A FIFO: the reader gets the whole zip, and the FIFO stays a FIFO.
    let fifo = d.join("pipe");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if made.is_ok_and(|s| s.success()) {
        let p = fifo.clone();
        let reader = std::thread::spawn(move || std::fs::read(p).unwrap());
        write_zip_entries(&fifo, &entries).unwrap();
        // Checked before waiting on the reader, which a replaced FIFO would leave blocked.
        assert!(!std::fs::metadata(&fifo).unwrap().is_file());
        let got = reader.join().unwrap();
        let copy = d.join("copy.zip");
        std::fs::write(&copy, &got).unwrap();
        let back = read_zip_entries(&copy).unwrap();
        assert_eq!(back["k/a.txt"], b"first entry");
        assert_eq!(back["k/b.bin"], entries[2].1);
    } else {
        println!("SKIPPED zips_write_devices_and_pipes_in_place_and_refuse_folders (FIFO part): no mkfifo");
    }
    // A full device: an error, and the device is still a device.
    if std::path::Path::new("/dev/full").exists() {
        let e = write_zip_entries(std::path::Path::new("/dev/full"), &entries).unwrap_err();
        assert!(e.to_string().contains("/dev/full"), "{e}");
        assert!(!std::fs::metadata("/dev/full").unwrap().is_file());
    }
    // A folder, and a file in a folder that does not exist.
    let e = write_zip_entries(&d, &entries).unwrap_err().to_string();
    assert!(e.contains("is a directory"), "{e}");
    let e = check_output_path(&d, "-o").unwrap_err().to_string();
    assert!(e.contains("-o: is a directory"), "{e}");
    let missing = d.join("nodir").join("K.zip");
    let e = write_zip_entries(&missing, &entries).unwrap_err().to_string();
    assert!(e.contains("K.zip") && e.contains("does not exist"), "{e}");
    let e = check_output_path(&missing, "-o").unwrap_err().to_string();
    assert!(
        e.contains("the directory") && e.contains("nodir does not exist"),
        "{e}"
    );
    assert!(!d.join("nodir").exists());
    // A regular file: replaced whole; nothing else left in the folder.
    let out = d.join("out.zip");
    std::fs::write(&out, b"old").unwrap();
    write_zip_entries(&out, &entries).unwrap();
    assert_eq!(read_zip_entries(&out).unwrap()["k/a.txt"], b"first entry");
    // No temporary file left: only what the test made.
    let mut names: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    let want: Vec<&str> = ["copy.zip", "out.zip", "pipe"]
        .into_iter()
        .filter(|n| d.join(n).exists() || *n == "out.zip")
        .collect();
    assert_eq!(names, want);
    std::fs::remove_dir_all(&d).unwrap();
}
