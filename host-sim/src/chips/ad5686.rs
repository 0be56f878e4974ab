//! Simulated AD5686-class quad 16-bit DAC (coefficient outputs C00..C03 on
//! channels A..D) with its active-low LDAC pin.
//!
//! Frame: bits 23..20 command (0001 write input register, 0010 update DAC
//! register from input, 0011 write and update, 0110 software reset), bits
//! 19..16 channel mask (A = 0001, B = 0010, C = 0100, D = 1000; several bits
//! address several channels), bits 15..0 straight binary data. LDAC: a
//! falling edge copies all input registers to the DAC registers at once
//! (the 1983 "strobe"); while LDAC is held low, writes to an input register
//! go straight through to the DAC register. Output: V = 20 V · code / 65536
//! − 10 V. Power-on and software reset load mid-scale (0 V: the board ties
//! RSTSEL for mid-scale, so the coefficient outputs start at zero).

use super::{faulty_shift, FaultInjector, SimSpiError};
use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::spi::{ErrorType, Operation, SpiDevice};
use std::cell::RefCell;
use std::convert::Infallible;
use std::rc::Rc;

pub const CMD_WRITE_INPUT: u32 = 0b0001;
pub const CMD_UPDATE: u32 = 0b0010;
pub const CMD_WRITE_UPDATE: u32 = 0b0011;
pub const CMD_RESET: u32 = 0b0110;
pub const MIDSCALE: u16 = 0x8000;

#[derive(Clone, Debug)]
pub struct Ad5686State {
    pub input: [u16; 4],
    pub dac: [u16; 4],
    /// LDAC pin level (true = high, idle).
    pub ldac_high: bool,
    pub frames: u64,
    pub bad_frames: u64,
    pub strobes: u64,
    pub faults: FaultInjector,
}

impl Default for Ad5686State {
    fn default() -> Self {
        Self {
            input: [MIDSCALE; 4],
            dac: [MIDSCALE; 4],
            ldac_high: true,
            frames: 0,
            bad_frames: 0,
            strobes: 0,
            faults: FaultInjector::default(),
        }
    }
}

impl Ad5686State {
    /// Output of channel `ch` (0 = A), V.
    pub fn volts(&self, ch: usize) -> f64 {
        self.dac
            .get(ch)
            .map_or(0.0, |&c| 20.0 * f64::from(c) / 65536.0 - 10.0)
    }

    fn frame(&mut self, w: u32) {
        self.frames += 1;
        let cmd = (w >> 20) & 0xF;
        let mask = (w >> 16) & 0xF;
        let data = (w & 0xFFFF) as u16;
        let chans = (0..4).filter(|k| mask & (1 << k) != 0);
        match cmd {
            CMD_WRITE_INPUT => {
                for k in chans {
                    self.input[k] = data;
                    if !self.ldac_high {
                        self.dac[k] = data;
                    }
                }
            }
            CMD_UPDATE => {
                for k in chans {
                    self.dac[k] = self.input[k];
                }
            }
            CMD_WRITE_UPDATE => {
                for k in chans {
                    self.input[k] = data;
                    self.dac[k] = data;
                }
            }
            CMD_RESET => {
                self.input = [MIDSCALE; 4];
                self.dac = [MIDSCALE; 4];
            }
            _ => self.bad_frames += 1,
        }
    }

    fn set_ldac(&mut self, high: bool) {
        if self.ldac_high && !high {
            self.dac = self.input;
            self.strobes += 1;
        }
        self.ldac_high = high;
    }
}

/// The SPI device of the quad DAC.
#[derive(Clone, Debug, Default)]
pub struct SimAd5686 {
    pub state: Rc<RefCell<Ad5686State>>,
}

impl SimAd5686 {
    pub fn new() -> Self {
        Self::default()
    }
    /// The LDAC pin of this chip.
    pub fn ldac_pin(&self) -> SimLdacPin {
        SimLdacPin {
            state: self.state.clone(),
        }
    }
}

impl ErrorType for SimAd5686 {
    type Error = SimSpiError;
}

impl SpiDevice<u8> for SimAd5686 {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), Self::Error> {
        let mut s = self.state.borrow_mut();
        let fault = s.faults.next();
        let Some(frame) = faulty_shift(operations, 0, fault)? else {
            return Ok(());
        };
        match frame.word24() {
            Some(w) => s.frame(w),
            None => s.bad_frames += 1,
        }
        Ok(())
    }
}

/// The active-low LDAC line of the quad DAC.
#[derive(Clone, Debug)]
pub struct SimLdacPin {
    state: Rc<RefCell<Ad5686State>>,
}

impl PinErrorType for SimLdacPin {
    type Error = Infallible;
}

impl OutputPin for SimLdacPin {
    fn set_low(&mut self) -> Result<(), Self::Error> {
        self.state.borrow_mut().set_ldac(false);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Self::Error> {
        self.state.borrow_mut().set_ldac(true);
        Ok(())
    }
}
