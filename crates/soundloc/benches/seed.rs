//! Criterion benchmark of the seed configuration on the CPU backend: one localization
//! (GSVD and textbook GEVD, M = 60, 73 bins, W = 50, 2522 directions, 2 sources).
//! `soundloc bench` prints the full report (batched throughput, PERIOD 50/1, stage split).
//! Also: eight 8 × 8 Hermitian decompositions (4 leading vectors), one at a time
//! (`subspace::eigh`) against one group in vector lanes (`subspace::eigh_lanes`).

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

fn small_eigh(c: &mut Criterion) {
    use soundloc::real::C;
    use soundloc::subspace::eigh::Eigh;
    use soundloc::subspace::eigh_lanes::{EighLanes, Form, LANES};
    let (n, k) = (8, 4);
    // Rank two plus a floor, the shape of an 8-mic ring's R with two talkers.
    let problems: Vec<Vec<C<f64>>> = (0..LANES)
        .map(|p| {
            let u = |s: usize, i: usize| {
                let x = ((p * 31 + s * 7 + i * 13) as f64 * 0.37).sin();
                C::new(x, ((p + s + i * 3) as f64 * 0.71).cos())
            };
            (0..n * n)
                .map(|ij| {
                    let (i, j) = (ij / n, ij % n);
                    let d = if i == j { 0.01 } else { 0.0 };
                    u(0, i) * u(0, j).conj() * 10.0 + u(1, i) * u(1, j).conj() * 3.0 + C::new(d, 0.0)
                })
                .collect()
        })
        .collect();
    let mut g = c.benchmark_group("eight_8x8_decompositions");
    let mut one = Eigh::new(n);
    let mut v = vec![C::new(0.0, 0.0); n * k];
    g.bench_function("one_at_a_time", |b| {
        b.iter(|| {
            for a in &problems {
                let (re, im) = one.matrix_mut();
                for (i, z) in a.iter().enumerate() {
                    (re[i], im[i]) = (z.re, z.im);
                }
                one.solve(k, &mut v).expect("solve");
            }
        })
    });
    let mut lanes = EighLanes::new(n);
    g.bench_function("one_group_in_lanes", |b| {
        b.iter(|| {
            lanes.clear(Form::R);
            for a in &problems {
                lanes.push(a, None).expect("push");
            }
            lanes.solve(k).expect("solve");
        })
    });
    g.finish();
}

criterion_group!(benches, seed, small_eigh);
criterion_main!(benches);
