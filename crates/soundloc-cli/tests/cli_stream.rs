//! `soundloc localize` on streams: WAV or raw PCM on standard input, TCP (connecting and
//! listening); results as windows complete, equal to the same audio read from a file.

mod common;

use common::{bin, s16le, spawn_piped, RAW_S16_RING};
use soundloc::audio::Audio;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const OPTS: [&str; 9] = [
    "--grid",
    "ring:5",
    "--window-type",
    "past",
    "--period",
    "10",
    "--device",
    "cpu",
    "-q",
];

fn tmp(name: &str) -> PathBuf {
    common::tmp("cli-stream", name)
}

/// A fresh folder `name` of this test process.
fn tmp_dir(name: &str) -> PathBuf {
    let dir = tmp(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn scene() -> (Audio, PathBuf, PathBuf) {
    common::ring_scene("cli-stream", "", 1)
}

fn from_file(wav: &Path, geo: &Path) -> String {
    let o = bin()
        .arg("localize")
        .arg(wav)
        .arg("--geometry")
        .arg(geo)
        .args(OPTS)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = String::from_utf8(o.stdout).unwrap();
    assert!(s.lines().count() > 10, "{s}");
    s
}

/// A WAV header with the streaming placeholder size, as `arecord` writes to a pipe.
fn streaming_wav_header(channels: u16, rate: u32) -> Vec<u8> {
    let mut h = Vec::new();
    h.extend_from_slice(b"RIFF");
    h.extend_from_slice(&0xFFFF_FFFFu32.to_le_bytes());
    h.extend_from_slice(b"WAVEfmt ");
    h.extend_from_slice(&16u32.to_le_bytes());
    h.extend_from_slice(&1u16.to_le_bytes());
    h.extend_from_slice(&channels.to_le_bytes());
    h.extend_from_slice(&rate.to_le_bytes());
    h.extend_from_slice(&(rate * 2 * channels as u32).to_le_bytes());
    h.extend_from_slice(&(2 * channels).to_le_bytes());
    h.extend_from_slice(&16u16.to_le_bytes());
    h.extend_from_slice(b"data");
    h.extend_from_slice(&0xFFFF_FFFFu32.to_le_bytes());
    h
}

/// `soundloc localize tcp-listen:127.0.0.1:0` on raw ring PCM (plus `extra`): the child,
/// its stderr and the port it waits on.
fn listener(
    geo: &Path,
    extra: &[&std::ffi::OsStr],
) -> (std::process::Child, BufReader<std::process::ChildStderr>, u16) {
    let mut child = bin()
        .args(["localize", "tcp-listen:127.0.0.1:0"])
        .args(RAW_S16_RING)
        .arg("--geometry")
        .arg(geo)
        .args(&OPTS[..8])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let port = listening_port(&mut err);
    (child, err, port)
}

/// The port a `tcp-listen:…:0` run says it waits on (read from its stderr).
fn listening_port(err: &mut impl BufRead) -> u16 {
    let mut line = String::new();
    let t = Instant::now();
    loop {
        line.clear();
        assert!(
            err.read_line(&mut line).unwrap() > 0,
            "soundloc exited before listening"
        );
        if let Some(p) = line.trim().strip_prefix("soundloc: waiting for a sender on tcp:") {
            return p.rsplit(':').next().unwrap().parse::<u16>().unwrap();
        }
        assert!(t.elapsed() < Duration::from_secs(60));
    }
}

/// Read stdout lines on a thread, with the time each arrived.
fn lines_of(r: impl Read + Send + 'static) -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for l in BufReader::new(r).lines().map_while(Result::ok) {
            if tx.send(l).is_err() {
                return;
            }
        }
    });
    rx
}

#[test]
fn stdin_wav_prints_results_before_the_input_ends() {
    let (audio, geo, wav) = scene();
    let want = from_file(&wav, &geo);
    let mut child = spawn_piped(bin().args(["localize", "-", "--geometry"]).arg(&geo).args(OPTS));
    let mut stdin = child.stdin.take().unwrap();
    let rx = lines_of(child.stdout.take().unwrap());
    stdin.write_all(&streaming_wav_header(8, 16000)).unwrap();
    // The first second, slowly, in 100 ms pieces: the first PAST window (50 frames,
    // 0.5 s) completes inside it.
    for k in 0..10 {
        stdin.write_all(&s16le(&audio, k * 1600..(k + 1) * 1600)).unwrap();
        stdin.flush().unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    let first = rx
        .recv_timeout(Duration::from_secs(60))
        .expect("a result line before stdin is closed");
    assert!(first.starts_with("{\"frame\":50,"), "{first}");
    stdin
        .write_all(&s16le(&audio, 16000..audio.num_samples()))
        .unwrap();
    drop(stdin);
    let status = child.wait().unwrap();
    let mut got = vec![first];
    got.extend(rx.iter());
    assert!(status.success());
    assert_eq!(
        got.join("\n") + "\n",
        want,
        "stdin results differ from the file's"
    );
}

#[test]
fn raw_pcm_on_stdin_equals_the_file() {
    let (audio, geo, wav) = scene();
    let want = from_file(&wav, &geo);
    let bytes = s16le(&audio, 0..audio.num_samples());
    // Any pool: the main thread pushes as one of its workers where it has two or more
    // threads (`soundloc::pool`), hands over to the single worker otherwise.
    for threads in [None, Some("1"), Some("3")] {
        let mut cmd = bin();
        if let Some(t) = threads {
            cmd.env("RAYON_NUM_THREADS", t);
        }
        let mut child = spawn_piped(
            cmd.args(["localize", "-"])
                .args(RAW_S16_RING)
                .arg("--geometry")
                .arg(&geo)
                .args(OPTS),
        );
        let mut stdin = child.stdin.take().unwrap();
        // Odd-sized writes: frames split across writes.
        for c in bytes.chunks(7777) {
            stdin.write_all(c).unwrap();
        }
        drop(stdin);
        let o = child.wait_with_output().unwrap();
        assert!(
            o.status.success(),
            "{threads:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert_eq!(
            String::from_utf8(o.stdout).unwrap(),
            want,
            "RAYON_NUM_THREADS {threads:?}"
        );
    }
    // A raw file by path equals the pipe; being a file, a NaN in it or a size that is not
    // whole frames is an error naming it, before any result (a stream's NaN becomes 0
    // with a warning, so that a glitch does not end a live capture).
    let channels = audio.num_channels();
    let raw_file = |file: &Path, enc: &str| {
        bin()
            .args(["localize", file.to_str().unwrap(), "--raw", enc])
            .args(["--raw-channels", &channels.to_string(), "--rate", "16000"])
            .arg("--geometry")
            .arg(&geo)
            .args(OPTS)
            .output()
            .unwrap()
    };
    let raw = tmp("raw_pcm_file.s16");
    std::fs::write(&raw, &bytes).unwrap();
    let o = raw_file(&raw, "s16le");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(String::from_utf8(o.stdout).unwrap(), want);
    let mut f32s: Vec<u8> = (0..audio.num_samples())
        .flat_map(|i| (0..channels).map(move |c| (i, c)))
        .flat_map(|(i, c)| audio.channels[c][i].to_le_bytes())
        .collect();
    f32s[4 * (1000 * channels + 3)..4 * (1000 * channels + 4)].copy_from_slice(&f32::NAN.to_le_bytes());
    let nan = tmp("raw_pcm_nan.f32");
    std::fs::write(&nan, &f32s).unwrap();
    let cut = tmp("raw_pcm_cut.s16");
    std::fs::write(&cut, &bytes[..bytes.len() - 3]).unwrap();
    for (file, enc, want) in [
        (&nan, "f32le", "NaN"),
        (&cut, "s16le", "not a whole number of sample frames"),
    ] {
        let o = raw_file(file, enc);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{want}: {e}");
        assert!(
            e.contains(want) && e.contains(file.file_name().unwrap().to_str().unwrap()),
            "{want}: {e}"
        );
        assert!(o.stdout.is_empty(), "{want}: no results");
    }
    // --raw needs its companions.
    let o = bin()
        .args(["localize", "-", "--raw", "s16le", "--geometry"])
        .arg(&geo)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    // A WAV (or FLAC) stream given as raw PCM: its header would shift every sample (the
    // channels rotate by 6 here and the directions come out wrong), so it is refused;
    // --realtime on a pipe is refused as on a socket (a pipe arrives at its writer's pace).
    let file = std::fs::read(&wav).unwrap();
    for (extra, input, want) in [
        (&RAW_S16_RING[..], &file[..], "starts with a WAV header"),
        (
            &RAW_S16_RING[..],
            &b"fLaC\0\0\0\x22 and more"[..],
            "starts with a FLAC header",
        ),
        (&["--realtime"][..], &file[..], "--realtime paces a file; a pipe"),
    ] {
        let mut child = spawn_piped(
            bin()
                .args(["localize", "-"])
                .args(extra)
                .arg("--geometry")
                .arg(&geo)
                .args(OPTS),
        );
        let mut stdin = child.stdin.take().unwrap();
        let _ = stdin.write_all(input);
        drop(stdin);
        let o = child.wait_with_output().unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{want}: {e}");
        assert!(e.contains(want), "{want}: {e}");
        assert!(o.stdout.is_empty(), "{want}: no results");
    }
}

/// `cat rec.raw | soundloc localize -`: a pipe that delivers audio far ahead of real
/// time is read like a file, however far the localizer falls behind; nothing is dropped.
#[test]
fn a_file_piped_faster_than_real_time_loses_nothing() {
    let (audio, geo, _) = common::ring_scene("cli-stream", "long-", 8);
    // PERIOD 1: the localizer falls far behind a producer that writes everything at once.
    let opts = ["--grid", "ring:5", "--period", "1", "--device", "cpu"];
    let bytes = s16le(&audio, 0..audio.num_samples());
    let raw = tmp("long.raw");
    std::fs::write(&raw, &bytes).unwrap();
    let o = bin()
        .args(["localize"])
        .arg(&raw)
        .args(RAW_S16_RING)
        .arg("--geometry")
        .arg(&geo)
        .args(opts)
        .arg("-q")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let want = String::from_utf8(o.stdout).unwrap();
    assert!(want.lines().count() > 1000, "{} results", want.lines().count());
    let mut child = spawn_piped(
        bin()
            .args(["localize", "-"])
            .args(RAW_S16_RING)
            .arg("--geometry")
            .arg(&geo)
            .args(opts)
            .args(["--max-buffer", "4"]),
    );
    let mut stdin = child.stdin.take().unwrap();
    // (A failed run closes the pipe: its stderr, below, says why.)
    let writer = std::thread::spawn(move || stdin.write_all(&bytes).is_ok());
    let o = child.wait_with_output().unwrap();
    let _ = writer.join();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("input gap"), "{err}");
    assert!(err.contains("faster than real time"), "{err}");
    // Read like a file: no live session's progress lines (every 10 s of audio).
    assert!(!err.contains("s localized, real-time factor"), "{err}");
    assert_eq!(String::from_utf8(o.stdout).unwrap(), want, "{err}");
}

#[test]
fn tcp_listen_and_connect_equal_the_file_and_a_cut_frame_is_reported() {
    let (audio, geo, wav) = scene();
    let want = from_file(&wav, &geo);
    // soundloc listens; the test sends raw PCM, then 3 stray bytes, and hangs up.
    let (child, mut err, port) = listener(&geo, &[]);
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.write_all(&s16le(&audio, 0..audio.num_samples())).unwrap();
    s.write_all(&[1, 2, 3]).unwrap();
    drop(s);
    let mut rest = String::new();
    err.read_to_string(&mut rest).unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{rest}");
    assert_eq!(String::from_utf8(o.stdout).unwrap(), want);
    assert!(
        rest.contains(
            "ended inside a sample frame (one sample of every channel): the last 3 of 16 bytes ignored"
        ),
        "{rest}"
    );

    // soundloc connects to a sender of a WAV stream.
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = l.local_addr().unwrap();
    let data = std::fs::read(&wav).unwrap();
    let sender = std::thread::spawn(move || {
        let (mut s, _) = l.accept().unwrap();
        for c in data.chunks(10000) {
            s.write_all(c).unwrap();
        }
    });
    let o = bin()
        .arg("localize")
        .arg(format!("tcp:{addr}"))
        .arg("--geometry")
        .arg(&geo)
        .args(OPTS)
        .output()
        .unwrap();
    sender.join().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(String::from_utf8(o.stdout).unwrap(), want);
    // Nobody listening: soundloc tries again for --connect-timeout, then a clear error.
    let t = Instant::now();
    let o = bin()
        .args([
            "localize",
            &format!("tcp:{addr}"),
            "--connect-timeout",
            "0.6",
            "--geometry",
        ])
        .arg(&geo)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(t.elapsed() >= Duration::from_millis(600), "{:?}", t.elapsed());
    assert!(
        err.contains("refused the connection (no sender yet); trying again for up to 0.6 s")
            && err.contains("connecting")
            && err.contains("no sender came within 0.6 s (--connect-timeout)"),
        "{err}"
    );
    // A sender that starts listening after soundloc started: soundloc waits for it, and
    // the results are the file's (without -q, so that its note shows it was refused first).
    let child = bin()
        .args(["localize", &format!("tcp:{addr}"), "--geometry"])
        .arg(&geo)
        .args(&OPTS[..OPTS.len() - 1])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(700));
    let l = TcpListener::bind(addr).unwrap();
    let (mut s, _) = l.accept().unwrap();
    s.write_all(&std::fs::read(&wav).unwrap()).unwrap();
    drop(s);
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("refused the connection (no sender yet); trying again"),
        "{err}"
    );
    assert_eq!(String::from_utf8(o.stdout).unwrap(), want);
    drop(l);
    // --realtime paces files only; with a network source it is refused, not ignored.
    let o = bin()
        .args(["localize", &format!("tcp:{addr}"), "--realtime", "--geometry"])
        .arg(&geo)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--realtime paces a file"));
    // Waiting for a sender, a missing TF file or a channel count the array cannot take is
    // an error at once, not after a sender connected (its audio would be lost).
    // So are a busy --serve port and a receiver host that does not resolve (they were
    // found only after the sender connected, until 2026-12-02).
    let busy = TcpListener::bind("127.0.0.1:0").unwrap();
    let busy = busy.local_addr().unwrap().port().to_string();
    for (tf, channels, want, extra) in [
        ("/nonexistent/tf.zip", "8", "/nonexistent/tf.zip", &[][..]),
        ("", "6", "has 6 channels", &[][..]),
        ("", "8", "cannot listen", &["--serve", busy.as_str()][..]),
        (
            "",
            "8",
            "cannot resolve",
            &["--hark-stream", "no-such-host.invalid:5530"][..],
        ),
        (
            "",
            "8",
            "cannot resolve",
            &["--odas-ssl", "no-such-host.invalid:9001"][..],
        ),
    ] {
        let mut cmd = bin();
        cmd.args([
            "localize",
            "tcp-listen:127.0.0.1:0",
            "--raw",
            "s16le",
            "--rate",
            "16000",
        ])
        .args(["--raw-channels", channels]);
        if tf.is_empty() {
            cmd.arg("--geometry").arg(&geo);
        } else {
            cmd.args(["--tf", tf]);
        }
        cmd.args(extra);
        let mut child = cmd.stderr(Stdio::piped()).stdout(Stdio::null()).spawn().unwrap();
        let t = Instant::now();
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break Some(s);
            }
            if t.elapsed() > Duration::from_secs(20) {
                let _ = child.kill();
                break None;
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let mut err = String::new();
        child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
        assert_eq!(status.and_then(|s| s.code()), Some(2), "{want}: {err}");
        assert!(
            err.contains(want) && !err.contains("waiting for a sender"),
            "{err}"
        );
    }
}

/// A sender that resets the connection (a crash, a network drop) ends the stream as a
/// close would: what arrived is localized, every output is completed, exit 0, a warning.
#[cfg(unix)]
#[test]
fn a_reset_connection_ends_the_input_and_keeps_the_outputs() {
    use std::os::fd::AsRawFd;
    let (audio, geo, wav) = scene();
    let want = from_file(&wav, &geo);
    let out = tmp("reset.jsonl");
    let _ = std::fs::remove_file(&out);
    let (child, mut err, port) = listener(&geo, &["-o".as_ref(), out.as_os_str()]);
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.write_all(&s16le(&audio, 0..audio.num_samples())).unwrap();
    // Let it all be read, then close with SO_LINGER 0: a reset instead of a close.
    std::thread::sleep(Duration::from_millis(500));
    let linger = libc::linger {
        l_onoff: 1,
        l_linger: 0,
    };
    // SAFETY: a valid socket and a correctly sized option value.
    let rc = unsafe {
        libc::setsockopt(
            s.as_raw_fd(),
            libc::SOL_SOCKET,
            libc::SO_LINGER,
            &linger as *const libc::linger as *const libc::c_void,
            std::mem::size_of::<libc::linger>() as libc::socklen_t,
        )
    };
    assert_eq!(rc, 0);
    drop(s);
    let mut rest = String::new();
    err.read_to_string(&mut rest).unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{rest}");
    assert!(rest.contains("the sender went away"), "{rest}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), want, "{rest}");
}

/// `soundloc listen` without an array says so before looking for a microphone.
#[test]
fn listen_without_an_array_names_the_missing_option_first() {
    if !cfg!(feature = "capture") {
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED listen_without_an_array_names_the_missing_option_first: built without the capture feature"
        );
        return;
    }
    let o = bin().args(["listen", "--seconds", "1"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("no transfer functions: give --tf FILE"), "{err}");
    let o = bin()
        .args(["listen", "--seconds", "1", "--max-buffer", "1e12", "--geometry"])
        .arg(scene().1)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--max-buffer must be a number of seconds above 0 and at most 3600"),
        "{err}"
    );
}

/// `soundloc listen` through ALSA: a capture PCM of ALSA's `file` plugin (over the `null`
/// device) plays the scene's samples as a microphone would deliver them.
#[test]
fn listen_through_alsa_equals_the_file() {
    if !cfg!(feature = "capture") {
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED listen_through_alsa_equals_the_file: built without the capture feature"
        );
        return;
    }
    let (audio, geo, wav) = scene();
    let want = from_file(&wav, &geo);
    let home = tmp("alsa-home");
    std::fs::create_dir_all(&home).unwrap();
    let raw = home.join("in.raw");
    std::fs::write(&raw, s16le(&audio, 0..audio.num_samples())).unwrap();
    std::fs::write(
        home.join(".asoundrc"),
        format!(
            "pcm.!default {{\n type file\n slave.pcm \"null\"\n file \"/dev/null\"\n infile \"{}\"\n format \"raw\"\n}}\n",
            raw.display()
        ),
    )
    .unwrap();
    let o = bin()
        .env("HOME", &home)
        .args([
            "listen",
            "--channels-in",
            "8",
            "--rate",
            "16000",
            "--seconds",
            "3",
            "--geometry",
        ])
        .arg(&geo)
        .args(OPTS)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    if err.contains("no input configuration")
        || err.contains("opening a")
        || err.contains("no capture device found")
    {
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED listen_through_alsa_equals_the_file: no ALSA capture device ({err})"
        );
        return;
    }
    assert!(o.status.success(), "{err}");
    assert_eq!(String::from_utf8(o.stdout).unwrap(), want, "{err}");
}

#[test]
fn negative_numbers_parse_and_bad_values_fail_before_any_work() {
    let (_, geo, wav) = scene();
    let run = |extra: &[&str]| {
        bin()
            .arg("localize")
            .arg(&wav)
            .arg("--geometry")
            .arg(&geo)
            .args(extra)
            .output()
            .unwrap()
    };
    let o = run(&["--lower-freq", "-100"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("frequency range must satisfy 0 <= lower"), "{e}");
    let o = run(&["--max-peaks", "-5"]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("max-peaks must be -1"));
    let o = run(&["--min-deg", "-90", "--max-deg", "90", "-q", "--device", "cpu"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // HARK's spelling of the algorithms (MUSIC_ALGORITHM=SEVD) is the same value.
    let o = run(&["--algorithm", "SEVD", "-q", "--device", "cpu"]);
    let lower = run(&["--algorithm", "sevd", "-q", "--device", "cpu"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(o.stdout, lower.stdout);
    // `tf make` reads a negative value as a value (and refuses it for what it is).
    let o = bin()
        .args(["tf", "make", "--geometry"])
        .arg(&geo)
        .args(["--grid", "ring:5", "--grid-radius", "-1", "-o"])
        .arg(tmp("neg.zip"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.code() == Some(2) && e.contains("positive"), "{e}");
    let under_file = format!("{}/out.jsonl", wav.display());
    for (flags, want) in [
        (&["--plot", "x.jpg"][..], "PNG or SVG"),
        (&["--summary", "s.json"][..], "--summary needs --track"),
        (&["-o", "/nonexistent-dir/out.jsonl"][..], "does not exist"),
        (&["-o", under_file.as_str()][..], "is a file, not a folder"),
        (&["--track", "--thresh", "nan"][..], "THRESH must be finite"),
        (&["--grid", "ring:0.001"][..], "at least 0.1 degrees"),
        (&["--grid-radius", "0"][..], "grid radius must be positive"),
        // Each message names what was given (these named a noise range, an empty range
        // 1..M-1 = 0 and the channels left after selection as the file's until 2026-12-08).
        (&["--noise-segments", "0:1,2:1"][..], "--noise-segments: segment \"2:1\": need 0 <= START < END"),
        (&["--channels", "0"][..], "1 microphone: localization needs at least 2"),
        (
            &["--input-channels", "0,2,4,6"][..],
            "has 8 channels, of which --input-channels (input_channels=) picks 4, but the transfer functions have 8 microphones",
        ),
        // The queue of a live input is sized from it: a huge value is refused, not
        // allocated (it aborted before).
        (
            &["--max-buffer", "1e300"][..],
            "--max-buffer must be a number of seconds above 0 and at most 3600",
        ),
        (&["--max-buffer", "0"][..], "--max-buffer must be"),
        (
            &["--connect-timeout", "-1"][..],
            "--connect-timeout must be a number of seconds, 0 or more (got -1)",
        ),
        (&["--connect-timeout", "inf"][..], "--connect-timeout must be"),
    ] {
        let o = run(flags);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flags:?}: {e}");
        assert!(e.contains(want), "{flags:?}: {e}");
        assert!(
            o.stdout.is_empty(),
            "{flags:?}: nothing on stdout before the error"
        );
    }
}

/// A live session on stdin (raw s16le, the ring scene's first `samples`) stopped with
/// Ctrl-C after `wait`: its exit status, its stderr after "streaming from", its `-o` file
/// and the directory that holds it.
fn stopped_live_session(tag: &str, samples: usize, wait: Duration) -> (ExitStatus, String, PathBuf, PathBuf) {
    let (audio, geo, _) = scene();
    let dir = tmp_dir(tag);
    let out = dir.join("live.jsonl");
    let mut child = spawn_piped(
        common::bin_for_ctrl_c()
            .args(["localize", "-"])
            .args(RAW_S16_RING)
            .arg("--geometry")
            .arg(&geo)
            .args(&OPTS[..8])
            .arg("-o")
            .arg(&out),
    );
    let mut stdin = child.stdin.take().unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    while !line.contains("streaming from") {
        line.clear();
        assert!(err.read_line(&mut line).unwrap() > 0, "soundloc exited early");
    }
    stdin.write_all(&s16le(&audio, 0..samples)).unwrap();
    stdin.flush().unwrap();
    std::thread::sleep(wait);
    let ok = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let status = child.wait().unwrap();
    let mut rest = String::new();
    err.read_to_string(&mut rest).unwrap();
    drop(stdin);
    (status, rest, out, dir)
}

#[test]
fn ctrl_c_ends_a_live_session_cleanly() {
    let (status, rest, out, dir) = stopped_live_session("ctrlc", 24000, Duration::from_millis(1500));
    assert!(status.success(), "{rest}");
    assert!(rest.contains("stopping"), "{rest}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.lines().count() >= 10, "{text}");
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 1, "no temporary file left: {left:?}");
}

/// Ctrl-C before the first window was complete (a live session stopped at once) ends
/// cleanly: no results, a note saying why, an empty `-o` file, exit 0. It was the error a
/// too-short recording gets (exit 2, no `-o`) until 2026-12-02.
#[test]
fn ctrl_c_before_the_first_window_gives_no_results_and_no_error() {
    // 0.1 s: less than one window of 50 frames.
    let (status, rest, out, _) = stopped_live_session("ctrlc-early", 1600, Duration::from_millis(800));
    assert!(status.success(), "{rest}");
    assert!(rest.contains("no results: the audio has 1600 samples"), "{rest}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "");
}
