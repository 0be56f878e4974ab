//! The hand-offs of `crate::handoff` to the loop tick under the board's
//! preemption, step by step, with the tick's real readers: the loop tick
//! (the reader, highest priority) may run to completion between any two
//! stores of a writer (the X or index handler), never the other way. The
//! writer's steps are the seqlock's (`crate::handoff::seqlock`, whose own
//! tests cover a writer that overruns a reader) and follow
//! `xevent::EventState::publish` / `Shared::index_event` store for store (a
//! test checks that a publication by the real writer leaves the same
//! words); the reader is the real `LoopState::take_published`.

#![allow(clippy::unwrap_used)]

extern crate std;

use crate::command::COLS;
use crate::firmware::looptick::{Estimator, LoopState};
use crate::handoff::coeffs::{META, NULL_META, VALUES, X};
use crate::handoff::Shared;
use crate::safety::Fault;
use crate::servo::ServoDesign;
use crate::spindle::{EdgeStamps, EncoderAngle, EncoderConfig};
use crate::units::{SpindleAngle, XInches};
use core::sync::atomic::Ordering;
use proptest::prelude::*;
use std::format;
use std::vec::Vec;

/// One coefficient set as the X handler publishes it.
#[derive(Clone, Debug)]
struct Set {
    x: i32,
    null: bool,
    terms: usize,
    value: [i32; COLS],
}

#[derive(Clone, Copy, Debug)]
enum Step {
    Seq,
    X,
    Value(usize),
    Meta,
    Gen,
}

/// The stores of one publication, in the writer's order: the slot's
/// sequence word (then the release fence), X, the columns, the meta
/// word, and last the generation.
fn steps(s: &Set) -> Vec<Step> {
    let mut v = std::vec![Step::Seq, Step::X];
    if !s.null {
        for i in 0..s.terms {
            v.push(Step::Value(i));
        }
    }
    v.push(Step::Meta);
    v.push(Step::Gen);
    v
}

fn store(sh: &Shared, g: u32, s: &Set, step: Step) {
    let lock = sh.coefficients().lock();
    let slot = lock.slot(g);
    match step {
        Step::Seq => {
            lock.begin(g);
        }
        Step::X => slot[X].store(s.x as u32, Ordering::Relaxed),
        Step::Value(i) => slot[VALUES + i].store(s.value[i] as u32, Ordering::Relaxed),
        Step::Meta => slot[META].store(
            if s.null { NULL_META } else { s.terms as u32 },
            Ordering::Relaxed,
        ),
        Step::Gen => lock.publish(g),
    }
}

fn loop_state() -> LoopState {
    let cfg = ServoDesign::brief(20_000).config().unwrap();
    let mut lp = LoopState::new(cfg);
    lp.x_published = true;
    lp
}

fn set() -> impl Strategy<Value = Set> {
    (
        any::<i32>(),
        prop::bool::weighted(0.2),
        1..=COLS,
        prop::array::uniform8(any::<i32>()),
    )
        .prop_map(|(x, null, terms, v)| {
            let mut value = [0; COLS];
            for i in 0..COLS {
                value[i] = v[i % 8];
            }
            Set {
                x,
                null,
                terms,
                value,
            }
        })
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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Publications of random sets (null ones among them) with the loop
    /// tick run at random points between the writer's stores (several
    /// times between two stores, or not at all during a publication):
    /// after every run the tick holds exactly the latest completely
    /// published set, never a mix of two, never an older one it takes
    /// for new, and its generation never goes back.
    #[test]
    fn the_loop_tick_between_any_two_stores_takes_the_latest_whole_set(
        sets in prop::collection::vec(set(), 1..6),
        runs in prop::collection::vec(prop::collection::vec(0usize..64, 0..4), 6),
    ) {
        let sh = Shared::new();
        let mut lp = loop_state();
        let mut published = 0u32;
        for (k, s) in sets.iter().enumerate() {
            let g = k as u32 + 1;
            let st = steps(s);
            // Reader runs before step j (j = st.len(): after the last).
            let mut at: Vec<usize> = runs[k].iter().map(|&r| r % (st.len() + 1)).collect();
            at.sort_unstable();
            let mut next = at.iter().peekable();
            for (j, &step) in st.iter().enumerate() {
                while next.peek().is_some_and(|&&a| a == j) {
                    next.next();
                    tick_reads(&mut lp, &sh);
                    prop_assert_eq!(lp.coeff_seen, published, "before store {} of generation {}", j, g);
                    holds(&lp, &sets, published)?;
                }
                store(&sh, g, s, step);
                if matches!(step, Step::Gen) {
                    published = g;
                }
            }
            for _ in next {
                tick_reads(&mut lp, &sh);
                prop_assert_eq!(lp.coeff_seen, published);
                holds(&lp, &sets, published)?;
            }
        }
        tick_reads(&mut lp, &sh);
        prop_assert_eq!(lp.coeff_seen, sets.len() as u32);
        holds(&lp, &sets, published)?;
    }

    /// Index pulses published store by store, the loop tick at random
    /// points: the estimator sees each pair it takes whole (its state
    /// is that of an estimator given the latest published pair
    /// directly), the tick takes the latest, reports two pulses within
    /// one of its periods as an extra index, and latches exactly the
    /// faults the direct estimator gives (a torn pair would change
    /// both).
    #[test]
    fn the_loop_tick_between_any_two_stores_takes_the_latest_whole_index(
        pairs in prop::collection::vec((any::<u32>(), any::<u32>()), 1..8),
        runs in prop::collection::vec(0usize..5, 8),
    ) {
        let cfg = EncoderConfig {
            counts_per_rev: 4096,
            ticks_per_s: 200_000_000,
            min_rpm: 30,
            max_rpm: 600,
            index_tolerance_counts: 2,
            index_angle: SpindleAngle(0),
            edge_stamps: EdgeStamps::Captured,
        };
        let sh = Shared::new();
        let mut lp = loop_state();
        lp.spindle = Estimator::Encoder(EncoderAngle::new(cfg).unwrap());
        let mut want = EncoderAngle::new(cfg).unwrap();
        let mut want_fault: Option<Fault> = None;
        let trip = |f: &mut Option<Fault>, new: Fault| match *f {
            Some(o) if o.reaction() >= new.reaction() => {}
            _ => *f = Some(new),
        };
        let (mut published, mut seen) = (0u32, 0u32);
        for k in 0..=pairs.len() {
            // The four steps of `Shared::index_event` for pulse k + 1
            // (the sequence word with its fence, the two words, the
            // generation); the tick before step `runs[k]` (4: not
            // during it), and once more after the last pulse.
            for j in 0..4 {
                if runs[k.min(7)] == j || k == pairs.len() {
                    lp.take_published(&sh);
                    if published != seen {
                        if published - seen > 1 {
                            trip(&mut want_fault, Fault::IndexExtra);
                        }
                        let (c, e) = pairs[published as usize - 1];
                        if let Err(f) = want.on_index(c, e) {
                            trip(&mut want_fault, f);
                        }
                        seen = published;
                    }
                    prop_assert_eq!(lp.index_seen, published);
                    prop_assert_eq!(
                        format!("{:?}", lp.spindle),
                        format!("{:?}", Estimator::Encoder(want.clone()))
                    );
                    prop_assert_eq!(lp.fault, want_fault);
                }
                if k == pairs.len() {
                    break;
                }
                let s = k as u32 + 1;
                let (count, edge) = pairs[k];
                let lock = sh.index_lock();
                match j {
                    0 => {
                        lock.begin(s);
                    }
                    1 => lock.slot(s)[0].store(count, Ordering::Relaxed),
                    2 => lock.slot(s)[1].store(edge, Ordering::Relaxed),
                    _ => {
                        lock.publish(s);
                        published = s;
                    }
                }
            }
        }
        prop_assert_eq!(seen, pairs.len() as u32);
    }
}

/// The step writer stores what the real writers store: a publication
/// by `EventState::publish` (the X handler, default table, live and
/// null) and by `Shared::index_event` leaves the same words in the same
/// slots as the steps above.
#[test]
fn the_step_writer_leaves_the_words_the_real_writers_leave() {
    use crate::firmware::config::{FirmwareConfig, SpindleMode, XMode};
    use crate::firmware::xevent::EventState;
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
    let mut ev = EventState::new(gen, &fc, None);
    let real = Shared::new();
    let mirror = Shared::new();
    for (k, (x_in, null)) in [(3.25, false), (4.0, true), (5.5, false)]
        .into_iter()
        .enumerate()
    {
        let g = k as u32 + 1;
        let x = XInches::from_f64(x_in);
        ev.publish(&real, x, null).unwrap();
        let slot = real.coefficients().lock().slot(g);
        let meta = slot[META].load(Ordering::Relaxed);
        let mut s = Set {
            x: x.to_bits(),
            null: meta & NULL_META != 0,
            terms: (meta & !NULL_META) as usize,
            value: [0; COLS],
        };
        assert_eq!(s.null, null);
        for i in 0..COLS {
            s.value[i] = slot[VALUES + i].load(Ordering::Relaxed) as i32;
        }
        for step in steps(&s) {
            store(&mirror, g, &s, step);
        }
        assert_eq!(
            real.coefficient_generation(),
            mirror.coefficient_generation()
        );
        let (a, b) = (real.coefficients().lock(), mirror.coefficients().lock());
        for g in [g, g + 1] {
            assert_eq!(a.seq(g), b.seq(g));
            let live = if s.null { 0 } else { s.terms };
            for i in (0..VALUES).chain(VALUES..VALUES + live) {
                assert_eq!(
                    a.slot(g)[i].load(Ordering::Relaxed),
                    b.slot(g)[i].load(Ordering::Relaxed)
                );
            }
        }
    }
    // The index.
    let real = Shared::new();
    real.index_event(5678, 1234);
    let lock = real.index_lock();
    assert_eq!(
        [
            lock.slot(1)[0].load(Ordering::Relaxed),
            lock.slot(1)[1].load(Ordering::Relaxed),
            lock.seq(1)
        ],
        [1234, 5678, 1]
    );
    assert_eq!(real.index_events(), 1);
}
