//! An injected hang of each firmware handler trips the watchdog, on the
//! emulated Cortex-M4F with the board's real priorities and preemption.
//!
//! The handlers as on the NUCLEO: the loop tick (CMSDK timer 0, IRQ 8,
//! priority 0x00) runs `LoopState::loop_tick`; the X handler (timer 1,
//! IRQ 9) and the index handler (dual timer, IRQ 10) share the lower
//! priority 0x80 and run `EventState::x_event` / `index_event` on a
//! synthetic feed (a half-mil every 1.5 ms) and spindle (an index every
//! 20 ms, 3000 rpm). The background (thread mode) feeds the CMSDK watchdog (5 ms
//! timeout, its interrupt is the NMI) through `zslide::watchdog::FeedGate`,
//! as `src/main.rs` feeds the IWDG: only when the loop tick has run since
//! the last feed.
//!
//! Phases, each ended by the watchdog's NMI or by a 15 ms limit on the hang:
//! 0. 40 ms with every handler alive: the watchdog must not expire;
//! 1. the X handler hangs (spins) at its next event: the loop tick goes on
//!    preempting it (counted), the background is starved, the watchdog
//!    must expire within its 5 ms of the last feed;
//! 2. the same for the index handler;
//! 3. the same for the loop tick itself (everything below it starves);
//! 4. the loop tick stops firing (its timer stopped): the background runs
//!    on but the tick count stands still, and the watchdog must expire;
//! 5. the control: fed from the loop tick instead (the design the feed
//!    gate replaced), a hung X handler is not caught: the hang runs out
//!    its 15 ms without an expiry.
//!
//! The NMI handler stands for the reset the real watchdog causes: it
//! records the instant and releases the hang, so the next phase can run.
//! Exit status 0 (semihosting) when every phase went as stated.
#![no_std]
#![no_main]

use core::sync::atomic::{AtomicBool, AtomicU32, AtomicU8, Ordering};

use cortex_m::peripheral::NVIC;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use defmt_semihosting as _;
use zslide::firmware::{
    EventState, Firmware, FirmwareConfig, LoopState, NoCoefficientDac, Shared, SpindleMode,
    TickInput, XMode,
};
use zslide::handoff::handover::Handover;
use zslide::hw::{AmplifierDac, BusError, GaugeAdc, GaugeSample};
use zslide::servo::ServoConfig;
use zslide::watchdog::FeedGate;
use zslide::xpos::latch_word;
use zslide_qemu::board::{
    dualtimer, interrupt, watchdog, Interrupt, PCLK_HZ, TIMER0_LOOP, TIMER1_EVENTS,
};
use zslide_qemu::exit;

const LOOP_HZ: u32 = 20_000;
/// The watchdog's timeout: 5 ms of PCLK, the NUCLEO's IWDG's.
const TIMEOUT: u32 = PCLK_HZ / 1_000_000 * zslide::watchdog::TIMEOUT_US;
/// Longest an injected hang spins when no NMI releases it: 15 ms.
const HANG_LIMIT: u32 = 3 * TIMEOUT;
/// The expiry must come within the timeout of the hang's start, and no
/// earlier than the timeout less the longest gap between two feeds (one
/// loop period, 50 µs, plus the background's own pass).
const EXPIRY_MIN: u32 = TIMEOUT - PCLK_HZ / LOOP_HZ - PCLK_HZ / 10_000;
/// Phase 0 length, PCLK cycles (40 ms: eight timeouts, two index events).
const ALIVE: u32 = PCLK_HZ / 25;

/// Which handler hangs next (`NONE`: none).
const NONE: u8 = 0;
const X: u8 = 1;
const INDEX: u8 = 2;
const LOOP: u8 = 3;
static HANG: AtomicU8 = AtomicU8::new(NONE);
/// Clock when the hang began, and when the NMI came.
static HANG_AT: AtomicU32 = AtomicU32::new(0);
static NMI_AT: AtomicU32 = AtomicU32::new(0);
static NMI_COUNT: AtomicU32 = AtomicU32::new(0);
/// Loop ticks at the hang's start and at the NMI.
static TICKS_AT_HANG: AtomicU32 = AtomicU32::new(0);
static TICKS_AT_NMI: AtomicU32 = AtomicU32::new(0);
/// The hang ended by its own limit (no NMI).
static HANG_TIMED_OUT: AtomicBool = AtomicBool::new(false);
/// Phase 5: the loop tick feeds the watchdog itself.
static FEED_FROM_TICK: AtomicBool = AtomicBool::new(false);

/// Loop ticks run (what the background's feed gate reads).
static TICKS: AtomicU32 = AtomicU32::new(0);
static X_EVENTS: AtomicU32 = AtomicU32::new(0);
static INDEX_EVENTS: AtomicU32 = AtomicU32::new(0);

static SHARED: Shared = Shared::new();
/// Each handler's part, handed over by reference as in the other images
/// (`zslide::handoff::handover`).
static LOOP_PART: Handover<LoopState> = Handover::new();
static EVENT_PART: Handover<EventState> = Handover::new();

/// A gauge at rest and a DAC that takes every code: the loop's outputs
/// are not what this image checks.
struct Resting;
impl GaugeAdc for Resting {
    fn read(&mut self) -> Result<GaugeSample, BusError> {
        Ok(GaugeSample {
            code: 0,
            overrange: false,
        })
    }
}
impl AmplifierDac for Resting {
    fn write(&mut self, _code: i32) -> Result<(), BusError> {
        Ok(())
    }
    fn clamp_to_ground(&mut self) -> Result<(), BusError> {
        Ok(())
    }
    fn release_clamp(&mut self) -> Result<(), BusError> {
        Ok(())
    }
}

/// Spins while `which` is the injected hang: until the NMI releases it or
/// [`HANG_LIMIT`] has passed.
fn hang_if(which: u8) {
    if HANG.load(Ordering::Acquire) != which {
        return;
    }
    let start = dualtimer::clock();
    HANG_AT.store(start, Ordering::Release);
    TICKS_AT_HANG.store(TICKS.load(Ordering::Relaxed), Ordering::Release);
    while HANG.load(Ordering::Acquire) == which {
        if dualtimer::clock().wrapping_sub(start) > HANG_LIMIT {
            HANG_TIMED_OUT.store(true, Ordering::Release);
            HANG.store(NONE, Ordering::Release);
        }
    }
}

#[interrupt]
fn TIMER0() {
    static mut LP: Option<&'static mut LoopState> = None;
    TIMER0_LOOP.clear_interrupt();
    let Some(lp) = LOOP_PART.claim(LP) else {
        return;
    };
    lp.loop_tick(&SHARED, &TickInput::NONE, &mut Resting, &mut Resting);
    TICKS.fetch_add(1, Ordering::Relaxed);
    if FEED_FROM_TICK.load(Ordering::Relaxed) {
        watchdog::feed();
    }
    hang_if(LOOP);
}

#[interrupt]
fn TIMER1() {
    static mut EV: Option<&'static mut EventState> = None;
    TIMER1_EVENTS.clear_interrupt();
    let Some(ev) = EVENT_PART.claim(EV) else {
        return;
    };
    let n = X_EVENTS.fetch_add(1, Ordering::Relaxed);
    let now = dualtimer::clock();
    let _ = ev.x_event(&SHARED, latch_word(4_000 + n), now, &mut NoCoefficientDac);
    hang_if(X);
}

/// The index handler: as the NUCLEO's EXTI3, `Shared::index_event` (it
/// owns no handler state).
#[interrupt]
fn DUALTIMER() {
    dualtimer::clear_interrupt();
    let n = INDEX_EVENTS.fetch_add(1, Ordering::Relaxed);
    SHARED.index_event(dualtimer::clock(), n.wrapping_mul(4_096));
    hang_if(INDEX);
}

/// The watchdog's expiry. On the NUCLEO this is a reset; here it records
/// the instant, reloads the watchdog and releases the hung handler.
// SAFETY (cortex-m-rt: an NMI handler must not touch data a critical
// section protects): it touches only atomics and the watchdog's registers.
#[exception]
unsafe fn NonMaskableInt() {
    NMI_AT.store(dualtimer::clock(), Ordering::Release);
    TICKS_AT_NMI.store(TICKS.load(Ordering::Relaxed), Ordering::Release);
    NMI_COUNT.fetch_add(1, Ordering::AcqRel);
    watchdog::feed();
    HANG.store(NONE, Ordering::Release);
}

/// The background for `cycles` of the clock (or until `until_nmi` and an
/// NMI came): feed when the loop tick ran. It polls instead of sleeping in
/// `wfi` as the NUCLEO's does: under `-icount shift=0,sleep=off` a core
/// asleep in `wfi` loses every second period of the CMSDK timers (404
/// instead of 800 loop ticks in 40 ms), which would halve the loop rate
/// this check depends on.
fn background(gate: &mut FeedGate, cycles: u32, until_nmi: Option<u32>) {
    let start = dualtimer::clock();
    while dualtimer::clock().wrapping_sub(start) < cycles {
        if !FEED_FROM_TICK.load(Ordering::Relaxed) && gate.may_feed(TICKS.load(Ordering::Relaxed)) {
            watchdog::feed();
        }
        if let Some(n) = until_nmi {
            if NMI_COUNT.load(Ordering::Acquire) > n || HANG_TIMED_OUT.load(Ordering::Acquire) {
                return;
            }
        }
        cortex_m::asm::nop();
    }
}

/// Microseconds of `cycles` PCLK cycles.
fn us(cycles: u32) -> u32 {
    cycles / (PCLK_HZ / 1_000_000)
}

#[entry]
fn main() -> ! {
    let cfg = FirmwareConfig {
        loop_cfg: match ServoConfig::at_rate(LOOP_HZ) {
            Ok(c) => c,
            Err(_) => fail("servo design refused"),
        },
        spindle: SpindleMode::None,
        x: XMode::Legacy { clock_hz: PCLK_HZ },
        coefficient_output: false,
        gauge_reversed: false,
    };
    let Ok(fw) = Firmware::with_table(zslide::DEFAULT_TABLE, cfg) else {
        fail("configuration refused");
    };
    let (lp, ev, _learn) = fw.into_parts();
    // `None` only on a second run of this code (main never returns).
    LOOP_PART.give(cortex_m::singleton!(: LoopState = lp));
    EVENT_PART.give(cortex_m::singleton!(: EventState = ev));
    defmt::info!(
        "watchdog check: CMSDK watchdog {=u32} us (NMI), loop tick {=u32} Hz at priority 0x00, X and index handlers at 0x80, fed by the background when the loop tick ran",
        us(TIMEOUT),
        LOOP_HZ
    );

    // SAFETY: unmasking can break a critical section that relies on masking
    // these interrupts; none does: the handlers share data with `main` only
    // through the hand-over (a critical-section cell) and atomics, and with each other
    // only through `SHARED` (atomics).
    unsafe {
        let mut cp = cortex_m::Peripherals::steal();
        cp.NVIC.set_priority(Interrupt::TIMER0, 0x00);
        cp.NVIC.set_priority(Interrupt::TIMER1, 0x80);
        cp.NVIC.set_priority(Interrupt::DUALTIMER, 0x80);
        NVIC::unmask(Interrupt::TIMER0);
        NVIC::unmask(Interrupt::TIMER1);
        NVIC::unmask(Interrupt::DUALTIMER);
    }
    dualtimer::start_clock();
    let mut gate = FeedGate::new(TICKS.load(Ordering::Relaxed), 1);
    watchdog::start(TIMEOUT);
    TIMER0_LOOP.start_periodic(PCLK_HZ / LOOP_HZ);
    // X every 1.5 ms, index every 20 ms, not in step with the loop tick.
    TIMER1_EVENTS.start_periodic(PCLK_HZ / 1_000 * 3 / 2 + 377);
    dualtimer::start_periodic(PCLK_HZ / 50 + 911);

    let mut ok = true;
    // 0: every handler alive.
    background(&mut gate, ALIVE, None);
    let nmis = NMI_COUNT.load(Ordering::Acquire);
    let (ticks, xs, idx) = (
        TICKS.load(Ordering::Relaxed),
        X_EVENTS.load(Ordering::Relaxed),
        INDEX_EVENTS.load(Ordering::Relaxed),
    );
    defmt::info!(
        "every handler alive for {=u32} us: {=u32} loop ticks, {=u32} X events, {=u32} index events; watchdog expiries {=u32} (expected 0)",
        us(ALIVE),
        ticks,
        xs,
        idx,
        nmis
    );
    if nmis != 0 || ticks < 790 || xs < 25 || idx < 1 {
        defmt::error!("FAIL: the watchdog expired, or a handler did not run, with nothing hung");
        ok = false;
    }

    for (which, name) in [
        (X, "X handler"),
        (INDEX, "index handler"),
        (LOOP, "loop tick"),
    ] {
        let before = NMI_COUNT.load(Ordering::Acquire);
        HANG_TIMED_OUT.store(false, Ordering::Release);
        HANG.store(which, Ordering::Release);
        background(&mut gate, 10 * HANG_LIMIT, Some(before));
        let fired = NMI_COUNT.load(Ordering::Acquire) > before;
        let after = NMI_AT
            .load(Ordering::Acquire)
            .wrapping_sub(HANG_AT.load(Ordering::Acquire));
        let ticks_during = TICKS_AT_NMI
            .load(Ordering::Acquire)
            .wrapping_sub(TICKS_AT_HANG.load(Ordering::Acquire));
        if fired {
            defmt::info!(
                "hung {=str}: watchdog expired {=u32} us after the hang began (bound {=u32}..={=u32} us); the loop tick ran {=u32} times meanwhile",
                name,
                us(after),
                us(EXPIRY_MIN),
                us(TIMEOUT),
                ticks_during
            );
        } else {
            defmt::error!(
                "FAIL: hung {=str}: the watchdog did not expire in {=u32} us",
                name,
                us(HANG_LIMIT)
            );
            ok = false;
            continue;
        }
        // A hung X or index handler is preempted by the loop tick, which
        // keeps running (so feeding from the loop tick would have missed
        // it); a hung loop tick stops it.
        // (The loop tick runs 100 times in a timeout.)
        let per_timeout = TIMEOUT / (PCLK_HZ / LOOP_HZ);
        let expected_ticks = if which == LOOP {
            0..=1
        } else {
            per_timeout * 3 / 4..=per_timeout
        };
        if !(EXPIRY_MIN..=TIMEOUT).contains(&after) || !expected_ticks.contains(&ticks_during) {
            defmt::error!(
                "FAIL: hung {=str}: expiry time or loop ticks out of bounds",
                name
            );
            ok = false;
        }
        // Let the machine run again before the next hang.
        gate = FeedGate::new(TICKS.load(Ordering::Relaxed), 1);
        watchdog::feed();
        background(&mut gate, TIMEOUT / 2, None);
    }

    // 4: the loop tick stops firing; the background runs on.
    let before = NMI_COUNT.load(Ordering::Acquire);
    TIMER0_LOOP.stop();
    HANG_AT.store(dualtimer::clock(), Ordering::Release);
    background(&mut gate, HANG_LIMIT, Some(before));
    let after = NMI_AT
        .load(Ordering::Acquire)
        .wrapping_sub(HANG_AT.load(Ordering::Acquire));
    if NMI_COUNT.load(Ordering::Acquire) > before {
        defmt::info!(
            "stopped loop tick: watchdog expired {=u32} us after its timer stopped (bound {=u32}..={=u32} us)",
            us(after),
            us(EXPIRY_MIN),
            us(TIMEOUT)
        );
        if !(EXPIRY_MIN..=TIMEOUT).contains(&after) {
            defmt::error!("FAIL: stopped loop tick: expiry time out of bounds");
            ok = false;
        }
    } else {
        defmt::error!(
            "FAIL: stopped loop tick: the watchdog did not expire in {=u32} us",
            us(HANG_LIMIT)
        );
        ok = false;
    }

    // 5: the control, fed from the loop tick.
    TIMER0_LOOP.start_periodic(PCLK_HZ / LOOP_HZ);
    FEED_FROM_TICK.store(true, Ordering::Release);
    watchdog::feed();
    let before = NMI_COUNT.load(Ordering::Acquire);
    HANG_TIMED_OUT.store(false, Ordering::Release);
    HANG.store(X, Ordering::Release);
    background(&mut gate, 10 * HANG_LIMIT, Some(before));
    let caught = NMI_COUNT.load(Ordering::Acquire) > before;
    defmt::info!(
        "control, fed from the loop tick: hung X handler {=str} (expected: not caught)",
        if caught {
            "caught"
        } else {
            "not caught in 15 ms"
        }
    );
    if caught || !HANG_TIMED_OUT.load(Ordering::Acquire) {
        defmt::error!(
            "FAIL: the control phase caught the hang: the check cannot tell the designs apart"
        );
        ok = false;
    }
    watchdog::stop();
    if ok {
        defmt::info!("PASS");
    }
    exit(ok)
}

fn fail(what: &str) -> ! {
    defmt::error!("FAIL: {=str}", what);
    exit(false)
}

// cortex-m-rt requires the HardFault handler to be an `unsafe fn`; its body
// does nothing unsafe itself.
#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    defmt::error!("FAIL: hard fault at pc {=u32:#010x}", ef.pc());
    exit(false)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    defmt::error!("FAIL: panic: {}", defmt::Display2Format(info));
    exit(false)
}
