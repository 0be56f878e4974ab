//! Stop-gap bridge from the simulated chips to the core's converter traits
//! (`zslide::hw::GaugeAdc`, `AmplifierDac`), written from the COMMON.md frame
//! formats, so the firmware's `loop_tick` runs against the plant today. When
//! the core's `drivers` module lands (drivers generic over `SpiDevice`), use
//! those on the simulated chips instead and delete this file: the point of
//! the simulated chips is to test the real drivers.

use embedded_hal::spi::SpiDevice;
use zslide::hw::{AmplifierDac, BusError, GaugeAdc, GaugeSample};

fn frame(word: u32) -> [u8; 3] {
    [(word >> 16) as u8, (word >> 8) as u8, word as u8]
}

/// Amplifier DAC (AD5791 class) over any `SpiDevice`.
pub struct SpiAmplifierDac<S>(pub S);

impl<S: SpiDevice> SpiAmplifierDac<S> {
    /// DAC register to 0 V, then control: RBUF, not clamped, not tristate,
    /// two's complement.
    pub fn release_clamp(&mut self) -> Result<(), BusError> {
        self.write(0)?;
        self.0.write(&frame(0x20_0002)).map_err(|_| BusError)
    }
}

impl<S: SpiDevice> AmplifierDac for SpiAmplifierDac<S> {
    fn write(&mut self, code: i32) -> Result<(), BusError> {
        let w = 0x10_0000 | (code as u32 & 0xF_FFFF);
        self.0.write(&frame(w)).map_err(|_| BusError)
    }
    fn clamp_to_ground(&mut self) -> Result<(), BusError> {
        self.0.write(&frame(0x20_0006)).map_err(|_| BusError)
    }
}

/// Gauge ADC (AD4020 class) over any `SpiDevice`.
pub struct SpiGaugeAdc<S>(pub S);

impl<S: SpiDevice> GaugeAdc for SpiGaugeAdc<S> {
    fn read(&mut self) -> Result<GaugeSample, BusError> {
        let mut b = [0u8; 3];
        self.0.read(&mut b).map_err(|_| BusError)?;
        let w = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        if w & 0b111 != 0b010 {
            return Err(BusError);
        }
        Ok(GaugeSample {
            code: super::sext20(w >> 4),
            overrange: w & 0b1000 != 0,
        })
    }
}
