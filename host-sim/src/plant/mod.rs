//! The Z-slide plant: slide + voice-coil motor + structural mode
//! ([`zslide`]), power amplifier ([`amplifier`]), capacitance gauge
//! ([`gauge`]), cutting force ([`cutting`]), their exact linear stepping
//! ([`linear`]) and the [`Rig`] that wires them to the simulated converter
//! chips. Units: inch, lbf, s, A, V (see `docs/PLANT.md`).

pub mod amplifier;
pub mod cutting;
pub mod gauge;
pub mod linear;
pub mod rig;
pub mod zslide;

pub use amplifier::{AmpRegime, Amplifier, AmplifierParams};
pub use cutting::{BoltHoles, CuttingParams};
pub use gauge::{Gauge, GaugeParams};
pub use linear::{Discrete, LinearSystem, ZohCache};
pub use rig::{Rig, RigConfig};
pub use zslide::{ModeParams, ZSlide, ZSlideParams};
