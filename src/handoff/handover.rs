//! The hand-over of a handler's state at boot: the one way both images
//! (the NUCLEO's `src/main.rs` and `src/centre.rs`, the QEMU board's
//! `boards/qemu`) give each interrupt handler the parts it owns.
//!
//! The board builds the state in `main`, moves it into one `'static` place
//! of its own (`cortex_m::singleton!`: one `.bss` value, the only copy) and
//! gives the handler a reference to it through a [`Handover`], before the
//! handler's interrupt is unmasked. The handler claims it on its first run
//! and keeps it in its own `static mut` (which cortex-m-rt hands the
//! handler as a safe `&mut`); every later run only tests that it has it.
//!
//! Why a reference and not the value: a `static` `Option<T>` whose `None`
//! is niche-encoded as a nonzero pattern puts the whole state in `.data`
//! with a flash initialiser, once for the cell and once for the handler's
//! copy (the NUCLEO X handler's slope table alone is 8.7 KiB; the QEMU loop
//! handler's state with its 40 KiB plant model was kept twice). A reference
//! is a word in either place.
//!
//! The cell is a `critical_section::Mutex<Cell<..>>`, not a `RefCell`: a
//! `RefCell` borrow inside a handler links the "already borrowed" panic into
//! it (`cargo xtask no-panic`), while `Cell::take`/`set` move the reference
//! whole and cannot fail. The critical section runs twice per handler in the
//! whole run (at `give` and at the first `claim`), never on the hot path.

use core::cell::Cell;
use critical_section::Mutex;

/// A handler's state, handed from `main` to the handler once (module docs).
pub struct Handover<T: 'static> {
    cell: Mutex<Cell<Option<&'static mut T>>>,
}

impl<T: 'static> Handover<T> {
    /// Empty: a handler that runs before [`give`](Self::give) finds nothing
    /// and returns.
    pub const fn new() -> Self {
        Self {
            cell: Mutex::new(Cell::new(None)),
        }
    }

    /// Boot: gives the handler its state. `None` (a `singleton!` that
    /// already ran, which `main` never does) leaves the handler idle.
    pub fn give(&self, state: Option<&'static mut T>) {
        critical_section::with(|cs| self.cell.borrow(cs).set(state));
    }

    /// Handler: its state, claimed into `mine` (the handler's own
    /// `static mut`) on the first run after [`give`](Self::give); `None`
    /// before it.
    #[inline(always)]
    pub fn claim<'a>(&self, mine: &'a mut Option<&'static mut T>) -> Option<&'a mut T> {
        if mine.is_none() {
            *mine = critical_section::with(|cs| self.cell.borrow(cs).take());
        }
        mine.as_deref_mut()
    }
}

impl<T: 'static> Default for Handover<T> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::Handover;

    #[test]
    fn a_handler_gets_nothing_before_the_give_then_the_one_state_it_was_given() {
        let h: Handover<u32> = Handover::new();
        let mut mine = None;
        assert!(h.claim(&mut mine).is_none());
        let state: &'static mut u32 = std::boxed::Box::leak(std::boxed::Box::new(7));
        h.give(Some(state));
        let first = h.claim(&mut mine).map(|s| {
            *s += 1;
            *s
        });
        assert_eq!(first, Some(8));
        // The handler keeps it: a second claim is the same state, and the
        // cell is empty (no second owner can take it).
        assert_eq!(h.claim(&mut mine).copied(), Some(8));
        let mut other = None;
        assert!(h.claim(&mut other).is_none());
    }
}
