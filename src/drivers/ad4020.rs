//! Gauge ADC, AD4020 class: 20 bits, conversions started by hardware (CNV
//! from the loop timer), read as 3 bytes: bits 23..4 the two's complement
//! result, bit 3 OV (input over range), bits 2..0 the fixed pattern 0b010.
//! A frame without the pattern (a stuck bus reads all 0s or all 1s) is a
//! bus error, never a number.

use super::bytes_frame;
use crate::hw::{BusError, GaugeAdc, GaugeSample};
use embedded_hal::spi::SpiDevice;

pub const PATTERN_MASK: u32 = 0b111;
pub const PATTERN: u32 = 0b010;
pub const OV_BIT: u32 = 1 << 3;

/// Decodes one 24-bit frame.
pub fn decode(frame: u32) -> Result<GaugeSample, BusError> {
    if frame & PATTERN_MASK != PATTERN || frame >> 24 != 0 {
        return Err(BusError);
    }
    // Sign-extend bits 23..4 (shift to the top, arithmetic shift back).
    let code = ((frame << 8) as i32) >> 12;
    Ok(GaugeSample {
        code,
        overrange: frame & OV_BIT != 0,
    })
}

pub struct Ad4020<SPI> {
    spi: SPI,
}

impl<SPI: SpiDevice> Ad4020<SPI> {
    pub fn new(spi: SPI) -> Self {
        Self { spi }
    }
    pub fn release(self) -> SPI {
        self.spi
    }
}

impl<SPI: SpiDevice> GaugeAdc for Ad4020<SPI> {
    fn read(&mut self) -> Result<GaugeSample, BusError> {
        let mut b = [0u8; 3];
        self.spi.read(&mut b).map_err(|_| BusError)?;
        decode(bytes_frame(b))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::super::fake::Spi;
    use super::*;

    fn frame(code: i32, ov: bool) -> u32 {
        (((code as u32) & 0xF_FFFF) << 4) | if ov { OV_BIT } else { 0 } | PATTERN
    }

    #[test]
    fn decodes_codes_and_flags_stuck_buses() {
        for code in [0, 1, -1, (1 << 19) - 1, -(1 << 19), 12345, -54321] {
            for ov in [false, true] {
                assert_eq!(
                    decode(frame(code, ov)),
                    Ok(GaugeSample {
                        code,
                        overrange: ov
                    })
                );
            }
        }
        assert_eq!(decode(0x00_0000), Err(BusError));
        assert_eq!(decode(0xFF_FFFF), Err(BusError));
        let mut spi = Spi::default();
        spi.replies.extend([frame(-7, false), 0xFF_FFFF]);
        let mut adc = Ad4020::new(spi);
        assert_eq!(
            adc.read(),
            Ok(GaugeSample {
                code: -7,
                overrange: false
            })
        );
        assert_eq!(adc.read(), Err(BusError));
    }
}
