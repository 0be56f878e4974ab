//! The H743's own ADC1 for two slow analog inputs: the centring slides'
//! tachometers (`zslide-centre`). 16 bits, single-ended 0..3.3 V, an
//! injected sequence of two channels started by software once per loop
//! tick and read at the next (so a tick reads what was converted ≈ 2 µs
//! after the previous one: one tick of delay, which the centring servo's
//! 10 kHz tick makes 0.1 ms).
//!
//! | input | pin | channel |
//! |---|---|---|
//! | tachometer X′ | PA3 (NUCLEO A0) | ADC12_INP15 |
//! | tachometer Y′ | PC0 (NUCLEO A1) | ADC123_INP10 |
//!
//! Conditioning (external, per input): the tachometer's ±25 V span onto
//! the ADC's 0..3.3 V, 1.65 V at 0 V: `v_adc = 1.65 V + v_tach · 1.65/25`
//! (a divider into a buffered mid-rail offset). So code 32 768 is 0 V and
//! one code is 25 V / 32 768 = 762.9 µV of tachometer.
//!
//! Clock: synchronous, HCLK / 4 = 50 MHz (CKMODE = 11), which revision V
//! divides by two internally (25 MHz); BOOST = 11. Register bit positions
//! from RM0433 rev 8 §25.6.

use stm32h7::stm32h743v::{ADC1, ADC12_COMMON, RCC};

use super::gpio::{Mode, Pin, Port};

pub const TACH_X_PIN: Pin = Pin::new(Port::A, 3);
pub const TACH_Y_PIN: Pin = Pin::new(Port::C, 0);
const CH_X: u32 = 15;
const CH_Y: u32 = 10;

/// Tachometer volts per ADC code, as µV = (code − 32 768) · 25·10⁶ / 2¹⁵.
pub const TACH_FULL_SCALE_UV: i64 = 25_000_000;

// ADC_CR
const CR_ADEN: u32 = 1 << 0;
const CR_JADSTART: u32 = 1 << 3;
const CR_BOOST_50MHZ: u32 = 0b11 << 8;
const CR_ADCALLIN: u32 = 1 << 16;
const CR_ADVREGEN: u32 = 1 << 28;
const CR_ADCAL: u32 = 1 << 31;
// ADC_ISR
const ISR_ADRDY: u32 = 1 << 0;
const ISR_JEOC: u32 = 1 << 5;
const ISR_JEOS: u32 = 1 << 6;
const ISR_LDORDY: u32 = 1 << 12;
// ADC_CFGR: injected queue disabled (JQDIS), 16-bit (RES = 000).
const CFGR_JQDIS: u32 = 1 << 31;
/// Polls of a status bit before giving up (each a few cycles at 400 MHz;
/// calibration takes ≈ 16 k ADC cycles = 0.7 ms, the regulator 10 µs).
const SPIN_LIMIT: u32 = 2_000_000;

/// The converter did not answer (a status bit never came).
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub struct AdcTimeout(pub &'static str);

/// The two tachometer inputs.
pub struct Tachometers {
    adc: ADC1,
}

fn wait(adc: &ADC1, bit: u32, set: bool, what: &'static str) -> Result<(), AdcTimeout> {
    for _ in 0..SPIN_LIMIT {
        if (adc.isr().read().bits() & bit != 0) == set {
            return Ok(());
        }
    }
    Err(AdcTimeout(what))
}

impl Tachometers {
    /// Powers up, calibrates and enables ADC1, and starts the first
    /// conversion. Bounded: a converter that never answers is an error.
    pub fn init(adc: ADC1, common: &ADC12_COMMON, rcc: &RCC) -> Result<Self, AdcTimeout> {
        TACH_X_PIN.configure(Mode::Analog);
        TACH_Y_PIN.configure(Mode::Analog);
        // SAFETY: RCC AHB1ENR bit 5 (ADC12EN) only enables the clock; the
        // dummy read is the two-cycle wait of RM0433 §8.5.10.
        unsafe { rcc.ahb1enr().modify(|r, w| w.bits(r.bits() | (1 << 5))) };
        let _ = rcc.ahb1enr().read();
        // SAFETY: ADC12_CCR CKMODE (bits 17:16) = 11, HCLK/4; written while
        // both ADCs are disabled (after reset), as §25.4.3 requires.
        unsafe { common.ccr().write(|w| w.bits(0b11 << 16)) };
        // SAFETY: the power-up sequence of §25.4.6: leave deep power-down
        // (CR = 0 clears DEEPPWD), then the regulator on with BOOST for
        // this clock; ADC1 belongs to this struct alone.
        unsafe {
            adc.cr().write(|w| w.bits(0));
            adc.cr().write(|w| w.bits(CR_ADVREGEN | CR_BOOST_50MHZ));
        }
        wait(&adc, ISR_LDORDY, true, "ADC regulator (LDORDY)")?;
        // SAFETY: single-ended calibration with linearity (§25.4.8): ADCAL
        // with ADCALLIN set and ADCALDIF clear, ADC disabled.
        unsafe {
            adc.cr()
                .write(|w| w.bits(CR_ADVREGEN | CR_BOOST_50MHZ | CR_ADCALLIN | CR_ADCAL));
        }
        for _ in 0..SPIN_LIMIT {
            if adc.cr().read().bits() & CR_ADCAL == 0 {
                break;
            }
        }
        if adc.cr().read().bits() & CR_ADCAL != 0 {
            return Err(AdcTimeout("ADC calibration (ADCAL)"));
        }
        // SAFETY: configuration while disabled (§25.4.9): 16-bit, injected
        // queue off; the two channels preselected (PCSEL), 16.5 cycles of
        // sampling each (SMPR2 fields of 3 bits from channel 10: 011),
        // injected sequence of two (JL = 1) by software trigger (JEXTEN =
        // 00), JSQ1 = X′, JSQ2 = Y′.
        unsafe {
            adc.cfgr().write(|w| w.bits(CFGR_JQDIS));
            adc.pcsel().write(|w| w.bits((1 << CH_X) | (1 << CH_Y)));
            adc.smpr2()
                .write(|w| w.bits((0b011 << (3 * (CH_X - 10))) | (0b011 << (3 * (CH_Y - 10)))));
            adc.jsqr().write(|w| w.bits(1 | (CH_X << 9) | (CH_Y << 15)));
            adc.isr().write(|w| w.bits(ISR_ADRDY));
            adc.cr()
                .write(|w| w.bits(CR_ADVREGEN | CR_BOOST_50MHZ | CR_ADEN));
        }
        wait(&adc, ISR_ADRDY, true, "ADC enable (ADRDY)")?;
        let t = Self { adc };
        t.start();
        Ok(t)
    }

    fn start(&self) {
        // SAFETY: JADSTART starts the injected sequence; ADEN etc. are kept
        // (read-modify-write of this ADC's own CR).
        unsafe { self.adc.cr().modify(|r, w| w.bits(r.bits() | CR_JADSTART)) };
    }

    /// The readings converted since the last call, in µV of tachometer
    /// (X′, Y′), and the next conversion started. `None` if the sequence
    /// has not finished (a converter that stopped): the caller decides.
    pub fn read_uv(&mut self) -> Option<[i32; 2]> {
        if self.adc.isr().read().bits() & ISR_JEOS == 0 {
            return None;
        }
        let x = self.adc.jdr1().read().bits() as i64 & 0xFFFF;
        let y = self.adc.jdr2().read().bits() as i64 & 0xFFFF;
        // SAFETY: JEOS and JEOC are rc_w1 flags of this ADC: writing 1
        // clears exactly them.
        unsafe { self.adc.isr().write(|w| w.bits(ISR_JEOS | ISR_JEOC)) };
        self.start();
        let uv = |code: i64| (((code - 32_768) * TACH_FULL_SCALE_UV) >> 15) as i32;
        Some([uv(x), uv(y)])
    }
}
