//! Where stdout or an output goes away: a closed stdout pipe (`| head -1`) ends any
//! subcommand quietly (the other outputs still written), a full one (`> /dev/full`) and a
//! FIFO whose reader left are errors naming them, and nothing panics.

mod common;

use common::bin;
use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::Stdio;

fn tmp(name: &str) -> PathBuf {
    common::tmp("cli-stdout", name)
}

/// An 8-mic ring recording (two talkers) and its geometry, in files of the test's own.
fn scene(test: &str) -> (PathBuf, PathBuf) {
    let (_, geo, wav) = common::ring_scene("cli-stdout", &format!("{test}-"), 1);
    (wav, geo)
}

/// Run `cmd`, read one line of its stdout and close it (like `| head -1`): the line, the
/// exit status and stderr.
fn first_line_then_close(cmd: &mut std::process::Command) -> (String, std::process::ExitStatus, String) {
    let mut child = cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    let status = child.wait().unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    (first, status, err)
}

#[test]
fn a_closed_stdout_pipe_ends_the_run_quietly() {
    let (wav, geo) = scene("a_closed_stdout_pipe_ends_the_run_quietly");
    let (first, status, err) = first_line_then_close(bin().args([
        "localize",
        wav.to_str().unwrap(),
        "--geometry",
        geo.to_str().unwrap(),
        "--grid",
        "ring:5",
        "--period",
        "1",
        "-q",
    ]));
    assert!(first.starts_with("{\"frame\""), "{first}");
    assert!(status.success() && err.is_empty(), "{status:?}: {err}");
}

/// Stdout closed early with other outputs asked for: the run goes on for them (the
/// summary is written, a note says so), exit 0. Until 2026-12-02 it stopped at once with
/// exit 0 and the summary was never written.
#[test]
fn a_closed_stdout_leaves_the_other_outputs_written() {
    let (wav, geo) = scene("closed_stdout_other_outputs");
    let summary = tmp("closed_stdout_summary.json");
    let _ = std::fs::remove_file(&summary);
    let (_, status, err) = first_line_then_close(
        bin()
            .args([
                "localize",
                wav.to_str().unwrap(),
                "--geometry",
                geo.to_str().unwrap(),
            ])
            .args(["--grid", "ring:5", "--period", "1", "--track", "--summary"])
            .arg(&summary),
    );
    assert!(status.success(), "{status:?}: {err}");
    assert!(err.contains("stdout was closed by its reader"), "{err}");
    let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert!(s.as_array().is_some_and(|a| !a.is_empty()), "{s}");
}

/// A FIFO given as an output whose reader goes away is an error naming it (exit 2), not
/// the quiet success of a closed stdout; nothing else is written.
#[cfg(unix)]
#[test]
fn a_closed_fifo_output_is_an_error_naming_it() {
    let (wav, geo) = scene("closed_fifo");
    let fifo = tmp("closed_fifo.jsonl");
    let summary = tmp("closed_fifo_summary.json");
    let _ = std::fs::remove_file(&fifo);
    let _ = std::fs::remove_file(&summary);
    assert!(std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let reader = {
        let fifo = fifo.clone();
        // Reads 100 bytes, then closes its end.
        std::thread::spawn(move || {
            let mut f = std::fs::File::open(&fifo).unwrap();
            let mut b = [0u8; 100];
            std::io::Read::read_exact(&mut f, &mut b).unwrap();
        })
    };
    let o = bin()
        .args([
            "localize",
            wav.to_str().unwrap(),
            "--geometry",
            geo.to_str().unwrap(),
        ])
        .args(["--grid", "ring:5", "--period", "1", "--track", "-q", "--odas-ssl"])
        .arg(&fifo)
        .arg("--summary")
        .arg(&summary)
        .output()
        .unwrap();
    reader.join().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("{}: writing ODAS messages", fifo.display())),
        "{err}"
    );
    assert!(!summary.exists());
}

/// The utility subcommands print through the same checked writer: a closed stdout pipe
/// was a panic (exit 101, a backtrace) in `tf make`, `tf inspect`, `noisecm inspect`,
/// `demo` and `bench` until 2026-12-02, and `> /dev/full` one too.
#[test]
fn utility_commands_end_quietly_on_a_closed_stdout_and_fail_on_a_full_one() {
    let zip = tmp("closed_tf.zip");
    let _ = std::fs::remove_file(&zip);
    let make = ["tf", "make", "--builtin", "circle8", "--grid", "ring:5", "-o"];
    let inspect = ["tf", "inspect"];
    for args in [&make[..], &inspect[..]] {
        // A pipe whose reader is already gone: every write fails with EPIPE.
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let o = bin().args(args).arg(&zip).stdout(writer).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{args:?}: {:?} {err}", o.status);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(zip.exists());
    }
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let o = bin().args(inspect).arg(&zip).stdout(full).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("writing results to stdout: No space left on device"),
        "{err}"
    );
}

/// `-o`, `--odas-sst` and the HARK logs naming FIFOs are followed live, as stdout is: their
/// first lines arrive while the input is still open (until 2026-12-02 `-o` and ODAS came
/// only at the end, or in 8 KiB bursts, although the README offers a FIFO to follow ODAS
/// output live; the HARK logs until 2026-12-03).
#[cfg(unix)]
#[test]
fn fifo_outputs_are_flushed_as_results_come() {
    use std::io::Write;
    use std::sync::mpsc;
    let (wav, geo) = scene("live_fifo");
    let bytes = std::fs::read(&wav).unwrap();
    let mut fifos = Vec::new();
    for name in [
        "live_fifo.jsonl",
        "live_fifo_sst.json",
        "live_fifo.log",
        "live_fifo.xml",
    ] {
        let f = tmp(name);
        let _ = std::fs::remove_file(&f);
        assert!(std::process::Command::new("mkfifo")
            .arg(&f)
            .status()
            .unwrap()
            .success());
        fifos.push(f);
    }
    let (tx, rx) = mpsc::channel();
    let readers: Vec<_> = fifos
        .iter()
        .cloned()
        .map(|f| {
            let tx = tx.clone();
            std::thread::spawn(move || {
                let mut r = BufReader::new(std::fs::File::open(&f).unwrap());
                // The first line after the XML log's head.
                let mut line = String::new();
                while line.is_empty() || line.starts_with("<hark_xml") {
                    line.clear();
                    r.read_line(&mut line).unwrap();
                }
                tx.send(line).unwrap();
                std::io::Read::read_to_end(&mut r, &mut Vec::new()).unwrap();
            })
        })
        .collect();
    let mut child = common::spawn_piped(
        bin()
            .args(["localize", "-", "--geometry", geo.to_str().unwrap()])
            .args(["--grid", "ring:5", "--period", "10", "--track", "-q", "-o"])
            .arg(&fifos[0])
            .arg("--odas-sst")
            .arg(&fifos[1])
            .arg("--log-text")
            .arg(&fifos[2])
            .arg("--log-xml")
            .arg(&fifos[3]),
    );
    // The first second (a few results: less than a write buffer holds), then wait with
    // stdin still open.
    let cut = 44 + 16000 * 8 * 2;
    assert!(bytes.len() > 2 * cut);
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(&bytes[..cut]).unwrap();
    stdin.flush().unwrap();
    let mut first = Vec::new();
    for _ in 0..fifos.len() {
        first.push(
            rx.recv_timeout(std::time::Duration::from_secs(60))
                .expect("a line before the input ended"),
        );
    }
    // A result line, the first line of an ODAS message ("{" alone), a text log line
    // (frame, then id x y z per source) and an XML log frame.
    first.sort();
    assert!(
        first[0].starts_with("    <positions type=\"localization\" frame=\""),
        "{first:?}"
    );
    let text: Vec<&str> = first[1].split_whitespace().collect();
    assert!(
        text[0].parse::<u64>().is_ok()
            && (text.len() - 1).is_multiple_of(4)
            && text.iter().all(|t| t.parse::<f64>().is_ok()),
        "{first:?}"
    );
    assert_eq!(first[2], "{\n", "{first:?}");
    assert!(first[3].starts_with("{\"frame\""), "{first:?}");
    stdin.write_all(&bytes[cut..]).unwrap();
    drop(stdin);
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for r in readers {
        r.join().unwrap();
    }
}

/// The summary and the HARK logs, taken in as results come (since 2026-12-03: no longer
/// from every result kept to the end), hold what the whole run's results give: the
/// summary equals `summarize` of the printed results (and gives the tracker's first
/// sightings, which the results do not hold), the text log their `to_text`.
#[test]
fn summary_and_logs_equal_the_whole_runs() {
    let (wav, geo) = scene("summary_and_logs");
    let (summary, log) = (tmp("summary_and_logs.json"), tmp("summary_and_logs.log"));
    let run = |extra: &[&str]| {
        bin()
            .args([
                "localize",
                wav.to_str().unwrap(),
                "--geometry",
                geo.to_str().unwrap(),
            ])
            .args(["--grid", "ring:5", "--period", "5", "--track", "-q", "--summary"])
            .arg(&summary)
            .args(extra)
            .output()
            .unwrap()
    };
    let o = run(&["--log-text", log.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let results: Vec<soundloc::LocalizationResult> = String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(results.len() > 20);
    let mut want = serde_json::to_value(soundloc::tracking::summarize(&results)).unwrap();
    assert!(want.as_array().is_some_and(|a| a.len() >= 2), "{want}");
    let got: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    // Only the run knows the tracker's first sightings: with the room default's
    // confirmation (W = 50 frames) each is 50 frames or more before the id's first result.
    for (g, w) in got.as_array().unwrap().iter().zip(want.as_array_mut().unwrap()) {
        let (seen, start) = (
            g["first_seen_frame"].as_u64().unwrap(),
            g["start_frame"].as_u64().unwrap(),
        );
        assert!(seen + 50 <= start, "{g}");
        assert!(
            (g["first_seen_s"].as_f64().unwrap() - seen as f64 * 0.01).abs() < 0.011,
            "{g}"
        );
        w["first_seen_frame"] = g["first_seen_frame"].clone();
        w["first_seen_s"] = g["first_seen_s"].clone();
    }
    assert_eq!(got, want);
    assert_eq!(
        std::fs::read_to_string(&log).unwrap(),
        soundloc::formats::source_log::to_text(&results)
    );
    // With --preroll the results wait PREROLL frames behind the ids given: the first
    // sightings are kept all the same (they were lost where an output had no result yet).
    let o = run(&["--preroll", "400"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let pre: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    let seen = |v: &serde_json::Value| -> Vec<u64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|s| s["first_seen_frame"].as_u64().unwrap())
            .collect()
    };
    assert_eq!(seen(&pre), seen(&got), "{pre}");
}
