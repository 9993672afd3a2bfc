//! # soundloc — MUSIC sound source localization for microphone arrays
//!
//! soundloc finds where sounds come from (azimuth, elevation) with the MUSIC family —
//! SEVD-, GEVD- and GSVD-MUSIC — as robot-audition users know it from HARK's
//! LocalizeMUSIC, on the CPU (faer + rayon) or on a CUDA GPU.
//!
//! ## The pipeline (one module per stage, in order)
//!
//! | stage | module | in → out |
//! |---|---|---|
//! | audio in | [`audio`], [`input`] | WAV/FLAC/raw PCM → blocks of samples (raw PCM values) |
//! | STFT | [`stft`] | samples → frames `[frame][bin][mic]` (used bins only), streaming |
//! | correlation windows | [`correlation`] | frames → due windows; R_k per window (1/W Σ x xᴴ), scaled |
//! | noise | [`noise`] | noise audio / time range / file / online policy → K_k per bin |
//! | subspace | [`subspace`] | R_k (and K_k) → signal/noise subspace (SEVD, GEVD, GEVD-HARK, GSVD) |
//! | spectrum | [`music`] | subspace × transfer functions → P̄(d), dB |
//! | peaks | [`peaks`] | spectrum → local maxima, top NUM_SOURCE |
//! | tracking | [`tracking`] | peaks over time → sources with ids |
//! | outputs | [`output`] | JSON lines, CSV, .npy, plots, HARK logs and streams, ODAS SSL/SST, the live view |
//!
//! Beside it: the array description in [`array`](mod@array) (geometry, direction grid, transfer
//! functions), file formats in [`formats`], a scene simulator in [`sim`], and the compute
//! backends in [`backend`] (CPU and CUDA behind one batch interface). [`engine`] is the
//! only orchestration, a stream engine: it plans once ([`plan`]), takes blocks of samples
//! of any length, and feeds batches of due windows to a backend; a batch run is one push
//! of the whole recording and a flush. [`localizer`] is the public face: a plain, serde
//! [`LocalizerSpec`] holding every option becomes a [`Localizer`] (precision and device
//! resolved once) that the CLI, the Python binding and the server all use.
//!
//! ## Conventions
//! - SI units inside: metres, seconds, Hz. Degrees only at I/O; names carry units
//!   (`sample_rate_hz`, `azimuth_deg`).
//! - Azimuth = atan2(y, x), from +x toward +y, in (−180°, 180°]; elevation from the x-y
//!   plane.
//! - FFT kernel e^{−j2πkn/N}, unnormalised; integer PCM is used as raw sample values (an
//!   int16 sample 1000 is 1000.0), as HARK does: this sets the dB scale of results.
//! - Compute precision is a type parameter `T: Real` (`f32` default, `f64` reference).
#![deny(missing_docs)]

pub mod array;
pub mod audio;
pub(crate) mod avx;
pub mod backend;
pub mod bench;
pub mod config;
pub mod correlation;
pub mod demo;
pub mod engine;
pub mod error;
pub mod formats;
pub mod frames;
pub mod input;
pub(crate) mod lanes;
pub mod localizer;
pub mod music;
pub mod noise;
pub mod output;
pub mod peaks;
pub mod plan;
pub mod pool;
pub(crate) mod projections;
pub mod real;
pub mod result;
pub mod sim;
pub mod srp;
pub mod stft;
pub mod subspace;
pub mod tracking;

pub use config::{Algorithm, LocalizeConfig, Precision, WindowFunction, WindowType};
pub use engine::{Localization, Output, SpectrumTable, StreamGroup, TrackingSpec};
pub use error::{Error, Result};
pub use input::{Block, ChannelMap, RawMapping};
pub use localizer::{ArraySpec, Localizer, LocalizerGroup, LocalizerSpec, NoiseSource};
pub use noise::policy::NoiseUpdate;
pub use real::Real;
pub use result::{LocalizationResult, Source};
