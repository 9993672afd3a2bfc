//! Criterion benchmark of the seed configuration on the CPU backend: one localization
//! (GSVD and textbook GEVD, M = 60, 73 bins, W = 50, 2522 directions, 2 sources).
//! `soundloc bench` prints the full report (batched throughput, PERIOD 50/1, stage split).

use criterion::{criterion_group, criterion_main, Criterion};
use soundloc::backend::{cpu::CpuBackend, Backend, BatchOutput, Job};
use soundloc::bench::{inputs, BenchConfig};
use soundloc::Algorithm;

fn seed(c: &mut Criterion) {
    let mut g = c.benchmark_group("seed_config_one_localization");
    g.sample_size(20);
    for alg in [Algorithm::Gsvd, Algorithm::Gevd, Algorithm::Sevd] {
        let cfg = BenchConfig {
            algorithm: alg,
            batch: 1,
            ..Default::default()
        };
        let inp = inputs::<f32>(&cfg).expect("inputs");
        let mut be = CpuBackend::new(inp.plan.clone());
        let mut out = BatchOutput::default();
        g.bench_function(alg.name(), |b| {
            b.iter(|| {
                be.process(&[Job::once(&inp.spectra, &inp.windows[..1])], false, &mut out)
                    .expect("process")
            })
        });
    }
    g.finish();
}

criterion_group!(benches, seed);
criterion_main!(benches);
