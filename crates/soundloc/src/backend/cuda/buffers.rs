//! Device and pinned host buffers of the CUDA backend: what they are, how they grow.

use super::*;

/// A device buffer (freed by the backend).
#[derive(Default)]
pub(super) struct Buf {
    pub(super) ptr: DevPtr,
    pub(super) bytes: usize,
}

/// A pinned host buffer.
pub(super) struct Pinned {
    pub(super) ptr: *mut u8,
    pub(super) bytes: usize,
}

impl Default for Pinned {
    fn default() -> Self {
        Pinned {
            ptr: std::ptr::null_mut(),
            bytes: 0,
        }
    }
}

pub(super) fn csize<T: Real>() -> usize {
    std::mem::size_of::<C<T>>()
}

pub(super) fn as_bytes<V>(v: &[V]) -> &[u8] {
    // SAFETY: plain-old-data slices (reals, complex pairs, integers).
    unsafe { std::slice::from_raw_parts(v.as_ptr() as *const u8, std::mem::size_of_val(v)) }
}

#[derive(Clone, Copy)]
pub(super) enum BufId {
    St,
    N2Den,
    N2Num,
    Wcm,
    Wrm,
    Weights,
    Offs,
    Nbrs,
    AzOk,
}

#[derive(Clone, Copy)]
pub(super) enum Scratch {
    X,
    Win,
    R,
    E,
    E64,
    Jacobi,
    Ppart,
    Gain,
    Bw,
    Info,
    Prof,
    H,
    Scale,
    Db,
    Spec,
    Out,
    BinMax,
    /// eigh.cu's T for count.cu, [sub-batch matrix][2M] doubles.
    Tri,
    /// count.cu's k̂, [window · nb + bin] ints.
    Count,
}

#[derive(Clone, Copy)]
pub(super) enum HostBuf {
    Stage0,
    Stage1,
    Win,
    Out,
    Spec,
    Bw,
    /// Zeros (to clear device buffers with a copy).
    Zero,
    /// count.cu's k̂ per matrix.
    Count,
}

impl<T: Real> CudaBackend<T> {
    pub(super) fn buf(&mut self, id: BufId) -> &mut Buf {
        match id {
            BufId::St => &mut self.d_st,
            BufId::N2Den => &mut self.d_n2den,
            BufId::N2Num => &mut self.d_n2num,
            BufId::Wcm => &mut self.d_wcm,
            BufId::Wrm => &mut self.d_wrm,
            BufId::Weights => &mut self.d_weights,
            BufId::Offs => &mut self.d_offs,
            BufId::Nbrs => &mut self.d_nbrs,
            BufId::AzOk => &mut self.d_azok,
        }
    }

    /// Synchronous upload of plan data into its buffer (grown as needed).
    pub(super) fn upload(&mut self, id: BufId, data: &[u8]) -> Result<()> {
        let need = data.len().max(16);
        let (ptr, bytes) = {
            let b = self.buf(id);
            (b.ptr, b.bytes)
        };
        if bytes < need {
            if ptr != 0 {
                self.gpu.free(ptr);
            }
            let p = self.gpu.alloc(need)?;
            *self.buf(id) = Buf { ptr: p, bytes: need };
        }
        let dst = self.buf(id).ptr;
        if !data.is_empty() {
            // SAFETY: `data` outlives the synchronisation below; dst holds `need` bytes.
            unsafe { self.gpu.htod(dst, data.as_ptr(), data.len(), Stream::Copy)? };
            self.gpu.sync(Stream::Copy)?;
        }
        Ok(())
    }

    /// Pick the sub-batch size and the largest batch from free device memory.
    pub(super) fn size_batches(&mut self) -> Result<()> {
        let l = &self.lay;
        let (cs, ts) = (csize::<T>(), std::mem::size_of::<T>());
        let sms = self.gpu.sm_count().max(1);
        // About 32 matrices per multiprocessor per sub-batch: several waves of the
        // decomposition kernel, so that the tail of one wave does not dominate.
        let sub = (32 * sms).div_ceil(l.nb).clamp(1, 256);
        let h_per_mat = if l.eigh && l.valmode != 0 {
            l.m * l.m * 16
        } else {
            0
        };
        let per_sub_window = l.nb * l.m * l.m * l.r_size
            + l.nb * l.ne * l.m * cs
            + if l.e64 { l.nb * l.ns * l.m * 16 } else { 0 }
            + l.nb * (l.dec_scratch_per_mat + h_per_mat)
            + l.nb * l.d * ts;
        let (free, _) = self.gpu.mem_info()?;
        let budget = free / 4;
        self.sub_batch = sub.min((budget / per_sub_window.max(1)).max(1));
        let w = self.plan.config.window.max(1);
        let per_window = w * l.nb * l.m * cs + l.d * (8 + 4 + ts) + l.nb * (ts + 8) + (1 + l.peak_kout) * 16;
        self.max_batch =
            ((free / 4).saturating_sub(self.sub_batch * per_sub_window) / per_window.max(1)).clamp(1, 4096);
        Ok(())
    }

    /// The device buffer behind a scratch slot.
    pub(super) fn slot(&mut self, which: Scratch) -> &mut Buf {
        match which {
            Scratch::X => &mut self.d_x,
            Scratch::Win => &mut self.d_win,
            Scratch::R => &mut self.d_r,
            Scratch::E => &mut self.d_e,
            Scratch::E64 => &mut self.d_e64,
            Scratch::Jacobi => &mut self.d_scratch,
            Scratch::Ppart => &mut self.d_ppart,
            Scratch::Gain => &mut self.d_gain,
            Scratch::Bw => &mut self.d_bw,
            Scratch::Info => &mut self.d_info,
            Scratch::Prof => &mut self.d_prof,
            Scratch::H => &mut self.d_h,
            Scratch::Scale => &mut self.d_scale,
            Scratch::Db => &mut self.d_db,
            Scratch::Spec => &mut self.d_spec,
            Scratch::Out => &mut self.d_out,
            Scratch::BinMax => &mut self.d_binmax,
            Scratch::Tri => &mut self.d_tri,
            Scratch::Count => &mut self.d_count,
        }
    }

    pub(super) fn ensure(&mut self, which: Scratch, bytes: usize) -> Result<DevPtr> {
        let Buf {
            ptr: old,
            bytes: have,
        } = *self.slot(which);
        if have >= bytes.max(16) {
            return Ok(old);
        }
        let grow = (bytes.max(16) + bytes / 4).max(have * 3 / 2);
        if old != 0 {
            self.gpu.free(old);
            // Never leave a freed pointer in the slot if the allocation below fails.
            *self.slot(which) = Buf { ptr: 0, bytes: 0 };
        }
        let p = self.gpu.alloc(grow)?;
        *self.slot(which) = Buf { ptr: p, bytes: grow };
        Ok(p)
    }

    pub(super) fn ensure_pinned(&mut self, which: HostBuf, bytes: usize) -> Result<*mut u8> {
        let need = bytes.max(16);
        let cur = match which {
            HostBuf::Stage0 => &self.h_stage[0],
            HostBuf::Stage1 => &self.h_stage[1],
            HostBuf::Win => &self.h_win,
            HostBuf::Out => &self.h_out,
            HostBuf::Spec => &self.h_spec,
            HostBuf::Bw => &self.h_bw,
            HostBuf::Zero => &self.h_zero,
            HostBuf::Count => &self.h_count,
        };
        if cur.bytes >= need {
            return Ok(cur.ptr);
        }
        let old = cur.ptr;
        let grow = need.max(cur.bytes * 3 / 2);
        if !old.is_null() {
            // Outstanding copies may still read or write it.
            self.gpu.sync(Stream::Copy)?;
            self.gpu.sync(Stream::Compute)?;
            self.gpu.free_pinned(old);
        }
        let p = self.gpu.alloc_pinned(grow)?;
        let slot = match which {
            HostBuf::Stage0 => &mut self.h_stage[0],
            HostBuf::Stage1 => &mut self.h_stage[1],
            HostBuf::Win => &mut self.h_win,
            HostBuf::Out => &mut self.h_out,
            HostBuf::Spec => &mut self.h_spec,
            HostBuf::Bw => &mut self.h_bw,
            HostBuf::Count => &mut self.h_count,
            HostBuf::Zero => {
                // SAFETY: p holds `grow` bytes, just allocated.
                unsafe { std::ptr::write_bytes(p, 0, grow) };
                &mut self.h_zero
            }
        };
        *slot = Pinned { ptr: p, bytes: grow };
        Ok(p)
    }
}

/// Copy host bytes into pinned memory, in parallel for large copies.
pub(super) fn copy_to_pinned(src: &[u8], dst: *mut u8) {
    pub(super) const PIECE: usize = 256 << 10;
    pub(super) struct P(*mut u8);
    // SAFETY: disjoint pieces of one buffer are written by different threads.
    unsafe impl Sync for P {}
    unsafe impl Send for P {}
    let d = P(dst);
    if src.len() <= 2 * PIECE || rayon::current_num_threads() < 2 {
        // SAFETY: the caller sized `dst` for `src`.
        unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), dst, src.len()) };
        return;
    }
    src.par_chunks(PIECE).enumerate().for_each(|(i, c)| {
        let d = &d;
        // SAFETY: piece i lands at offset i·PIECE, inside the buffer, disjoint from others.
        unsafe { std::ptr::copy_nonoverlapping(c.as_ptr(), d.0.add(i * PIECE), c.len()) };
    });
}
