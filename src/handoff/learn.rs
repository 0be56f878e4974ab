//! The learning samples' hand-off (loop tick → learner): a
//! single-producer single-consumer ring (see the module docs, `super`).

use crate::servo::repetitive::SAMPLE_WORDS;
use crate::servo::LearnSample;
use core::sync::atomic::{AtomicU32, Ordering};

/// Slots of the learning ring: the learner may fall this many ticks behind
/// (it runs after every tick on the boards).
pub const LEARN_QUEUE: usize = 8;

/// The learning samples in flight (see the module docs).
pub(crate) struct LearnQueue {
    slots: [[AtomicU32; SAMPLE_WORDS]; LEARN_QUEUE],
    /// Samples written (the tick's), and read (the learner's).
    head: AtomicU32,
    tail: AtomicU32,
    /// Samples the tick dropped (the ring was full), so far.
    lost: AtomicU32,
}

impl LearnQueue {
    pub(crate) const fn new() -> Self {
        Self {
            slots: [const { [const { AtomicU32::new(0) }; SAMPLE_WORDS] }; LEARN_QUEUE],
            head: AtomicU32::new(0),
            tail: AtomicU32::new(0),
            lost: AtomicU32::new(0),
        }
    }

    /// Appends a sample (the loop tick, the only writer); a full ring
    /// drops it and counts it lost.
    #[inline(always)]
    pub(crate) fn push(&self, s: &LearnSample) {
        let h = self.head.load(Ordering::Relaxed);
        if h.wrapping_sub(self.tail.load(Ordering::Acquire)) >= LEARN_QUEUE as u32 {
            let n = self.lost.load(Ordering::Relaxed);
            self.lost.store(n.wrapping_add(1), Ordering::Relaxed);
            return;
        }
        let slot = &self.slots[h as usize % LEARN_QUEUE];
        for (w, v) in slot.iter().zip(s.0) {
            w.store(v, Ordering::Relaxed);
        }
        self.head.store(h.wrapping_add(1), Ordering::Release);
    }

    /// Takes the oldest sample (the learner, the only reader).
    #[inline(always)]
    pub(crate) fn pop(&self) -> Option<LearnSample> {
        let t = self.tail.load(Ordering::Relaxed);
        if t == self.head.load(Ordering::Acquire) {
            return None;
        }
        let slot = &self.slots[t as usize % LEARN_QUEUE];
        let s = LearnSample(core::array::from_fn(|k| slot[k].load(Ordering::Relaxed)));
        self.tail.store(t.wrapping_add(1), Ordering::Release);
        Some(s)
    }

    /// Samples dropped so far (the learner compares it with the count it
    /// last saw).
    pub(crate) fn lost(&self) -> u32 {
        self.lost.load(Ordering::Relaxed)
    }
}
