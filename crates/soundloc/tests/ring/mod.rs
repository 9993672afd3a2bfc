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
