//! Subspace decomposition per bin.
