//! The coefficient sets' hand-off (X handler → loop tick, and the handler
//! below it): one [`Seqlock`] of X, a meta word and the column values at
//! X, all the loop tick evaluates (Z and its φ-derivatives; the changes
//! across the grid interval, for ∂Z/∂X, are not needed there and are not
//! carried).

use super::seqlock::Seqlock;
use crate::command::{Coefficients, COLS};
use crate::units::XInches;
use crate::word::Word;
use core::sync::atomic::Ordering;

/// The meta word of a null set (no live columns: the null command).
pub(crate) const NULL_META: u32 = 1 << 31;
/// Word layout of a set: X (`XInches` bits), meta (live columns or
/// [`NULL_META`]), then the column values (Q30).
pub(crate) const X: usize = 0;
pub(crate) const META: usize = 1;
pub(crate) const VALUES: usize = 2;
const WORDS: usize = VALUES + COLS;

/// The published coefficient sets (see the module docs).
pub(crate) struct CoeffHandoff(Seqlock<WORDS>);

impl CoeffHandoff {
    pub(crate) const fn new() -> Self {
        let mut init = [0; WORDS];
        init[META] = NULL_META;
        Self(Seqlock::new(init))
    }

    /// The seqlock itself (a writer's single steps, in tests).
    #[cfg(test)]
    pub(crate) fn lock(&self) -> &Seqlock<WORDS> {
        &self.0
    }

    /// Sets published so far.
    pub(crate) fn generation(&self) -> u32 {
        self.0.generation()
    }

    /// The writer (the X handler): generation `g` (the last plus one) at
    /// `x`; `fill` stores the column values and returns the meta word. An
    /// `Err` of `fill` leaves `g` unpublished (the next publication
    /// writes the same slot again).
    #[inline(always)]
    pub(crate) fn publish<E>(
        &self,
        g: u32,
        x: XInches,
        fill: impl FnOnce(&[Word]) -> Result<u32, E>,
    ) -> Result<(), E> {
        let w = self.0.begin(g);
        w[X].store(x.to_bits() as u32, Ordering::Relaxed);
        let meta = fill(&w[VALUES..])?;
        w[META].store(meta, Ordering::Relaxed);
        self.0.publish(g);
        Ok(())
    }

    /// The reader, once for both takers: when the newest set's generation
    /// is not `seen`, `read` gets its values, meta word and X. A set
    /// overwritten while read (a writer that preempts the reader) returns
    /// `Err` with its X and leaves `seen`, so the next call takes the next
    /// one.
    #[inline(always)]
    fn read<R>(
        &self,
        seen: &mut u32,
        read: impl FnOnce(&[Word], u32, XInches) -> R,
    ) -> Result<Option<R>, XInches> {
        let g = self.0.latest();
        if g == *seen {
            return Ok(None);
        }
        let r = self.0.read(g, |w| {
            let meta = w[META].load(Ordering::Relaxed);
            let x = XInches::from_bits(w[X].load(Ordering::Relaxed) as i32);
            (read(&w[VALUES..], meta, x), x)
        });
        match r {
            Ok((r, _)) => {
                *seen = g;
                Ok(Some(r))
            }
            Err((_, x)) => Err(x),
        }
    }

    /// Copies the latest set into `c` when its generation is not `seen`.
    /// Returns the set's X when one was taken; a set overwritten while
    /// copied leaves `c` null and `seen` unchanged, and returns `Err` with
    /// its X.
    #[inline(always)]
    pub(crate) fn take(
        &self,
        seen: &mut u32,
        c: &mut Coefficients,
    ) -> Result<Option<XInches>, XInches> {
        let taken = self.read(seen, |values, meta, x| {
            if meta & NULL_META != 0 {
                c.set_null(x);
            } else {
                let n = (meta as usize).min(COLS);
                for (v, sv) in c.value.iter_mut().zip(values.iter()).take(n) {
                    *v = sv.load(Ordering::Relaxed) as i32;
                }
                c.set_live(n as u8, x);
            }
            x
        });
        if let Err(x) = taken {
            c.set_null(x);
        }
        taken
    }

    /// Takes the X and the null flag of the newest set, not its values, if
    /// its generation is not `seen`: what the loop tick needs on every set,
    /// where the values serve only its fallback evaluation. A set
    /// overwritten while read returns `Err` with its X and leaves `seen`.
    #[inline(always)]
    pub(crate) fn take_x(&self, seen: &mut u32) -> Result<Option<(XInches, bool)>, XInches> {
        self.read(seen, |_, meta, x| (x, meta & NULL_META != 0))
    }
}
