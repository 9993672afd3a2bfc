//! Microphone positions in metres.

/// Microphone positions, one `[x, y, z]` in metres per channel, in channel order.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Geometry {
    /// Positions in metres.
    pub mics: Vec<[f64; 3]>,
}

impl Geometry {
    /// Number of microphones.
    pub fn num_mics(&self) -> usize {
        self.mics.len()
    }
}
