//! Audio reader tests.
use super::flac_write::encode_flac_verbatim as encode_flac;
use super::*;
use std::path::{Path, PathBuf};

pub(crate) fn temp_dir(tag: &str) -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(0);
    let d = std::env::temp_dir().join(format!(
        "soundloc-audio-{tag}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write_int_wav(path: &Path, bits: u16, frames: &[Vec<i32>]) {
    let spec = hound::WavSpec {
        channels: frames[0].len() as u16,
        sample_rate: 16000,
        bits_per_sample: bits,
        sample_format: hound::SampleFormat::Int,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for f in frames {
        for &s in f {
            match bits {
                8 => w.write_sample(s as i8).unwrap(),
                16 => w.write_sample(s as i16).unwrap(),
                _ => w.write_sample(s).unwrap(),
            }
        }
    }
    w.finalize().unwrap();
}

fn write_float_wav(path: &Path, frames: &[Vec<f32>]) {
    let spec = hound::WavSpec {
        channels: frames[0].len() as u16,
        sample_rate: 48000,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for f in frames {
        for &s in f {
            w.write_sample(s).unwrap();
        }
    }
    w.finalize().unwrap();
}

#[test]
fn reads_int16_raw_values() {
    let d = temp_dir("i16");
    let p = d.join("a.wav");
    let frames: Vec<Vec<i32>> = (0..100).map(|i| vec![1000, -i, 32767, -32768]).collect();
    write_int_wav(&p, 16, &frames);
    let a = read_audio(&p).unwrap();
    assert_eq!(a.sample_rate_hz, 16000);
    assert_eq!((a.num_channels(), a.num_samples()), (4, 100));
    assert_eq!(a.channels[0][5], 1000.0);
    assert_eq!(a.channels[1][7], -7.0);
    assert_eq!(a.channels[2][0], 32767.0);
    assert_eq!(a.channels[3][99], -32768.0);
    assert!((a.duration_s() - 100.0 / 16000.0).abs() < 1e-12);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn reads_int24_and_int32_raw_values() {
    let d = temp_dir("i24");
    let p = d.join("a.wav");
    write_int_wav(&p, 24, &[vec![8_388_607, -8_388_608], vec![1000, -1]]);
    let a = read_audio(&p).unwrap();
    assert_eq!(
        a.channels,
        vec![vec![8_388_607.0, 1000.0], vec![-8_388_608.0, -1.0]]
    );
    let p = d.join("b.wav");
    write_int_wav(&p, 32, &[vec![1 << 30, 123], vec![-7, 0]]);
    let a = read_audio(&p).unwrap();
    assert_eq!(
        a.channels,
        vec![vec![(1u32 << 30) as f32, -7.0], vec![123.0, 0.0]]
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn reads_float32_as_is_any_channel_count() {
    let d = temp_dir("f32");
    let p = d.join("a.wav");
    let frames: Vec<Vec<f32>> = (0..10)
        .map(|i| (0..9).map(|c| i as f32 * 0.25 - c as f32).collect())
        .collect();
    write_float_wav(&p, &frames);
    let a = read_audio(&p).unwrap();
    assert_eq!(a.sample_rate_hz, 48000);
    assert_eq!((a.num_channels(), a.num_samples()), (9, 10));
    assert_eq!(a.channels[8][3], 0.75 - 8.0);
    std::fs::remove_dir_all(&d).unwrap();
}

/// A plain WAV file: format tag, bits per sample, channels, the data bytes.
fn wav_bytes(tag: u16, bits: u16, channels: u16, data: &[u8]) -> Vec<u8> {
    let fb = channels as u32 * bits as u32 / 8;
    let mut v = b"RIFF".to_vec();
    v.extend((36 + data.len() as u32).to_le_bytes());
    v.extend(b"WAVEfmt ");
    v.extend(16u32.to_le_bytes());
    v.extend(tag.to_le_bytes());
    v.extend(channels.to_le_bytes());
    v.extend(16000u32.to_le_bytes());
    v.extend((16000 * fb).to_le_bytes());
    v.extend((fb as u16).to_le_bytes());
    v.extend(bits.to_le_bytes());
    v.extend(b"data");
    v.extend((data.len() as u32).to_le_bytes());
    v.extend(data);
    v
}

#[test]
fn reads_uint8_and_float64() {
    let d = temp_dir("u8f64");
    // 8-bit PCM is unsigned: 0 → −128, 128 → 0, 255 → 127 (hound stores i8 + 128).
    let p = d.join("a.wav");
    write_int_wav(&p, 8, &[vec![-128, 0], vec![127, -1]]);
    let a = read_audio(&p).unwrap();
    assert_eq!(a.channels, vec![vec![-128.0, 127.0], vec![0.0, -1.0]]);
    // 64-bit float (what scipy.io.wavfile.write writes for float64 arrays), 3 channels.
    let x = [0.5f64, -0.25, 1e-3, 2.0, -1.0, 0.125];
    let data: Vec<u8> = x.iter().flat_map(|v| v.to_le_bytes()).collect();
    let p = d.join("b.wav");
    std::fs::write(&p, wav_bytes(3, 64, 3, &data)).unwrap();
    let a = read_audio(&p).unwrap();
    assert_eq!(
        a.channels,
        vec![vec![0.5, 2.0], vec![-0.25, -1.0], vec![1e-3f64 as f32, 0.125]]
    );
    // A float64 value beyond f32's range is an error naming the sample, not an infinity.
    let data: Vec<u8> = [1.0f64, 1e300].iter().flat_map(|v| v.to_le_bytes()).collect();
    let p = d.join("big.wav");
    std::fs::write(&p, wav_bytes(3, 64, 1, &data)).unwrap();
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(
        e.contains("big.wav")
            && e.contains("sample 1 of channel 0 is 1e300 (0-based), beyond the range of the 32-bit floats"),
        "{e}"
    );
    // The same encodings as headerless PCM (`--raw u8`, `--raw f64le`).
    let name = Path::new("-");
    let mut src = RawSource::new(
        std::io::Cursor::new(vec![0u8, 128, 255, 7]),
        RawEncoding::U8,
        2,
        8000,
        name,
    )
    .unwrap();
    let mut buf = Vec::new();
    assert_eq!(src.read_interleaved(10, &mut buf).unwrap(), 2);
    assert_eq!(buf, vec![-128.0, 0.0, 127.0, -121.0]);
    let bytes: Vec<u8> = x.iter().flat_map(|v| v.to_le_bytes()).collect();
    let mut src = RawSource::new(std::io::Cursor::new(bytes), RawEncoding::F64le, 3, 8000, name).unwrap();
    assert_eq!(src.read_interleaved(10, &mut buf).unwrap(), 2);
    assert_eq!(buf, x.iter().map(|&v| v as f32).collect::<Vec<_>>());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn reads_flac_16_and_24() {
    let d = temp_dir("flac");
    let ch16: Vec<Vec<i32>> = vec![
        (0..2500).map(|i| (i * 13 % 65536) - 32768).collect(),
        (0..2500).map(|i| -(i % 1000)).collect(),
        (0..2500).map(|_| 1000).collect(),
    ];
    let p = d.join("a.flac");
    std::fs::write(&p, encode_flac(16000, 16, &ch16)).unwrap();
    let a = read_audio(&p).unwrap();
    assert_eq!(
        (a.sample_rate_hz, a.num_channels(), a.num_samples()),
        (16000, 3, 2500)
    );
    let want: Vec<Vec<f32>> = ch16
        .iter()
        .map(|c| c.iter().map(|&s| s as f32).collect())
        .collect();
    assert_eq!(a.channels, want);
    let ch24: Vec<Vec<i32>> = vec![vec![8_388_607, -8_388_608, 1000, -1]];
    // A name without the extension: detection is by magic bytes.
    let p = d.join("noext");
    std::fs::write(&p, encode_flac(44100, 24, &ch24)).unwrap();
    let a = read_audio(&p).unwrap();
    assert_eq!(a.sample_rate_hz, 44100);
    assert_eq!(a.channels, vec![vec![8_388_607.0, -8_388_608.0, 1000.0, -1.0]]);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn errors_name_the_file() {
    let d = temp_dir("err");
    // Unreadable path.
    let e = read_audio(d.join("missing.wav")).unwrap_err();
    assert!(
        matches!(e, Error::Io { .. }) && e.to_string().contains("missing.wav"),
        "{e}"
    );
    // Empty file.
    let p = d.join("empty.wav");
    std::fs::write(&p, b"").unwrap();
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(e.contains("empty.wav") && e.contains("empty file"), "{e}");
    // Not a WAV/FLAC.
    let p = d.join("text.wav");
    std::fs::write(&p, b"hello, this is not audio").unwrap();
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(e.contains("text.wav") && e.contains("not a WAV"), "{e}");
    // Zero frames.
    let p = d.join("zero.wav");
    let spec = hound::WavSpec {
        channels: 2,
        sample_rate: 16000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    hound::WavWriter::create(&p, spec).unwrap().finalize().unwrap();
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(e.contains("zero.wav") && e.contains("no audio frames"), "{e}");
    // NaN / infinite samples.
    let p = d.join("nan.wav");
    let mut frames = vec![vec![0.0f32; 3]; 2000];
    frames[1234][2] = f32::NAN;
    write_float_wav(&p, &frames);
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(
        e.contains("nan.wav") && e.contains("sample 1234 of channel 2 is NaN"),
        "{e}"
    );
    let p = d.join("inf.wav");
    frames[1234][2] = 0.0;
    frames[7][0] = f32::NEG_INFINITY;
    write_float_wav(&p, &frames);
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(e.contains("sample 7 of channel 0 is infinite"), "{e}");
    // Unsupported bit depth (64-bit integer PCM).
    let p = d.join("i64.wav");
    std::fs::write(&p, wav_bytes(1, 64, 1, &[0u8; 16])).unwrap();
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(
        e.contains("i64.wav") && e.contains("unsupported bit depth: 64-bit integer PCM"),
        "{e}"
    );
    // Truncated data.
    let p = d.join("trunc.wav");
    write_int_wav(&p, 16, &vec![vec![5, 6]; 100]);
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() - 101]).unwrap();
    match read_audio(&p) {
        Ok(a) => assert!(a.num_samples() < 100),
        Err(e) => assert!(e.to_string().contains("trunc.wav"), "{e}"),
    }
    // Corrupt FLAC.
    let p = d.join("bad.flac");
    let mut f = encode_flac(16000, 16, &[vec![1; 100]]);
    let n = f.len();
    f[n - 10] ^= 0xff;
    std::fs::write(&p, f).unwrap();
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(e.contains("bad.flac"), "{e}");
    // FLAC cut at a frame boundary: the header of a 2048-sample stream (STREAMINFO ends at
    // byte 42) with only its first frame, or none; it was read as a shorter stream.
    let p = d.join("cut.flac");
    let long = encode_flac(16000, 16, &[(0..2048).collect()]);
    let short = encode_flac(16000, 16, &[(0..1024).collect()]);
    for (frames, kept) in [(&short[42..], 1024), (&short[short.len()..], 0)] {
        std::fs::write(&p, [&long[..42], frames].concat()).unwrap();
        let e = read_audio(&p).unwrap_err().to_string();
        assert!(
            e.contains("cut.flac")
                && e.contains(&format!(
                    "declares 2048 samples per channel, the frames hold {kept}"
                )),
            "{e}"
        );
    }
    // The whole stream reads as before.
    std::fs::write(&p, &long).unwrap();
    assert_eq!(read_audio(&p).unwrap().num_samples(), 2048);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn select_and_slice() {
    let a = Audio::new(
        10,
        vec![(0..20).map(|i| i as f32).collect(), vec![-1.0; 20], vec![2.0; 20]],
    )
    .unwrap();
    let s = a.select_channels(&[2, 0]).unwrap();
    assert_eq!(s.num_channels(), 2);
    assert_eq!(s.channels[0][0], 2.0);
    assert_eq!(s.channels[1][3], 3.0);
    let e = a.select_channels(&[0, 3]).unwrap_err().to_string();
    assert!(e.contains("channel 3") && e.contains("3 channels"), "{e}");
    assert!(a.select_channels(&[]).is_err());
    let e = a.select_channels(&[1, 0, 1]).unwrap_err().to_string();
    assert!(
        e.contains("channel 1 is selected twice (positions 0 and 2"),
        "{e}"
    );
    let t = a.slice_seconds(0.5, 1.2).unwrap();
    assert_eq!(t.num_samples(), 7);
    assert_eq!(t.channels[0][0], 5.0);
    assert!(a.slice_seconds(0.0, 2.0).is_ok());
    assert!(a.slice_seconds(1.0, 2.5).is_err());
    assert!(a.slice_seconds(1.0, 1.0).is_err());
    assert!(a.slice_seconds(-0.1, 1.0).is_err());
    assert!(a.slice_seconds(f64::NAN, 1.0).is_err());
    assert!(Audio::new(10, vec![vec![0.0; 3], vec![0.0; 2]]).is_err());
}

#[test]
fn write_wav_round_trips() {
    let d = temp_dir("write");
    let a = Audio::new(
        16000,
        vec![
            vec![1000.0, -1000.4, 40000.0, -0.6],
            vec![0.5, 1.5, -2.5, 32767.0],
        ],
    )
    .unwrap();
    let p = d.join("i16.wav");
    a.write_wav(&p, SampleFormat::Int16).unwrap();
    let b = read_audio(&p).unwrap();
    assert_eq!(b.channels[0], vec![1000.0, -1000.0, 32767.0, -1.0]);
    assert_eq!(b.channels[1], vec![1.0, 2.0, -3.0, 32767.0]);
    let p = d.join("f32.wav");
    a.write_wav(&p, SampleFormat::Float32).unwrap();
    assert_eq!(read_audio(&p).unwrap(), a);
    // Only the target file is left behind.
    let names: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2);
    std::fs::remove_dir_all(&d).unwrap();
}

/// A sum of tones sampled at `rate` for `n` frames, `ch` channels (each channel delayed).
fn tones(rate: u32, n: usize, ch: usize) -> Vec<f32> {
    let mut v = Vec::with_capacity(n * ch);
    for i in 0..n {
        for c in 0..ch {
            let t = i as f64 / rate as f64 - c as f64 * 1e-4;
            let x = 1000.0 * (2.0 * std::f64::consts::PI * 440.0 * t).sin()
                + 500.0 * (2.0 * std::f64::consts::PI * 2500.0 * t + 0.3).sin();
            v.push(x as f32);
        }
    }
    v
}

#[test]
fn resampling_keeps_band_limited_signals_and_their_timing() {
    use super::resample::Resampler;
    for (rin, rout) in [(48000u32, 16000u32), (44100, 16000), (16000, 48000)] {
        let (n, ch) = (rin as usize / 2 + 37, 3);
        let input = tones(rin, n, ch);
        let mut rs = Resampler::new(rin, rout, ch).unwrap();
        let mut out = Vec::new();
        rs.process(&input, &mut out).unwrap();
        rs.finish(&mut out).unwrap();
        // Exactly ⌈n · out / in⌉ frames.
        let want_frames = (n as u64 * rout as u64).div_ceil(rin as u64) as usize;
        assert_eq!(out.len(), want_frames * ch, "{rin} -> {rout}");
        // Sample k is the signal at time k / rout (no delay), away from the two ends.
        let reference = tones(rout, want_frames, ch);
        let edge = rout as usize / 50;
        let mut worst = 0.0f32;
        for k in edge * ch..(want_frames - edge) * ch {
            worst = worst.max((out[k] - reference[k]).abs());
        }
        assert!(worst < 2.0, "{rin} -> {rout}: worst error {worst} of 1500 peak");
    }
}

#[test]
fn resampling_does_not_depend_on_the_block_sizes() {
    use super::resample::Resampler;
    use rand::{Rng, SeedableRng};
    let ch = 4;
    let input = tones(48000, 30011, ch);
    let run = |cuts: &[usize]| {
        let mut rs = Resampler::new(48000, 16000, ch).unwrap();
        let mut out = Vec::new();
        let mut at = 0;
        for &c in cuts {
            let end = (at + c).min(30011);
            rs.process(&input[at * ch..end * ch], &mut out).unwrap();
            at = end;
        }
        rs.process(&input[at * ch..], &mut out).unwrap();
        rs.finish(&mut out).unwrap();
        out
    };
    let whole = run(&[]);
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    for _ in 0..5 {
        let cuts: Vec<usize> = (0..40).map(|_| rng.gen_range(0..2000)).collect();
        assert_eq!(run(&cuts), whole);
    }
    // One frame at a time.
    assert_eq!(run(&vec![1; 30011]), whole);
    // Gaps: output frames are skipped by position, so many gaps do not accumulate a lag.
    let mut rs = Resampler::new(48000, 16000, ch).unwrap();
    let mut sink = Vec::new();
    let skips: Vec<u64> = [1, 1, 1, 3000]
        .iter()
        .map(|&g| rs.gap(g, &mut sink).unwrap())
        .collect();
    assert_eq!((skips, sink.len()), (vec![1, 0, 0, 1000], 0));
    // Bad blocks are errors, not panics.
    assert!(rs.process(&[0.0; 5], &mut Vec::new()).is_err());
    assert!(Resampler::new(0, 16000, 2).is_err());
    // Hostile rates are errors, not gigabytes: 1 Hz input, coprime rates with many channels.
    let e = Resampler::new(1, 16000, 8).err().unwrap().to_string();
    assert!(e.contains("1 Hz") && e.contains("upsampling"), "{e}");
    let e = Resampler::new(999_983, 16000, 64).err().unwrap().to_string();
    assert!(e.contains("999983 Hz") && e.contains("common factor"), "{e}");
    // Awkward but reasonable rates still work.
    assert!(Resampler::new(44101, 16000, 60).is_ok());
    assert!(Resampler::new(8000, 16000, 2).is_ok());
}

/// Live input with many gaps: every stretch lands at its true output time (the samples
/// after the last gap match the signal at their absolute times), and the output holds
/// exactly ⌈(frames and gaps) · out / in⌉ frames.
#[test]
fn resampling_across_gaps_keeps_true_times() {
    use super::resample::Resampler;
    let ch = 2;
    let n = 48000;
    let input = tones(48000, n, ch);
    let mut rs = Resampler::new(48000, 16000, ch).unwrap();
    let mut out = Vec::new();
    let mut at = 0;
    // 40 stretches of 1001 frames, each followed by a gap of 2 frames (⌈2/3⌉ = 1 output
    // frame rounded up each time: a per-gap rounding would drift 40 samples).
    for _ in 0..40 {
        rs.process(&input[at * ch..(at + 1001) * ch], &mut out).unwrap();
        at += 1001;
        let skip = rs.gap(2, &mut out).unwrap() as usize;
        out.extend(std::iter::repeat_n(f32::NAN, skip * ch));
        at += 2;
    }
    // The last stretch starts at output frame ⌈40 120 / 3⌉: no lag accumulated.
    let start = out.len() / ch;
    assert_eq!(start, at.div_ceil(3));
    rs.process(&input[at * ch..], &mut out).unwrap();
    rs.finish(&mut out).unwrap();
    assert_eq!(out.len(), 16000 * ch);
    // Its samples, away from its edges, are the signal from input frame `at` on (output
    // frame `start` holds input time at / 48 000 s: less than one output sample early).
    let reference = tones(48000, n, ch);
    let mut worst = 0.0f32;
    for i in start + 200..16000 - 200 {
        for c in 0..ch {
            let k = at + 3 * (i - start);
            worst = worst.max((out[i * ch + c] - reference[k * ch + c]).abs());
        }
    }
    assert!(worst < 2.0, "worst error after 40 gaps: {worst}");
}

#[test]
fn a_whole_recording_resampled() {
    let a = Audio {
        sample_rate_hz: 48000,
        channels: vec![vec![0.5; 4800], vec![-0.25; 4800]],
    };
    let b = super::resample::resample_audio(&a, 16000).unwrap();
    assert_eq!(
        (b.sample_rate_hz, b.num_channels(), b.num_samples()),
        (16000, 2, 1600)
    );
    // A constant stays constant away from the edges.
    assert!(b.channels[0][100..1500].iter().all(|&x| (x - 0.5).abs() < 1e-3));
    assert!(b.channels[1][100..1500].iter().all(|&x| (x + 0.25).abs() < 1e-3));
    assert_eq!(super::resample::resample_audio(&b, 16000).unwrap(), b);
}

/// WAVE_FORMAT_EXTENSIBLE (the sub-format GUID's tag) is read like the plain header. A
/// header that contradicts itself is read packed with a note where that is unambiguous
/// (block align 0 or too small, more valid bits than the container), and refused where it
/// is not (a block align larger than the packed frame: samples in wider slots).
#[test]
fn extensible_headers_read_and_contradicting_headers_are_noted_or_refused() {
    let d = temp_dir("wavext");
    let samples: [i16; 4] = [1000, -2000, 3000, -4000];
    let data: Vec<u8> = samples.iter().flat_map(|v| v.to_le_bytes()).collect();
    // 2 channels × 16 bits, extensible: cbSize 22, valid bits, channel mask, PCM GUID.
    let ext = |valid: u16| -> Vec<u8> {
        let mut v = b"RIFF".to_vec();
        v.extend((60 + data.len() as u32).to_le_bytes());
        v.extend(b"WAVEfmt ");
        v.extend(40u32.to_le_bytes());
        v.extend(0xFFFEu16.to_le_bytes());
        v.extend(2u16.to_le_bytes());
        v.extend(16000u32.to_le_bytes());
        v.extend((16000u32 * 4).to_le_bytes());
        v.extend(4u16.to_le_bytes());
        v.extend(16u16.to_le_bytes());
        v.extend(22u16.to_le_bytes());
        v.extend(valid.to_le_bytes());
        v.extend(3u32.to_le_bytes());
        v.extend([1, 0, 0, 0, 0, 0, 0x10, 0, 0x80, 0, 0, 0xAA, 0, 0x38, 0x9B, 0x71]);
        v.extend(b"data");
        v.extend((data.len() as u32).to_le_bytes());
        v.extend(&data);
        v
    };
    let want = vec![vec![1000.0, 3000.0], vec![-2000.0, -4000.0]];
    let notes_of = |p: &Path| -> Vec<String> {
        let mut src = crate::audio::open_source(p).unwrap();
        let mut buf = Vec::new();
        while src.read_interleaved(1024, &mut buf).unwrap() > 0 {}
        src.take_notes()
    };
    let p = d.join("ext.wav");
    std::fs::write(&p, ext(16)).unwrap();
    assert_eq!(read_audio(&p).unwrap().channels, want);
    assert!(notes_of(&p).is_empty());
    let p = d.join("ext30.wav");
    std::fs::write(&p, ext(30)).unwrap();
    assert_eq!(read_audio(&p).unwrap().channels, want);
    let n = notes_of(&p).join("\n");
    assert!(
        n.contains("ext30.wav") && n.contains("30 valid bits in 16-bit samples"),
        "{n}"
    );
    // Block align 2 (one channel's size) and 0 for 2 channels of 16 bits: read packed, noted.
    for align in [2u16, 0] {
        let mut v = ext(16);
        v[32..34].copy_from_slice(&align.to_le_bytes());
        let p = d.join(format!("align{align}.wav"));
        std::fs::write(&p, v).unwrap();
        assert_eq!(read_audio(&p).unwrap().channels, want);
        let n = notes_of(&p).join("\n");
        assert!(
            n.contains(&format!(
                "block align {align} bytes, but 2 channels of 16-bit samples make 4"
            )),
            "{n}"
        );
    }
    // Block align 6 > 4: the samples may sit in wider slots; refused.
    let mut v = ext(16);
    v[32..34].copy_from_slice(&6u16.to_le_bytes());
    let p = d.join("align6.wav");
    std::fs::write(&p, v).unwrap();
    let e = read_audio(&p).unwrap_err().to_string();
    assert!(
        e.contains("align6.wav") && e.contains("block align 6 bytes") && e.contains("wider slots"),
        "{e}"
    );
}

/// The frames a source delivers in blocks of `block` before its error, and the error.
fn frames_before_error(mut s: Box<dyn AudioSource>, block: usize) -> (Vec<f32>, String) {
    let mut all = Vec::new();
    let mut buf = Vec::new();
    loop {
        match s.read_interleaved(block, &mut buf) {
            Ok(0) => return (all, String::new()),
            Ok(_) => all.extend_from_slice(&buf),
            Err(e) => return (all, e.to_string()),
        }
    }
}

#[test]
fn a_cut_file_yields_its_whole_frames_then_the_error_at_any_block_size() {
    let d = temp_dir("cut");
    // WAV: 2 channels, 3000 frames declared, the file cut after 1234.5 frames.
    let p = d.join("cut.wav");
    let frames: Vec<Vec<i32>> = (0..3000).map(|i| vec![i % 1000, -(i % 700)]).collect();
    write_int_wav(&p, 16, &frames);
    let bytes = std::fs::read(&p).unwrap();
    let header = bytes.len() - 3000 * 4;
    std::fs::write(&p, &bytes[..header + 1234 * 4 + 2]).unwrap();
    let want: Vec<f32> = frames[..1234].iter().flatten().map(|&v| v as f32).collect();
    // FLAC: 3 frames of 1024 declared, 2 present, then a third cut inside.
    let q = d.join("cut.flac");
    let ch: Vec<i32> = (0..3072).map(|i| (i * 7) % 5000 - 2500).collect();
    let long = encode_flac(16000, 16, std::slice::from_ref(&ch));
    let two = encode_flac(16000, 16, &[ch[..2048].to_vec()]);
    std::fs::write(
        &q,
        [&long[..42], &two[42..], &long[two.len()..two.len() + 40]].concat(),
    )
    .unwrap();
    let want_flac: Vec<f32> = ch[..2048].iter().map(|&v| v as f32).collect();
    for (path, want, needle) in [
        (&p, &want, "truncated WAV file"),
        (&q, &want_flac, "truncated FLAC file"),
    ] {
        for block in [1, 100, 1 << 20] {
            for from_file in [true, false] {
                let s = if from_file {
                    open_source(path).unwrap()
                } else {
                    let r = std::io::Cursor::new(std::fs::read(path).unwrap());
                    open_stream(r, path).unwrap()
                };
                let (got, e) = frames_before_error(s, block);
                assert_eq!(&got, want, "{} block {block} file {from_file}", path.display());
                assert!(e.contains(needle) && e.contains(&*path.to_string_lossy()), "{e}");
            }
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}
