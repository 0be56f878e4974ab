//! The hand-off between interrupt priorities: lock-free, atomics only.
//!
//! # Priorities
//!
//! The loop tick runs at the highest priority; the X and index events run
//! below it (one level, so they never preempt each other) and are preempted
//! by it. The state is split by owner: `LoopState` belongs to the
//! loop-tick handler, `EventState` to the X/index handlers, and the only
//! data they share is [`Shared`]: atomics, no locks, no masking.
//!
//! * Coefficients (X event → loop tick): a double buffer of atomic words and
//!   a generation counter. The X handler writes the whole coefficient set
//!   into the slot of generation + 1 (modulo 2) — first that slot's own
//!   sequence word, a release fence, then the data — and publishes it with
//!   one `Release` store of the generation. The loop tick compares the
//!   generation (one load per tick) and copies the slot only when it
//!   changed; after an acquire fence it keeps the copy only if the slot's
//!   sequence word still equals the generation (the seqlock rule), else it
//!   takes the next one. On a single core where the tick preempts the X
//!   handler, the slot being written is never the published one and the
//!   tick runs to completion before the handler resumes, so the check never
//!   fails there; it makes the scheme correct under real concurrency too (a
//!   host test with two threads finds torn sets without it). A lock
//!   (critical section) would instead delay the loop tick by a whole X
//!   event; RTIC ceilings would tie the core to one framework; this costs a
//!   few instructions per tick.
//! * Index (index event → loop tick, [`Shared::index_event`]): the same
//!   two-slot scheme for the `(count at index, edge time)` pair; the loop tick applies it to the
//!   estimator at its next tick (≤ one loop period later: the phase is taken
//!   from the hardware-latched count and edge time, so the delay costs no
//!   accuracy). More than one index within one loop period is
//!   [`Fault::IndexExtra`].
//! * Faults found by the X handler (X outside the table, glitch storm, bad
//!   BCD, coefficient-DAC bus error) are set as bits of one atomic word; the
//!   loop tick latches them at its next tick and reacts.
//!
//! `firmware::Firmware` bundles the three for single-threaded users (host tests,
//! `host-sim`): its methods call the parts with its own [`Shared`]. The
//! boards take the parts apart (`Firmware::into_parts`) and give each
//! handler its own, with a `static` [`Shared`].
//!
//! * Operator requests (arm, disarm, clear a fault; [`Request`]) are bits of
//!   one atomic word any priority may set; the loop tick takes them all at
//!   its next tick.
//! * Learning (loop tick → learner, `crate::learning`): each tick's
//!   [`LearnSample`] goes into a single-producer single-consumer ring of
//!   [`LEARN_QUEUE`] slots (the tick writes a slot, then publishes it with
//!   one `Release` store of its head index; the learner reads the slots up
//!   to it and frees them with one `Release` store of its tail index). A
//!   full ring drops the sample and counts it lost; the learner, seeing the
//!   count change, restarts its bin accounting. The learned table itself
//!   ([`LearnedTable`]) is atomic words: the tick reads bins the learner
//!   is not writing (see `servo::repetitive`).

use crate::config::COLS;
use crate::safety::{Device, Fault};
use crate::servo::{LearnSample, LearnedTable};
use core::sync::atomic::{fence, AtomicI32, AtomicU32, Ordering};

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

/// Fault bits of the X handler ([`Shared::x_faults`]).
pub(crate) const XF_OUTSIDE: u32 = 1 << 0;
pub(crate) const XF_STORM: u32 = 1 << 1;
pub(crate) const XF_BCD: u32 = 1 << 2;
pub(crate) const XF_QUAD_BUS: u32 = 1 << 3;

pub(crate) fn x_fault_bit(f: Fault) -> u32 {
    match f {
        Fault::XOutsideTable => XF_OUTSIDE,
        Fault::XBadBcd => XF_BCD,
        Fault::Bus(Device::CoefficientDac) => XF_QUAD_BUS,
        // Every other fault the X path can meet is a storm of some kind.
        _ => XF_STORM,
    }
}

pub(crate) const X_FAULTS: [(u32, Fault); 4] = [
    (XF_OUTSIDE, Fault::XOutsideTable),
    (XF_STORM, Fault::XGlitchStorm),
    (XF_BCD, Fault::XBadBcd),
    (XF_QUAD_BUS, Fault::Bus(Device::CoefficientDac)),
];

/// The data that crosses priorities (see the module docs): written by the
/// X/index handlers, read by the loop tick. `const`-constructible, so a
/// board can keep it in a `static`.
pub struct Shared {
    pub(crate) coeff_gen: AtomicU32,
    pub(crate) coeff: [CoeffSlot; 2],
    pub(crate) index_seq: AtomicU32,
    /// `[count at index, edge ticks, sequence]` per slot.
    pub(crate) index: [[AtomicU32; 3]; 2],
    pub(crate) x_faults: AtomicU32,
    pub(crate) x_accepted: AtomicU32,
    pub(crate) x_ignored: AtomicU32,
    /// Operator requests ([`Request`] bits), taken by the next loop tick.
    pub(crate) requests: AtomicU32,
    /// The learned correction table (written by the learner).
    pub(crate) learned: LearnedTable,
    pub(crate) learn: LearnQueue,
}

/// Slots of the learning ring: the learner may fall this many ticks behind
/// (it runs after every tick on the boards).
pub const LEARN_QUEUE: usize = 8;

/// The learning samples in flight (see the module docs).
pub(crate) struct LearnQueue {
    slots: [[AtomicU32; 4]; LEARN_QUEUE],
    /// Samples written (the tick's), and read (the learner's).
    head: AtomicU32,
    tail: AtomicU32,
    /// Samples the tick dropped (the ring was full), so far.
    lost: AtomicU32,
}

impl LearnQueue {
    const fn new() -> Self {
        Self {
            slots: [const { [const { AtomicU32::new(0) }; 4] }; LEARN_QUEUE],
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

/// What the operator (a switch, the host link, host-sim) asks of the loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Request {
    /// Sign check, then bumpless engagement on the table command.
    Arm,
    /// Ramp to null, then disable the amplifier.
    Disarm,
    /// Clear the latched fault (refused while its cause is present or the
    /// loop is armed).
    ClearFault,
}

impl Request {
    pub(crate) const fn bit(self) -> u32 {
        match self {
            Request::Arm => 1,
            Request::Disarm => 2,
            Request::ClearFault => 4,
        }
    }
}

impl Shared {
    pub const fn new() -> Self {
        Self {
            coeff_gen: AtomicU32::new(0),
            coeff: [CoeffSlot::new(), CoeffSlot::new()],
            index_seq: AtomicU32::new(0),
            index: [
                [AtomicU32::new(0), AtomicU32::new(0), AtomicU32::new(0)],
                [AtomicU32::new(0), AtomicU32::new(0), AtomicU32::new(0)],
            ],
            x_faults: AtomicU32::new(0),
            x_accepted: AtomicU32::new(0),
            x_ignored: AtomicU32::new(0),
            requests: AtomicU32::new(0),
            learned: LearnedTable::new(),
            learn: LearnQueue::new(),
        }
    }
    /// The learned correction table (reports: its peak, a snapshot).
    pub fn learned(&self) -> &LearnedTable {
        &self.learned
    }
    /// Posts an operator request for the next loop tick (any priority,
    /// lock-free).
    pub fn request(&self, r: Request) {
        self.requests.fetch_or(r.bit(), Ordering::Release);
    }
    /// Legacy X events accepted (an update published) so far.
    pub fn x_accepted(&self) -> u32 {
        self.x_accepted.load(Ordering::Relaxed)
    }
    /// Legacy X events debounced (same half-mil state) so far.
    pub fn x_ignored(&self) -> u32 {
        self.x_ignored.load(Ordering::Relaxed)
    }
    /// Index events received so far.
    pub fn index_events(&self) -> u32 {
        self.index_seq.load(Ordering::Relaxed)
    }
    /// Coefficient sets published so far.
    pub fn coefficient_generation(&self) -> u32 {
        self.coeff_gen.load(Ordering::Relaxed)
    }
    /// The once-per-revolution index, published for the loop tick: the
    /// encoder count at the edge (ignored with a tachometer) and the edge's
    /// timestamp. Needs no handler state, so an index interrupt can call it
    /// on a `static` [`Shared`] directly. One writer (one priority level).
    #[inline(always)]
    pub fn index_event(&self, edge_ticks: u32, count_at_index: u32) {
        let s = self.index_seq.load(Ordering::Relaxed).wrapping_add(1);
        let slot = &self.index[(s & 1) as usize];
        slot[2].store(s, Ordering::Relaxed);
        fence(Ordering::Release);
        slot[0].store(count_at_index, Ordering::Relaxed);
        slot[1].store(edge_ticks, Ordering::Relaxed);
        self.index_seq.store(s, Ordering::Release);
    }
    pub(crate) fn raise(&self, f: Fault) {
        self.x_faults.fetch_or(x_fault_bit(f), Ordering::Relaxed);
    }
}

impl Default for Shared {
    fn default() -> Self {
        Self::new()
    }
}
