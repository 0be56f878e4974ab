//! The Z-slide plant, written once: the slide with its voice-coil motor and
//! the 3150 Hz coil-frame mode ([`slide`]), the linear power amplifier with
//! its current limit and trip ([`amplifier`]), the capacitance gauge with
//! its seeded noise and the gauge ADC's quantisation ([`gauge`]). Units:
//! inch, lbf, s, A, V (`docs/PLANT.md`).
//!
//! `host-sim` uses it (behind its simulated converter chips and scheduler)
//! and so does the QEMU image (`boards/qemu`, stepped in its loop-timer
//! interrupt). `no_std`: without the `std` feature the f64 functions come
//! from `libm` and the slide steps with discretisations generated at build
//! time ([`slide::ZSlide::preload`]); with it they are computed on demand
//! by [`zoh`] (nalgebra's matrix exponential).
#![cfg_attr(not(any(feature = "std", test)), no_std)]

pub mod amplifier;
pub mod fastmath;
pub mod gauge;
pub mod slide;
pub mod statespace;
#[cfg(feature = "std")]
pub mod zoh;

pub use amplifier::{AmpRegime, Amplifier, AmplifierParams};
pub use gauge::{Gauge, GaugeParams};
pub use slide::{ModeParams, ZSlide, ZSlideParams};
