//! The CUDA backend (CUDA libraries loaded at run time; kernels compiled by NVRTC).

use super::Backend;
use crate::plan::Plan;
use crate::real::Real;
use crate::{Error, Result};
use std::sync::Arc;

/// Build a CUDA backend on device `ordinal`, or say why none can be had.
pub fn new_backend<T: Real>(_plan: Arc<Plan<T>>, _ordinal: usize) -> Result<Box<dyn Backend<T>>> {
    Err(Error::Device("the CUDA backend is not part of this build yet".into()))
}
