//! `soundloc batch`: one result file per recording equal to `localize`'s, shards that
//! split the list, resumable reruns, and a broken input that fails alone.

mod common;

use common::{bin, ring_scene, tmp};
use std::path::PathBuf;

const TAG: &str = "batch";

fn localize_one(geo: &PathBuf, wav: &PathBuf) -> String {
    let out = bin()
        .args(["localize", "-q", "--grid", "ring:5", "--geometry"])
        .arg(geo)
        .arg(wav)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn batch_writes_one_file_per_input_shards_and_resumes() {
    let (_, geo, wav) = ring_scene(TAG, "", 1);
    // Four copies under different names, listed in a manifest (relative paths). Names
    // with dots keep everything before the extension ("c.take1.wav" → "c.take1.jsonl":
    // cut at the first dot, the two takes would share one result file).
    let dir = wav.parent().unwrap().to_path_buf();
    let names = ["a.wav", "b.wav", "c.take1.wav", "c.take2.wav"];
    for n in names {
        std::fs::copy(&wav, dir.join(n)).unwrap();
    }
    let manifest = tmp(TAG, "list.txt");
    std::fs::write(
        &manifest,
        "# recordings\na.wav\n\nb.wav\nc.take1.wav\nc.take2.wav\n",
    )
    .unwrap();
    let want = localize_one(&geo, &wav);
    let out_dir = tmp(TAG, "out");
    let run = |extra: &[&str]| {
        bin()
            .args(["batch", "--grid", "ring:5", "--geometry"])
            .arg(&geo)
            .arg("--manifest")
            .arg(&manifest)
            .arg("--out-dir")
            .arg(&out_dir)
            .args(extra)
            .output()
            .unwrap()
    };
    // Shard 1 of 2 takes b and c.take2 only.
    let o = run(&["--shard", "1/2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!out_dir.join("a.jsonl").exists() && out_dir.join("b.jsonl").exists());
    assert!(out_dir.join("c.take2.jsonl").exists() && !out_dir.join("c.take1.jsonl").exists());
    assert!(!out_dir.join("c.jsonl").exists());
    // The set-up note (the room default's NormMUSIC) once, not once per recording.
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.matches("NormMUSIC").count(), 1, "{err}");
    // The rest: shard 0 of 2; then a rerun of everything skips all four.
    assert!(run(&["--shard", "0/2"]).status.success());
    for n in ["a", "b", "c.take1", "c.take2"] {
        let got = std::fs::read_to_string(out_dir.join(format!("{n}.jsonl"))).unwrap();
        assert_eq!(got, want, "{n}.jsonl differs from localize's output");
    }
    let o = run(&[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && err.contains("0 localized, 4 skipped"),
        "{err}"
    );
    // A temporary file of a killed run (its process gone) is pointed out, not deleted;
    // one of a running process (this test's) is not mentioned.
    let dead = out_dir.join(".b.jsonl.999999999-0.tmp");
    let alive = out_dir.join(format!(".c.jsonl.{}-0.tmp", std::process::id()));
    std::fs::write(&dead, "partial").unwrap();
    std::fs::write(&alive, "partial").unwrap();
    let err = String::from_utf8_lossy(&run(&[]).stderr).into_owned();
    if cfg!(target_os = "linux") {
        assert!(
            err.contains("1 temporary file(s) of interrupted runs")
                && err.contains(".b.jsonl.999999999-0.tmp"),
            "{err}"
        );
    }
    assert!(dead.exists() && alive.exists());
    std::fs::remove_file(&dead).unwrap();
    std::fs::remove_file(&alive).unwrap();
    // --overwrite redoes them.
    let o = run(&["--overwrite", "-q"]);
    assert!(o.status.success());
    // Bad shard and per-input-only options are refused before anything runs.
    let o = run(&["--shard", "2/2"]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--shard"));
    let o = run(&["-o", "x.jsonl"]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("--out-dir"));
}

#[test]
fn a_broken_input_fails_alone_and_names_itself() {
    let (_, geo, wav) = ring_scene(TAG, "broken-", 1);
    let dir = wav.parent().unwrap().to_path_buf();
    let good = dir.join("good.wav");
    std::fs::copy(&wav, &good).unwrap();
    let bad = dir.join("bad.wav");
    std::fs::write(&bad, b"RIFF\x10\x00\x00\x00WAVEjunk").unwrap();
    let out_dir = tmp(TAG, "out-broken");
    let o = bin()
        .args(["batch", "--grid", "ring:5", "--geometry"])
        .arg(&geo)
        .arg(&bad)
        .arg(&good)
        .arg("--out-dir")
        .arg(&out_dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("bad.wav") && err.contains("1 localized") && err.contains("1 failed"),
        "{err}"
    );
    assert!(out_dir.join("good.jsonl").exists());
    assert!(
        !out_dir.join("bad.jsonl").exists(),
        "nothing half-written for the broken input"
    );
    // Two inputs that would write the same result file are refused up front.
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    std::fs::copy(&wav, dir.join("sub/good.wav")).unwrap();
    let o = bin()
        .args(["batch", "--grid", "ring:5", "--geometry"])
        .arg(&geo)
        .arg(&good)
        .arg(dir.join("sub/good.wav"))
        .arg("--out-dir")
        .arg(&out_dir)
        .output()
        .unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("would both write"));
    // Standard input and network sources are `localize`'s, not batch's (it wrote "-.jsonl").
    for not_a_file in ["-", "tcp:127.0.0.1:9"] {
        let o = bin()
            .args(["batch", "--grid", "ring:5", "--geometry"])
            .arg(&geo)
            .arg(not_a_file)
            .arg("--out-dir")
            .arg(&out_dir)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("batch localizes recordings (files)"), "{err}");
    }
    // A folder where a result would go is that recording's failure, not a result that
    // exists (a rerun must not count it as done).
    let out_dir2 = tmp(TAG, "out-folder");
    std::fs::create_dir_all(out_dir2.join("good.jsonl")).unwrap();
    let o = bin()
        .args(["batch", "--grid", "ring:5", "--geometry"])
        .arg(&geo)
        .arg(&good)
        .arg("--out-dir")
        .arg(&out_dir2)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("is a directory") && err.contains("0 skipped") && err.contains("1 failed"),
        "{err}"
    );
}
