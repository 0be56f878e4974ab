//! What the QEMU `mps2-an386` images share: the board (vector table, CMSDK
//! timers). The images: `zslide-qemu` (`src/main.rs`, the firmware closing
//! its loop on the plant model) and `zslide-qemu-replay`
//! (`src/bin/replay.rs`, host-sim's recordings played through the same
//! handlers).
#![no_std]

pub mod board;
