//! Mutation fuzzing of every file reader soundloc has: WAV, FLAC, HARK TF zip, HGTF, noise
//! correlation matrices (text pair and zip), geometry TOML and source-location logs (text
//! and XML).
//!
//! Each [`Target`] starts from valid files it makes itself and produces inputs by seeded
//! mutation: byte-level edits (bit flips, random and "interesting" integers over header
//! fields, insertions, deletions, duplications, truncation), number swaps in text formats,
//! and — for zips — edits of one entry's content re-zipped with valid CRCs, so the XML and
//! matrix parsers behind the container are reached too. [`run`] writes each input to a
//! file, calls the reader under `catch_unwind`, and counts: accepted, refused with an
//! error that names the file (as every error must), refused without naming it, panics and
//! slow executions. The suite runs 2000 inputs per target
//! (`tests/mutation.rs`); `soundloc-fuzz` runs millions (FUZZING.md).
//!
//! The same targets serve the coverage-guided harness in `fuzz/` (cargo-afl): it takes a
//! target's [`Target::file_name`], [`Target::companions`] and [`Target::read`], and its seed
//! corpus from [`write_seeds`]. [`cli`] fuzzes the `soundloc` command line.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use soundloc::array::freefield::free_field;
use soundloc::array::{Geometry, Grid, TransferFunctions};
use soundloc::audio::{flac_write::encode_flac_verbatim, open_source, Audio, SampleFormat};
use soundloc::formats::hark_zip::{read_zip_entries, write_tf_zip, write_zip_entries};
use soundloc::formats::noise_cm::{Expected, NoiseCm};
use soundloc::formats::source_log;
use soundloc::result::{LocalizationResult, Source};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

pub mod cli;

/// What a target's reader does with one file: Ok, or the error's message.
type Reader = fn(&Path) -> Result<(), String>;

/// One reader and how to make inputs for it.
pub struct Target {
    /// Name (`wav`, `tf-zip`, ...).
    pub name: &'static str,
    /// File name the input is written as (the extension matters to some readers).
    pub file_name: &'static str,
    /// Valid files.
    seeds: Vec<Vec<u8>>,
    /// Zip seeds as entries, for content-level mutation.
    zip_seeds: Vec<Vec<(String, Vec<u8>)>>,
    /// Files written once beside the input (e.g. the imaginary part of a text pair).
    companions: Vec<(&'static str, Vec<u8>)>,
    reader: Reader,
}

impl Target {
    /// The valid files mutation starts from.
    pub fn seeds(&self) -> &[Vec<u8>] {
        &self.seeds
    }

    /// Files the reader expects beside the input (name, content), e.g. `K_i` for `K_r`.
    pub fn companions(&self) -> &[(&'static str, Vec<u8>)] {
        &self.companions
    }

    /// Zip seeds as (entry name, content) lists; empty for targets that are not zips.
    pub fn zip_seeds(&self) -> &[Vec<(String, Vec<u8>)>] {
        &self.zip_seeds
    }

    /// Read `path` with this target's reader: Ok, or the error's message. A panic is a bug.
    pub fn read(&self, path: &Path) -> Result<(), String> {
        (self.reader)(path)
    }
}

/// The target called `name`, if any.
pub fn target(name: &str) -> Option<Target> {
    targets().into_iter().find(|t| t.name == name)
}

/// Write every target's seeds into `dir/<target>/seed-<i>` (a seed corpus for coverage-guided
/// fuzzers); returns how many files were written. Zip targets also get
/// `dir/<target>@entries/seed-<k>`: the index of one entry (a byte) followed by that entry's
/// content, the input of a harness that puts the content back in the zip with valid CRCs
/// (see [`zip_with_entry`]).
pub fn write_seeds(dir: &Path) -> std::io::Result<usize> {
    let mut n = 0;
    for t in targets() {
        let d = dir.join(t.name);
        std::fs::create_dir_all(&d)?;
        for (i, s) in t.seeds.iter().enumerate() {
            std::fs::write(d.join(format!("seed-{i}")), s)?;
            n += 1;
        }
        if let Some(entries) = t.zip_seeds.first() {
            let d = dir.join(format!("{}@entries", t.name));
            std::fs::create_dir_all(&d)?;
            for (k, (_, content)) in entries.iter().enumerate() {
                let mut b = vec![k as u8];
                b.extend_from_slice(content);
                std::fs::write(d.join(format!("seed-{k}")), b)?;
                n += 1;
            }
        }
    }
    Ok(n)
}

/// Write the zip seed `entries` to `path` with the entry chosen by `input[0]` (modulo the
/// number of entries) holding `input[1..]`, with valid CRCs; false when nothing was written.
pub fn zip_with_entry(path: &Path, entries: &[(String, Vec<u8>)], input: &[u8]) -> bool {
    let Some((&k, content)) = input.split_first() else {
        return false;
    };
    if entries.is_empty() {
        return false;
    }
    let k = k as usize % entries.len();
    let mut e = entries.to_vec();
    e[k].1 = content.to_vec();
    write_zip_entries(path, &e).is_ok()
}

fn tmp_dir(tag: &str) -> PathBuf {
    let base = if Path::new("/dev/shm").is_dir() {
        PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    let d = base.join(format!("soundloc-fuzz-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temporary folder");
    d
}

fn read_audio_all(p: &Path) -> Result<(), String> {
    let mut s = open_source(p).map_err(|e| e.to_string())?;
    let mut buf = Vec::new();
    let mut total = 0usize;
    loop {
        let n = s.read_interleaved(4096, &mut buf).map_err(|e| e.to_string())?;
        if n == 0 {
            return Ok(());
        }
        total += n;
        if total > 1 << 26 {
            return Ok(());
        }
    }
}

fn bytes_of(write: impl FnOnce(&Path)) -> Vec<u8> {
    let d = tmp_dir("seed");
    let p = d.join("seed");
    write(&p);
    let b = std::fs::read(&p).expect("seed file");
    let _ = std::fs::remove_dir_all(&d);
    b
}

fn small_tf() -> TransferFunctions {
    free_field(
        &Geometry::circle(3, 0.05, 0.0),
        &Grid::ring(45.0, 0.0, 1.0),
        32,
        16000,
        0..17,
        343.0,
    )
    .expect("free-field TFs")
}

fn hgtf_seed() -> Vec<u8> {
    let tf = small_tf();
    let (m, d, nb) = (tf.num_mics, tf.num_dirs(), tf.num_bins);
    let mut fmt = Vec::new();
    fmt.extend_from_slice(&1u16.to_le_bytes());
    fmt.extend_from_slice(&0u16.to_le_bytes());
    for v in [
        1i32,
        m as i32,
        tf.nfft as i32,
        tf.nfft as i32,
        tf.sample_rate_hz as i32,
    ] {
        fmt.extend_from_slice(&v.to_le_bytes());
    }
    for _ in 0..m {
        for v in [0.05f32, 0.0, 0.0] {
            fmt.extend_from_slice(&v.to_le_bytes());
        }
    }
    let mut body = Vec::new();
    body.extend_from_slice(&1u16.to_le_bytes());
    body.extend_from_slice(&0u16.to_le_bytes());
    body.extend_from_slice(&(d as i32).to_le_bytes());
    body.extend_from_slice(&1i32.to_le_bytes());
    for p in &tf.grid.points {
        for v in p {
            body.extend_from_slice(&(*v as f32).to_le_bytes());
        }
    }
    for dir in 0..d {
        for mic in 0..m {
            for b in 0..nb {
                let c = tf.get(dir, mic, b);
                body.extend_from_slice(&c.re.to_le_bytes());
                body.extend_from_slice(&c.im.to_le_bytes());
            }
        }
    }
    let mut chunks = Vec::new();
    for (tag, b) in [(b"fmt ", &fmt), (b"M2PG", &body)] {
        chunks.extend_from_slice(tag);
        chunks.extend_from_slice(&(b.len() as u32).to_le_bytes());
        chunks.extend_from_slice(b);
    }
    let mut out = b"HARK".to_vec();
    out.extend_from_slice(&((chunks.len() + 4) as u32).to_le_bytes());
    out.extend_from_slice(b"HGTF");
    out.extend_from_slice(&chunks);
    out
}

fn results() -> Vec<LocalizationResult> {
    (0..3)
        .map(|f| LocalizationResult {
            num_active: None,
            frame: f * 50,
            time_s: f as f64 * 0.5,
            sources: vec![Source {
                id: Some(f as i64),
                grid_index: 3,
                azimuth_deg: 30.0,
                elevation_deg: 10.0,
                x: 0.85,
                y: 0.49,
                z: 0.17,
                power_db: 24.5,
                held: false,
            }],
        })
        .collect()
}

fn noise_cm() -> NoiseCm {
    let mut rng = StdRng::seed_from_u64(7);
    let ch: Vec<Vec<f32>> = (0..3)
        .map(|_| (0..4000).map(|_| rng.gen_range(-1000.0..1000.0)).collect())
        .collect();
    NoiseCm::estimate(&ch, 16000, 32, 16, soundloc::WindowFunction::Hanning, None)
        .expect("noise estimate")
        .0
}

fn zip_entries(write: impl FnOnce(&Path)) -> (Vec<u8>, Vec<(String, Vec<u8>)>) {
    let bytes = bytes_of(write);
    let d = tmp_dir("zipseed");
    let p = d.join("seed.zip");
    std::fs::write(&p, &bytes).expect("seed zip");
    let entries = read_zip_entries(&p)
        .expect("seed zip entries")
        .into_iter()
        .collect();
    let _ = std::fs::remove_dir_all(&d);
    (bytes, entries)
}

/// Every target, with its seeds.
pub fn targets() -> Vec<Target> {
    let audio = {
        let mut rng = StdRng::seed_from_u64(1);
        Audio {
            sample_rate_hz: 16000,
            channels: (0..2)
                .map(|_| {
                    (0..800)
                        .map(|_| rng.gen_range(-3000.0f32..3000.0).round())
                        .collect()
                })
                .collect(),
        }
    };
    let ints: Vec<Vec<i32>> = audio
        .channels
        .iter()
        .map(|c| c.iter().map(|&v| v as i32).collect())
        .collect();
    let (tf_zip, tf_entries) = zip_entries(|p| write_tf_zip(&small_tf(), p).expect("tf zip"));
    let cm = noise_cm();
    let (cm_zip, cm_entries) = zip_entries(|p| cm.write_zip(p).expect("cm zip"));
    let (cm_re, cm_im) = {
        let d = tmp_dir("cmtext");
        let (re, im) = (d.join("K_r"), d.join("K_i"));
        cm.write_text_pair(&re, &im).expect("cm text");
        let pair = (std::fs::read(&re).expect("re"), std::fs::read(&im).expect("im"));
        let _ = std::fs::remove_dir_all(&d);
        pair
    };
    let tf_reader: Reader = |p| TransferFunctions::load(p).map(drop).map_err(|e| e.to_string());
    let cm_reader: Reader = |p| {
        NoiseCm::load(p, Expected::default())
            .map(drop)
            .map_err(|e| e.to_string())
    };
    let log_reader: Reader = |p| source_log::read(p, 0.01).map(drop).map_err(|e| e.to_string());
    vec![
        Target {
            name: "wav",
            file_name: "input.wav",
            seeds: vec![
                bytes_of(|p| audio.write_wav(p, SampleFormat::Int16).expect("wav")),
                bytes_of(|p| audio.write_wav(p, SampleFormat::Float32).expect("wav")),
            ],
            zip_seeds: Vec::new(),
            companions: Vec::new(),
            reader: read_audio_all,
        },
        Target {
            name: "flac",
            file_name: "input.flac",
            seeds: vec![
                encode_flac_verbatim(16000, 16, &ints),
                encode_flac_verbatim(44100, 24, &ints),
            ],
            zip_seeds: Vec::new(),
            companions: Vec::new(),
            reader: read_audio_all,
        },
        Target {
            name: "tf-zip",
            file_name: "tf.zip",
            seeds: vec![tf_zip],
            zip_seeds: vec![tf_entries],
            companions: Vec::new(),
            reader: tf_reader,
        },
        Target {
            name: "hgtf",
            file_name: "tf_loc.dat",
            seeds: vec![hgtf_seed()],
            zip_seeds: Vec::new(),
            companions: Vec::new(),
            reader: tf_reader,
        },
        Target {
            name: "noise-cm-zip",
            file_name: "K.zip",
            seeds: vec![cm_zip],
            zip_seeds: vec![cm_entries],
            companions: Vec::new(),
            reader: cm_reader,
        },
        Target {
            name: "noise-cm-text",
            file_name: "K_r",
            seeds: vec![cm_re],
            zip_seeds: Vec::new(),
            companions: vec![("K_i", cm_im)],
            reader: cm_reader,
        },
        Target {
            name: "geometry",
            file_name: "array.toml",
            seeds: vec![Geometry::circle(8, 0.0365, 0.0).to_toml_string().into_bytes()],
            zip_seeds: Vec::new(),
            companions: Vec::new(),
            reader: |p| Geometry::load(p).map(drop).map_err(|e| e.to_string()),
        },
        Target {
            name: "odas-cfg",
            file_name: "array.cfg",
            seeds: vec![odas_cfg_seed().into_bytes()],
            zip_seeds: Vec::new(),
            companions: Vec::new(),
            reader: |p| {
                soundloc::array::Geometry::load_with_mapping(p)
                    .map(drop)
                    .map_err(|e| e.to_string())
            },
        },
        Target {
            name: "source-log",
            file_name: "log.txt",
            seeds: vec![
                source_log::to_text(&results()).into_bytes(),
                source_log::to_xml(&results()).into_bytes(),
            ],
            zip_seeds: Vec::new(),
            companions: Vec::new(),
            reader: log_reader,
        },
    ]
}

/// An ODAS configuration of the 8-mic ring on a 10-channel device, in ODAS's layout
/// (comments, nested groups, lists, strings, hex and exponent numbers).
fn odas_cfg_seed() -> String {
    let mics: Vec<String> = Geometry::circle(8, 0.0365, 0.0)
        .mics
        .iter()
        .enumerate()
        .map(|(i, m)| {
            format!(
                "        # Microphone {i}\n        {{ mu = ( {:+.4}, {:+.4}, {:+.4} ); sigma2 = ( 0.0, 0.0, 0.0 ); angle = ( 80.0, 90.0 ); }}",
                m[0], m[1], m[2]
            )
        })
        .collect();
    format!(
        "version = \"2.1\";\nraw: {{\n    fS = 16000; nBits = 0x20; nChannels = 10;\n    interface: {{ type = \"soundcard\"; card = 1; }}\n}}\n\
         mapping: {{ map: (10, 9, 8, 7, 6, 5, 4, 3); }}\n/* general */\ngeneral: {{\n    epsilon = 1E-20;\n    mics = (\n{}\n    );\n}};\n",
        mics.join(",\n")
    )
}

const INTERESTING: [u64; 14] = [
    0,
    1,
    0x7f,
    0xff,
    0x7fff,
    0xffff,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_fff0,
    0xffff_ffff,
    1 << 32,
    0x7fff_ffff_ffff_ffff,
    u64::MAX,
    1 << 40,
];

const NUMBERS: [&str; 12] = [
    "0",
    "-1",
    "1e308",
    "-1e308",
    "nan",
    "inf",
    "4294967296",
    "99999999999999999999",
    "1e-320",
    "2",
    "65536",
    "",
];

/// One mutated copy of `seed`.
pub fn mutate(rng: &mut StdRng, seed: &[u8]) -> Vec<u8> {
    let mut b = seed.to_vec();
    for _ in 0..rng.gen_range(1..=4) {
        let n = b.len();
        match rng.gen_range(0..9) {
            0 if n > 0 => {
                let i = rng.gen_range(0..n);
                b[i] ^= 1 << rng.gen_range(0..8);
            }
            1 if n > 0 => {
                let i = rng.gen_range(0..n);
                b[i] = rng.gen();
            }
            2 if n > 0 => {
                // An interesting integer over what may be a header field.
                let i = rng.gen_range(0..n);
                let v = INTERESTING[rng.gen_range(0..INTERESTING.len())].to_le_bytes();
                let w = [1, 2, 4, 8][rng.gen_range(0..4)];
                let w = w.min(n - i);
                b[i..i + w].copy_from_slice(&v[..w]);
            }
            3 => {
                let i = rng.gen_range(0..=n);
                let len = rng.gen_range(1..64);
                let ins: Vec<u8> = (0..len).map(|_| rng.gen()).collect();
                b.splice(i..i, ins);
            }
            4 if n > 1 => {
                let i = rng.gen_range(0..n);
                let j = (i + rng.gen_range(1..=n.min(256))).min(n);
                b.drain(i..j);
            }
            5 if n > 0 => {
                b.truncate(rng.gen_range(0..n));
            }
            6 if n > 1 => {
                // Duplicate a chunk somewhere else.
                let i = rng.gen_range(0..n);
                let j = (i + rng.gen_range(1..=n.min(512))).min(n);
                let chunk = b[i..j].to_vec();
                let at = rng.gen_range(0..=n);
                b.splice(at..at, chunk);
            }
            7 => {
                // In text: replace one number with an awkward one.
                if let Ok(s) = std::str::from_utf8(&b) {
                    let starts: Vec<usize> = s
                        .char_indices()
                        .filter(|&(i, c)| {
                            c.is_ascii_digit() && (i == 0 || !s.as_bytes()[i - 1].is_ascii_digit())
                        })
                        .map(|(i, _)| i)
                        .collect();
                    if !starts.is_empty() {
                        let i = starts[rng.gen_range(0..starts.len())];
                        let end = s[i..]
                            .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
                            .map_or(s.len(), |k| i + k);
                        let repl = NUMBERS[rng.gen_range(0..NUMBERS.len())];
                        b.splice(i..end, repl.bytes());
                    }
                }
            }
            _ if n > 0 => {
                // Deep nesting or a long run of one byte.
                let i = rng.gen_range(0..n);
                let c = if rng.gen_bool(0.5) { b'<' } else { b[i] };
                let run = vec![c; rng.gen_range(1..4096)];
                b.splice(i..i, run);
            }
            _ => {}
        }
    }
    b
}

/// What a run found.
#[derive(Debug, Default, Clone)]
pub struct Report {
    /// Inputs tried.
    pub execs: u64,
    /// Inputs the reader accepted.
    pub accepted: u64,
    /// Inputs refused with an error naming the file.
    pub refused: u64,
    /// Errors that do not name the file (examples).
    pub unnamed_errors: Vec<String>,
    /// Number of such errors.
    pub unnamed: u64,
    /// Panics (message; the input is saved when a crash folder is given).
    pub panics: Vec<String>,
    /// Slowest single execution.
    pub max_exec: Duration,
    /// Executions slower than the hang threshold.
    pub slow: u64,
}

/// An execution slower than this counts as a hang.
pub const HANG: Duration = Duration::from_secs(2);

/// Make `iters` inputs for `t` from `seed` and read each; panicking inputs are saved into
/// `crashes` when given.
pub fn run(t: &Target, iters: u64, seed: u64, crashes: Option<&Path>) -> Report {
    let dir = tmp_dir(t.name);
    for (name, bytes) in &t.companions {
        std::fs::write(dir.join(name), bytes).expect("companion file");
    }
    let path = dir.join(t.file_name);
    let name = t.file_name;
    let mut rng = StdRng::seed_from_u64(seed);
    let mut r = Report::default();
    for i in 0..iters {
        let input = if !t.zip_seeds.is_empty() && rng.gen_bool(0.5) {
            // Mutate one entry's content and re-zip with valid CRCs.
            let mut entries = t.zip_seeds[rng.gen_range(0..t.zip_seeds.len())].clone();
            let files: Vec<usize> = (0..entries.len())
                .filter(|&k| !entries[k].0.ends_with('/'))
                .collect();
            let k = files[rng.gen_range(0..files.len())];
            entries[k].1 = mutate(&mut rng, &entries[k].1);
            if write_zip_entries(&path, &entries).is_err() {
                continue;
            }
            None
        } else {
            let s = &t.seeds[rng.gen_range(0..t.seeds.len())];
            Some(mutate(&mut rng, s))
        };
        if let Some(b) = &input {
            std::fs::write(&path, b).expect("input file");
        }
        let start = Instant::now();
        let res = std::panic::catch_unwind(|| (t.reader)(&path));
        let dt = start.elapsed();
        r.execs += 1;
        r.max_exec = r.max_exec.max(dt);
        if dt > HANG {
            r.slow += 1;
        }
        match res {
            Ok(Ok(())) => r.accepted += 1,
            Ok(Err(e)) if e.contains(name) => r.refused += 1,
            Ok(Err(e)) => {
                r.unnamed += 1;
                if r.unnamed_errors.len() < 5 {
                    r.unnamed_errors.push(e);
                }
            }
            Err(p) => {
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                if let Some(c) = crashes {
                    let _ = std::fs::create_dir_all(c);
                    let _ = std::fs::copy(&path, c.join(format!("{}-{seed}-{i}", t.name)));
                }
                r.panics.push(format!("input {i}: {msg}"));
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    r
}
