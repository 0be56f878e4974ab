//! EXTI lines 0..15 for the CPU (RM0433 §20: RTSR1, FTSR1, CPUIMR1,
//! CPUPR1), SYSCFG's EXTI port selection, the independent watchdog IWDG1
//! (§45: key register, prescaler and reload writable only after 0x5555,
//! PVU/RVU while an update is in flight, reset when the counter reaches 0)
//! and DBGMCU (the debug freeze and clock bits: no effect without a
//! debugger).

use crate::Violation;

#[derive(Default)]
pub struct Exti {
    pub rtsr1: u32,
    pub ftsr1: u32,
    pub cpuimr1: u32,
    pub cpupr1: u32,
}

impl Exti {
    pub fn read(&self, reg: &str) -> Option<u32> {
        Some(match reg {
            "rtsr1" => self.rtsr1,
            "ftsr1" => self.ftsr1,
            "cpuimr1" => self.cpuimr1,
            "cpupr1" => self.cpupr1,
            _ => return None,
        })
    }
    pub fn write(&mut self, reg: &str, v: u32) -> Result<(), Violation> {
        match reg {
            "rtsr1" => self.rtsr1 = v,
            "ftsr1" => self.ftsr1 = v,
            "cpuimr1" => self.cpuimr1 = v,
            "cpupr1" => self.cpupr1 &= !v, // rc_w1
            _ => return Err(Violation::Unmodelled),
        }
        Ok(())
    }
    /// An edge on line `n` (rising when `rising`): latched when that edge
    /// is selected.
    pub fn edge(&mut self, n: u32, rising: bool) {
        let sel = if rising { self.rtsr1 } else { self.ftsr1 };
        if sel & (1 << n) != 0 {
            self.cpupr1 |= 1 << n;
        }
    }
    /// The CPU interrupt line of EXTI `n`.
    pub fn irq_level(&self, n: u32) -> bool {
        self.cpupr1 & self.cpuimr1 & (1 << n) != 0
    }
}

#[derive(Default)]
pub struct Syscfg {
    pub exticr: [u32; 4],
}

impl Syscfg {
    pub fn read(&self, reg: &str) -> Option<u32> {
        let i = ["exticr1", "exticr2", "exticr3", "exticr4"]
            .iter()
            .position(|r| *r == reg)?;
        Some(self.exticr[i])
    }
    pub fn write(&mut self, reg: &str, v: u32) -> Result<(), Violation> {
        let i = ["exticr1", "exticr2", "exticr3", "exticr4"]
            .iter()
            .position(|r| *r == reg)
            .ok_or(Violation::Unmodelled)?;
        self.exticr[i] = v & 0xFFFF;
        Ok(())
    }
    /// The port (0 = A) that EXTI line `n` listens to.
    pub fn port_of(&self, n: u32) -> u32 {
        (self.exticr[(n / 4) as usize] >> (4 * (n % 4))) & 0xF
    }
}

/// LSI, Hz (datasheet DS12110: 32 kHz typical).
const LSI_HZ: u64 = 32_000;

pub struct Iwdg {
    pub running: bool,
    unlocked: bool,
    pub pr: u32,
    pub rlr: u32,
    /// When the counter was last reloaded (ps), and the update in flight.
    reloaded_at: u64,
    /// PVU and RVU: until when each update is in flight (ps).
    update_until: [u64; 2],
    pub feeds: u64,
}

impl Iwdg {
    pub fn new() -> Self {
        Self {
            running: false,
            unlocked: false,
            pr: 0,
            rlr: 0xFFF,
            reloaded_at: 0,
            update_until: [0; 2],
            feeds: 0,
        }
    }
    fn count_ps(&self) -> u64 {
        (4u64 << self.pr.min(6)) * 1_000_000_000_000 / LSI_HZ
    }
    /// When the counter reaches 0 (a reset), if running.
    pub fn expires_at(&self) -> Option<u64> {
        self.running
            .then(|| self.reloaded_at + (u64::from(self.rlr) + 1) * self.count_ps())
    }
    pub fn read(&self, reg: &str, t: u64) -> Option<u32> {
        Some(match reg {
            "pr" => self.pr,
            "rlr" => self.rlr,
            // PVU | RVU for five LSI cycles after a write (RM0433 §45.4.4).
            "sr" => {
                u32::from(t < self.update_until[0]) | (u32::from(t < self.update_until[1]) << 1)
            }
            _ => return None,
        })
    }
    pub fn write(&mut self, reg: &str, v: u32, t: u64) -> Result<(), Violation> {
        let update = 5 * 1_000_000_000_000 / LSI_HZ;
        match reg {
            "kr" => match v & 0xFFFF {
                0xCCCC => {
                    self.running = true;
                    self.reloaded_at = t;
                }
                0x5555 => self.unlocked = true,
                0xAAAA => {
                    self.unlocked = false;
                    self.reloaded_at = t;
                    self.feeds += 1;
                }
                _ => self.unlocked = false,
            },
            "pr" | "rlr" => {
                if !self.unlocked {
                    return Err(Violation::rule(format!(
                        "IWDG_{} written without the 0x5555 key (RM0433 §45.4.5: write-protected; the write is lost)",
                        reg.to_uppercase()
                    )));
                }
                let i = usize::from(reg == "rlr");
                if t < self.update_until[i] {
                    return Err(Violation::rule(format!(
                        "IWDG_{} written while its previous update is in flight ({} set)",
                        reg.to_uppercase(),
                        ["PVU", "RVU"][i]
                    )));
                }
                if i == 0 {
                    self.pr = v & 0b111;
                } else {
                    self.rlr = v & 0xFFF;
                }
                self.update_until[i] = t + update;
            }
            _ => return Err(Violation::Unmodelled),
        }
        Ok(())
    }
}

#[derive(Default)]
pub struct Dbgmcu {
    pub cr: u32,
    pub apb4fz1: u32,
}

impl Dbgmcu {
    pub fn read(&self, reg: &str) -> Option<u32> {
        Some(match reg {
            "idc" => 0x1003_6450, // revision V, H743
            "cr" => self.cr,
            "apb4fz1" => self.apb4fz1,
            _ => return None,
        })
    }
    pub fn write(&mut self, reg: &str, v: u32) -> Result<(), Violation> {
        match reg {
            "cr" => self.cr = v,
            "apb4fz1" => self.apb4fz1 = v,
            _ => return Err(Violation::Unmodelled),
        }
        Ok(())
    }
}
