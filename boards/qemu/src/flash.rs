//! The image's parameter flash. mps2-an386 has no flash controller, so the
//! parameter store (`zslide::store`, the code the NUCLEO runs) works on a
//! NOR model with the NUCLEO's geometry: `zslide::store::ram::Bank2Region`
//! (two 128 KiB sectors, 32-byte words, a word programmed only when erased,
//! erased a sector at a time), placed in the `ZSFL` region of `memory.x`
//! (QEMU's PSRAM).
//!
//! Power cuts across boots (`cargo xtask flash-cut`): with the semihosting
//! argument `flash` the model's content lives in the host file
//! [`FILE`] in QEMU's working directory: read at boot (none: a new board,
//! erased flash) and written back after every flash operation, as a real
//! flash keeps each operation. With `cut=N` the power fails during flash
//! operation N: the model tears it (half its words written and the word the
//! cut fell in left erased, or half its sector erased), the file keeps
//! that, and the image stops at once, as a board whose supply died would;
//! the next boot finds what the cut left. (A word left unreadable by the
//! cut is the store's host tests' case, `zslide::store::tests`: the file
//! holds bytes, not the model's ECC state.)

use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m_semihosting::nr;
use embedded_storage_async::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use zslide::store::ram::{Bank2Region, RamFlashError, Tear, BANK2_REGION_BYTES, MAX_TORN};

/// The flash file in QEMU's working directory (NUL-terminated for
/// semihosting's `SYS_OPEN`).
pub const FILE: &[u8] = b"zspb-flash.bin\0";

extern "C" {
    static mut __zsfl_start: u8;
    static __zsfl_size: u8;
}

/// The parameter flash as the store sees it.
pub struct ImageFlash {
    model: &'static mut Bank2Region,
    /// Written back to [`FILE`] after every operation.
    persist: bool,
}

/// Set once the model is handed out: a second `&'static mut` to it would
/// alias.
static TAKEN: AtomicBool = AtomicBool::new(false);

/// `SYS_OPEN` modes (ARM semihosting: the index of the fopen mode string).
const OPEN_RB: usize = 1;
const OPEN_WB: usize = 5;

impl ImageFlash {
    /// The model, erased or (with `persist`) as [`FILE`] holds it; the power
    /// fails during operation `cut` (counted from here), if given. `None`
    /// when called twice, or when `FILE` exists but is not a whole region.
    pub fn boot(persist: bool, cut: Option<u32>) -> Option<Self> {
        if TAKEN.swap(true, Ordering::AcqRel) {
            return None;
        }
        let at = core::ptr::addr_of_mut!(__zsfl_start).cast::<Bank2Region>();
        let room = core::ptr::addr_of!(__zsfl_size) as usize;
        if room < core::mem::size_of::<Bank2Region>()
            || (at as usize) % core::mem::align_of::<Bank2Region>() != 0
        {
            return None;
        }
        // SAFETY: `memory.x` reserves ZSFL (PSRAM, mapped by QEMU for
        // mps2-an386) for this model alone: no section is linked there and
        // `TAKEN` makes this the only reference ever made; the region is
        // large enough and aligned (checked above). Every field is written
        // through raw pointers before the reference is formed, so it never
        // sees an invalid `Option` discriminant.
        let model = unsafe {
            core::ptr::addr_of_mut!((*at).bytes)
                .cast::<u8>()
                .write_bytes(0xFF, BANK2_REGION_BYTES);
            core::ptr::addr_of_mut!((*at).budget).write(cut);
            core::ptr::addr_of_mut!((*at).ops).write(0);
            core::ptr::addr_of_mut!((*at).erases).write(0);
            core::ptr::addr_of_mut!((*at).tear).write(Tear::Between);
            core::ptr::addr_of_mut!((*at).torn).write([None; MAX_TORN]);
            &mut *at
        };
        if persist && !load(&mut model.bytes) {
            return None;
        }
        Some(Self { model, persist })
    }

    /// Flash operations (writes and erases) since boot.
    pub fn ops(&self) -> u32 {
        self.model.ops
    }

    /// After each operation: the file follows the flash; a cut ends the
    /// run here.
    fn after(&mut self) {
        if self.persist && !save(&self.model.bytes) {
            defmt::error!("FAIL: the flash file could not be written");
            zslide_qemu::exit(false);
        }
        if self.model.budget == Some(0) {
            defmt::info!(
                "power cut during flash operation {=u32} (torn); the image stops",
                self.model.ops
            );
            zslide_qemu::exit(true);
        }
    }
}

/// A semihosting call on a three-word argument block.
fn call3(op: usize, args: [usize; 3]) -> isize {
    // SAFETY: the ARM semihosting calls used here (OPEN, READ, WRITE) take
    // a pointer to a block of three words; the block and every buffer its
    // words point to are borrowed by the caller for the whole call, which
    // reads (WRITE, OPEN's name) or writes (READ) at most the lengths given.
    unsafe { cortex_m_semihosting::syscall(op, &args) as isize }
}

fn close(handle: isize) {
    // SAFETY: CLOSE takes a one-word block holding a handle OPEN returned.
    unsafe {
        cortex_m_semihosting::syscall(nr::CLOSE, &[handle as usize]);
    }
}

/// Fills `bytes` from [`FILE`]: true when it is missing (erased flash
/// stays) or held exactly a region.
fn load(bytes: &mut [u8; BANK2_REGION_BYTES]) -> bool {
    let h = call3(nr::OPEN, [FILE.as_ptr() as usize, OPEN_RB, FILE.len() - 1]);
    if h < 0 {
        return true;
    }
    // READ returns the bytes *not* read.
    let left = call3(
        nr::READ,
        [h as usize, bytes.as_mut_ptr() as usize, bytes.len()],
    );
    close(h);
    if left != 0 {
        defmt::error!(
            "FAIL: the flash file is {=usize} bytes short of a region",
            left as usize
        );
    }
    left == 0
}

fn save(bytes: &[u8; BANK2_REGION_BYTES]) -> bool {
    let h = call3(nr::OPEN, [FILE.as_ptr() as usize, OPEN_WB, FILE.len() - 1]);
    if h < 0 {
        return false;
    }
    // WRITE returns the bytes *not* written.
    let left = call3(
        nr::WRITE,
        [h as usize, bytes.as_ptr() as usize, bytes.len()],
    );
    close(h);
    left == 0
}

impl ErrorType for ImageFlash {
    type Error = RamFlashError;
}

impl ReadNorFlash for ImageFlash {
    const READ_SIZE: usize = Bank2Region::READ_SIZE;

    async fn read(&mut self, offset: u32, out: &mut [u8]) -> Result<(), Self::Error> {
        self.model.read(offset, out).await
    }

    fn capacity(&self) -> usize {
        self.model.capacity()
    }
}

impl NorFlash for ImageFlash {
    const WRITE_SIZE: usize = Bank2Region::WRITE_SIZE;
    const ERASE_SIZE: usize = Bank2Region::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let r = self.model.erase(from, to).await;
        self.after();
        r
    }

    async fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), Self::Error> {
        let r = self.model.write(offset, data).await;
        self.after();
        r
    }
}
