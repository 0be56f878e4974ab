//! Converters for the core's integration tests: a gauge whose reading the
//! test sets, and an amplifier DAC that records what the firmware did.
#![allow(dead_code)]

use zslide::hw::{AmplifierDac, BusError, GaugeAdc, GaugeSample};

/// A gauge whose next reading the test sets.
pub struct Gauge(pub Result<GaugeSample, BusError>);

impl Gauge {
    pub fn at(code: i32) -> Self {
        Self(Ok(GaugeSample {
            code,
            overrange: false,
        }))
    }
    pub fn set(&mut self, code: i32) {
        self.0 = Ok(GaugeSample {
            code,
            overrange: false,
        });
    }
}

impl GaugeAdc for Gauge {
    fn read(&mut self) -> Result<GaugeSample, BusError> {
        self.0
    }
}

/// An amplifier DAC that records its writes and whether it is clamped.
#[derive(Default)]
pub struct Dac {
    pub writes: u32,
    pub last: i32,
    pub clamped: bool,
    pub releases: u32,
}

impl AmplifierDac for Dac {
    fn write(&mut self, code: i32) -> Result<(), BusError> {
        self.writes += 1;
        self.last = code;
        Ok(())
    }
    fn clamp_to_ground(&mut self) -> Result<(), BusError> {
        self.clamped = true;
        Ok(())
    }
    fn release_clamp(&mut self) -> Result<(), BusError> {
        self.clamped = false;
        self.releases += 1;
        Ok(())
    }
}
