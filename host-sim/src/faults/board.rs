//! What the NUCLEO board does about a stalled loop and a panic, outside the
//! core (`src/board/timers.rs`, `src/main.rs`), modelled on the simulated
//! machine so that the fault campaign can show their effect. The core has
//! only the feed decision (`zslide::watchdog::FeedGate`), no watchdog and
//! no panic handler of its own: these rows test this model of the board,
//! and say so. The model's background runs at every count, so it shows a
//! loop tick that stops firing; a handler that hangs (and starves the
//! background by its priority) is shown on the emulated Cortex-M4F instead
//! (`boards/qemu`, `zslide-qemu-watchdog`).

use crate::fwrig::{Cpu, FirmwareWorld};
use crate::sched::{EventSource, Nanos};
use embedded_hal::digital::OutputPin;
use std::cell::Cell;
use std::rc::Rc;

/// IWDG1 counter clock: LSI 32 kHz / 4 (`start_watchdog`: PR = 0).
pub const IWDG_COUNT_NS: Nanos = zslide::watchdog::IWDG_COUNT_NS as Nanos;
/// Reload value, the board's: 40 counts, 5 ms.
pub const IWDG_RELOAD: u32 = zslide::watchdog::IWDG_RELOAD as u32;

/// IWDG1: a down-counter on its own clock, reloaded when the board's
/// background feeds it, which it does only when the loop tick has run since
/// the last feed (`zslide::watchdog::FeedGate`, the same decision as
/// `main.rs`; the background runs after every interrupt, modelled here at
/// each count); at zero it resets the chip. The reset returns every
/// GPIO to its reset state, so the amplifier-enable line PG4 falls to its
/// external pull-down; the firmware that boots afterwards starts disarmed
/// and reports the watchdog reset (`main.rs`, RCC reset flags). The model
/// ends the simulated firmware there: the core is halted, the enable low.
pub struct Iwdg {
    next: Nanos,
    counter: u32,
    gate: zslide::watchdog::FeedGate,
    /// When it reset the chip.
    pub reset_at: Rc<Cell<Option<Nanos>>>,
}

impl Iwdg {
    /// Started at boot (t = 0), as `main.rs` starts it before the loop.
    pub fn new(reset_at: Rc<Cell<Option<Nanos>>>) -> Self {
        Self {
            next: IWDG_COUNT_NS,
            counter: IWDG_RELOAD,
            gate: zslide::watchdog::FeedGate::new(0, 1),
            reset_at,
        }
    }
}

impl EventSource<FirmwareWorld> for Iwdg {
    fn next_time(&self) -> Option<Nanos> {
        self.reset_at.get().is_none().then_some(self.next)
    }
    fn priority(&self) -> u8 {
        // Hardware: runs whatever the core does, before any handler due at
        // the same instant.
        u8::MAX
    }
    fn name(&self) -> &str {
        "iwdg"
    }
    fn fire(&mut self, now: Nanos, w: &mut FirmwareWorld) {
        self.next += IWDG_COUNT_NS;
        if self.gate.may_feed(w.fw.ticks()) {
            self.counter = IWDG_RELOAD;
            return;
        }
        if self.counter > 0 {
            self.counter -= 1;
            return;
        }
        chip_reset(w);
        self.reset_at.set(Some(now));
    }
}

/// A chip reset: every handler stops, PG4 falls to its pull-down.
fn chip_reset(w: &mut FirmwareWorld) {
    w.cpu = Cpu::Halted;
    // The simulated pin cannot fail; the board's pin write cannot either.
    let _ = w.enable.set_low();
}

/// The panic handler's effect (`main.rs`: interrupts masked, then one store
/// to GPIOG_BSRR drops PG4, then the log; it spins until the watchdog
/// resets the chip): nothing runs any more and the enable line is low at
/// once. The AD5791 keeps its last code, which the disabled amplifier no
/// longer follows.
pub fn panic(w: &mut FirmwareWorld) {
    chip_reset(w);
}
