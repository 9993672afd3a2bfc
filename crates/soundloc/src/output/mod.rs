//! Outputs: JSON lines, CSV, .npy spectra, plots, HARK logs and network streams, ODAS
//! messages and the live view's messages.

pub mod atomic;
pub mod csv;
pub mod hark_stream;
pub mod jsonl;
pub mod live;
pub mod netsink;
pub mod npy;
pub mod odas;
pub mod plot;
pub mod plot_keep;
pub mod style;
