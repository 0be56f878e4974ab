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
        (u128::from(self.time.get()) * u128::from(self.ticks_per_s) / 1_000_000_000) as u32
    }
}
