//! Soak: ten minutes of 8-channel audio pushed in 10 ms blocks, PERIOD 10, tracking on:
//! results keep coming and resident memory stays flat (measured after the first minute
//! and at the end). `scripts/soak.sh` runs the same for an hour and prints the figures.

use soundloc::backend::DeviceChoice;
use soundloc::{
    Algorithm, Block, LocalizeConfig, Localizer, LocalizerSpec, NoiseSource, Output, TrackingSpec, WindowType,
};

fn rss_kib() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    s.lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
}

#[test]
fn ten_minutes_in_10_ms_blocks_with_flat_memory() {
    let minutes: f64 = std::env::var("SOUNDLOC_SOAK_MINUTES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10.0);
    let geometry = soundloc::array::Geometry::circle(8, 0.0365, 0.0);
    let mut spec = LocalizerSpec::free_field(
        geometry.mics.clone(),
        soundloc::array::grid::GridSpec::Ring {
            step_deg: 5.0,
            elevation_deg: 0.0,
        },
    );
    spec.analysis = LocalizeConfig {
        window_type: WindowType::Past,
        period: 10,
        ..LocalizeConfig::default()
    };
    spec.algorithm = Some(Algorithm::Gevd);
    spec.noise = NoiseSource::Range {
        start_s: 0.0,
        end_s: 1.0,
    };
    spec.tracking = Some(TrackingSpec::default());
    spec.device = DeviceChoice::Cpu;
    let mut loc = Localizer::new(&spec).unwrap();
    // A source circling the array once a minute (plane wave, fractional delays by phase
    // of a few tones) over uncorrelated noise; deterministic.
    let fs = 16000.0;
    let block = 160;
    let total_blocks = (minutes * 60.0 * fs / block as f64) as usize;
    let mut state = 0x2545F4914F6CDD1Du64;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut out = Output::default();
    let mut buf = vec![0f32; block * 8];
    let (mut results, mut rss_1min, mut azimuth_ok) = (0usize, None, 0usize);
    for k in 0..total_blocks {
        for i in 0..block {
            let n = k * block + i;
            let t = n as f64 / fs;
            let az = (t / 60.0 * 360.0).to_radians();
            for (m, p) in geometry.mics.iter().enumerate() {
                let delay = -(p[0] * az.cos() + p[1] * az.sin()) / 343.0;
                let s: f64 = [700.0, 1100.0, 1700.0, 2300.0]
                    .iter()
                    .map(|f| (2.0 * std::f64::consts::PI * f * (t - delay)).sin())
                    .sum();
                let talking = t >= 1.0;
                buf[i * 8 + m] = (if talking { 1000.0 * s } else { 0.0 } + 100.0 * noise()) as f32;
            }
        }
        loc.push(
            Block::Interleaved {
                data: &buf,
                channels: 8,
            },
            &mut out,
        )
        .unwrap();
        for r in out.results.drain(..) {
            results += 1;
            let truth = (r.time_s / 60.0 * 360.0 + 180.0).rem_euclid(360.0) - 180.0;
            if let Some(s) = r.sources.first() {
                let d = (s.azimuth_deg - truth + 540.0).rem_euclid(360.0) - 180.0;
                azimuth_ok += usize::from(r.time_s > 1.5 && d.abs() <= 10.0);
            }
        }
        if k == (60.0 * fs) as usize / block {
            rss_1min = rss_kib();
        }
    }
    loc.flush(&mut out).unwrap();
    let rss_end = rss_kib();
    let expected = (minutes * 60.0 * fs - 512.0) / 160.0 / 10.0;
    assert!(
        (results as f64 - expected).abs() < 10.0,
        "{results} results, expected ~{expected}"
    );
    assert!(
        azimuth_ok as f64 >= 0.9 * results as f64,
        "{azimuth_ok} of {results} results on the moving source"
    );
    match (rss_1min, rss_end) {
        (Some(a), Some(b)) => {
            eprintln!("soak: {minutes} min, {results} results, RSS {a} KiB after 1 min, {b} KiB at the end");
            assert!(b <= a + 8 * 1024, "resident memory grew from {a} KiB to {b} KiB");
        }
        _ => eprintln!("SKIPPED soak memory check: /proc/self/status not readable"),
    }
}
