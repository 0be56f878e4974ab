//! Power, flash wait states and the clock tree (RM0433 §6.8, §8.5, §4.3).
//!
//! | clock | source | frequency |
//! |---|---|---|
//! | PLL1 reference | HSE 8 MHz (ST-LINK MCO, bypass) / 2, or HSI 64 MHz / 16 | 4 MHz |
//! | PLL1 VCO | × 200, wide range | 800 MHz |
//! | `sys_ck` = CPU (`pll1_p`, /2) | PLL1 | 400 MHz |
//! | AXI/AHB (HPRE /2) | `sys_ck` | 200 MHz |
//! | APB1..APB4 (each /2) | AHB | 100 MHz |
//! | APB1 timers (TIM2, TIM3, TIM5: ×2 since APB1 is divided) | APB1 | 200 MHz |
//! | SPI1/2/3 kernel (`pll1_q`, /8; D2CCIP1R.SPI123SEL reset value) | PLL1 | 100 MHz |
//! | SPI4/5 kernel (`rcc_pclk2`; SPI45SEL reset value) | APB2 | 100 MHz |
//!
//! 400 MHz needs voltage scale 1 (VOS1), which every H743 revision (Y and
//! V) allows; 480 MHz would need VOS0 and rev V. Flash: 2 wait states and
//! WRHIGHFREQ = 2 for a 200 MHz AXI clock at VOS1 (RM0433 table 17).
//!
//! HSE is tried first because the loop rate and every timestamp derive from
//! it: the ST-LINK's MCO is crystal-accurate, the HSI only factory-trimmed.
//! Boards whose solder bridges do not route the MCO to PH0 fall back to HSI
//! (reported at boot), with the same frequencies.

use stm32h7::stm32h743v::{FLASH, PWR, RCC};

pub const SYSCLK_HZ: u32 = 400_000_000;
pub const HCLK_HZ: u32 = 200_000_000;
/// Kernel clock of TIM2, TIM3, TIM5.
pub const APB1_TIMER_HZ: u32 = 200_000_000;

/// Where PLL1's reference came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum Source {
    /// 8 MHz from the ST-LINK's MCO into PH0 (HSE bypass).
    HseBypass,
    /// The internal 64 MHz RC oscillator (HSE did not start).
    Hsi,
}

const CR_HSEON: u32 = 1 << 16;
const CR_HSERDY: u32 = 1 << 17;
const CR_HSEBYP: u32 = 1 << 18;
const CR_PLL1ON: u32 = 1 << 24;
const CR_PLL1RDY: u32 = 1 << 25;
/// Polls of HSERDY before falling back to HSI: at 64 MHz, a few ms; an
/// external clock is ready within a few cycles when it is there at all.
const HSE_POLLS: u32 = 200_000;

/// Sets up power, flash and clocks as tabled above. Call once, first thing.
pub fn init(rcc: &RCC, pwr: &PWR, flash: &FLASH) -> Source {
    // SAFETY (every raw `bits` write in this function): the values are the
    // ones tabled above, in the field layout of RM0433 rev 8, written in the
    // order the manual requires (supply, then voltage scale, then wait
    // states, then PLL, then the switch). `main` calls this once, before
    // anything else depends on a clock.
    unsafe {
        // Supply: LDO on, SMPS absent on the H743 (CR3: SCUEN | LDOEN). The
        // first write after reset locks the configuration.
        pwr.cr3().write(|w| w.bits(0b110));
        while pwr.csr1().read().bits() & (1 << 13) == 0 {} // ACTVOSRDY
        pwr.d3cr().write(|w| w.bits(0b11 << 14)); // VOS1
        while pwr.d3cr().read().bits() & (1 << 13) == 0 {} // VOSRDY

        let acr = 2 | (2 << 4); // LATENCY = 2, WRHIGHFREQ = 2
        flash.acr().write(|w| w.bits(acr));
        while flash.acr().read().bits() & 0x3F != acr {}

        rcc.cr()
            .modify(|r, w| w.bits(r.bits() | CR_HSEBYP | CR_HSEON));
        let mut source = Source::Hsi;
        for _ in 0..HSE_POLLS {
            if rcc.cr().read().bits() & CR_HSERDY != 0 {
                source = Source::HseBypass;
                break;
            }
        }
        // PLLSRC (bits 1..0): 00 HSI, 10 HSE; DIVM1 (bits 9..4).
        let pllckselr = match source {
            Source::HseBypass => 0b10 | (2 << 4),
            Source::Hsi => {
                rcc.cr()
                    .modify(|r, w| w.bits(r.bits() & !(CR_HSEON | CR_HSEBYP)));
                16 << 4
            }
        };
        rcc.pllckselr().write(|w| w.bits(pllckselr));
        // PLL1RGE = 4..8 MHz, wide VCO, integer mode, P/Q/R outputs enabled.
        rcc.pllcfgr()
            .write(|w| w.bits((0b10 << 2) | (1 << 16) | (1 << 17) | (1 << 18)));
        // DIVN1 = 200, DIVP1 = 2, DIVQ1 = 8, DIVR1 = 2 (fields hold n − 1).
        rcc.pll1divr()
            .write(|w| w.bits(199 | (1 << 9) | (7 << 16) | (1 << 24)));
        rcc.cr().modify(|r, w| w.bits(r.bits() | CR_PLL1ON));
        while rcc.cr().read().bits() & CR_PLL1RDY == 0 {}

        // D1CPRE /1, HPRE /2, D1PPRE /2; D2PPRE1/2 /2; D3PPRE /2.
        rcc.d1cfgr().write(|w| w.bits(0b1000 | (0b100 << 4)));
        rcc.d2cfgr().write(|w| w.bits((0b100 << 4) | (0b100 << 8)));
        rcc.d3cfgr().write(|w| w.bits(0b100 << 4));
        // SW = PLL1 (bits 2..0), wait for SWS (bits 5..3).
        rcc.cfgr()
            .modify(|r, w| w.bits((r.bits() & !0b111) | 0b011));
        while (rcc.cfgr().read().bits() >> 3) & 0b111 != 0b011 {}
        source
    }
}

/// Clocks for every peripheral the board uses: GPIOA..G, TIM2/3/4/5, SPI1,
/// SPI3, SPI4, SYSCFG (EXTI line routing).
pub fn enable_peripherals(rcc: &RCC) {
    // SAFETY: enable bits only (RM0433 §8.7): AHB4ENR bits 0..6 = GPIOA..G;
    // APB1LENR TIM2EN 0, TIM3EN 1, TIM4EN 2, TIM5EN 3, SPI3EN 15; APB2ENR SPI1EN 12,
    // SPI4EN 13; APB4ENR SYSCFGEN 1. Setting them has no other effect.
    unsafe {
        rcc.ahb4enr().modify(|r, w| w.bits(r.bits() | 0x7F));
        rcc.apb1lenr()
            .modify(|r, w| w.bits(r.bits() | 0b1111 | (1 << 15)));
        rcc.apb2enr()
            .modify(|r, w| w.bits(r.bits() | (1 << 12) | (1 << 13)));
        rcc.apb4enr().modify(|r, w| w.bits(r.bits() | (1 << 1)));
    }
    // RM0433 §8.5.10: wait two cycles after enabling before access.
    let _ = rcc.apb4enr().read();
    cortex_m::asm::dsb();
}

/// Whether the last reset came from the independent watchdog (RSR.IWDG1RSTF,
/// bit 26); clears the reset flags (RMVF, bit 16).
pub fn take_watchdog_reset(rcc: &RCC) -> bool {
    let was = rcc.rsr().read().bits() & (1 << 26) != 0;
    // SAFETY: RMVF only clears the reset-cause flags.
    unsafe { rcc.rsr().modify(|r, w| w.bits(r.bits() | (1 << 16))) };
    was
}
