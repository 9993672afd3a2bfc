//! Outputs: JSON lines, CSV, .npy spectra, plots, HARK logs and network streams.

pub mod atomic;
pub mod csv;
pub mod hark_stream;
pub mod jsonl;
pub mod npy;
pub mod plot;
