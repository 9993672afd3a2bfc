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
    let rows: usize = rs.iter().map(|r| r.sources.len()).sum();
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
