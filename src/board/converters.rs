//! The two converters the loop tick uses, at the level of their SPI frames
//! (`docs/BOARD.md`, COMMON converter formats). Stop-gap board glue: when the
//! core's `drivers` module lands (AD5791, AD4020, AD5686 drivers generic over
//! `SpiDevice`), the board constructs those instead and this file goes.

use embedded_hal::spi::SpiDevice;
use zslide::hw::{AmplifierDac, BusError, GaugeAdc, GaugeSample};

/// AD5791 register addresses (frame bits 22..20).
const REG_DAC: u32 = 0b001 << 20;
const REG_CONTROL: u32 = 0b010 << 20;
/// Control register: RBUF (unity-gain output buffer configuration).
const CTRL_RBUF: u32 = 1 << 1;
/// Control register: OPGND, output clamped to ground.
const CTRL_OPGND: u32 = 1 << 2;

fn frame(word: u32) -> [u8; 3] {
    [(word >> 16) as u8, (word >> 8) as u8, word as u8]
}

/// AD5791 in front of the power amplifier, two's complement coding, LDAC
/// tied low (the output follows each frame's end).
pub struct Ad5791<S> {
    spi: S,
}

impl<S: SpiDevice> Ad5791<S> {
    pub fn new(spi: S) -> Self {
        Self { spi }
    }

    /// Output register to 0 V, then the output stage out of its power-on
    /// clamp (OPGND = 0, DACTRI = 0, two's complement, SDO enabled).
    pub fn release_clamp(&mut self) -> Result<(), BusError> {
        self.write(0)?;
        self.spi
            .write(&frame(REG_CONTROL | CTRL_RBUF))
            .map_err(|_| BusError)
    }
}

impl<S: SpiDevice> AmplifierDac for Ad5791<S> {
    fn write(&mut self, code: i32) -> Result<(), BusError> {
        let data = (code as u32) & 0xF_FFFF;
        self.spi.write(&frame(REG_DAC | data)).map_err(|_| BusError)
    }
    fn clamp_to_ground(&mut self) -> Result<(), BusError> {
        self.spi
            .write(&frame(REG_CONTROL | CTRL_RBUF | CTRL_OPGND))
            .map_err(|_| BusError)
    }
}

/// AD4020-class gauge ADC, conversion started by the loop timer's CNV pulse.
pub struct Ad4020<S> {
    spi: S,
}

impl<S: SpiDevice> Ad4020<S> {
    pub fn new(spi: S) -> Self {
        Self { spi }
    }
}

impl<S: SpiDevice> GaugeAdc for Ad4020<S> {
    fn read(&mut self) -> Result<GaugeSample, BusError> {
        let mut b = [0u8; 3];
        self.spi.read(&mut b).map_err(|_| BusError)?;
        let [b0, b1, b2] = b;
        let word = (u32::from(b0) << 16) | (u32::from(b1) << 8) | u32::from(b2);
        // bits 2..0 must read 0b010: an all-0 or all-1 frame is a dead bus.
        if word & 0b111 != 0b010 {
            return Err(BusError);
        }
        // bits 23..4: sign-extend the 20-bit result.
        let code = ((word << 8) as i32) >> 12;
        Ok(GaugeSample {
            code,
            overrange: word & 0b1000 != 0,
        })
    }
}
