//! Fuzzing of the `soundloc` command line: valid command lines (localize with a geometry or
//! a TF zip and every kind of noise input, batch, tf make/inspect, noisecm make/inspect,
//! help pages) are mutated — arguments dropped, duplicated, swapped, truncated, values
//! replaced with awkward strings (negative, `nan`, `inf`, `1e308`, huge integers, empty,
//! unicode, missing folders, `/dev/null` and `/dev/full` (through links in the work folder,
//! so that nothing is ever renamed over a device), folders), numbers inside values
//! replaced, unknown and out-of-place options added — and the real binary runs each one
//! as a subprocess.
//!
//! Every run gets a fresh work folder holding only the files made here (a WAV, a FLAC, raw
//! PCM, a geometry, a TF zip, noise matrices, a manifest), with `HOME`, `XDG_CACHE_HOME`
//! and `SOUNDLOC_CACHE_DIR` pointing into it, standard input empty, one compute thread
//! (`RAYON_NUM_THREADS=1`), a 4 GiB address-space limit and a time limit. Options that
//! reach the network (`--serve`, `--hark-stream`, `--odas-ssl/--odas-sst` with a
//! `HOST:PORT`, `tcp:` inputs) and commands that run long by design (`bench`, `demo`,
//! `listen` without `--help`) are never generated. Counted per run: exit 0, a clean error
//! (exit 1 or 2 with a message on stderr), an error without a message, a panic (exit 101
//! or `panicked at`), death by a signal (e.g. an abort), a time-out.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use soundloc::array::freefield::free_field;
use soundloc::array::{Geometry, Grid};
use soundloc::audio::{flac_write::encode_flac_verbatim, Audio, SampleFormat};
use soundloc::formats::hark_zip::write_tf_zip;
use soundloc::formats::noise_cm::NoiseCm;
use std::io::Read;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod args;
pub use args::{is_safe, mutate_args};

/// How one run of the binary ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Exit status 0.
    Ok,
    /// Exit status 1 or 2 with a message on stderr.
    CleanError,
    /// Another non-zero exit status, or no message on stderr.
    OtherError,
    /// Exit status 101 or `panicked at` on stderr.
    Panic,
    /// Killed by a signal (an abort, e.g. a failed allocation, or a segfault).
    Signal,
    /// Still running at the time limit (killed).
    Timeout,
}

/// One run worth reporting: the command line and how it ended.
#[derive(Debug, Clone)]
pub struct Finding {
    /// How it ended.
    pub outcome: Outcome,
    /// The arguments after `soundloc`.
    pub args: Vec<String>,
    /// Exit status or signal, in words.
    pub status: String,
    /// The end of stderr.
    pub stderr: String,
}

impl Finding {
    /// The command line, shell-quoted, as run in the work folder.
    pub fn command_line(&self) -> String {
        let mut s = String::from("soundloc");
        for a in &self.args {
            s.push(' ');
            s.push_str(&shell_quote(a));
        }
        s
    }
}

/// What a CLI run found.
#[derive(Debug, Default, Clone)]
pub struct CliReport {
    /// Command lines run.
    pub execs: u64,
    /// Exit 0.
    pub ok: u64,
    /// Exit 1/2 with a message.
    pub clean_errors: u64,
    /// Other non-zero exits or errors without a message (see `findings`).
    pub other_errors: u64,
    /// Panics.
    pub panics: u64,
    /// Deaths by a signal.
    pub signals: u64,
    /// Time-outs.
    pub timeouts: u64,
    /// Slowest run that finished.
    pub max_exec: Duration,
    /// The first few runs of each bad kind (all but Ok and CleanError).
    pub findings: Vec<Finding>,
}

impl CliReport {
    /// Panics, signals and time-outs: what must stay 0.
    pub fn bad(&self) -> u64 {
        self.panics + self.signals + self.timeouts
    }

    /// The outcome counts in one line ("… exit 0, … clean errors, …, slowest … ms").
    pub fn counts(&self) -> String {
        format!(
            "{} exit 0, {} clean errors, {} other errors, {} panics, {} signals, {} time-outs (slowest finished run {:.0} ms)",
            self.ok,
            self.clean_errors,
            self.other_errors,
            self.panics,
            self.signals,
            self.timeouts,
            self.max_exec.as_secs_f64() * 1e3
        )
    }
}

/// How many findings of one kind are kept.
const KEEP: usize = 20;

fn shell_quote(a: &str) -> String {
    if !a.is_empty()
        && a.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"-_.,:/=+@%".contains(&b))
    {
        a.to_string()
    } else {
        format!("'{}'", a.replace('\'', r"'\''"))
    }
}

/// The files every run's work folder starts with (name, content).
pub fn input_files() -> Vec<(String, Vec<u8>)> {
    let mut rng = StdRng::seed_from_u64(3);
    let (rate, n) = (16000u32, 20000usize);
    let noise = |rng: &mut StdRng| -> Vec<Vec<f32>> {
        (0..8)
            .map(|m| {
                (0..n)
                    .map(|i| {
                        let t = i as f64 / rate as f64;
                        let tone = 3000.0 * (2.0 * std::f64::consts::PI * 1000.0 * t + m as f64).sin();
                        (tone + rng.gen_range(-500.0..500.0)).round() as f32
                    })
                    .collect()
            })
            .collect()
    };
    let rec = Audio {
        sample_rate_hz: rate,
        channels: noise(&mut rng),
    };
    let noise_only = Audio {
        sample_rate_hz: rate,
        channels: (0..8)
            .map(|_| (0..n).map(|_| rng.gen_range(-500.0f32..500.0).round()).collect())
            .collect(),
    };
    let tmp = std::env::temp_dir().join(format!("soundloc-cli-fuzz-make-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).expect("temporary folder");
    let file = |name: &str, write: &dyn Fn(&Path)| -> (String, Vec<u8>) {
        let p = tmp.join(name);
        write(&p);
        (name.to_string(), std::fs::read(&p).expect("input file"))
    };
    let geometry = Geometry::circle(8, 0.0365, 0.0);
    let tf =
        free_field(&geometry, &Grid::ring(30.0, 0.0, 1.0), 512, rate, 0..257, 343.0).expect("free-field TFs");
    let cm = NoiseCm::estimate(
        &noise_only.channels,
        rate,
        512,
        160,
        soundloc::WindowFunction::Conj,
        None,
    )
    .expect("noise estimate")
    .0;
    let ints: Vec<Vec<i32>> = rec
        .channels
        .iter()
        .map(|c| c.iter().map(|&v| v as i32).collect())
        .collect();
    let raw: Vec<u8> = (0..n)
        .flat_map(|i| ints.iter().map(move |c| c[i]))
        .flat_map(|v| (v as i16).to_le_bytes())
        .collect();
    let mut files = vec![
        file("rec.wav", &|p| {
            rec.write_wav(p, SampleFormat::Int16).expect("wav")
        }),
        file("noise.wav", &|p| {
            noise_only.write_wav(p, SampleFormat::Float32).expect("wav")
        }),
        ("take.flac".into(), encode_flac_verbatim(rate, 16, &ints)),
        ("rec.raw".into(), raw),
        ("array.toml".into(), geometry.to_toml_string().into_bytes()),
        file("tf.zip", &|p| write_tf_zip(&tf, p).expect("tf zip")),
        file("K.zip", &|p| cm.write_zip(p).expect("cm zip")),
        (
            "list.txt".into(),
            b"# recordings\nrec.wav\n\ntake.flac\n".to_vec(),
        ),
    ];
    cm.write_text_pair(&tmp.join("K_r"), &tmp.join("K_i"))
        .expect("cm text");
    for name in ["K_r", "K_i"] {
        files.push((name.into(), std::fs::read(tmp.join(name)).expect("cm text")));
    }
    let _ = std::fs::remove_dir_all(&tmp);
    files
}

/// The valid command lines mutation starts from, each with how many leading words (the
/// subcommand) are kept as they are.
pub fn seed_command_lines() -> Vec<(usize, Vec<&'static str>)> {
    let l = |s: &'static str| s.split(' ').collect::<Vec<_>>();
    vec![
        (1, l("localize rec.wav --geometry array.toml --grid ring:30 -q")),
        (1, l("localize rec.wav --geometry array.toml --grid ring:10:20 --algorithm gevd --noise noise.wav --num-sources 1 --format csv -o out.csv -q")),
        (1, l("localize rec.wav --tf tf.zip --noise-cm K.zip --algorithm gsvd --track --summary sum.json --log-text log.txt --log-xml log.xml -q")),
        (1, l("localize take.flac --geometry array.toml --grid ring:20 --algorithm srp-phat --spectrum spec.npy --plot plot.png --fft-length 256 --hop 128 --window 10 --period 10 -q")),
        (1, l("localize rec.wav --geometry array.toml --grid sphere:40 --grid-radius 2 --speed-of-sound 340 --noise-range 0:0.2 --algorithm gevd-hark --refine --normalize-bins --diagonal-loading 0.01 --min-deg -90 --max-deg 90 --lower-freq 300 --upper-freq 3000 -q")),
        (1, l("localize rec.wav --geometry array.toml --grid ring:45 --noise-segments 0:0.1,0.2:0.3 --algorithm gsvd --channels 0,1,2,3,4,5 --input-channels 0,1,2,3,4,5,6,7 -q")),
        (1, l("localize rec.wav --geometry array.toml --grid ring:45 --noise-preceding 10:2 --algorithm gevd --period 20 -q")),
        (1, l("localize rec.raw --raw s16le --raw-channels 8 --rate 16000 --geometry array.toml --grid ring:30 --max-buffer 1 -q")),
        (1, l("localize rec.wav --tf tf.zip --noise-cm K_r --algorithm gevd --track --thresh 10 --pause-length 100 --min-src-interval 10 --min-id 5 --preroll 5 --odas-ssl ssl.json --odas-sst sst.json --odas-pots 2 --odas-tracks 2 --cache-dir cache --precision f64 --device cpu -q")),
        (1, l("localize rec.wav --geometry array.toml --grid ring:30 --spectrum-weight a-weighting --window-function hamming --window-type middle --eigenvalue-weight false --denominator unsquared --subspace-dim 3 --max-peaks 0 --num-sources 2 -q")),
        (1, l("localize rec.wav --geometry array.toml --grid ring:30 --lower-freq 500 --upper-freq 600 --spectrum-weights 1,2,3 --window-type past -q")),
        (1, l("localize rec.wav --tf tf.zip --no-cache --noise noise.wav --algorithm gevd --format csv --output out.csv")),
        (1, l("batch rec.wav take.flac --out-dir out --geometry array.toml --grid ring:30 -q")),
        (1, l("batch --manifest list.txt --out-dir out --shard 0/2 --overwrite --tf tf.zip --noise-range 0:0.2 --format csv -q")),
        (2, l("tf make --builtin circle8 --grid ring:30 -o made.zip --fft-length 256")),
        (2, l("tf make --geometry array.toml --grid sphere:50 --output made.zip --grid-radius 2 --sample-rate 48000 --speed-of-sound 340")),
        (2, l("tf make --builtin sphere60 --grid ring:45:10 -o made.zip --fft-length 128")),
        (2, l("tf inspect tf.zip --json --verify")),
        (2, l("tf inspect tf.zip")),
        (2, l("noisecm make noise.wav -o Kmade.zip --range 0:0.3 --fft-length 256 --hop 128 --window-function hanning --input-channels 0,1,2")),
        (2, l("noisecm make noise.wav --output Kmade --format text")),
        (2, l("noisecm inspect K.zip --json --bins")),
        (2, l("noisecm inspect K_r,K_i")),
        (2, l("noisecm inspect K_r")),
        (1, l("bench --algorithm gsvd --mics 8 --directions 72 --window 10 --repeats 1 --help")),
        (1, l("demo --scene ring8 --snr 0 --out-dir plots --help")),
        (1, l("listen --geometry array.toml --seconds 1 --help")),
        (1, l("localize --help")),
        (2, l("help localize")),
        (0, l("--version")),
    ]
}

extern "C" {
    fn setrlimit(resource: i32, rlim: *const [u64; 2]) -> i32;
}

/// Linux's RLIMIT_AS.
const RLIMIT_AS: i32 = 9;

/// The address-space limit of every run (as the reader fuzzing's `prlimit --as`).
pub const MEMORY_LIMIT: u64 = 4 << 30;

/// Run the binary once with `args` in a fresh `work` folder holding `files`.
pub fn run_once(
    bin: &Path,
    work: &Path,
    files: &[(String, Vec<u8>)],
    args: &[String],
    timeout: Duration,
) -> (Outcome, String, String, Duration) {
    let _ = std::fs::remove_dir_all(work);
    std::fs::create_dir_all(work.join("subdir")).expect("work folder");
    // Devices by links in the work folder: an output written "whole or not at all" renames
    // its temporary file over the link, never over the device itself.
    for (link, dev) in [("dev-null", "/dev/null"), ("dev-full", "/dev/full")] {
        std::os::unix::fs::symlink(dev, work.join(link)).expect("device link");
    }
    for (name, bytes) in files {
        std::fs::write(work.join(name), bytes).expect("input file");
    }
    let mut cmd = Command::new(bin);
    cmd.args(args)
        .current_dir(work)
        .env("HOME", work)
        .env("XDG_CACHE_HOME", work.join(".cache"))
        .env("SOUNDLOC_CACHE_DIR", work.join(".cache/soundloc"))
        .env("RAYON_NUM_THREADS", "1")
        .env("RUST_BACKTRACE", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    // SAFETY: setrlimit is async-signal-safe and touches no memory of the parent.
    unsafe {
        cmd.pre_exec(|| {
            let lim = [MEMORY_LIMIT, MEMORY_LIMIT];
            if setrlimit(RLIMIT_AS, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let start = Instant::now();
    let mut child = cmd.spawn().expect("running the soundloc binary");
    let mut err_pipe = child.stderr.take().expect("stderr pipe");
    let reader = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = err_pipe.read_to_end(&mut v);
        v
    });
    let mut timed_out = false;
    let status = loop {
        if let Some(s) = child.try_wait().expect("waiting for soundloc") {
            break s;
        }
        if start.elapsed() > timeout {
            timed_out = true;
            let _ = child.kill();
            break child.wait().expect("waiting for soundloc");
        }
        std::thread::sleep(Duration::from_millis(1));
    };
    let dt = start.elapsed();
    let stderr = String::from_utf8_lossy(&reader.join().unwrap_or_default()).into_owned();
    let (outcome, st) = if timed_out {
        (Outcome::Timeout, format!("killed after {timeout:?}"))
    } else if let Some(sig) = status.signal() {
        (Outcome::Signal, format!("signal {sig}"))
    } else {
        let code = status.code().unwrap_or(-1);
        let o = if code == 101 || stderr.contains("panicked at") {
            Outcome::Panic
        } else if code == 0 {
            Outcome::Ok
        } else if (code == 1 || code == 2) && !stderr.trim().is_empty() {
            Outcome::CleanError
        } else {
            Outcome::OtherError
        };
        (o, format!("exit {code}"))
    };
    (outcome, st, stderr, dt)
}

fn tail(s: &str, n: usize) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

/// Run `iters` mutated command lines (seeded) against `bin`, each with `timeout`.
/// `progress` is called after each run with the report so far.
pub fn fuzz_cli(
    bin: &Path,
    iters: u64,
    seed: u64,
    timeout: Duration,
    mut progress: impl FnMut(&CliReport),
) -> CliReport {
    let files = input_files();
    let seeds = seed_command_lines();
    let base = std::env::temp_dir().join(format!("soundloc-cli-fuzz-{}", std::process::id()));
    let work = base.join("w");
    let mut rng = StdRng::seed_from_u64(seed);
    let mut r = CliReport::default();
    while r.execs < iters {
        let (keep, s) = &seeds[rng.gen_range(0..seeds.len())];
        // One in 20 runs is a seed unchanged.
        let args = if rng.gen_bool(0.05) {
            s.iter().map(|a| a.to_string()).collect()
        } else {
            mutate_args(&mut rng, *keep, s)
        };
        if !is_safe(&args) {
            continue;
        }
        let (outcome, status, stderr, dt) = run_once(bin, &work, &files, &args, timeout);
        r.execs += 1;
        if outcome != Outcome::Timeout {
            r.max_exec = r.max_exec.max(dt);
        }
        let count = match outcome {
            Outcome::Ok => &mut r.ok,
            Outcome::CleanError => &mut r.clean_errors,
            Outcome::OtherError => &mut r.other_errors,
            Outcome::Panic => &mut r.panics,
            Outcome::Signal => &mut r.signals,
            Outcome::Timeout => &mut r.timeouts,
        };
        *count += 1;
        let kept = r.findings.iter().filter(|f| f.outcome == outcome).count();
        if !matches!(outcome, Outcome::Ok | Outcome::CleanError) && kept < KEEP {
            r.findings.push(Finding {
                outcome,
                args,
                status,
                stderr: tail(&stderr, 12),
            });
        }
        progress(&r);
    }
    let _ = std::fs::remove_dir_all(&base);
    r
}

/// Where the `soundloc` binary is: `$SOUNDLOC_BIN`, else `target/release/soundloc` of the
/// workspace this crate is in (None when it is not there).
pub fn find_binary() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("SOUNDLOC_BIN") {
        let p = PathBuf::from(p);
        return p.is_file().then_some(p);
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let p = root.join("target/release/soundloc");
    p.is_file().then_some(p)
}
