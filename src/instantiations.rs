//! The solver compiled once, here, for D = 2 and D = 3.
//!
//! `Simulation<D>` is generic, so every crate that calls it (each integration test, example
//! and the binary) would compile the whole solver again for its own D. With shared generics,
//! rustc's default at opt-level 0 and 1 (the dev profile), a downstream crate links the copies
//! an upstream crate already holds; taking the entry points' addresses in a non-generic function
//! makes this crate hold them. Release builds (opt-level 3) do not share generics and are not
//! affected.

use crate::simulation::{Simulation, SimulationBuilder};

/// The addresses of the solver's entry points for D = 2 and 3 (never called for its value).
#[doc(hidden)]
pub fn entry_points() -> Vec<usize> {
    #[allow(unused_mut)]
    let mut points = vec![
        SimulationBuilder::<2>::build as *const () as usize,
        SimulationBuilder::<3>::build as *const () as usize,
        Simulation::<2>::from_model as *const () as usize,
        Simulation::<3>::from_model as *const () as usize,
        Simulation::<2>::step as *const () as usize,
        Simulation::<3>::step as *const () as usize,
        Simulation::<2>::step_with as *const () as usize,
        Simulation::<3>::step_with as *const () as usize,
        Simulation::<2>::advance as *const () as usize,
        Simulation::<3>::advance as *const () as usize,
        Simulation::<2>::energies as *const () as usize,
        Simulation::<3>::energies as *const () as usize,
        Simulation::<2>::try_clone as *const () as usize,
        Simulation::<3>::try_clone as *const () as usize,
        Simulation::<2>::set_state as *const () as usize,
        Simulation::<3>::set_state as *const () as usize,
        Simulation::<2>::internal_forces as *const () as usize,
        Simulation::<3>::internal_forces as *const () as usize,
    ];
    #[cfg(feature = "formats")]
    points.extend([
        crate::io::scene::LoadedScene::build::<2> as *const () as usize,
        crate::io::scene::LoadedScene::build::<3> as *const () as usize,
        crate::io::scene::Scene::<2>::simulation as *const () as usize,
        crate::io::scene::Scene::<3>::simulation as *const () as usize,
        crate::io::output::run::<2> as *const () as usize,
        crate::io::output::run::<3> as *const () as usize,
        crate::io::output::run_with::<2> as *const () as usize,
        crate::io::output::run_with::<3> as *const () as usize,
        crate::io::output::resume::<2> as *const () as usize,
        crate::io::output::resume::<3> as *const () as usize,
        crate::io::checkpoint::Checkpoint::<2>::write as *const () as usize,
        crate::io::checkpoint::Checkpoint::<3>::write as *const () as usize,
        crate::io::checkpoint::Checkpoint::<2>::scene as *const () as usize,
        crate::io::checkpoint::Checkpoint::<3>::scene as *const () as usize,
    ]);
    #[cfg(feature = "rerun")]
    {
        use crate::recording::RerunRecorder;
        use crate::simulation::observe::Recorder;
        points.extend([
            <RerunRecorder<2> as Recorder<2>>::step_start as *const () as usize,
            <RerunRecorder<3> as Recorder<3>>::step_start as *const () as usize,
            <RerunRecorder<2> as Recorder<2>>::iteration as *const () as usize,
            <RerunRecorder<3> as Recorder<3>>::iteration as *const () as usize,
            <RerunRecorder<2> as Recorder<2>>::step_end as *const () as usize,
            <RerunRecorder<3> as Recorder<3>>::step_end as *const () as usize,
            <RerunRecorder<2> as Recorder<2>>::log as *const () as usize,
            <RerunRecorder<3> as Recorder<3>>::log as *const () as usize,
            RerunRecorder::<2>::finish as *const () as usize,
            RerunRecorder::<3>::finish as *const () as usize,
        ]);
    }
    points
}
