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
//!    [`checks::TRACK_BOUND`] gauge codes (or 2 % of the command's swing, if more)
//!    over ticks [`scenario::TRACK_FROM`]..=[`scenario::INJECT_AT`];
//!    the command is a real one (its swing exceeds [`checks::MIN_SWING`]);
//! 2. every X event was accepted or ignored as scripted, the loop tick took
//!    every published coefficient set, and ends with the coefficients of the
//!    last X; every index pulse arrived;
//! 3. a gauge bus error injected after tick [`scenario::INJECT_AT`] latches
//!    `Fault::Bus(GaugeAdc)`, clamps the DAC, drops the amplifier enable, and
//!    no DAC write follows;
//! 4. the timer interrupt ran exactly [`scenario::TICKS`] times and the firmware
//!    counted as many;
//! 5. the host link's capture holds what the loop did.
//!
//! The modules by concern: `scenario` (the synthetic machine and the run's
//! script), `tick` (the loop-tick handler), `events` (the machine-event
//! handler), `checks` (the checks above, after the run), `plant` (the slide
//! model behind the converters' SPI frames), `link` (the host link's
//! transports and regions); this file boots the firmware, hands each
//! handler its state and runs the background.
#![no_std]
#![no_main]

mod checks;
mod events;
mod flash;
mod link;
mod plant;
mod powercut;
mod scenario;
mod tick;

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m::peripheral::NVIC;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use defmt_semihosting as _;

use events::{Events, EVENTS_HANDOVER};
use plant::{Dac, DacSpi, GaugeSpi, Plant};
use scenario::{
    CLOCK_HZ, CPR, FAULT_AT, LOOP_HZ, RPM, START_CODE, TICKS, X_COUNT_CFG, X_EVERY, X_START_HM,
};
use tick::{Run, Summary, DONE, ISR_COUNT, RESULT, RUN_HANDOVER};
use zslide::drivers::{ad4020::Ad4020, ad5791::Ad5791};
use zslide::firmware::{Firmware, FirmwareConfig, Request, Shared, SpindleMode, XMode};
use zslide::link::proto::{Request as HostRequest, SpindleSource, Trigger, XSource};
use zslide::link::station::{Station, StationConfig};
use zslide::link::tap::TickTap;
use zslide::params::ParamSource;
use zslide::safety::{Device, Fault};
use zslide::servo::ServoDesign;
use zslide::spindle::EncoderConfig;
use zslide::store::{self, ram::BANK2_REGION_BYTES, Store};
use zslide::trace::Outputs;
use zslide::units::SpindleAngle;
use zslide_qemu::board::{enable, Interrupt, PCLK_HZ, TIMER0_LOOP, TIMER1_EVENTS};
use zslide_qemu::exit;
use zslide_qemu::trace;

/// What the two handlers share (atomics, `zslide::firmware`).
pub(crate) static SHARED: Shared = Shared::new();
/// DAC writes of the boot (`Ad5791::init`), before any loop tick.
pub(crate) static BOOT_DAC_WRITES: AtomicU32 = AtomicU32::new(0);
/// A link session (`link::session_requested`): no scripted injection, no
/// end; the host drives the loop.
pub(crate) static SESSION: AtomicBool = AtomicBool::new(false);
/// The fault-path check (`cargo xtask qemu`, xtask `faultpath`): with the
/// semihosting argument `hardfault` the loop tick executes a permanently
/// undefined instruction at tick [`FAULT_AT`]; with `panic` the background
/// panics once the loop tick has passed it. Either way the real handler
/// must drop the amplifier-enable output before anything else.
pub(crate) static INJECT: AtomicU32 = AtomicU32::new(INJECT_NONE);
pub(crate) const INJECT_NONE: u32 = 0;
pub(crate) const INJECT_HARDFAULT: u32 = 1;
pub(crate) const INJECT_PANIC: u32 = 2;

#[entry]
fn main() -> ! {
    // A power-cut run's save (`powercut.rs`) runs as a session does: no
    // arm, no scripted fault, no end but its own.
    let save = link::argument(b"save");
    let session = link::session_requested() || save;
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
    // Servo parameters (`zslide::store::boot`, as the NUCLEO): the store's
    // last saved block on the flash model, else the parameter region's
    // block, on the built-in design; or the built-in design with the
    // refusal latched. The model is erased unless a power-cut run keeps it
    // in a file (`flash`).
    let persist = link::argument(b"flash");
    let Some(flash) = flash::ImageFlash::boot(persist, link::value(b"cut=")) else {
        defmt::error!("FAIL: the parameter flash model could not be set up");
        exit(false);
    };
    let mut store = match Store::new(flash, 0..BANK2_REGION_BYTES as u32) {
        Ok(s) => s,
        Err(e) => powercut::refused(e),
    };
    let base = ServoDesign::brief(LOOP_HZ);
    let Ok((design, loop_cfg, param_source)) =
        store::boot::at_boot(&mut store, link::params_region(), &base)
    else {
        defmt::error!("FAIL: servo design refused");
        exit(false);
    };
    if persist {
        powercut::report_boot(&design, &param_source, store.flash().ops());
    }
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
    let Ok(mut fw) = Firmware::with_table_region(link::table_region(), cfg) else {
        defmt::error!("FAIL: configuration refused");
        exit(false);
    };
    // The part's interruption block: the interruption region's (`memory.x`:
    // 0x0038_1000, QEMU's loader, as `zslide table flash F.zsib` writes the
    // NUCLEO's), parsed here; a refused one is refused in words and the cut
    // runs without the edges' anticipation. With none there, the checked
    // run takes its scenario's part (`scenario::HOLES`); a link session a
    // whole face.
    match fw.set_interruptions_region(link::interruptions_region()) {
        Ok(Some(n)) => defmt::info!("interruption block (region): {=usize} holes", n),
        Ok(None) if session => defmt::info!("no interruption block: a whole face"),
        Ok(None) => match fw.set_interruptions(&scenario::interruption_block()) {
            Ok(()) => {
                let h = scenario::HOLES[0];
                defmt::info!(
                    "interruption block (the scenario's part): {=usize} holes of {=u32} uin on a {=u32} uin circle",
                    scenario::HOLES.len(),
                    h.diameter_uin,
                    h.centre_radius_uin
                );
            }
            Err(e) => {
                defmt::error!(
                    "FAIL: the scenario's interruption block refused: {}",
                    defmt::Display2Format(&e)
                );
                exit(false);
            }
        },
        Err(e) => defmt::error!(
            "interruption block refused, the cut runs without the edges' anticipation: {}",
            defmt::Display2Format(&e)
        ),
    }
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
    if save {
        powercut::save(&mut station, &SHARED, &mut store);
    }
    if session {
        defmt::info!("link session: frames on UART0, until QEMU stops");
        let mut uart = link::Uart0::new();
        loop {
            station.poll_with_store(&link::TAP, &SHARED, &mut uart, &mut store);
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
        station.poll_with_store(&link::TAP, &SHARED, &mut host, &mut store);
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
    let ok = checks::report(&s, &mut station, &mut host);
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
