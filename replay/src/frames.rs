//! What one SPI transaction sent and received, as the recorder's tap and
//! the player's device both see it: the written bytes of every operation in
//! order (MOSI), the read bytes of every operation in order (MISO), each as
//! a big-endian word of at most [`MAX_FRAME_BYTES`].

use crate::wire::MAX_FRAME_BYTES;
use embedded_hal::spi::Operation;

/// A frame of up to 3 bytes, or `None` when the operations carry more.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Frame {
    pub len: u8,
    pub word: u32,
}

impl Frame {
    fn push(&mut self, bytes: &[u8]) -> bool {
        for &b in bytes {
            if self.len >= MAX_FRAME_BYTES {
                return false;
            }
            self.word = (self.word << 8) | u32::from(b);
            self.len += 1;
        }
        true
    }
}

/// The bytes the operations write (before a `TransferInPlace` runs).
pub fn mosi(ops: &[Operation<'_, u8>]) -> Option<Frame> {
    let mut f = Frame::default();
    for op in ops {
        let ok = match op {
            Operation::Write(b) => f.push(b),
            Operation::TransferInPlace(b) => f.push(b),
            Operation::Transfer(_, w) => f.push(w),
            Operation::Read(_) | Operation::DelayNs(_) => true,
        };
        if !ok {
            return None;
        }
    }
    Some(f)
}

/// The bytes the operations read (after the transaction).
pub fn miso(ops: &[Operation<'_, u8>]) -> Option<Frame> {
    let mut f = Frame::default();
    for op in ops {
        let ok = match op {
            Operation::Read(b) => f.push(b),
            Operation::TransferInPlace(b) => f.push(b),
            Operation::Transfer(r, _) => f.push(r),
            Operation::Write(_) | Operation::DelayNs(_) => true,
        };
        if !ok {
            return None;
        }
    }
    Some(f)
}

/// Fills the operations' read buffers from `frame` (its bytes in order;
/// buffers beyond its length read 0).
pub fn fill_miso(ops: &mut [Operation<'_, u8>], frame: Frame) {
    let mut k = 0u8;
    let mut next = || {
        let b = if k < frame.len {
            (frame.word >> (8 * u32::from(frame.len - 1 - k))) as u8
        } else {
            0
        };
        k = k.saturating_add(1);
        b
    };
    for op in ops {
        match op {
            Operation::Read(b) | Operation::TransferInPlace(b) => {
                b.iter_mut().for_each(|x| *x = next())
            }
            Operation::Transfer(r, _) => r.iter_mut().for_each(|x| *x = next()),
            Operation::Write(_) | Operation::DelayNs(_) => {}
        }
    }
}
