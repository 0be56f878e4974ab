//! The parameters a board with a store boots with, in this order: the
//! store's last saved block; else the raw block at the region's start
//! (`params flash`); else the built-in design. A store that cannot be
//! read gives the built-in design and `ParamSource::Refused`, the path a
//! refused raw block takes (the board latches `Fault::Parameters`): the
//! machine does not arm on parameters nobody chose. A board whose store
//! owns the whole region reads the raw block at the region's start
//! ([`at_boot_owned`]).

use embedded_storage_async::nor_flash::NorFlash;

use super::ecc::EccError;
use super::{block_on, Store, StoreError, MAX_BLOCK};
use crate::params::{self, ParamSource};
use crate::safety::{DesignError, ParamError};
use crate::servo::design::{ServoConfig, ServoDesign};

/// `store`'s block, else `region`'s, else `base` (`params::at_boot`'s
/// contract: `Err` only when `base` itself does not design).
pub fn at_boot<F: NorFlash>(
    store: &mut Store<F>,
    region: &[u8],
    base: &ServoDesign,
) -> Result<(ServoDesign, ServoConfig, ParamSource), DesignError>
where
    F::Error: EccError,
{
    let refused = |e: ParamError| Ok((*base, base.config()?, ParamSource::Refused(e)));
    match store.load(base) {
        Ok(Some(block)) => params::at_boot(block, base),
        Ok(None) => params::at_boot(region, base),
        Err(StoreError::Block(e)) => refused(e),
        Err(_) => refused(ParamError::StoreUnreadable),
    }
}

/// [`at_boot`] for a store that owns its whole region from offset 0 (the
/// NUCLEO's): the raw-block step reads the region's start, where a block
/// written before the store owned the region (an older `zslide params
/// flash`) may sit, so that it still boots rather than being dropped
/// unseen; anything else there is the store's own and reads as no block.
pub fn at_boot_owned<F: NorFlash>(
    store: &mut Store<F>,
    base: &ServoDesign,
) -> Result<(ServoDesign, ServoConfig, ParamSource), DesignError>
where
    F::Error: EccError,
{
    let mut head = [0xFF; MAX_BLOCK];
    // A failed read leaves it erased; the store's own read reports it.
    if block_on(store.flash().read(0, &mut head)).is_err() || !head.starts_with(&params::MAGIC) {
        head = [0xFF; MAX_BLOCK];
    }
    at_boot(store, &head, base)
}
