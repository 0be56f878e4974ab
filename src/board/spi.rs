//! Blocking SPI master on the STM32H7 SPI block (RM0433 §50), as an
//! embedded-hal 1.0 `SpiDevice`: one bus, one chip select. The converters
//! need 24-bit frames; the device speaks bytes (three per frame, MSB first),
//! which is what the embedded-hal drivers in `zslide::drivers` expect.
//!
//! Each operation is one hardware transfer of known size (`TSIZE`), the
//! sequence ST's reference manual gives: load TSIZE with the block disabled,
//! enable, start, move bytes, wait for end of transfer, clear flags, disable.
//! Every wait is bounded; a converter that never answers is a bus error,
//! not a hung interrupt.

use core::convert::Infallible;
use core::ops::Deref;

use embedded_hal::digital::OutputPin;
use embedded_hal::spi::{ErrorKind, ErrorType, Operation, SpiDevice};
use stm32h7::stm32h743v::spi1::RegisterBlock;

/// CR1 bits.
const CR1_SPE: u32 = 1 << 0;
const CR1_CSTART: u32 = 1 << 9;
const CR1_SSI: u32 = 1 << 12;
/// SR bits.
const SR_RXP: u32 = 1 << 0;
const SR_TXP: u32 = 1 << 1;
const SR_EOT: u32 = 1 << 3;
const SR_OVR: u32 = 1 << 6;
/// IFCR: clear EOT, TXTF, UDR, OVR, CRCE, TIFRE, MODF, TSERF, SUSP.
const IFCR_ALL: u32 = 0xFF8;
/// Polls of a status flag before giving up: ≥ 25 µs at 400 MHz, against
/// 0.32 µs per byte at the slowest clock used here (25 MHz).
const POLL_LIMIT: u32 = 10_000;

/// SPI clock mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// CPOL = 0, CPHA = 0: sampled on rising SCK (AD4020).
    Mode0,
    /// CPOL = 0, CPHA = 1: sampled on falling SCK (AD5791, AD5686).
    Mode1,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpiError {
    /// A status flag did not come within the poll limit.
    Timeout,
    /// Received data overran the FIFO.
    Overrun,
}

impl embedded_hal::spi::Error for SpiError {
    fn kind(&self) -> ErrorKind {
        match self {
            SpiError::Timeout => ErrorKind::Other,
            SpiError::Overrun => ErrorKind::Overrun,
        }
    }
}

/// A chip select that the hardware drives itself (the AD4020's CNV comes
/// from the loop timer), so the device has nothing to do.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoCs;
impl embedded_hal::digital::ErrorType for NoCs {
    type Error = Infallible;
}
impl OutputPin for NoCs {
    fn set_low(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        Ok(())
    }
}

/// One SPI block (owned: the PAC's `SPIn` handle) and one chip select.
pub struct SpiDev<SPI, CS> {
    spi: SPI,
    cs: CS,
}

impl<SPI: Deref<Target = RegisterBlock>, CS: OutputPin> SpiDev<SPI, CS> {
    /// Configures `spi` as master, 8-bit frames, kernel clock divided by
    /// `2^(mbr+1)`, and takes the chip select (driven high = idle).
    pub fn new(spi: SPI, mbr: u8, mode: Mode, mut cs: CS) -> Self {
        let _ = cs.set_high();
        // SAFETY (all four writes): raw register values on an SPI block that
        // this device owns from now on, with SPE clear as RM0433 requires
        // for CFG1/CFG2. CFG1: MBR = mbr (≤ 7), DSIZE = 7 (8 bits), FIFO
        // threshold 1. CFG2: AFCNTR (keep driving SCK/MOSI while disabled),
        // SSM (software NSS) + MASTER, CPHA per mode, full duplex, MSB first.
        // CR1: SSI high so the master never sees a mode fault.
        unsafe {
            spi.cr1().write(|w| w.bits(CR1_SSI));
            spi.cfg1().write(|w| w.bits((u32::from(mbr & 7) << 28) | 7));
            let cpha = match mode {
                Mode::Mode0 => 0,
                Mode::Mode1 => 1 << 24,
            };
            spi.cfg2()
                .write(|w| w.bits((1 << 31) | (1 << 26) | (1 << 22) | cpha));
            spi.ifcr().write(|w| w.bits(IFCR_ALL));
        }
        Self { spi, cs }
    }

    fn wait(&self, flag: u32) -> Result<(), SpiError> {
        for _ in 0..POLL_LIMIT {
            let sr = self.spi.sr().read().bits();
            if sr & SR_OVR != 0 {
                return Err(SpiError::Overrun);
            }
            if sr & flag != 0 {
                return Ok(());
            }
        }
        Err(SpiError::Timeout)
    }

    /// One hardware transfer of `n` bytes: `out(i)` gives byte i to send,
    /// `inp(i, b)` takes byte i received.
    fn exchange(
        &mut self,
        n: usize,
        mut out: impl FnMut(usize) -> u8,
        mut inp: impl FnMut(usize, u8),
    ) -> Result<(), SpiError> {
        if n == 0 {
            return Ok(());
        }
        // TSIZE is 16 bits; longer operations go in several transfers.
        let mut done = 0;
        while done < n {
            let chunk = (n - done).min(0xFFFF);
            // SAFETY: CR1/CR2/IFCR/TXDR8 of the SPI block this device owns;
            // TSIZE is written with SPE clear, then the transfer started.
            unsafe {
                self.spi.cr1().write(|w| w.bits(CR1_SSI));
                self.spi.cr2().write(|w| w.bits(chunk as u32));
                self.spi.cr1().write(|w| w.bits(CR1_SSI | CR1_SPE));
                self.spi
                    .cr1()
                    .write(|w| w.bits(CR1_SSI | CR1_SPE | CR1_CSTART));
            }
            let mut result = Ok(());
            for i in done..done + chunk {
                result = self.wait(SR_TXP);
                if result.is_err() {
                    break;
                }
                // SAFETY: TXDR8 accepts any byte once TXP is set.
                unsafe { self.spi.txdr8().write(|w| w.bits(out(i))) };
                result = self.wait(SR_RXP);
                if result.is_err() {
                    break;
                }
                inp(i, self.spi.rxdr8().read().bits());
            }
            if result.is_ok() {
                result = self.wait(SR_EOT);
            }
            // SAFETY: clearing status flags and disabling the block are
            // always allowed; this also ends a transfer abandoned above.
            unsafe {
                self.spi.ifcr().write(|w| w.bits(IFCR_ALL));
                self.spi.cr1().write(|w| w.bits(CR1_SSI));
            }
            result?;
            done += chunk;
        }
        Ok(())
    }
}

impl<SPI, CS> ErrorType for SpiDev<SPI, CS> {
    type Error = SpiError;
}

impl<SPI: Deref<Target = RegisterBlock>, CS: OutputPin> SpiDevice<u8> for SpiDev<SPI, CS> {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), SpiError> {
        let _ = self.cs.set_low();
        let mut result = Ok(());
        for op in operations.iter_mut() {
            result = match op {
                Operation::Read(buf) => {
                    let n = buf.len();
                    self.exchange(
                        n,
                        |_| 0,
                        |i, b| {
                            if let Some(slot) = buf.get_mut(i) {
                                *slot = b;
                            }
                        },
                    )
                }
                Operation::Write(buf) => {
                    let n = buf.len();
                    self.exchange(n, |i| buf.get(i).copied().unwrap_or(0), |_, _| {})
                }
                Operation::Transfer(read, write) => {
                    let n = read.len().max(write.len());
                    self.exchange(
                        n,
                        |i| write.get(i).copied().unwrap_or(0),
                        |i, b| {
                            if let Some(slot) = read.get_mut(i) {
                                *slot = b;
                            }
                        },
                    )
                }
                Operation::TransferInPlace(buf) => {
                    let n = buf.len();
                    // One byte per transfer: each byte is sent before the
                    // reply overwrites it.
                    let mut res = Ok(());
                    for i in 0..n {
                        let b = buf.get(i).copied().unwrap_or(0);
                        let mut got = 0;
                        res = self.exchange(1, |_| b, |_, r| got = r);
                        if res.is_err() {
                            break;
                        }
                        if let Some(slot) = buf.get_mut(i) {
                            *slot = got;
                        }
                    }
                    res
                }
                Operation::DelayNs(ns) => {
                    // 400 cycles per µs at the 400 MHz core clock.
                    cortex_m::asm::delay(ns.saturating_mul(2) / 5);
                    Ok(())
                }
            };
            if result.is_err() {
                break;
            }
        }
        let _ = self.cs.set_high();
        result
    }
}
