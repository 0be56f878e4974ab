//! What the QEMU `mps2-an386` images share: the board (vector table, CMSDK
//! timers, dual timer, watchdog) and the end of a run. The images: `zslide-qemu` (`src/main.rs`, the firmware closing
//! its loop on the plant model) and `zslide-qemu-replay`
//! (`src/bin/replay.rs`, host-sim's recordings played through the same
//! handlers).
#![no_std]

pub mod board;
pub mod trace;

use cortex_m_semihosting::debug;

/// The first step of every fault path (HardFault, panic), as on the
/// NUCLEO: interrupts masked, then the amplifier-enable output dropped;
/// returns whether it was high (read before the store, for the log).
pub fn outputs_safe() -> bool {
    cortex_m::interrupt::disable();
    let was = board::enable::is_high();
    board::enable::set(false);
    was
}

/// Ends the run: semihosting exit with status 0 when `ok`, 1 otherwise.
pub fn exit(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::wfi();
    }
}
