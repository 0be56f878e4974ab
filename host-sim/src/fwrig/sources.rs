//! The world's event sources: the loop tick, the X half-mil interrupt and
//! the index pulse, at their exact instants.

use super::attached::XState;
use super::world::FirmwareWorld;
use crate::machine::hw::{SharedSpindle, XHalfMilLink};
use crate::sched::{prio, EventSource, Nanos, Scheduler};
use std::cell::RefCell;
use std::rc::Rc;

/// The loop tick as a periodic source of the world. A plain function
/// pointer (no boxed closure on the hot path).
pub struct WorldTick {
    name: &'static str,
    period_ns: Nanos,
    next: Nanos,
    fire: fn(&mut FirmwareWorld),
}

impl WorldTick {
    /// The firmware's loop tick every `period_ns`.
    pub fn loop_tick(period_ns: Nanos) -> Self {
        Self {
            name: "loop_tick",
            period_ns,
            next: period_ns,
            fire: FirmwareWorld::tick,
        }
    }
}

impl EventSource<FirmwareWorld> for WorldTick {
    #[inline]
    fn next_time(&self) -> Option<Nanos> {
        Some(self.next)
    }
    fn priority(&self) -> u8 {
        prio::LOOP_TICK
    }
    fn name(&self) -> &str {
        self.name
    }
    #[inline]
    fn fire(&mut self, _now: Nanos, w: &mut FirmwareWorld) {
        (self.fire)(w);
        self.next += self.period_ns;
    }
}

/// Half-mil interrupts of the legacy X interface, at their exact instants.
pub struct XHalfMilSource {
    link: Rc<RefCell<XHalfMilLink>>,
}

impl EventSource<FirmwareWorld> for XHalfMilSource {
    fn next_time(&self) -> Option<Nanos> {
        let l = self.link.borrow();
        // Nothing queued: wake at the end of the scanned window to scan on.
        Some(l.next_interrupt().map_or(l.scanned_to(), |i| i.t_ns))
    }
    fn priority(&self) -> u8 {
        prio::X_EVENT
    }
    fn name(&self) -> &str {
        "x_event"
    }
    fn fire(&mut self, now: Nanos, w: &mut FirmwareWorld) {
        let due = {
            let mut l = self.link.borrow_mut();
            match l.next_interrupt() {
                Some(i) if i.t_ns <= now => l.take(),
                Some(_) => None,
                None => {
                    l.scan();
                    None
                }
            }
        };
        if let Some(i) = due {
            w.x_event(i.stale);
        }
    }
}

/// Index pulses of the spindle (true and spurious), at their exact instants.
pub struct IndexSource {
    link: SharedSpindle,
}

impl EventSource<FirmwareWorld> for IndexSource {
    fn next_time(&self) -> Option<Nanos> {
        let l = self.link.borrow();
        Some(l.next_pulse().map_or(l.scanned_to(), |p| p.t_ns))
    }
    fn priority(&self) -> u8 {
        prio::INDEX
    }
    fn name(&self) -> &str {
        "index"
    }
    fn fire(&mut self, now: Nanos, w: &mut FirmwareWorld) {
        let due = {
            let mut l = self.link.borrow_mut();
            match l.next_pulse() {
                Some(p) if p.t_ns <= now => l.pop_pulse(),
                Some(_) => None,
                None => {
                    l.scan();
                    None
                }
            }
        };
        if let Some(p) = due {
            w.index_event(p.count, p.edge_ticks);
        }
    }
}

/// Scheduler source indices of a firmware run.
pub mod src {
    pub const LOOP_TICK: usize = 0;
}

/// Registers the X half-mil (legacy X) and index sources of the attached
/// machine, after the loop tick.
pub fn add_machine_sources(w: &FirmwareWorld, s: &mut Scheduler<FirmwareWorld>) {
    if let Some(m) = &w.machine {
        if let XState::Legacy { link, .. } = &m.x {
            s.add(XHalfMilSource { link: link.clone() });
        }
        s.add(IndexSource {
            link: m.spindle.clone(),
        });
    }
}
