//! Simulated AD5791-class 20-bit DAC in front of the power amplifier.
//!
//! Frame (24 bits, MSB first): bit 23 R/W̄ (0 = write), bits 22..20 register
//! (001 DAC, 010 control, 011 clearcode, 100 software control), bits 19..0
//! data. Control register: bit 1 RBUF, bit 2 OPGND (output clamped to
//! ground, set at power-on), bit 3 DACTRI (output tristate, set at
//! power-on), bit 4 BIN/2sC (0 = two's complement), bit 5 SDODIS. Software
//! control: bit 2 RESET, bit 1 CLR, bit 0 LDAC. LDAC is tied low on the
//! board, so the DAC register (and the output) updates at the end of each
//! DAC frame. A read (bit 23 = 1) returns `1, address, content` in the
//! next frame. Output: `V = 10 V · code / 2^19` (two's complement code);
//! clamped or tristate output reads as 0 V at the amplifier input.

use super::{faulty_shift, sext20, FaultInjector, SimSpiError, SimTime};
use embedded_hal::spi::{ErrorType, Operation, SpiDevice};
use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

pub const REG_DAC: u32 = 0b001;
pub const REG_CTRL: u32 = 0b010;
pub const REG_CLEARCODE: u32 = 0b011;
pub const REG_SWCTRL: u32 = 0b100;
pub const CTRL_RBUF: u32 = 1 << 1;
pub const CTRL_OPGND: u32 = 1 << 2;
pub const CTRL_DACTRI: u32 = 1 << 3;
pub const CTRL_BIN2SC: u32 = 1 << 4;
pub const CTRL_SDODIS: u32 = 1 << 5;
pub const SW_LDAC: u32 = 1 << 0;
pub const SW_CLR: u32 = 1 << 1;
pub const SW_RESET: u32 = 1 << 2;
/// Control register at power-on: output clamped to ground and tristate.
pub const CTRL_POWER_ON: u32 = CTRL_OPGND | CTRL_DACTRI;

#[derive(Clone, Debug)]
pub struct Ad5791State {
    pub dac: u32,
    pub ctrl: u32,
    pub clearcode: u32,
    /// Word shifted out on MISO in the next frame.
    pub sdo: u32,
    /// Output changes not yet seen by the plant: (time ns, volts).
    pub changes: VecDeque<(u64, f64)>,
    /// Output as the chip last set it (latest change), V.
    pub vout: f64,
    /// Delay from the handler's start to the frame end, ns (the time the
    /// firmware takes to compute and shift the word).
    pub latency_ns: u64,
    pub frames: u64,
    pub bad_frames: u64,
    pub dac_writes: u64,
    pub faults: FaultInjector,
}

impl Default for Ad5791State {
    fn default() -> Self {
        Self {
            dac: 0,
            ctrl: CTRL_POWER_ON,
            clearcode: 0,
            sdo: 0,
            changes: VecDeque::new(),
            vout: 0.0,
            latency_ns: 0,
            frames: 0,
            bad_frames: 0,
            dac_writes: 0,
            faults: FaultInjector::default(),
        }
    }
}

impl Ad5791State {
    /// Output volts for the current registers.
    pub fn output_volts(&self) -> f64 {
        if self.ctrl & (CTRL_OPGND | CTRL_DACTRI) != 0 {
            return 0.0;
        }
        10.0 * f64::from(self.code()) / f64::from(1u32 << 19)
    }
    /// DAC register as a signed code (offset binary is converted).
    pub fn code(&self) -> i32 {
        if self.ctrl & CTRL_BIN2SC != 0 {
            self.dac as i32 - (1 << 19)
        } else {
            sext20(self.dac)
        }
    }
    /// Power-on state (registers, not the fault plan or counters).
    fn reset(&mut self) {
        self.dac = 0;
        self.ctrl = CTRL_POWER_ON;
        self.clearcode = 0;
    }

    fn frame(&mut self, w: u32, now: u64) {
        self.frames += 1;
        let read = w & (1 << 23) != 0;
        let reg = (w >> 20) & 0b111;
        let data = w & 0xF_FFFF;
        let before = self.output_volts();
        if read {
            let content = match reg {
                REG_DAC => self.dac,
                REG_CTRL => self.ctrl,
                REG_CLEARCODE => self.clearcode,
                _ => 0,
            };
            self.sdo = (1 << 23) | (reg << 20) | content;
            return;
        }
        self.sdo = 0;
        match reg {
            REG_DAC => {
                self.dac = data;
                self.dac_writes += 1;
            }
            REG_CTRL => self.ctrl = data & 0x3FE,
            REG_CLEARCODE => self.clearcode = data,
            REG_SWCTRL => {
                if data & SW_RESET != 0 {
                    self.reset();
                } else if data & SW_CLR != 0 {
                    self.dac = self.clearcode;
                }
            }
            0b000 => {} // no operation: the frame that clocks a read-back out
            _ => self.bad_frames += 1, // reserved addresses
        }
        let after = self.output_volts();
        if after != before || reg == REG_DAC {
            self.vout = after;
            self.changes.push_back((now + self.latency_ns, after));
        }
    }
}

/// The SPI device the amplifier-DAC driver owns.
#[derive(Clone, Debug)]
pub struct SimAd5791 {
    pub state: Rc<RefCell<Ad5791State>>,
    pub time: SimTime,
}

impl SimAd5791 {
    pub fn new(time: SimTime) -> Self {
        Self {
            state: Rc::new(RefCell::new(Ad5791State::default())),
            time,
        }
    }
}

impl ErrorType for SimAd5791 {
    type Error = SimSpiError;
}

impl SpiDevice<u8> for SimAd5791 {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), Self::Error> {
        let mut s = self.state.borrow_mut();
        let fault = s.faults.next();
        let miso = if s.ctrl & CTRL_SDODIS != 0 { 0 } else { s.sdo };
        let frame = faulty_shift(operations, miso, fault)?;
        let Some(frame) = frame else { return Ok(()) };
        match frame.word24() {
            Some(w) => s.frame(w, self.time.get()),
            None => s.bad_frames += 1,
        }
        Ok(())
    }
}
