//! Simulated converter chips at the level of their SPI frames (the formats
//! of `notes/COMMON.md` / `docs/PLANT.md`), as embedded-hal 1.0
//! `SpiDevice<u8>` and `OutputPin` implementations, with bus-error
//! injection. Each chip is a handle (the device the firmware's driver owns)
//! onto state shared with the rig (`Rc<RefCell<..>>`): single-threaded and
//! deterministic.
//!
//! SPI semantics, common to the three chips: one transaction = one chip
//! select assertion = one frame. The chip's output shift register (MISO) is
//! loaded when CS falls, from the state left by earlier frames; MOSI bytes
//! are decoded when CS rises. A frame that is not exactly 24 bits is
//! ignored and counted (`bad_frames`), as the parts abort a write when
//! SYNC/CS rises early.

pub mod ad4020;
pub mod ad5686;
pub mod ad5791;
pub mod pins;

pub use ad4020::{Ad4020State, SimAd4020};
pub use ad5686::{Ad5686State, SimAd5686, SimLdacPin};
pub use ad5791::{Ad5791State, SimAd5791};
pub use pins::{AmpControl, SimAmpEnablePin, SimClock};

use embedded_hal::spi::{ErrorKind, Operation};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::cell::Cell;
use std::collections::VecDeque;
use std::rc::Rc;

/// Simulation time shared by the scheduler and the chips, ns.
pub type SimTime = Rc<Cell<u64>>;

/// The error a simulated SPI transaction returns when a bus error is
/// injected (the host controller reported a fault: timeout, overrun).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimSpiError;

impl embedded_hal::spi::Error for SimSpiError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

/// One injected bus fault, applied to one transaction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BusFault {
    /// The transaction returns `Err(SimSpiError)`; the chip sees nothing.
    Error,
    /// MISO and MOSI stuck low for the frame (all-zero bytes both ways).
    StuckLow,
    /// MISO and MOSI stuck high for the frame (all-one bytes both ways).
    StuckHigh,
    /// Bit `n` (0 = LSB of the 24-bit frame) flipped on MISO.
    FlipMiso(u8),
    /// Bit `n` (0 = LSB of the 24-bit frame) flipped on MOSI.
    FlipMosi(u8),
    /// CS glitch: the chip ignores the frame, MISO reads 0; no error
    /// reported to the host (a silently lost write).
    Drop,
}

/// Bus faults to inject: a queue of faults for the next transactions, and
/// an optional seeded random rate.
#[derive(Clone, Debug, Default)]
pub struct FaultInjector {
    /// Faults applied to the next transactions in order (one each).
    pub queue: VecDeque<BusFault>,
    random: Option<(ChaCha8Rng, f64, BusFault)>,
    /// Faults applied so far.
    pub injected: u64,
}

impl FaultInjector {
    /// Queues `fault` for the next `n` transactions.
    pub fn inject(&mut self, fault: BusFault, n: usize) {
        self.queue.extend(std::iter::repeat_n(fault, n));
    }
    /// Applies `fault` to each transaction with probability `p`, seeded.
    pub fn random(&mut self, seed: u64, p: f64, fault: BusFault) {
        self.random = Some((ChaCha8Rng::seed_from_u64(seed), p, fault));
    }
    #[inline]
    pub(crate) fn next(&mut self) -> Option<BusFault> {
        if self.random.is_none() && self.queue.is_empty() {
            return None;
        }
        let f = self.queue.pop_front().or_else(|| match &mut self.random {
            Some((rng, p, f)) => (rng.random::<f64>() < *p).then_some(*f),
            None => None,
        });
        if f.is_some() {
            self.injected += 1;
        }
        f
    }
}

/// MOSI bytes of one frame (no allocation: frames longer than 8 bytes are
/// invalid anyway and only their length is kept).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Frame {
    pub bytes: [u8; 8],
    pub len: usize,
}

impl Frame {
    /// The 24-bit word when the frame is exactly three bytes.
    pub fn word24(&self) -> Option<u32> {
        (self.len == 3).then(|| {
            (u32::from(self.bytes[0]) << 16)
                | (u32::from(self.bytes[1]) << 8)
                | u32::from(self.bytes[2])
        })
    }
}

/// Runs the operations of one transaction against a 24-bit MISO word;
/// returns the MOSI bytes. Bytes past the third read as 0 on MISO.
#[inline]
pub(crate) fn shift(ops: &mut [Operation<'_, u8>], miso_word: u32) -> Frame {
    let miso = [
        (miso_word >> 16) as u8,
        (miso_word >> 8) as u8,
        miso_word as u8,
    ];
    let mut f = Frame::default();
    // Fast path: the drivers' usual frame is one 3-byte write or read.
    if let [op] = ops {
        match op {
            Operation::Write(buf) if buf.len() == 3 => {
                f.bytes[..3].copy_from_slice(buf);
                f.len = 3;
                return f;
            }
            Operation::Read(buf) if buf.len() == 3 => {
                buf.copy_from_slice(&miso);
                f.len = 3;
                return f;
            }
            _ => {}
        }
    }
    shift_general(ops, miso)
}

/// Any other shape of transaction, byte by byte (kept out of line so the
/// 3-byte fast path above inlines into the chips).
#[inline(never)]
fn shift_general(ops: &mut [Operation<'_, u8>], miso: [u8; 3]) -> Frame {
    let mut f = Frame::default();
    let push = |b: u8, f: &mut Frame| -> u8 {
        let out = miso.get(f.len).copied().unwrap_or(0);
        if let Some(slot) = f.bytes.get_mut(f.len) {
            *slot = b;
        }
        f.len += 1;
        out
    };
    for op in ops.iter_mut() {
        match op {
            Operation::Read(buf) => {
                for b in buf.iter_mut() {
                    *b = push(0, &mut f);
                }
            }
            Operation::Write(buf) => {
                for &b in buf.iter() {
                    push(b, &mut f);
                }
            }
            Operation::Transfer(read, write) => {
                let n = read.len().max(write.len());
                for k in 0..n {
                    let out = push(write.get(k).copied().unwrap_or(0), &mut f);
                    if let Some(r) = read.get_mut(k) {
                        *r = out;
                    }
                }
            }
            Operation::TransferInPlace(buf) => {
                for b in buf.iter_mut() {
                    *b = push(*b, &mut f);
                }
            }
            Operation::DelayNs(_) => {}
        }
    }
    f
}

/// Applies an injected fault around [`shift`]: returns the MOSI frame the
/// chip sees (`None`: the chip sees no frame) or the error.
#[inline]
pub(crate) fn faulty_shift(
    ops: &mut [Operation<'_, u8>],
    miso_word: u32,
    fault: Option<BusFault>,
) -> Result<Option<Frame>, SimSpiError> {
    // The fault-free frame is the per-tick common case (two per loop tick):
    // keep it inline in the chip's `transaction`, the injected faults out of line.
    match fault {
        None => Ok(Some(shift(ops, miso_word))),
        Some(f) => injected_shift(ops, miso_word, f),
    }
}

#[cold]
#[inline(never)]
fn injected_shift(
    ops: &mut [Operation<'_, u8>],
    miso_word: u32,
    fault: BusFault,
) -> Result<Option<Frame>, SimSpiError> {
    match fault {
        BusFault::Error => {
            fill_reads(ops, 0xFF);
            Err(SimSpiError)
        }
        BusFault::StuckLow => {
            let mut f = shift(ops, 0);
            f.bytes = [0; 8];
            Ok(Some(f))
        }
        BusFault::StuckHigh => {
            let mut f = shift(ops, 0xFF_FFFF);
            fill_reads(ops, 0xFF);
            f.bytes = [0xFF; 8];
            Ok(Some(f))
        }
        BusFault::FlipMiso(n) => Ok(Some(shift(ops, miso_word ^ (1 << (n % 24))))),
        BusFault::FlipMosi(n) => {
            let mut f = shift(ops, miso_word);
            if let Some(w) = f.word24() {
                let w = w ^ (1 << (n % 24));
                f.bytes[0] = (w >> 16) as u8;
                f.bytes[1] = (w >> 8) as u8;
                f.bytes[2] = w as u8;
            }
            Ok(Some(f))
        }
        BusFault::Drop => {
            shift(ops, 0);
            Ok(None)
        }
    }
}

fn fill_reads(ops: &mut [Operation<'_, u8>], v: u8) {
    for op in ops.iter_mut() {
        match op {
            Operation::Read(buf) | Operation::TransferInPlace(buf) => {
                buf.iter_mut().for_each(|b| *b = v)
            }
            Operation::Transfer(read, _) => read.iter_mut().for_each(|b| *b = v),
            _ => {}
        }
    }
}

/// Sign-extends a 20-bit two's complement field.
pub fn sext20(v: u32) -> i32 {
    (((v & 0xF_FFFF) << 12) as i32) >> 12
}
