//! Helpers shared by the CLI's integration tests: the binary, a per-test temporary folder,
//! the 8-mic ring scene and raw PCM of it. (Each test binary uses only some of them.)
#![allow(dead_code)]

pub mod webdriver;

use soundloc::audio::{Audio, SampleFormat};
use std::path::PathBuf;
use std::process::Command;

/// The options of raw 16-bit PCM of the 8-mic scene at 16 kHz (after the input name).
pub const RAW_S16_RING: [&str; 6] = ["--raw", "s16le", "--raw-channels", "8", "--rate", "16000"];

/// The `soundloc` binary under test.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_soundloc"))
}

/// The `soundloc` binary with SIGINT at its default disposition, for tests that stop it
/// with Ctrl-C. A test runner started in the background of a non-interactive shell (a CI
/// script, `nohup … &`) inherits SIGINT ignored, and soundloc keeps an ignored signal
/// ignored (nohup's contract), so without this such a test would wait for ever.
pub fn bin_for_ctrl_c() -> Command {
    let mut c = bin();
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        // SAFETY: signal() is async-signal-safe, as pre_exec requires.
        unsafe {
            c.pre_exec(|| {
                libc::signal(libc::SIGINT, libc::SIG_DFL);
                Ok(())
            });
        }
    }
    c
}

/// `name` in a folder of this test process (`tag` keeps test files apart).
pub fn tmp(tag: &str, name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("soundloc-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// Samples rounded and clipped to int16 values.
pub fn int16(mut audio: Audio) -> Audio {
    for c in &mut audio.channels {
        for v in c.iter_mut() {
            *v = v.round().clamp(-32768.0, 32767.0);
        }
    }
    audio
}

/// The 8-mic ring scene (talkers at 30° and −120°, 3 s, repeated `repeat` times) as int16
/// values, its geometry file and a WAV of it, named with `prefix` in `tag`'s folder.
pub fn ring_scene(tag: &str, prefix: &str, repeat: usize) -> (Audio, PathBuf, PathBuf) {
    let s = soundloc::demo::ring8_incoherent(&[30.0, -120.0], 10.0, 4).unwrap();
    let mut audio = int16(s.render());
    for c in &mut audio.channels {
        let one = c.clone();
        for _ in 1..repeat {
            c.extend_from_slice(&one);
        }
    }
    // Tests of one binary run in parallel and share these files: each is written beside
    // its name and renamed over it, so a test reading it never sees it half written (a
    // plain write truncated the geometry while another test compared its bytes).
    let beside = |p: &std::path::Path| {
        let mut t = p.as_os_str().to_owned();
        t.push(format!(".{:?}.tmp", std::thread::current().id()));
        PathBuf::from(t)
    };
    let geo = tmp(tag, &format!("{prefix}ring8.toml"));
    let t = beside(&geo);
    std::fs::write(&t, s.geometry.to_toml_string()).unwrap();
    std::fs::rename(&t, &geo).unwrap();
    let wav = tmp(tag, &format!("{prefix}ring8x{repeat}.wav"));
    let t = beside(&wav);
    audio.write_wav(&t, SampleFormat::Int16).unwrap();
    std::fs::rename(&t, &wav).unwrap();
    (audio, geo, wav)
}

/// Interleaved s16le bytes of samples `range`.
pub fn s16le(audio: &Audio, range: std::ops::Range<usize>) -> Vec<u8> {
    let mut b = Vec::new();
    for i in range {
        for c in &audio.channels {
            b.extend_from_slice(&(c[i] as i16).to_le_bytes());
        }
    }
    b
}

/// Spawn `cmd` with standard input, output and error piped.
pub fn spawn_piped(cmd: &mut Command) -> std::process::Child {
    use std::process::Stdio;
    cmd.stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}
