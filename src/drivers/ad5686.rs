//! Quad coefficient DAC, AD5686 class (16 bits, channels A..D = C00..C03)
//! with its active-low LDAC pin: the legacy coefficient-output mode that
//! drops the firmware into the 1983 analog electronics.
//!
//! Frame: bits 23..20 command (0001 write input register, 0010 update DAC
//! register from input, 0011 write and update), bits 19..16 channel mask
//! (A=0001 … D=1000), bits 15..0 straight binary data. The coefficients of
//! one X event go to the input registers, then one low pulse on LDAC copies
//! all four to the outputs at once: the 1983 strobe (appendix A `DACS`).
//! Scaling (Table 3-1): [`crate::xpos::legacy_output::legacy_dac_code`].

use super::frame_bytes;
use crate::hw::BusError;
use embedded_hal::digital::OutputPin;
use embedded_hal::spi::SpiDevice;

pub const CMD_WRITE_INPUT: u32 = 0b0001;
pub const CMD_UPDATE_FROM_INPUT: u32 = 0b0010;
pub const CMD_WRITE_AND_UPDATE: u32 = 0b0011;

/// Frame for `command` on the channels in `mask` (bit 0 = A).
pub const fn frame(command: u32, mask: u8, data: u16) -> u32 {
    ((command & 0xF) << 20) | (((mask & 0xF) as u32) << 16) | data as u32
}

pub struct Ad5686<SPI, LDAC> {
    spi: SPI,
    ldac: LDAC,
}

impl<SPI: SpiDevice, LDAC: OutputPin> Ad5686<SPI, LDAC> {
    /// Takes the bus and the LDAC pin and sets LDAC idle (high).
    pub fn new(spi: SPI, mut ldac: LDAC) -> Result<Self, BusError> {
        ldac.set_high().map_err(|_| BusError)?;
        Ok(Self { spi, ldac })
    }

    pub fn release(self) -> (SPI, LDAC) {
        (self.spi, self.ldac)
    }

    /// Writes one channel's input register (not yet on the output).
    pub fn write_input(&mut self, channel: u8, code: u16) -> Result<(), BusError> {
        let f = frame(CMD_WRITE_INPUT, 1 << (channel & 3), code);
        self.spi.write(&frame_bytes(f)).map_err(|_| BusError)
    }

    /// One LDAC low pulse: every input register to its output at once.
    pub fn strobe(&mut self) -> Result<(), BusError> {
        self.ldac.set_low().map_err(|_| BusError)?;
        self.ldac.set_high().map_err(|_| BusError)
    }

    /// One legacy X event: the channels in `update` (bit j = C0j) get their
    /// codes, then a single strobe. Nothing is strobed if a write failed.
    pub fn output(&mut self, codes: &[u16; 4], update: u8) -> Result<(), BusError> {
        for (ch, code) in codes.iter().enumerate() {
            if update & (1 << ch) != 0 {
                self.write_input(ch as u8, *code)?;
            }
        }
        self.strobe()
    }
}

impl<SPI: SpiDevice, LDAC: OutputPin> crate::hw::CoefficientDac for Ad5686<SPI, LDAC> {
    fn output(&mut self, codes: &[u16; 4], update: u8) -> Result<(), BusError> {
        Ad5686::output(self, codes, update)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::super::fake::{Pin, Spi};
    use super::*;

    #[test]
    fn writes_the_updated_channels_then_strobes_once() {
        let mut d = Ad5686::new(Spi::default(), Pin::default()).unwrap();
        d.output(&[0x8000, 0x7000, 0x1234, 0x8010], 0b0110).unwrap();
        let (spi, pin) = d.release();
        assert_eq!(spi.written, [0x12_7000, 0x14_1234]);
        assert_eq!(pin.levels, [true, false, true]);

        let spi = Spi {
            fail: true,
            ..Spi::default()
        };
        let mut d = Ad5686::new(spi, Pin::default()).unwrap();
        assert_eq!(d.output(&[0; 4], 0b1111), Err(BusError));
        let (_, pin) = d.release();
        assert_eq!(pin.levels, [true], "no strobe after a failed write");
    }
}
