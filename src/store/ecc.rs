//! Flash words a power cut left unreadable, read as corrupt data instead
//! of an error.
//!
//! A cut inside the program of a flash word (STM32H7: 256 bits and their
//! ECC bits, programmed together) can leave the word partly programmed:
//! its ECC no longer matches, and every read of it is an uncorrectable
//! error (RM0433 §4.3.12: DBECCERR in FLASH_SR2, and a bus error on the
//! load; `board::flash` takes the bus error and reports
//! `FlashError::Ecc`). The word stays so until its sector is erased. If
//! the map saw that error it would refuse every load and every save, and
//! the board would boot on refused parameters at every boot from then on.
//!
//! [`SkipUnreadable`] sits between the map and the flash: a read that
//! meets such a word is redone word by word, and each unreadable word
//! reads as [`UNREADABLE`] bytes. For the map that is what the interrupted
//! write would have been, failed: a torn page marker reads as written
//! (zeros set the marker: the page state the write was making), a torn
//! item header fails its length CRC and a torn data word the item's CRC,
//! so the map skips the item and the next save goes after it. The word is
//! not written again (it is not erased); the map erases it with its page
//! when it comes round to it (`tests`: the boots after, and the save that
//! clears it).

use embedded_storage_async::nor_flash::{ErrorType, NorFlash, ReadNorFlash};

/// A flash error that may be an uncorrectable ECC error of a word.
pub trait EccError {
    /// The read touched a word whose ECC does not match its data.
    fn uncorrectable(&self) -> bool;
}

/// What an unreadable word reads as: every marker bit set, no CRC match.
pub const UNREADABLE: u8 = 0x00;

/// `F`, with unreadable words read as [`UNREADABLE`] (and counted).
pub struct SkipUnreadable<F> {
    pub flash: F,
    /// Reads of a word that was unreadable, since this was made.
    pub unreadable: u32,
}

impl<F: NorFlash> SkipUnreadable<F>
where
    F::Error: EccError,
{
    pub fn new(flash: F) -> Self {
        Self {
            flash,
            unreadable: 0,
        }
    }

    /// `out` from `offset` a flash word at a time, each unreadable word's
    /// part as [`UNREADABLE`].
    async fn read_by_word(&mut self, offset: u32, out: &mut [u8]) -> Result<(), F::Error> {
        let word = F::WRITE_SIZE as u32;
        let end = offset.saturating_add(out.len() as u32);
        let mut at = offset;
        while at < end {
            let next = (at / word).saturating_add(1).saturating_mul(word);
            let to = next.min(end);
            let part = &mut out[(at - offset) as usize..(to - offset) as usize];
            match self.flash.read(at, part).await {
                Ok(()) => {}
                Err(e) if e.uncorrectable() => {
                    part.fill(UNREADABLE);
                    self.unreadable = self.unreadable.saturating_add(1);
                }
                Err(e) => return Err(e),
            }
            at = to;
        }
        Ok(())
    }
}

impl<F: NorFlash> ErrorType for SkipUnreadable<F> {
    type Error = F::Error;
}

impl<F: NorFlash> ReadNorFlash for SkipUnreadable<F>
where
    F::Error: EccError,
{
    const READ_SIZE: usize = F::READ_SIZE;

    async fn read(&mut self, offset: u32, out: &mut [u8]) -> Result<(), Self::Error> {
        match self.flash.read(offset, out).await {
            Err(e) if e.uncorrectable() => self.read_by_word(offset, out).await,
            r => r,
        }
    }

    fn capacity(&self) -> usize {
        self.flash.capacity()
    }
}

impl<F: NorFlash> NorFlash for SkipUnreadable<F>
where
    F::Error: EccError,
{
    const WRITE_SIZE: usize = F::WRITE_SIZE;
    const ERASE_SIZE: usize = F::ERASE_SIZE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        self.flash.erase(from, to).await
    }

    async fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), Self::Error> {
        self.flash.write(offset, data).await
    }
}
