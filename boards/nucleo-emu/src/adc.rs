//! ADC1 and the ADC1/2 common block (RM0433 §25), as far as the centring
//! image uses them: deep power-down, the regulator (LDORDY), calibration
//! (ADCAL), enable (ADRDY), an injected sequence of up to four channels by
//! software trigger (JADSTART, JEOC/JEOS, JDR1..4), the clock mode.
//!
//! Rules: leaving deep power-down and starting the regulator, calibrating
//! and configuring only while ADEN = 0 (§25.4.6, §25.4.8, §25.4.9);
//! ADEN before LDORDY; JADSTART while disabled; CCR while ADC1 is enabled.

use crate::Violation;

/// Regulator start-up (datasheet t_ADCVREG_STUP ≤ 10 µs), calibration
/// (≈ 16 k ADC clocks at 25 MHz), one injected conversion (16.5 sampling
/// + 8.5 conversion cycles at 25 MHz), ps.
const LDO_PS: u64 = 10_000_000;
const CAL_PS: u64 = 655_000_000;
const CONV_PS: u64 = 1_000_000;

pub struct Adc {
    cr: u32,
    isr: u32,
    cfgr: u32,
    pcsel: u32,
    smpr2: u32,
    jsqr: u32,
    jdr: [u32; 4],
    ccr: u32,
    ldo_at: Option<u64>,
    cal_until: u64,
    jeos_at: Option<u64>,
    /// The input voltages the world applies, by channel: 16-bit codes.
    pub codes: [u16; 20],
    pub conversions: u64,
}

const CR_DEEPPWD: u32 = 1 << 29;
const CR_ADVREGEN: u32 = 1 << 28;
const CR_ADCAL: u32 = 1 << 31;
const CR_ADEN: u32 = 1 << 0;
const CR_JADSTART: u32 = 1 << 3;
const ISR_ADRDY: u32 = 1 << 0;
const ISR_JEOC: u32 = 1 << 5;
const ISR_JEOS: u32 = 1 << 6;
const ISR_LDORDY: u32 = 1 << 12;

impl Adc {
    pub fn new() -> Self {
        Self {
            cr: CR_DEEPPWD,
            isr: 0,
            cfgr: 0x8000_0000,
            pcsel: 0,
            smpr2: 0,
            jsqr: 0,
            jdr: [0; 4],
            ccr: 0,
            ldo_at: None,
            cal_until: 0,
            jeos_at: None,
            // Mid-scale: 0 V of tachometer (docs of src/board/adc.rs).
            codes: [32_768; 20],
            conversions: 0,
        }
    }

    fn enabled(&self) -> bool {
        self.cr & CR_ADEN != 0
    }

    fn settle(&mut self, t: u64) {
        if self.ldo_at.is_some_and(|at| t >= at) {
            self.isr |= ISR_LDORDY;
        }
        if self.cr & CR_ADCAL != 0 && t >= self.cal_until {
            self.cr &= !CR_ADCAL;
        }
        if let Some(at) = self.jeos_at {
            if t >= at {
                self.jeos_at = None;
                let n = ((self.jsqr & 0b11) + 1) as usize;
                for k in 0..n {
                    let ch = ((self.jsqr >> (9 + 6 * k)) & 0x1F) as usize;
                    self.jdr[k] = u32::from(self.codes.get(ch).copied().unwrap_or(0));
                }
                self.conversions += 1;
                self.isr |= ISR_JEOC | ISR_JEOS;
                self.cr &= !CR_JADSTART;
            }
        }
    }

    pub fn read(&mut self, reg: &str, t: u64) -> Option<u32> {
        self.settle(t);
        Some(match reg {
            "isr" => self.isr,
            "cr" => self.cr,
            "cfgr" => self.cfgr,
            "pcsel" => self.pcsel,
            "smpr2" => self.smpr2,
            "jsqr" => self.jsqr,
            "jdr1" => self.jdr[0],
            "jdr2" => self.jdr[1],
            "jdr3" => self.jdr[2],
            "jdr4" => self.jdr[3],
            _ => return None,
        })
    }

    pub fn write(&mut self, reg: &str, v: u32, t: u64) -> Result<(), Violation> {
        self.settle(t);
        let disabled_only = |what: &str, on: bool| {
            if on {
                Err(Violation::rule(format!(
                    "ADC1_{what} written with ADEN = 1 (RM0433 §25.4.9: configuration while the ADC is disabled)"
                )))
            } else {
                Ok(())
            }
        };
        match reg {
            "isr" => self.isr &= !v, // rc_w1
            "cr" => {
                let on = self.enabled();
                if v & CR_ADVREGEN != 0 && v & CR_DEEPPWD != 0 {
                    return Err(Violation::rule(
                        "ADC1_CR: ADVREGEN with DEEPPWD set (§25.4.6: leave deep power-down first)",
                    ));
                }
                if v & CR_ADVREGEN != 0 && self.cr & CR_ADVREGEN == 0 {
                    self.ldo_at = Some(t + LDO_PS);
                }
                if v & CR_ADCAL != 0 {
                    if on {
                        return Err(Violation::rule("ADC1_CR: ADCAL with ADEN = 1 (§25.4.8)"));
                    }
                    if self.isr & ISR_LDORDY == 0 {
                        return Err(Violation::rule(
                            "ADC1_CR: ADCAL before LDORDY (the regulator is not ready)",
                        ));
                    }
                    self.cal_until = t + CAL_PS;
                }
                if v & CR_ADEN != 0 && !on {
                    if self.isr & ISR_LDORDY == 0 {
                        return Err(Violation::rule("ADC1_CR: ADEN before LDORDY"));
                    }
                    if self.cr & CR_ADCAL != 0 {
                        return Err(Violation::rule("ADC1_CR: ADEN while calibrating"));
                    }
                    self.isr |= ISR_ADRDY;
                }
                if v & CR_JADSTART != 0 && self.cr & CR_JADSTART == 0 {
                    if !on && v & CR_ADEN == 0 {
                        return Err(Violation::rule("ADC1_CR: JADSTART with the ADC disabled"));
                    }
                    let n = u64::from((self.jsqr & 0b11) + 1);
                    self.jeos_at = Some(t + n * CONV_PS);
                }
                // ADCAL stays set until the calibration ends.
                let keep = self.cr & CR_ADCAL;
                self.cr = v | keep;
                if v & CR_ADCAL != 0 {
                    self.cr |= CR_ADCAL;
                }
            }
            "cfgr" => {
                disabled_only("CFGR", self.enabled())?;
                self.cfgr = v;
            }
            "pcsel" => {
                disabled_only("PCSEL", self.enabled())?;
                self.pcsel = v;
            }
            "smpr2" => {
                disabled_only("SMPR2", self.enabled())?;
                self.smpr2 = v;
            }
            "jsqr" => {
                if self.cr & CR_JADSTART != 0 {
                    return Err(Violation::rule(
                        "ADC1_JSQR written while an injected sequence runs (JADSTART = 1)",
                    ));
                }
                self.jsqr = v;
            }
            _ => return Err(Violation::Unmodelled),
        }
        Ok(())
    }

    pub fn read_common(&self, reg: &str) -> Option<u32> {
        (reg == "ccr").then_some(self.ccr)
    }

    pub fn write_common(&mut self, reg: &str, v: u32) -> Result<(), Violation> {
        if reg != "ccr" {
            return Err(Violation::Unmodelled);
        }
        if self.enabled() {
            return Err(Violation::rule("ADC12_CCR written with ADC1 enabled (§25.4.3: the clock mode is set with both ADCs disabled)"));
        }
        self.ccr = v;
        Ok(())
    }
}
