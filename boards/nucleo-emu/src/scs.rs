//! The Cortex-M7's system control space (ARMv7-M ARM, B3): NVIC (enables,
//! pending, active, 8-bit priority fields of which the H743 implements the
//! top 4), SCB (CPUID, ICSR, VTOR, AIRCR, SCR, CCR with the cache enables,
//! SHPR, SHCSR, CFSR, CPACR), the cache maintenance operations, the FPU's FPCCR, and
//! SysTick. Exception entry and return themselves are `cpu.rs`'s.

use crate::Violation;

/// IRQs the H743 has (RM0433 table 137: 150 lines).
pub const IRQS: usize = 150;
/// Priority bits the H743 implements.
pub const PRIO_BITS: u32 = 4;

pub struct Scs {
    pub enabled: [bool; IRQS],
    pub pending: [bool; IRQS],
    pub ipr: [u8; IRQS],
    /// SHPR bytes for exceptions 4..15.
    pub shpr: [u8; 12],
    pub vtor: u32,
    pub cpacr: u32,
    pub ccr: u32,
    pub scr: u32,
    /// SHCSR: the fault handlers' enables and pended bits, as written.
    pub shcsr: u32,
    /// CFSR: write 1 to clear. The model raises no fault status (an
    /// access it cannot serve stops the run instead), so it reads 0
    /// unless a status bit is set here.
    pub cfsr: u32,
    pub aircr_prigroup: u32,
    pub fpccr: u32,
    /// The data cache was invalidated (all sets and ways) since reset.
    dcache_invalidated: bool,
    dcisw_ops: u32,
    csselr: u32,
    pub systick: [u32; 3],
    pub pendsv: bool,
    pub reset_requested: bool,
}

/// The M7's cache geometry (CCSIDR): 16 KiB data cache, 4 ways × 128
/// sets of 32 bytes; 16 KiB instruction cache, 2 ways × 256 sets.
const CCSIDR_D: u32 = 0xF01F_E019;
const CCSIDR_I: u32 = 0xF03F_C00B;
const DCACHE_SETS_WAYS: u32 = 128 * 4;

impl Scs {
    pub fn new(vtor: u32) -> Self {
        Self {
            enabled: [false; IRQS],
            pending: [false; IRQS],
            ipr: [0; IRQS],
            shpr: [0; 12],
            vtor,
            cpacr: 0,
            ccr: 0x0000_0200, // STKALIGN
            scr: 0,
            shcsr: 0,
            cfsr: 0,
            aircr_prigroup: 0,
            fpccr: 0xC000_0000, // ASPEN | LSPEN
            dcache_invalidated: false,
            dcisw_ops: 0,
            csselr: 0,
            systick: [0; 3],
            pendsv: false,
            reset_requested: false,
        }
    }

    /// Priority of exception `n` (16 + IRQ for interrupts), as the NVIC
    /// compares it: the implemented bits only.
    pub fn priority(&self, n: u32) -> u8 {
        let mask = !((1u8 << (8 - PRIO_BITS)) - 1);
        match n {
            4..=15 => self.shpr[(n - 4) as usize] & mask,
            n if n >= 16 && ((n - 16) as usize) < IRQS => self.ipr[(n - 16) as usize] & mask,
            _ => 0,
        }
    }

    pub fn read(&mut self, off: u32, size: usize) -> Result<u32, Violation> {
        let word = |flags: &[bool; IRQS], base: u32| -> u32 {
            let i = ((off - base) / 4) as usize * 32;
            (0..32).fold(0, |v, b| {
                v | (u32::from(*flags.get(i + b).unwrap_or(&false)) << b)
            })
        };
        Ok(match off {
            0xE010 => self.systick[0],
            0xE014 => self.systick[1],
            0xE018 => self.systick[2],
            0xE100..=0xE11C => word(&self.enabled, 0xE100),
            0xE180..=0xE19C => word(&self.enabled, 0xE180),
            0xE200..=0xE21C => word(&self.pending, 0xE200),
            0xE280..=0xE29C => word(&self.pending, 0xE280),
            0xE400..=0xE4EF => {
                let i = (off - 0xE400) as usize;
                (0..size).fold(0, |v, k| {
                    v | (u32::from(*self.ipr.get(i + k).unwrap_or(&0)) << (8 * k))
                })
            }
            0xED00 => 0x411F_C271, // CPUID: Cortex-M7 r1p1 (H743 revision V)
            0xED08 => self.vtor,
            0xED0C => 0xFA05_0000 | (self.aircr_prigroup << 8),
            0xED10 => self.scr,
            0xED14 => self.ccr,
            0xED18..=0xED23 => {
                let i = (off - 0xED18) as usize;
                (0..size).fold(0, |v, k| v | (u32::from(self.shpr[i + k]) << (8 * k)))
            }
            0xED24 => self.shcsr,
            0xED28 => self.cfsr,
            0xED78 => 0x0900_0003, // CLIDR: I and D caches at level 1
            0xED7C => 0x8303_C003, // CTR
            0xED80 => {
                if self.csselr & 1 != 0 {
                    CCSIDR_I
                } else {
                    CCSIDR_D
                }
            }
            0xED84 => self.csselr,
            0xED88 => self.cpacr,
            0xEF34 => self.fpccr,
            _ => return Err(Violation::Unmodelled),
        })
    }

    pub fn write(&mut self, off: u32, size: usize, v: u32) -> Result<(), Violation> {
        let set = |flags: &mut [bool; IRQS], base: u32, to: bool| {
            let i = ((off - base) / 4) as usize * 32;
            for b in 0..32 {
                if v & (1 << b) != 0 {
                    if let Some(f) = flags.get_mut(i + b) {
                        *f = to;
                    }
                }
            }
        };
        match off {
            0xE010 => self.systick[0] = v & 0x7,
            0xE014 => self.systick[1] = v & 0xFF_FFFF,
            0xE018 => self.systick[2] = 0,
            0xE100..=0xE11C => set(&mut self.enabled, 0xE100, true),
            0xE180..=0xE19C => set(&mut self.enabled, 0xE180, false),
            0xE200..=0xE21C => set(&mut self.pending, 0xE200, true),
            0xE280..=0xE29C => set(&mut self.pending, 0xE280, false),
            0xE400..=0xE4EF => {
                let i = (off - 0xE400) as usize;
                for k in 0..size {
                    let byte = (v >> (8 * k)) as u8;
                    if byte & ((1 << (8 - PRIO_BITS)) - 1) != 0 {
                        return Err(Violation::rule(format!(
                            "NVIC_IPR{}: priority {byte:#04x} uses bits below the {PRIO_BITS} the H743 implements (they read as 0: two priorities meant to differ may not)",
                            i + k
                        )));
                    }
                    if let Some(p) = self.ipr.get_mut(i + k) {
                        *p = byte;
                    }
                }
            }
            0xED04 => {
                if v & (1 << 28) != 0 {
                    self.pendsv = true;
                }
                if v & (1 << 27) != 0 {
                    self.pendsv = false;
                }
            }
            0xED08 => self.vtor = v & !0x7F,
            0xED0C => {
                if v >> 16 != 0x05FA {
                    return Err(Violation::rule(
                        "SCB_AIRCR written without VECTKEY 0x05FA (the write is ignored)",
                    ));
                }
                self.aircr_prigroup = (v >> 8) & 0b111;
                if v & (1 << 2) != 0 {
                    self.reset_requested = true;
                }
            }
            0xED10 => self.scr = v,
            0xED14 => {
                if v & (1 << 16) != 0 && self.ccr & (1 << 16) == 0 && !self.dcache_invalidated {
                    return Err(Violation::rule(
                        "SCB_CCR.DC set before the data cache was invalidated (its contents are unknown at reset)",
                    ));
                }
                self.ccr = v;
            }
            0xED18..=0xED23 => {
                let i = (off - 0xED18) as usize;
                for k in 0..size {
                    self.shpr[i + k] = (v >> (8 * k)) as u8;
                }
            }
            0xED24 => self.shcsr = v,
            0xED28 => self.cfsr &= !v,
            0xED84 => self.csselr = v,
            0xED88 => self.cpacr = v,
            0xEF34 => self.fpccr = v,
            // ICIALLU, ICIMVAU, DCIMVAC, DCISW, DCCMVAU, DCCMVAC, DCCSW,
            // DCCIMVAC, DCCISW, BPIALL: maintenance operations (the model
            // keeps no cache, so they change nothing but the DC rule).
            0xEF50 | 0xEF58 | 0xEF5C | 0xEF64 | 0xEF68 | 0xEF6C | 0xEF70 | 0xEF74 | 0xEF78 => {}
            0xEF60 => {
                self.dcisw_ops += 1;
                if self.dcisw_ops >= DCACHE_SETS_WAYS {
                    self.dcache_invalidated = true;
                }
            }
            _ => return Err(Violation::Unmodelled),
        }
        Ok(())
    }

    /// The FPU is enabled for the CPU (CPACR CP10/CP11 full access).
    pub fn fpu_enabled(&self) -> bool {
        (self.cpacr >> 20) & 0xF == 0xF
    }
}
