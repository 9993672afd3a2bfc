//! How [`Engine`] runs its windows: the due windows of new frames, in batches that share
//! a K, through its backend (and the CPU when a device fails and fallback is on), and
//! which frames it can let go of afterwards.

use super::{Engine, Output};
use crate::backend::{cpu::CpuBackend, Backend, Job, WindowSpec};
use crate::noise::policy::KSource;
use crate::real::Real;
use crate::{Error, Result};

impl<T: Real> Engine<T> {
    /// Transform the complete frames, run the due windows, drop what is no longer needed.
    pub(super) fn advance(&mut self, out: &mut Output) -> Result<()> {
        let before = self.ring.end();
        self.stft
            .frames_into(&mut self.ring, self.noise.keep_samples_from());
        let after = self.ring.end();
        self.noise.observe_frames(&self.ring, before..after)?;
        if let Some(h) = &mut self.health {
            let sp = self.ring.spectra();
            let fl = sp.num_bins * sp.num_mics;
            let from = before.saturating_sub(self.ring.first());
            h.observe_frames(&sp.data[from * fl..], sp.num_bins);
        }
        let mut due = Vec::new();
        self.scheduler.due(after, &mut due);
        self.pending.extend(due);
        self.run_pending(out)?;
        self.release_frames();
        Ok(())
    }

    /// Drop the frames no window still needs (those of windows waiting to run stay, and,
    /// while windows overlap by more than half, those of the last window run).
    pub(super) fn release_frames(&mut self) {
        let mut next = self.pending.front().map_or(self.scheduler.next_start(), |w| {
            w.start.min(self.scheduler.next_start())
        });
        let c = &self.plan.config;
        if let Some(s) = self.last_start.filter(|_| 2 * c.period < c.window) {
            next = next.min(s);
        }
        if let Some(o) = &mut self.onset {
            // Frames no window reads (PERIOD > W) still pass through the onset average.
            // With one K for the whole stream, installed, they are weighed now, with the
            // K any later batch would use, instead of being kept until the next window
            // runs (up to PERIOD frames); else they wait for that window's K.
            if o.next_frame() < next && self.noise.fixed() && self.current == Some(KSource::Initial) {
                let first = self.ring.first();
                o.apply(&self.plan, self.ring.spectra_mut(), first, next);
            }
            next = next.min(o.next_frame());
        }
        self.ring.drop_before(self.noise.keep_frames_from(next));
    }

    /// Run pending windows in batches that share a K, switching K between them.
    pub(super) fn run_pending(&mut self, out: &mut Output) -> Result<()> {
        let Some(batch) = self.backend.as_ref().map(|b| b.max_windows_per_batch().max(1)) else {
            return Ok(()); // a group's stream: the group runs them
        };
        while let Some(&w) = self.pending.front() {
            let Some(src) = self.noise.choose(&w) else {
                return Ok(()); // K not known yet: hold
            };
            if self.current.as_ref() != Some(&src) {
                let (k, what) = self.noise.matrices(&src, &self.ring, w.frame)?;
                self.install(&k)
                    .map_err(|e| Error::Mismatch(format!("{what}: {e}")))?;
                self.current = Some(src.clone());
            }
            let mut chunk = vec![w];
            self.pending.pop_front();
            while chunk.len() < batch {
                match self.pending.front() {
                    Some(&next) if self.noise.choose(&next).as_ref() == Some(&src) => {
                        chunk.push(next);
                        self.pending.pop_front();
                    }
                    _ => break,
                }
            }
            self.run_windows(&chunk, out)?;
        }
        Ok(())
    }

    /// Onset-weight the frames not weighted yet up to the end of `windows` (absolute
    /// starts), with the K installed for them, before a backend reads them (the GPU
    /// uploads only the frames a call's windows read). Every frame is weighted once, in
    /// order, with the K of the first batch that reaches it, so the weights do not
    /// depend on how the input was split into blocks ([`Engine::release_frames`] keeps
    /// the frames not weighted yet). A no-op without onset weighting.
    pub(super) fn weigh_frames(&mut self, windows: &[WindowSpec]) {
        let upto = windows.iter().map(|w| w.start + w.len).max().unwrap_or(0);
        if let Some(o) = &mut self.onset {
            let first = self.ring.first();
            o.apply(&self.plan, self.ring.spectra_mut(), first, upto);
        }
    }

    fn run_windows(&mut self, windows: &[WindowSpec], out: &mut Output) -> Result<()> {
        self.weigh_frames(windows);
        let want = self.wants_spectrum();
        let mut batch = std::mem::take(&mut self.batch);
        let job = Job {
            stream: self.stream,
            first: self.ring.first(),
            spectra: self.ring.spectra(),
            windows,
        };
        let mut r = match self.backend.as_mut() {
            Some(b) => b.process(&[job], want, &mut batch),
            None => Err(Error::Config(
                "a group's stream runs its windows through the group".into(),
            )),
        };
        if let (Err(Error::Device(e)), true) = (&r, self.cpu_fallback) {
            out.notes.push(format!(
                "warning: {} failed ({e}); going on with the CPU from frame {}",
                self.device_name(),
                self.report_frame(windows[0].frame)
            ));
            let mut cpu: Box<dyn Backend<T>> = Box::new(CpuBackend::new(self.plan.clone()));
            r = cpu.process(&[job], want, &mut batch);
            self.backend = Some(cpu);
            self.cpu_fallback = false;
        }
        let r = r.and_then(|()| self.deliver(windows, &batch, 0, out));
        self.batch = batch;
        r
    }

    /// The job that hands `windows` (of this stream, absolute frames) to a backend.
    pub(super) fn job<'a>(&'a self, windows: &'a [WindowSpec]) -> Job<'a, T> {
        Job {
            stream: self.stream,
            first: self.ring.first(),
            spectra: self.ring.spectra(),
            windows,
        }
    }

    /// Whether windows run for this stream ask for the spectrum.
    pub(super) fn wants_spectrum(&self) -> bool {
        self.options.want_spectrum || self.plan.config.refine
    }
}
