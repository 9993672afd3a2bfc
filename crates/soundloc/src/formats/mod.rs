//! File formats robot-audition users already have (HARK's), read and written.
//! Layouts: `shared/spec/hark-formats.md`.

pub mod hark_mat;
pub mod hark_zip;
pub mod hgtf;
pub mod noise_cm;
pub mod source_log;
pub mod tf_zip_read;
pub mod xml;
pub mod zip_archive;
