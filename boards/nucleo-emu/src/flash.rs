//! The embedded flash interface (RM0433 §4): ACR (wait states) and bank 2
//! (KEYR2, CR2, SR2, CCR2) over bank 2's 1 MiB of cells.
//!
//! Rules enforced (each a stop with the rule's words):
//! * CR2 written while locked (RM0433 §4.5.1); a wrong key sequence locks
//!   CR2 until reset.
//! * A write into bank 2 without PG set (PGSERR in silicon, §4.3.8).
//! * Programming a flash word that is not erased (§4.3.8: only an erased
//!   word may be programmed: its ECC would be wrong).
//! * The eight writes of a 256-bit word not to one flash word, or an
//!   operation started with the last word incomplete (INCERR).
//! * A read of bank 2 while it erases or programs (it would stall the bus:
//!   the firmware's design keeps every handler's data out of bank 2).
//! * Erase with SER and PG together, or START without SER (§4.3.10).
//!
//! Times (datasheet DS12110 table 41 gives 2-4 s per 128 KiB sector and
//! about 16 µs per flash word at x64): the erase is [`ERASE_PS`] here, not
//! seconds, so that a save fits in a short run; the program is 16 µs.

use crate::Violation;

pub const BANK2_BASE: u32 = 0x0810_0000;
pub const BANK2_SIZE: usize = 1 << 20;
const SECTOR: usize = 128 * 1024;
/// Sector erase time here (stated in docs/BOARD.md: silicon takes 2-4 s).
pub const ERASE_PS: u64 = 20_000_000_000;
const PROGRAM_PS: u64 = 16_000_000;

const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;
const CR_LOCK: u32 = 1 << 0;
const CR_PG: u32 = 1 << 1;
const CR_SER: u32 = 1 << 2;
const CR_START: u32 = 1 << 7;
const SR_BSY: u32 = 1 << 0;
const SR_WBNE: u32 = 1 << 1;
const SR_QW: u32 = 1 << 2;
const SR_EOP: u32 = 1 << 16;

pub struct Flash {
    pub acr: u32,
    cr2: u32,
    sr2_flags: u32,
    key_state: u8,
    locked_until_reset: bool,
    /// Bank 2's cells.
    pub bank2: Vec<u8>,
    /// The flash word being written: its address and the words so far.
    buffer: Option<(u32, [u32; 8], usize)>,
    busy_until: u64,
    eop: bool,
    pub erases: u64,
    pub programs: u64,
}

impl Flash {
    pub fn new(bank2: Vec<u8>) -> Self {
        Self {
            acr: 0x37, // reset: LATENCY 7, WRHIGHFREQ 3
            cr2: CR_LOCK | (0b11 << 4),
            sr2_flags: 0,
            key_state: 0,
            locked_until_reset: false,
            bank2,
            buffer: None,
            busy_until: 0,
            eop: false,
            erases: 0,
            programs: 0,
        }
    }

    fn busy(&self, t: u64) -> bool {
        t < self.busy_until
    }

    pub fn read(&self, reg: &str, t: u64) -> Option<u32> {
        Some(match reg {
            "acr" => self.acr,
            "bank2.cr" => self.cr2,
            "bank2.sr" => {
                let mut sr = self.sr2_flags;
                if self.busy(t) {
                    sr |= SR_BSY | SR_QW;
                } else if self.eop {
                    sr |= SR_EOP;
                }
                if self.buffer.is_some() {
                    sr |= SR_WBNE;
                }
                sr
            }
            _ => return None,
        })
    }

    pub fn write(&mut self, reg: &str, v: u32, t: u64) -> Result<(), Violation> {
        match reg {
            "acr" => self.acr = v & 0x3F,
            "bank2.keyr" => {
                if self.locked_until_reset {
                    return Err(Violation::rule(
                        "FLASH_KEYR2 written after a wrong key sequence (locked until reset)",
                    ));
                }
                match (self.key_state, v) {
                    (0, KEY1) => self.key_state = 1,
                    (1, KEY2) => {
                        self.key_state = 0;
                        self.cr2 &= !CR_LOCK;
                    }
                    _ => {
                        self.locked_until_reset = true;
                        return Err(Violation::rule(format!(
                            "FLASH_KEYR2: wrong key {v:#010x} (RM0433 §4.5.1: CR2 locked until the next reset)"
                        )));
                    }
                }
            }
            "bank2.cr" => {
                if self.cr2 & CR_LOCK != 0 {
                    // Ignored while locked: harmless when it changes nothing
                    // (a driver locking what is locked already).
                    if v | CR_LOCK != self.cr2 {
                        return Err(Violation::rule(format!(
                            "FLASH_CR2 = {v:#x} written while locked (RM0433 §4.5.1: ignored; unlock with KEYR2 first)"
                        )));
                    }
                    return Ok(());
                }
                if v & CR_LOCK != 0 {
                    self.cr2 = v & !CR_START;
                    return Ok(());
                }
                if v & CR_SER != 0 && v & CR_PG != 0 {
                    return Err(Violation::rule(
                        "FLASH_CR2: SER and PG set together (RM0433 §4.3.10)",
                    ));
                }
                if v & CR_START != 0 {
                    if v & CR_SER == 0 {
                        return Err(Violation::rule(
                            "FLASH_CR2: START without SER (no sector erase selected)",
                        ));
                    }
                    if self.busy(t) {
                        return Err(Violation::rule("FLASH_CR2: START while bank 2 is busy"));
                    }
                    if self.buffer.is_some() {
                        return Err(Violation::rule(
                            "FLASH_CR2: erase with a flash word half written (INCERR)",
                        ));
                    }
                    let snb = ((v >> 8) & 0b111) as usize;
                    self.bank2[snb * SECTOR..(snb + 1) * SECTOR].fill(0xFF);
                    self.busy_until = t + ERASE_PS;
                    self.eop = true;
                    self.erases += 1;
                }
                self.cr2 = v & !CR_START;
            }
            "bank2.ccr" => {
                self.sr2_flags &= !v;
                if v & SR_EOP != 0 {
                    self.eop = false;
                }
            }
            _ => return Err(Violation::Unmodelled),
        }
        Ok(())
    }

    /// A CPU read of bank 2's cells.
    pub fn read_cells(&self, addr: u32, size: usize, t: u64) -> Result<u32, Violation> {
        if self.busy(t) {
            return Err(Violation::rule(format!(
                "read of bank 2 at {addr:#010x} while it erases or programs (the bus stalls until it ends)"
            )));
        }
        let o = (addr - BANK2_BASE) as usize;
        let mut v = 0u32;
        for i in 0..size {
            v |= u32::from(self.bank2[o + i]) << (8 * i);
        }
        Ok(v)
    }

    /// A CPU write into bank 2: one 32-bit part of a 256-bit flash word.
    pub fn write_cells(&mut self, addr: u32, size: usize, v: u32, t: u64) -> Result<(), Violation> {
        if self.cr2 & CR_PG == 0 || self.cr2 & CR_LOCK != 0 {
            return Err(Violation::rule(format!(
                "write into bank 2 at {addr:#010x} without PG set in an unlocked CR2 (PGSERR)"
            )));
        }
        if size != 4 || addr % 4 != 0 {
            return Err(Violation::rule(format!(
                "bank 2 written with a {size}-byte access at {addr:#010x}"
            )));
        }
        if self.busy(t) {
            return Err(Violation::rule("write into bank 2 while it is busy"));
        }
        let word = addr & !31;
        let i = ((addr % 32) / 4) as usize;
        let (base, mut data, n) = self.buffer.take().unwrap_or((word, [0; 8], 0));
        if base != word || i != n {
            return Err(Violation::rule(format!(
                "bank 2: write at {addr:#010x} is not the next 32 bits of the flash word at {base:#010x} (INCERR)"
            )));
        }
        data[i] = v;
        if n + 1 < 8 {
            self.buffer = Some((base, data, n + 1));
            return Ok(());
        }
        let o = (base - BANK2_BASE) as usize;
        if self.bank2[o..o + 32].iter().any(|&b| b != 0xFF) {
            return Err(Violation::rule(format!(
                "bank 2: flash word at {base:#010x} programmed while not erased (RM0433 §4.3.8)"
            )));
        }
        for (k, w) in data.iter().enumerate() {
            self.bank2[o + 4 * k..o + 4 * k + 4].copy_from_slice(&w.to_le_bytes());
        }
        self.busy_until = t + PROGRAM_PS;
        self.eop = true;
        self.programs += 1;
        Ok(())
    }
}
