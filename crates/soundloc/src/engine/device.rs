//! Which backend runs a plan: the CPU, one GPU, several, or whichever is there.

use crate::backend::cpu::CpuBackend;
use crate::backend::{Backend, DeviceChoice};
use crate::plan::Plan;
use crate::real::Real;
use crate::Result;
use std::path::Path;
use std::sync::Arc;

/// Build the backend for a device choice. `Auto` uses CUDA when a usable GPU and the
/// libraries are present, else the CPU; the approximate mode (subspace tracking) runs on
/// the CPU only, so `Auto` picks the CPU and a CUDA choice is an error there. `cache`: the
/// folder where compiled GPU kernels are kept between runs (None: compile each time).
pub fn make_backend<T: Real>(
    plan: Arc<Plan<T>>,
    device: DeviceChoice,
    cache: Option<&Path>,
) -> Result<Box<dyn Backend<T>>> {
    if plan.config.subspace_tracking {
        return match device {
            DeviceChoice::Cpu | DeviceChoice::Auto => Ok(Box::new(CpuBackend::new(plan))),
            _ => Err(crate::Error::Config(format!(
                "subspace tracking (the approximate mode) runs on the CPU only; got --device {device} (use --device cpu, device=\"cpu\" in Python)"
            ))),
        };
    }
    match device {
        DeviceChoice::Cpu => Ok(Box::new(CpuBackend::new(plan))),
        DeviceChoice::Cuda => crate::backend::cuda::new_backend(plan, 0, cache),
        DeviceChoice::CudaAll | DeviceChoice::CudaSet(_) => {
            let ordinals = match device.ordinals() {
                Some(o) => o,
                None => (0..crate::backend::cuda::device_count()?).collect(),
            };
            let parts = ordinals
                .into_iter()
                .map(|i| crate::backend::cuda::new_backend(plan.clone(), i, cache))
                .collect::<Result<Vec<_>>>()?;
            Ok(Box::new(crate::backend::multi::MultiBackend::new(parts)?))
        }
        DeviceChoice::Auto => match crate::backend::cuda::new_backend(plan.clone(), 0, cache) {
            Ok(b) => Ok(b),
            Err(e) => {
                tracing::info!("CUDA not used ({e}); running on the CPU");
                Ok(Box::new(CpuBackend::new(plan)))
            }
        },
    }
}

/// Start the slow one-time GPU set-up in the background when `device` may use CUDA (see
/// [`crate::backend::cuda::prewarm`]); `cpu_only`: the run is bound to the CPU anyway.
/// Keep the guard until the backend is built.
pub fn prewarm(device: DeviceChoice, cpu_only: bool) -> Option<crate::backend::cuda::Prewarm> {
    if cpu_only {
        return None;
    }
    match device {
        DeviceChoice::Cpu => None,
        DeviceChoice::Cuda | DeviceChoice::Auto => crate::backend::cuda::prewarm(Some(vec![0])),
        DeviceChoice::CudaAll | DeviceChoice::CudaSet(_) => crate::backend::cuda::prewarm(device.ordinals()),
    }
}

/// The default folder for compiled kernels (the soundloc cache folder), for callers that
/// have no cache setting of their own.
pub fn default_cache() -> Option<std::path::PathBuf> {
    crate::array::tf_cache::TfCache::Default.dir()
}
