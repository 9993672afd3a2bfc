//! Microphone positions in metres.
//!
//! A geometry file is TOML, positions in metres in channel order, either
//!
//! ```toml
//! mics = [[0.0365, 0.0, 0.0], [0.0258, 0.0258, 0.0]]
//! ```
//!
//! or one table per microphone:
//!
//! ```toml
//! [[mic]]
//! x = 0.0365
//! y = 0.0
//! z = 0.0       # optional, default 0
//! ```
//!
//! An ODAS configuration (`*.cfg`, libconfig: `general.mics[i].mu`) is read as well, with
//! its device channel map ([`super::odas_cfg`], [`Geometry::load_with_mapping`]).
//!
//! Directions are seen from the origin of the positions' frame, HARK's convention (a
//! robot's head centre; TAMAGO's microphones sit on a circle above the egg's centre),
//! as long as the origin lies within the array. Positions in a frame whose origin lies
//! outside it (room coordinates, as pyroomacoustics' `L` holds them) are seen from the
//! microphones' centroid instead ([`Geometry::direction_frame`]).
//!
//! Built-in shapes: [`Geometry::circle`] puts mic i at
//! (r cos 2πi/n, r sin 2πi/n, z) — the TAMAGO-03 array is `circle(8, 0.0365, 0.0)`;
//! [`Geometry::sphere`] spreads n mics near-uniformly over a sphere (Fibonacci lattice).
//! Non-finite or duplicate positions (closer than 1 µm) and unknown keys are errors.

use super::odas_cfg::OdasArray;
use crate::input::RawMapping;
use crate::{Error, Result};
use std::path::Path;

/// Microphone positions, one `[x, y, z]` in metres per channel, in channel order.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Geometry {
    /// Positions in metres.
    pub mics: Vec<[f64; 3]>,
}

/// An array wider than this (metres) gets [`Geometry::units_note`].
pub const UNITS_NOTE_APERTURE_M: f64 = 10.0;
/// Two microphones closer than this (metres) are "the same position".
pub const DUPLICATE_TOLERANCE_M: f64 = 1e-6;

/// Largest coordinate a microphone may have, metres: far past any array (a value from a
/// corrupt file is caught before its squares overflow).
pub const MAX_COORD_M: f64 = 1e6;

impl Geometry {
    /// Number of microphones.
    pub fn num_mics(&self) -> usize {
        self.mics.len()
    }

    /// A geometry from positions, checked like a file (finite, no duplicates, at least
    /// one microphone). `what` names the source in error messages.
    pub fn new(mics: Vec<[f64; 3]>, what: &Path) -> Result<Self> {
        let g = Geometry { mics };
        g.validate(what)?;
        Ok(g)
    }

    /// Check positions: at least one mic, every coordinate finite and within
    /// ±[`MAX_COORD_M`], no two closer than 1 µm.
    pub fn validate(&self, what: &Path) -> Result<()> {
        if self.mics.is_empty() {
            return Err(Error::format(what, "no microphones"));
        }
        if self.mics.len() > super::MAX_MICS {
            return Err(Error::format(
                what,
                format!(
                    "{} microphones: at most {} are supported",
                    self.mics.len(),
                    super::MAX_MICS
                ),
            ));
        }
        for (i, p) in self.mics.iter().enumerate() {
            if p.iter().any(|v| !v.is_finite()) {
                return Err(Error::format(
                    what,
                    format!("mic {i}: position {p:?} is not finite"),
                ));
            }
            if p.iter().any(|v| v.abs() > MAX_COORD_M) {
                return Err(Error::format(
                    what,
                    format!("mic {i}: position {p:?} m lies beyond ±{MAX_COORD_M:e} m (metres expected)"),
                ));
            }
        }
        for i in 0..self.mics.len() {
            for j in 0..i {
                if dist(self.mics[i], self.mics[j]) < DUPLICATE_TOLERANCE_M {
                    return Err(Error::format(
                        what,
                        format!("mic {i}: same position as mic {j} ({:?})", self.mics[i]),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Parse the TOML text of a geometry file (see the module docs). Errors name
    /// `path_for_errors` and the microphone, e.g.
    /// `ring8.toml: mic 3: expected 3 coordinates, found 2`.
    pub fn from_toml_str(text: &str, path_for_errors: &Path) -> Result<Self> {
        let fail = |m: String| Error::format(path_for_errors, m);
        let value: toml::Table = text.parse().map_err(|e: toml::de::Error| {
            // Where: line and column of the span's start (1-based).
            let at = e.span().map_or(String::new(), |sp| {
                let before = &text[..sp.start.min(text.len())];
                let line = before.matches('\n').count() + 1;
                let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
                format!(" at line {line}, column {col}")
            });
            let hint = if text.contains("np.float") || text.contains("array(") {
                " (numpy's repr is not TOML: write plain numbers, e.g. from positions.tolist())"
            } else {
                ""
            };
            fail(format!("invalid TOML{at}: {}{hint}", e.message().trim_end()))
        })?;
        if let Some(k) = value.keys().find(|k| !matches!(k.as_str(), "mics" | "mic")) {
            return Err(fail(format!(
                "unknown key `{k}` (a geometry file holds `mics = [[x, y, z], ...]` or `[[mic]]` tables)"
            )));
        }
        let mut mics = Vec::new();
        match (value.get("mics"), value.get("mic")) {
            (Some(_), Some(_)) => {
                return Err(fail(
                    "give either `mics = [[x, y, z], ...]` or `[[mic]]` tables, not both".into(),
                ))
            }
            (Some(list), None) => {
                let list = list
                    .as_array()
                    .ok_or_else(|| fail("`mics` must be a list of [x, y, z] lists (metres)".into()))?;
                for (i, m) in list.iter().enumerate() {
                    let coords = m.as_array().ok_or_else(|| {
                        fail(format!(
                            "mic {i}: expected a list [x, y, z], found {}",
                            m.type_str()
                        ))
                    })?;
                    if coords.len() != 3 {
                        return Err(fail(format!(
                            "mic {i}: expected 3 coordinates, found {}",
                            coords.len()
                        )));
                    }
                    let mut p = [0.0; 3];
                    for (k, c) in coords.iter().enumerate() {
                        p[k] = number(c).ok_or_else(|| {
                            fail(format!(
                                "mic {i}: coordinate {k} must be a number, found {}",
                                c.type_str()
                            ))
                        })?;
                    }
                    mics.push(p);
                }
            }
            (None, Some(tables)) => {
                let tables = tables
                    .as_array()
                    .ok_or_else(|| fail("`mic` must be an array of tables ([[mic]])".into()))?;
                for (i, t) in tables.iter().enumerate() {
                    let t = t.as_table().ok_or_else(|| {
                        fail(format!(
                            "mic {i}: expected a table with x, y, z (`[[mic]]`); for a list of [x, y, z] \
                             lists the key is `mics`"
                        ))
                    })?;
                    if let Some(k) = t.keys().find(|k| !matches!(k.as_str(), "x" | "y" | "z")) {
                        return Err(fail(format!("mic {i}: unknown key `{k}` (expected x, y, z)")));
                    }
                    let mut p = [0.0; 3];
                    for (k, name) in ["x", "y", "z"].iter().enumerate() {
                        match t.get(*name) {
                            Some(v) => {
                                p[k] = number(v).ok_or_else(|| {
                                    fail(format!(
                                        "mic {i}: {name} must be a number, found {}",
                                        v.type_str()
                                    ))
                                })?
                            }
                            None if *name == "z" => {}
                            None => return Err(fail(format!("mic {i}: missing {name}"))),
                        }
                    }
                    mics.push(p);
                }
            }
            (None, None) => {
                return Err(fail(
                    "no microphones: expected `mics = [[x, y, z], ...]` or `[[mic]]` tables (metres)".into(),
                ))
            }
        }
        Geometry::new(mics, path_for_errors)
    }

    /// Read a geometry file: TOML, or an ODAS configuration ([`Self::load_with_mapping`]).
    pub fn load(path: &Path) -> Result<Self> {
        Ok(Self::load_with_mapping(path)?.0)
    }

    /// Read a geometry file with the capture device's channel map it may carry: an ODAS
    /// configuration (libconfig with `general.mics`, whatever the file's name;
    /// [`super::odas_cfg`]) gives its positions and its `mapping`; a TOML file its
    /// positions and no map. When neither fits, a `*.cfg`/`*.conf` file gets ODAS's error,
    /// any other TOML's.
    pub fn load_with_mapping(path: &Path) -> Result<(Self, Option<RawMapping>)> {
        let text =
            crate::formats::read_text_bounded(path, crate::formats::MAX_GEOMETRY_BYTES, "geometry file")?;
        let odas = |t: &str| OdasArray::from_str(t, path).map(|a| (a.geometry, a.mapping));
        let cfg_name = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("cfg") || e.eq_ignore_ascii_case("conf"));
        let libconfig = crate::formats::libconfig::parse(&text, path);
        let has_mics = |root: &crate::formats::libconfig::Value| {
            root.get("general").and_then(|g| g.get("mics")).is_some()
        };
        match (libconfig, Self::from_toml_str(&text, path)) {
            // ODAS's layout (whatever the name): its positions and map.
            (Ok(ref root), _) if has_mics(root) => odas(&text),
            (_, Ok(g)) => Ok((g, None)),
            // Neither: a *.cfg file's error is ODAS's (the line of a syntax error, or the
            // missing general.mics), any other file's is TOML's.
            (Err(e), Err(_)) if cfg_name => Err(e),
            (Ok(_), Err(_)) if cfg_name => odas(&text),
            (_, Err(e)) => Err(e),
        }
    }

    /// The geometry as TOML (`mics = [[x, y, z], ...]`, metres), readable by
    /// [`Geometry::from_toml_str`] to the same numbers.
    pub fn to_toml_string(&self) -> String {
        let mut s = String::from("# microphone positions in metres, channel order\nmics = [\n");
        for p in &self.mics {
            s.push_str(&format!("    [{:?}, {:?}, {:?}],\n", p[0], p[1], p[2]));
        }
        s.push_str("]\n");
        s
    }

    /// `n` microphones on a circle of radius `radius_m` in the plane z = `z_m`; mic i at
    /// azimuth 2πi/n from +x toward +y.
    pub fn circle(n: usize, radius_m: f64, z_m: f64) -> Self {
        let mics = (0..n)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                [radius_m * a.cos(), radius_m * a.sin(), z_m]
            })
            .collect();
        Geometry { mics }
    }

    /// `n` microphones spread near-uniformly over a sphere of radius `radius_m` centred on
    /// the origin (Fibonacci lattice: z_i = 1 − (2i + 1)/n, azimuth i·π(3 − √5)).
    pub fn sphere(n: usize, radius_m: f64) -> Self {
        Geometry {
            mics: fibonacci_sphere(n)
                .into_iter()
                .map(|u| [u[0] * radius_m, u[1] * radius_m, u[2] * radius_m])
                .collect(),
        }
    }

    /// The microphones' centroid (mean position), metres.
    pub fn centroid(&self) -> [f64; 3] {
        let n = self.mics.len().max(1) as f64;
        let mut c = [0.0; 3];
        for p in &self.mics {
            for (c, v) in c.iter_mut().zip(p) {
                *c += v / n;
            }
        }
        c
    }

    /// The geometry in the frame its directions are seen from, for a grid of points
    /// `grid_radius_m` from its origin, and a note when the origin lies outside the array.
    ///
    /// The origin of the positions' frame stays the point directions are seen from unless
    /// it lies both outside the array (farther from the microphones' centroid than the
    /// farthest microphone) and farther from the centroid than half the grid radius. So
    /// HARK's frames keep their origin — a robot's head centre with the array on its front
    /// or a ring above it (a note says the origin lies outside the array) — while a room's
    /// corner, as in pyroomacoustics' `L`, does not: there the positions are moved so that
    /// the centroid is the origin (a note says so), since a grid centred metres away
    /// would not surround the array and a far source's direction would not be the array's.
    pub fn direction_frame(&self, grid_radius_m: f64) -> (Geometry, Option<String>) {
        let c = self.centroid();
        let reach = self.mics.iter().map(|&p| dist(p, c)).fold(0.0, f64::max);
        let off = dist(c, [0.0; 3]);
        if off <= reach * (1.0 + 1e-9) {
            return (self.clone(), None);
        }
        let from = format!(
            "the origin of the microphone positions lies outside the array ({off:.3} m from the microphones' centroid \
             [{:.3}, {:.3}, {:.3}] m, the farthest microphone {reach:.3} m)",
            c[0], c[1], c[2]
        );
        if off <= 0.5 * grid_radius_m {
            let note = format!(
                "{from}: directions are seen from the origin, as in HARK's robot frames (positions centred on the \
                 array give directions seen from it)"
            );
            return (self.clone(), Some(note));
        }
        let moved = Geometry {
            mics: self.mics.iter().map(|&p| sub(p, c)).collect(),
        };
        let note = format!(
            "{from}, farther than half the grid radius ({grid_radius_m} m): directions are seen from the centroid"
        );
        (moved, Some(note))
    }

    /// Largest distance between two microphones (the aperture), metres.
    pub fn aperture_m(&self) -> f64 {
        aperture_m(&self.mics)
    }

    /// A note when the positions look like millimetres or centimetres: an aperture over
    /// [`UNITS_NOTE_APERTURE_M`] (positions are metres; the arrays of robots, drones and
    /// rooms span centimetres to a few metres).
    pub fn units_note(&self) -> Option<String> {
        let a = self.aperture_m();
        (a > UNITS_NOTE_APERTURE_M).then(|| {
            format!(
                "warning: the microphones span {a:.1} m: positions are in metres (in millimetres or centimetres? divide them by 1000 or 100)"
            )
        })
    }
}

/// Largest distance between two of `positions` (an array's aperture), metres.
pub fn aperture_m(positions: &[[f64; 3]]) -> f64 {
    let mut d: f64 = 0.0;
    for (i, &a) in positions.iter().enumerate() {
        for &b in &positions[..i] {
            d = d.max(dist(a, b));
        }
    }
    d
}

fn number(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

pub(crate) fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// a − b.
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// a · b.
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// a × b.
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The first of `positions`, the one farthest from it and their distance (None: fewer
/// than two).
fn farthest_from_first(positions: &[[f64; 3]]) -> Option<([f64; 3], [f64; 3], f64)> {
    let (&p0, rest) = positions.split_first()?;
    let far = rest
        .iter()
        .copied()
        .max_by(|a, b| dist(*a, p0).total_cmp(&dist(*b, p0)))?;
    Some((p0, far, dist(far, p0)))
}

/// The unit normal of the plane all `positions` lie in (within 10⁻⁴ of the largest
/// distance from the first position), or None: fewer than three, on one line, or not in
/// one plane.
pub fn plane_normal(positions: &[[f64; 3]]) -> Option<[f64; 3]> {
    let (p0, far, span) = farthest_from_first(positions)?;
    let rest = &positions[1..];
    let e = sub(far, p0);
    let n = rest
        .iter()
        .map(|&p| cross(e, sub(p, p0)))
        .max_by(|a, b| dot(*a, *a).total_cmp(&dot(*b, *b)))?;
    let len = dot(n, n).sqrt();
    // Not on one line: some microphone lies off it by more than 10⁻³ of the span.
    if !(span > 0.0 && len > 1e-3 * span * span) {
        return None;
    }
    let n = n.map(|v| v / len);
    positions
        .iter()
        .all(|&p| dot(sub(p, p0), n).abs() <= 1e-4 * span)
        .then_some(n)
}

/// The unit direction of the line all `positions` lie on (within 10⁻⁴ of the largest
/// distance from the first position), or None: fewer than two distinct positions, or not
/// on one line.
pub fn line_direction(positions: &[[f64; 3]]) -> Option<[f64; 3]> {
    let (p0, far, span) = farthest_from_first(positions)?;
    if !(span > 0.0 && span.is_finite()) {
        return None;
    }
    let e = sub(far, p0).map(|v| v / span);
    positions
        .iter()
        .all(|&p| {
            let c = cross(e, sub(p, p0));
            dot(c, c).sqrt() <= 1e-4 * span
        })
        .then_some(e)
}

/// A note when free-field transfer functions cannot tell some of `grid`'s directions
/// apart because of where the microphones at `positions` lie:
/// - on one line: a direction's spectrum depends only on its angle to the line, so every
///   direction of a cone around it gives the same spectrum (on a ring in a plane through
///   the line, a direction and its mirror image across it); noted when the grid holds two
///   directions more than 5° apart whose angles to the line differ by less than 0.5°;
/// - in one plane, with directions on both sides of it: a point and its mirror image
///   through that plane are the same distance from every microphone, so a source may be
///   reported at its mirror image.
///
/// `points` are the directions that can be reported (the grid's within the azimuth range).
pub fn mirror_note(positions: &[[f64; 3]], points: &[[f64; 3]]) -> Option<String> {
    let c = Geometry {
        mics: positions.to_vec(),
    }
    .centroid();
    let unit = |p: [f64; 3]| {
        let v = sub(p, c);
        let l = dot(v, v).sqrt();
        (l > 0.0).then(|| v.map(|x| x / l))
    };
    if let Some(axis) = line_direction(positions) {
        // Directions sorted by their angle to the line; a run of angles within 0.5° of
        // its first whose directions are not all within 5° of its first one lies on one
        // cone (a ring through the line holds exact mirror images, a sphere grid a point
        // every fraction of a degree of angle).
        let mut by_angle: Vec<([f64; 3], f64)> = points
            .iter()
            .filter_map(|&p| unit(p))
            .map(|u| (u, dot(u, axis).clamp(-1.0, 1.0).acos().to_degrees()))
            .collect();
        by_angle.sort_by(|a, b| a.1.total_cmp(&b.1));
        let apart = 5f64.to_radians().cos();
        let mut first = 0;
        let mut cone = false;
        for i in 1..by_angle.len() {
            if by_angle[i].1 - by_angle[first].1 > 0.5 {
                first = i;
            } else if dot(by_angle[i].0, by_angle[first].0) < apart {
                cone = true;
                break;
            }
        }
        return cone.then(|| {
            format!(
                "the microphones lie on one line: in free field only a direction's angle to that line \
                 can be told apart (every direction on a cone around the line gives the same spectrum; \
                 on a ring through the line, a direction and its mirror image across it), so a source \
                 may be reported anywhere on its cone; use a grid of one half-plane through the line \
                 ({}), or an array that is not linear",
                half_plane_range(axis)
            )
        });
    }
    let n = plane_normal(positions)?;
    let side = |p: [f64; 3]| {
        let v = sub(p, c);
        let h = dot(v, n);
        (h.abs() > 0.05 * dot(v, v).sqrt()).then_some(h > 0.0)
    };
    let sides: Vec<bool> = points.iter().filter_map(|&p| side(p)).collect();
    (sides.contains(&true) && sides.contains(&false)).then(|| {
        "the microphones lie in one plane and the grid has directions on both sides of it: in free \
         field a direction and its mirror image through the plane give the same spectrum, so a source \
         may be reported on the wrong side (e.g. below a horizontal array instead of above); use a grid \
         on one side of the plane (for an array lying horizontally: hemisphere:N, e.g. hemisphere:1261, \
         the directions above it), or a non-planar array"
            .to_string()
    })
}

/// The azimuth range of one half-plane through a line along `axis`, as the user would
/// give it. HARK's range is MIN_DEG < azimuth ≤ MAX_DEG, so MIN_DEG sits half a degree
/// below the line's direction: both ends of the line (its endfire directions, which have
/// no mirror image) stay in.
fn half_plane_range(axis: [f64; 3]) -> String {
    let horizontal = (axis[0] * axis[0] + axis[1] * axis[1]).sqrt();
    if horizontal < 0.9 {
        return "on a ring: --min-deg/--max-deg spanning 180° from the line's direction".into();
    }
    // The line's azimuth, taken in (−90°, 90°] (either end of the line would do).
    let mut phi = axis[1].atan2(axis[0]).to_degrees();
    if phi <= -90.0 {
        phi += 180.0;
    } else if phi > 90.0 {
        phi -= 180.0;
    }
    let phi = (phi * 10.0).round() / 10.0;
    format!(
        "on a ring: --min-deg {} --max-deg {}; the range leaves MIN_DEG itself out",
        phi - 0.5,
        phi + 180.0
    )
}

/// Unit vectors of an `n`-point Fibonacci lattice on the sphere:
/// z_i = 1 − (2i + 1)/n, azimuth_i = i·π(3 − √5).
pub(crate) fn fibonacci_sphere(n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f64 + 1.0) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let a = golden * i as f64;
            [r * a.cos(), r * a.sin(), z]
        })
        .collect()
}

#[cfg(test)]
mod tests;
