use super::*;

fn p() -> &'static Path {
    Path::new("ring8.toml")
}

#[test]
fn a_planar_array_with_a_grid_on_both_sides_gets_a_note() {
    use crate::array::Grid;
    let ring = Geometry::circle(8, 0.0365, 0.0);
    let n = plane_normal(&ring.mics).unwrap();
    assert!((n[2].abs() - 1.0).abs() < 1e-12, "{n:?}");
    // Both hemispheres: the note; the ring's own plane or one side only: none.
    assert!(mirror_note(&ring.mics, &Grid::sphere(200, 1.0).points)
        .unwrap()
        .contains("mirror image"));
    assert_eq!(mirror_note(&ring.mics, &Grid::ring(5.0, 0.0, 1.0).points), None);
    assert_eq!(mirror_note(&ring.mics, &Grid::ring(5.0, 30.0, 1.0).points), None);
    // A tilted plane, a 3-D array, a line.
    let tilted: Vec<[f64; 3]> = ring.mics.iter().map(|p| [p[0], p[1], 0.5 * p[0] + 1.0]).collect();
    assert!(plane_normal(&tilted).is_some());
    assert_eq!(plane_normal(&Geometry::sphere(60, 0.1).mics), None);
    assert_eq!(
        mirror_note(&Geometry::sphere(60, 0.1).mics, &Grid::sphere(200, 1.0).points),
        None
    );
    let line: Vec<[f64; 3]> = (0..4).map(|i| [0.05 * i as f64, 0.0, 0.0]).collect();
    assert_eq!(plane_normal(&line), None);
    assert_eq!(plane_normal(&line[..2]), None);
}

/// A linear array: every grid that holds two directions on one cone around the line
/// gets the cone note (a full ring through the line, a ring across it, a sphere); a
/// half ring from the line's direction does not; the ring array keeps its own rule.
#[test]
fn a_linear_array_with_directions_on_one_cone_gets_a_note() {
    use crate::array::Grid;
    // Kinect-like: 4 microphones along x, unevenly spaced.
    let line = vec![
        [-0.113, 0.0, 0.0],
        [0.036, 0.0, 0.0],
        [0.076, 0.0, 0.0],
        [0.113, 0.0, 0.0],
    ];
    let axis = line_direction(&line).unwrap();
    assert!((axis[0].abs() - 1.0).abs() < 1e-12, "{axis:?}");
    for grid in [Grid::ring(5.0, 0.0, 1.0), Grid::sphere(500, 1.0)] {
        assert!(mirror_note(&line, &grid.points).unwrap().contains("cone"));
    }
    // Along z, a ring in the x-y plane is one cone (every direction at 90°).
    let vertical: Vec<[f64; 3]> = line.iter().map(|p| [0.0, 0.0, p[0]]).collect();
    assert!(mirror_note(&vertical, &Grid::ring(5.0, 0.0, 1.0).points).is_some());
    // Azimuth 0…180° (one half-plane through the x axis): each angle once.
    let ring = Grid::ring(5.0, 0.0, 1.0);
    let half: Vec<[f64; 3]> = (0..ring.len())
        .filter(|&i| crate::peaks::azimuth_in_range(ring.azimuth_deg(i), 0.0, 180.0))
        .map(|i| ring.points[i])
        .collect();
    assert_eq!(half.len(), 36); // (0, 180]: HARK's wrap puts 0° at 360°
    assert_eq!(mirror_note(&line, &half), None);
    assert_eq!(line_direction(&Geometry::circle(8, 0.0365, 0.0).mics), None);
    assert_eq!(line_direction(&[[0.0; 3], [0.0; 3]]), None);
    assert_eq!(
        mirror_note(&Geometry::circle(8, 0.0365, 0.0).mics, &ring.points),
        None
    );
}

#[test]
fn directions_are_seen_from_the_origin_within_the_array_else_from_the_centroid() {
    // TAMAGO-like: a ring above the origin (within the array): kept as it is.
    let raised = Geometry::circle(8, 0.0365, 0.011);
    assert_eq!(raised.direction_frame(1.0), (raised.clone(), None));
    // A room's coordinates: moved to the centroid, with a note.
    let room = Geometry {
        mics: raised
            .mics
            .iter()
            .map(|p| [p[0] + 3.0, p[1] + 2.5, p[2] + 1.2])
            .collect(),
    };
    let (moved, note) = room.direction_frame(1.0);
    assert!(note.unwrap().contains("[3.000, 2.500, 1.211] m"));
    let c = moved.centroid();
    assert!(c.iter().all(|v| v.abs() < 1e-12), "{c:?}");
    for (a, b) in moved.mics.iter().zip(&room.mics) {
        assert!((0..3).all(|k| (a[k] - (b[k] - room.centroid()[k])).abs() < 1e-12));
    }
    // One microphone away from the origin: moved onto it.
    let one = Geometry {
        mics: vec![[0.0, 0.0, 0.1]],
    };
    assert_eq!(one.direction_frame(0.1).0.mics, vec![[0.0, 0.0, 0.0]]);
    // A robot's frame: an arc on the front of a head 0.1 m in radius, the origin at the
    // head's centre, outside the arc but within half the 1 m grid: kept, with a note.
    let arc = Geometry {
        mics: (0..4)
            .map(|i| {
                let a = (-45.0 + 30.0 * i as f64).to_radians();
                [0.1 * a.cos(), 0.1 * a.sin(), 0.0]
            })
            .collect(),
    };
    let (kept, note) = arc.direction_frame(1.0);
    assert_eq!(kept, arc);
    assert!(note.unwrap().contains("directions are seen from the origin"));
}

#[test]
fn parse_both_forms() {
    let g = Geometry::from_toml_str("mics = [[0.1, 0, 0], [0, 0.1, 0.05]]", p()).unwrap();
    assert_eq!(g.mics, vec![[0.1, 0.0, 0.0], [0.0, 0.1, 0.05]]);
    let g2 = Geometry::from_toml_str(
        "[[mic]]\nx = 0.1\ny = 0\n[[mic]]\nx = 0\ny = 0.1\nz = 0.05\n",
        p(),
    )
    .unwrap();
    assert_eq!(g, g2);
    let c = Geometry::circle(8, 0.0365, 0.0);
    let back = Geometry::from_toml_str(&c.to_toml_string(), p()).unwrap();
    assert_eq!(back, c);
}

#[test]
fn errors_name_file_and_mic() {
    let e = |t: &str| Geometry::from_toml_str(t, p()).unwrap_err().to_string();
    assert_eq!(
        e("mics = [[0,0,0],[1,0,0],[0,1,0],[1,1]]"),
        "ring8.toml: mic 3: expected 3 coordinates, found 2"
    );
    assert_eq!(
        e("mics = [[0,0,0],[0,0,0]]"),
        "ring8.toml: mic 1: same position as mic 0 ([0.0, 0.0, 0.0])"
    );
    assert!(e("mics = [[nan,0,0]]").starts_with("ring8.toml: mic 0: position"));
    assert!(e("mics = [[0,\"a\",0]]").contains("mic 0: coordinate 1 must be a number"));
    assert!(e("[[mic]]\nx=1\n").contains("mic 0: missing y"));
    assert!(e("[[mic]]\nx=1\ny=2\nw=3").contains("unknown key `w`"));
    assert!(e("mics = [[0, 0, 0], [1, 0, 0]]\nextra = 5").contains("unknown key `extra`"));
    assert!(e("mics = [").starts_with("ring8.toml: invalid TOML at line 1, column 9"));
    // numpy 2's repr of its floats, and a list under [[mic]]'s key.
    let np = e("mics = [[np.float64(0.1), 0.0, 0.0],\n [0.0, 0.1, 0.0]]");
    assert!(
        np.contains("at line 1, column 10") && np.contains("positions.tolist()"),
        "{np}"
    );
    let mic = e("mic = [[0, 0, 0], [0.1, 0, 0]]");
    assert!(
        mic.contains("for a list of [x, y, z] lists the key is `mics`"),
        "{mic}"
    );
    assert!(e("").contains("no microphones"));
    let missing = Geometry::load(Path::new("/nonexistent/ring8.toml")).unwrap_err();
    assert!(missing.to_string().starts_with("/nonexistent/ring8.toml: "));
    let missing = Geometry::load(Path::new("/nonexistent/respeaker.cfg")).unwrap_err();
    assert!(missing.to_string().starts_with("/nonexistent/respeaker.cfg: "));
}

/// An ODAS configuration is recognised by its name or, under another name, by its
/// content; a broken TOML file still gets the TOML error.
#[test]
fn odas_configurations_load_by_name_or_content() {
    let dir = std::env::temp_dir().join(format!("soundloc-geom-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = crate::array::odas_cfg::tests::RESPEAKER_USB;
    for name in ["respeaker.cfg", "respeaker.CONF", "respeaker.txt"] {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        let (g, map) = Geometry::load_with_mapping(&p).unwrap();
        assert_eq!(g.num_mics(), 4, "{name}");
        assert_eq!(map.unwrap().map, vec![1, 2, 3, 4], "{name}");
        assert_eq!(Geometry::load(&p).unwrap(), g);
    }
    let p = dir.join("broken.toml");
    std::fs::write(&p, "mics = [[0, 0, 0]").unwrap();
    assert!(Geometry::load(&p)
        .unwrap_err()
        .to_string()
        .contains("invalid TOML"));
    // A TOML geometry named .cfg still loads as TOML.
    let p = dir.join("toml.cfg");
    std::fs::write(&p, "mics = [[0, 0, 0], [0.1, 0, 0]]").unwrap();
    assert_eq!(Geometry::load_with_mapping(&p).unwrap().0.num_mics(), 2);
    // A .cfg that is neither says what ODAS's layout lacks.
    let p = dir.join("other.cfg");
    std::fs::write(&p, "mics = 5;").unwrap();
    assert!(Geometry::load(&p)
        .unwrap_err()
        .to_string()
        .contains("no `general.mics` list: not an ODAS array configuration"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn builtins() {
    let c = Geometry::circle(8, 0.0365, 0.2);
    assert_eq!(c.num_mics(), 8);
    assert!((c.mics[2][0]).abs() < 1e-12 && (c.mics[2][1] - 0.0365).abs() < 1e-12);
    assert!(c.mics.iter().all(|m| m[2] == 0.2));
    assert!((c.aperture_m() - 0.073).abs() < 1e-12);
    let s = Geometry::sphere(60, 0.1);
    assert_eq!(s.num_mics(), 60);
    s.validate(p()).unwrap();
    for m in &s.mics {
        assert!((dist(*m, [0.0; 3]) - 0.1).abs() < 1e-12);
    }
    // Near-uniform: centroid close to the origin.
    let cz: f64 = s.mics.iter().map(|m| m[2]).sum::<f64>() / 60.0;
    assert!(cz.abs() < 1e-12);
}

#[test]
fn positions_in_millimetres_get_a_units_note() {
    let mm = Geometry::circle(8, 36.5, 0.0);
    let n = mm.units_note().expect("a note");
    assert!(
        n.contains("span 73.0 m") && n.contains("divide them by 1000 or 100"),
        "{n}"
    );
    assert!(Geometry::circle(8, 0.0365, 0.0).units_note().is_none());
    // An array across a room (6 m) is an array.
    assert!(Geometry::circle(8, 3.0, 0.0).units_note().is_none());
}
