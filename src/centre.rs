//! Firmware entry of the second system, the automatic part centring of
//! Feezell 1967 (Y-1594), on the NUCLEO-H743ZI2: `zslide-centre`
//! (`docs/CENTRING.md`, wiring in `docs/BOARD.md`). The same board support
//! (`src/board/`) and the same core as `zslide-fw`; the sequence, the
//! estimators and the slide servos are `zslide::centring`, run here once
//! per loop tick exactly as `host-sim center` runs them.
//!
//! | NVIC priority | handler | source | work |
//! |---|---|---|---|
//! | 0x00 | `TIM3` | centring tick, 10 kHz, TIM3 CC2 | table angle (encoder + index captures), transducer (AD4020), tachometers (ADC1), `Centring::tick`, slide motor voltages (AD5686 channels A, B, one LDAC strobe) |
//! | thread | `main` loop | - | start/stop button, results and refusals in words, watchdog |
//!
//! The tick owns everything it touches; it hands events to the background
//! through a lock-free single-producer ring of atomics ([`Events`]).
#![cfg_attr(target_os = "none", no_std, no_main)]

// The board support zslide-fw uses; its X-interface and Z-loop pieces are
// not needed here.
#[cfg(target_os = "none")]
#[allow(dead_code)]
mod board;

#[cfg(target_os = "none")]
mod app {
    use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, Ordering};

    use cortex_m::peripheral::NVIC;
    use cortex_m_rt::{entry, exception, ExceptionFrame};
    use stm32h7::stm32h743v::{interrupt, Interrupt, Peripherals, SPI3, SPI4};
    use zslide::centring::{Centring, Config, Event, Inputs, LoopDesign, Method, State};
    use zslide::drivers::{ad4020::Ad4020, ad5686::Ad5686};
    use zslide::handoff::handover::Handover;
    use zslide::hw::{Encoder, GaugeAdc};
    use zslide::safety::{Device, Fault};
    use zslide::spindle::{EdgeStamps, EncoderConfig};
    use zslide::units::{SpindleAngle, TableInches};
    use zslide::watchdog::FeedGate;

    use crate::board::adc::Tachometers;
    use crate::board::gpio::Output;
    use crate::board::spi::{self, NoCs, SpiDev};
    use crate::board::timers::{self, SpindleEncoder};
    use crate::board::{self, clocks, pins};

    defmt::timestamp!("{=u32:us}", timers::micros());

    /// The centring tick (the rate `host-sim center` runs the sequence at).
    const TICK_HZ: u32 = 10_000;
    /// Table encoder counts per turn after ×4 decoding (a 9000-line
    /// encoder: 36 000, as the simulated table).
    const TABLE_CPR: u32 = 36_000;
    /// The centring clock: the 200 MHz capture stamps, extended past
    /// TIM2's 21.5 s wrap in the tick and divided down to 1 µs, so that a
    /// revolution at the table's slowest 1 rpm (60 s) fits a 32-bit clock
    /// (71 min).
    const CLOCK_HZ: u32 = 1_000_000;
    const CAPTURE_PER_CLOCK: u64 = (timers::CLOCK_HZ / CLOCK_HZ) as u64;
    /// Slide amplifiers: ±10 V from the AD5686 (offset binary, 16 bits)
    /// times this gain gives the motor voltage; ±130 V covers the
    /// ±128.967 V at which the motors reach their 365 rad/s limit.
    const AMP_GAIN: i64 = 13;
    /// Nominal radius of the part where the transducer touches it, inches
    /// (the operator's setting; 2 in as in the simulator).
    const PART_RADIUS_IN: f64 = 2.0;

    fn config() -> Config {
        Config {
            method: Method::Lsq,
            design: LoopDesign::Compensated,
            // The fit corrects in full (docs/CENTRING.md: K = 1 for LSQ).
            k_q30: 1 << 30,
            // The seed's level, 0.0001 in.
            level: TableInches::from_f64(0.0001),
            max_cycles: 8,
            tick_hz: TICK_HZ,
            max_correction_ticks: 60 * TICK_HZ,
            encoder: EncoderConfig {
                counts_per_rev: TABLE_CPR,
                ticks_per_s: CLOCK_HZ,
                min_rpm: 1,
                max_rpm: 26,
                index_tolerance_counts: 2,
                index_angle: SpindleAngle(0),
                edge_stamps: EdgeStamps::Captured,
            },
            // I2F30 saturates just below 2 in (the simulator's setting too).
            part_radius: TableInches::from_f64(PART_RADIUS_IN),
        }
    }

    /// Transducer: ±70 V (140 V/in over ±0.5 in) through a 1/7 divider
    /// onto the AD4020's ±10 V, so one code of 2¹⁹ = 10 V is 2⁻²⁰ in, and
    /// in `TableInches` (I2F30) exactly 2¹⁰ bits.
    fn reading(code: i32) -> TableInches {
        TableInches::from_bits(code.saturating_mul(1 << 10))
    }

    /// Motor voltage (mV) → AD5686 code (offset binary, ±10 V).
    fn motor_code(mv: i32) -> u16 {
        let code = 32_768 + i64::from(mv) * 32_768 / (AMP_GAIN * 10_000);
        code.clamp(0, 65_535) as u16
    }

    /// The 200 MHz capture clock extended to 64 bits and read in µs.
    struct CentringClock {
        ext: u64,
        last: u32,
    }

    impl CentringClock {
        fn new() -> Self {
            let now = timers::now_ticks();
            Self {
                ext: u64::from(now),
                last: now,
            }
        }
        /// Advances to TIM2's count now; call at least once per 21 s.
        fn now_us(&mut self) -> u32 {
            let now = timers::now_ticks();
            self.ext += u64::from(now.wrapping_sub(self.last));
            self.last = now;
            (self.ext / CAPTURE_PER_CLOCK) as u32
        }
        /// A stamp captured before the last `now_us` (within one wrap), in µs.
        fn stamp_us(&self, stamp: u32) -> u32 {
            let back = u64::from(self.last.wrapping_sub(stamp));
            (self.ext.saturating_sub(back) / CAPTURE_PER_CLOCK) as u32
        }
    }

    /// Everything the tick owns.
    struct Tick {
        /// Formed once at boot: its float conversions (`from_f64`, which
        /// panics on NaN) stay out of the handler (`cargo xtask no-panic`
        /// found them there when the tick built it at each start).
        cfg: Config,
        run: Option<Centring>,
        clock: CentringClock,
        encoder: SpindleEncoder,
        transducer: Ad4020<SpiDev<SPI4, NoCs>>,
        tach: Tachometers,
        motors: Ad5686<SpiDev<SPI3, Output>, Output>,
    }

    /// What the tick tells the background, in order: a ring of atomics,
    /// one producer (the tick) and one consumer (the background); events
    /// come a few a minute, so eight slots never fill in practice, and a
    /// full ring drops the newest event and counts it.
    struct Events {
        slots: [[AtomicI32; 4]; 8],
        head: AtomicU32,
        tail: AtomicU32,
        dropped: AtomicU32,
    }

    const EV_MEASURED: i32 = 1;
    const EV_CORRECTED: i32 = 2;
    const EV_REFUSED: i32 = 3;
    const EV_CENTRED: i32 = 4;
    const EV_STOPPED: i32 = 5;
    const EV_BUS: i32 = 6;

    impl Events {
        const fn new() -> Self {
            #[allow(clippy::declare_interior_mutable_const)]
            const Z: AtomicI32 = AtomicI32::new(0);
            #[allow(clippy::declare_interior_mutable_const)]
            const S: [AtomicI32; 4] = [Z, Z, Z, Z];
            Self {
                slots: [S, S, S, S, S, S, S, S],
                head: AtomicU32::new(0),
                tail: AtomicU32::new(0),
                dropped: AtomicU32::new(0),
            }
        }
        fn push(&self, ev: [i32; 4]) {
            let head = self.head.load(Ordering::Relaxed);
            if head.wrapping_sub(self.tail.load(Ordering::Acquire)) >= 8 {
                self.dropped.fetch_add(1, Ordering::Relaxed);
                return;
            }
            for (slot, v) in self.slots[(head % 8) as usize].iter().zip(ev) {
                slot.store(v, Ordering::Relaxed);
            }
            self.head.store(head.wrapping_add(1), Ordering::Release);
        }
        fn pop(&self) -> Option<[i32; 4]> {
            let tail = self.tail.load(Ordering::Relaxed);
            if tail == self.head.load(Ordering::Acquire) {
                return None;
            }
            let s = &self.slots[(tail % 8) as usize];
            let ev = [
                s[0].load(Ordering::Relaxed),
                s[1].load(Ordering::Relaxed),
                s[2].load(Ordering::Relaxed),
                s[3].load(Ordering::Relaxed),
            ];
            self.tail.store(tail.wrapping_add(1), Ordering::Release);
            Some(ev)
        }
    }

    static EVENTS: Events = Events::new();
    /// The tick's state is one `.bss` value (`cortex_m::singleton!`) handed
    /// over by reference (`zslide::handoff::handover`: as an `Option<Tick>`
    /// static the 5.8 KiB state was in `.data` twice).
    static TICK_HANDOVER: Handover<Tick> = Handover::new();
    static TICKS: AtomicU32 = AtomicU32::new(0);
    /// The level detector's setting, µin, for the log.
    static LEVEL_UIN: AtomicI32 = AtomicI32::new(0);
    /// The background asks the tick to start (true) or stop (false) a run.
    static START: AtomicBool = AtomicBool::new(false);
    static STOP: AtomicBool = AtomicBool::new(false);
    /// A run is in progress (the slide amplifiers enabled).
    static RUNNING: AtomicBool = AtomicBool::new(false);

    #[entry]
    fn main() -> ! {
        // RTT as zslide-fw sets it up (one control block for the board
        // support): defmt on up channel 0, first, so that nothing logged is
        // lost. The link's channel pair exists but this image serves no host
        // link: its log is the interface.
        let _ = board::link::init_rtt();
        let Some(dp) = Peripherals::take() else {
            boot_failure("device peripherals taken twice");
        };
        let Some(mut cp) = cortex_m::Peripherals::take() else {
            boot_failure("core peripherals taken twice");
        };
        let (watchdog_reset, source) = board::bring_up(&dp, &mut cp);
        defmt::info!(
            "zslide-centre on NUCLEO-H743ZI2: core {=u32} MHz from {}; centring tick {=u32} Hz; table {=u32} counts/turn",
            clocks::SYSCLK_HZ / 1_000_000,
            source,
            TICK_HZ,
            TABLE_CPR
        );
        if watchdog_reset {
            defmt::error!("the last reset was the watchdog: {}", Fault::Watchdog);
        }
        // The configuration is formed and checked once here (Centring::new
        // refuses a configuration it cannot run), not at every start.
        let cfg = config();
        if Centring::new(cfg).is_none() {
            boot_failure("centring configuration refused");
        }
        LEVEL_UIN.store(uin(cfg.level.to_bits()), Ordering::Relaxed);
        let tach = match Tachometers::init(dp.ADC1, &dp.ADC12_COMMON, &dp.RCC) {
            Ok(t) => t,
            Err(e) => {
                defmt::error!("tachometer ADC: {} did not answer", e.0);
                boot_failure("tachometer ADC");
            }
        };
        let transducer_spi = SpiDev::new(dp.SPI4, 0, spi::Mode::Mode0, NoCs);
        let motor_spi = SpiDev::new(dp.SPI3, 1, spi::Mode::Mode1, Output(pins::QUAD_DAC_SYNC));
        let Ok(mut motors) = Ad5686::new(motor_spi, Output(pins::QUAD_DAC_LDAC)) else {
            boot_failure("slide DAC LDAC pin");
        };
        if motors.output(&[motor_code(0); 4], 0b1111).is_err() {
            boot_failure("slide DAC does not answer");
        }
        timers::start_spindle_encoder(&dp.TIM4);
        timers::start_captures(&dp.TIM2, &dp.TIM4);
        let tick = Tick {
            cfg,
            run: None,
            clock: CentringClock::new(),
            encoder: SpindleEncoder::new(),
            transducer: Ad4020::new(transducer_spi),
            tach,
            motors,
        };
        // `None` only on a second run of this code, which cannot happen
        // (main never returns); the tick would then stay idle.
        let tick = cortex_m::singleton!(: Tick = tick);
        TICK_HANDOVER.give(tick);
        timers::start_watchdog(&dp.IWDG, &dp.DBGMCU);
        timers::start_loop_timer_at(&dp.TIM3, TICK_HZ);
        // SAFETY: every datum shared with the handler is an atomic or
        // behind `critical_section`; unmasking breaks no critical section.
        unsafe {
            cp.NVIC.set_priority(Interrupt::TIM3, 0x00);
            NVIC::unmask(Interrupt::TIM3);
        }
        background()
    }

    fn boot_failure(reason: &str) -> ! {
        cortex_m::interrupt::disable();
        board::force_amplifier_off();
        defmt::error!("boot refused: {=str} ({})", reason, Fault::Panic);
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// Off-centre bits (I2F30) in µin, for the log.
    fn uin(bits: i32) -> i32 {
        ((i64::from(bits) * 1_000_000) >> 30) as i32
    }

    fn background() -> ! {
        let (mut button, mut since) = (false, timers::micros());
        let mut gate = FeedGate::new(TICKS.load(Ordering::Relaxed), 1);
        let mut dropped = 0;
        loop {
            if gate.may_feed(TICKS.load(Ordering::Relaxed)) {
                timers::feed_watchdog();
            }
            // B1: a press starts a run, a press during a run stops it.
            let level = pins::ARM_BUTTON.is_high();
            let now = timers::micros();
            if level != button && now.wrapping_sub(since) >= 20_000 {
                button = level;
                if level {
                    if RUNNING.load(Ordering::Relaxed) {
                        STOP.store(true, Ordering::Release);
                        defmt::info!("stop requested");
                    } else {
                        START.store(true, Ordering::Release);
                        defmt::info!("centring requested");
                    }
                }
            }
            if level == button {
                since = now;
            }
            while let Some([kind, a, b, c]) = EVENTS.pop() {
                match kind {
                    EV_MEASURED => defmt::info!(
                        "cycle {=i32}: off centre x {=i32} µin, y {=i32} µin",
                        a,
                        uin(b),
                        uin(c)
                    ),
                    EV_CORRECTED => defmt::info!("cycle {=i32}: slides settled", a),
                    EV_CENTRED => defmt::info!(
                        "centred: x {=i32} µin, y {=i32} µin (level {=i32} µin)",
                        uin(b),
                        uin(c),
                        LEVEL_UIN.load(Ordering::Relaxed)
                    ),
                    EV_REFUSED => match refusal(a) {
                        Some(f) => defmt::error!("refused: {} ({})", f, f.reason()),
                        None => defmt::error!("refused (code {=i32})", a),
                    },
                    EV_BUS => defmt::error!(
                        "stopped: {} (slides off)",
                        Fault::Bus(if a == 0 {
                            Device::GaugeAdc
                        } else {
                            Device::CoefficientDac
                        })
                    ),
                    EV_STOPPED => defmt::info!("stopped by the operator (slides off)"),
                    _ => {}
                }
            }
            let d = EVENTS.dropped.load(Ordering::Relaxed);
            if d != dropped {
                dropped = d;
                defmt::warn!("{=u32} events lost (ring full)", d);
            }
            cortex_m::asm::wfi();
        }
    }

    /// The refusals `Centring` reports, numbered for the event ring.
    const REFUSALS: [Fault; 7] = [
        Fault::CentringTableStopped,
        Fault::CentringOutOfRange,
        Fault::CentringWorse,
        Fault::CentringNoConvergence,
        Fault::CentringSlideTimeout,
        Fault::IndexExtra,
        Fault::IndexMissing,
    ];

    fn refusal_code(f: Fault) -> i32 {
        REFUSALS
            .iter()
            .position(|&r| r == f)
            .map_or(-1, |i| i as i32)
    }

    fn refusal(code: i32) -> Option<Fault> {
        usize::try_from(code)
            .ok()
            .and_then(|i| REFUSALS.get(i).copied())
    }

    /// Motors to 0 V, amplifiers off, the run ended.
    fn stop(t: &mut Tick) {
        let _ = t.motors.output(&[motor_code(0); 4], 0b0011);
        pins::AMP_ENABLE.set(false);
        t.run = None;
        RUNNING.store(false, Ordering::Relaxed);
    }

    #[interrupt]
    fn TIM3() {
        static mut TICK: Option<&'static mut Tick> = None;
        timers::ack_loop_tick();
        let Some(t) = TICK_HANDOVER.claim(TICK) else {
            return;
        };
        TICKS.store(
            TICKS.load(Ordering::Relaxed).wrapping_add(1),
            Ordering::Relaxed,
        );
        let now = t.clock.now_us();
        let sample = t.encoder.sample();
        let index = timers::index_capture().map(|(edge, count)| (count, t.clock.stamp_us(edge)));
        let gauge = t.transducer.read();
        let tach = t.tach.read_uv();
        if START.swap(false, Ordering::Acquire) && t.run.is_none() {
            t.run = Centring::new(t.cfg);
            RUNNING.store(t.run.is_some(), Ordering::Relaxed);
            pins::AMP_ENABLE.set(t.run.is_some());
        }
        if STOP.swap(false, Ordering::Acquire) && t.run.is_some() {
            stop(t);
            EVENTS.push([EV_STOPPED, 0, 0, 0]);
            return;
        }
        let Some(run) = t.run.as_mut() else {
            return;
        };
        let (Ok(g), Some(tach_uv)) = (gauge, tach) else {
            // A converter that did not answer: the slides stop; the run
            // cannot go on without its measurements.
            stop(t);
            EVENTS.push([EV_BUS, 0, 0, 0]);
            return;
        };
        let inputs = Inputs {
            count: sample.count,
            edge_ticks: t.clock.stamp_us(sample.edge_ticks),
            now,
            index,
            reading: reading(g.code),
            tach_uv,
        };
        let (mv, ev) = run.tick(&inputs);
        let codes = [
            motor_code(mv[0]),
            motor_code(mv[1]),
            motor_code(0),
            motor_code(0),
        ];
        if t.motors.output(&codes, 0b0011).is_err() {
            stop(t);
            EVENTS.push([EV_BUS, 1, 0, 0]);
            return;
        }
        match ev {
            Some(Event::Measured(n, o)) => {
                EVENTS.push([EV_MEASURED, n as i32, o.x.to_bits(), o.y.to_bits()])
            }
            Some(Event::Corrected(n)) => EVENTS.push([EV_CORRECTED, n as i32, 0, 0]),
            Some(Event::Refused(f)) => {
                EVENTS.push([EV_REFUSED, refusal_code(f), 0, 0]);
                stop(t);
                return;
            }
            None => {}
        }
        if let State::Centred(o) = run.state() {
            EVENTS.push([EV_CENTRED, 0, o.x.to_bits(), o.y.to_bits()]);
            stop(t);
        }
    }

    #[exception]
    unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
        cortex_m::interrupt::disable();
        board::force_amplifier_off();
        defmt::error!("hard fault at pc {=u32:#010x}: {}", ef.pc(), Fault::Panic);
        loop {
            cortex_m::asm::nop();
        }
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        cortex_m::interrupt::disable();
        board::force_amplifier_off();
        defmt::error!("panic: {} ({})", defmt::Display2Format(info), Fault::Panic);
        cortex_m::asm::udf()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("zslide-centre runs on the board: build it with `cargo build --release --bin zslide-centre --target thumbv7em-none-eabihf`");
}
