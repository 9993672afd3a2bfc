use super::*;

#[test]
fn segments_cover_complete_frames_only() {
    // N = 512, hop 160, 16 kHz: frame f is samples 160f .. 160f + 511.
    assert_eq!(segment_frames(0, 0.0, 1.0, 512, 160, 16000.0).unwrap(), 0..97);
    assert_eq!(segment_frames(1, 2.0, 2.5, 512, 160, 16000.0).unwrap(), 200..247);
    let e = segment_frames(1, 1.0, 1.02, 512, 160, 16000.0).unwrap_err();
    assert!(e.to_string().contains("noise segment 1 (1–1.02 s)"), "{e}");
    assert!(segment_frames(0, 2.0, 1.0, 512, 160, 16000.0).is_err());
    assert!(segment_frames(0, f64::NAN, 1.0, 512, 160, 16000.0).is_err());
}

#[test]
fn sources_are_causal() {
    let config = LocalizeConfig {
        algorithm: crate::Algorithm::Gsvd,
        ..LocalizeConfig::default()
    };
    let w = |start: usize| WindowSpec {
        frame: start,
        start,
        len: 50,
    };
    // Segments at frames 0..90 and 120..180 (hop 160, N 512, fs 16 kHz).
    let to_s = |f: usize| f as f64 * 160.0 / 16000.0;
    let segs = vec![
        (0.0, to_s(89) + 512.0 / 16000.0),
        (to_s(120), to_s(179) + 512.0 / 16000.0),
    ];
    let mut p = NoisePolicy::new(&config, 2, InitialNoise::Given(None), NoiseUpdate::Segments(segs)).unwrap();
    assert_eq!(p.segments[0].frames, 0..90);
    assert_eq!(p.segments[1].frames, 120..180);
    let mut ring = FrameRing::<f64>::new(config.bin_range().len(), 2);
    // Feed frames with a recognisable value so the segment K are not zero.
    let mut s = crate::backend::Spectra::<f64>::zeros(300, config.bin_range().len(), 2);
    for (i, v) in s.data.iter_mut().enumerate() {
        *v = crate::real::C::new(1.0 + (i % 7) as f64, (i % 3) as f64);
    }
    let mut src = Vec::new();
    for (n, start) in [
        (100usize, 0usize),
        (100, 50),
        (200, 100),
        (200, 150),
        (300, 200),
        (300, 250),
    ] {
        while ring.end() < n {
            let f = ring.end();
            let dst = ring.grow(1);
            dst.copy_from_slice(&s.data[f * dst.len()..(f + 1) * dst.len()]);
            p.observe_frames(&ring, f..f + 1).unwrap();
        }
        src.push(p.choose(&w(start)).unwrap());
    }
    // Window [0, 49]: nothing complete; [50, 99]: segment 0 (ends at 89); [150, 199]:
    // segment 1 (ends at 179).
    assert_eq!(
        src,
        vec![
            KSource::Initial,
            KSource::Segment(0),
            KSource::Segment(0),
            KSource::Segment(1),
            KSource::Segment(1),
            KSource::Segment(1)
        ]
    );
    let mut p = NoisePolicy::new(
        &config,
        2,
        InitialNoise::Given(None),
        NoiseUpdate::Preceding { frames: 40, gap: 20 },
    )
    .unwrap();
    let got: Vec<KSource> = (0..6).map(|i| p.choose(&w(i * 50)).unwrap()).collect();
    assert_eq!(got[0], KSource::Initial);
    assert_eq!(got[1], KSource::Initial); // 50 < 60: keeps the previous K
    assert_eq!(got[2], KSource::Frames(40..80));
    assert_eq!(got[5], KSource::Frames(190..230));
    // A range estimate holds every window until it is complete.
    let mut p = NoisePolicy::new(&config, 2, InitialNoise::Range(0.0, 1.0), NoiseUpdate::Fixed).unwrap();
    assert!(p.choose(&w(0)).is_none());
}
