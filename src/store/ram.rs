//! A NOR flash in RAM for the parameter store: the QEMU image's and
//! host-sim's parameter region, and the power-cut tests' flash.
//!
//! It is no kinder than the STM32H7's bank: a write may only program an
//! erased word (the H7's ECC refuses a second write to a 256-bit flash
//! word), and with a power budget it stops after that many operations,
//! the last one torn: half its page erased, or half its words written and
//! the word the cut fell in either left erased ([`Tear::Between`]) or
//! partly programmed ([`Tear::Inside`]). A partly programmed word no
//! longer matches its ECC bits: every read that touches it fails with
//! [`RamFlashError::Ecc`] (the H7: DBECCERR in FLASH_SR2 and a bus error on
//! the load, RM0433 §4.3.12), and it cannot be programmed again, until its
//! page is erased.

use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// Why the model refused an operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RamFlashError {
    NotAligned,
    OutOfBounds,
    /// A word written twice without an erase between.
    NotErased,
    /// The power budget ran out (this operation was cut, or came after).
    PowerCut,
    /// The read touched a word whose ECC does not match (a word torn by
    /// a cut inside it): an uncorrectable error, the word at this offset.
    Ecc(u32),
}

impl crate::store::ecc::EccError for RamFlashError {
    fn uncorrectable(&self) -> bool {
        matches!(self, RamFlashError::Ecc(_))
    }
}

/// What a cut leaves of the flash word it falls in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tear {
    /// The cut fell between words: the word was never started (erased).
    Between,
    /// The cut fell inside the word: partly programmed, unreadable (ECC).
    Inside,
}

/// How many words left unreadable by cuts the model holds at once (the
/// power-cut tests make at most two before an erase clears them); a cut
/// beyond that tears [`Tear::Between`].
pub const MAX_TORN: usize = 8;

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            RamFlashError::NotAligned => NorFlashErrorKind::NotAligned,
            RamFlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            _ => NorFlashErrorKind::Other,
        }
    }
}

/// The NUCLEO's parameter region (`memory.x` `ZSPB`) as a model: two
/// 128 KiB sectors of STM32H7 bank 2, programmed in 32-byte flash words
/// (the QEMU image's parameter flash, host-sim's, and the host's image of a
/// store that `zslide params flash` writes).
pub type Bank2Region = RamFlash<BANK2_REGION_BYTES, { 128 * 1024 }, 32>;
/// [`Bank2Region`]'s size, bytes.
pub const BANK2_REGION_BYTES: usize = 256 * 1024;

/// `N` bytes of flash in pages of `PAGE` bytes, programmed in words of
/// `WORD` bytes.
#[derive(Clone)]
pub struct RamFlash<const N: usize, const PAGE: usize, const WORD: usize> {
    pub bytes: [u8; N],
    /// Operations (writes and erases) left before the power fails; `None`:
    /// no cut.
    pub budget: Option<u32>,
    /// Writes and erases done (the cut one included), and of them erases.
    pub ops: u32,
    pub erases: u32,
    /// What a cut leaves of the word it falls in.
    pub tear: Tear,
    /// The offsets of the words a cut left unreadable, until erased.
    pub torn: [Option<u32>; MAX_TORN],
}

impl<const N: usize, const PAGE: usize, const WORD: usize> RamFlash<N, PAGE, WORD> {
    /// Erased flash.
    pub const fn new() -> Self {
        Self {
            bytes: [0xFF; N],
            budget: None,
            ops: 0,
            erases: 0,
            tear: Tear::Between,
            torn: [None; MAX_TORN],
        }
    }

    /// How many words are unreadable (torn inside, not erased since).
    pub fn torn_words(&self) -> usize {
        self.torn.iter().flatten().count()
    }

    /// The first unreadable word that `from..to` touches.
    fn torn_in(&self, from: usize, to: usize) -> Option<u32> {
        self.torn
            .iter()
            .flatten()
            .copied()
            .find(|&w| (w as usize) < to && w as usize + WORD > from)
    }

    /// Flash holding `image` from address 0 (what QEMU's loader put there).
    pub fn with_image(image: &[u8]) -> Self {
        let mut f = Self::new();
        let n = image.len().min(N);
        f.bytes[..n].copy_from_slice(&image[..n]);
        f
    }

    /// Counts one operation; `Ok(true)`: do it whole, `Ok(false)`: the
    /// power fails during it (tear it, then refuse).
    fn spend(&mut self) -> Result<bool, RamFlashError> {
        match self.budget {
            Some(0) => Err(RamFlashError::PowerCut),
            Some(n) => {
                self.ops += 1;
                self.budget = Some(n - 1);
                Ok(n > 1)
            }
            None => {
                self.ops += 1;
                Ok(true)
            }
        }
    }
}

impl<const N: usize, const PAGE: usize, const WORD: usize> Default for RamFlash<N, PAGE, WORD> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, const PAGE: usize, const WORD: usize> ErrorType for RamFlash<N, PAGE, WORD> {
    type Error = RamFlashError;
}

impl<const N: usize, const PAGE: usize, const WORD: usize> ReadNorFlash
    for RamFlash<N, PAGE, WORD>
{
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, out: &mut [u8]) -> Result<(), Self::Error> {
        let at = offset as usize;
        let src = self
            .bytes
            .get(at..at + out.len())
            .ok_or(RamFlashError::OutOfBounds)?;
        if let Some(w) = self.torn_in(at, at + out.len()) {
            return Err(RamFlashError::Ecc(w));
        }
        out.copy_from_slice(src);
        Ok(())
    }

    fn capacity(&self) -> usize {
        N
    }
}

impl<const N: usize, const PAGE: usize, const WORD: usize> NorFlash for RamFlash<N, PAGE, WORD> {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = PAGE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        let (from, to) = (from as usize, to as usize);
        if !from.is_multiple_of(PAGE) || !to.is_multiple_of(PAGE) {
            return Err(RamFlashError::NotAligned);
        }
        if from > to || to > N {
            return Err(RamFlashError::OutOfBounds);
        }
        for page in (from..to).step_by(PAGE) {
            let whole = self.spend()?;
            self.erases += 1;
            let end = if whole { page + PAGE } else { page + PAGE / 2 };
            self.bytes[page..end].fill(0xFF);
            for t in &mut self.torn {
                if t.is_some_and(|w| (page..end).contains(&(w as usize))) {
                    *t = None;
                }
            }
            if !whole {
                return Err(RamFlashError::PowerCut);
            }
        }
        Ok(())
    }

    async fn write(&mut self, offset: u32, data: &[u8]) -> Result<(), Self::Error> {
        let at = offset as usize;
        if !at.is_multiple_of(WORD) || !data.len().is_multiple_of(WORD) {
            return Err(RamFlashError::NotAligned);
        }
        let dst = self
            .bytes
            .get(at..at + data.len())
            .ok_or(RamFlashError::OutOfBounds)?;
        if dst.iter().any(|&b| b != 0xFF) || self.torn_in(at, at + data.len()).is_some() {
            return Err(RamFlashError::NotErased);
        }
        let whole = self.spend()?;
        let words = data.len() / WORD;
        let n = if whole { words } else { words / 2 } * WORD;
        self.bytes[at..at + n].copy_from_slice(&data[..n]);
        if whole {
            return Ok(());
        }
        if n < data.len() && self.tear == Tear::Inside {
            if let Some(slot) = self.torn.iter_mut().find(|t| t.is_none()) {
                // Programming only clears bits: half the word's bytes
                // reached the cells when the power failed.
                let half = WORD / 2;
                self.bytes[at + n..at + n + half].copy_from_slice(&data[n..n + half]);
                *slot = Some((at + n) as u32);
            }
        }
        Err(RamFlashError::PowerCut)
    }
}
