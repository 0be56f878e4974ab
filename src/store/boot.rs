//! The parameters a board with a store boots with, in this order: the
//! store's last saved block; else the raw block at the region's start
//! (`params flash`); else the built-in design. A store that cannot be
//! read gives the built-in design and `ParamSource::Refused`, the path a
//! refused raw block takes (the board latches `Fault::Parameters`): the
//! machine does not arm on parameters nobody chose.

use embedded_storage_async::nor_flash::NorFlash;

use super::{Store, StoreError};
use crate::params::{self, ParamSource};
use crate::safety::{DesignError, ParamError};
use crate::servo::design::{ServoConfig, ServoDesign};

/// `store`'s block, else `region`'s, else `base` (`params::at_boot`'s
/// contract: `Err` only when `base` itself does not design).
pub fn at_boot<F: NorFlash>(
    store: &mut Store<F>,
    region: &[u8],
    base: &ServoDesign,
) -> Result<(ServoDesign, ServoConfig, ParamSource), DesignError> {
    let refused = |e: ParamError| Ok((*base, base.config()?, ParamSource::Refused(e)));
    match store.load(base) {
        Ok(Some(block)) => params::at_boot(block, base),
        Ok(None) => params::at_boot(region, base),
        Err(StoreError::Block(e)) => refused(e),
        Err(_) => refused(ParamError::StoreUnreadable),
    }
}
