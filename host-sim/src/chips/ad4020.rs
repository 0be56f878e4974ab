//! Simulated AD4020-class 20-bit gauge ADC.
//!
//! Conversions are started by hardware (CNV from the loop timer): the rig
//! calls [`Ad4020State::convert`] at the timer instant with the gauge
//! voltage. Reading 3 bytes returns bits 23..4 = the 20-bit two's
//! complement result, bit 3 = OV (input at or beyond full scale), bits 2..0
//! = the fixed pattern 0b010. Code = round(V · 2^19 / 10 V), clamped to
//! [−2^19, 2^19 − 1]. Re-reading without a new conversion returns the same
//! result. MOSI is ignored.

use super::{faulty_shift, FaultInjector, SimSpiError};
use embedded_hal::spi::{ErrorType, Operation, SpiDevice};
use std::cell::RefCell;
use std::rc::Rc;

/// The fixed low bits of every frame.
pub const PATTERN: u32 = 0b010;
pub const OV_BIT: u32 = 1 << 3;
pub const FULL_SCALE_V: f64 = zslide_plant::gauge::ADC_FULL_SCALE_V;

#[derive(Clone, Debug, Default)]
pub struct Ad4020State {
    /// Frame of the last conversion.
    pub result: u32,
    /// Last converted code and input, for traces.
    pub code: i32,
    pub input_v: f64,
    pub conversions: u64,
    pub reads: u64,
    pub faults: FaultInjector,
}

impl Ad4020State {
    /// CNV: converts `volts`.
    pub fn convert(&mut self, volts: f64) {
        // The quantisation is the plant model's (shared with the QEMU image).
        let (code, ov) = zslide_plant::gauge::adc_convert(volts);
        self.code = code;
        self.input_v = volts;
        self.result = ((code as u32 & 0xF_FFFF) << 4) | if ov { OV_BIT } else { 0 } | PATTERN;
        self.conversions += 1;
    }
}

/// The SPI device the gauge-ADC driver owns.
#[derive(Clone, Debug, Default)]
pub struct SimAd4020 {
    pub state: Rc<RefCell<Ad4020State>>,
}

impl SimAd4020 {
    pub fn new() -> Self {
        Self::default()
    }
}

impl ErrorType for SimAd4020 {
    type Error = SimSpiError;
}

impl SpiDevice<u8> for SimAd4020 {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), Self::Error> {
        let mut s = self.state.borrow_mut();
        let fault = s.faults.next();
        let result = s.result;
        faulty_shift(operations, result, fault)?;
        s.reads += 1;
        Ok(())
    }
}
