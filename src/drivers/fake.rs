//! A recording SPI device and pin for the driver tests.
extern crate std;
use core::convert::Infallible;
use embedded_hal::spi::{ErrorKind, ErrorType, Operation, SpiDevice};
use std::collections::VecDeque;
use std::vec::Vec;

#[derive(Debug)]
pub struct FakeError;
impl embedded_hal::spi::Error for FakeError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

/// Records written frames; answers reads from a queue of 24-bit frames.
#[derive(Default)]
pub struct Spi {
    pub written: Vec<u32>,
    pub replies: VecDeque<u32>,
    pub fail: bool,
}

impl ErrorType for Spi {
    type Error = FakeError;
}

impl SpiDevice for Spi {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), FakeError> {
        if self.fail {
            return Err(FakeError);
        }
        for op in ops {
            match op {
                Operation::Write(b) => {
                    assert_eq!(b.len(), 3, "frames are 24 bits");
                    self.written.push(super::bytes_frame([b[0], b[1], b[2]]));
                }
                Operation::Read(b) => {
                    let f = super::frame_bytes(self.replies.pop_front().unwrap_or(0));
                    b.copy_from_slice(&f);
                }
                Operation::Transfer(r, w) => {
                    self.written.push(super::bytes_frame([w[0], w[1], w[2]]));
                    let f = super::frame_bytes(self.replies.pop_front().unwrap_or(0));
                    r.copy_from_slice(&f);
                }
                Operation::TransferInPlace(b) => {
                    self.written.push(super::bytes_frame([b[0], b[1], b[2]]));
                    let f = super::frame_bytes(self.replies.pop_front().unwrap_or(0));
                    b.copy_from_slice(&f);
                }
                Operation::DelayNs(_) => {}
            }
        }
        Ok(())
    }
}

/// A pin that records its levels (true = high).
#[derive(Default)]
pub struct Pin {
    pub levels: Vec<bool>,
}
impl embedded_hal::digital::ErrorType for Pin {
    type Error = Infallible;
}
impl embedded_hal::digital::OutputPin for Pin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.levels.push(false);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.levels.push(true);
        Ok(())
    }
}
