//! RCC and PWR (RM0433 §8, §6): ready bits follow their enables, and the
//! clock tree the registers describe gives every frequency the other models
//! use (CPU, timers, SPI kernels). FLASH_ACR's wait states are checked
//! against the AXI clock at the switch (RM0433 table 17).

use crate::Violation;

pub const HSE_HZ: u64 = 8_000_000; // ST-LINK MCO, bypass
pub const HSI_HZ: u64 = 64_000_000;

pub struct Rcc {
    pub cr: u32,
    pub cfgr: u32,
    pub d1cfgr: u32,
    pub d2cfgr: u32,
    pub d3cfgr: u32,
    pub pllckselr: u32,
    pub pllcfgr: u32,
    pub pll1divr: u32,
    pub rsr: u32,
    pub ahb1enr: u32,
    pub ahb4enr: u32,
    pub apb1lenr: u32,
    pub apb2enr: u32,
    pub apb4enr: u32,
}

const CR_HSION: u32 = 1 << 0;
const CR_HSIRDY: u32 = 1 << 2;
const CR_HSEON: u32 = 1 << 16;
const CR_HSERDY: u32 = 1 << 17;
const CR_PLL1ON: u32 = 1 << 24;
const CR_PLL1RDY: u32 = 1 << 25;

impl Rcc {
    pub fn new(watchdog_reset: bool) -> Self {
        Self {
            cr: CR_HSION | CR_HSIRDY | (1 << 5), // HSI on and ready, HSIDIV /1
            cfgr: 0,
            d1cfgr: 0,
            d2cfgr: 0,
            d3cfgr: 0,
            pllckselr: 0x0202_0200, // DIVM1..3 = 32, PLLSRC = HSI
            pllcfgr: 0x01FF_0000,
            pll1divr: 0x0101_0280,
            // PORRSTF, PINRSTF, BORRSTF, D1/D2RSTF: a power-on; IWDG1RSTF
            // after a watchdog reset.
            rsr: 0x00FE_0000 | if watchdog_reset { 1 << 26 } else { 0 },
            ahb1enr: 0,
            ahb4enr: 0,
            apb1lenr: 0,
            apb2enr: 0,
            apb4enr: 0,
        }
    }

    pub fn read(&self, reg: &str) -> Option<u32> {
        Some(match reg {
            "cr" => self.cr,
            "cfgr" => self.cfgr,
            "d1cfgr" => self.d1cfgr,
            "d2cfgr" => self.d2cfgr,
            "d3cfgr" => self.d3cfgr,
            "pllckselr" => self.pllckselr,
            "pllcfgr" => self.pllcfgr,
            "pll1divr" => self.pll1divr,
            "rsr" | "c1_rsr" => self.rsr,
            "ahb1enr" | "c1_ahb1enr" => self.ahb1enr,
            "ahb4enr" | "c1_ahb4enr" => self.ahb4enr,
            "apb1lenr" | "c1_apb1lenr" => self.apb1lenr,
            "apb2enr" | "c1_apb2enr" => self.apb2enr,
            "apb4enr" | "c1_apb4enr" => self.apb4enr,
            _ => return None,
        })
    }

    pub fn write(
        &mut self,
        reg: &str,
        v: u32,
        flash_acr: u32,
        vos1: bool,
    ) -> Result<bool, Violation> {
        match reg {
            "cr" => {
                // Ready bits follow the enables (an 8 MHz MCO is there).
                let mut cr = v & !(CR_HSIRDY | CR_HSERDY | CR_PLL1RDY | (1 << 14));
                if cr & CR_HSION != 0 {
                    cr |= CR_HSIRDY;
                }
                if cr & CR_HSEON != 0 {
                    cr |= CR_HSERDY;
                }
                if cr & CR_PLL1ON != 0 {
                    cr |= CR_PLL1RDY;
                }
                if self.sws() == 0b011 && cr & CR_PLL1ON == 0 {
                    return Err(Violation::rule(
                        "RCC_CR: PLL1 turned off while it clocks the system",
                    ));
                }
                self.cr = cr;
            }
            "cfgr" => {
                let sw = v & 0b111;
                if sw == 0b011 {
                    if self.cr & CR_PLL1RDY == 0 {
                        return Err(Violation::rule("RCC_CFGR: SW = PLL1 before PLL1RDY"));
                    }
                    self.cfgr = v;
                    let hclk = self.hclk_hz_if(0b011);
                    check_wait_states(hclk, flash_acr, vos1)?;
                    // SWS follows SW.
                    self.cfgr = (v & !(0b111 << 3)) | (sw << 3);
                    return Ok(true);
                }
                self.cfgr = (v & !(0b111 << 3)) | (sw << 3);
            }
            "d1cfgr" => self.d1cfgr = v,
            "d2cfgr" => self.d2cfgr = v,
            "d3cfgr" => self.d3cfgr = v,
            "pllckselr" | "pllcfgr" | "pll1divr" => {
                if self.cr & CR_PLL1ON != 0 {
                    return Err(Violation::rule(
                        "RCC PLL1 configuration written while PLL1 is on (RM0433 §8.7: only while PLL1ON = 0)",
                    ));
                }
                match reg {
                    "pllckselr" => self.pllckselr = v,
                    "pllcfgr" => self.pllcfgr = v,
                    _ => self.pll1divr = v,
                }
            }
            "rsr" | "c1_rsr" => {
                if v & (1 << 16) != 0 {
                    self.rsr = 0; // RMVF
                }
            }
            "ahb1enr" | "c1_ahb1enr" => self.ahb1enr = v,
            "ahb4enr" | "c1_ahb4enr" => self.ahb4enr = v,
            "apb1lenr" | "c1_apb1lenr" => self.apb1lenr = v,
            "apb2enr" | "c1_apb2enr" => self.apb2enr = v,
            "apb4enr" | "c1_apb4enr" => self.apb4enr = v,
            _ => return Err(Violation::Unmodelled),
        }
        Ok(false)
    }

    fn sws(&self) -> u32 {
        (self.cfgr >> 3) & 0b111
    }

    fn pll1_vco_hz(&self) -> u64 {
        let src = match self.pllckselr & 0b11 {
            0b00 => HSI_HZ,
            0b10 => HSE_HZ,
            _ => 0,
        };
        let divm = u64::from((self.pllckselr >> 4) & 0x3F);
        if divm == 0 {
            return 0;
        }
        let n = u64::from(self.pll1divr & 0x1FF) + 1;
        src / divm * n
    }
    fn pll1_p_hz(&self) -> u64 {
        self.pll1_vco_hz() / (u64::from((self.pll1divr >> 9) & 0x7F) + 1)
    }
    pub fn pll1_q_hz(&self) -> u64 {
        self.pll1_vco_hz() / (u64::from((self.pll1divr >> 16) & 0x7F) + 1)
    }

    /// The system clock (CPU).
    pub fn sys_hz(&self) -> u64 {
        match self.sws() {
            0b011 => self.pll1_p_hz(),
            0b010 => HSE_HZ,
            _ => HSI_HZ,
        }
    }
    fn hclk_hz_if(&self, sws: u32) -> u64 {
        let sys = if sws == 0b011 {
            self.pll1_p_hz()
        } else {
            self.sys_hz()
        };
        sys / div(self.d1cfgr >> 8) / div(self.d1cfgr)
    }
    pub fn hclk_hz(&self) -> u64 {
        self.hclk_hz_if(self.sws())
    }
    fn pclk1_hz(&self) -> u64 {
        self.hclk_hz() / apb_div(self.d2cfgr >> 4)
    }
    pub fn pclk2_hz(&self) -> u64 {
        self.hclk_hz() / apb_div(self.d2cfgr >> 8)
    }
    /// TIM2..7 kernel clock: twice PCLK1 when APB1 is divided (TIMPRE = 0).
    pub fn apb1_timer_hz(&self) -> u64 {
        if apb_div(self.d2cfgr >> 4) > 1 {
            2 * self.pclk1_hz()
        } else {
            self.pclk1_hz()
        }
    }
    /// Whether a peripheral's bus clock is on (RM0433 §8.5.10: an access
    /// to a peripheral whose clock is off reads 0 and drops writes).
    pub fn clocked(&self, periph: &str) -> bool {
        let bit = |r: u32, b: u32| r & (1 << b) != 0;
        match periph {
            p if p.starts_with("GPIO") => {
                let n = u32::from(p.as_bytes()[4] - b'A');
                bit(self.ahb4enr, n)
            }
            "TIM2" => bit(self.apb1lenr, 0),
            "TIM3" => bit(self.apb1lenr, 1),
            "TIM4" => bit(self.apb1lenr, 2),
            "TIM5" => bit(self.apb1lenr, 3),
            "SPI3" => bit(self.apb1lenr, 15),
            "SPI1" => bit(self.apb2enr, 12),
            "SPI4" => bit(self.apb2enr, 13),
            "SYSCFG" => bit(self.apb4enr, 1),
            "ADC1" | "ADC12_COMMON" => bit(self.ahb1enr, 5),
            _ => true,
        }
    }
}

/// HPRE / D1CPRE (4 bits: 0xxx = 1, 1000 = 2, ... 1111 = 512).
fn div(field: u32) -> u64 {
    let f = field & 0xF;
    if f < 8 {
        1
    } else {
        [2, 4, 8, 16, 64, 128, 256, 512][(f - 8) as usize]
    }
}
/// D1PPRE/D2PPRE1/2/D3PPRE (3 bits: 0xx = 1, 100 = 2 .. 111 = 16).
fn apb_div(field: u32) -> u64 {
    let f = field & 0b111;
    if f < 4 {
        1
    } else {
        1 << (f - 3)
    }
}

/// RM0433 table 17 (VOS1): AXI clock limits per LATENCY with WRHIGHFREQ.
fn check_wait_states(hclk: u64, acr: u32, vos1: bool) -> Result<(), Violation> {
    let latency = acr & 0xF;
    let wrhighfreq = (acr >> 4) & 0b11;
    if !vos1 && hclk > 100_000_000 {
        return Err(Violation::rule(
            "switch to PLL1: AXI clock above 100 MHz without VOS1 ready (RM0433 §6.8.6)",
        ));
    }
    let max = match (latency, wrhighfreq) {
        (0, 0) => 70_000_000,
        (1, 1) => 140_000_000,
        (2, 2) => 210_000_000,
        (l, w) if l >= 2 && w >= 2 => 225_000_000,
        _ => 0,
    };
    if hclk > max {
        return Err(Violation::rule(format!(
            "switch to PLL1: AXI clock {} MHz with FLASH_ACR LATENCY = {latency}, WRHIGHFREQ = {wrhighfreq} (RM0433 table 17 at VOS1)",
            hclk / 1_000_000
        )));
    }
    Ok(())
}

pub struct Pwr {
    pub cr3: u32,
    cr3_written: bool,
    pub d3cr: u32,
}

impl Pwr {
    pub fn new() -> Self {
        Self {
            cr3: 0b110, // SCUEN, LDOEN
            cr3_written: false,
            d3cr: 0b01 << 14, // VOS3
        }
    }
    pub fn vos1_ready(&self) -> bool {
        (self.d3cr >> 14) & 0b11 == 0b11
    }
    pub fn read(&self, reg: &str) -> Option<u32> {
        Some(match reg {
            "cr3" => self.cr3,
            // ACTVOSRDY (13), and ACTVOS (15:14) following VOS.
            "csr1" => (1 << 13) | (self.d3cr & (0b11 << 14)),
            // VOSRDY follows VOS.
            "d3cr" => self.d3cr | (1 << 13),
            _ => return None,
        })
    }
    pub fn write(&mut self, reg: &str, v: u32) -> Result<(), Violation> {
        match reg {
            "cr3" => {
                // RM0433 §6.8.4: the supply configuration is written once
                // after power-on; later writes are ignored.
                if self.cr3_written && v != self.cr3 {
                    return Err(Violation::rule(
                        "PWR_CR3 written a second time with another supply configuration",
                    ));
                }
                if v & 0b111 != 0b110 {
                    return Err(Violation::rule(format!(
                        "PWR_CR3 = {v:#x}: the H743 has no SMPS; only LDO (LDOEN | SCUEN) is valid"
                    )));
                }
                self.cr3 = v;
                self.cr3_written = true;
            }
            "d3cr" => {
                if !self.cr3_written {
                    return Err(Violation::rule(
                        "PWR_D3CR (VOS) written before the supply configuration (RM0433 §6.8.4)",
                    ));
                }
                self.d3cr = v & (0b11 << 14);
            }
            _ => return Err(Violation::Unmodelled),
        }
        Ok(())
    }
}
