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
//!   one `Release` store of the generation. A reader compares the
//!   generation (one load per tick) and copies the slot only when it
//!   changed; after an acquire fence it keeps the copy only if the slot's
//!   sequence word still equals the generation (the seqlock rule), else it
//!   takes the next one. The loop tick reads only X and the null flag this
//!   way on every set, and copies the values only when it evaluates the
//!   command itself (a stale expansion, `crate::handoff::ahead`); the handler below
//!   it copies every set. On a single core where the tick preempts the X
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
//! * Learning (loop tick → learner, `crate::firmware::learning`): each tick's
//!   [`LearnSample`] goes into a single-producer single-consumer ring of
//!   [`LEARN_QUEUE`] slots (the tick writes a slot, then publishes it with
//!   one `Release` store of its head index; the learner reads the slots up
//!   to it and frees them with one `Release` store of its tail index). A
//!   full ring drops the sample and counts it lost; the learner, seeing the
//!   count change, restarts its bin accounting. The learned table itself
//!   ([`LearnedTable`]) is atomic words: the tick reads bins the learner
//!   is not writing (see `servo::repetitive`).

pub mod ahead;
pub(crate) mod coeffs;

pub(crate) use coeffs::{CoeffSlot, NULL_META};

use crate::command::{Coefficients, COLS};
use crate::safety::{Device, Fault};
use crate::servo::{LearnSample, LearnedTable};
use crate::units::XInches;
use ahead::AheadHandoff;
use core::sync::atomic::{fence, AtomicU32, Ordering};

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
    /// The command evaluated ahead of the tick (`crate::handoff::ahead`).
    pub(crate) ahead: AheadHandoff,
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
    /// The seqlock reader of the module docs, once for both takers: when
    /// the newest coefficient set's generation is not `seen`, `read` gets
    /// its slot, meta word and X between the generation and the slot's
    /// sequence check. A set overwritten while read (a writer that
    /// preempts the reader) returns `Err` with its X and leaves `seen`, so
    /// the next call takes the next one.
    #[inline(always)]
    fn read_coefficients<R>(
        &self,
        seen: &mut u32,
        read: impl FnOnce(&CoeffSlot, u32, XInches) -> R,
    ) -> Result<Option<R>, XInches> {
        let g = self.coeff_gen.load(Ordering::Acquire);
        if g == *seen {
            return Ok(None);
        }
        let slot = &self.coeff[(g & 1) as usize];
        let meta = slot.meta.load(Ordering::Relaxed);
        let x = XInches::from_bits(slot.x.load(Ordering::Relaxed));
        let r = read(slot, meta, x);
        fence(Ordering::Acquire);
        if slot.seq.load(Ordering::Relaxed) == g {
            *seen = g;
            Ok(Some(r))
        } else {
            Err(x)
        }
    }

    /// Copies the latest coefficient set into `c` when its generation is
    /// not `seen`. Returns the set's X when one was taken; a set
    /// overwritten while copied leaves `c` null and `seen` unchanged, and
    /// returns `Err` with its X.
    #[inline(always)]
    pub(crate) fn take_coefficients(
        &self,
        seen: &mut u32,
        c: &mut Coefficients,
    ) -> Result<Option<XInches>, XInches> {
        let taken = self.read_coefficients(seen, |slot, meta, x| {
            if meta & NULL_META != 0 {
                c.set_null(x);
            } else {
                let n = (meta as usize).min(COLS);
                for (v, sv) in c.value.iter_mut().zip(slot.value.iter()).take(n) {
                    *v = sv.load(Ordering::Relaxed);
                }
                c.set_live(n as u8, x);
            }
            x
        });
        if let Err(x) = taken {
            c.set_null(x);
        }
        taken
    }

    /// Takes the X and the null flag of the newest coefficient set, not
    /// its values, if its generation is not `seen`: what the loop tick
    /// needs on every set, where the values serve only its fallback
    /// evaluation. A set overwritten while read returns `Err` with its X
    /// and leaves `seen`.
    #[inline(always)]
    pub(crate) fn take_coefficient_x(
        &self,
        seen: &mut u32,
    ) -> Result<Option<(XInches, bool)>, XInches> {
        self.read_coefficients(seen, |_, meta, x| (x, meta & NULL_META != 0))
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

/// The hand-offs under the board's preemption, step by step: the loop tick
/// (the reader, highest priority) may run to completion between any two
/// stores of a writer (the X or index handler), never the other way. The
/// writer's steps follow the protocol of the module docs and
/// `xevent::EventState::publish` / [`Shared::index_event`] store for store
/// (a test checks that a publication by the real writer leaves the same
/// words); the reader is the real `LoopState::take_published`.
#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod preemption_tests {
    extern crate std;

    use super::*;
    use crate::firmware::looptick::{Estimator, LoopState};
    use crate::servo::ServoDesign;
    use crate::spindle::{EdgeStamps, EncoderAngle, EncoderConfig};
    use crate::units::{SpindleAngle, XInches};
    use proptest::prelude::*;
    use std::format;
    use std::vec::Vec;

    /// One coefficient set as the X handler publishes it.
    #[derive(Clone, Debug)]
    struct Set {
        x: i32,
        null: bool,
        terms: usize,
        value: [i32; COLS],
    }

    #[derive(Clone, Copy, Debug)]
    enum Step {
        Seq,
        X,
        Value(usize),
        Meta,
        Gen,
    }

    /// The stores of one publication, in the writer's order: the slot's
    /// sequence word (then the release fence), X, the columns, the meta
    /// word, and last the generation.
    fn steps(s: &Set) -> Vec<Step> {
        let mut v = std::vec![Step::Seq, Step::X];
        if !s.null {
            for i in 0..s.terms {
                v.push(Step::Value(i));
            }
        }
        v.push(Step::Meta);
        v.push(Step::Gen);
        v
    }

    fn store(sh: &Shared, g: u32, s: &Set, step: Step) {
        let slot = &sh.coeff[(g & 1) as usize];
        match step {
            Step::Seq => {
                slot.seq.store(g, Ordering::Relaxed);
                fence(Ordering::Release);
            }
            Step::X => slot.x.store(s.x, Ordering::Relaxed),
            Step::Value(i) => slot.value[i].store(s.value[i], Ordering::Relaxed),
            Step::Meta => slot.meta.store(
                if s.null { NULL_META } else { s.terms as u32 },
                Ordering::Relaxed,
            ),
            Step::Gen => sh.coeff_gen.store(g, Ordering::Release),
        }
    }

    fn loop_state() -> LoopState {
        let cfg = ServoDesign::brief(20_000).config().unwrap();
        let mut lp = LoopState::new(cfg);
        lp.x_published = true;
        lp
    }

    fn set() -> impl Strategy<Value = Set> {
        (
            any::<i32>(),
            prop::bool::weighted(0.2),
            1..=COLS,
            prop::array::uniform8(any::<i32>()),
        )
            .prop_map(|(x, null, terms, v)| {
                let mut value = [0; COLS];
                for i in 0..COLS {
                    value[i] = v[i % 8];
                }
                Set {
                    x,
                    null,
                    terms,
                    value,
                }
            })
    }

    /// The tick's two reads of a set: its X and null flag on every tick
    /// (`take_published`), its values when it evaluates the command itself
    /// (the fallback's copy in `command_at`), both in one tick.
    fn tick_reads(lp: &mut LoopState, sh: &Shared) {
        lp.take_published(sh);
        let _ = sh.take_coefficients(&mut lp.fallback_seen, &mut lp.fallback);
    }

    /// What the reader holds must be exactly set `g` (0: none yet).
    fn holds(lp: &LoopState, sets: &[Set], g: u32) -> Result<(), TestCaseError> {
        let c = &lp.fallback;
        let Some(s) = g.checked_sub(1).map(|k| &sets[k as usize]) else {
            prop_assert!(lp.coeff_null);
            prop_assert!(c.null);
            return Ok(());
        };
        prop_assert_eq!(
            lp.last_x().map(|x| x.to_bits()),
            Some(s.x),
            "X of generation {}",
            g
        );
        prop_assert_eq!(lp.coeff_null, s.null, "generation {}", g);
        prop_assert_eq!(c.x().to_bits(), s.x, "X of generation {}", g);
        prop_assert_eq!(c.null, s.null, "generation {}", g);
        if !s.null {
            prop_assert_eq!(usize::from(c.terms()), s.terms);
            prop_assert_eq!(
                &c.value[..s.terms],
                &s.value[..s.terms],
                "torn values, generation {}",
                g
            );
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        /// Publications of random sets (null ones among them) with the loop
        /// tick run at random points between the writer's stores (several
        /// times between two stores, or not at all during a publication):
        /// after every run the tick holds exactly the latest completely
        /// published set, never a mix of two, never an older one it takes
        /// for new, and its generation never goes back.
        #[test]
        fn the_loop_tick_between_any_two_stores_takes_the_latest_whole_set(
            sets in prop::collection::vec(set(), 1..6),
            runs in prop::collection::vec(prop::collection::vec(0usize..64, 0..4), 6),
        ) {
            let sh = Shared::new();
            let mut lp = loop_state();
            let mut published = 0u32;
            for (k, s) in sets.iter().enumerate() {
                let g = k as u32 + 1;
                let st = steps(s);
                // Reader runs before step j (j = st.len(): after the last).
                let mut at: Vec<usize> = runs[k].iter().map(|&r| r % (st.len() + 1)).collect();
                at.sort_unstable();
                let mut next = at.iter().peekable();
                for (j, &step) in st.iter().enumerate() {
                    while next.peek().is_some_and(|&&a| a == j) {
                        next.next();
                        tick_reads(&mut lp, &sh);
                        prop_assert_eq!(lp.coeff_seen, published, "before store {} of generation {}", j, g);
                        holds(&lp, &sets, published)?;
                    }
                    store(&sh, g, s, step);
                    if matches!(step, Step::Gen) {
                        published = g;
                    }
                }
                for _ in next {
                    tick_reads(&mut lp, &sh);
                    prop_assert_eq!(lp.coeff_seen, published);
                    holds(&lp, &sets, published)?;
                }
            }
            tick_reads(&mut lp, &sh);
            prop_assert_eq!(lp.coeff_seen, sets.len() as u32);
            holds(&lp, &sets, published)?;
        }

        /// Index pulses published store by store, the loop tick at random
        /// points: the estimator sees each pair it takes whole (its state
        /// is that of an estimator given the latest published pair
        /// directly), the tick takes the latest, reports two pulses within
        /// one of its periods as an extra index, and latches exactly the
        /// faults the direct estimator gives (a torn pair would change
        /// both).
        #[test]
        fn the_loop_tick_between_any_two_stores_takes_the_latest_whole_index(
            pairs in prop::collection::vec((any::<u32>(), any::<u32>()), 1..8),
            runs in prop::collection::vec(0usize..6, 8),
        ) {
            let cfg = EncoderConfig {
                counts_per_rev: 4096,
                ticks_per_s: 200_000_000,
                min_rpm: 30,
                max_rpm: 600,
                index_tolerance_counts: 2,
                index_angle: SpindleAngle(0),
                edge_stamps: EdgeStamps::Captured,
            };
            let sh = Shared::new();
            let mut lp = loop_state();
            lp.spindle = Estimator::Encoder(EncoderAngle::new(cfg).unwrap());
            let mut want = EncoderAngle::new(cfg).unwrap();
            let mut want_fault: Option<Fault> = None;
            let trip = |f: &mut Option<Fault>, new: Fault| match *f {
                Some(o) if o.reaction() >= new.reaction() => {}
                _ => *f = Some(new),
            };
            let (mut published, mut seen) = (0u32, 0u32);
            for k in 0..=pairs.len() {
                // The five stores of `Shared::index_event` for pulse k + 1;
                // the tick before store `runs[k]` (5: not during it), and
                // once more after the last pulse.
                for j in 0..5 {
                    if runs[k.min(7)] == j || k == pairs.len() {
                        lp.take_published(&sh);
                        if published != seen {
                            if published - seen > 1 {
                                trip(&mut want_fault, Fault::IndexExtra);
                            }
                            let (c, e) = pairs[published as usize - 1];
                            if let Err(f) = want.on_index(c, e) {
                                trip(&mut want_fault, f);
                            }
                            seen = published;
                        }
                        prop_assert_eq!(lp.index_seen, published);
                        prop_assert_eq!(
                            format!("{:?}", lp.spindle),
                            format!("{:?}", Estimator::Encoder(want.clone()))
                        );
                        prop_assert_eq!(lp.fault, want_fault);
                    }
                    if k == pairs.len() {
                        break;
                    }
                    let s = k as u32 + 1;
                    let (count, edge) = pairs[k];
                    let slot = &sh.index[(s & 1) as usize];
                    match j {
                        0 => slot[2].store(s, Ordering::Relaxed),
                        1 => fence(Ordering::Release),
                        2 => slot[0].store(count, Ordering::Relaxed),
                        3 => slot[1].store(edge, Ordering::Relaxed),
                        _ => {
                            sh.index_seq.store(s, Ordering::Release);
                            published = s;
                        }
                    }
                }
            }
            prop_assert_eq!(seen, pairs.len() as u32);
        }
    }

    /// The step writer stores what the real writers store: a publication
    /// by `EventState::publish` (the X handler, default table, live and
    /// null) and by `Shared::index_event` leaves the same words in the same
    /// slots as the steps above.
    #[test]
    fn the_step_writer_leaves_the_words_the_real_writers_leave() {
        use crate::firmware::config::{FirmwareConfig, SpindleMode, XMode};
        use crate::firmware::xevent::EventState;
        let gen = crate::firmware::config::load_table(crate::DEFAULT_TABLE).ok();
        let fc = FirmwareConfig {
            loop_cfg: ServoDesign::brief(20_000).config().unwrap(),
            spindle: SpindleMode::None,
            x: XMode::Legacy {
                clock_hz: 1_000_000,
            },
            coefficient_output: false,
            gauge_reversed: false,
        };
        let mut ev = EventState::new(gen, &fc, None);
        let real = Shared::new();
        let mirror = Shared::new();
        for (k, (x_in, null)) in [(3.25, false), (4.0, true), (5.5, false)]
            .into_iter()
            .enumerate()
        {
            let g = k as u32 + 1;
            let x = XInches::from_f64(x_in);
            ev.publish(&real, x, null).unwrap();
            let slot = &real.coeff[(g & 1) as usize];
            let meta = slot.meta.load(Ordering::Relaxed);
            let mut s = Set {
                x: x.to_bits(),
                null: meta & NULL_META != 0,
                terms: (meta & !NULL_META) as usize,
                value: [0; COLS],
            };
            assert_eq!(s.null, null);
            for i in 0..COLS {
                s.value[i] = slot.value[i].load(Ordering::Relaxed);
            }
            for step in steps(&s) {
                store(&mirror, g, &s, step);
            }
            assert_eq!(
                real.coeff_gen.load(Ordering::Relaxed),
                mirror.coeff_gen.load(Ordering::Relaxed)
            );
            for (a, b) in real.coeff.iter().zip(&mirror.coeff) {
                assert_eq!(a.seq.load(Ordering::Relaxed), b.seq.load(Ordering::Relaxed));
                assert_eq!(a.x.load(Ordering::Relaxed), b.x.load(Ordering::Relaxed));
                assert_eq!(
                    a.meta.load(Ordering::Relaxed),
                    b.meta.load(Ordering::Relaxed)
                );
                let live = if s.null { 0 } else { s.terms };
                for i in 0..live {
                    assert_eq!(
                        a.value[i].load(Ordering::Relaxed),
                        b.value[i].load(Ordering::Relaxed)
                    );
                }
            }
        }
        // The index.
        let real = Shared::new();
        real.index_event(5678, 1234);
        let slot = &real.index[1];
        assert_eq!(
            [
                slot[0].load(Ordering::Relaxed),
                slot[1].load(Ordering::Relaxed),
                slot[2].load(Ordering::Relaxed)
            ],
            [1234, 5678, 1]
        );
        assert_eq!(real.index_seq.load(Ordering::Relaxed), 1);
    }
}
