//! The Z-slide plant: slide + voice-coil motor + structural mode
//! ([`zslide`]), power amplifier ([`amplifier`]), capacitance gauge
//! ([`gauge`]) — the project's one model, `zslide-plant`, which the QEMU
//! image steps too — plus what only the host needs: the cutting force
//! ([`cutting`]), general exact linear stepping and analysis ([`linear`])
//! and the [`Rig`] that wires the model to the simulated converter chips.
//! Units: inch, lbf, s, A, V (see `docs/PLANT.md`).

pub mod cutting;
pub mod linear;
pub mod rig;

/// The slide, motor and mode (`zslide_plant::slide`) and their continuous
/// state space as a [`LinearSystem`] for analysis ([`StateSpace`]).
pub mod zslide {
    pub use super::linear::StateSpace;
    pub use zslide_plant::slide::*;
}
pub use zslide_plant::{amplifier, gauge};

pub use amplifier::{AmpRegime, Amplifier, AmplifierParams};
pub use cutting::{BoltHoles, CuttingParams};
pub use gauge::{Gauge, GaugeParams};
pub use linear::{Discrete, LinearSystem, StateSpace, ZohCache};
pub use rig::{Rig, RigConfig};
pub use zslide::{ModeParams, ZSlide, ZSlideParams};
