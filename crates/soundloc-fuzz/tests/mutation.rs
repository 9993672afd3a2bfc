//! The suite's mutation run: 2000 seeded inputs per reader, made from valid files
//! the targets generate. No input may panic or hang, and every refusal names the file.

#[test]
fn every_reader_survives_mutated_input_and_names_the_file() {
    let iters = std::env::var("SOUNDLOC_FUZZ_ITERS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2000);
    let mut failures = Vec::new();
    for t in soundloc_fuzz::targets() {
        let r = soundloc_fuzz::run(&t, iters, 20261125, None);
        println!(
            "{}: {} execs, {} accepted, {} refused, max {:.1} ms",
            t.name,
            r.execs,
            r.accepted,
            r.refused,
            r.max_exec.as_secs_f64() * 1e3
        );
        assert!(
            r.execs >= iters * 9 / 10,
            "{}: only {} inputs made",
            t.name,
            r.execs
        );
        assert!(
            r.refused > 0,
            "{}: the mutations never produced a bad file",
            t.name
        );
        if !r.panics.is_empty() || r.unnamed > 0 || r.slow > 0 {
            failures.push(format!(
                "{}: {} panics {:?}, {} errors without the file name {:?}, {} slow",
                t.name,
                r.panics.len(),
                r.panics.iter().take(3).collect::<Vec<_>>(),
                r.unnamed,
                r.unnamed_errors,
                r.slow
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
