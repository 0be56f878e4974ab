//! Portable core of the Z-slide controller.
//!
//! `no_std`, no allocation, no chips and no simulator: boards (`src/main.rs`,
//! `boards/qemu`) and `host-sim` implement its traits. The data path reads in
//! the module order: X position and spindle angle arrive by interrupt, the
//! coefficient table is interpolated at X, the command is formed at φ, the
//! loop closes on the gauge, and the result goes to the DAC. See
//! `docs/ARCHITECTURE.md`.
#![no_std]
#![forbid(unsafe_code)]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

pub mod hw;
pub mod safety;
pub mod table;
pub mod units;
pub mod trig;
pub mod interp;
pub mod command;
pub mod xpos;
pub mod spindle;
pub mod drivers;
