//! Several devices behind one [`Backend`]: each batch of windows is cut into contiguous
//! shares, one per device in proportion to its batch capacity, run at the same time (one
//! thread per device, each with its own backend, stream and workspace), and the outputs
//! are joined in window order — so results equal one device's. A new plan (K changed)
//! reaches every device.

use super::{Backend, BatchOutput, Job, StageTimes};
use crate::plan::Plan;
use crate::real::Real;
use crate::Result;
use std::sync::Arc;

/// Backends on several devices, used as one.
pub struct MultiBackend<T: Real> {
    parts: Vec<Box<dyn Backend<T>>>,
    outs: Vec<BatchOutput>,
}

impl<T: Real> MultiBackend<T> {
    /// Join `parts` (at least one).
    pub fn new(parts: Vec<Box<dyn Backend<T>>>) -> Result<Self> {
        if parts.is_empty() {
            return Err(crate::Error::Config("no device to run on".into()));
        }
        let outs = parts.iter().map(|_| BatchOutput::default()).collect();
        Ok(MultiBackend { parts, outs })
    }

    /// Number of devices.
    pub fn num_devices(&self) -> usize {
        self.parts.len()
    }
}

/// The windows `r` of the flattened window list of `jobs` (jobs in order, windows in
/// order), as jobs.
pub fn sub_jobs<'a, T: Real>(jobs: &[Job<'a, T>], r: std::ops::Range<usize>) -> Vec<Job<'a, T>> {
    let mut out = Vec::new();
    let mut at = 0;
    for j in jobs {
        let n = j.windows.len();
        let (lo, hi) = (r.start.max(at), r.end.min(at + n));
        if lo < hi {
            out.push(Job {
                windows: &j.windows[lo - at..hi - at],
                ..*j
            });
        }
        at += n;
    }
    out
}

/// Cut `n` windows into contiguous shares proportional to `caps` (each ≤ its cap when
/// `n` ≤ Σ caps); shares may be empty.
pub fn shares(n: usize, caps: &[usize]) -> Vec<std::ops::Range<usize>> {
    let total: usize = caps.iter().sum::<usize>().max(1);
    let mut out = Vec::with_capacity(caps.len());
    let mut start = 0;
    let mut acc = 0;
    for (i, &c) in caps.iter().enumerate() {
        acc += c;
        let end = if i + 1 == caps.len() {
            n
        } else {
            (n * acc).div_ceil(total).min(n)
        };
        let end = end.max(start);
        out.push(start..end);
        start = end;
    }
    out
}

impl<T: Real> Backend<T> for MultiBackend<T> {
    fn device_name(&self) -> String {
        let names: Vec<String> = self.parts.iter().map(|p| p.device_name()).collect();
        if names.len() == 1 {
            return names[0].clone();
        }
        format!("{} devices: {}", names.len(), names.join(" + "))
    }

    fn max_windows_per_batch(&self) -> usize {
        self.parts.iter().map(|p| p.max_windows_per_batch()).sum()
    }

    fn process(&mut self, jobs: &[Job<'_, T>], want_spectrum: bool, out: &mut BatchOutput) -> Result<()> {
        // The parts check their own share; jobs that disagree on `phased` could be split
        // apart, so that is checked for the whole call.
        super::check_phased("multi-device backend", jobs)?;
        let caps: Vec<usize> = self.parts.iter().map(|p| p.max_windows_per_batch()).collect();
        let cut = shares(super::count_windows(jobs), &caps);
        let parts: Vec<Vec<Job<'_, T>>> = cut.iter().map(|r| sub_jobs(jobs, r.clone())).collect();
        let results: Vec<Result<()>> = std::thread::scope(|s| {
            let handles: Vec<_> = self
                .parts
                .iter_mut()
                .zip(self.outs.iter_mut())
                .zip(&parts)
                .filter(|(_, j)| !j.is_empty())
                .map(|((p, o), j)| s.spawn(move || p.process(j, want_spectrum, o)))
                .collect();
            handles
                .into_iter()
                .map(|h| {
                    h.join()
                        .unwrap_or_else(|_| Err(crate::Error::Device("a device thread panicked".into())))
                })
                .collect()
        });
        for r in results {
            r?;
        }
        out.peaks.clear();
        out.spectrum_db.clear();
        out.bin_weight.clear();
        out.source_count.clear();
        for (o, r) in self.outs.iter_mut().zip(&cut) {
            if r.is_empty() {
                continue;
            }
            out.peaks.append(&mut o.peaks);
            out.spectrum_db.append(&mut o.spectrum_db);
            out.bin_weight.append(&mut o.bin_weight);
            out.source_count.append(&mut o.source_count);
        }
        Ok(())
    }

    fn set_plan(&mut self, plan: Arc<Plan<T>>) -> Result<()> {
        for p in &mut self.parts {
            p.set_plan(plan.clone())?;
        }
        Ok(())
    }

    /// Summed over devices (device time, not wall time).
    fn stage_times(&self) -> StageTimes {
        let mut t = StageTimes::default();
        for p in &self.parts {
            let s = p.stage_times();
            t.correlation_ms += s.correlation_ms;
            t.decomposition_ms += s.decomposition_ms;
            t.spectrum_ms += s.spectrum_ms;
            t.peaks_ms += s.peaks_ms;
        }
        t
    }

    fn reset_stage_times(&mut self) {
        for p in &mut self.parts {
            p.reset_stage_times();
        }
    }

    fn forget(&mut self, stream: super::StreamId) {
        for p in &mut self.parts {
            p.forget(stream);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::cpu::CpuBackend;
    use crate::backend::DeviceChoice;
    use crate::bench::{inputs, BenchConfig};
    use crate::config::Algorithm;

    #[test]
    fn shares_cover_the_batch_in_order_and_follow_capacity() {
        assert_eq!(shares(10, &[16, 16]), vec![0..5, 5..10]);
        assert_eq!(shares(1, &[16, 16]), vec![0..1, 1..1]);
        assert_eq!(shares(9, &[10, 20]), vec![0..3, 3..9]);
        assert_eq!(shares(0, &[4, 4, 4]), vec![0..0, 0..0, 0..0]);
        for n in 0..40 {
            let s = shares(n, &[3, 5, 7]);
            assert_eq!(s[0].start, 0);
            assert_eq!(s[2].end, n);
            assert!(s.windows(2).all(|w| w[0].end == w[1].start));
        }
    }

    #[test]
    fn two_cpu_backends_standing_in_for_two_gpus_equal_one() {
        for alg in [Algorithm::Gsvd, Algorithm::Gevd] {
            let cfg = BenchConfig {
                algorithm: alg,
                num_mics: 8,
                num_dirs: 200,
                batch: 7,
                ..BenchConfig::default()
            };
            let inp = inputs::<f32>(&cfg).unwrap();
            let mut one = CpuBackend::new(inp.plan.clone());
            let mut want = BatchOutput::default();
            one.process(&[Job::once(&inp.spectra, &inp.windows)], true, &mut want)
                .unwrap();
            let parts: Vec<Box<dyn Backend<f32>>> = vec![
                Box::new(CpuBackend::new(inp.plan.clone())),
                Box::new(CpuBackend::new(inp.plan.clone())),
            ];
            let mut two = MultiBackend::new(parts).unwrap();
            assert_eq!(two.max_windows_per_batch(), 2 * one.max_windows_per_batch());
            let mut got = BatchOutput::default();
            two.process(&[Job::once(&inp.spectra, &inp.windows)], true, &mut got)
                .unwrap();
            assert_eq!(got, want, "{alg:?}");
            assert_eq!(got.peaks.len(), 7);
            // A new plan reaches both; a smaller batch (one device idle) still matches.
            two.set_plan(inp.plan.clone()).unwrap();
            one.process(&[Job::once(&inp.spectra, &inp.windows[..1])], false, &mut want)
                .unwrap();
            two.process(&[Job::once(&inp.spectra, &inp.windows[..1])], false, &mut got)
                .unwrap();
            assert_eq!(got, want);
        }
    }

    #[test]
    fn several_streams_in_one_call_split_across_devices_equal_one() {
        let cfg = BenchConfig {
            algorithm: Algorithm::Gevd,
            num_mics: 6,
            num_dirs: 120,
            batch: 9,
            ..BenchConfig::default()
        };
        let inp = inputs::<f32>(&cfg).unwrap();
        let (s1, s2) = (
            crate::backend::StreamId::fresh(),
            crate::backend::StreamId::fresh(),
        );
        let jobs = [
            Job {
                stream: s1,
                first: 0,
                spectra: &inp.spectra,
                windows: &inp.windows[..4],
            },
            Job {
                stream: s2,
                first: 0,
                spectra: &inp.spectra,
                windows: &inp.windows[4..],
            },
        ];
        let mut one = CpuBackend::new(inp.plan.clone());
        let mut want = BatchOutput::default();
        one.process(&jobs, true, &mut want).unwrap();
        // Each stream alone gives the same rows.
        let mut alone = BatchOutput::default();
        one.process(&jobs[1..], true, &mut alone).unwrap();
        assert_eq!(alone.peaks[..], want.peaks[4..]);
        let parts: Vec<Box<dyn Backend<f32>>> = vec![
            Box::new(CpuBackend::new(inp.plan.clone())),
            Box::new(CpuBackend::new(inp.plan.clone())),
        ];
        let mut two = MultiBackend::new(parts).unwrap();
        let mut got = BatchOutput::default();
        two.process(&jobs, true, &mut got).unwrap();
        assert_eq!(got, want);
        assert_eq!(got.peaks.len(), 9);
        let cut = sub_jobs(&jobs, 3..6);
        assert_eq!(cut.len(), 2);
        assert_eq!((cut[0].windows.len(), cut[1].windows.len()), (1, 2));
        assert_eq!(cut[1].stream, s2);
    }

    #[test]
    fn device_lists_parse_and_print() {
        let p = |s: &str| s.parse::<DeviceChoice>();
        assert_eq!(p("auto").unwrap(), DeviceChoice::Auto);
        assert_eq!(p("cuda:0").unwrap(), DeviceChoice::Cuda);
        assert_eq!(p("cuda:all").unwrap(), DeviceChoice::CudaAll);
        let two = p("cuda:0, 1").unwrap();
        assert_eq!(two, DeviceChoice::CudaSet(3));
        assert_eq!(two.to_string(), "cuda:0,1");
        assert_eq!(two.ordinals(), Some(vec![0, 1]));
        assert_eq!(p("cuda:3,1").unwrap().ordinals(), Some(vec![1, 3]));
        for bad in ["gpu", "cuda:", "cuda:x", "cuda:64", "cuda:1,1", "cuda:-1"] {
            assert!(p(bad).is_err(), "{bad}");
        }
        let twice = p("cuda:0,2,0").unwrap_err().to_string();
        assert!(twice.contains("GPU 0 is named twice"), "{twice}");
        let j: DeviceChoice = serde_json::from_str("\"cuda:2,3\"").unwrap();
        assert_eq!(serde_json::to_string(&j).unwrap(), "\"cuda:2,3\"");
        assert!(serde_json::from_str::<DeviceChoice>("\"tpu\"").is_err());
    }
}
