//! The loop tick's side of the host link: what the tick hands the
//! background, in a few stores, never waiting.
//!
//! The board calls [`TickTap::after_tick`] right after
//! `LoopState::loop_tick`, in the same handler. On an idle tick it costs
//! one comparison of the latched fault and one load of [`TapShared`]'s
//! request word; everything else happens only when the background asked
//! for it (a status snapshot, new parameters) or a capture is armed (one
//! sample of six words into a ring of atomics per tick). The background
//! (`station`) never reads `LoopState`: it gets
//! * fault changes, timestamped, through a lock-free queue (the log),
//! * a [`Snapshot`] when it sets [`REQ_SNAPSHOT`], through a queue,
//! * the capture ring, once the tick marks it done,
//!
//! and hands the tick new servo configurations through a third queue
//! ([`REQ_CONFIG`]), applied only while disarmed. The queues are heapless's
//! lock-free bounded queues (Vyukov's, atomics only, no masking; `&self`
//! methods on a `static`, and the index wraps by a constant mask: no
//! division, no panic path, which `cargo xtask no-panic` checks). They live
//! in [`TapShared`] with the capture ring, so a board needs one `static`.

use super::proto::{CaptureState, LoopPhase, LoopSnapshot as Snapshot, Sample, Trigger, X_UNKNOWN};
use crate::firmware::looptick::LoopState;
use crate::safety::Fault;
use crate::servo::{Phase, ServoConfig};
use core::mem::Discriminant;
use core::sync::atomic::{AtomicI32, AtomicU32, Ordering};
use heapless::mpmc::Queue;

/// Request bits of [`TapShared::requests`].
pub const REQ_SNAPSHOT: u32 = 1;
pub const REQ_CONFIG: u32 = 2;
pub const REQ_CAPTURE: u32 = 4;
pub const REQ_EXCITE: u32 = 8;

/// A change of the latched fault (`None`: cleared) at a loop tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FaultEvent {
    pub tick: u32,
    pub fault: Option<Fault>,
}

/// Fault changes the queue holds between two background passes (more are
/// lost, never block the tick).
pub const FAULT_QUEUE: usize = 16;

/// Capture phases in the low bits of [`Scope::state`] (0: idle); the arming's
/// generation above them, so that the tick tells a new arming from the
/// one it is recording.
const PH_ARMED: u32 = 1;
const PH_TRIGGERED: u32 = 2;
const PH_DONE: u32 = 3;
const PH_MASK: u32 = 3;
const GEN_ONE: u32 = 4;

const TRIG_IMMEDIATE: u32 = 0;
const TRIG_FAULT: u32 = 1;
const TRIG_FERR: u32 = 2;
const TRIG_TICK: u32 = 3;

/// The capture ring: `N` samples (a power of two) of six words, atomics
/// so that the tick writes and the background reads without a lock (the
/// background reads only after the tick has marked the capture done and
/// stopped writing; a new arming is the background's own act).
pub struct Scope<const N: usize> {
    ring: [[AtomicI32; 6]; N],
    state: AtomicU32,
    trigger: AtomicU32,
    level: AtomicU32,
    samples: AtomicU32,
    pre: AtomicU32,
    /// Set by the tick when done: ring index of the first sample, samples
    /// before the trigger, and the trigger's loop tick.
    start: AtomicU32,
    before: AtomicU32,
    trigger_tick: AtomicU32,
}

/// What the background shares with the tick besides the queues: the
/// request word and the capture ring. `const`-constructible for a `static`.
pub struct TapShared<'s, const N: usize> {
    requests: AtomicU32,
    /// The capture ring, a `static` of its own: all zeros, so it costs no
    /// flash (`.bss`), where the queues' initial state does (`.data`).
    pub(crate) scope: &'s Scope<N>,
    pub(crate) faults: Queue<FaultEvent, FAULT_QUEUE>,
    pub(crate) snapshots: Queue<Snapshot, 2>,
    pub(crate) configs: Queue<ServoConfig, 2>,
    /// An identification sine's step, amplitude, ticks, start tick and
    /// the start tick's largest lead (0: start at once, no start tick)
    /// ([`REQ_EXCITE`]; written whole by the background before it sets
    /// the bit).
    pub(crate) excite: [AtomicU32; 5],
}

impl<'s, const N: usize> TapShared<'s, N> {
    // heapless deprecates `mpmc::Queue::new` because an operation preempted
    // half-way can make the *other* side's operation fail until it
    // resumes (never a panic or a torn item). Here each queue has one
    // producer and one consumer on one core, and that can only happen to
    // an enqueue into a full queue (it would reuse the cell a preempted
    // dequeue holds): the configuration is enqueued whole before the tick
    // is told to look (`REQ_CONFIG`), the background drains the snapshot
    // queue before it asks for one, and a fault change is lost only
    // after 16 unread ones, as it would be anyway.
    #[allow(deprecated)]
    pub const fn new(scope: &'s Scope<N>) -> Self {
        Self {
            requests: AtomicU32::new(0),
            scope,
            faults: Queue::new(),
            snapshots: Queue::new(),
            configs: Queue::new(),
            excite: [const { AtomicU32::new(0) }; 5],
        }
    }

    pub(crate) fn request(&self, bits: u32) {
        self.requests.fetch_or(bits, Ordering::Release);
    }
}

impl<const N: usize> Default for Scope<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Scope<N> {
    pub const fn new() -> Self {
        assert!(
            N.is_power_of_two() && N <= 1 << 15,
            "capture ring: a power of two"
        );
        Self {
            ring: [const { [const { AtomicI32::new(0) }; 6] }; N],
            state: AtomicU32::new(0),
            trigger: AtomicU32::new(0),
            level: AtomicU32::new(0),
            samples: AtomicU32::new(0),
            pre: AtomicU32::new(0),
            start: AtomicU32::new(0),
            before: AtomicU32::new(0),
            trigger_tick: AtomicU32::new(0),
        }
    }

    /// Arms a capture (any state: a new arming replaces the old one).
    pub(crate) fn arm(&self, samples: u16, pre: u16, trigger: Trigger) {
        let (kind, level) = match trigger {
            Trigger::Immediate => (TRIG_IMMEDIATE, 0),
            Trigger::Fault => (TRIG_FAULT, 0),
            Trigger::FollowingError { level } => (TRIG_FERR, level),
            Trigger::AtTick { tick } => (TRIG_TICK, tick),
        };
        self.trigger.store(kind, Ordering::Relaxed);
        self.level.store(level, Ordering::Relaxed);
        self.samples.store(u32::from(samples), Ordering::Relaxed);
        self.pre.store(u32::from(pre), Ordering::Relaxed);
        let gen = (self.state.load(Ordering::Relaxed) & !PH_MASK).wrapping_add(GEN_ONE);
        self.state.store(gen | PH_ARMED, Ordering::Release);
    }

    pub(crate) fn state(&self) -> CaptureState {
        match self.state.load(Ordering::Acquire) & PH_MASK {
            PH_ARMED => CaptureState::Armed,
            PH_TRIGGERED => CaptureState::Triggered,
            PH_DONE => CaptureState::Done,
            _ => CaptureState::Idle,
        }
    }

    pub(crate) fn trigger(&self) -> Trigger {
        match self.trigger.load(Ordering::Relaxed) {
            TRIG_FAULT => Trigger::Fault,
            TRIG_FERR => Trigger::FollowingError {
                level: self.level.load(Ordering::Relaxed),
            },
            TRIG_TICK => Trigger::AtTick {
                tick: self.level.load(Ordering::Relaxed),
            },
            _ => Trigger::Immediate,
        }
    }

    pub(crate) fn samples(&self) -> u16 {
        self.samples.load(Ordering::Relaxed) as u16
    }
    pub(crate) fn pre(&self) -> u16 {
        self.pre.load(Ordering::Relaxed) as u16
    }

    /// (samples recorded, of them before the trigger, trigger tick) of a
    /// done capture.
    pub(crate) fn result(&self) -> (u16, u16, u32) {
        let before = self.before.load(Ordering::Relaxed);
        let after = self.samples.load(Ordering::Relaxed) - self.pre.load(Ordering::Relaxed);
        (
            (before + after) as u16,
            before as u16,
            self.trigger_tick.load(Ordering::Relaxed),
        )
    }

    /// Sample `i` (0 = oldest) of a done capture.
    pub(crate) fn sample(&self, i: u16) -> Sample {
        let at = (self.start.load(Ordering::Relaxed) + u32::from(i)) as usize & (N - 1);
        let w = |k: usize| {
            self.ring
                .get(at)
                .and_then(|s| s.get(k))
                .map_or(0, |a| a.load(Ordering::Relaxed))
        };
        Sample {
            command: w(0),
            position: w(1),
            error: w(2),
            output: w(3),
            phi: w(4) as u32,
            x_bits: w(5),
        }
    }
}

/// The tick's own part of the link: what it remembers between ticks.
pub struct TickTap {
    /// The latched fault's kind as last seen (see [`kind`]).
    fault: Option<Discriminant<Fault>>,
    configs_applied: u32,
    configs_refused: u32,
    // Capture in progress: the state word it belongs to, samples written,
    // samples still due after the trigger, and its settings.
    scope_state: u32,
    written: u32,
    due: u32,
    samples: u32,
    pre: u32,
    trigger: u32,
    level: u32,
    /// |error| was at or above the level on the last recorded tick.
    over: bool,
}

/// The kind of the latched fault: what the tap compares every tick (a tag
/// load, where comparing whole faults calls `Fault::eq`). It misses no
/// change the loop makes: a latched fault is replaced only by a more
/// severe one, always of another kind, and the detail of a kind with one
/// (`Table`, `Parameters`) is fixed at boot, so within one kind only a
/// clear and a new latch in the same tick could pass unseen (a `Bus`
/// fault of another converter): the status still shows it, only its log
/// record would be missing.
fn kind(f: Option<Fault>) -> Option<Discriminant<Fault>> {
    f.as_ref().map(core::mem::discriminant)
}

fn phase(p: Phase) -> LoopPhase {
    match p {
        Phase::Disarmed => LoopPhase::Disarmed,
        Phase::SignCheck => LoopPhase::SignCheck,
        Phase::Engaging => LoopPhase::Engaging,
        Phase::Engaged => LoopPhase::Engaged,
        Phase::Disarming => LoopPhase::Disarming,
    }
}

impl Default for TickTap {
    fn default() -> Self {
        Self::new()
    }
}

impl TickTap {
    pub const fn new() -> Self {
        Self {
            fault: None,
            configs_applied: 0,
            configs_refused: 0,
            scope_state: 0,
            written: 0,
            due: 0,
            samples: 0,
            pre: 0,
            trigger: 0,
            level: 0,
            over: true,
        }
    }

    /// After each loop tick, in the loop-tick handler (module docs).
    /// Never inlined, so that `cargo xtask isr-cost` counts it apart; the
    /// common tick (no fault change, nothing asked) is a comparison and a
    /// load, the rest is out of line.
    #[inline(never)]
    pub fn after_tick<const N: usize>(&mut self, sh: &TapShared<'_, N>, lp: &mut LoopState) {
        // Relaxed: what the request bits announce (queue cells, the capture
        // settings) is read with its own acquire in `serve`.
        let req = sh.requests.load(Ordering::Relaxed);
        if req == 0 {
            if kind(lp.fault()) == self.fault {
                return;
            }
        } else if req == REQ_CAPTURE && kind(lp.fault()) == self.fault {
            // A capture running and nothing else: the recording, inline.
            self.record(sh.scope, lp, false, &sh.requests);
            return;
        }
        self.serve(sh, lp, req);
    }

    #[inline(never)]
    #[cold]
    fn serve<const N: usize>(&mut self, sh: &TapShared<'_, N>, lp: &mut LoopState, req: u32) {
        let fault = lp.fault();
        let latched = kind(fault) != self.fault;
        if latched {
            self.fault = kind(fault);
            // A full queue (the background stopped draining) loses the
            // event, never the tick; the log counts what it got.
            let _ = sh.faults.enqueue(FaultEvent {
                tick: lp.ticks(),
                fault,
            });
        }
        if req & REQ_CAPTURE != 0 {
            self.record(sh.scope, lp, latched && fault.is_some(), &sh.requests);
        }
        if req & REQ_CONFIG != 0 {
            sh.requests.fetch_and(!REQ_CONFIG, Ordering::Relaxed);
            while let Some(cfg) = sh.configs.dequeue() {
                if lp.reconfigure(cfg) {
                    self.configs_applied = self.configs_applied.wrapping_add(1);
                } else {
                    self.configs_refused = self.configs_refused.wrapping_add(1);
                }
            }
        }
        if req & REQ_EXCITE != 0 {
            sh.requests.fetch_and(!REQ_EXCITE, Ordering::Relaxed);
            let [step, amplitude, ticks, at, lead] =
                [0, 1, 2, 3, 4].map(|i| sh.excite.get(i).map_or(0, |a| a.load(Ordering::Acquire)));
            // Phase 0 on the next tick, or on tick `at` when anchored (a
            // lead): an `at` already reached wraps to beyond any lead and
            // is refused, as is one too far ahead (no sine: 0 ticks).
            let wait = if lead == 0 {
                0
            } else {
                at.wrapping_sub(lp.ticks().wrapping_add(1))
            };
            let ticks = if wait > lead { 0 } else { ticks };
            // A refusal shows in the snapshot (`exciting` false).
            let _ = lp.excite(step, amplitude, ticks, wait);
        }
        if req & REQ_SNAPSHOT != 0 {
            sh.requests.fetch_and(!REQ_SNAPSHOT, Ordering::Relaxed);
            let sp = lp.setpoint_state();
            let _ = sh.snapshots.enqueue(Snapshot {
                ticks: lp.ticks(),
                phase: phase(lp.servo().phase()),
                amplifier_enabled: lp.amplifier_enable(),
                fault,
                clear_refused: lp.clear_refused(),
                x_bits: lp.last_x().map(|x| x.to_bits()),
                null_command: lp.command_null(),
                phi: sp.angle().map(|a| a.0),
                phi_step_q8: sp.step_q8(),
                command: lp.command_code(),
                position: lp.position_code(),
                output: lp.output_code(),
                table_command: lp.table_code(),
                configs_applied: self.configs_applied,
                configs_refused: self.configs_refused,
                exciting: lp.exciting(),
            });
        }
    }

    /// One capture sample, and the trigger.
    #[inline(always)]
    fn record<const N: usize>(
        &mut self,
        sc: &Scope<N>,
        lp: &LoopState,
        fault_latched: bool,
        requests: &AtomicU32,
    ) {
        let st = sc.state.load(Ordering::Acquire);
        if st != self.scope_state {
            // A new arming (or the background's own reset).
            self.scope_state = st;
            self.written = 0;
            self.samples = sc.samples.load(Ordering::Relaxed);
            self.pre = sc.pre.load(Ordering::Relaxed);
            self.trigger = sc.trigger.load(Ordering::Relaxed);
            self.level = sc.level.load(Ordering::Relaxed);
            // A level already exceeded at the arming is no crossing.
            self.over = true;
        }
        let ph = st & PH_MASK;
        if ph != PH_ARMED && ph != PH_TRIGGERED {
            requests.fetch_and(!REQ_CAPTURE, Ordering::Relaxed);
            return;
        }
        let command = lp.command_code();
        let position = lp.position_code();
        let error = command.saturating_sub(position);
        let at = self.written as usize & (N - 1);
        if let Some([c, p, e, o, a, x]) = sc.ring.get(at) {
            c.store(command, Ordering::Relaxed);
            p.store(position, Ordering::Relaxed);
            e.store(error, Ordering::Relaxed);
            o.store(lp.output_code(), Ordering::Relaxed);
            let phi = lp.setpoint_state().angle().map_or(0, |v| v.0);
            a.store(phi as i32, Ordering::Relaxed);
            x.store(
                lp.last_x().map_or(X_UNKNOWN, |v| v.to_bits()),
                Ordering::Relaxed,
            );
        }
        self.written = self.written.wrapping_add(1);
        let gen = st & !PH_MASK;
        if ph == PH_ARMED {
            let over = error.unsigned_abs() >= self.level;
            let hit = match self.trigger {
                TRIG_FAULT => fault_latched,
                // Crossing the level from below, like a scope's edge.
                TRIG_FERR => over && !self.over,
                TRIG_TICK => lp.ticks() == self.level,
                _ => true,
            };
            self.over = over;
            if !hit {
                return;
            }
            let before = (self.written - 1).min(self.pre);
            sc.before.store(before, Ordering::Relaxed);
            sc.start
                .store(self.written.wrapping_sub(1 + before), Ordering::Relaxed);
            sc.trigger_tick.store(lp.ticks(), Ordering::Relaxed);
            self.due = self.samples.saturating_sub(self.pre).saturating_sub(1);
            self.advance(sc, gen | PH_ARMED, gen | PH_TRIGGERED);
        } else {
            self.due = self.due.saturating_sub(1);
        }
        if self.due == 0 && self.scope_state & PH_MASK == PH_TRIGGERED {
            self.advance(sc, gen | PH_TRIGGERED, gen | PH_DONE);
        }
    }

    /// Moves the capture on, unless the background re-armed it meanwhile.
    fn advance<const N: usize>(&mut self, sc: &Scope<N>, from: u32, to: u32) {
        if sc
            .state
            .compare_exchange(from, to, Ordering::Release, Ordering::Relaxed)
            .is_ok()
        {
            self.scope_state = to;
        }
    }
}
