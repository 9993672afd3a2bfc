//! Outputs: JSON lines, CSV, .npy spectra, plots, HARK logs and network streams.
