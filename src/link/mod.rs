//! The host link: status, fault log, arm/disarm/clear, servo parameters
//! and a triggered capture (a servo drive's built-in oscilloscope), over
//! any byte transport (RTT on the NUCLEO, the CMSDK UART in QEMU).
//!
//! * `proto`: the wire format (postcard + COBS + CRC-32, versioned), shared
//!   with the host CLI (`cargo xtask link`);
//! * `tap`: the loop tick's part (a few stores per tick, lock-free);
//! * `station`: the background's part (frames, replies, the fault log).
//!
//! The protocol and the walkthrough: `docs/BOARD.md`.

pub mod proto;
pub mod station;
pub mod tap;
