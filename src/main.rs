//! Firmware entry for the real board, NUCLEO-H743ZI2 (`docs/BOARD.md`).
//! Built only for the target (`cargo fw`); on the host this file is an empty
//! program so that `cargo test` links.
//!
//! Interrupts (STM32H7: 4 priority bits, the value is the top nibble; lower
//! is more urgent):
//!
//! | NVIC priority | handler | source | work |
//! |---|---|---|---|
//! | 0x00 | `TIM3` | loop tick, 20 kHz, TIM3 CC2 | gauge in, `Firmware::loop_tick`, DAC out, watchdog |
//! | 0x10 | `EXTI2` | legacy X half-mil interrupt, PG2 | latch the BCD word, publish it |
//! | 0x10 | `EXTI3` | spindle index, PG3 | timestamp it, publish it |
//! | thread | `main` loop | - | background: status and fault logging |
//!
//! The loop-tick handler owns the `Firmware` and its converters outright
//! (moved in once, before its interrupt is unmasked); lower priorities see
//! its results only through atomics, so nothing ever masks the loop tick
//! except the one-instruction critical section of that hand-over.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;

#[cfg(target_os = "none")]
mod app {
    use core::cell::RefCell;
    use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

    use cortex_m::peripheral::NVIC;
    use cortex_m_rt::{entry, exception, ExceptionFrame};
    use critical_section::Mutex;
    use defmt_rtt as _;
    use stm32h7::stm32h743v::{interrupt, Interrupt, Peripherals, SPI1, SPI4};
    use zslide::firmware::{Firmware, LoopConfig};
    use zslide::hw::XLatch;
    use zslide::safety::{Device, Fault};

    use crate::board::converters::{Ad4020, Ad5791};
    use crate::board::gpio::Output;
    use crate::board::spi::{self, NoCs, SpiDev};
    use crate::board::{self, clocks, pins, timers};

    defmt::timestamp!("{=u32:us}", timers::micros());

    /// NVIC priorities (top nibble significant).
    const PRIO_LOOP_TICK: u8 = 0x00;
    const PRIO_X_EVENT: u8 = 0x10;
    const PRIO_INDEX: u8 = 0x10;

    /// Everything the loop-tick handler owns.
    struct Loop {
        fw: Firmware,
        gauge: Ad4020<SpiDev<SPI4, NoCs>>,
        dac: Ad5791<SpiDev<SPI1, Output>>,
    }

    static HANDOFF: Mutex<RefCell<Option<Loop>>> = Mutex::new(RefCell::new(None));
    static TICKS: AtomicU32 = AtomicU32::new(0);
    /// The first fault the loop latched, published once for the background.
    static FAULT: Mutex<RefCell<Option<Fault>>> = Mutex::new(RefCell::new(None));
    static FAULT_PUBLISHED: AtomicBool = AtomicBool::new(false);
    static X_LATCH: AtomicU32 = AtomicU32::new(0);
    static X_EVENTS: AtomicU32 = AtomicU32::new(0);
    static INDEX_TICKS: AtomicU32 = AtomicU32::new(0);
    static INDEX_EVENTS: AtomicU32 = AtomicU32::new(0);

    #[entry]
    fn main() -> ! {
        // Before anything else: the amplifier-enable pin low (its external
        // pull-down already holds it there through reset).
        let Some(dp) = Peripherals::take() else {
            panic!("device peripherals taken twice");
        };
        let Some(mut cp) = cortex_m::Peripherals::take() else {
            panic!("core peripherals taken twice");
        };
        let watchdog_reset = clocks::take_watchdog_reset(&dp.RCC);
        let source = clocks::init(&dp.RCC, &dp.PWR, &dp.FLASH);
        clocks::enable_peripherals(&dp.RCC);
        board::configure_pins();
        timers::start_free_running(&dp.TIM2, &dp.TIM5);
        cp.SCB.enable_icache();
        cp.SCB.enable_dcache(&mut cp.CPUID);
        // SAFETY: DBGMCU_CR bits 0..2 (DBGSLEEP/STOP/STBY_D1) and 21..22
        // (D1/D3 debug clocks) keep the debug port and RTT reachable while
        // the core sleeps in `wfi`; they do nothing without a debugger.
        unsafe {
            dp.DBGMCU
                .cr()
                .modify(|r, w| w.bits(r.bits() | 0b111 | (1 << 21) | (1 << 22)));
        }

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
        // The quad DAC of the legacy coefficient-output mode: bus ready, LDAC
        // idle high; its driver arrives with that mode.
        let _quad_spi = SpiDev::new(dp.SPI3, 1, spi::Mode::Mode1, Output(pins::QUAD_DAC_SYNC));

        let mut dac = Ad5791::new(amp_spi);
        let mut fw = Firmware::new(LoopConfig::at_rate(timers::LOOP_HZ));
        // Until the command path lands, the loop holds the slide at null.
        fw.set_target_code(0);
        if dac.release_clamp().is_err() {
            fw.trip(Fault::Bus(Device::AmplifierDac));
        }
        let lp = Loop {
            fw,
            gauge: Ad4020::new(gauge_spi),
            dac,
        };
        critical_section::with(|cs| HANDOFF.borrow(cs).replace(Some(lp)));

        board::configure_exti(&dp.SYSCFG, &dp.EXTI);
        timers::start_watchdog(&dp.IWDG, &dp.DBGMCU);
        timers::start_loop_timer(&dp.TIM3);
        // SAFETY: setting priorities and unmasking can break critical
        // sections that rely on masking; none does here: every datum shared
        // with these handlers is an atomic or behind `critical_section`.
        unsafe {
            cp.NVIC.set_priority(Interrupt::TIM3, PRIO_LOOP_TICK);
            cp.NVIC.set_priority(Interrupt::EXTI2, PRIO_X_EVENT);
            cp.NVIC.set_priority(Interrupt::EXTI3, PRIO_INDEX);
            NVIC::unmask(Interrupt::TIM3);
            NVIC::unmask(Interrupt::EXTI2);
            NVIC::unmask(Interrupt::EXTI3);
        }

        background()
    }

    /// Thread mode, the lowest priority: reports, then sleeps.
    fn background() -> ! {
        let mut last_report = timers::micros();
        let mut reported_fault = false;
        loop {
            if !reported_fault && FAULT_PUBLISHED.load(Ordering::Acquire) {
                let fault = critical_section::with(|cs| *FAULT.borrow(cs).borrow());
                if let Some(f) = fault {
                    defmt::error!("fault {} -> {}", f, f.reaction());
                }
                reported_fault = true;
            }
            let now = timers::micros();
            if now.wrapping_sub(last_report) >= 1_000_000 {
                last_report = now;
                defmt::info!(
                    "ticks {=u32}, X events {=u32} (last latch {=u32:#x}), index events {=u32} (last at {=u32})",
                    TICKS.load(Ordering::Relaxed),
                    X_EVENTS.load(Ordering::Relaxed),
                    X_LATCH.load(Ordering::Relaxed),
                    INDEX_EVENTS.load(Ordering::Relaxed),
                    INDEX_TICKS.load(Ordering::Relaxed)
                );
            }
            cortex_m::asm::wfi();
        }
    }

    #[interrupt]
    fn TIM3() {
        static mut LOOP: Option<Loop> = None;
        timers::ack_loop_tick();
        if LOOP.is_none() {
            *LOOP = critical_section::with(|cs| HANDOFF.borrow(cs).take());
        }
        let Some(lp) = LOOP.as_mut() else {
            return;
        };
        lp.fw
            .loop_tick(&zslide::firmware::TickInput::NONE, &mut lp.gauge, &mut lp.dac);
        pins::AMP_ENABLE.set(lp.fw.amplifier_enable());
        timers::feed_watchdog();
        TICKS.store(lp.fw.ticks(), Ordering::Relaxed);
        if let Some(f) = lp.fw.fault() {
            if !FAULT_PUBLISHED.load(Ordering::Relaxed) {
                critical_section::with(|cs| FAULT.borrow(cs).replace(Some(f)));
                FAULT_PUBLISHED.store(true, Ordering::Release);
            }
        }
    }

    /// Legacy half-mil interrupt: latch the word at the edge and publish it
    /// for the X-position logic (`zslide::xpos`, to come).
    #[interrupt]
    fn EXTI2() {
        board::ack_exti(2);
        X_LATCH.store(board::LatchPins.read().0, Ordering::Relaxed);
        X_EVENTS.fetch_add(1, Ordering::Release);
    }

    /// Spindle index: timestamp it for the spindle-angle logic.
    #[interrupt]
    fn EXTI3() {
        board::ack_exti(3);
        INDEX_TICKS.store(timers::now_ticks(), Ordering::Relaxed);
        INDEX_EVENTS.fetch_add(1, Ordering::Release);
    }

    // cortex-m-rt requires the HardFault handler to be an `unsafe fn`; its
    // body does nothing unsafe itself (the pin store is `Pin::set`'s).
    #[exception]
    unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
        cortex_m::interrupt::disable();
        board::force_amplifier_off();
        defmt::error!("hard fault at pc {=u32:#010x}: {}", ef.pc(), Fault::Panic);
        // The watchdog, no longer fed, resets the chip within 10 ms.
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
