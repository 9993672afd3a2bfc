//! Shoebox rooms for the simulator: the image-source method (Allen & Berkley) and the
//! windowed-sinc response that renders many reflections at once (see the module docs of
//! [`crate::sim`] for the model).

use super::SPEED_OF_SOUND_M_S;
use crate::{Error, Result};
use std::f64::consts::PI;

/// A shoebox room for image sources.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Room {
    /// Size (x, y, z) in metres.
    pub size_m: [f64; 3],
    /// Position of the room's corner (its minimum x, y, z) in array coordinates, metres.
    pub origin_m: [f64; 3],
    /// Wall reflection coefficient β (amplitude), 0..=1.
    pub reflection: f64,
    /// Highest reflection order kept (1: first order, 2: up to second order, …
    /// [`MAX_REFLECTION_ORDER`] at most).
    pub max_order: u32,
}

/// Highest reflection order a [`Room`] may ask for (≈ 10⁴ images per source).
pub const MAX_REFLECTION_ORDER: u32 = 24;

/// Above this many images per source, the reflections (order ≥ 1) are rendered through
/// a time-domain impulse response of windowed-sinc taps instead of exact phase ramps.
pub(super) const EXACT_IMAGES_MAX: usize = 64;

/// Half-length of the windowed-sinc fractional-delay taps (samples).
const SINC_HALF: i64 = 16;

impl Room {
    /// A room of `size_m` (corner at `origin_m`) whose walls give a reverberation time of
    /// `rt60_s` seconds by Sabine's formula: RT60 = 0.161·V / (S·α) with V the volume,
    /// S the wall area and α = 1 − β² the absorption, so β = √(1 − α). The order is the
    /// one whose images arrive about RT60/2 after the direct sound (where the tail is
    /// ≈ 30 dB down), capped at [`MAX_REFLECTION_ORDER`].
    pub fn with_rt60(size_m: [f64; 3], origin_m: [f64; 3], rt60_s: f64) -> Result<Room> {
        let [x, y, z] = size_m;
        if !(size_m.iter().all(|v| v.is_finite() && *v > 0.0) && rt60_s.is_finite() && rt60_s > 0.0) {
            return Err(Error::Config(format!("room {size_m:?} m with RT60 {rt60_s} s")));
        }
        let volume = x * y * z;
        let area = 2.0 * (x * y + y * z + x * z);
        let alpha = 0.161 * volume / (area * rt60_s);
        if alpha >= 1.0 {
            return Err(Error::Config(format!(
                "RT60 {rt60_s} s is shorter than a room of {size_m:?} m can have (absorption {alpha:.2} > 1)"
            )));
        }
        let mean_dim = (x + y + z) / 3.0;
        let order = (0.5 * rt60_s * SPEED_OF_SOUND_M_S / mean_dim).ceil() as u32;
        Ok(Room {
            size_m,
            origin_m,
            reflection: (1.0 - alpha).sqrt(),
            max_order: order.clamp(1, MAX_REFLECTION_ORDER),
        })
    }
}

/// Image sources of a source at `position_m` (the direct path first): positions in
/// metres and amplitude factors β^order. Without a room, just the source itself.
pub fn image_sources(position_m: [f64; 3], room: Option<&Room>) -> Vec<([f64; 3], f64)> {
    let Some(room) = room else {
        return vec![(position_m, 1.0)];
    };
    let n_max = room.max_order as i64;
    // Per axis: (coordinate, reflections) for every image coordinate.
    let axis = |a: usize| -> Vec<(f64, u32)> {
        let u = position_m[a] - room.origin_m[a];
        let l = room.size_m[a];
        let mut v = Vec::new();
        for n in -n_max..=n_max {
            for q in 0..2i64 {
                let refl = (2 * n - q).unsigned_abs() as u32;
                if refl as i64 <= n_max {
                    let c = (1 - 2 * q) as f64 * u + 2.0 * n as f64 * l + room.origin_m[a];
                    v.push((c, refl));
                }
            }
        }
        v
    };
    let (ax, ay, az) = (axis(0), axis(1), axis(2));
    let mut out = vec![(position_m, 1.0)];
    for &(x, ox) in &ax {
        for &(y, oy) in &ay {
            for &(z, oz) in &az {
                let order = ox + oy + oz;
                if order == 0 || order > room.max_order {
                    continue;
                }
                out.push(([x, y, z], room.reflection.powi(order as i32)));
            }
        }
    }
    out
}

/// The impulse response (length `len`) of the given paths (delay in samples, amplitude):
/// each a Hann-windowed sinc of ±[`SINC_HALF`] taps centred on its fractional delay.
pub(super) fn reflections_response(paths: &[(f64, f64)], len: usize) -> Vec<f64> {
    let mut h = vec![0.0f64; len];
    for &(d, a) in paths {
        if a == 0.0 || !d.is_finite() {
            continue;
        }
        let base = d.floor() as i64;
        for t in base - SINC_HALF + 1..=base + SINC_HALF {
            if t < 0 || t as usize >= len {
                continue;
            }
            let x = t as f64 - d;
            let sinc = if x.abs() < 1e-12 {
                1.0
            } else {
                (PI * x).sin() / (PI * x)
            };
            let w = 0.5 + 0.5 * (PI * x / SINC_HALF as f64).cos();
            h[t as usize] += a * sinc * w;
        }
    }
    h
}
