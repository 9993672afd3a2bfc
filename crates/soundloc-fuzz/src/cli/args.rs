//! The command-line mutations: the options, flags, awkward values and numbers the fuzzer
//! inserts, how a seed command line is mutated, and which results may be run here.

use rand::rngs::StdRng;
use rand::Rng;

/// Options each subcommand knows, for inserting out of place; the value is an example.
const OPTIONS: [(&str, &str); 49] = [
    ("--tf", "tf.zip"),
    ("--geometry", "array.toml"),
    ("--grid", "ring:30"),
    ("--grid-radius", "1"),
    ("--speed-of-sound", "343"),
    ("--channels", "0,1"),
    ("--input-channels", "0,1,2"),
    ("--noise", "noise.wav"),
    ("--noise-range", "0:0.2"),
    ("--noise-cm", "K.zip"),
    ("--noise-segments", "0:0.1"),
    ("--noise-preceding", "5:1"),
    ("--algorithm", "gevd"),
    ("--num-sources", "2"),
    ("--max-peaks", "-1"),
    ("--window", "50"),
    ("--window-type", "future"),
    ("--period", "50"),
    ("--min-deg", "-180"),
    ("--max-deg", "180"),
    ("--lower-freq", "500"),
    ("--upper-freq", "2800"),
    ("--fft-length", "512"),
    ("--hop", "160"),
    ("--window-function", "conj"),
    ("--eigenvalue-weight", "true"),
    ("--spectrum-weights", "1,1"),
    ("--diagonal-loading", "0.1"),
    ("--subspace-dim", "3"),
    ("--format", "csv"),
    ("--output", "o.txt"),
    ("--spectrum", "s.npy"),
    ("--plot", "p.svg"),
    ("--summary", "s.json"),
    ("--log-text", "l.txt"),
    ("--raw", "s24le"),
    ("--raw", "f64le"),
    ("--raw-channels", "8"),
    ("--rate", "16000"),
    ("--precision", "f64"),
    ("--range", "0:0.1"),
    ("--builtin", "circle8"),
    ("--sample-rate", "8000"),
    ("--out-dir", "o"),
    ("--manifest", "list.txt"),
    ("--shard", "1/2"),
    ("--thresh", "5"),
    ("--preroll", "3"),
    ("--cache-dir", "c"),
];

const FLAGS: [&str; 13] = [
    "--track",
    "--resample",
    "--refine",
    "--normalize-bins",
    "--no-cache",
    "--realtime",
    "--json",
    "--verify",
    "--bins",
    "--overwrite",
    "-q",
    "--help",
    "-V",
];

/// Values that are wrong in some interesting way.
const VALUES: [&str; 59] = [
    "-1",
    "0",
    "-0",
    "1",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e-320",
    "4294967296",
    "4294967295",
    "18446744073709551615",
    "18446744073709551616",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999999999",
    "0x10",
    "1_000",
    "",
    " ",
    "\t",
    ",",
    ",,,",
    "0,,1",
    "-1,2",
    "0,0,0,0,0,0,0,0,0,0,0,0",
    ":",
    "::",
    "0:0",
    "1:0",
    "-1:1",
    "nan:inf",
    "0:1e308",
    "ring:",
    "ring:0",
    "ring:-5",
    "ring:nan",
    "ring:1e-300",
    "ring:30:90",
    "ring:30:1e308",
    "sphere:0",
    "sphere:1",
    "sphere:-1",
    "sphere:4294967296",
    "0/0",
    "3/2",
    "0/18446744073709551615",
    "é",
    "日本語",
    "\u{202e}evil",
    "🎤🎤",
    "dev-null",
    "dev-full",
    "/dev/null/x",
    "/proc/nonexistent/x",
    "missing/dir/file.wav",
    "subdir",
];

/// Numbers put in place of a number inside a value (`ring:30` → `ring:-1`).
const NUMBERS: [&str; 10] = [
    "-1",
    "0",
    "nan",
    "inf",
    "1e308",
    "1e-308",
    "4294967296",
    "99999999999999999999",
    "-0",
    "",
];

const SUBCOMMANDS: [&str; 8] = ["localize", "batch", "tf", "noisecm", "help", "inspect", "", "-h"];

fn interesting(rng: &mut StdRng) -> String {
    match rng.gen_range(0..10) {
        0 => "A".repeat(rng.gen_range(1..5000)),
        1 => format!("{}", rng.gen::<i64>()),
        2 => format!("{:e}", rng.gen::<f64>() * 10f64.powi(rng.gen_range(-300..300))),
        _ => VALUES[rng.gen_range(0..VALUES.len())].to_string(),
    }
}

/// Replace one number inside `v` by an awkward one, if it has any.
fn replace_number(rng: &mut StdRng, v: &str) -> Option<String> {
    let b = v.as_bytes();
    let starts: Vec<usize> = (0..b.len())
        .filter(|&i| b[i].is_ascii_digit() && (i == 0 || !b[i - 1].is_ascii_digit() && b[i - 1] != b'.'))
        .collect();
    if starts.is_empty() {
        return None;
    }
    let i = starts[rng.gen_range(0..starts.len())];
    let end = v[i..]
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .map_or(v.len(), |k| i + k);
    Some(format!(
        "{}{}{}",
        &v[..i],
        NUMBERS[rng.gen_range(0..NUMBERS.len())],
        &v[end..]
    ))
}

/// One mutated copy of a seed command line (`keep` leading words left alone, mostly).
pub fn mutate_args(rng: &mut StdRng, keep: usize, seed: &[&str]) -> Vec<String> {
    let mut a: Vec<String> = seed.iter().map(|s| s.to_string()).collect();
    let keep = keep.min(a.len());
    for _ in 0..rng.gen_range(1..=4) {
        let n = a.len();
        let free = n - keep;
        match rng.gen_range(0..12) {
            0 if free > 0 => {
                a.remove(rng.gen_range(keep..n));
            }
            1 if free > 0 => {
                let i = rng.gen_range(keep..n);
                let v = a[i].clone();
                a.insert(rng.gen_range(keep..=n), v);
            }
            2 if free > 1 => {
                let (i, j) = (rng.gen_range(keep..n), rng.gen_range(keep..n));
                a.swap(i, j);
            }
            3 | 4 if free > 0 => {
                // A value (an argument not starting with -) or any argument.
                let values: Vec<usize> = (keep..n).filter(|&i| !a[i].starts_with('-')).collect();
                let i = if values.is_empty() || rng.gen_bool(0.2) {
                    rng.gen_range(keep..n)
                } else {
                    values[rng.gen_range(0..values.len())]
                };
                a[i] = interesting(rng);
            }
            5 if free > 0 => {
                let i = rng.gen_range(keep..n);
                if let Some(v) = replace_number(rng, &a[i]) {
                    a[i] = v;
                }
            }
            6 => {
                // A known option out of place, with its example value, an awkward one or none.
                let (o, v) = OPTIONS[rng.gen_range(0..OPTIONS.len())];
                let at = rng.gen_range(keep..=n);
                let mut ins = vec![o.to_string()];
                match rng.gen_range(0..4) {
                    0 => {}
                    1 => ins.push(interesting(rng)),
                    _ => ins.push(v.to_string()),
                }
                a.splice(at..at, ins);
            }
            7 => {
                let at = rng.gen_range(keep..=n);
                let f = match rng.gen_range(0..6) {
                    0 => ["--bogus", "-x", "--", "-", "---", "--=", "-qq", "--TF", "-o"][rng.gen_range(0..9)]
                        .to_string(),
                    _ => FLAGS[rng.gen_range(0..FLAGS.len())].to_string(),
                };
                a.insert(at, f);
            }
            8 if free > 1 => {
                // Join an option and its value: --opt=value.
                let opts: Vec<usize> = (keep..n - 1).filter(|&i| a[i].starts_with("--")).collect();
                if !opts.is_empty() {
                    let i = opts[rng.gen_range(0..opts.len())];
                    let v = a.remove(i + 1);
                    a[i] = format!("{}={v}", a[i]);
                }
            }
            9 if free > 0 => {
                a.truncate(rng.gen_range(keep..n));
            }
            10 if rng.gen_bool(0.1) && n > 0 => {
                a[0] = SUBCOMMANDS[rng.gen_range(0..SUBCOMMANDS.len())].to_string();
            }
            _ if free > 0 => {
                // A value in place of another option's value.
                let i = rng.gen_range(keep..n);
                a[i] = OPTIONS[rng.gen_range(0..OPTIONS.len())].1.to_string();
            }
            _ => {}
        }
    }
    a
}

/// Options whose value may be a network address; only plain file names are allowed after them.
const NETWORK_OPTIONS: [&str; 4] = ["--serve", "--hark-stream", "--odas-ssl", "--odas-sst"];

/// Whether a command line may be run here: nothing that reaches the network, listens, or
/// runs long by design (`bench`, `demo`, `listen` only with `--help`).
pub fn is_safe(args: &[String]) -> bool {
    let plain = |v: &str| {
        !v.is_empty()
            && v.bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'.' || b == b'_' || b == b'-')
    };
    let help = args.iter().any(|a| a == "--help" || a == "-h");
    let long = args
        .iter()
        .find(|a| !a.starts_with('-'))
        .is_some_and(|c| c == "bench" || c == "demo" || c == "listen");
    if long && !help {
        return false;
    }
    for (i, a) in args.iter().enumerate() {
        if a.to_ascii_lowercase().contains("tcp") {
            return false;
        }
        for o in NETWORK_OPTIONS {
            if let Some(rest) = a.strip_prefix(o) {
                let ok = if let Some(v) = rest.strip_prefix('=') {
                    plain(v)
                } else if rest.is_empty() {
                    args.get(i + 1).is_some_and(|v| plain(v))
                } else {
                    true // another option that starts alike (none do today)
                };
                if !ok {
                    return false;
                }
            }
        }
    }
    true
}
