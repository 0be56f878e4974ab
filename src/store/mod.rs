//! Servo parameters kept across power cycles, saved by the firmware itself
//! (a `save` over the link, only while the loop is disarmed).
//!
//! The store is a `sequential-storage` map over the board's parameter
//! region (at least two erase pages): one item, key [`KEY`], whose value is
//! the CRC'd parameter block of `params` (the format `params::encode_block`
//! writes and `params::load_region` checks, unchanged). Each save appends a
//! new item; the map erases a page only when it moves on to the next, so
//! pages wear evenly, and an item counts only once its header and CRC are
//! whole: a power cut anywhere in a save leaves the previous block readable
//! (`tests`: a cut at every flash operation of many saves). The block's
//! own CRC is checked again on load, so a value the map returns is one the
//! firmware would accept from a region.
//!
//! The flash is any `embedded_storage_async` `NorFlash` (boards: the
//! STM32H7's bank-2 sectors; QEMU and host-sim: a flash model) whose error
//! tells an uncorrectable ECC error apart ([`ecc`]): a flash word a cut
//! left unreadable is read as a corrupt item, so it costs that one save,
//! not every boot after it. The map's
//! API is async; every flash here completes at once, so [`block_on`] polls
//! each future to completion on the calling thread.
//!
//! Timing (`docs/BOARD.md` "Saving parameters"): a save is 3 flash writes
//! and, every 314th, a move to the other page with one page erase
//! (STM32H7: 128 KiB sector erase, of the order of 2 s, up to about 4 s).
//! That is far beyond the 5 ms watchdog and the 50 µs loop tick, so the
//! firmware saves only while disarmed, from the background, while the
//! loop tick runs on from the other bank, with the watchdog fed from the
//! flash driver's busy-wait (`board::flash`, its `feed` hook) and the
//! amplifier off.

use core::future::Future;
use core::ops::Range;
use core::pin::pin;
use core::task::{Context, Poll, Waker};

use embedded_storage_async::nor_flash::NorFlash;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage};

use crate::params;

pub mod boot;
pub mod ecc;
pub mod ram;

use ecc::{EccError, SkipUnreadable};

/// The map key of the parameter block.
pub const KEY: u8 = 1;

/// The largest parameter block: every parameter once.
pub const MAX_BLOCK: usize = params::HEADER_LEN + params::PARAMS.len() * params::ENTRY_LEN;

/// The map's work buffer: key, the largest block, rounded up to a flash
/// word of up to 32 bytes (the STM32H7's).
pub const BUFFER: usize = (1 + MAX_BLOCK).div_ceil(32) * 32;

/// Why a save or a load did not happen (sent over the link in a refusal).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum StoreError {
    /// The flash driver failed.
    Flash(FlashFault),
    /// The region is not a store the map recognises (needs an erase).
    Corrupted,
    /// The region is too small for the map (two pages) or the block.
    Config,
    /// The stored block fails the parameter block's own checks.
    Block(params::ParamError),
    /// Anything else the map reports.
    Map,
    /// A save asked while the loop is armed.
    Armed,
    /// The board has no flash driver for the store.
    NoDriver,
}

/// The flash driver's failure (`NorFlashErrorKind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum FlashFault {
    NotAligned,
    OutOfBounds,
    Other,
}

/// Where the station saves the parameter block: the board's store, or
/// [`NoStore`] on a board without a flash driver.
pub trait ParamStore {
    fn save(&mut self, block: &[u8], base: &crate::servo::ServoDesign) -> Result<(), StoreError>;
}

impl<F: NorFlash> ParamStore for Store<F>
where
    F::Error: EccError,
{
    // Never inlined: `cargo xtask no-panic` stops its check of the link's
    // service here (the map's code has panic paths; `THREAD_STOPS`).
    #[inline(never)]
    fn save(&mut self, block: &[u8], base: &crate::servo::ServoDesign) -> Result<(), StoreError> {
        Store::save(self, block, base)
    }
}

/// A board without a flash driver: every save is refused by name.
pub struct NoStore;

impl ParamStore for NoStore {
    fn save(&mut self, _: &[u8], _: &crate::servo::ServoDesign) -> Result<(), StoreError> {
        Err(StoreError::NoDriver)
    }
}

impl core::fmt::Display for StoreError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            StoreError::Flash(k) => write!(f, "the flash driver failed: {k:?}"),
            StoreError::Corrupted => {
                f.write_str("the parameter store is corrupt (erase the parameter region)")
            }
            StoreError::Config => {
                f.write_str("the parameter region is too small for the store (two erase pages)")
            }
            StoreError::Block(e) => write!(f, "the stored parameter block is refused: {e}"),
            StoreError::Map => f.write_str("the parameter store refused the operation"),
            StoreError::Armed => f.write_str(
                "save refused: the parameters are saved only while the loop is disarmed (a flash erase holds up the link and the arm button for seconds): disarm first",
            ),
            StoreError::NoDriver => f.write_str(
                "save refused: this board has no flash driver for the parameter store (write a block with `params flash`)",
            ),
        }
    }
}

fn map_error<E: embedded_storage_async::nor_flash::NorFlashError>(
    e: sequential_storage::Error<E>,
) -> StoreError {
    use embedded_storage_async::nor_flash::NorFlashErrorKind as K;
    match e {
        sequential_storage::Error::Storage { value, .. } => StoreError::Flash(match value.kind() {
            K::NotAligned => FlashFault::NotAligned,
            K::OutOfBounds => FlashFault::OutOfBounds,
            _ => FlashFault::Other,
        }),
        sequential_storage::Error::Corrupted { .. } => StoreError::Corrupted,
        sequential_storage::Error::ItemTooBig | sequential_storage::Error::BufferTooSmall(_) => {
            StoreError::Config
        }
        _ => StoreError::Map,
    }
}

/// Runs a future whose every step completes at once (a synchronous
/// flash behind an async trait) to its end.
pub fn block_on<F: Future>(f: F) -> F::Output {
    let mut f = pin!(f);
    let mut cx = Context::from_waker(Waker::noop());
    loop {
        if let Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return v;
        }
    }
}

/// The parameter store on `flash` over `range` (whole erase pages).
pub struct Store<F: NorFlash>
where
    F::Error: EccError,
{
    map: MapStorage<u8, SkipUnreadable<F>, Cache<Uncached, Uncached, Uncached, u8>>,
    buf: [u8; BUFFER],
}

impl<F: NorFlash> Store<F>
where
    F::Error: EccError,
{
    pub fn new(flash: F, range: Range<u32>) -> Result<Self, StoreError> {
        let cfg = MapConfig::try_new(range).map_err(|_| StoreError::Config)?;
        Ok(Self {
            map: MapStorage::new(SkipUnreadable::new(flash), cfg, Cache::new_uncached()),
            buf: [0; BUFFER],
        })
    }

    /// Saves `block` (a parameter block `params::encode_block` wrote; it
    /// is checked again here against `base`, so a refused block never
    /// reaches the flash).
    pub fn save(
        &mut self,
        block: &[u8],
        base: &crate::servo::ServoDesign,
    ) -> Result<(), StoreError> {
        params::load_region(block, base).map_err(StoreError::Block)?;
        block_on(self.map.store_item(&mut self.buf, &KEY, &block)).map_err(map_error)
    }

    /// The last saved block, whole and checked against `base`; `None` when
    /// nothing was ever saved.
    pub fn load(&mut self, base: &crate::servo::ServoDesign) -> Result<Option<&[u8]>, StoreError> {
        let got: Option<&[u8]> =
            block_on(self.map.fetch_item(&mut self.buf, &KEY)).map_err(map_error)?;
        match got {
            None => Ok(None),
            Some(b) => {
                params::load_region(b, base).map_err(StoreError::Block)?;
                Ok(Some(b))
            }
        }
    }

    /// The flash under the store (a simulated machine keeps its image
    /// across runs; a model's operation count).
    pub fn flash(&mut self) -> &mut F {
        &mut self.map.flash().flash
    }

    /// Reads that met a flash word left unreadable by a cut (read as a
    /// corrupt item), since this store was made.
    pub fn unreadable_reads(&mut self) -> u32 {
        self.map.flash().unreadable
    }

    /// The flash back (a test's model, to "reboot" on).
    pub fn into_flash(self) -> F {
        self.map.destroy().0.flash
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests;
