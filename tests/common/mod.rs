//! Converters for the core's integration tests: a gauge whose reading the
//! test sets, and an amplifier DAC that records what the firmware did.
#![allow(dead_code)]

use zslide::hw::{AmplifierDac, BusError, GaugeAdc, GaugeSample};

/// A gauge whose next reading the test sets.
pub struct Gauge(pub Result<GaugeSample, BusError>, pub u32);

impl Gauge {
    pub fn at(code: i32) -> Self {
        Self(
            Ok(GaugeSample {
                code,
                overrange: false,
            }),
            0,
        )
    }
    pub fn set(&mut self, code: i32) {
        self.0 = Ok(GaugeSample {
            code,
            overrange: false,
        });
    }
}

impl GaugeAdc for Gauge {
    /// The code, one code lower on every other read: a real 20-bit
    /// reading of a held slide moves by its noise (≥ 10 codes RMS), and
    /// one that does not is a frozen gauge (`servo::monitor`). A code on a
    /// rail stays there (a pinned gauge).
    fn read(&mut self) -> Result<GaugeSample, BusError> {
        self.1 = self.1.wrapping_add(1);
        let mut r = self.0;
        if let Ok(s) = &mut r {
            if s.code > zslide::codes::CODE_MIN + 1 && s.code < zslide::codes::CODE_MAX {
                s.code -= (self.1 & 1) as i32 ^ 1;
            }
        }
        r
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
