//! NUCLEO-H743ZI2 board support: pins, clocks, timers, SPI, converters.
//! `docs/BOARD.md` is the wiring reference; this module is its source of
//! truth (the pin constants below).

// The tachometer inputs of the centring machine (`zslide-centre`); the
// Z-slide firmware has no analog input yet.
#[allow(dead_code)]
pub mod adc;
pub mod clocks;
// The parameter store's flash: the Z-slide firmware's; the centring image
// saves no parameters.
#[allow(dead_code)]
pub mod flash;
pub mod gpio;
pub mod link;
pub mod spi;
pub mod timers;

use gpio::{Mode, Pin};
use stm32h7::stm32h743v::{EXTI, SYSCFG};
use zslide::hw::{XLatch, XLatchWord};

/// The pin map. Chosen clear of the NUCLEO's LEDs (PB0, PE1, PB14), user
/// button (PC13), Ethernet RMII (PA1, PA2, PA7, PB13, PC1, PC4, PC5, PG11,
/// PG13), USB (PA8..PA12, PG6, PG7) and ST-LINK VCP (PD8, PD9) lines.
pub mod pins {
    use super::gpio::{Pin, Port};

    /// Amplifier enable, active high. Must have an external pull-down so
    /// that reset, power-up and a watchdog reset keep the amplifier off.
    pub const AMP_ENABLE: Pin = Pin::new(Port::G, 4);

    /// SPI1 (AF5), amplifier DAC AD5791, mode 1, 25 MHz.
    pub const AMP_DAC_SCK: Pin = Pin::new(Port::A, 5);
    pub const AMP_DAC_MISO: Pin = Pin::new(Port::A, 6);
    pub const AMP_DAC_MOSI: Pin = Pin::new(Port::B, 5);
    /// AD5791 SYNC (chip select), GPIO, active low.
    pub const AMP_DAC_SYNC: Pin = Pin::new(Port::D, 14);

    /// SPI4 (AF5), gauge ADC AD4020, mode 0, 50 MHz. SDI tied high.
    pub const GAUGE_SCK: Pin = Pin::new(Port::E, 12);
    pub const GAUGE_MISO: Pin = Pin::new(Port::E, 13);
    pub const GAUGE_MOSI: Pin = Pin::new(Port::E, 14);
    /// AD4020 CNV, TIM3_CH1 (AF2): conversion start from the loop timer.
    pub const GAUGE_CNV: Pin = Pin::new(Port::C, 6);

    /// SPI3 (AF6), quad coefficient DAC AD5686, mode 1, 25 MHz.
    pub const QUAD_DAC_SCK: Pin = Pin::new(Port::C, 10);
    pub const QUAD_DAC_MISO: Pin = Pin::new(Port::C, 11);
    pub const QUAD_DAC_MOSI: Pin = Pin::new(Port::C, 12);
    /// AD5686 SYNC, GPIO, active low.
    pub const QUAD_DAC_SYNC: Pin = Pin::new(Port::A, 4);
    /// AD5686 LDAC, GPIO, active low: a low pulse updates all four outputs.
    pub const QUAD_DAC_LDAC: Pin = Pin::new(Port::G, 5);

    /// Legacy X interface: the four latched BCD digits on PF0..PF15
    /// (`hw::XLatchWord` bits 0..15, one port read), the half-mil flag and
    /// the mil-zero flag.
    pub const BCD_PORT: Port = Port::F;
    pub const X_HALF_MIL_FLAG: Pin = Pin::new(Port::G, 0);
    pub const X_MIL_ZERO_FLAG: Pin = Pin::new(Port::G, 1);
    /// The half-mil interrupt, EXTI2 on its rising edge.
    pub const X_HALF_MIL_IRQ: Pin = Pin::new(Port::G, 2);
    /// Spindle once-per-revolution index, wired to two pins: TIM2_CH1
    /// (AF1) captures the edge's time on the clock and raises the index
    /// interrupt; TIM4_CH3 (AF2) captures the encoder count at the edge.
    pub const SPINDLE_INDEX_TIME: Pin = Pin::new(Port::A, 0);
    pub const SPINDLE_INDEX_COUNT: Pin = Pin::new(Port::B, 8);
    /// Arm/disarm: the NUCLEO's user button B1 (high while pressed).
    pub const ARM_BUTTON: Pin = Pin::new(Port::C, 13);
    /// The power amplifier's fault output (high: tripped), pulled down.
    pub const AMP_FAULT: Pin = Pin::new(Port::G, 9);
    /// Spindle encoder A/B, TIM4_CH1/CH2 (AF2): quadrature counter.
    pub const SPINDLE_ENC_A: Pin = Pin::new(Port::D, 12);
    pub const SPINDLE_ENC_B: Pin = Pin::new(Port::D, 13);
    /// The same A/B lines wired also to TIM2_CH3/CH4 (AF1): both edges of
    /// both lines captured on the clock, i.e. every count's edge time.
    pub const SPINDLE_ENC_A_TIME: Pin = Pin::new(Port::B, 10);
    pub const SPINDLE_ENC_B_TIME: Pin = Pin::new(Port::B, 11);
}

/// Configures every pin of the map; outputs start at their safe level
/// (amplifier off, chip selects and LDAC high).
/// What both images do first after RTT: note a watchdog reset (and clear
/// its flag), clocks, peripheral clocks, pins, the free-running clock
/// (TIM2, TIM5), caches, and debug access in sleep. Returns whether the
/// last reset was the watchdog's and the clock source.
pub fn bring_up(
    dp: &stm32h7::stm32h743v::Peripherals,
    cp: &mut cortex_m::Peripherals,
) -> (bool, clocks::Source) {
    let watchdog_reset = clocks::take_watchdog_reset(&dp.RCC);
    let source = clocks::init(&dp.RCC, &dp.PWR, &dp.FLASH);
    clocks::enable_peripherals(&dp.RCC);
    configure_pins();
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
    (watchdog_reset, source)
}

pub fn configure_pins() {
    use pins::*;
    AMP_ENABLE.configure(Mode::Output(false));
    AMP_DAC_SYNC.configure(Mode::Output(true));
    QUAD_DAC_SYNC.configure(Mode::Output(true));
    QUAD_DAC_LDAC.configure(Mode::Output(true));
    for p in [
        AMP_DAC_SCK,
        AMP_DAC_MISO,
        AMP_DAC_MOSI,
        GAUGE_SCK,
        GAUGE_MISO,
        GAUGE_MOSI,
    ] {
        p.configure(Mode::Alternate(5));
    }
    for p in [QUAD_DAC_SCK, QUAD_DAC_MISO, QUAD_DAC_MOSI] {
        p.configure(Mode::Alternate(6));
    }
    GAUGE_CNV.configure(Mode::Alternate(2));
    SPINDLE_ENC_A.configure(Mode::Alternate(2));
    SPINDLE_ENC_B.configure(Mode::Alternate(2));
    SPINDLE_INDEX_COUNT.configure(Mode::Alternate(2));
    for p in [SPINDLE_INDEX_TIME, SPINDLE_ENC_A_TIME, SPINDLE_ENC_B_TIME] {
        p.configure(Mode::Alternate(1));
    }
    for n in 0..16 {
        Pin::new(BCD_PORT, n).configure(Mode::Input(0));
    }
    for p in [X_HALF_MIL_FLAG, X_MIL_ZERO_FLAG, X_HALF_MIL_IRQ, ARM_BUTTON] {
        p.configure(Mode::Input(0));
    }
    AMP_FAULT.configure(Mode::Input(2));
}

/// Routes PG2 to EXTI2, rising edge, unmasked for the CPU (the NVIC line
/// stays masked until `main` unmasks it).
pub fn configure_exti(syscfg: &SYSCFG, exti: &EXTI) {
    const PORT_G: u32 = 6;
    const LINES: u32 = 1 << 2;
    // SAFETY: EXTICR1 field EXTI2 (bits 11..8) selects port G; RTSR1/CPUIMR1
    // bit 2 enables rising-edge events and their interrupt; CPUPR1 clears
    // a stale pending bit (write 1).
    unsafe {
        syscfg
            .exticr1()
            .modify(|r, w| w.bits((r.bits() & !0x0F00) | (PORT_G << 8)));
        exti.rtsr1().modify(|r, w| w.bits(r.bits() | LINES));
        exti.cpupr1().write(|w| w.bits(LINES));
        exti.cpuimr1().modify(|r, w| w.bits(r.bits() | LINES));
    }
}

/// Clears a pending EXTI line (`line` < 16).
pub fn ack_exti(line: u32) {
    // SAFETY: writing 1 to a CPUPR1 bit clears only that line's pending flag.
    unsafe { (*EXTI::ptr()).cpupr1().write(|w| w.bits(1 << (line & 15))) };
}

/// The legacy X latch on the pins above.
pub struct LatchPins;

impl XLatch for LatchPins {
    fn read(&mut self) -> XLatchWord {
        let digits = u32::from(pins::BCD_PORT.read());
        let half = if pins::X_HALF_MIL_FLAG.is_high() {
            XLatchWord::HALF_MIL
        } else {
            0
        };
        let zero = if pins::X_MIL_ZERO_FLAG.is_high() {
            XLatchWord::MIL_ZERO
        } else {
            0
        };
        XLatchWord(digits | half | zero)
    }
}

/// Forces the amplifier off from any context, owning nothing: one store to
/// GPIOG_BSRR. Used by the panic and fault handlers before anything else.
pub fn force_amplifier_off() {
    pins::AMP_ENABLE.set(false);
}
