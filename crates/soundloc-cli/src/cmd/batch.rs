//! `soundloc batch`: many recordings, one result file each — for archives on plain
//! clusters (SLURM arrays, GNU parallel): a manifest or a list of inputs, `--shard K/N`,
//! and resumable runs (inputs whose result file exists are skipped).

use super::input::{spawn_reader, InputArgs};
use super::localize::{drive, note, FormatArg};
use super::run_args::RunArgs;
use anyhow::{anyhow, bail, Context};
use soundloc::formats::noise_cm::NoiseCm;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recordings (WAV/FLAC).
    pub inputs: Vec<PathBuf>,
    /// A manifest: one recording per line (blank lines and lines starting with # are
    /// skipped; relative paths are relative to the manifest's folder).
    #[arg(long)]
    pub manifest: Option<PathBuf>,
    /// Folder for the results, one file per recording named after it (rec.wav →
    /// rec.jsonl, or rec.csv with --format csv); created if missing.
    #[arg(long)]
    pub out_dir: PathBuf,
    /// Only share K of N (0-based): the inputs whose position in the list is K modulo N,
    /// e.g. --shard $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT with a 0-based array
    /// (sbatch --array=0-3; for --array=1-4 subtract 1).
    #[arg(long)]
    pub shard: Option<String>,
    /// Localize inputs whose result file already exists again (default: skip them, so a
    /// rerun resumes where an interrupted one stopped; files are written whole or not at all).
    #[arg(long)]
    pub overwrite: bool,
    /// A recording cut short (it ends before the length its header declares) is localized
    /// up to the cut, with a warning, instead of failing.
    #[arg(long)]
    pub allow_truncated: bool,
    #[command(flatten)]
    pub run: RunArgs,
}

/// Parse `K/N` with K < N.
pub fn parse_shard(s: &str) -> anyhow::Result<(usize, usize)> {
    let bad = || anyhow!("--shard {s:?}: expected K/N with 0 <= K < N, e.g. 0/4");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let k: usize = k.trim().parse().map_err(|_| bad())?;
    let n: usize = n.trim().parse().map_err(|_| bad())?;
    if n == 0 || k >= n {
        return Err(bad());
    }
    Ok((k, n))
}

/// The inputs named on the command line and in the manifest, in order.
fn inputs(a: &Args) -> anyhow::Result<Vec<PathBuf>> {
    let mut v = a.inputs.clone();
    if let Some(m) = &a.manifest {
        let text = std::fs::read_to_string(m)
            .with_context(|| format!("{}: cannot read the manifest", m.display()))?;
        let base = m.parent().unwrap_or(Path::new("."));
        for line in text.lines() {
            let t = line.trim();
            if t.is_empty() || t.starts_with('#') {
                continue;
            }
            let p = PathBuf::from(t);
            v.push(if p.is_absolute() { p } else { base.join(p) });
        }
    }
    if v.is_empty() {
        bail!("no inputs: name recordings or give --manifest FILE");
    }
    Ok(v)
}

/// The shared run options that name one output file or endpoint per run: batch refuses
/// them (each recording's results go to `--out-dir`), so its `--help` does not list them;
/// `odas_pots`/`odas_tracks`, which only size the ODAS outputs, are hidden with them.
const PER_INPUT_ONLY: [&str; 12] = [
    "output",
    "spectrum",
    "plot",
    "summary",
    "log_text",
    "log_xml",
    "hark_stream",
    "serve",
    "odas_ssl",
    "odas_sst",
    "odas_pots",
    "odas_tracks",
];

/// For `mut_args` on the batch command: hide [`PER_INPUT_ONLY`] from its help.
pub fn hide_per_input_options(a: clap::Arg) -> clap::Arg {
    let hide = PER_INPUT_ONLY.contains(&a.get_id().as_str());
    a.hide(hide)
}

pub fn run(mut a: Args) -> anyhow::Result<ExitCode> {
    let r = &a.run;
    let per_input_only = [
        ("-o/--output", r.output.is_some()),
        ("--spectrum", r.spectrum.is_some()),
        ("--plot", r.plot.is_some()),
        ("--summary", r.summary.is_some()),
        ("--log-text", r.log_text.is_some()),
        ("--log-xml", r.log_xml.is_some()),
        ("--hark-stream", r.hark_stream.is_some()),
        ("--serve", r.live.serve.is_some()),
        ("--odas-ssl", r.live.odas_ssl.is_some()),
        ("--odas-sst", r.live.odas_sst.is_some()),
    ];
    if let Some((flag, _)) = per_input_only.iter().find(|(_, set)| *set) {
        bail!("{flag} is not available with batch: each recording's results go to --out-dir");
    }
    let all = inputs(&a)?;
    if let Some(p) = all.iter().find(|p| {
        let s = p.to_string_lossy();
        s == "-" || s.starts_with("tcp:") || s.starts_with("tcp-listen:")
    }) {
        bail!(
            "{}: batch localizes recordings (files); for standard input or a network source use `soundloc localize`",
            p.display()
        );
    }
    let (k, n) = match &a.shard {
        Some(s) => parse_shard(s)?,
        None => (0, 1),
    };
    let ext = match a.run.format {
        FormatArg::Jsonl => "jsonl",
        FormatArg::Csv => "csv",
    };
    // Result names must not collide (over the whole list, so shards agree).
    let mut seen: HashMap<PathBuf, &Path> = HashMap::new();
    let mut jobs = Vec::new();
    for (i, p) in all.iter().enumerate() {
        let stem = p
            .file_stem()
            .ok_or_else(|| anyhow!("{}: not a file name", p.display()))?;
        // Everything before the recording's extension: "rec.take1.wav" → "rec.take1.jsonl".
        let mut name = stem.to_os_string();
        name.push(".");
        name.push(ext);
        let out = a.out_dir.join(name);
        if let Some(prev) = seen.insert(out.clone(), p) {
            bail!(
                "{} and {} would both write {}: rename one or run them separately",
                prev.display(),
                p.display(),
                out.display()
            );
        }
        if i % n == k {
            jobs.push((p.clone(), out));
        }
    }
    // No result may replace a recording of the list or one of the run's files.
    let r = &a.run;
    let cm_files = r.noise_cm.as_deref().map(NoiseCm::files_read).unwrap_or_default();
    let files: Vec<(&Path, &str)> = all
        .iter()
        .map(|p| (p.as_path(), "a recording of this batch"))
        .chain(
            [
                (r.tf.as_deref(), "--tf"),
                (r.geometry.as_deref(), "--geometry"),
                (r.noise.as_deref(), "--noise"),
            ]
            .into_iter()
            .filter_map(|(p, w)| p.map(|p| (p, w))),
        )
        .chain(cm_files.iter().map(|p| (p.as_path(), "--noise-cm")))
        .collect();
    let outs: Vec<(&Path, &str)> = jobs.iter().map(|(_, o)| (o.as_path(), "the result")).collect();
    soundloc::output::atomic::check_outputs(&outs, &files)?;
    std::fs::create_dir_all(&a.out_dir)
        .with_context(|| format!("{}: cannot create the folder", a.out_dir.display()))?;
    let quiet = a.run.quiet;
    let stale = soundloc::output::atomic::stale_temporaries(&a.out_dir);
    if let Some(first) = stale.first() {
        note(
            quiet,
            &format!(
                "{}: {} temporary file(s) of interrupted runs whose processes are gone (e.g. {}); delete them",
                a.out_dir.display(),
                stale.len(),
                first.file_name().unwrap_or_default().to_string_lossy()
            ),
        );
    }
    let (mut done, mut skipped, mut failed) = (0usize, 0usize, Vec::new());
    for (p, out) in jobs {
        // Only a result file counts as done: a folder at its name is an error of that
        // recording's, as writing the result there would be.
        if out.is_dir() {
            eprintln!(
                "soundloc: error: {}: the result path {} is a directory",
                p.display(),
                out.display()
            );
            failed.push(p.display().to_string());
            continue;
        }
        if !a.overwrite && out.exists() {
            skipped += 1;
            continue;
        }
        a.run.output = Some(out.clone());
        let input = InputArgs {
            input: p.display().to_string(),
            raw: None,
            raw_channels: None,
            rate: None,
            max_buffer: 10.0,
            realtime: false,
            keep_listening: false,
            connect_timeout: 0.0,
            allow_truncated: a.allow_truncated,
        };
        let res = input.open(true).and_then(|inp| {
            let (fmt, rx) = spawn_reader(inp.source, false, &input, false);
            drive(&a.run, &inp.name, false, fmt, rx, None)
        });
        match res {
            Ok(code) if code == ExitCode::SUCCESS => {
                done += 1;
                if !quiet {
                    eprintln!("soundloc: {} -> {}", p.display(), out.display());
                }
            }
            Ok(_) => failed.push(format!("{}: did not finish", p.display())),
            Err(e) => {
                // Most errors already name the recording.
                let msg = format!("{e:#}");
                if msg.contains(&p.display().to_string()) {
                    eprintln!("soundloc: error: {msg}");
                } else {
                    eprintln!("soundloc: error: {}: {msg}", p.display());
                }
                failed.push(p.display().to_string());
            }
        }
    }
    if !quiet || !failed.is_empty() {
        eprintln!(
            "soundloc: batch{}: {done} localized, {skipped} skipped (result exists), {} failed",
            a.shard
                .as_deref()
                .map(|s| format!(" shard {s}"))
                .unwrap_or_default(),
            failed.len()
        );
    }
    Ok(if failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shard_parsing() {
        assert_eq!(parse_shard("0/4").unwrap(), (0, 4));
        assert_eq!(parse_shard(" 3 / 4 ").unwrap(), (3, 4));
        for bad in ["4/4", "1/0", "x/2", "2", "-1/3"] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn per_input_options_are_hidden_from_batch_and_refused() {
        use clap::CommandFactory;
        let cli = super::super::Cli::command();
        let batch = cli.find_subcommand("batch").unwrap();
        let localize = cli.find_subcommand("localize").unwrap();
        for id in PER_INPUT_ONLY {
            let arg = |c: &clap::Command| c.get_arguments().find(|a| a.get_id() == id).cloned();
            assert!(
                arg(batch)
                    .unwrap_or_else(|| panic!("no option {id}"))
                    .is_hide_set(),
                "{id}"
            );
            assert!(!arg(localize).unwrap().is_hide_set(), "{id}");
        }
        let help = batch.clone().render_long_help().to_string();
        assert!(
            !help.contains("--output") && !help.contains("--odas-ssl"),
            "{help}"
        );
        assert!(
            help.contains("--out-dir") && help.contains("--spectrum-weight"),
            "{help}"
        );
        // Hidden, still parsed, and refused with the reason.
        for (flag, value) in [
            ("-o", "x.jsonl"),
            ("--odas-ssl", "ssl.json"),
            ("--summary", "s.json"),
        ] {
            let cli = <super::super::Cli as clap::Parser>::try_parse_from([
                "soundloc",
                "batch",
                "--out-dir",
                "/nonexistent/out",
                flag,
                value,
                "a.wav",
            ])
            .unwrap();
            let super::super::Command::Batch(a) = cli.command else {
                panic!()
            };
            let e = run(*a).unwrap_err().to_string();
            assert!(e.contains("is not available with batch"), "{flag}: {e}");
        }
    }
}
