//! The Z-slide firmware on the emulated board: QEMU `mps2-an386`
//! (Cortex-M4F). The same integrated `zslide::firmware` as the
//! NUCLEO-H743ZI2, fed by a synthetic machine:
//!
//! * CMSDK timer 0 (IRQ 8, highest priority) is the loop tick: the synthetic
//!   spindle encoder is sampled, `LoopState::loop_tick` reads the gauge
//!   through the real `Ad4020` driver, evaluates the command of
//!   the table in the table region (`memory.x`, loaded by QEMU's
//!   `-device loader`) and writes the real `Ad5791` driver; the plant
//!   (`plant.rs`: the project's one model, `zslide-plant`, behind
//!   `SpiDevice`s that speak the chips' frames) then moves one tick.
//! * CMSDK timer 1 (IRQ 9, lower priority) plays the machine's events up to
//!   the present world time: legacy half-mil X events from a synthetic feed
//!   (with duplicate words the debounce must ignore and a reversal), and the
//!   spindle's index pulses, into `EventState::x_event` / `index_event`.
//!   Each time it runs it then applies the loop tick's learning samples
//!   (`LearnState::run`, the learning below the tick).
//! * The two handlers share only `SHARED` (atomics, `zslide::firmware`).
//! * With the `modern-x` feature X is instead a count (0.5 µin per count),
//!   moving at the same 20 in/min from 2.0 in, that timer 1 hands to
//!   `EventState::x_count_event` each time it runs (a new count every time,
//!   so it re-interpolates every time: the worst case of that mode) before
//!   it plays the index pulses; check 2 asks for no X events and the
//!   loop's coefficients at the last count's X.
//!
//! World time is the loop tick count × 50 µs (the firmware's clock counts
//! 25 MHz from it), so the run and its log are deterministic. defmt goes out
//! over semihosting; the run ends with a semihosting exit, status 0 when
//! every check passed. Checks:
//! 1. no fault; the slide (its gauge reading) follows the table's command within
//!    [`TRACK_BOUND`] gauge codes (or 2 % of the command's swing, if more)
//!    over ticks [`TRACK_FROM`]..=[`INJECT_AT`];
//!    the command is a real one (its swing exceeds [`MIN_SWING`]);
//! 2. every X event was accepted or ignored as scripted, the loop tick took
//!    every published coefficient set, and ends with the coefficients of the
//!    last X; every index pulse arrived;
//! 3. a gauge bus error injected after tick [`INJECT_AT`] latches
//!    `Fault::Bus(GaugeAdc)`, clamps the DAC, drops the amplifier enable, and
//!    no DAC write follows;
//! 4. the timer interrupt ran exactly [`TICKS`] times and the firmware
//!    counted as many.
#![no_std]
#![no_main]

mod link;
mod plant;

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m::peripheral::NVIC;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use critical_section::Mutex;
use defmt_semihosting as _;

use plant::{Dac, DacSpi, GaugeSpi, Plant};
use zslide::drivers::{ad4020::Ad4020, ad5791::Ad5791};
use zslide::firmware::{
    EventState, Firmware, FirmwareConfig, LearnState, LoopState, NoCoefficientDac, Request, Shared,
    SpindleMode, SpindleReading, TickInput, XMode,
};
use zslide::handoff::handover::Handover;
use zslide::hw::EncoderSample;
use zslide::link::proto::{
    CaptureState, Reply, Request as HostRequest, SpindleSource, Trigger, XSource,
};
use zslide::link::station::{Station, StationConfig};
use zslide::link::tap::TickTap;
use zslide::params::{self, ParamSource};
use zslide::safety::{Device, Fault};
use zslide::servo::ServoDesign;
use zslide::spindle::EncoderConfig;
use zslide::trace::{Event, Outputs};
use zslide::units::SpindleAngle;
use zslide::xpos::{half_mils_to_x, latch_word, CountConfig, CountX};
use zslide_qemu::board::{enable, interrupt, Interrupt, PCLK_HZ, TIMER0_LOOP, TIMER1_EVENTS};
use zslide_qemu::exit;
use zslide_qemu::trace;

/// Loop-tick rate, Hz (the real board's rate).
const LOOP_HZ: u32 = 20_000;
/// Firmware clock (`hw::Clock`): 25 MHz, 1250 counts per loop tick.
const CLOCK_HZ: u32 = 25_000_000;
const CLOCK_PER_TICK: u32 = CLOCK_HZ / LOOP_HZ;
/// Loop ticks the run lasts (0.3 s of world time; the loop tracks the
/// table for 0.23 s of it, ticks [`TRACK_FROM`]..=[`INJECT_AT`]).
const TICKS: u32 = 6_000;
/// The gauge bus breaks after this tick.
const INJECT_AT: u32 = 5_600;
/// Tracking is checked from this tick to [`INJECT_AT`].
const TRACK_FROM: u32 = 1_001;
/// Tracking bound: 500 gauge codes = 9.5 µin (measured: 469,
/// `expected.log`; 156 with the coil inductance set to nil, measured when
/// the figure was 448 and not since: most of the error is the 0.26 ms electrical
/// lag the servo's feedforward does not invert, 7.5° at 80 Hz). The servo
/// follows the table here mostly on its plant-inverse feedforward and 45 Hz
/// feedback (at 1200 rpm the part's harmonics are at 40-80 Hz; the
/// learning acts a revolution later and is not what this short run
/// measures), and the plant (host-sim's model: coil inductance, 3150 Hz
/// mode, 8.5 µs DAC latency, modern gauge noise of 0.2 µin RMS = 10 codes
/// in the position read here) is not the rigid model the feedforward
/// inverts. The host-sim tests hold the servo to its real figures; this
/// run proves the same loop closes on the target with the same plant.
const TRACK_BOUND: u32 = 500;
/// The bound grows with the command beyond that: the part of the error the
/// feedforward leaves is proportional to the command (a linear mismatch of
/// a linear plant), so a table of another part is held to the same 2 % of
/// its swing (the default table: 469 codes = 2.0 % of 23 135, under the
/// 500-code floor; a 160 in
/// focal length at 1200 rpm swings 89 705 codes).
const TRACK_BOUND_OF_SWING_PERCENT: u32 = 2;
/// The command must swing at least this much (codes; 1 µin = 52.4 codes).
const MIN_SWING: i32 = 5_000;
/// The slide rests here at power-up, gauge codes (−0.001 in).
const START_CODE: i32 = -52_429;

/// Synthetic spindle: 1200 rpm, 4096 counts per turn, the first index at
/// count [`INDEX0`], then every turn.
const RPM: u64 = 1_200;
const CPR: u32 = 4_096;
const INDEX0: u32 = 300;
/// Synthetic X feed: from 2.0000 in, one half-mil every [`X_EVERY`] ticks
/// (0.0005 in / 1.5 ms = 20 in/min) from tick [`X_FIRST`].
const X_START_HM: u32 = 4_000;
const X_FIRST: u32 = 10;
const X_EVERY: u32 = 30;
/// Modern X (`modern-x`): counts per inch of the X count (0.5 µin each),
/// 1000 counts per half-mil.
const X_COUNTS_PER_INCH: i32 = 2_000_000;
const X_COUNT_CFG: CountConfig = CountConfig {
    counts_per_inch: X_COUNTS_PER_INCH,
    zero_count: 0,
    max_step_counts: 1_000,
};
/// Events (by number) that the latch repeats right away: debounced.
const DUPLICATES: [u32; 4] = [15, 45, 75, 105];
/// From this event on the feed reverses one half-mil and resumes.
const REVERSAL: u32 = 60;
/// No machine events after this tick (the bus-error phase follows).
const EVENTS_UNTIL: u32 = INJECT_AT - 100;
/// Ticks at which the handler records a trace sample for the log.
const TRACE_AT: [u32; 14] = [
    1, 50, 100, 200, 400, 800, 1600, 2400, 3200, 4000, 4800, 5600, 5601, 6000,
];

/// World time in loop ticks, published by the loop tick.
static WORLD_TICK: AtomicU32 = AtomicU32::new(0);

defmt::timestamp!(
    "{=u32:us}",
    WORLD_TICK.load(Ordering::Relaxed) * (1_000_000 / LOOP_HZ)
);

/// Spindle count at clock time `t`.
fn spindle_count(t: u64) -> u32 {
    (t * RPM * u64::from(CPR) / (60 * u64::from(CLOCK_HZ))) as u32
}
/// Clock time of the edge that brought count `c` (first instant at it).
fn spindle_edge(c: u32) -> u64 {
    let per = RPM * u64::from(CPR);
    (u64::from(c) * 60 * u64::from(CLOCK_HZ)).div_ceil(per)
}
/// The encoder reading at clock time `t`.
fn encoder_at(t: u64) -> EncoderSample {
    let count = spindle_count(t);
    EncoderSample {
        count,
        edge_ticks: spindle_edge(count) as u32,
    }
}
/// Half-mil position of X event number `i`.
fn x_script(i: u32) -> u32 {
    if i < REVERSAL {
        X_START_HM + i
    } else {
        X_START_HM + i - 2
    }
}
/// Tick of X event number `i`.
fn x_tick(i: u32) -> u32 {
    X_FIRST + X_EVERY * i
}
/// X events scheduled before [`EVENTS_UNTIL`] (none with a counted X).
fn x_events() -> u32 {
    if cfg!(feature = "modern-x") {
        return 0;
    }
    (EVENTS_UNTIL - X_FIRST).div_ceil(X_EVERY)
}
/// The X count at loop tick `n` (`modern-x`): the same 20 in/min from
/// 2.0000 in as the legacy script (one half-mil per [`X_EVERY`] ticks from
/// tick [`X_FIRST`]), continuous, until [`EVENTS_UNTIL`].
fn x_count_at(n: u32) -> u32 {
    let per_hm = (X_COUNTS_PER_INCH / 2000) as u32;
    let moved = n.clamp(X_FIRST, EVENTS_UNTIL) - X_FIRST;
    X_START_HM * per_hm + moved * per_hm / X_EVERY
}
/// Index pulses before [`EVENTS_UNTIL`].
fn index_pulses() -> u32 {
    let until = u64::from(EVENTS_UNTIL) * u64::from(CLOCK_PER_TICK);
    (0..16)
        .filter(|m| spindle_edge(INDEX0 + CPR * m) <= until)
        .count() as u32
}

#[derive(Clone, Copy, Default, defmt::Format)]
struct Sample {
    tick: u32,
    /// X of the coefficients and the spindle angle the table command was
    /// evaluated at (`cargo xtask test` recomputes it on the host).
    x_bits: i32,
    phi: u32,
    table: i32,
    command: i32,
    position: i32,
    output: i32,
}

/// What the loop-tick handler saw, published once at the end of the run.
#[derive(Clone, Copy, Default)]
struct Summary {
    fw_ticks: u32,
    fault_before: Option<Fault>,
    track_max_error: u32,
    table_min: i32,
    table_max: i32,
    coeff_x_bits: i32,
    coeff_null: bool,
    fault_after: Option<Fault>,
    dac_clamped: bool,
    amplifier_enable: bool,
    writes_at_inject: u32,
    writes_at_end: u32,
    /// Plant steps the generated discretisations could not take (`plant.rs`).
    plant_missing_steps: u64,
    trace: [Sample; TRACE_AT.len()],
}

/// Everything the loop-tick handler owns.
///
/// `repr(C)`, the loop's state first: a field more than 4 KiB into it (the
/// 40 KiB plant was laid out first) needs its offset built in a register
/// (`movw`) on every access; within the first 4 KiB the offset is the
/// load's own 12-bit immediate.
#[repr(C)]
struct Run {
    lp: LoopState,
    tap: TickTap,
    plant: Plant,
    gauge: Ad4020<GaugeSpi>,
    dac: Ad5791<DacSpi>,
    summary: Summary,
    traced: usize,
    outputs: Outputs,
}

/// Everything the event handler owns.
///
/// `repr(C)`, the learner first, for the reason given at [`Run`]: the X
/// handler's state (8.7 KiB with its slope table) would otherwise put it
/// beyond the loads' 12-bit offsets.
#[repr(C)]
struct Events {
    learn: LearnState,
    ev: EventState,
    next_x: u32,
    next_index: u32,
    /// Coefficient generation last traced.
    generation: u32,
}

static SHARED: Shared = Shared::new();
/// Hands the parts to the handlers once, before their interrupts are
/// unmasked: each is one `.bss` value (`cortex_m::singleton!`) handed over by
/// reference, as on the NUCLEO (`zslide::handoff::handover`).
static RUN_HANDOVER: Handover<Run> = Handover::new();
static EVENTS_HANDOVER: Handover<Events> = Handover::new();
static RESULT: Mutex<Cell<Option<Summary>>> = Mutex::new(Cell::new(None));
static ISR_COUNT: AtomicU32 = AtomicU32::new(0);
/// DAC writes of the boot (`Ad5791::init`), before any loop tick.
static BOOT_DAC_WRITES: AtomicU32 = AtomicU32::new(0);
static DONE: AtomicBool = AtomicBool::new(false);
/// A link session (`link::session_requested`): no scripted injection, no
/// end; the host drives the loop.
static SESSION: AtomicBool = AtomicBool::new(false);
/// The fault-path check (`cargo xtask qemu`, xtask `faultpath`): with the
/// semihosting argument `hardfault` the loop tick executes a permanently
/// undefined instruction at tick [`FAULT_AT`]; with `panic` the background
/// panics once the loop tick has passed it. Either way the real handler
/// must drop the amplifier-enable output before anything else.
static INJECT: AtomicU32 = AtomicU32::new(INJECT_NONE);
const INJECT_NONE: u32 = 0;
const INJECT_HARDFAULT: u32 = 1;
const INJECT_PANIC: u32 = 2;
/// The loop is engaged and tracking there (the amplifier enabled).
const FAULT_AT: u32 = 3_000;

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

#[entry]
fn main() -> ! {
    let session = link::session_requested();
    SESSION.store(session, Ordering::Relaxed);
    if link::argument(b"hardfault") {
        INJECT.store(INJECT_HARDFAULT, Ordering::Relaxed);
    } else if link::argument(b"panic") {
        INJECT.store(INJECT_PANIC, Ordering::Relaxed);
    }
    defmt::info!(
        "zslide on QEMU mps2-an386: loop tick {=u32} Hz (CMSDK timer 0, IRQ 8), machine events on timer 1 (IRQ 9), {=u32} ticks",
        LOOP_HZ,
        TICKS
    );
    // Servo parameters: the parameter region's block on the built-in
    // design, or the built-in design with the block's refusal latched.
    let base = ServoDesign::brief(LOOP_HZ);
    let Ok((design, loop_cfg, param_source)) = params::at_boot(link::params_region(), &base) else {
        defmt::error!("FAIL: servo design refused");
        exit(false);
    };
    let cfg = FirmwareConfig {
        loop_cfg,
        spindle: SpindleMode::Encoder(EncoderConfig {
            counts_per_rev: CPR,
            ticks_per_s: CLOCK_HZ,
            min_rpm: 60,
            max_rpm: 3_000,
            // The index reaches the firmware up to two loop ticks late here
            // (timer 1 plays it back); the phase comes from the latched count.
            index_tolerance_counts: 32,
            index_angle: SpindleAngle(0),
            edge_stamps: zslide::spindle::EdgeStamps::Captured,
        }),
        x: if cfg!(feature = "modern-x") {
            XMode::Count(X_COUNT_CFG)
        } else {
            XMode::Legacy { clock_hz: CLOCK_HZ }
        },
        coefficient_output: false,
        gauge_reversed: false,
    };
    defmt::info!("loop config: {}", cfg.loop_cfg);
    // The table region (`memory.x`: 0x0030_0000), written by QEMU's
    // `-device loader`; parsed and sign-checked here.
    let Ok(fw) = Firmware::with_table_region(link::table_region(), cfg) else {
        defmt::error!("FAIL: configuration refused");
        exit(false);
    };
    let table = fw.table_identity();
    if let (Some(g), Ok(id)) = (fw.command_gen(), &table) {
        let h = g.interpolator().table().header();
        defmt::info!(
                "table: {=u8} terms {}, {=u32} nodes, null from {}; c {=i64} nin, S_y {=i64} nin, tool radius {=i64} nin; {=u32} bytes, CRC {=u32:#010x}",
                h.terms,
                h.representation,
                h.node_count,
                g.x_null(),
                id.geometry.c_nin,
                id.geometry.s_y_nin,
                id.geometry.tool_radius_nin,
                id.len,
                id.crc
            );
    }
    if let Err(e) = &table {
        defmt::error!(
            "coefficient table refused, slide held at null: {}",
            defmt::Display2Format(e)
        );
    }
    let (mut lp, ev, learn) = fw.into_parts();
    match param_source {
        ParamSource::Refused(e) => {
            defmt::error!("servo parameter block refused, amplifier kept off: {}", e);
            lp.trip(Fault::Parameters(e));
        }
        ParamSource::Block { entries, crc } => {
            defmt::info!(
                "servo parameters: block of {=u16} entries, CRC {=u32:#010x}",
                entries,
                crc
            )
        }
        ParamSource::BuiltIn => {}
    }
    let mut station: Station<{ link::CAPTURE }> = Station::new(StationConfig {
        loop_hz: LOOP_HZ,
        x_source: if cfg!(feature = "modern-x") {
            XSource::Count
        } else {
            XSource::LegacyHalfMil
        },
        spindle_source: SpindleSource::Encoder,
        table,
        design,
        params: param_source,
    });
    let mut dac = Ad5791::new(DacSpi::new());
    if dac.init().is_err() {
        lp.trip(Fault::Bus(Device::AmplifierDac));
    }
    // The boot's own writes (the init's): the refused-parameters check
    // counts the loop's writes after them.
    BOOT_DAC_WRITES.store(Dac::writes(), Ordering::Relaxed);
    let plant = Plant::new(
        f64::from(START_CODE) / zslide::codes::GAUGE_CODES_PER_INCH,
        LOOP_HZ,
    );
    defmt::info!(
        "plant: slide at {=i32} codes (0.001 in = 52429), zslide-plant Model 15 with the 3150 Hz mode, modern gauge; spindle {=u32} rpm, {=u32} counts/turn; X from {=u32} half-mils, one every {=u32} ticks",
        plant.gauge_code(),
        RPM as u32,
        CPR,
        X_START_HM,
        X_EVERY
    );
    let run = Run {
        lp,
        tap: TickTap::new(),
        plant,
        gauge: Ad4020::new(GaugeSpi),
        dac,
        summary: Summary::default(),
        traced: 0,
        outputs: Outputs::new(),
    };
    let events = Events {
        ev,
        learn,
        next_x: 0,
        next_index: 0,
        generation: 0,
    };
    // `None` only on a second run of this code, which cannot happen (main
    // never returns); that handler would then stay idle.
    RUN_HANDOVER.give(cortex_m::singleton!(: Run = run));
    EVENTS_HANDOVER.give(cortex_m::singleton!(: Events = events));

    // SAFETY: unmasking can break a critical section that relies on masking
    // these interrupts; none does: the handlers share data with `main` only
    // through the hand-over and `RESULT` (critical-section cells) and atomics, and with each other
    // only through `SHARED` (atomics).
    unsafe {
        let mut cp = cortex_m::Peripherals::steal();
        cp.NVIC.set_priority(Interrupt::TIMER0, 0x00);
        cp.NVIC.set_priority(Interrupt::TIMER1, 0x80);
        NVIC::unmask(Interrupt::TIMER0);
        NVIC::unmask(Interrupt::TIMER1);
    }
    // The operator's arm: the loop runs its sign check on the slide model,
    // then engages bumpless (the amplifier never enables on its own). In a
    // link session the host arms.
    if !session {
        SHARED.request(Request::Arm);
    }
    trace::start();
    TIMER0_LOOP.start_periodic(PCLK_HZ / LOOP_HZ);
    // Not a multiple of the loop period: the event handler runs at every
    // phase of the loop tick and is preempted by it.
    TIMER1_EVENTS.start_periodic(PCLK_HZ / LOOP_HZ * 2 + 377);
    if session {
        defmt::info!("link session: frames on UART0, until QEMU stops");
        let mut uart = link::Uart0::new();
        loop {
            station.poll(&link::TAP, &SHARED, &mut uart);
            cortex_m::asm::wfi();
        }
    }

    // The scripted host arms a capture of the first 1024 ticks: the loop
    // runs (and is checked, and its cost counted) with the tap recording.
    let mut host = link::Script::new();
    host.send(&HostRequest::CaptureStart {
        samples: link::CAPTURE as u16,
        pre: 0,
        trigger: Trigger::Immediate,
    });
    // Give up after 100 000 idle wake-ups (the run needs ~9000).
    let mut waits = 0u32;
    while !DONE.load(Ordering::Acquire) {
        if INJECT.load(Ordering::Relaxed) == INJECT_PANIC
            && ISR_COUNT.load(Ordering::Relaxed) >= FAULT_AT
        {
            panic!("injected in the background at tick {}", FAULT_AT);
        }
        station.poll(&link::TAP, &SHARED, &mut host);
        waits += 1;
        if waits > 100_000 {
            defmt::error!(
                "FAIL: the loop-tick interrupt stalled after {=u32} ticks",
                ISR_COUNT.load(Ordering::Relaxed)
            );
            exit(false);
        }
        cortex_m::asm::wfi();
    }
    NVIC::mask(Interrupt::TIMER1);

    let Some(s) = critical_section::with(|cs| RESULT.borrow(cs).get()) else {
        defmt::error!("FAIL: no summary from the loop-tick handler");
        exit(false);
    };
    for t in s.trace.iter() {
        defmt::info!(
            "tick {=u32}: X {=i32} phi {=u32} table {=i32}  command {=i32}  position {=i32}  dac {=i32}",
            t.tick,
            t.x_bits,
            t.phi,
            t.table,
            t.command,
            t.position,
            t.output
        );
    }
    let mut ok = true;
    // A refused (or missing) table: the checks become "held at null".
    let refused = matches!(s.fault_before, Some(Fault::Table(_)));
    // A refused parameter block: the amplifier is never enabled and the
    // DAC never written; the slide stays where it rests.
    let params_refused = matches!(s.fault_before, Some(Fault::Parameters(_)));

    let swing = s.table_max.saturating_sub(s.table_min);
    let bound = TRACK_BOUND.max(swing.unsigned_abs() / 100 * TRACK_BOUND_OF_SWING_PERCENT);
    defmt::info!(
        "tracking: max |command - position| = {=u32} codes over ticks {=u32}..={=u32} (bound {=u32}; 1 code = 0.019 uin); table command {=i32}..{=i32} codes (swing bound {=i32}); fault {}",
        s.track_max_error,
        TRACK_FROM,
        INJECT_AT,
        bound,
        s.table_min,
        s.table_max,
        MIN_SWING,
        s.fault_before
    );
    if params_refused {
        // Undriven, the slide stays at rest: the modern gauge's noise is
        // 10 codes RMS, a driven move is thousands (the table swings 23 135).
        const AT_REST: u32 = 500;
        let moved = s
            .trace
            .iter()
            .map(|t| t.position.abs_diff(START_CODE))
            .max()
            .unwrap_or(u32::MAX);
        let loop_writes = Dac::writes().wrapping_sub(BOOT_DAC_WRITES.load(Ordering::Relaxed));
        let off = loop_writes == 0 && s.dac_clamped && !s.amplifier_enable && moved <= AT_REST;
        defmt::info!(
            "refused parameters: fault {}, DAC writes by the loop {=u32}, DAC clamped {=bool}, amplifier enable {=bool}, slide moved at most {=u32} codes from rest",
            s.fault_before,
            loop_writes,
            s.dac_clamped,
            s.amplifier_enable,
            moved
        );
        if !off {
            defmt::error!("FAIL: the amplifier was driven with the parameter block refused");
            ok = false;
        }
    } else if refused {
        let held = s.table_min == 0 && s.table_max == 0 && s.track_max_error <= TRACK_BOUND;
        defmt::info!(
            "refused table: table command {=i32}..{=i32}, slide within {=u32} codes of the null command (bound {=u32})",
            s.table_min,
            s.table_max,
            s.track_max_error,
            TRACK_BOUND
        );
        if !held {
            defmt::error!("FAIL: the slide was not held at null with the table refused");
            ok = false;
        }
    } else if s.fault_before.is_some() || s.track_max_error > bound || swing < MIN_SWING {
        defmt::error!("FAIL: the loop did not follow the table's command");
        ok = false;
    }

    let scheduled = x_events();
    let dups = DUPLICATES.iter().filter(|&&i| i < scheduled).count() as u32;
    let last_x = match (scheduled.checked_sub(1), CountX::new(X_COUNT_CFG)) {
        (Some(last), _) => half_mils_to_x(x_script(last)),
        (None, Some(cx)) => cx.x(x_count_at(INJECT_AT)),
        (None, None) => zslide::units::XInches::ZERO,
    };
    let (accepted, ignored) = (SHARED.x_accepted(), SHARED.x_ignored());
    defmt::info!(
        "X events: {=u32} accepted, {=u32} ignored (scripted {=u32} + {=u32} duplicates); {=u32} coefficient sets published; loop coefficients at {} (last X {}), null {=bool}",
        accepted,
        ignored,
        scheduled,
        dups,
        SHARED.coefficient_generation(),
        zslide::units::XInches::from_bits(s.coeff_x_bits),
        last_x,
        s.coeff_null
    );
    // Modern X publishes a set per count instead of per X event.
    let sets_ok = if cfg!(feature = "modern-x") {
        SHARED.coefficient_generation() > 0
    } else {
        SHARED.coefficient_generation() == scheduled
    };
    if accepted != scheduled
        || ignored != dups
        || !sets_ok
        || (!refused && (s.coeff_x_bits != last_x.to_bits() || s.coeff_null))
    {
        defmt::error!("FAIL: X events not handled as scripted");
        ok = false;
    }
    let pulses = index_pulses();
    defmt::info!(
        "index events: {=u32} (scripted {=u32})",
        SHARED.index_events(),
        pulses
    );
    if SHARED.index_events() != pulses {
        defmt::error!("FAIL: index pulses lost");
        ok = false;
    }

    let writes_after = s.writes_at_end.wrapping_sub(s.writes_at_inject);
    defmt::info!(
        "gauge bus error after tick {=u32}: fault {}, DAC clamped {=bool}, amplifier enable {=bool}, DAC writes since {=u32}",
        INJECT_AT,
        s.fault_after,
        s.dac_clamped,
        s.amplifier_enable,
        writes_after
    );
    // With the parameter block refused, the more severe fault is already
    // latched (same reaction) and holds.
    let expected_after = if params_refused {
        s.fault_before
    } else {
        Some(Fault::Bus(Device::GaugeAdc))
    };
    let reacted = s.fault_after == expected_after
        && s.dac_clamped
        && !s.amplifier_enable
        && writes_after == 0;
    if !reacted {
        defmt::error!("FAIL: wrong reaction to the gauge bus error");
        ok = false;
    }
    // 5. The capture holds what the loop did: at a traced tick inside it,
    // the recorded command, output, X and φ are the traced ones.
    let mut ask = |r: HostRequest| {
        host.send(&r);
        (0..100).find_map(|_| {
            station.poll(&link::TAP, &SHARED, &mut host);
            host.reply()
        })
    };
    let captured = match ask(HostRequest::CaptureInfo) {
        Some(Reply::Capture(c)) if c.state == CaptureState::Done => Some(c),
        _ => None,
    };
    let probe = s.trace.iter().find(|t| t.tick == 800);
    let same = match (captured, probe) {
        (Some(c), Some(t)) => {
            match ask(HostRequest::CaptureRead {
                from: (t.tick - c.trigger_tick) as u16,
            }) {
                Some(Reply::Samples { samples, .. }) => samples.first().is_some_and(|x| {
                    (x.command, x.output, x.x_bits, x.phi) == (t.command, t.output, t.x_bits, t.phi)
                }),
                _ => false,
            }
        }
        _ => false,
    };
    defmt::info!(
        "capture: {=u16} loop ticks from tick {=u32} recorded while the loop ran; at tick 800 it holds the traced command, output, X and phi: {=bool}",
        captured.map_or(0, |c| c.recorded),
        captured.map_or(0, |c| c.trigger_tick),
        same
    );
    if !same || captured.map(|c| c.recorded) != Some(link::CAPTURE as u16) {
        defmt::error!("FAIL: the capture does not hold the loop's samples");
        ok = false;
    }

    let isr = ISR_COUNT.load(Ordering::Relaxed);
    defmt::info!(
        "loop-tick interrupt ran {=u32} times, firmware counted {=u32} (expected {=u32})",
        isr,
        s.fw_ticks,
        TICKS
    );
    if isr != TICKS || s.fw_ticks != TICKS {
        defmt::error!("FAIL: wrong tick count");
        ok = false;
    }
    if s.plant_missing_steps != 0 {
        defmt::error!(
            "FAIL: the plant skipped {=u64} steps (no generated discretisation)",
            s.plant_missing_steps
        );
        ok = false;
    }
    if ok {
        defmt::info!("PASS");
    }
    exit(ok)
}

// cortex-m-rt requires the HardFault handler to be an `unsafe fn`; its body
// does nothing unsafe itself.
// Both fault paths make the outputs safe first (interrupts masked, the
// enable output dropped), then log what the output held before and holds
// now, read back from the device.
#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    let was = zslide_qemu::outputs_safe();
    defmt::error!(
        "FAIL: hard fault at pc {=u32:#010x}; amplifier enable output was high {=bool}, now high {=bool} (read back)",
        ef.pc(),
        was,
        enable::is_high()
    );
    exit(false)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    let was = zslide_qemu::outputs_safe();
    TIMER0_LOOP.stop();
    TIMER1_EVENTS.stop();
    defmt::error!(
        "FAIL: panic: {}; amplifier enable output was high {=bool}, now high {=bool} (read back)",
        defmt::Display2Format(info),
        was,
        enable::is_high()
    );
    exit(false)
}
