//! The two-slot seqlock every hand-off of a value between priorities uses:
//! one writer at one priority, readers that may run between any two of
//! its stores (a higher priority preempting it) or, on a host, at the same
//! time.
//!
//! The writer of generation g (one more than the last) stores g into slot
//! g mod 2's own sequence word, a release fence, then the slot's words,
//! and publishes with one `Release` store of the generation. A reader loads
//! the generation (`Acquire`), reads the words of its slot, an acquire
//! fence, and keeps them only if the slot's sequence word is still g. On a
//! single core where the reader preempts the writer, the slot being written
//! is never the published one and the reader runs to completion, so the
//! check never fails there; it makes the scheme correct under real
//! concurrency too (a host test with two threads finds torn sets without
//! it). A lock would delay the reader by a whole write; this costs a few
//! instructions.

use crate::word::Word;
use core::sync::atomic::{fence, Ordering};

/// One slot: its sequence word and its data.
struct Slot<const N: usize> {
    /// Generation being written into / held by this slot; stored before
    /// the data, so a reader that finds it unchanged after reading has a
    /// whole set.
    seq: Word,
    words: [Word; N],
}

/// Two slots of `N` words and the published generation (0: none yet).
/// `const`-constructible, so a board can keep it in a `static`.
pub(crate) struct Seqlock<const N: usize> {
    gen: Word,
    slots: [Slot<N>; 2],
}

impl<const N: usize> Seqlock<N> {
    /// Nothing published; both slots hold `init`.
    pub(crate) const fn new(init: [u32; N]) -> Self {
        Self {
            gen: Word::new(0),
            slots: [Slot::new(init), Slot::new(init)],
        }
    }

    /// The generation published last (the writer's count; any priority).
    #[inline(always)]
    pub(crate) fn generation(&self) -> u32 {
        self.gen.load(Ordering::Relaxed)
    }

    /// The writer: starts generation `g` (the last published plus one) in
    /// its slot and returns that slot's words to store (`Relaxed`).
    #[inline(always)]
    pub(crate) fn begin(&self, g: u32) -> &[Word; N] {
        let slot = &self.slots[(g & 1) as usize];
        slot.seq.store(g, Ordering::Relaxed);
        fence(Ordering::Release);
        &slot.words
    }

    /// The writer: publishes generation `g` after its words are stored.
    #[inline(always)]
    pub(crate) fn publish(&self, g: u32) {
        self.gen.store(g, Ordering::Release);
    }

    /// The reader, first half: the newest generation (0: none yet).
    #[inline(always)]
    pub(crate) fn latest(&self) -> u32 {
        self.gen.load(Ordering::Acquire)
    }

    /// The reader, second half: `read` gets generation `g`'s words (`g` from
    /// [`Seqlock::latest`]); `Ok` with its result if the slot still held
    /// `g` afterwards, `Err` with it if the writer overwrote the slot
    /// meanwhile (the result may then mix two generations).
    #[inline(always)]
    pub(crate) fn read<R>(&self, g: u32, read: impl FnOnce(&[Word; N]) -> R) -> Result<R, R> {
        let slot = &self.slots[(g & 1) as usize];
        let r = read(&slot.words);
        fence(Ordering::Acquire);
        if slot.seq.load(Ordering::Relaxed) == g {
            Ok(r)
        } else {
            Err(r)
        }
    }
}

#[cfg(test)]
impl<const N: usize> Seqlock<N> {
    /// Generation `g`'s slot (a writer's single steps, in tests).
    pub(crate) fn slot(&self, g: u32) -> &[Word; N] {
        &self.slots[(g & 1) as usize].words
    }
    /// Which of this seqlock's words is at `addr` (a store reported by
    /// `crate::word::recording`), if any.
    pub(crate) fn word_at(&self, addr: usize) -> Option<LockWord> {
        let at = |w: &Word| core::ptr::from_ref(w) as usize == addr;
        if at(&self.gen) {
            return Some(LockWord::Gen);
        }
        for (s, slot) in self.slots.iter().enumerate() {
            if at(&slot.seq) {
                return Some(LockWord::Seq(s));
            }
            if let Some(i) = slot.words.iter().position(at) {
                return Some(LockWord::Data(s, i));
            }
        }
        None
    }
}

/// A word of a [`Seqlock`]: the generation, a slot's sequence word, word
/// `i` of a slot.
#[cfg(test)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LockWord {
    Gen,
    Seq(usize),
    Data(usize, usize),
}

impl<const N: usize> Slot<N> {
    const fn new(init: [u32; N]) -> Self {
        let mut words = [const { Word::new(0) }; N];
        let mut i = 0;
        while i < N {
            words[i] = Word::new(init[i]);
            i += 1;
        }
        Self {
            seq: Word::new(0),
            words,
        }
    }
}

/// The seqlock under the board's preemption, step by step: the reader (the
/// higher priority) runs to completion between any two stores of the
/// writer, or the writer runs between any two loads of the reader (two
/// cores, or a host's threads).
#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec;

    const N: usize = 5;

    /// The writer's steps for one generation: the slot's sequence word and
    /// the release fence ([`Seqlock::begin`]), each word, the generation
    /// ([`Seqlock::publish`]).
    #[derive(Clone, Copy, Debug)]
    enum Step {
        Begin,
        Word(usize),
        Publish,
    }

    fn steps(g: u32) -> impl Iterator<Item = (u32, Step)> {
        core::iter::once(Step::Begin)
            .chain((0..N).map(Step::Word))
            .chain(core::iter::once(Step::Publish))
            .map(move |s| (g, s))
    }

    fn store(l: &Seqlock<N>, sets: &[[u32; N]], (g, step): (u32, Step)) {
        match step {
            Step::Begin => {
                l.begin(g);
            }
            Step::Word(i) => {
                l.slots[(g & 1) as usize].words[i].store(sets[g as usize - 1][i], Ordering::Relaxed)
            }
            Step::Publish => l.publish(g),
        }
    }

    /// A reader that keeps the newest whole set it found.
    fn take(l: &Seqlock<N>, seen: &mut u32, held: &mut Option<[u32; N]>) {
        let g = l.latest();
        if g == *seen {
            return;
        }
        if let Ok(v) = l.read(g, |w| {
            core::array::from_fn(|k| w[k].load(Ordering::Relaxed))
        }) {
            *seen = g;
            *held = Some(v);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        /// Publications of random sets with the reader run at random
        /// points between the writer's stores (several times between two
        /// stores, or not at all during a publication): after every run
        /// the reader holds exactly the latest completely published set,
        /// never a mix of two, never an older one, and its generation
        /// never goes back.
        #[test]
        fn a_reader_between_any_two_stores_takes_the_latest_whole_set(
            sets in prop::collection::vec(prop::array::uniform5(any::<u32>()), 1..6),
            runs in prop::collection::vec(0usize..(N + 2) * 6, 0..12),
        ) {
            let l = Seqlock::<N>::new([0; N]);
            let all: Vec<(u32, Step)> = (1..=sets.len() as u32).flat_map(steps).collect();
            let (mut seen, mut held, mut published) = (0u32, None, 0u32);
            for (j, &s) in all.iter().enumerate() {
                for _ in runs.iter().filter(|&&r| r == j) {
                    take(&l, &mut seen, &mut held);
                    prop_assert_eq!(seen, published);
                    prop_assert_eq!(held, published.checked_sub(1).map(|k| sets[k as usize]));
                }
                store(&l, &sets, s);
                if let (g, Step::Publish) = s {
                    published = g;
                }
            }
            take(&l, &mut seen, &mut held);
            prop_assert_eq!(seen, sets.len() as u32);
            prop_assert_eq!(held, sets.last().copied());
        }

        /// The writer runs `w` of its steps after the reader has loaded
        /// `at` words of generation 1: the reader gets generation 1 whole,
        /// or `Err` exactly when the writer began generation 3 in the same
        /// slot meanwhile.
        #[test]
        fn a_reader_overrun_by_the_writer_gets_err_never_a_torn_set(
            sets in prop::collection::vec(prop::array::uniform5(any::<u32>()), 3..5),
            at in 0..=N,
            w in 0usize..(N + 2) * 3,
        ) {
            let l = Seqlock::<N>::new([0; N]);
            steps(1).for_each(|s| store(&l, &sets, s));
            let rest: Vec<(u32, Step)> = (2..=sets.len() as u32).flat_map(steps).take(w).collect();
            let g = l.latest();
            let r = l.read(g, |words| {
                let mut v = [0; N];
                for (k, x) in v.iter_mut().enumerate() {
                    if k == at {
                        rest.iter().for_each(|&s| store(&l, &sets, s));
                    }
                    *x = words[k].load(Ordering::Relaxed);
                }
                if at == N {
                    rest.iter().for_each(|&s| store(&l, &sets, s));
                }
                v
            });
            let overrun = rest.iter().any(|&(g, s)| g == 3 && matches!(s, Step::Begin));
            match r {
                Ok(v) => {
                    prop_assert!(!overrun);
                    prop_assert_eq!(v, sets[0]);
                }
                Err(_) => prop_assert!(overrun),
            }
        }
    }
}
