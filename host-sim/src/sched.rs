//! Deterministic discrete-event scheduler.
//!
//! Event sources (the loop-tick timer, the X half-mil interrupt, the
//! spindle index, encoder edges, cutting-force changes, one-shot test
//! events) each say when they fire next and at which priority. The
//! scheduler repeatedly takes the earliest event; at equal times the higher
//! priority runs first (loop tick above X and index above background, as on
//! the target's NVIC), and at equal time and priority the source registered
//! first. Before an event runs, the world (the plant) is advanced exactly to
//! the event's time and the shared simulation clock is set to it, so the
//! handler's SPI frames are timestamped at the event.
//!
//! Handlers run to completion and take no simulated time, except that the
//! amplifier DAC applies its output `latency_ns` after the frame (see
//! `chips::ad5791`); preemption is therefore not modelled. Everything is
//! integer nanoseconds and a fixed order, so a run is reproducible
//! bit-for-bit from its seeds.

use std::collections::BinaryHeap;

/// Simulation time, ns.
pub type Nanos = u64;

/// What events act on: advances the continuous part exactly.
pub trait World {
    /// Advances the plant to `t_ns` (never backwards).
    fn advance_to(&mut self, t_ns: Nanos);
    /// Sets the clock the chips and the firmware read.
    fn set_time(&mut self, t_ns: Nanos);
}

/// Standard priorities (higher runs first at equal times).
pub mod prio {
    pub const LOOP_TICK: u8 = 200;
    pub const X_EVENT: u8 = 150;
    pub const INDEX: u8 = 140;
    pub const ENCODER: u8 = 130;
    pub const PLANT_INPUT: u8 = 100;
    pub const BACKGROUND: u8 = 10;
    pub const RECORD: u8 = 0;
}

/// A source of events.
pub trait EventSource<W> {
    /// Time of the next event, `None` when the source is exhausted.
    fn next_time(&self) -> Option<Nanos>;
    fn priority(&self) -> u8;
    fn name(&self) -> &str;
    /// Runs the event due at `now` and moves on to the following one.
    fn fire(&mut self, now: Nanos, world: &mut W);
}

/// An event handler: `(now, world)`.
pub type Handler<W> = Box<dyn FnMut(Nanos, &mut W)>;
/// An observer called after every event: `(now, source index, world)`.
pub type Observer<W> = Box<dyn FnMut(Nanos, usize, &W)>;

/// A periodic event (timer interrupt) calling `handler(now, world)`.
pub struct Periodic<W> {
    name: String,
    priority: u8,
    period_ns: Nanos,
    next: Nanos,
    handler: Handler<W>,
}

impl<W> Periodic<W> {
    pub fn new(
        name: &str,
        priority: u8,
        first_ns: Nanos,
        period_ns: Nanos,
        handler: impl FnMut(Nanos, &mut W) + 'static,
    ) -> Self {
        assert!(period_ns > 0, "period must be positive");
        Self {
            name: name.to_string(),
            priority,
            period_ns,
            next: first_ns,
            handler: Box::new(handler),
        }
    }
}

impl<W> EventSource<W> for Periodic<W> {
    fn next_time(&self) -> Option<Nanos> {
        Some(self.next)
    }
    fn priority(&self) -> u8 {
        self.priority
    }
    fn name(&self) -> &str {
        &self.name
    }
    fn fire(&mut self, now: Nanos, world: &mut W) {
        (self.handler)(now, world);
        self.next += self.period_ns;
    }
}

type OneShotFn<W> = Box<dyn FnOnce(Nanos, &mut W)>;

struct Pending<W> {
    t: Nanos,
    seq: u64,
    f: OneShotFn<W>,
}
impl<W> PartialEq for Pending<W> {
    fn eq(&self, o: &Self) -> bool {
        (self.t, self.seq) == (o.t, o.seq)
    }
}
impl<W> Eq for Pending<W> {}
impl<W> PartialOrd for Pending<W> {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl<W> Ord for Pending<W> {
    // Min-heap on (time, insertion order).
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        (o.t, o.seq).cmp(&(self.t, self.seq))
    }
}

/// One-shot events at given times (fault injections, force changes,
/// scripted test steps), FIFO among equal times.
pub struct OneShots<W> {
    name: String,
    priority: u8,
    heap: BinaryHeap<Pending<W>>,
    seq: u64,
}

impl<W> OneShots<W> {
    pub fn new(name: &str, priority: u8) -> Self {
        Self {
            name: name.to_string(),
            priority,
            heap: BinaryHeap::new(),
            seq: 0,
        }
    }
    pub fn at(&mut self, t_ns: Nanos, f: impl FnOnce(Nanos, &mut W) + 'static) {
        self.heap.push(Pending {
            t: t_ns,
            seq: self.seq,
            f: Box::new(f),
        });
        self.seq += 1;
    }
}

impl<W> EventSource<W> for OneShots<W> {
    fn next_time(&self) -> Option<Nanos> {
        self.heap.peek().map(|p| p.t)
    }
    fn priority(&self) -> u8 {
        self.priority
    }
    fn name(&self) -> &str {
        &self.name
    }
    fn fire(&mut self, now: Nanos, world: &mut W) {
        if let Some(p) = self.heap.pop() {
            (p.f)(now, world);
        }
    }
}

/// The scheduler: owns the sources, not the world.
pub struct Scheduler<W> {
    sources: Vec<Box<dyn EventSource<W>>>,
    /// Priorities, read once at `add` (a source's priority is fixed).
    prios: Vec<u8>,
    now: Nanos,
    /// Events fired per source (same order as added).
    pub fired: Vec<u64>,
    /// Optional observer called after every event: (time, source index).
    pub on_event: Option<Observer<W>>,
}

impl<W: World> Default for Scheduler<W> {
    fn default() -> Self {
        Self::new()
    }
}

impl<W: World> Scheduler<W> {
    pub fn new() -> Self {
        Self {
            sources: Vec::new(),
            prios: Vec::new(),
            now: 0,
            fired: Vec::new(),
            on_event: None,
        }
    }
    /// Adds a source; returns its index.
    pub fn add(&mut self, s: impl EventSource<W> + 'static) -> usize {
        self.prios.push(s.priority());
        self.sources.push(Box::new(s));
        self.fired.push(0);
        self.sources.len() - 1
    }
    pub fn now(&self) -> Nanos {
        self.now
    }
    pub fn source_name(&self, k: usize) -> &str {
        self.sources.get(k).map_or("?", |s| s.name())
    }

    /// The next (time, source) in the deterministic order.
    fn pick(&self) -> Option<(Nanos, usize)> {
        let mut best: Option<(Nanos, u8, usize)> = None;
        for (k, (s, &p)) in self.sources.iter().zip(&self.prios).enumerate() {
            if let Some(t) = s.next_time() {
                let t = t.max(self.now);
                let better = match best {
                    None => true,
                    Some((bt, bp, _)) => t < bt || (t == bt && p > bp),
                };
                if better {
                    best = Some((t, p, k));
                }
            }
        }
        best.map(|(t, _, k)| (t, k))
    }

    /// Runs every event with time ≤ `t_end`, then advances the world to
    /// `t_end`. Returns the number of events run.
    pub fn run_until(&mut self, world: &mut W, t_end: Nanos) -> u64 {
        let mut n = 0;
        while let Some((t, k)) = self.pick() {
            if t > t_end {
                break;
            }
            world.advance_to(t);
            world.set_time(t);
            self.now = t;
            self.sources[k].fire(t, world);
            self.fired[k] += 1;
            n += 1;
            if let Some(obs) = self.on_event.as_mut() {
                obs(t, k, world);
            }
        }
        world.advance_to(t_end);
        world.set_time(t_end);
        self.now = t_end;
        n
    }
}
