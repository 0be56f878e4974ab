//! The Z-slide firmware on the emulated board: QEMU `mps2-an386`
//! (Cortex-M4F). CMSDK timer 0 interrupts at the loop rate; its handler runs
//! the same `Firmware::loop_tick` as the NUCLEO-H743ZI2, against the plant
//! model in `plant.rs` instead of converters. defmt goes out over semihosting
//! (timestamps from timer 1), and the run ends with a semihosting exit:
//! status 0 when every check below passed, 1 otherwise.
//!
//! The run: the slide rests at −0.001 in; the loop engages there (bumpless)
//! and ramps the command to +0.001 in at the slew limit against a 5 mV
//! amplifier offset. Checks, in order:
//! 1. no fault and |command − position| ≤ [`SETTLE_BOUND`] codes over the
//!    [`SETTLE_WINDOW`] ticks before [`INJECT_AT`], command on target;
//! 2. a gauge bus error injected after tick [`INJECT_AT`] latches
//!    `Fault::Bus(GaugeAdc)`, clamps the DAC, drops the amplifier enable, and
//!    no DAC write follows;
//! 3. the interrupt ran exactly [`TICKS`] times and the firmware counted as
//!    many.
#![no_std]
#![no_main]

mod board;
mod plant;

use core::cell::Cell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m::peripheral::NVIC;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use cortex_m_semihosting::debug;
use critical_section::Mutex;
use defmt_semihosting as _;

use board::{interrupt, Interrupt, PCLK_HZ, TIMER0_LOOP, TIMER1_STAMP};
use plant::{Dac, Plant};
use zslide::firmware::{Firmware, LoopConfig};
use zslide::safety::{Device, Fault};

/// Loop-tick rate, Hz (the real board's rate).
const LOOP_HZ: u32 = 20_000;
/// Loop ticks the run lasts (0.1 s of virtual time).
const TICKS: u32 = 2_000;
/// The gauge bus breaks after this tick.
const INJECT_AT: u32 = 1_600;
/// Ticks before the injection over which the loop must have settled.
const SETTLE_WINDOW: u32 = 200;
/// Settling bound: 8 gauge codes = 0.15 µin.
const SETTLE_BOUND: u32 = 8;
/// Start and target positions, gauge codes (52 429 codes = 0.001 in).
const START_CODE: i32 = -52_429;
const TARGET_CODE: i32 = 52_429;
/// Amplifier input offset of the plant, volts.
const OFFSET_V: f64 = 0.005;
/// Ticks at which the handler records a trace sample for the log.
const TRACE_AT: [u32; 12] = [1, 25, 50, 75, 100, 150, 200, 400, 800, 1600, 1601, 2000];

defmt::timestamp!("{=u32:us}", TIMER1_STAMP.elapsed() / (PCLK_HZ / 1_000_000));

#[derive(Clone, Copy, Default, defmt::Format)]
struct Sample {
    tick: u32,
    command: i32,
    position: i32,
    output: i32,
}

/// What the loop-tick handler saw, published once at the end of the run.
#[derive(Clone, Copy, Default)]
struct Summary {
    fw_ticks: u32,
    fault_before: Option<Fault>,
    settle_max_error: u32,
    on_target: bool,
    fault_after: Option<Fault>,
    dac_clamped: bool,
    amplifier_enable: bool,
    writes_at_inject: u32,
    writes_at_end: u32,
    trace: [Sample; TRACE_AT.len()],
}

/// Everything the loop-tick handler owns.
struct Run {
    fw: Firmware,
    plant: Plant,
    dac: Dac,
    summary: Summary,
    traced: usize,
}

/// Hands the run to the handler once, before its interrupt is unmasked.
static HANDOFF: Mutex<Cell<Option<Run>>> = Mutex::new(Cell::new(None));
static RESULT: Mutex<Cell<Option<Summary>>> = Mutex::new(Cell::new(None));
static ISR_COUNT: AtomicU32 = AtomicU32::new(0);
static DONE: AtomicBool = AtomicBool::new(false);

#[interrupt]
fn TIMER0() {
    static mut RUN: Option<Run> = None;
    TIMER0_LOOP.clear_interrupt();
    let n = ISR_COUNT.fetch_add(1, Ordering::Relaxed) + 1;
    if RUN.is_none() {
        *RUN = critical_section::with(|cs| HANDOFF.borrow(cs).take());
    }
    let Some(run) = RUN.as_mut() else {
        return;
    };

    run.fw.loop_tick(&zslide::firmware::TickInput::NONE, &mut run.plant, &mut run.dac);
    let enabled = run.fw.amplifier_enable();
    run.plant.step(run.dac.volts(), enabled);

    let s = &mut run.summary;
    let error = run.fw.command_code().abs_diff(run.plant.gauge_code());
    if n > INJECT_AT - SETTLE_WINDOW && n <= INJECT_AT {
        s.settle_max_error = s.settle_max_error.max(error);
    }
    if let Some(&at) = TRACE_AT.get(run.traced) {
        if at == n {
            if let Some(slot) = s.trace.get_mut(run.traced) {
                *slot = Sample {
                    tick: n,
                    command: run.fw.command_code(),
                    position: run.plant.gauge_code(),
                    output: run.fw.output_code(),
                };
            }
            run.traced += 1;
        }
    }
    if n == INJECT_AT {
        s.fault_before = run.fw.fault();
        s.on_target = run.fw.command_code() == run.fw.target_code();
        s.writes_at_inject = run.dac.writes;
        run.plant.gauge_bus_broken = true;
    }
    if n >= TICKS {
        // No further entry: timer off, its line masked and unpended.
        TIMER0_LOOP.stop();
        NVIC::mask(Interrupt::TIMER0);
        NVIC::unpend(Interrupt::TIMER0);
        s.fw_ticks = run.fw.ticks();
        s.fault_after = run.fw.fault();
        s.dac_clamped = run.dac.clamped();
        s.amplifier_enable = enabled;
        s.writes_at_end = run.dac.writes;
        let summary = *s;
        critical_section::with(|cs| RESULT.borrow(cs).set(Some(summary)));
        DONE.store(true, Ordering::Release);
    }
}

#[entry]
fn main() -> ! {
    TIMER1_STAMP.start_free_running();
    defmt::info!(
        "zslide on QEMU mps2-an386: loop tick {=u32} Hz from CMSDK timer 0 (IRQ 8), {=u32} ticks",
        LOOP_HZ,
        TICKS
    );
    let cfg = LoopConfig::at_rate(LOOP_HZ);
    defmt::info!("loop config: {}", cfg);
    let mut fw = Firmware::new(cfg);
    fw.set_target_code(TARGET_CODE);
    let plant = Plant::new(
        f64::from(START_CODE) / plant::CODES_PER_IN,
        OFFSET_V,
        LOOP_HZ,
    );
    defmt::info!(
        "plant: slide at {=i32} codes, target {=i32} codes (0.001 in = 52429), amplifier offset 5 mV",
        plant.gauge_code(),
        TARGET_CODE
    );
    let run = Run {
        fw,
        plant,
        dac: Dac::default(),
        summary: Summary::default(),
        traced: 0,
    };
    critical_section::with(|cs| HANDOFF.borrow(cs).set(Some(run)));

    // SAFETY: unmasking can break a critical section that relies on masking
    // this interrupt; none does: the handler shares data with `main` only
    // through `critical_section::Mutex` and atomics.
    unsafe {
        let mut cp = cortex_m::Peripherals::steal();
        cp.NVIC.set_priority(Interrupt::TIMER0, 0);
        NVIC::unmask(Interrupt::TIMER0);
    }
    TIMER0_LOOP.start_periodic(PCLK_HZ / LOOP_HZ);

    // Give up after 5 s of virtual time (the run needs 0.1 s).
    let started = TIMER1_STAMP.elapsed();
    while !DONE.load(Ordering::Acquire) {
        if TIMER1_STAMP.elapsed().wrapping_sub(started) > 5 * PCLK_HZ {
            defmt::error!(
                "FAIL: the loop-tick interrupt stalled after {=u32} ticks",
                ISR_COUNT.load(Ordering::Relaxed)
            );
            exit(false);
        }
        cortex_m::asm::wfi();
    }

    let Some(s) = critical_section::with(|cs| RESULT.borrow(cs).get()) else {
        defmt::error!("FAIL: no summary from the loop-tick handler");
        exit(false);
    };
    for t in s.trace.iter() {
        defmt::info!(
            "tick {=u32}: command {=i32}  position {=i32}  dac {=i32}",
            t.tick,
            t.command,
            t.position,
            t.output
        );
    }
    let mut ok = true;
    let settled = s.fault_before.is_none() && s.on_target && s.settle_max_error <= SETTLE_BOUND;
    defmt::info!(
        "settling: max |command - position| = {=u32} codes over ticks {=u32}..={=u32} (bound {=u32} codes; 1 code = 0.019 uin), on target {=bool}, fault {}",
        s.settle_max_error,
        INJECT_AT - SETTLE_WINDOW + 1,
        INJECT_AT,
        SETTLE_BOUND,
        s.on_target,
        s.fault_before
    );
    if !settled {
        defmt::error!("FAIL: the loop did not settle on its command");
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
    let reacted = s.fault_after == Some(Fault::Bus(Device::GaugeAdc))
        && s.dac_clamped
        && !s.amplifier_enable
        && writes_after == 0;
    if !reacted {
        defmt::error!("FAIL: wrong reaction to the gauge bus error");
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
    if ok {
        defmt::info!("PASS");
    }
    exit(ok)
}

fn exit(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::wfi();
    }
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    defmt::error!("FAIL: hard fault at pc {=u32:#010x}", ef.pc());
    exit(false)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    TIMER0_LOOP.stop();
    defmt::error!("FAIL: panic: {}", defmt::Display2Format(info));
    exit(false)
}
