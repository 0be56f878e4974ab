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
//! Three hand-offs carry a value from one priority to another, all through
//! one mechanism, the two-slot seqlock of [`seqlock`] (one writer, readers
//! that may preempt it; a reader never sees a torn value and never waits):
//!
//! * Coefficients (X event → loop tick and the learning handler,
//!   [`coeffs`]): X, the live columns and their values at X. The loop tick
//!   reads only X and the null flag on every set, and copies the values
//!   only when it evaluates the command itself (a stale expansion,
//!   [`ahead`]); the handler below it copies every set. A set overwritten
//!   while read is taken as null until the next.
//! * Index (index event → loop tick, [`Shared::index_event`]): the
//!   `(count at index, edge time)` pair; the loop tick applies it to the
//!   estimator at its next tick (≤ one loop period later: the phase is taken
//!   from the hardware-latched count and edge time, so the delay costs no
//!   accuracy). More than one index within one loop period, or a pair
//!   overwritten while read, is [`Fault::IndexExtra`].
//! * The command ahead of the tick (learning handler → loop tick,
//!   [`ahead`]): the expansion and the learned correction at the angle the
//!   tick posted (its request is four plain words).
//!
//! A lock (critical section) would instead delay the loop tick by a whole
//! X event; RTIC ceilings would tie the core to one framework; the seqlock
//! costs a few instructions per tick.
//! * Faults found by the X handler (X outside the table, glitch storm, bad
//!   BCD, coefficient-DAC bus error) are set as bits of one atomic word; the
//!   loop tick latches them at its next tick and reacts.
//!
//! `firmware::Firmware` bundles the three for single-threaded users (host tests,
//! `host-sim`): its methods call the parts with its own [`Shared`]. The
//! boards take the parts apart (`Firmware::into_parts`) and give each
//! handler its own through a [`handover::Handover`] (once, at boot), with a
//! `static` [`Shared`].
//!
//! * Operator requests (arm, disarm, clear a fault; [`Request`]) are bits of
//!   one atomic word any priority may set; the loop tick takes them all at
//!   its next tick.
//! * Learning (loop tick → learner, `crate::firmware::learning`, [`learn`]):
//!   each tick's [`LearnSample`](crate::servo::LearnSample) goes into a
//!   single-producer single-consumer ring of [`learn::LEARN_QUEUE`] slots (the tick writes a slot, then publishes it with
//!   one `Release` store of its head index; the learner reads the slots up
//!   to it and frees them with one `Release` store of its tail index). A
//!   full ring drops the sample and counts it lost; the learner, seeing the
//!   count change, restarts its bin accounting. The learned table itself
//!   ([`LearnedTable`]) is atomic words: the tick reads bins the learner
//!   is not writing (see `servo::repetitive`).

pub mod ahead;
pub(crate) mod coeffs;
pub mod handover;
pub mod learn;
pub(crate) mod seqlock;

use crate::safety::{Device, Fault};
use crate::servo::LearnedTable;
use ahead::AheadHandoff;
use coeffs::CoeffHandoff;
use core::sync::atomic::{AtomicU32, Ordering};
use learn::LearnQueue;
use seqlock::Seqlock;

/// Fault bits of the handlers below the tick ([`Shared::x_faults`]): the
/// X handler's (0..3) and contour monitoring's (4..7, the learning
/// handler's: `servo::monitor`).
pub(crate) const XF_OUTSIDE: u32 = 1 << 0;
pub(crate) const XF_STORM: u32 = 1 << 1;
pub(crate) const XF_BCD: u32 = 1 << 2;
pub(crate) const XF_QUAD_BUS: u32 = 1 << 3;
pub(crate) const XF_DEPTH: u32 = 1 << 4;
pub(crate) const XF_OSCILLATION: u32 = 1 << 5;
pub(crate) const XF_GAUGE_FROZEN: u32 = 1 << 6;
pub(crate) const XF_X_STALLED: u32 = 1 << 7;
/// Contour monitoring's bits: lowered at every arming, so that a fault
/// raised again after a clear is a new bit for the tick.
pub(crate) const XF_MONITOR: u32 = XF_DEPTH | XF_OSCILLATION | XF_GAUGE_FROZEN | XF_X_STALLED;

pub(crate) fn x_fault_bit(f: Fault) -> u32 {
    match f {
        Fault::XOutsideTable => XF_OUTSIDE,
        Fault::XBadBcd => XF_BCD,
        Fault::Bus(Device::CoefficientDac) => XF_QUAD_BUS,
        Fault::DepthGuard => XF_DEPTH,
        Fault::Oscillation => XF_OSCILLATION,
        Fault::GaugeFrozen => XF_GAUGE_FROZEN,
        Fault::XStalled => XF_X_STALLED,
        // Every other fault the X path can meet is a storm of some kind.
        _ => XF_STORM,
    }
}

pub(crate) const X_FAULTS: [(u32, Fault); 8] = [
    (XF_OUTSIDE, Fault::XOutsideTable),
    (XF_STORM, Fault::XGlitchStorm),
    (XF_BCD, Fault::XBadBcd),
    (XF_QUAD_BUS, Fault::Bus(Device::CoefficientDac)),
    (XF_DEPTH, Fault::DepthGuard),
    (XF_OSCILLATION, Fault::Oscillation),
    (XF_GAUGE_FROZEN, Fault::GaugeFrozen),
    (XF_X_STALLED, Fault::XStalled),
];

/// The data that crosses priorities (see the module docs): written by the
/// X/index handlers, read by the loop tick. `const`-constructible, so a
/// board can keep it in a `static`.
pub struct Shared {
    /// The coefficient sets (X handler → loop tick, learning handler).
    coeff: CoeffHandoff,
    /// The index pulses: `[count at index, edge ticks]` (index handler →
    /// loop tick).
    index: Seqlock<2>,
    /// Fault bits of the X handler, latched by the loop tick.
    x_faults: AtomicU32,
    x_accepted: AtomicU32,
    x_ignored: AtomicU32,
    /// Operator requests ([`Request`] bits), taken by the next loop tick.
    requests: AtomicU32,
    /// The learned correction table (written by the learner).
    learned: LearnedTable,
    /// The tick's samples for the learner.
    learn: LearnQueue,
    /// The command evaluated ahead of the tick (`ahead`).
    ahead: AheadHandoff,
}

/// One index pulse as the loop tick takes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct IndexPulse {
    pub(crate) count_at_index: u32,
    pub(crate) edge_ticks: u32,
    /// More than one pulse since the last taken (within one loop period).
    pub(crate) missed: bool,
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
            coeff: CoeffHandoff::new(),
            index: Seqlock::new([0; 2]),
            x_faults: AtomicU32::new(0),
            x_accepted: AtomicU32::new(0),
            x_ignored: AtomicU32::new(0),
            requests: AtomicU32::new(0),
            learned: LearnedTable::new(),
            learn: LearnQueue::new(),
            ahead: AheadHandoff::new(),
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
        self.index.generation()
    }
    /// Coefficient sets published so far.
    pub fn coefficient_generation(&self) -> u32 {
        self.coeff.generation()
    }
    /// The once-per-revolution index, published for the loop tick: the
    /// encoder count at the edge (ignored with a tachometer) and the edge's
    /// timestamp. Needs no handler state, so an index interrupt can call it
    /// on a `static` [`Shared`] directly. One writer (one priority level).
    #[inline(always)]
    pub fn index_event(&self, edge_ticks: u32, count_at_index: u32) {
        let s = self.index.generation().wrapping_add(1);
        let w = self.index.begin(s);
        w[0].store(count_at_index, Ordering::Relaxed);
        w[1].store(edge_ticks, Ordering::Relaxed);
        self.index.publish(s);
    }
    /// The newest index pulse if its sequence is not `seen` (the loop
    /// tick, which then has seen it); `Err` when the writer overwrote it
    /// while read (pulses faster than the loop rate).
    #[inline(always)]
    pub(crate) fn take_index(&self, seen: &mut u32) -> Result<Option<IndexPulse>, ()> {
        let s = self.index.latest();
        if s == *seen {
            return Ok(None);
        }
        let missed = s.wrapping_sub(*seen) > 1;
        let read = self.index.read(s, |w| {
            (w[0].load(Ordering::Relaxed), w[1].load(Ordering::Relaxed))
        });
        *seen = s;
        match read {
            Ok((count_at_index, edge_ticks)) => Ok(Some(IndexPulse {
                count_at_index,
                edge_ticks,
                missed,
            })),
            Err(_) => Err(()),
        }
    }
    /// The index pulses' seqlock (a writer's single steps, in tests).
    #[cfg(test)]
    pub(crate) fn index_lock(&self) -> &Seqlock<2> {
        &self.index
    }
    /// The coefficient sets' hand-off.
    #[inline(always)]
    pub(crate) fn coefficients(&self) -> &CoeffHandoff {
        &self.coeff
    }
    /// The hand-off of the command ahead of the tick.
    #[inline(always)]
    pub(crate) fn ahead(&self) -> &AheadHandoff {
        &self.ahead
    }
    /// The learning samples' ring.
    #[inline(always)]
    pub(crate) fn learn_queue(&self) -> &LearnQueue {
        &self.learn
    }
    /// The X handler's fault bits so far (the loop tick latches new ones).
    #[inline(always)]
    pub(crate) fn x_faults(&self) -> u32 {
        self.x_faults.load(Ordering::Relaxed)
    }
    /// Sets the X handler's bit for `f`.
    pub(crate) fn raise(&self, f: Fault) {
        self.x_faults.fetch_or(x_fault_bit(f), Ordering::Relaxed);
    }
    /// Lowers contour monitoring's bits (the learning handler, at an
    /// arming: its faults are raised once per arming).
    pub(crate) fn lower_monitor(&self) {
        self.x_faults.fetch_and(!XF_MONITOR, Ordering::Relaxed);
    }
    /// Counts an accepted legacy X event (the X handler, the only writer:
    /// a load and a store, no read-modify-write loop).
    #[inline(always)]
    pub(crate) fn count_x_accepted(&self) {
        let n = self.x_accepted.load(Ordering::Relaxed);
        self.x_accepted.store(n.wrapping_add(1), Ordering::Relaxed);
    }
    /// Counts a debounced legacy X event (the X handler, the only writer).
    #[inline(always)]
    pub(crate) fn count_x_ignored(&self) {
        let n = self.x_ignored.load(Ordering::Relaxed);
        self.x_ignored.store(n.wrapping_add(1), Ordering::Relaxed);
    }
    /// Whether an operator request waits (the loop tick, every tick).
    #[inline(always)]
    pub(crate) fn requests_pending(&self) -> bool {
        self.requests.load(Ordering::Relaxed) != 0
    }
    /// Takes every waiting operator request ([`Request::bit`]s).
    #[inline(always)]
    pub(crate) fn take_requests(&self) -> u32 {
        self.requests.swap(0, Ordering::Acquire)
    }
}

impl Default for Shared {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each fault of the word (the X handler's and contour monitoring's)
    /// has its own single bit, and `x_fault_bit` names it: a word holding
    /// two faults at once says both. Contour monitoring's are the bits an
    /// arming lowers, and only those.
    #[test]
    fn each_x_fault_has_its_own_bit() {
        let mut seen = 0u32;
        for (bit, f) in X_FAULTS {
            assert_eq!(bit.count_ones(), 1, "{f:?}");
            assert_eq!(seen & bit, 0, "{f:?} shares a bit");
            assert_eq!(x_fault_bit(f), bit, "{f:?}");
            seen |= bit;
        }
        assert_eq!(seen, 0xff);
        assert_eq!(XF_MONITOR, 0xf0);
    }

    /// The X handler's raised faults are read back as their bits, all of
    /// them: X outside the table (bit 0) and bad BCD (bit 2) raised are
    /// 0b101.
    #[test]
    fn raised_x_faults_read_back_as_their_bits() {
        let s = Shared::new();
        assert_eq!(s.x_faults(), 0);
        s.raise(Fault::XOutsideTable);
        s.raise(Fault::XBadBcd);
        assert_eq!(s.x_faults(), 0b101);
    }

    /// The X handler's counts read back as counted: 3 accepted, 2
    /// debounced.
    #[test]
    fn the_x_event_counts_read_back_as_counted() {
        let s = Shared::new();
        for _ in 0..3 {
            s.count_x_accepted();
        }
        for _ in 0..2 {
            s.count_x_ignored();
        }
        assert_eq!((s.x_accepted(), s.x_ignored()), (3, 2));
    }

    /// Each operator request waits as its own bit (arm 1, disarm 2, clear
    /// 4, the bits the loop tick decodes) until the tick takes them all at
    /// once; none waits after.
    #[test]
    fn posted_requests_wait_as_their_own_bits_until_taken() {
        let s = Shared::new();
        assert!(!s.requests_pending());
        s.request(Request::Arm);
        s.request(Request::ClearFault);
        assert!(s.requests_pending());
        assert_eq!(s.take_requests(), 0b101);
        assert!(!s.requests_pending());
        assert_eq!(s.take_requests(), 0);
        s.request(Request::Disarm);
        assert_eq!(s.take_requests(), 0b010);
    }
}
