//! Audio I/O through the public API: simulated scenes written to WAV and read back.

use soundloc::array::Geometry;
use soundloc::audio::{read_audio, SampleFormat};
use soundloc::sim::{position_from_az_el, render, Scene, SceneSource, Signal};

fn temp_dir(tag: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("soundloc-it-audio-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn scene() -> (Scene, Geometry) {
    let geo = Geometry {
        mics: vec![
            [0.05, 0.0, 0.0],
            [0.0, 0.05, 0.0],
            [-0.05, 0.0, 0.0],
            [0.0, -0.05, 0.0],
        ],
    };
    let scene = Scene::new()
        .with_source(
            SceneSource::new(position_from_az_el(45.0, 0.0, 1.5), Signal::Speech)
                .with_gain(3000.0)
                .active_between(0.5, 2.0),
        )
        .with_source(SceneSource::new([0.0, 0.0, 0.4], Signal::Rotor).with_gain(200.0));
    (
        Scene {
            sensor_noise_std: 20.0,
            ..scene
        },
        geo,
    )
}

#[test]
fn simulated_scene_round_trips_through_wav() {
    let (scene, geo) = scene();
    let audio = render(&scene, &geo, 16000, 2.0, 1);
    let d = temp_dir("rt");
    let f32_path = d.join("scene_f32.wav");
    audio.write_wav(&f32_path, SampleFormat::Float32).unwrap();
    assert_eq!(read_audio(&f32_path).unwrap(), audio);

    let i16_path = d.join("scene_i16.wav");
    audio.write_wav(&i16_path, SampleFormat::Int16).unwrap();
    let back = read_audio(&i16_path).unwrap();
    assert_eq!((back.num_channels(), back.num_samples()), (4, 32000));
    for (a, b) in audio.channels.iter().zip(&back.channels) {
        for (x, y) in a.iter().zip(b) {
            // Raw values: int16 keeps the sample value, rounded.
            assert!((x.clamp(-32768.0, 32767.0) - y).abs() <= 0.5 + 1e-3, "{x} vs {y}");
        }
    }
    // Channel selection and time slicing on the read audio.
    let part = back
        .select_channels(&[3, 1])
        .unwrap()
        .slice_seconds(0.5, 1.5)
        .unwrap();
    assert_eq!((part.num_channels(), part.num_samples()), (2, 16000));
    assert_eq!(part.channels[0][0], back.channels[3][8000]);
    assert!((part.duration_s() - 1.0).abs() < 1e-12);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn errors_name_the_file() {
    let d = temp_dir("err");
    let p = d.join("notes.txt");
    std::fs::write(&p, "not audio at all").unwrap();
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(e.contains("notes.txt"), "{e}");
    let e = read_audio(d.join("absent.flac")).unwrap_err().to_string();
    assert!(e.contains("absent.flac"), "{e}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// Everything `src` delivers in blocks of 256 frames, and its notes.
fn read_with_notes(src: &mut dyn soundloc::audio::AudioSource) -> (Vec<f32>, Vec<String>) {
    let (mut got, mut notes, mut buf) = (Vec::new(), Vec::new(), Vec::new());
    loop {
        let n = src.read_interleaved(256, &mut buf).unwrap();
        notes.extend(src.take_notes());
        if n == 0 {
            return (got, notes);
        }
        got.extend_from_slice(&buf);
    }
}

/// A live stream (stdin, a socket) is not ended by a non-finite sample: it becomes 0, with
/// one warning naming it and a count at the end; every sample keeps its place. A file with
/// the same bytes is refused (it can be fixed and read again).
#[test]
fn a_streams_non_finite_samples_become_zero_with_a_warning() {
    use soundloc::audio::{RawEncoding, RawSource};
    let mut x: Vec<f32> = (0..3000).map(|i| (i % 17) as f32).collect();
    x[1001] = f32::NAN;
    x[2500] = f32::INFINITY;
    let bytes: Vec<u8> = x.iter().flat_map(|v| v.to_le_bytes()).collect();
    let name = std::path::Path::new("-");
    let mut src = RawSource::new(
        std::io::Cursor::new(bytes.clone()),
        RawEncoding::F32le,
        2,
        16000,
        name,
    )
    .unwrap();
    let (got, notes) = read_with_notes(&mut src);
    let mut want = x.clone();
    want[1001] = 0.0;
    want[2500] = 0.0;
    assert_eq!(got, want);
    assert_eq!(notes.len(), 2, "{notes:?}");
    assert!(
        notes[0].starts_with("warning: -: sample 500 of channel 1 is NaN"),
        "{notes:?}"
    );
    assert!(
        notes[1].contains("2 non-finite or out-of-range samples were replaced by 0"),
        "{notes:?}"
    );
    // A finite sample beyond any converter's range (1e20: an uninitialised buffer, or
    // s16 read as f32le) is such a glitch too; 1e14 itself is kept.
    let mut y = x.clone();
    y[1001] = 0.0;
    y[2500] = 1e14;
    y[2701] = -1e20;
    let bytes: Vec<u8> = y.iter().flat_map(|v| v.to_le_bytes()).collect();
    let mut src = RawSource::new(std::io::Cursor::new(bytes), RawEncoding::F32le, 2, 16000, name).unwrap();
    let (got, notes) = read_with_notes(&mut src);
    y[2701] = 0.0;
    assert_eq!(got, y);
    assert!(
        notes.len() == 2
            && notes[0].starts_with("warning: -: sample 1350 of channel 1 is -1e20, beyond ±1e14")
            && notes[1].contains("1 non-finite or out-of-range samples"),
        "{notes:?}"
    );
    // A WAV file with a NaN is still an error.
    let d = temp_dir("nan-file");
    let p = d.join("nan.wav");
    let mut a = soundloc::audio::Audio {
        sample_rate_hz: 16000,
        channels: vec![vec![0.5; 100], vec![0.25; 100]],
    };
    a.channels[1][40] = f32::NAN;
    a.write_wav(&p, SampleFormat::Float32).unwrap();
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(e.contains("sample 40 of channel 1 is NaN"), "{e}");
}
