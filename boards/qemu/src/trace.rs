//! The QEMU image's trace clock: the CMSDK dual timer's free-running
//! 25 MHz count (the loop-tick timer's period count alone gives no time
//! inside a tick). The events themselves are `zslide::trace`'s, on the log
//! in builds with the `trace` feature (`cargo xtask qemu --vcd FILE`);
//! without it the clock is never started and nothing is emitted.

use crate::board::{dualtimer, PCLK_HZ};
use zslide::trace::Event;

/// Starts the clock and names its rate (trace builds).
#[inline(always)]
pub fn start() {
    if cfg!(feature = "trace") {
        dualtimer::start_clock();
        zslide::trace::announce_clock(PCLK_HZ);
    }
}

/// PCLK cycles since [`start`] (trace builds; 0 otherwise).
#[inline(always)]
pub fn clock() -> u32 {
    if cfg!(feature = "trace") {
        dualtimer::clock()
    } else {
        0
    }
}

/// One event, stamped now.
#[inline(always)]
pub fn emit(e: Event) {
    zslide::trace::emit(e, clock());
}
