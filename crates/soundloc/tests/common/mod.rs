//! Helpers shared by the stream tests: a free-field ring spec for a demo scene, and a push
//! of a whole recording in blocks of random sizes and layouts.

use rand::{Rng, SeedableRng};
use soundloc::backend::DeviceChoice;
use soundloc::demo::DemoScene;
use soundloc::{Block, LocalizeConfig, Localizer, LocalizerSpec, Output};

/// A 5° ring-grid, free-field spec for `scene`'s array with `config`, on the CPU, keeping
/// the spectrum.
pub fn spec_for(scene: &DemoScene, config: &LocalizeConfig) -> LocalizerSpec {
    let mut s = LocalizerSpec::free_field(
        scene.geometry.mics.clone(),
        soundloc::array::grid::GridSpec::Ring {
            step_deg: 5.0,
            elevation_deg: 0.0,
        },
    );
    s.analysis = config.clone();
    s.algorithm = Some(config.algorithm);
    s.device = DeviceChoice::Cpu;
    s.spectrum = true;
    s
}

/// Push `channels` in blocks of random sizes (1 sample … `max_block`), interleaved or
/// planar at random; flush.
pub fn stream(loc: &mut Localizer, channels: &[Vec<f32>], max_block: usize, seed: u64) -> Output {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let len = channels[0].len();
    let mut out = Output::default();
    let mut pos = 0;
    let mut seen = (0, 0);
    while pos < len {
        let n = if rng.gen_bool(0.3) {
            rng.gen_range(1..20)
        } else {
            rng.gen_range(1..=max_block)
        }
        .min(len - pos);
        if rng.gen_bool(0.5) {
            let mut inter = Vec::with_capacity(n * channels.len());
            for i in pos..pos + n {
                inter.extend(channels.iter().map(|c| c[i]));
            }
            loc.push(
                Block::Interleaved {
                    data: &inter,
                    channels: channels.len(),
                },
                &mut out,
            )
            .unwrap();
        } else {
            let part: Vec<Vec<f32>> = channels.iter().map(|c| c[pos..pos + n].to_vec()).collect();
            loc.push(Block::Planar(&part), &mut out).unwrap();
        }
        pos += n;
        seen = rows_follow_results(&out, seen);
    }
    loc.flush(&mut out).unwrap();
    rows_follow_results(&out, seen);
    out
}

/// The spectrum rows a push or flush added are those of the results it added (same
/// frames, in order), also while the interval extender holds results back; returns the
/// new (results, rows) counts.
fn rows_follow_results(out: &Output, (r0, s0): (usize, usize)) -> (usize, usize) {
    // No rows yet: the results so far stay unmatched, and rows that come later must
    // start with theirs (a localizer that wants no spectrum never has rows).
    let Some(t) = &out.spectrum else {
        return (r0, 0);
    };
    let results: Vec<usize> = out.results[r0..].iter().map(|r| r.frame).collect();
    assert_eq!(
        results,
        t.frames[s0..],
        "a push's spectrum rows are not its results'"
    );
    (out.results.len(), t.frames.len())
}
