//! Firmware entry for the real board, NUCLEO-H743ZI2 (`docs/BOARD.md`).
//! Built only for the target (`cargo fw`); on the host this file is an empty
//! program so that `cargo test` links.
//!
//! Interrupts (STM32H7: 4 priority bits, the value is the top nibble; lower
//! is more urgent):
//!
//! | NVIC priority | handler | source | work |
//! |---|---|---|---|
//! | 0x00 | `TIM3` | loop tick, 20 kHz, TIM3 CC2 | `LoopState::loop_tick`: gauge, spindle angle, command, loop, DAC; watchdog |
//! | 0x10 | `EXTI2` | legacy X half-mil interrupt, PG2 | `EventState::x_event` on the latched word |
//! | 0x10 | `TIM2` | spindle index, TIM2 CH1 capture (PA0) | `Shared::index_event` with the captured time and count |
//! | 0x20 | `TIM7` | pended by the loop tick (TIM7 itself unused) | `LearnState::run`: the learning on the tick's samples, then the command ahead of the next tick |
//! | thread | `main` loop | - | background: host link (`zslide::link`, RTT), status and fault logging, arm button, watchdog |
//!
//! Each handler owns its part of the firmware outright (moved in once,
//! before its interrupt is unmasked); they share only `SHARED`, atomics
//! (`zslide::firmware`), so nothing ever masks the loop tick except the
//! one-time hand-over.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;

#[cfg(target_os = "none")]
mod app {
    use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

    use cortex_m::peripheral::NVIC;
    use cortex_m_rt::{entry, exception, ExceptionFrame};
    use embedded_storage_async::nor_flash::ReadNorFlash;
    use stm32h7::stm32h743v::{interrupt, Interrupt, Peripherals, SPI1, SPI3, SPI4};
    use zslide::drivers::{ad4020::Ad4020, ad5686::Ad5686, ad5791::Ad5791};
    use zslide::firmware::{
        EventState, Firmware, FirmwareConfig, LearnState, LoopState, Request, Shared, SpindleMode,
        SpindleReading, TickInput, XMode,
    };
    use zslide::handoff::handover::Handover;
    use zslide::hw::{Encoder, XLatch};
    use zslide::link::proto::{SpindleSource, XSource};
    use zslide::link::station::{Station, StationConfig};
    use zslide::link::tap::TickTap;
    use zslide::params::ParamSource;
    use zslide::safety::{Device, Fault};
    use zslide::servo::{ServoConfig, ServoDesign};
    use zslide::spindle::EncoderConfig;
    use zslide::store::{self, ParamStore, Store};
    use zslide::trace::{self, Event, Outputs};
    use zslide::units::SpindleAngle;
    use zslide::watchdog::FeedGate;

    use crate::board::gpio::Output;
    use crate::board::link::{self, RttLink, TAP};
    use crate::board::spi::{self, NoCs, SpiDev};
    use crate::board::timers::SpindleEncoder;
    use crate::board::{self, clocks, pins, timers};

    defmt::timestamp!("{=u32:us}", timers::micros());

    /// NVIC priorities (top nibble significant).
    const PRIO_LOOP_TICK: u8 = 0x00;
    const PRIO_X_EVENT: u8 = 0x10;
    const PRIO_INDEX: u8 = 0x10;
    /// The learning: below the X events (it may wait a tick or two).
    const PRIO_LEARN: u8 = 0x20;

    /// The spindle encoder's counts per turn after ×4 decoding (a board
    /// setting: 1024-line encoder).
    const SPINDLE_CPR: u32 = 4096;
    /// Legacy coefficient-output mode (drop-in for the 8080 board): each X
    /// event also writes C00..C03 to the AD5686 and strobes LDAC.
    const COEFFICIENT_OUTPUT: bool = false;

    fn config(loop_cfg: ServoConfig) -> FirmwareConfig {
        FirmwareConfig {
            loop_cfg,
            spindle: SpindleMode::Encoder(EncoderConfig {
                counts_per_rev: SPINDLE_CPR,
                ticks_per_s: timers::CLOCK_HZ,
                min_rpm: 30,
                max_rpm: 1_200,
                index_tolerance_counts: 4,
                index_angle: SpindleAngle(0),
                // Every count's edge captured on TIM2 (`timers::start_captures`).
                edge_stamps: zslide::spindle::EdgeStamps::Captured,
            }),
            x: XMode::Legacy {
                clock_hz: timers::CLOCK_HZ,
            },
            coefficient_output: COEFFICIENT_OUTPUT,
            gauge_reversed: false,
        }
    }

    /// Everything the loop-tick handler owns.
    struct Loop {
        lp: LoopState,
        tap: TickTap,
        /// The loop's outputs on the trace (`--features trace` only).
        outputs: Outputs,
        gauge: Ad4020<SpiDev<SPI4, NoCs>>,
        dac: Ad5791<SpiDev<SPI1, Output>>,
        spindle: SpindleEncoder,
    }

    /// Everything the X-event handler owns.
    struct XHandler {
        ev: EventState,
        quad: Ad5686<SpiDev<SPI3, Output>, Output>,
        /// Coefficient generation last traced.
        generation: u32,
    }

    static SHARED: Shared = Shared::new();
    // Each handler's state is one `.bss` value (`cortex_m::singleton!`)
    // handed over by reference (`zslide::handoff::handover`, the QEMU
    // board's way too).
    static LOOP_HANDOVER: Handover<Loop> = Handover::new();
    static X_HANDOVER: Handover<XHandler> = Handover::new();
    static LEARN_HANDOVER: Handover<LearnState> = Handover::new();
    static TICKS: AtomicU32 = AtomicU32::new(0);
    /// The amplifier is enabled (the loop armed), for the arm button.
    static ARMED: AtomicBool = AtomicBool::new(false);

    #[entry]
    fn main() -> ! {
        // The amplifier-enable pin is low from reset (its external
        // pull-down holds it); RTT first, so that every log line reaches
        // the probe.
        let rtt = link::init_rtt();
        let Some(dp) = Peripherals::take() else {
            boot_failure("device peripherals taken twice");
        };
        let Some(mut cp) = cortex_m::Peripherals::take() else {
            boot_failure("core peripherals taken twice");
        };
        let (watchdog_reset, source) = board::bring_up(&dp, &mut cp);

        defmt::info!(
            "zslide-fw on NUCLEO-H743ZI2: core {=u32} MHz, AHB {=u32} MHz from {}; loop tick {=u32} Hz; clock {=u32} Hz",
            clocks::SYSCLK_HZ / 1_000_000,
            clocks::HCLK_HZ / 1_000_000,
            source,
            timers::LOOP_HZ,
            timers::CLOCK_HZ
        );
        if watchdog_reset {
            defmt::error!("the last reset was the watchdog: {}", Fault::Watchdog);
        }

        let amp_spi = SpiDev::new(dp.SPI1, 1, spi::Mode::Mode1, Output(pins::AMP_DAC_SYNC));
        let gauge_spi = SpiDev::new(dp.SPI4, 0, spi::Mode::Mode0, NoCs);
        let quad_spi = SpiDev::new(dp.SPI3, 1, spi::Mode::Mode1, Output(pins::QUAD_DAC_SYNC));

        // Servo parameters: the parameter store's last saved block
        // (`zslide::store`, bank 2: `board::flash`) on the built-in design;
        // the store owns the whole region (`zslide params flash` writes a
        // store holding one block); a bare block an older `params flash`
        // left at the region's start still boots. A refused block or an unreadable store leaves the built-in
        // design in the loop and the amplifier off (`Fault::Parameters`,
        // never cleared). The watchdog is fed inside the driver's
        // busy-waits through its own gate: only while the loop tick runs.
        let mut gate = FeedGate::new(TICKS.load(Ordering::Relaxed), 1);
        let feed = move || {
            if gate.may_feed(TICKS.load(Ordering::Relaxed)) {
                timers::feed_watchdog();
            }
        };
        let flash = board::flash::Bank2::new(dp.FLASH, feed);
        let capacity = flash.capacity() as u32;
        let Ok(mut store) = Store::new(flash, 0..capacity) else {
            boot_failure("the parameter region is not a store (two sectors)");
        };
        let base = ServoDesign::brief(timers::LOOP_HZ);
        let Ok((design, loop_cfg, param_source)) = store::boot::at_boot_owned(&mut store, &base)
        else {
            boot_failure("servo design refused");
        };
        // The table region is parsed and sign-checked here; a missing or
        // refused table leaves the firmware latched in Fault::Table with
        // the slide held at null (no built-in fallback: docs/BOARD.md).
        let Ok(mut fw) = Firmware::with_table_region(link::table_region(), config(loop_cfg)) else {
            boot_failure("firmware configuration refused");
        };
        let table = fw.table_identity();
        match &table {
            Ok(id) => defmt::info!(
                "coefficient table: c {=i64} nin, S_y {=i64} nin, tool radius {=i64} nin; {=u8} terms, {=u32} nodes; {=u32} bytes, CRC {=u32:#010x}",
                id.geometry.c_nin,
                id.geometry.s_y_nin,
                id.geometry.tool_radius_nin,
                id.terms,
                id.node_count,
                id.len,
                id.crc
            ),
            Err(e) => defmt::error!(
                "coefficient table refused, slide held at null: {}",
                defmt::Display2Format(e)
            ),
        }
        // The part's interruption block (bank 2 sector 7), parsed into
        // RAM: erased is a whole face; a refused block is refused in words
        // and the cut runs without the edges' anticipation.
        match fw.set_interruptions_region(link::interruptions_region()) {
            Ok(Some(n)) => defmt::info!("interruption block: {=usize} holes", n),
            Ok(None) => defmt::info!("no interruption block: a whole face"),
            Err(e) => defmt::error!(
                "interruption block refused, the cut runs without the edges' anticipation: {}",
                defmt::Display2Format(&e)
            ),
        }
        let (mut lp, ev, learn) = fw.into_parts();
        match param_source {
            ParamSource::Refused(e) => {
                defmt::error!("servo parameter block refused, amplifier kept off: {}", e);
                lp.trip(Fault::Parameters(e));
            }
            ParamSource::Block { entries, crc } => defmt::info!(
                "servo parameters: block of {=u16} entries, CRC {=u32:#010x}",
                entries,
                crc
            ),
            ParamSource::BuiltIn => defmt::info!("servo parameters: built-in"),
        }
        let station = Station::new(StationConfig {
            loop_hz: timers::LOOP_HZ,
            x_source: XSource::LegacyHalfMil,
            spindle_source: SpindleSource::Encoder,
            table,
            design,
            params: param_source,
        });
        let mut dac = Ad5791::new(amp_spi);
        // Zero code, output released, control register read back.
        if dac.init().is_err() {
            lp.trip(Fault::Bus(Device::AmplifierDac));
        }
        let quad = match Ad5686::new(quad_spi, Output(pins::QUAD_DAC_LDAC)) {
            Ok(q) => q,
            Err(_) => boot_failure("coefficient DAC LDAC pin"),
        };
        timers::start_spindle_encoder(&dp.TIM4);
        timers::start_captures(&dp.TIM2, &dp.TIM4);
        let lp = Loop {
            lp,
            tap: TickTap::new(),
            outputs: Outputs::new(),
            gauge: Ad4020::new(gauge_spi),
            dac,
            spindle: SpindleEncoder::new(),
        };
        // `None` only on a second run of this code, which cannot happen
        // (main never returns); that handler would then stay idle.
        let lp = cortex_m::singleton!(: Loop = lp);
        let x = cortex_m::singleton!(: XHandler = XHandler {
            ev,
            quad,
            generation: 0,
        });
        let learn = cortex_m::singleton!(: LearnState = learn);
        LOOP_HANDOVER.give(lp);
        X_HANDOVER.give(x);
        LEARN_HANDOVER.give(learn);

        board::configure_exti(&dp.SYSCFG, &dp.EXTI);
        timers::start_watchdog(&dp.IWDG, &dp.DBGMCU);
        // With `--features trace`: the trace clock is TIM2 (5 ns).
        trace::announce_clock(timers::CLOCK_HZ);
        timers::start_loop_timer(&dp.TIM3);
        // SAFETY: setting priorities and unmasking can break critical
        // sections that rely on masking; none does here: every datum shared
        // with these handlers is an atomic or behind `critical_section`.
        unsafe {
            cp.NVIC.set_priority(Interrupt::TIM3, PRIO_LOOP_TICK);
            cp.NVIC.set_priority(Interrupt::EXTI2, PRIO_X_EVENT);
            cp.NVIC.set_priority(Interrupt::TIM2, PRIO_INDEX);
            cp.NVIC.set_priority(Interrupt::TIM7, PRIO_LEARN);
            NVIC::unmask(Interrupt::TIM3);
            NVIC::unmask(Interrupt::EXTI2);
            NVIC::unmask(Interrupt::TIM2);
            NVIC::unmask(Interrupt::TIM7);
        }

        background(station, rtt, store)
    }

    /// A boot that cannot go on (a refused configuration, say): not a
    /// panic, so that the image has no panic path of its own; the outputs
    /// are made safe exactly as the panic handler does, the reason is
    /// logged, and the core stays halted. The interrupts were never
    /// unmasked and the watchdog never started, so nothing restarts it into
    /// the same refusal: power-cycle or reflash after fixing the cause.
    fn boot_failure(reason: &str) -> ! {
        cortex_m::interrupt::disable();
        board::force_amplifier_off();
        defmt::error!("boot refused: {=str} ({})", reason, Fault::Panic);
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// Thread mode, the lowest priority: the host link, reports, the arm
    /// button and the watchdog, then sleeps until the next interrupt (the
    /// loop tick wakes it 20 000 times a second).
    fn background(
        mut station: Station<{ link::CAPTURE }>,
        mut rtt: RttLink,
        mut store: impl ParamStore,
    ) -> ! {
        let mut last_report = timers::micros();
        // Fault-log records reported so far.
        let mut reported = 0u32;
        // The arm button, debounced: a level held 20 ms is a press.
        let (mut button, mut since) = (false, timers::micros());
        // Fed here, below every handler, and only when the loop tick ran
        // (`zslide::watchdog`): a hung handler or a stopped loop tick
        // lets the 5 ms watchdog reset the chip.
        let mut gate = FeedGate::new(TICKS.load(Ordering::Relaxed), 1);
        loop {
            if gate.may_feed(TICKS.load(Ordering::Relaxed)) {
                timers::feed_watchdog();
            }
            // A save (disarmed only) runs here: its erase takes seconds,
            // the loop tick runs on from bank 1 meanwhile (`board::flash`).
            station.poll_with_store(&TAP, &SHARED, &mut rtt, &mut store);
            let latched = station.fault_log().last().is_some_and(|r| !r.cleared);
            let level = pins::ARM_BUTTON.is_high();
            let now = timers::micros();
            if level != button && now.wrapping_sub(since) >= 20_000 {
                button = level;
                if level {
                    // A press toggles: arm when off, disarm when on. After a
                    // fault: clear (refused while its cause is present), and
                    // the next press arms.
                    if ARMED.load(Ordering::Relaxed) {
                        SHARED.request(Request::Disarm);
                        defmt::info!("disarm requested");
                    } else if latched {
                        SHARED.request(Request::ClearFault);
                        defmt::info!("fault clear requested");
                    } else {
                        SHARED.request(Request::Arm);
                        defmt::info!("arm requested");
                    }
                }
            }
            if level == button {
                since = now;
            }
            // New fault-log records (the link's log, fed by the loop tick).
            let logged = station.faults_logged();
            if logged != reported {
                let new = logged.wrapping_sub(reported) as usize;
                let kept = station.fault_log().count();
                for r in station.fault_log().skip(kept.saturating_sub(new)) {
                    if r.cleared {
                        defmt::info!("tick {=u32}: fault cleared: {}", r.tick, r.fault);
                    } else {
                        defmt::error!(
                            "tick {=u32}: fault {} -> {}",
                            r.tick,
                            r.fault,
                            r.fault.reaction()
                        );
                    }
                }
                reported = logged;
            }
            let now = timers::micros();
            if now.wrapping_sub(last_report) >= 1_000_000 {
                last_report = now;
                defmt::info!(
                    "ticks {=u32}, X events {=u32} accepted / {=u32} ignored, coefficient sets {=u32}, index events {=u32}",
                    TICKS.load(Ordering::Relaxed),
                    SHARED.x_accepted(),
                    SHARED.x_ignored(),
                    SHARED.coefficient_generation(),
                    SHARED.index_events()
                );
            }
            cortex_m::asm::wfi();
        }
    }

    #[interrupt]
    fn TIM3() {
        static mut LOOP: Option<&'static mut Loop> = None;
        timers::ack_loop_tick();
        let Some(l) = LOOP_HANDOVER.claim(LOOP) else {
            return;
        };
        trace::emit(Event::LoopEnter, timers::now_ticks());
        // The encoder first, then the clock: `now` is then never before
        // the captured edge of the count read (an edge between the two
        // reads would otherwise look 2³² ticks old, a stall).
        let spindle = SpindleReading::Encoder(l.spindle.sample());
        let input = TickInput {
            now: timers::now_ticks(),
            spindle,
            x_count: 0,
            amplifier_fault: pins::AMP_FAULT.is_high(),
        };
        l.lp.loop_tick(&SHARED, &input, &mut l.gauge, &mut l.dac);
        // The learning on this tick's sample, once the tick is done.
        NVIC::pend(Interrupt::TIM7);
        let enable = l.lp.amplifier_enable();
        pins::AMP_ENABLE.set(enable);
        trace::emit(Event::LoopExit, timers::now_ticks());
        l.outputs.after_tick(&l.lp, timers::now_ticks);
        // Fault changes, snapshots, capture: a few stores (zslide::link::tap).
        l.tap.after_tick(&TAP, &mut l.lp);
        ARMED.store(enable, Ordering::Relaxed);
        TICKS.store(l.lp.ticks(), Ordering::Relaxed);
    }

    /// Legacy half-mil interrupt: the word latched at the edge, into the
    /// firmware's X path (decode, debounce, schedule, coefficients for the
    /// loop tick; the quad DAC in the coefficient-output mode).
    #[interrupt]
    fn EXTI2() {
        static mut X: Option<&'static mut XHandler> = None;
        board::ack_exti(2);
        let word = board::LatchPins.read();
        let now = timers::now_ticks();
        if let Some(x) = X_HANDOVER.claim(X) {
            trace::emit(Event::XEnter, now);
            // Faults reach the loop tick through SHARED.
            let _ = x.ev.x_event(&SHARED, word, now, &mut x.quad);
            trace::emit(Event::XExit, timers::now_ticks());
            let g = SHARED.coefficient_generation();
            if g != x.generation {
                x.generation = g;
                trace::emit(Event::Coefficients(g), timers::now_ticks());
            }
        }
    }

    /// The learning (pended by every loop tick; the timer TIM7 itself is
    /// not used): the tick's samples into the learned table.
    #[interrupt]
    fn TIM7() {
        static mut LEARN: Option<&'static mut LearnState> = None;
        if let Some(l) = LEARN_HANDOVER.claim(LEARN) {
            l.run(&SHARED);
        }
    }

    /// Spindle index (TIM2 CC1): the edge's time and the spindle count at
    /// the edge, both captured in hardware, for the loop tick's estimator.
    #[interrupt]
    fn TIM2() {
        trace::emit(Event::IndexEnter, timers::now_ticks());
        if let Some((edge, count)) = timers::index_capture() {
            SHARED.index_event(edge, count);
        }
        trace::emit(Event::IndexExit, timers::now_ticks());
    }

    // cortex-m-rt requires the HardFault handler to be an `unsafe fn`; its
    // body does nothing unsafe itself (the pin store is `Pin::set`'s).
    #[exception]
    unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
        cortex_m::interrupt::disable();
        board::force_amplifier_off();
        defmt::error!("hard fault at pc {=u32:#010x}: {}", ef.pc(), Fault::Panic);
        // The watchdog, no longer fed, resets the chip within 5 ms.
        loop {
            cortex_m::asm::nop();
        }
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        // Outputs safe before anything that could fail: mask interrupts so
        // the loop tick cannot re-enable the amplifier, then one store to
        // GPIOG_BSRR drops the enable line. Neither needs RAM or locks.
        cortex_m::interrupt::disable();
        board::force_amplifier_off();
        defmt::error!("panic: {} ({})", defmt::Display2Format(info), Fault::Panic);
        // A permanently undefined instruction: probe-rs reports it and
        // stops; without a debugger the watchdog resets the chip.
        cortex_m::asm::udf()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("zslide-fw runs on the board: build it with `cargo fw`");
}
