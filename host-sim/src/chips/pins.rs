//! Simulated pins and timers: the amplifier enable line and the firmware
//! core's clock.

use super::SimTime;
use embedded_hal::digital::{ErrorType, OutputPin};
use std::cell::RefCell;
use std::convert::Infallible;
use std::rc::Rc;

/// State of the amplifier's enable line as the rig sees it.
#[derive(Clone, Debug, Default)]
pub struct AmpControl {
    /// Line level (true = enable).
    pub enable: bool,
    /// Edges not yet applied to the amplifier, (time ns, level).
    pub changes: Vec<(u64, bool)>,
}

/// The amplifier enable output (high = enabled). A rising edge also resets
/// a tripped amplifier (see `plant::amplifier`).
#[derive(Clone, Debug)]
pub struct SimAmpEnablePin {
    pub state: Rc<RefCell<AmpControl>>,
    pub time: SimTime,
}

impl SimAmpEnablePin {
    pub fn new(time: SimTime) -> Self {
        Self {
            state: Rc::new(RefCell::new(AmpControl::default())),
            time,
        }
    }
    fn set(&mut self, level: bool) {
        let mut s = self.state.borrow_mut();
        s.enable = level;
        let t = self.time.get();
        s.changes.push((t, level));
    }
}

impl ErrorType for SimAmpEnablePin {
    type Error = Infallible;
}

impl OutputPin for SimAmpEnablePin {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        self.set(false);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        self.set(true);
        Ok(())
    }
}

/// `zslide::hw::Clock` on simulation time: a free-running counter at
/// `ticks_per_s`, wrapping at 2³².
#[derive(Clone, Debug)]
pub struct SimClock {
    pub time: SimTime,
    pub ticks_per_s: u64,
}

impl SimClock {
    pub fn new(time: SimTime, ticks_per_s: u64) -> Self {
        Self { time, ticks_per_s }
    }
}

impl zslide::hw::Clock for SimClock {
    fn now_ticks(&mut self) -> u32 {
        clock_ticks(self.time.get(), self.ticks_per_s)
    }
}

/// A free-running clock of `ticks_per_s` (≤ 2³²) at `t_ns`: ⌊t·f / 10⁹⌋
/// wrapping at 2³², exactly, without a 128-bit division (whole seconds
/// and the rest apart; only the low 32 bits are kept, so the seconds'
/// product may wrap).
#[inline]
pub fn clock_ticks(t_ns: u64, ticks_per_s: u64) -> u32 {
    const NS: u64 = 1_000_000_000;
    let (s, r) = (t_ns / NS, t_ns % NS);
    s.wrapping_mul(ticks_per_s)
        .wrapping_add(r * ticks_per_s / NS) as u32
}

#[cfg(test)]
mod tests {
    #[test]
    fn clock_ticks_equal_the_128_bit_form() {
        let mut g = 0x2545_F491_4F6C_DD1Du64;
        for tps in [
            1_000u64,
            25_000_000,
            100_000_000,
            200_000_000,
            4_000_000_000,
        ] {
            for k in 0..20_000u64 {
                g ^= g << 13;
                g ^= g >> 7;
                g ^= g << 17;
                let t = if k < 10 { k } else { g >> (k % 40) };
                let want = (u128::from(t) * u128::from(tps) / 1_000_000_000) as u32;
                assert_eq!(super::clock_ticks(t, tps), want, "t {t} f {tps}");
            }
        }
    }
}
