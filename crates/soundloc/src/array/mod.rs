//! The array description: microphone geometry, candidate directions, and the transfer
//! functions that tie them together (measured, from HARK files, or computed free-field).
//!
//! Conventions: positions in metres, right-handed x/y/z; azimuth = atan2(y, x) from +x
//! toward +y; elevation from the x-y plane; degrees only at I/O.

pub mod freefield;
pub mod geometry;
pub mod grid;
pub mod transfer;

pub use geometry::Geometry;
pub use grid::{Grid, GridKind};
pub use transfer::TransferFunctions;
