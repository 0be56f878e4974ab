//! Bit-exact replay of the firmware's handlers: a run recorded in
//! host-sim (every handler call with the inputs it saw, every frame and
//! pin level it produced, what it changed) is played through the same
//! entry points and the same converter drivers on another machine (the
//! emulated Cortex-M4F: `boards/qemu`, binary `zslide-qemu-replay`), and
//! every output is compared; the first difference names the tick, the
//! output, the expected and the got value.
//!
//! * [`wire`]: what a run holds and how it is coded (postcard varints of
//!   differences: about 15 bytes a loop tick);
//! * [`container`]: the runs behind a magic, a version and a CRC, as the
//!   recording sits in the target's flash;
//! * [`setup`]: the firmware configuration of a run;
//! * [`player`]: the replay (`no_std`, no allocation);
//! * `record` (feature `record`, host): the taps, the recorder, and
//!   `alter` for the self-check that a changed code is caught.
#![cfg_attr(not(feature = "std"), no_std)]

pub mod container;
pub mod frames;
pub mod player;
#[cfg(feature = "record")]
pub mod record;
pub mod setup;
pub mod wire;

pub use player::{play_run, Call, Mismatch, Outcome, Output, Played, RunError};
pub use wire::{Dev, Event, Setup, XResult};
