//! The host link: status, fault log, arm/disarm/clear, servo parameters
//! and a triggered capture (a servo drive's built-in oscilloscope), over
//! any byte transport (RTT on the NUCLEO, the CMSDK UART in QEMU).
//!
//! * `proto`: the wire format (postcard + COBS + CRC-32, versioned), shared
//!   with the host tool (`zslide`, `zslide-host/`);
//! * `tap`: the loop tick's part (a few stores per tick, lock-free);
//! * `station`: the background's part (frames, replies, the fault log).
//!
//! The protocol and the walkthrough: `docs/BOARD.md`.

pub mod proto;
pub mod station;
pub mod tap;

/// Capture ring of every board and of the simulated machine, loop ticks
/// (1024: 51 ms at 20 kHz, 24 KiB of the NUCLEO's DTCM).
pub const CAPTURE: usize = 1024;
