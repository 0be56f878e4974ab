//! The 32-bit word the hand-offs between interrupt priorities share
//! (`crate::handoff`'s seqlock slots, their sequence words and generation,
//! and the coefficient columns the X handler stores into them).
//!
//! On a board it is `AtomicU32`. In the crate's tests it is [`Word`], an
//! `AtomicU32` whose every store is reported to a per-thread hook after it
//! lands: a test sees the real writer's stores in their real order and can
//! run a reader between any two of them (`firmware::preemption_tests`),
//! instead of replaying an order of its own.

#[cfg(not(test))]
pub type Word = core::sync::atomic::AtomicU32;

#[cfg(test)]
pub use recording::Word;

#[cfg(test)]
pub mod recording {
    extern crate std;

    use core::sync::atomic::{AtomicU32, Ordering};
    use std::boxed::Box;
    use std::cell::RefCell;

    /// Called after each store of a [`Word`] on this thread: the word's
    /// address and the value stored.
    pub type Hook = Box<dyn FnMut(usize, u32)>;

    std::thread_local! {
        static HOOK: RefCell<Option<Hook>> = const { RefCell::new(None) };
    }

    /// An `AtomicU32` that reports its stores.
    #[derive(Debug, Default)]
    pub struct Word(AtomicU32);

    impl Word {
        pub const fn new(v: u32) -> Self {
            Self(AtomicU32::new(v))
        }

        pub fn load(&self, order: Ordering) -> u32 {
            self.0.load(order)
        }

        pub fn store(&self, v: u32, order: Ordering) {
            self.0.store(v, order);
            // Taken out while it runs: a store the hook itself makes (a
            // reader's own state) is not reported to it again.
            if let Some(mut hook) = HOOK.with(|h| h.borrow_mut().take()) {
                hook(core::ptr::from_ref(self) as usize, v);
                HOOK.with(|h| *h.borrow_mut() = Some(hook));
            }
        }
    }

    /// Runs `f` with `hook` called after each store of a [`Word`] on this
    /// thread; the hook is removed after.
    pub fn with_hook<R>(hook: Hook, f: impl FnOnce() -> R) -> R {
        HOOK.with(|h| *h.borrow_mut() = Some(hook));
        let r = f();
        HOOK.with(|h| *h.borrow_mut() = None);
        r
    }
}
