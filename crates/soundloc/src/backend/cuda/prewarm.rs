//! The GPUs' one-time set-up (driver initialisation, each device's primary context),
//! started early on a background thread so that it overlaps loading and planning.

use super::{device, guarded};

/// Start the GPUs' one-time set-up (driver initialisation, each device's primary context:
/// ≈ 0.2 s) on a background thread, so that it overlaps loading the transfer functions
/// and planning; a backend built while the guard lives finds it done (or waits for it
/// inside the driver). `ordinals`: the devices, None for all. None without a driver;
/// failures are left for the backend to report. Dropping the guard waits for the thread
/// (never leaving it inside the driver at exit) and gives its context references back.
pub fn prewarm(ordinals: Option<Vec<usize>>) -> Option<Prewarm> {
    if !device::driver_present() {
        return None;
    }
    let thread = std::thread::Builder::new()
        .name("soundloc-cuda-prewarm".into())
        .spawn(move || {
            let mut kept = Vec::new();
            let _ = guarded(|| {
                let list = match ordinals {
                    Some(o) => o,
                    None => (0..device::device_count()?).collect(),
                };
                for i in list {
                    device::retain_context(i)?;
                    kept.push(i);
                }
                tracing::debug!("cuda: driver and contexts ready (prewarm)");
                Ok(())
            });
            kept
        })
        .ok()?;
    Some(Prewarm { thread: Some(thread) })
}

/// The background set-up of [`prewarm`]; see there.
pub struct Prewarm {
    thread: Option<std::thread::JoinHandle<Vec<usize>>>,
}

impl Drop for Prewarm {
    fn drop(&mut self) {
        if let Some(kept) = self.thread.take().and_then(|t| t.join().ok()) {
            let _ = guarded(|| {
                kept.into_iter().for_each(device::release_context);
                Ok(())
            });
        }
    }
}
