//! The parameter store's flash: the `ZSPB` sectors of STM32H743 bank 2
//! (`memory.x`: 0x081A_0000, sectors 5 and 6), erased and programmed
//! through the bank-2 registers of the embedded flash interface (RM0433
//! §4.3.8 programming, §4.3.10 sector erase, §4.9 registers): KEYR2, CR2,
//! SR2, CCR2.
//!
//! What it relies on (RM0433 §4.3.5 / §4.3.9, read-while-write between the
//! banks): while bank 2 erases or programs, code and data fetched from
//! bank 1 are served, so the loop tick and every handler keep running. A
//! read of bank 2 in that time stalls the bus until the operation ends, so
//! nothing the handlers read may live in bank 2: `memory.x` keeps the
//! image and the coefficient table in bank 1 and the store alone in bank
//! 2, and this driver reads the region only between operations. The
//! watchdog is fed inside every busy-wait through the caller's `feed`
//! (`zslide::watchdog::FeedGate`: only while the loop tick runs), so a
//! 2-4 s sector erase neither starves it nor hides a stalled tick.
//!
//! The D-cache is on (`board::bring_up`) and flash is cacheable: lines of
//! the region are invalidated after every erase and program, so the store
//! reads what the flash holds.
//!
//! A power cut during a flash-word program can leave the word partly
//! programmed, with an uncorrectable ECC error: reading it sets DBECCERR2
//! in SR2 (FLASH_ECC_FA2R: the word) and answers the load with a bus
//! error (RM0433 §4.3.12), which would be a HardFault, and the watchdog's
//! reset, at every boot. So every read runs one flash word at a time with
//! the bus fault ignored (FAULTMASK raised, SCB CCR.BFHFNMIGN set:
//! ARMv7-M ARM B3.2.8; a D-cache line is one 32-byte flash word, so an
//! error is never shared with a neighbour), and a word with DBECCERR2 set
//! afterwards is reported as [`FlashError::Ecc`], which the store reads
//! as a corrupt item (`zslide::store::ecc`) and its page's next erase
//! clears. FAULTMASK holds off the loop tick for the few bus cycles of one
//! word's reads. Not run on a board: built, and the sequences checked
//! against RM0433 and the ARMv7-M ARM only.

use core::sync::atomic::{compiler_fence, Ordering};

use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use stm32h7::stm32h743v::FLASH;
use zslide::store::ram::Bank2Region;

use super::timers;

/// Bank 2's first address and sector size (RM0433 table 7).
const BANK2_BASE: u32 = 0x0810_0000;
const SECTOR: u32 = 128 * 1024;
/// One flash word: 256 bits, programmed as eight 32-bit writes.
const WORD: usize = 32;

/// KEYR2's unlock sequence (RM0433 §4.5.1).
const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;

/// CR2 bits (RM0433 §4.9.4).
const CR_LOCK: u32 = 1 << 0;
const CR_PG: u32 = 1 << 1;
const CR_SER: u32 = 1 << 2;
/// PSIZE = 0b11: 64-bit parallelism, the fastest erase, for VDD 2.7-3.6 V
/// (the NUCLEO's 3.3 V).
const CR_PSIZE_X64: u32 = 0b11 << 4;
const CR_START: u32 = 1 << 7;
const CR_SNB_SHIFT: u32 = 8;
const CR_SNB_MASK: u32 = 0b111 << CR_SNB_SHIFT;
const CR_PSIZE_MASK: u32 = 0b11 << 4;

/// SR2 bits (RM0433 §4.9.5): busy, write buffer not empty, queue wait.
const SR_BSY: u32 = 1 << 0;
const SR_WBNE: u32 = 1 << 1;
const SR_QW: u32 = 1 << 2;
const SR_EOP: u32 = 1 << 16;
/// WRPERR, PGSERR, STRBERR, INCERR, OPERR, RDPERR, RDSERR, SNECCERR,
/// DBECCERR (bits 17-19, 21-26); CCR2 clears each at the same bit.
const SR_ERRORS: u32 = 0b111 << 17 | 0b11_1111 << 21;
/// SR2's uncorrectable (double) ECC error on a read (DBECCERR2).
const SR_DBECCERR: u32 = 1 << 26;

/// SCB CCR.BFHFNMIGN: at priority -1 (FAULTMASK) a precise data bus fault
/// is ignored, the load's value unknown (ARMv7-M ARM B3.2.8).
const CCR_BFHFNMIGN: u32 = 1 << 8;
/// CFSR's BusFault status (write 1 to clear): PRECISERR, IMPRECISERR,
/// BFARVALID.
const CFSR_BUS: u32 = 1 << 9 | 1 << 10 | 1 << 15;
/// SHCSR.BUSFAULTPENDED: an imprecise bus fault waiting for FAULTMASK.
const SHCSR_BUSFAULTPENDED: u32 = 1 << 14;

/// The longest a busy-wait may last: an erase takes 2-4 s (datasheet);
/// beyond this the flash interface is taken to be stuck.
const TIMEOUT_US: u32 = 10_000_000;

extern "C" {
    static __zspb_start: u8;
    static __zspb_size: u8;
}

/// Why a flash operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    NotAligned,
    OutOfBounds,
    /// KEYR2 did not unlock CR2 (a wrong key sequence locks it until reset).
    Locked,
    /// The operation ended with these SR2 error flags set (cleared since).
    Flags(u32),
    /// The bank stayed busy past [`TIMEOUT_US`].
    Timeout,
    /// A read met a flash word with an uncorrectable ECC error (DBECCERR2):
    /// the word's offset in the region.
    Ecc(u32),
    /// A read ended in a bus fault without an ECC error (SCB CFSR bits).
    Bus(u32),
}

impl zslide::store::ecc::EccError for FlashError {
    fn uncorrectable(&self) -> bool {
        matches!(self, FlashError::Ecc(_))
    }
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            _ => NorFlashErrorKind::Other,
        }
    }
}

impl defmt::Format for FlashError {
    fn format(&self, f: defmt::Formatter) {
        match self {
            FlashError::NotAligned => defmt::write!(f, "not aligned to a flash word or sector"),
            FlashError::OutOfBounds => defmt::write!(f, "outside the parameter region"),
            FlashError::Locked => defmt::write!(f, "bank 2 did not unlock (KEYR2)"),
            FlashError::Flags(sr) => defmt::write!(f, "bank 2 error flags SR2 = {=u32:#010x}", sr),
            FlashError::Timeout => defmt::write!(f, "bank 2 busy for over 10 s"),
            FlashError::Ecc(at) => {
                defmt::write!(
                    f,
                    "uncorrectable ECC error in the flash word at {=u32:#x}",
                    at
                )
            }
            FlashError::Bus(cfsr) => {
                defmt::write!(f, "bus fault on a read, CFSR = {=u32:#010x}", cfsr)
            }
        }
    }
}

/// The region's first address and length (the `memory.x` symbols).
fn region() -> (u32, u32) {
    (
        core::ptr::addr_of!(__zspb_start) as u32,
        // The *address* of the size symbol is the length (a linker
        // constant, never dereferenced).
        core::ptr::addr_of!(__zspb_size) as u32,
    )
}

/// The parameter region of bank 2 as a NOR flash; `feed` is called in
/// every busy-wait (the watchdog).
pub struct Bank2<W: FnMut()> {
    flash: FLASH,
    feed: W,
}

// The models the store is tested on have this geometry.
const _: () = assert!(WORD == <Bank2Region as NorFlash>::WRITE_SIZE);
const _: () = assert!(SECTOR as usize == <Bank2Region as NorFlash>::ERASE_SIZE);

impl<W: FnMut()> Bank2<W> {
    /// Takes the flash interface (after `clocks::init` set its wait
    /// states); CR2 is left locked.
    pub fn new(flash: FLASH, feed: W) -> Self {
        let mut b = Self { flash, feed };
        b.lock();
        b
    }

    fn cr(&self) -> u32 {
        self.flash.bank2().cr().read().bits()
    }

    fn set_cr(&self, v: u32) {
        // SAFETY: CR2 controls only bank 2's erase and program requests;
        // every value written here is one of the RM0433 §4.3.8 / §4.3.10
        // sequences (PG, or SER with SNB and START, PSIZE x64, or LOCK),
        // and bank 2 holds only the parameter region this driver owns.
        unsafe {
            self.flash.bank2().cr().write(|w| w.bits(v));
        }
    }

    fn sr(&self) -> u32 {
        self.flash.bank2().sr().read().bits()
    }

    fn lock(&mut self) {
        self.set_cr(self.cr() & !(CR_PG | CR_SER | CR_SNB_MASK) | CR_LOCK);
    }

    /// RM0433 §4.5.1: the two keys into KEYR2 clear CR2's LOCK.
    fn unlock(&mut self) -> Result<(), FlashError> {
        if self.cr() & CR_LOCK != 0 {
            // SAFETY: KEYR2 only takes the unlock keys; writing them is
            // the documented way to clear LOCK (a wrong value would lock
            // CR2 until reset, which these constants are not).
            unsafe {
                self.flash.bank2().keyr().write(|w| w.bits(KEY1));
                self.flash.bank2().keyr().write(|w| w.bits(KEY2));
            }
        }
        if self.cr() & CR_LOCK != 0 {
            return Err(FlashError::Locked);
        }
        Ok(())
    }

    /// Waits until bank 2 has no operation queued or running, feeding the
    /// watchdog.
    fn idle(&mut self) -> Result<(), FlashError> {
        let start = timers::micros();
        while self.sr() & (SR_QW | SR_BSY | SR_WBNE) != 0 {
            (self.feed)();
            if timers::micros().wrapping_sub(start) > TIMEOUT_US {
                return Err(FlashError::Timeout);
            }
        }
        Ok(())
    }

    /// SR2's error flags, cleared (with EOP).
    fn take_errors(&mut self) -> u32 {
        let errors = self.sr() & SR_ERRORS;
        // SAFETY: CCR2's bits only clear the SR2 flags at the same
        // positions (EOP and the error flags).
        unsafe {
            self.flash.bank2().ccr().write(|w| w.bits(errors | SR_EOP));
        }
        errors
    }

    /// Waits for the operation just started; its error flags as an error.
    fn wait(&mut self) -> Result<(), FlashError> {
        self.idle()?;
        match self.take_errors() {
            0 => Ok(()),
            e => Err(FlashError::Flags(e)),
        }
    }

    /// One operation between unlock and lock, whatever its outcome.
    fn unlocked(
        &mut self,
        op: impl FnOnce(&mut Self) -> Result<(), FlashError>,
    ) -> Result<(), FlashError> {
        self.unlock()?;
        // Flags left from before (a failed operation, a read's ECC
        // report) are not this operation's.
        let r = self.idle().and_then(|()| {
            self.take_errors();
            op(self)
        });
        self.lock();
        r
    }

    fn erase_sector(&mut self, sector: u32) -> Result<(), FlashError> {
        self.unlocked(|b| {
            let cr = b.cr() & !(CR_PSIZE_MASK | CR_SNB_MASK | CR_PG);
            b.set_cr(cr | CR_SER | CR_PSIZE_X64 | (sector << CR_SNB_SHIFT));
            b.set_cr(cr | CR_SER | CR_PSIZE_X64 | (sector << CR_SNB_SHIFT) | CR_START);
            b.wait()
        })
    }

    /// Programs one flash word at `addr` (32-byte aligned, erased).
    fn program_word(&mut self, addr: u32, data: &[u8]) -> Result<(), FlashError> {
        self.unlocked(|b| {
            b.set_cr(b.cr() & !(CR_SER | CR_SNB_MASK) | CR_PG);
            // PG must be set before the first write reaches the bank.
            cortex_m::asm::dsb();
            for (i, w) in data.chunks_exact(4).enumerate() {
                let v = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
                // SAFETY: `addr` is a 32-byte-aligned flash word inside
                // the parameter region (checked by the caller), which no
                // Rust reference covers; with PG set the bank takes these
                // eight consecutive word writes as one 256-bit program.
                unsafe { core::ptr::write_volatile((addr as *mut u32).add(i), v) };
            }
            // The eighth write closes the word; wait only once it is out.
            cortex_m::asm::dsb();
            let r = b.wait();
            b.set_cr(b.cr() & !CR_PG);
            r
        })
    }
}

impl<W: FnMut()> Bank2<W> {
    /// Reads `out` from `addr`, all inside one flash word, with a bus
    /// fault ignored; the word's ECC error (SR2 DBECCERR2) as an error.
    fn read_word(&mut self, addr: u32, out: &mut [u8]) -> Result<(), FlashError> {
        // SAFETY: SCB's CCR, CFSR and SHCSR are read and written only
        // here and at boot; CCR is put back as it was before FAULTMASK is
        // released, and only the bus-fault status this read caused is
        // cleared.
        let cp = unsafe { cortex_m::Peripherals::steal() };
        let ccr = cp.SCB.ccr.read();
        // SAFETY: FAULTMASK raises the priority to -1 for the reads below
        // (no handler preempts them) and is released at once after.
        unsafe { core::arch::asm!("cpsid f", options(nomem, nostack, preserves_flags)) };
        // SAFETY: BFHFNMIGN only changes how a data bus fault is taken at
        // priority -1, which this code alone runs at.
        unsafe { cp.SCB.ccr.write(ccr | CCR_BFHFNMIGN) };
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
        for (i, b) in out.iter_mut().enumerate() {
            // SAFETY: inside the region (`span`, the caller), readable
            // flash whether erased or programmed (a torn word's bus error
            // is ignored above), never covered by a Rust reference (the
            // bank changes under it); no operation runs on the bank while
            // this reads (each ends before its call returns).
            *b = unsafe { core::ptr::read_volatile((addr as *const u8).add(i)) };
        }
        cortex_m::asm::dsb();
        let bus = cp.SCB.cfsr.read() & CFSR_BUS;
        // SAFETY: write-1-to-clear of the bus-fault status just read, and
        // of a bus fault pended by these reads (taken otherwise the moment
        // FAULTMASK drops); CCR as it was.
        unsafe {
            cp.SCB.cfsr.write(bus);
            cp.SCB.shcsr.modify(|v| v & !SHCSR_BUSFAULTPENDED);
            cp.SCB.ccr.write(ccr);
        }
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
        // SAFETY: as above: the priority back to what it was.
        unsafe { core::arch::asm!("cpsie f", options(nomem, nostack, preserves_flags)) };
        if self.sr() & SR_DBECCERR != 0 {
            // SAFETY: CCR2's DBECCERR bit only clears the flag (and with
            // it FLASH_ECC_FA2R).
            unsafe {
                self.flash.bank2().ccr().write(|w| w.bits(SR_DBECCERR));
            }
            let (base, _) = region();
            return Err(FlashError::Ecc(
                addr.wrapping_sub(base) & !(WORD as u32 - 1),
            ));
        }
        if bus != 0 {
            return Err(FlashError::Bus(bus));
        }
        Ok(())
    }
}

/// The region's lines dropped from the D-cache, so the next read sees the
/// flash (RM0433 §4.3.8: the cache is not kept coherent by the bank).
fn invalidate(addr: u32, len: usize) {
    compiler_fence(Ordering::SeqCst);
    // SAFETY: SCB's cache maintenance registers are write-only commands;
    // invalidating lines of flash (write-through, so never dirty) loses no
    // data, and no other code uses SCB's cache operations after boot.
    let mut cp = unsafe { cortex_m::Peripherals::steal() };
    // SAFETY: as above: the range is the flash just erased or programmed.
    unsafe { cp.SCB.invalidate_dcache_by_address(addr as usize, len) };
}

/// `offset..offset + len` inside the region, as addresses.
fn span(offset: u32, len: usize) -> Result<u32, FlashError> {
    let (base, size) = region();
    let end = offset
        .checked_add(len as u32)
        .ok_or(FlashError::OutOfBounds)?;
    if end > size {
        return Err(FlashError::OutOfBounds);
    }
    Ok(base + offset)
}

impl<W: FnMut()> ErrorType for Bank2<W> {
    type Error = FlashError;
}

impl<W: FnMut()> ReadNorFlash for Bank2<W> {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, out: &mut [u8]) -> Result<(), Self::Error> {
        let addr = span(offset, out.len())?;
        let mut rest = out;
        let mut at = addr;
        // One flash word at a time: the first from `addr` to its end.
        while !rest.is_empty() {
            let n = (WORD - at as usize % WORD).min(rest.len());
            let (word, tail) = rest.split_at_mut(n);
            self.read_word(at, word)?;
            at += n as u32;
            rest = tail;
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        region().1 as usize
    }
}

impl<W: FnMut()> NorFlash for Bank2<W> {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = SECTOR as usize;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        if !from.is_multiple_of(SECTOR) || !to.is_multiple_of(SECTOR) || from > to {
            return Err(FlashError::NotAligned);
        }
        let start = span(from, (to - from) as usize)?;
        if !start.is_multiple_of(SECTOR) || start < BANK2_BASE {
            return Err(FlashError::NotAligned);
        }
        for addr in (start..start + (to - from)).step_by(SECTOR as usize) {
            self.erase_sector((addr - BANK2_BASE) / SECTOR)?;
            invalidate(addr, SECTOR as usize);
        }
        Ok(())
    }

    async fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), Self::Error> {
        if !(offset as usize).is_multiple_of(WORD) || !data.len().is_multiple_of(WORD) {
            return Err(FlashError::NotAligned);
        }
        let start = span(offset, data.len())?;
        for (i, word) in data.chunks_exact(WORD).enumerate() {
            let addr = start + (i * WORD) as u32;
            let r = self.program_word(addr, word);
            invalidate(addr, WORD);
            r?;
        }
        Ok(())
    }
}
