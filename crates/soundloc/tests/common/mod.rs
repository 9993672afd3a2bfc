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
    }
    loc.flush(&mut out).unwrap();
    out
}
