//! Candidate directions (the search grid) and their neighbour relation.

/// How the grid points are arranged; decides the peak search's neighbour relation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GridKind {
    /// One ring at a fixed elevation, sorted by azimuth; neighbours are left/right (wrapping).
    Ring,
    /// Points over the (half- or full) sphere with an explicit neighbour table.
    Sphere,
    /// Any other set of points with an explicit neighbour table (e.g. from a TF zip).
    Irregular,
}

/// Candidate source directions.
///
/// `points[i]` is the position of direction i as stored in the TF (not necessarily a unit
/// vector: HARK stores the measurement position, e.g. 1 m away). `neighbors[i]` lists the
/// neighbours of i (never i itself) used by the peak search.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Grid {
    /// Positions in metres (or unit vectors), one per direction.
    pub points: Vec<[f64; 3]>,
    /// The arrangement.
    pub kind: GridKind,
    /// Neighbour indices per direction, without the point itself.
    pub neighbors: Vec<Vec<usize>>,
}

impl Grid {
    /// Number of directions.
    pub fn len(&self) -> usize {
        self.points.len()
    }
    /// True when there are no directions.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
    /// Azimuth of direction `i` in degrees, atan2(y, x), in (-180, 180].
    pub fn azimuth_deg(&self, i: usize) -> f64 {
        let [x, y, _] = self.points[i];
        y.atan2(x).to_degrees()
    }
    /// Elevation of direction `i` in degrees from the x-y plane.
    pub fn elevation_deg(&self, i: usize) -> f64 {
        let [x, y, z] = self.points[i];
        z.atan2((x * x + y * y).sqrt()).to_degrees()
    }
    /// Unit vector of direction `i`.
    pub fn unit(&self, i: usize) -> [f64; 3] {
        let [x, y, z] = self.points[i];
        let r = (x * x + y * y + z * z).sqrt();
        if r > 0.0 {
            [x / r, y / r, z / r]
        } else {
            [1.0, 0.0, 0.0]
        }
    }
}
