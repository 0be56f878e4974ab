//! Automatic part centring (Y-1594, Feezell 1967): the second
//! system on the same core.
//!
//! A rotary table (1-25 rpm) carries two cross slides and the part; a
//! transducer (±0.5 in) touches the part. Each cycle samples one revolution,
//! estimates the off-centre ([`estimate`]), and, unless the level detector
//! finds both axes below the bias, moves both slides by `K` times it with a
//! tachometer-feedback servo per slide ([`servo`]); the sequence and its
//! refusals are in [`cycle`]. Lengths are [`crate::units::TableInches`]
//! (I2F30) in the table frame; the table angle is a
//! [`crate::units::SpindleAngle`] from [`crate::spindle::EncoderAngle`].
//! See `docs/CENTRING.md`.

pub mod cycle;
pub mod estimate;
pub mod servo;

pub use cycle::{Centring, Config, Event, Inputs, Method, State};
pub use estimate::OffCentre;
pub use servo::LoopDesign;
