//! When the independent watchdog may be fed.
//!
//! The watchdog is fed from the background (thread mode, the lowest
//! priority), and only when the loop tick has run since the last feed.
//! That catches both ways the machine can stop being controlled:
//!
//! * a handler that hangs (the loop tick, an X or index event, the learning
//!   below them, stuck in a loop or a bus wait) starves everything below
//!   it, the background included: no feed;
//! * a loop tick that stops firing (its timer stopped, its interrupt
//!   masked) leaves the background running but the tick count still: no
//!   feed.
//!
//! Fed from the loop tick itself, as before, a hung X or index handler
//! went unnoticed (the tick preempts them and kept feeding) and only a
//! dead loop tick was caught. The watchdog's own timeout (5 ms on the
//! NUCLEO) then resets the chip, which drops the amplifier enable.

/// IWDG1's reload value on the NUCLEO (`board::timers::start_watchdog`;
/// RLR is a 12-bit register): 40 counts of its clock, LSI 32 kHz / 4. The
/// one figure the board, the simulator's model of it and the QEMU
/// watchdog check take the timeout from (why 5 ms: `start_watchdog`).
pub const IWDG_RELOAD: u16 = 39;
/// One count of IWDG1's clock, ns (LSI 32 kHz / 4, PR = 0).
pub const IWDG_COUNT_NS: u32 = 125_000;
/// The watchdog's timeout, µs: 5 ms.
pub const TIMEOUT_US: u32 = (IWDG_RELOAD as u32 + 1) * (IWDG_COUNT_NS / 1000);

/// The feed decision, kept by the background.
#[derive(Clone, Debug)]
pub struct FeedGate {
    last_ticks: u32,
    min_ticks: u32,
}

impl FeedGate {
    /// A gate that feeds once at least `min_ticks` loop ticks (≥ 1) have
    /// run since the last feed; `ticks_now` is the loop's tick count at
    /// start.
    pub const fn new(ticks_now: u32, min_ticks: u32) -> Self {
        Self {
            last_ticks: ticks_now,
            min_ticks: if min_ticks == 0 { 1 } else { min_ticks },
        }
    }

    /// Whether to feed now, given the loop's tick count (wrapping).
    pub fn may_feed(&mut self, loop_ticks: u32) -> bool {
        let ran = loop_ticks.wrapping_sub(self.last_ticks);
        if ran >= self.min_ticks {
            self.last_ticks = loop_ticks;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A background that keeps running while the loop tick's count stands
    /// still never feeds: the watchdog expires. Once the ticks move again
    /// it feeds, across the counter's wrap too.
    #[test]
    fn feeds_only_when_the_loop_tick_has_run() {
        let mut g = FeedGate::new(u32::MAX - 2, 1);
        assert!(!g.may_feed(u32::MAX - 2));
        assert!(g.may_feed(u32::MAX - 1));
        for _ in 0..1000 {
            assert!(!g.may_feed(u32::MAX - 1), "stalled loop must not feed");
        }
        assert!(g.may_feed(3), "wrapped count is progress");
        let mut g = FeedGate::new(0, 20);
        assert!(!g.may_feed(19));
        assert!(g.may_feed(20));
        assert!(!g.may_feed(39));
    }
}
