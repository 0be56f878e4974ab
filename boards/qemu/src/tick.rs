//! The loop-tick handler (CMSDK timer 0, highest priority): the firmware's
//! loop tick on the real converter drivers, then one step of the plant
//! model, and what the checks need of it (the tracking error, the trace
//! samples, the state at the bus-error injection and at the end).

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m::peripheral::NVIC;
use critical_section::Mutex;
use zslide::drivers::{ad4020::Ad4020, ad5791::Ad5791};
use zslide::firmware::{LoopState, SpindleReading, TickInput};
use zslide::handoff::handover::Handover;
use zslide::link::tap::TickTap;
use zslide::safety::Fault;
use zslide::trace::{Event, Outputs};
use zslide_qemu::board::{enable, interrupt, Interrupt, TIMER0_LOOP, TIMER1_EVENTS};
use zslide_qemu::trace;

use crate::plant::{Dac, DacSpi, GaugeSpi, Plant};
use crate::scenario::{
    encoder_at, x_count_at, CLOCK_PER_TICK, FAULT_AT, INJECT_AT, TICKS, TRACE_AT, TRACK_FROM,
    WORLD_TICK,
};
use crate::{link, INJECT, INJECT_HARDFAULT, SESSION, SHARED};

#[derive(Clone, Copy, Default, defmt::Format)]
pub(crate) struct Sample {
    pub(crate) tick: u32,
    /// X of the coefficients and the spindle angle the table command was
    /// evaluated at (`cargo xtask test` recomputes it on the host).
    pub(crate) x_bits: i32,
    pub(crate) phi: u32,
    pub(crate) table: i32,
    pub(crate) command: i32,
    pub(crate) position: i32,
    pub(crate) output: i32,
}

/// What the loop-tick handler saw, published once at the end of the run.
#[derive(Clone, Copy, Default)]
pub(crate) struct Summary {
    pub(crate) fw_ticks: u32,
    pub(crate) fault_before: Option<Fault>,
    pub(crate) track_max_error: u32,
    pub(crate) table_min: i32,
    pub(crate) table_max: i32,
    pub(crate) coeff_x_bits: i32,
    pub(crate) coeff_null: bool,
    pub(crate) fault_after: Option<Fault>,
    pub(crate) dac_clamped: bool,
    pub(crate) amplifier_enable: bool,
    pub(crate) writes_at_inject: u32,
    pub(crate) writes_at_end: u32,
    /// Plant steps the generated discretisations could not take (`plant.rs`).
    pub(crate) plant_missing_steps: u64,
    pub(crate) trace: [Sample; TRACE_AT.len()],
}

/// Everything the loop-tick handler owns.
///
/// `repr(C)`, the loop's state first: a field more than 4 KiB into it (the
/// 40 KiB plant was laid out first) needs its offset built in a register
/// (`movw`) on every access; within the first 4 KiB the offset is the
/// load's own 12-bit immediate.
#[repr(C)]
pub(crate) struct Run {
    pub(crate) lp: LoopState,
    pub(crate) tap: TickTap,
    pub(crate) plant: Plant,
    pub(crate) gauge: Ad4020<GaugeSpi>,
    pub(crate) dac: Ad5791<DacSpi>,
    pub(crate) summary: Summary,
    pub(crate) traced: usize,
    pub(crate) outputs: Outputs,
}

/// Hands the state to the handler once, before its interrupt is unmasked:
/// one `.bss` value (`cortex_m::singleton!`) handed over by reference, as
/// on the NUCLEO (`zslide::handoff::handover`).
pub(crate) static RUN_HANDOVER: Handover<Run> = Handover::new();
pub(crate) static RESULT: Mutex<Cell<Option<Summary>>> = Mutex::new(Cell::new(None));
pub(crate) static ISR_COUNT: AtomicU32 = AtomicU32::new(0);
pub(crate) static DONE: AtomicBool = AtomicBool::new(false);

#[interrupt]
fn TIMER0() {
    static mut RUN: Option<&'static mut Run> = None;
    TIMER0_LOOP.clear_interrupt();
    let n = ISR_COUNT.fetch_add(1, Ordering::Relaxed) + 1;
    let Some(run) = RUN_HANDOVER.claim(RUN) else {
        return;
    };
    WORLD_TICK.store(n, Ordering::Release);
    trace::emit(Event::LoopEnter);
    let now = u64::from(n) * u64::from(CLOCK_PER_TICK);
    let input = TickInput {
        now: now as u32,
        spindle: SpindleReading::Encoder(encoder_at(now)),
        x_count: x_count_at(n),
        // The emulated amplifier has no fault line.
        amplifier_fault: false,
    };

    run.lp
        .loop_tick(&SHARED, &input, &mut run.gauge, &mut run.dac);
    trace::emit(Event::LoopExit);
    run.outputs.after_tick(&run.lp, trace::clock);
    run.tap.after_tick(&link::TAP, &mut run.lp);
    // The enable output, and the amplifier follows the output (read back).
    enable::set(run.lp.amplifier_enable());
    let enabled = enable::is_high();
    if n == FAULT_AT && INJECT.load(Ordering::Relaxed) == INJECT_HARDFAULT {
        cortex_m::asm::udf();
    }
    if SESSION.load(Ordering::Relaxed) {
        run.plant.step(Dac::volts(), enabled);
        return;
    }
    run.plant.step(Dac::volts(), enabled);

    let s = &mut run.summary;
    let error = run.lp.command_code().abs_diff(run.plant.gauge_code());
    if (TRACK_FROM..=INJECT_AT).contains(&n) {
        s.track_max_error = s.track_max_error.max(error);
        s.table_min = s.table_min.min(run.lp.table_code());
        s.table_max = s.table_max.max(run.lp.table_code());
    }
    if let Some(&at) = TRACE_AT.get(run.traced) {
        if at == n {
            if let Some(slot) = s.trace.get_mut(run.traced) {
                *slot = Sample {
                    tick: n,
                    x_bits: run.lp.last_x().map_or(0, |x| x.to_bits()),
                    phi: run.lp.setpoint_state().angle().map_or(0, |a| a.0),
                    table: run.lp.table_code(),
                    command: run.lp.command_code(),
                    position: run.plant.gauge_code(),
                    output: run.lp.output_code(),
                };
            }
            run.traced += 1;
        }
    }
    if n == INJECT_AT {
        s.fault_before = run.lp.fault();
        s.writes_at_inject = Dac::writes();
        s.coeff_x_bits = run.lp.last_x().map_or(0, |x| x.to_bits());
        s.coeff_null = run.lp.command_null();
        run.plant.gauge_bus_broken = true;
        run.plant.publish_gauge();
    }
    if n >= TICKS {
        // No further entry: timers off, lines masked and unpended.
        TIMER0_LOOP.stop();
        TIMER1_EVENTS.stop();
        NVIC::mask(Interrupt::TIMER0);
        NVIC::unpend(Interrupt::TIMER0);
        s.fw_ticks = run.lp.ticks();
        s.fault_after = run.lp.fault();
        s.dac_clamped = Dac::clamped();
        s.amplifier_enable = enabled;
        s.writes_at_end = Dac::writes();
        s.plant_missing_steps = run.plant.missing_steps();
        let summary = *s;
        critical_section::with(|cs| RESULT.borrow(cs).set(Some(summary)));
        DONE.store(true, Ordering::Release);
    }
}
