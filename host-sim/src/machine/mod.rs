//! Machine models the firmware's position inputs come from: the X slide with
//! its interferometer counter chain, and the spindle with its index,
//! tachometer and encoder. Clean, seeded, reusable by every scenario.
pub mod config;
pub mod hw;
pub mod spindle;
pub mod xslide;

pub use config::{MachineConfig, SpindleSensor, XInterface};
