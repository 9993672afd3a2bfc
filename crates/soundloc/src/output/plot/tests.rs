//! Unit tests of the plots.
use super::*;

/// Two sources moving slowly on a 5°-ring grid plus a sphere-like elevation layer.
fn synthetic(rings: &[f64]) -> SpectrumPlot {
    let mut az = Vec::new();
    let mut el = Vec::new();
    for &e in rings {
        for k in 0..72 {
            az.push(wrap_az(k as f64 * 5.0));
            el.push(e);
        }
    }
    let times: Vec<f64> = (0..60).map(|i| i as f64 * 0.5).collect();
    let mut db = Vec::new();
    let mut peaks = Vec::new();
    for &t in &times {
        let s1 = 30.0 + t;
        let s2 = -120.0;
        for (j, &a) in az.iter().enumerate() {
            let d1 = wrap_az(a - s1).abs();
            let d2 = wrap_az(a - s2).abs();
            let elev_drop = el[j].abs() / 10.0;
            db.push(
                (25.0 * (-d1 * d1 / 200.0).exp() + 18.0 * (-d2 * d2 / 200.0).exp() + 2.0 - elev_drop) as f32,
            );
        }
        peaks.push(vec![(s1, 27.0), (s2, 20.0)]);
    }
    SpectrumPlot {
        times_s: times,
        azimuth_deg: az,
        elevation_deg: el,
        db,
        peak_ids: peaks
            .iter()
            .map(|l| (0..l.len()).map(|k| (k == 0).then_some(3)).collect())
            .collect(),
        peaks,
        truth_azimuths_deg: vec![30.0, -120.0],
        title: "synthetic spectrum".into(),
    }
}

fn temp_dir() -> std::path::PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(0);
    let d = std::env::temp_dir().join(format!(
        "soundloc-plot-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn the_legend_lists_the_longest_tracks() {
    // Ids 0..=9 with 10 − id peaks each except id 9 with 20, and untracked peaks.
    let mut marks = vec![(None, (0.0, 0.0))];
    for id in 0..10i64 {
        let n = if id == 9 { 20 } else { 10 - id as usize };
        marks.extend(std::iter::repeat_n((Some(id), (0.0, 0.0)), n));
    }
    let mut groups: Vec<Option<i64>> = marks.iter().map(|m| m.0).collect();
    groups.sort_unstable();
    groups.dedup();
    let listed = legend_groups(&marks, &groups);
    let want = [None, Some(0), Some(1), Some(2), Some(3), Some(4), Some(9)];
    assert_eq!(listed, want);
    // Few groups: every one.
    assert_eq!(legend_groups(&marks[..12], &groups[..3]), groups[..3].to_vec());
}

#[test]
fn heat_map_bins_max_over_elevation_and_fills_gaps() {
    let p = synthetic(&[0.0, 30.0]);
    let hm = heat_map(&p, 1000);
    assert_eq!(hm.bins, 180);
    assert_eq!(hm.edges.len(), 61);
    assert_eq!(hm.edges[60], 30.0);
    // Bin of azimuth 30° (bin 105) holds the ring-0 value (the max over elevations).
    let d = p.azimuth_deg.len();
    let j = p.azimuth_deg.iter().position(|&a| a == 30.0).unwrap();
    assert_eq!(hm.values[105], p.db[j].max(p.db[j + d / 2]));
    // No empty bins: all values finite.
    assert!(hm.values.iter().all(|v| v.is_finite()));
    // Merging columns by max.
    let hm2 = heat_map(&p, 25);
    assert_eq!(hm2.edges.len(), 21);
    assert!(hm2.values[105] >= hm.values[105]);
}

#[test]
fn renders_png() {
    let d = temp_dir();
    let path = d.join("spectrum.png");
    plot_spectrum(&path, &synthetic(&[0.0, 20.0, -20.0])).unwrap();
    let decoder = png::Decoder::new(std::fs::File::open(&path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), PLOT_SIZE);
    let px = &buf[..info.buffer_size()];
    let n = px.len() as f64;
    let mean = px.iter().map(|&v| v as f64).sum::<f64>() / n;
    let var = px.iter().map(|&v| (v as f64 - mean).powi(2)).sum::<f64>() / n;
    assert!(var > 1000.0, "pixel variance {var}");
    // Many distinct colours (heat map), and text pixels exist (dark grey/black).
    let distinct: std::collections::HashSet<&[u8]> = px.chunks(3).collect();
    assert!(distinct.len() > 50, "{} colours", distinct.len());
    // Nothing else was left in the directory.
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
    // A path without .png still gets a PNG.
    let other = d.join("spectrum.img");
    plot_spectrum(&other, &synthetic(&[0.0])).unwrap();
    assert_eq!(&std::fs::read(&other).unwrap()[..8], b"\x89PNG\r\n\x1a\n");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn renders_svg_with_labels() {
    let d = temp_dir();
    let path = d.join("spectrum.SVG");
    plot_spectrum(&path, &synthetic(&[0.0])).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with("<svg"), "{}", &text[..50]);
    for label in [
        "time (s)",
        "azimuth (deg)",
        "power (dB)",
        "synthetic spectrum",
        "true direction",
    ] {
        assert!(text.contains(label), "missing {label}");
    }
    // Twelve short tracks of five results each, and untracked peaks: the legend names
    // the untracked peaks, six ids and the six left out.
    let mut p = synthetic(&[0.0]);
    p.peak_ids = (0..p.peaks.len())
        .map(|i| vec![Some(i as i64 / 5), None])
        .collect();
    plot_spectrum(&path, &p).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let has = |label: &str| text.lines().any(|l| l.trim() == label);
    for label in ["detected peak", "source 0", "source 5", "+6 shorter sources"] {
        assert!(has(label), "missing {label}");
    }
    assert!(!has("source 6"));
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn bad_input_is_an_error_and_leaves_nothing() {
    let d = temp_dir();
    let path = d.join("x.png");
    let mut p = synthetic(&[0.0]);
    p.db.pop();
    assert!(plot_spectrum(&path, &p).is_err());
    let mut p = synthetic(&[0.0]);
    p.peaks.pop();
    assert!(plot_spectrum(&path, &p).is_err());
    let mut p = synthetic(&[0.0]);
    p.peak_ids[0].push(Some(1));
    assert!(plot_spectrum(&path, &p).is_err());
    assert!(plot_spectrum(&path, &SpectrumPlot::default()).is_err());
    assert_eq!(std::fs::read_dir(&d).unwrap().count(), 0);
    // A single result, constant spectrum, no annotations: still draws.
    let p = SpectrumPlot {
        times_s: vec![0.0],
        azimuth_deg: vec![0.0, 90.0, 180.0, -90.0],
        elevation_deg: vec![],
        db: vec![3.0; 4],
        ..Default::default()
    };
    plot_spectrum(&path, &p).unwrap();
    assert!(path.exists());
    std::fs::remove_dir_all(&d).unwrap();
}
