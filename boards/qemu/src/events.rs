//! The machine-event handler (CMSDK timer 1, below the loop tick): the
//! synthetic machine's X events (or X count) and index pulses up to the
//! present world time, into the firmware's X and index handlers, then the
//! learning on the loop tick's samples.

use core::sync::atomic::Ordering;

use zslide::firmware::{EventState, LearnState, NoCoefficientDac};
use zslide::handoff::handover::Handover;
use zslide::trace::Event;
use zslide::xpos::latch_word;
use zslide_qemu::board::{interrupt, TIMER1_EVENTS};
use zslide_qemu::trace;

use crate::scenario::{
    spindle_edge, x_count_at, x_events, x_script, x_tick, CLOCK_PER_TICK, CPR, DUPLICATES,
    EVENTS_UNTIL, INDEX0, WORLD_TICK,
};
use crate::{SESSION, SHARED};

/// Everything the event handler owns.
///
/// `repr(C)`, the learner first, for the reason given at [`Run`]: the X
/// handler's state (8.7 KiB with its slope table) would otherwise put it
/// beyond the loads' 12-bit offsets.
#[repr(C)]
pub(crate) struct Events {
    pub(crate) learn: LearnState,
    pub(crate) ev: EventState,
    pub(crate) next_x: u32,
    pub(crate) next_index: u32,
    /// Coefficient generation last traced.
    pub(crate) generation: u32,
}

/// Hands the state to the handler once (as [`crate::tick::RUN_HANDOVER`]).
pub(crate) static EVENTS_HANDOVER: Handover<Events> = Handover::new();

/// The machine's events up to the present world time, in time order: X
/// events (with scripted duplicates) and index pulses.
#[interrupt]
fn TIMER1() {
    static mut EVENTS: Option<&'static mut Events> = None;
    TIMER1_EVENTS.clear_interrupt();
    let Some(e) = EVENTS_HANDOVER.claim(EVENTS) else {
        return;
    };
    // A link session keeps the spindle turning (index pulses) forever.
    let k = if SESSION.load(Ordering::Relaxed) {
        WORLD_TICK.load(Ordering::Acquire)
    } else {
        WORLD_TICK.load(Ordering::Acquire).min(EVENTS_UNTIL)
    };
    let now = u64::from(k) * u64::from(CLOCK_PER_TICK);
    if cfg!(feature = "modern-x") {
        // A fault it finds reaches the loop tick through SHARED.
        let _ = e.ev.x_count_event(&SHARED, x_count_at(k));
    }
    loop {
        let x_at = (e.next_x < x_events())
            .then(|| u64::from(x_tick(e.next_x)) * u64::from(CLOCK_PER_TICK))
            .filter(|&t| t <= now);
        let index_count = INDEX0 + CPR * e.next_index;
        let index_at = Some(spindle_edge(index_count)).filter(|&t| t <= now);
        match (x_at, index_at) {
            (Some(tx), ti) if ti.is_none_or(|ti| tx <= ti) => {
                let i = e.next_x;
                let word = latch_word(x_script(i));
                trace::emit(Event::XEnter);
                let _ =
                    e.ev.x_event(&SHARED, word, tx as u32, &mut NoCoefficientDac);
                trace::emit(Event::XExit);
                if DUPLICATES.contains(&i) {
                    // The latch fires again in the same state.
                    trace::emit(Event::XEnter);
                    let _ =
                        e.ev.x_event(&SHARED, word, tx as u32 + 200, &mut NoCoefficientDac);
                    trace::emit(Event::XExit);
                }
                let g = SHARED.coefficient_generation();
                if g != e.generation {
                    e.generation = g;
                    trace::emit(Event::Coefficients(g));
                }
                e.next_x += 1;
            }
            (_, Some(ti)) => {
                trace::emit(Event::IndexEnter);
                e.ev.index_event(&SHARED, ti as u32, index_count);
                trace::emit(Event::IndexExit);
                e.next_index += 1;
            }
            _ => break,
        }
    }
    e.learn.run(&SHARED);
}
