//! The hand-offs of `crate::handoff` to the loop tick under the board's
//! preemption, with the real writers and the tick's real readers: the loop
//! tick (the reader, highest priority) may run to completion between any
//! two stores of a writer (the X handler's `EventState::publish`, the index
//! handler's `Shared::index_event`), never the other way. The writers'
//! stores are the real ones, in their real order: every hand-off word is a
//! `crate::word::Word`, which in tests reports each store to a hook, and
//! the hook runs the tick's reads after the stores a schedule names. Each
//! test checks the recorded order (a slot's sequence word first, the
//! generation last, every word of the set in between), then every single
//! and every pair of reader positions among the recorded stores, then
//! random runs of several.

#![allow(clippy::unwrap_used, clippy::panic)]

extern crate std;

use crate::command::COLS;
use crate::firmware::config::{FirmwareConfig, SpindleMode, XMode};
use crate::firmware::looptick::{Estimator, LoopState};
use crate::firmware::xevent::EventState;
use crate::handoff::coeffs::{META, NULL_META, VALUES, X};
use crate::handoff::seqlock::LockWord;
use crate::handoff::Shared;
use crate::safety::Fault;
use crate::servo::ServoDesign;
use crate::spindle::{EdgeStamps, EncoderAngle, EncoderConfig};
use crate::units::{SpindleAngle, XInches};
use crate::word::recording::with_hook;
use core::cell::RefCell;
use core::sync::atomic::Ordering;
use proptest::prelude::*;
use std::boxed::Box;
use std::format;
use std::rc::Rc;
use std::vec::Vec;

/// One coefficient set as the X handler published it.
#[derive(Clone, Debug, PartialEq)]
struct Set {
    x: i32,
    null: bool,
    terms: usize,
    value: [i32; COLS],
}

/// The X handler on the default table (legacy X, no spindle).
fn x_handler() -> EventState {
    let gen = crate::firmware::config::load_table(crate::DEFAULT_TABLE).ok();
    let fc = FirmwareConfig {
        loop_cfg: ServoDesign::brief(20_000).config().unwrap(),
        spindle: SpindleMode::None,
        x: XMode::Legacy {
            clock_hz: 1_000_000,
        },
        coefficient_output: false,
        gauge_reversed: false,
    };
    EventState::new(gen, &fc, None)
}

/// Publication `g`'s words as the writer left them in its slot.
fn published_set(sh: &Shared, g: u32) -> Set {
    let lock = sh.coefficients().lock();
    let slot = lock.slot(g);
    let meta = slot[META].load(Ordering::Relaxed);
    let mut s = Set {
        x: slot[X].load(Ordering::Relaxed) as i32,
        null: meta & NULL_META != 0,
        terms: (meta & !NULL_META) as usize,
        value: [0; COLS],
    };
    for i in 0..COLS {
        s.value[i] = slot[VALUES + i].load(Ordering::Relaxed) as i32;
    }
    s
}

/// Where the tick runs its reads: after how many of the writer's stores
/// (0: before the first), once per entry.
type Schedule = [usize];

/// How many entries of `at` are `n`.
fn runs_at(at: &Schedule, n: usize) -> usize {
    at.iter().filter(|&&a| a == n).count()
}

fn loop_state() -> LoopState {
    let cfg = ServoDesign::brief(20_000).config().unwrap();
    let mut lp = LoopState::new(cfg);
    lp.x_published = true;
    lp
}

/// The tick's two reads of a set: its X and null flag on every tick
/// (`take_published`), its values when it evaluates the command itself
/// (the fallback's copy in `command_at`), both in one tick.
fn tick_reads(lp: &mut LoopState, sh: &Shared) {
    lp.take_published(sh);
    let _ = sh
        .coefficients()
        .take(&mut lp.fallback_seen, &mut lp.fallback);
}

/// What the reader holds must be exactly set `g` (0: none yet).
fn holds(lp: &LoopState, sets: &[Set], g: u32) -> Result<(), TestCaseError> {
    let c = &lp.fallback;
    let Some(s) = g.checked_sub(1).map(|k| &sets[k as usize]) else {
        prop_assert!(lp.coeff_null);
        prop_assert!(c.null);
        return Ok(());
    };
    prop_assert_eq!(
        lp.last_x().map(|x| x.to_bits()),
        Some(s.x),
        "X of generation {}",
        g
    );
    prop_assert_eq!(lp.coeff_null, s.null, "generation {}", g);
    prop_assert_eq!(c.x().to_bits(), s.x, "X of generation {}", g);
    prop_assert_eq!(c.null, s.null, "generation {}", g);
    if !s.null {
        prop_assert_eq!(usize::from(c.terms()), s.terms);
        prop_assert_eq!(
            &c.value[..s.terms],
            &s.value[..s.terms],
            "torn values, generation {}",
            g
        );
    }
    Ok(())
}

/// The X handler's publications `pubs` (X in inches, null) on a fresh
/// hand-off, the tick's reads run where `at` says; after each run the tick
/// holds exactly the latest completely published set of `sets` (the
/// writer's output, from an uninterrupted run). The writer's stores, as
/// the words of the coefficients' seqlock, in order.
fn coeffs_under(pubs: &[(f64, bool)], sets: &Rc<Vec<Set>>, at: &Schedule) -> Vec<Option<LockWord>> {
    let sh = Rc::new(Shared::new());
    let lp = Rc::new(RefCell::new(loop_state()));
    let check: Rc<dyn Fn(usize)> = {
        let (sh, lp, sets, at) = (sh.clone(), lp.clone(), sets.clone(), at.to_vec());
        Rc::new(move |n| {
            for _ in 0..runs_at(&at, n) {
                let mut lp = lp.borrow_mut();
                tick_reads(&mut lp, &sh);
                let published = sh.coefficient_generation();
                assert_eq!(
                    lp.coeff_seen, published,
                    "after store {n} (schedule {at:?})"
                );
                if let Err(e) = holds(&lp, &sets, published) {
                    panic!("after store {n} (schedule {at:?}): {e}");
                }
            }
        })
    };
    let mut ev = x_handler();
    let log = {
        let sh2 = sh.clone();
        recorded(
            move |addr| sh2.coefficients().lock().word_at(addr),
            &check,
            || {
                for &(x, null) in pubs {
                    ev.publish(&sh, XInches::from_f64(x), null).unwrap();
                }
            },
        )
    };
    let mut lp = lp.borrow_mut();
    tick_reads(&mut lp, &sh);
    assert_eq!(lp.coeff_seen, pubs.len() as u32);
    holds(&lp, sets, pubs.len() as u32).unwrap();
    log
}

/// Runs `write` with every store it makes recorded (as `word_at` names
/// it) and `check` called with the count of stores so far, before the
/// first (0) and after each.
fn recorded(
    word_at: impl Fn(usize) -> Option<LockWord> + 'static,
    check: &Rc<dyn Fn(usize)>,
    write: impl FnOnce(),
) -> Vec<Option<LockWord>> {
    let log = Rc::new(RefCell::new(Vec::new()));
    check(0);
    let hook = {
        let (log, check) = (log.clone(), check.clone());
        move |addr: usize, _: u32| {
            let n = {
                let mut log = log.borrow_mut();
                log.push(word_at(addr));
                log.len()
            };
            check(n);
        }
    };
    with_hook(Box::new(hook), write);
    log.take()
}

/// The sets the X handler publishes for `pubs`, uninterrupted.
fn sets_of(pubs: &[(f64, bool)]) -> Rc<Vec<Set>> {
    let sh = Shared::new();
    let mut ev = x_handler();
    let mut sets = Vec::new();
    for (g, &(x, null)) in pubs.iter().enumerate() {
        ev.publish(&sh, XInches::from_f64(x), null).unwrap();
        let s = published_set(&sh, g as u32 + 1);
        assert_eq!(s.null, null);
        sets.push(s);
    }
    Rc::new(sets)
}

/// The seqlock's rule on the recorded stores of generations 1, 2, ...:
/// each starts with its slot's sequence word and ends with the generation,
/// and between them stores only its own slot's words, every one the
/// reader takes (`words(g)`) at least once.
fn check_order(order: &[Option<LockWord>], gens: usize, words: impl Fn(u32) -> Vec<usize>) {
    let mut pubs = order.split_inclusive(|w| *w == Some(LockWord::Gen));
    for g in 1..=gens as u32 {
        let slot = (g & 1) as usize;
        let p = pubs
            .next()
            .unwrap_or_else(|| panic!("generation {g} never published: {order:?}"));
        assert_eq!(
            p.first(),
            Some(&Some(LockWord::Seq(slot))),
            "generation {g}: {p:?}"
        );
        assert_eq!(
            p.last(),
            Some(&Some(LockWord::Gen)),
            "generation {g}: {p:?}"
        );
        for w in &p[1..p.len() - 1] {
            assert!(
                matches!(w, Some(LockWord::Data(s, _)) if *s == slot),
                "generation {g}: {p:?}"
            );
        }
        for i in words(g) {
            assert!(
                p.contains(&Some(LockWord::Data(slot, i))),
                "generation {g} never stores word {i}: {p:?}"
            );
        }
    }
    assert!(
        pubs.next().is_none(),
        "stores after the last publication: {order:?}"
    );
}

/// The words of a set the tick reads: X, meta, and a live set's values.
fn set_words(s: &Set) -> Vec<usize> {
    let live = if s.null { 0 } else { s.terms };
    [X, META].into_iter().chain(VALUES..VALUES + live).collect()
}

/// Publications across the table, a null one among them, two in a row
/// at neighbouring X (the column cache's fast path) and one going back.
const PUBS: [(f64, bool); 5] = [
    (3.25, false),
    (4.0, true),
    (5.5, false),
    (5.531_25, false),
    (2.0, false),
];

#[test]
fn the_loop_tick_after_any_one_or_two_of_the_x_handlers_stores_takes_the_latest_whole_set() {
    let sets = sets_of(&PUBS);
    let order = coeffs_under(&PUBS, &sets, &[]);
    check_order(&order, PUBS.len(), |g| set_words(&sets[g as usize - 1]));
    let n = order.len();
    assert!(n > 4 * PUBS.len(), "{n} stores");
    for i in 0..=n {
        for j in i..=n {
            coeffs_under(&PUBS, &sets, &[i, j]);
        }
    }
}

/// The index handler's pulses `pairs` (count, edge) on a fresh hand-off,
/// the tick's reads run where `at` says; after each run the tick's
/// estimator is one given the latest published pulse directly, it has
/// taken the latest, and it latched exactly the faults the direct
/// estimator gives (a torn pair would change both), two pulses within one
/// of its runs as an extra index. The stores, as the index seqlock's
/// words, in order.
fn index_under(pairs: &[(u32, u32)], at: &Schedule) -> Vec<Option<LockWord>> {
    let cfg = EncoderConfig {
        counts_per_rev: 4096,
        ticks_per_s: 200_000_000,
        min_rpm: 30,
        max_rpm: 600,
        index_tolerance_counts: 2,
        index_angle: SpindleAngle(0),
        edge_stamps: EdgeStamps::Captured,
    };
    let sh = Rc::new(Shared::new());
    let mut lp0 = loop_state();
    lp0.spindle = Estimator::Encoder(EncoderAngle::new(cfg).unwrap());
    // The tick, and what it should hold: the direct estimator, its fault,
    // the pulses it has taken.
    let state = Rc::new(RefCell::new((
        lp0,
        EncoderAngle::new(cfg).unwrap(),
        None::<Fault>,
        0u32,
    )));
    let check: Rc<dyn Fn(usize)> = {
        let (sh, state, pairs, at) = (sh.clone(), state.clone(), pairs.to_vec(), at.to_vec());
        Rc::new(move |n| {
            for _ in 0..runs_at(&at, n) {
                let (lp, want, want_fault, seen) = &mut *state.borrow_mut();
                let trip = |f: &mut Option<Fault>, new: Fault| match *f {
                    Some(o) if o.reaction() >= new.reaction() => {}
                    _ => *f = Some(new),
                };
                lp.take_published(&sh);
                let published = sh.index_events();
                if published != *seen {
                    if published - *seen > 1 {
                        trip(want_fault, Fault::IndexExtra);
                    }
                    let (c, e) = pairs[published as usize - 1];
                    if let Err(f) = want.on_index(c, e) {
                        trip(want_fault, f);
                    }
                    *seen = published;
                }
                assert_eq!(
                    lp.index_seen, published,
                    "after store {n} (schedule {at:?})"
                );
                assert_eq!(
                    format!("{:?}", lp.spindle),
                    format!("{:?}", Estimator::Encoder(want.clone())),
                    "after store {n} (schedule {at:?})"
                );
                assert_eq!(lp.fault, *want_fault, "after store {n} (schedule {at:?})");
            }
        })
    };
    let log = {
        let sh2 = sh.clone();
        recorded(
            move |addr| sh2.index_lock().word_at(addr),
            &check,
            || {
                for &(count, edge) in pairs {
                    sh.index_event(edge, count);
                }
            },
        )
    };
    assert_eq!(state.borrow().3.max(sh.index_events()), pairs.len() as u32);
    log
}

#[test]
fn the_loop_tick_after_any_one_or_two_of_the_index_handlers_stores_takes_the_latest_whole_index() {
    let pairs = [
        (100, 5_000),
        (4196, 120_000_000),
        (8292, 240_000_000),
        (12_388, 360_000_000),
    ];
    let order = index_under(&pairs, &[]);
    check_order(&order, pairs.len(), |_| std::vec![0, 1]);
    let n = order.len();
    assert_eq!(n, 4 * pairs.len());
    for i in 0..=n {
        for j in i..=n {
            index_under(&pairs, &[i, j]);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Random publications (null ones among them) with the tick run at
    /// random points between the X handler's real stores, several times
    /// between two, or not at all during a publication.
    #[test]
    fn the_loop_tick_between_the_x_handlers_stores_takes_the_latest_whole_set(
        pubs in prop::collection::vec((0.0..7.0f64, prop::bool::weighted(0.2)), 1..6),
        at in prop::collection::vec(0usize..200, 0..10),
    ) {
        let sets = sets_of(&pubs);
        let n = coeffs_under(&pubs, &sets, &[]).len();
        let at: Vec<usize> = at.iter().map(|a| a % (n + 1)).collect();
        coeffs_under(&pubs, &sets, &at);
    }

    /// Random index pulses, the tick at random points between the index
    /// handler's real stores.
    #[test]
    fn the_loop_tick_between_the_index_handlers_stores_takes_the_latest_whole_index(
        pairs in prop::collection::vec((any::<u32>(), any::<u32>()), 1..8),
        at in prop::collection::vec(0usize..64, 0..10),
    ) {
        let n = 4 * pairs.len();
        let at: Vec<usize> = at.iter().map(|a| a % (n + 1)).collect();
        index_under(&pairs, &at);
    }
}
