//! A device that fails mid-run: under `auto` the stream goes on on the CPU with no result
//! lost or repeated (and says so); otherwise a clear error, with the results before it
//! delivered once.

use soundloc::backend::cpu::CpuBackend;
use soundloc::backend::{Backend, BatchOutput, Job, StageTimes};
use soundloc::demo::ring8_drone;
use soundloc::engine::{Engine, StreamOptions};
use soundloc::input::ChannelMap;
use soundloc::noise::policy::{InitialNoise, NoiseUpdate};
use soundloc::plan::Plan;
use soundloc::{Block, Error, LocalizeConfig, Output, Result};
use std::sync::Arc;

/// A CPU backend that reports a device error from its `fail_at`-th call on.
struct Failing {
    inner: CpuBackend<f32>,
    calls: usize,
    fail_at: usize,
}

impl Backend<f32> for Failing {
    fn device_name(&self) -> String {
        "cuda:9 (a test stand-in)".into()
    }
    fn max_windows_per_batch(&self) -> usize {
        3
    }
    fn process(&mut self, jobs: &[Job<'_, f32>], want: bool, out: &mut BatchOutput) -> Result<()> {
        self.calls += 1;
        if self.calls >= self.fail_at {
            return Err(Error::Device("CUDA_ERROR_ILLEGAL_ADDRESS (launch)".into()));
        }
        self.inner.process(jobs, want, out)
    }
    fn set_plan(&mut self, plan: Arc<Plan<f32>>) -> Result<()> {
        self.inner.set_plan(plan)
    }
    fn stage_times(&self) -> StageTimes {
        self.inner.stage_times()
    }
    fn reset_stage_times(&mut self) {
        self.inner.reset_stage_times()
    }
}

#[test]
fn a_failing_device_falls_back_to_the_cpu_or_fails_clearly() {
    let sc = ring8_drone(0.0, 3).unwrap();
    let audio = sc.render();
    let config = LocalizeConfig {
        period: 10,
        ..LocalizeConfig::default()
    };
    let tf = sc.transfer_functions(&config).unwrap();
    let plan = Arc::new(Plan::<f32>::new(&config, &tf, None).unwrap());
    let options = StreamOptions {
        initial_noise: InitialNoise::Given(None),
        noise_update: NoiseUpdate::Fixed,
        tracking: None,
        channels: ChannelMap::identity(8),
        want_spectrum: false,
    };
    let push_all = |e: &mut Engine<f32>| -> (Output, Result<()>) {
        let mut out = Output::default();
        for p0 in (0..audio.channels[0].len()).step_by(1600) {
            let part: Vec<Vec<f32>> = audio
                .channels
                .iter()
                .map(|c| c[p0..(p0 + 1600).min(c.len())].to_vec())
                .collect();
            if let Err(err) = e.push(Block::Planar(&part), &mut out) {
                return (out, Err(err));
            }
        }
        let r = e.flush(&mut out);
        (out, r)
    };
    let mut cpu = Engine::new(
        plan.clone(),
        Box::new(CpuBackend::new(plan.clone())),
        options.clone(),
    )
    .unwrap();
    let (want, r) = push_all(&mut cpu);
    r.unwrap();
    assert!(want.results.len() > 20);
    let failing = || Failing {
        inner: CpuBackend::new(plan.clone()),
        calls: 0,
        fail_at: 5,
    };
    // `auto`: the same results, each once, and a note.
    let mut e = Engine::new(plan.clone(), Box::new(failing()), options.clone()).unwrap();
    e.set_cpu_fallback(true);
    let (got, r) = push_all(&mut e);
    r.unwrap();
    assert!(got.results == want.results, "results lost or repeated");
    assert!(
        got.notes
            .iter()
            .any(|n| n.contains("cuda:9") && n.contains("going on with the CPU")),
        "{:?}",
        got.notes
    );
    assert!(e.device_name().starts_with("cpu"));
    // A named device: the error, after the results of the batches that ran.
    let mut e = Engine::new(plan.clone(), Box::new(failing()), options).unwrap();
    let (got, r) = push_all(&mut e);
    let err = r.unwrap_err();
    assert!(err.to_string().contains("ILLEGAL_ADDRESS"), "{err}");
    assert!(!got.results.is_empty() && got.results.len() < want.results.len());
    assert!(got.results[..] == want.results[..got.results.len()]);
}
