//! The spec the scene tests localize the 8-mic ring's demo scenes with (accuracy.rs,
//! coherence.rs): free field, a 5° ring grid, PERIOD 25, on the CPU. A module of its own,
//! not `common`: every suite that includes it uses all of it.

use soundloc::array::grid::GridSpec;
use soundloc::backend::DeviceChoice;
use soundloc::demo::DemoScene;
use soundloc::localizer::LocalizerSpec;

/// The free-field spec for `sc`'s array: 5° ring grid at elevation 0, PERIOD 25, CPU.
pub fn ring_spec(sc: &DemoScene) -> LocalizerSpec {
    let mut spec = LocalizerSpec::free_field(
        sc.geometry.mics.clone(),
        GridSpec::Ring {
            step_deg: 5.0,
            elevation_deg: 0.0,
        },
    );
    spec.analysis.period = 25;
    spec.device = DeviceChoice::Cpu;
    spec
}

/// A two-talker drone scene of the accuracy study on the ring (four rotors 25 cm away,
/// talkers at 0 dB SNR) in a room of `rt60_s` (0: anechoic), seed `seed`.
pub fn two_talker_drone(rt60_s: f64, seed: u64) -> DemoScene {
    use soundloc::bench::accuracy::{scene, Condition, StudyArray};
    let c = Condition {
        rt60_s,
        talkers: 2,
        snr_db: 0.0,
    };
    scene(StudyArray::Ring8, c, seed).unwrap()
}

/// [`ring_spec`] with K from the scene's noise-only range: no algorithm named, so the
/// robust default runs unless the caller names one.
pub fn drone_spec(sc: &DemoScene) -> LocalizerSpec {
    let mut spec = ring_spec(sc);
    spec.noise = soundloc::NoiseSource::Range {
        start_s: sc.noise_range_s.0,
        end_s: sc.noise_range_s.1,
    };
    spec
}
