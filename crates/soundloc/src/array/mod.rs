//! The array description: microphone geometry, candidate directions, and the transfer
//! functions that tie them together (measured, from HARK files, or computed free-field).
//!
//! Conventions: positions in metres, right-handed x/y/z; azimuth = atan2(y, x) from +x
//! toward +y; elevation from the x-y plane; degrees only at I/O.

pub mod freefield;
pub mod geometry;
pub mod grid;
mod neighbors;
pub mod odas_cfg;
pub mod tf_cache;
pub mod transfer;

pub use geometry::Geometry;
pub use grid::{Grid, GridKind};
pub use transfer::TransferFunctions;

/// Most microphones accepted (a geometry file, a TF file, positions from Python).
pub const MAX_MICS: usize = 1024;
/// Most directions accepted in a grid.
pub const MAX_DIRECTIONS: usize = 100_000;
/// Finest ring step accepted, degrees (3600 directions).
pub const MIN_RING_STEP_DEG: f64 = 0.1;
/// Most transfer-function values (directions × microphones × bins) built or loaded:
/// 2 GiB of complex f32.
pub const MAX_TF_VALUES: usize = 1 << 28;
