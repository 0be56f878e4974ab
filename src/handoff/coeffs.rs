//! The coefficient set's slot of the hand-off (X event → loop tick and the
//! handler below it): the seqlock of the module docs (`super`).

use crate::command::COLS;
use core::sync::atomic::{AtomicI32, AtomicU32};

/// One published coefficient set: the column values at X, all the loop
/// tick evaluates (Z and its φ-derivatives; the changes across the grid
/// interval, for ∂Z/∂X, are not needed there and are not carried).
pub(crate) struct CoeffSlot {
    pub(crate) value: [AtomicI32; COLS],
    pub(crate) x: AtomicI32,
    /// Live columns, or [`NULL_META`] for the null command.
    pub(crate) meta: AtomicU32,
    /// Generation being written into / held by this slot; stored before the
    /// data, so a reader that finds it unchanged after copying has a
    /// complete set (the seqlock rule).
    pub(crate) seq: AtomicU32,
}

pub(crate) const NULL_META: u32 = 1 << 31;

impl CoeffSlot {
    pub(crate) const fn new() -> Self {
        Self {
            value: [const { AtomicI32::new(0) }; COLS],
            x: AtomicI32::new(0),
            meta: AtomicU32::new(NULL_META),
            seq: AtomicU32::new(0),
        }
    }
}
