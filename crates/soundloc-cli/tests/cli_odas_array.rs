//! An ODAS user's array file (`odaslive -c array.cfg`) as `--geometry`: positions from
//! `general.mics`, and the device's channels mapped to the microphones by `mapping.map`.

mod common;

use common::{bin, ring_scene, tmp};
use soundloc::audio::{Audio, SampleFormat};
use std::path::{Path, PathBuf};
use std::process::Output;

/// An ODAS configuration of `mics` whose microphone i is on device channel 10 − i
/// (1-based) of a 10-channel device: mapping.map = (10, 9, …, 3).
fn odas_cfg(mics: &[[f64; 3]], path: &Path) {
    let mut t = String::from(
        "version = \"2.1\";\nraw: {\n    fS = 16000;\n    nChannels = 10;\n    interface: { type = \"soundcard\"; card = 1; device = 0; }\n}\n",
    );
    let map: Vec<String> = (0..mics.len()).map(|i| (10 - i).to_string()).collect();
    t.push_str(&format!("mapping: {{ map: ({}); }}\n", map.join(", ")));
    t.push_str(
        "general: {\n    epsilon = 1E-20;\n    speedofsound: { mu = 343.0; sigma2 = 25.0; };\n    mics = (\n",
    );
    for (i, m) in mics.iter().enumerate() {
        t.push_str(&format!(
            "        # Microphone {}\n        {{ mu = ( {:+.6}, {:+.6}, {:+.6} ); direction = ( +0.000, +0.000, +1.000 ); angle = ( 80.0, 100.0 ); }}{}\n",
            i + 1,
            m[0],
            m[1],
            m[2],
            if i + 1 < mics.len() { "," } else { "" }
        ));
    }
    t.push_str("    );\n    nThetas = 181;\n};\n");
    std::fs::write(path, t).unwrap();
}

fn localize(wav: &Path, cfg: &Path) -> Output {
    bin()
        .arg("localize")
        .arg(wav)
        .arg("--geometry")
        .arg(cfg)
        .args(["--grid", "ring:5", "--device", "cpu", "--num-sources", "2"])
        .output()
        .unwrap()
}

/// Azimuths found in every window after the first second, rounded to the grid.
fn azimuths(o: &Output) -> Vec<Vec<i64>> {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let results = soundloc::output::jsonl::read_jsonl(&o.stdout[..], Path::new("stdout")).unwrap();
    results
        .iter()
        .filter(|r| r.time_s >= 1.0)
        .map(|r| {
            let mut a: Vec<i64> = r.sources.iter().map(|s| s.azimuth_deg.round() as i64).collect();
            a.sort();
            a
        })
        .collect()
}

fn write(path: PathBuf, channels: Vec<Vec<f32>>) -> PathBuf {
    Audio::new(16000, channels)
        .unwrap()
        .write_wav(&path, SampleFormat::Int16)
        .unwrap();
    path
}

#[test]
fn an_odas_configuration_maps_the_device_channels_to_its_microphones() {
    let (audio, geo, _) = ring_scene("cli-odas", "", 1);
    let mics = soundloc::array::Geometry::load(&geo).unwrap().mics;
    let cfg = tmp("cli-odas", "ring8.cfg");
    odas_cfg(&mics, &cfg);
    // The device's 10 channels: microphone i on channel 9 − i (0-based); channels 0 and 1
    // carry a loud tone that is no microphone's.
    let n = audio.num_samples();
    let tone: Vec<f32> = (0..n).map(|t| 8000.0 * (t as f32 * 0.37).sin()).collect();
    let mut device = vec![tone.clone(), tone];
    for c in 2..10 {
        device.push(audio.channels[9 - c].clone());
    }
    let device_wav = write(tmp("cli-odas", "device10.wav"), device);
    let mics_wav = write(tmp("cli-odas", "mics8.wav"), audio.channels.clone());

    let from_device = azimuths(&localize(&device_wav, &cfg));
    assert!(from_device.len() >= 3);
    for a in &from_device {
        // Talkers at −120° and 30° (the ring scene); a mapping in the wrong order would
        // mirror them, one ignored would refuse 10 channels for 8 microphones.
        assert!(
            a.len() == 2 && (a[0] + 120).abs() <= 5 && (a[1] - 30).abs() <= 5,
            "{a:?}"
        );
    }
    // A recording of the microphones alone, in the file's order, is taken as it is: the
    // same results.
    assert_eq!(azimuths(&localize(&mics_wav, &cfg)), from_device);

    // Any other channel count is named with both choices.
    let nine = write(
        tmp("cli-odas", "nine.wav"),
        audio.channels[..8]
            .iter()
            .chain([&audio.channels[0]])
            .cloned()
            .collect(),
    );
    let o = localize(&nine, &cfg);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("nine.wav")
            && err.contains("has 9 channels")
            && err.contains("maps 8 of a 10-channel device"),
        "{err}"
    );
    // An explicit --input-channels wins over the file's map.
    let picked: Vec<String> = (2..10).rev().map(|c| c.to_string()).collect();
    let o = bin()
        .arg("localize")
        .arg(&device_wav)
        .arg("--geometry")
        .arg(&cfg)
        .args([
            "--grid",
            "ring:5",
            "--device",
            "cpu",
            "--num-sources",
            "2",
            "--input-channels",
        ])
        .arg(picked.join(","))
        .output()
        .unwrap();
    assert_eq!(azimuths(&o), from_device);

    // A broken configuration names the file and the line.
    let bad = tmp("cli-odas", "bad.cfg");
    std::fs::write(
        &bad,
        std::fs::read_to_string(&cfg)
            .unwrap()
            .replace("map: (10,", "map: (11,"),
    )
    .unwrap();
    let o = localize(&device_wav, &bad);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("bad.cfg: mapping.map[0] is 11: channels are numbered 1..=10"),
        "{err}"
    );
}
