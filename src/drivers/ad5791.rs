//! Amplifier DAC, AD5791 class: 20 bits, ±10 V, two's complement.
//!
//! Frame: bit 23 R/W (0 = write), bits 22..20 register (001 DAC, 010
//! control, 011 clearcode, 100 software control), bits 19..0 data. At power
//! on the output is clamped to ground (OPGND) and tristated (DACTRI);
//! [`Ad5791::init`] selects two's complement, releases both, and reads the
//! control register back (a read frame, then a no-op frame that clocks the
//! content out), so a dead or miswired bus is found before the loop closes.
//! LDAC is tied low on the board: the output follows each DAC frame's end.

use super::{bytes_frame, frame_bytes};
use crate::hw::{AmplifierDac, BusError};
use embedded_hal::spi::{Operation, SpiDevice};

pub const REG_NOP: u32 = 0b000;
pub const REG_DAC: u32 = 0b001;
pub const REG_CONTROL: u32 = 0b010;
pub const REG_CLEARCODE: u32 = 0b011;
pub const REG_SOFTWARE: u32 = 0b100;

/// Control register bits.
pub const CTRL_RBUF: u32 = 1 << 1;
pub const CTRL_OPGND: u32 = 1 << 2;
pub const CTRL_DACTRI: u32 = 1 << 3;
/// 1 = offset binary; the driver uses two's complement (0).
pub const CTRL_BIN2SC: u32 = 1 << 4;
pub const CTRL_SDODIS: u32 = 1 << 5;

/// Output live: internal amplifier in unity gain (RBUF), two's complement,
/// not clamped, not tristated, SDO enabled for read-back.
pub const CTRL_RUN: u32 = CTRL_RBUF;
/// Safe state: output clamped to ground through the chip's own switch.
pub const CTRL_SAFE: u32 = CTRL_RBUF | CTRL_OPGND;

/// The DAC's code range: the 20-bit codes of `crate::codes`.
pub use crate::codes::{CODE_MAX, CODE_MIN};

/// Write frame for `reg` with 20 data bits.
pub const fn write_frame(reg: u32, data: u32) -> u32 {
    ((reg & 0b111) << 20) | (data & 0xF_FFFF)
}

/// Read-request frame for `reg`.
pub const fn read_frame(reg: u32) -> u32 {
    (1 << 23) | ((reg & 0b111) << 20)
}

pub struct Ad5791<SPI> {
    spi: SPI,
}

impl<SPI: SpiDevice> Ad5791<SPI> {
    pub fn new(spi: SPI) -> Self {
        Self { spi }
    }

    pub fn release(self) -> SPI {
        self.spi
    }

    fn write(&mut self, frame: u32) -> Result<(), BusError> {
        self.spi.write(&frame_bytes(frame)).map_err(|_| BusError)
    }

    /// Reads a register's 20 data bits: the read request in one frame, then
    /// a no-op frame that clocks the content out. Two chip-select frames:
    /// the chip acts on the last 24 bits of a frame when SYNC rises, so a
    /// single 48-bit frame would lose the request (found by the simulated
    /// chip, `host-sim` `chips::ad5791`).
    pub fn read_register(&mut self, reg: u32) -> Result<u32, BusError> {
        self.write(read_frame(reg))?;
        let mut reply = frame_bytes(write_frame(REG_NOP, 0));
        self.spi
            .transaction(&mut [Operation::TransferInPlace(&mut reply)])
            .map_err(|_| BusError)?;
        Ok(bytes_frame(reply) & 0xF_FFFF)
    }

    /// At power-up the chip is clamped and tristated: released as after a
    /// fault ([`AmplifierDac::release_clamp`]).
    pub fn init(&mut self) -> Result<(), BusError> {
        AmplifierDac::release_clamp(self)
    }
}

impl<SPI: SpiDevice> AmplifierDac for Ad5791<SPI> {
    fn write(&mut self, code: i32) -> Result<(), BusError> {
        let c = code.clamp(CODE_MIN, CODE_MAX) as u32;
        Ad5791::write(self, write_frame(REG_DAC, c))
    }

    fn clamp_to_ground(&mut self) -> Result<(), BusError> {
        Ad5791::write(self, write_frame(REG_CONTROL, CTRL_SAFE))
    }

    /// Zero code first, then the control register, verified by read-back.
    fn release_clamp(&mut self) -> Result<(), BusError> {
        Ad5791::write(self, write_frame(REG_DAC, 0))?;
        Ad5791::write(self, write_frame(REG_CONTROL, CTRL_RUN))?;
        if self.read_register(REG_CONTROL)? & 0x3E != CTRL_RUN {
            return Err(BusError);
        }
        Ok(())
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::super::fake::Spi;
    use super::*;

    #[test]
    fn frames_match_the_board_format() {
        let mut d = Ad5791::new(Spi::default());
        AmplifierDac::write(&mut d, -1).unwrap();
        AmplifierDac::write(&mut d, 1 << 22).unwrap(); // clamps to full scale
        AmplifierDac::write(&mut d, i32::MIN).unwrap();
        d.clamp_to_ground().unwrap();
        let spi = d.release();
        assert_eq!(spi.written, [0x1F_FFFF, 0x17_FFFF, 0x18_0000, 0x20_0006]);
    }

    #[test]
    fn init_verifies_the_control_register() {
        let mut spi = Spi::default();
        // Reply to the read: the control register content in the next frame.
        spi.replies.push_back(0x20_0002);
        let mut d = Ad5791::new(spi);
        d.init().unwrap();
        let spi = d.release();
        assert_eq!(spi.written, [0x10_0000, 0x20_0002, 0xA0_0000, 0x00_0000]);

        let mut spi = Spi::default();
        spi.replies.push_back(0x20_000E); // still clamped and tristated
        assert_eq!(Ad5791::new(spi).init(), Err(BusError));

        let spi = Spi {
            fail: true,
            ..Spi::default()
        };
        assert_eq!(AmplifierDac::write(&mut Ad5791::new(spi), 0), Err(BusError));
    }
}
