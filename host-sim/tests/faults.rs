//! The fault campaign (`host-sim faults`) on the legacy machine: every
//! fault injected into a cut at X = 5 in is detected with its own reason,
//! ends in the safe state its reaction defines, and never takes the tool
//! deeper into the part than the depth of cut (docs/SAFETY.md, "Fault
//! campaign", derives the bound).

use host_sim::faults::{campaign, run_case, spec, Case};
use zslide::safety::Reaction;

/// Chapter 5's depth of cut, in: the stock the finishing pass removes.
const DEPTH_OF_CUT_IN: f64 = 0.0003;

fn legacy() -> host_sim::cut::CutSpec {
    spec(host_sim::scenario::load("legacy-hw").unwrap()).unwrap()
}

#[test]
fn every_injected_fault_is_detected_with_its_reason_and_ends_safe_within_the_depth_of_cut() {
    let spec = legacy();
    let out = campaign(&spec, &Case::ALL, 0).unwrap();
    assert_eq!(out.len(), Case::ALL.len());
    for (case, o) in Case::ALL.iter().zip(&out) {
        let r = &o.row;
        assert_eq!(r.fault, case.name());
        if !case.applies() {
            assert_eq!(r.detected, None);
            assert!(r.reason.starts_with("not applicable"), "{r:?}");
            continue;
        }
        let f = o
            .latched
            .unwrap_or_else(|| panic!("{}: not detected", r.fault));
        assert!(case.expects(f), "{}: latched {f:?}", r.fault);
        assert_eq!(r.detected, Some(true));
        assert!(
            r.reason.starts_with(f.reason()),
            "{}: {}",
            r.fault,
            r.reason
        );
        assert_eq!(r.reason.contains("board model"), case.board_model());
        assert_eq!(
            r.reaction.as_deref(),
            Some(format!("{:?}", f.reaction()).as_str())
        );
        assert_eq!(r.safe_state, Some(true), "{r:?}");
        let t = r.time_to_safe_ms.expect("time to safe");
        // The last 100 ms of the run are in the safe state.
        let last = o.trace.last().unwrap();
        match f.reaction() {
            Reaction::DisableAmplifier => assert!(!last.amp_enabled, "{r:?}"),
            Reaction::RampToNull => {
                assert!(last.amp_enabled && last.command_in == 0.0, "{r:?}");
            }
        }
        assert!(t >= 0.0);
        let e = r.max_excursion_uin.unwrap();
        assert!(
            e < DEPTH_OF_CUT_IN * 1e6,
            "{}: {e} µin into the part, beyond the depth of cut",
            r.fault
        );
    }
}

#[test]
fn the_watchdog_resets_the_chip_ten_milliseconds_after_the_loop_stops() {
    let o = run_case(&legacy(), Case::StalledLoop, 0).unwrap();
    let t = o.row.time_to_safe_ms.unwrap();
    // IWDG1: 80 counts of 125 µs after the last feed (the last tick ran
    // within one loop period, 50 µs, before the stall; the count that sees
    // no feed is at most one count late).
    assert!((10.0..=10.0 + 0.125 + 0.05 + 0.125).contains(&t), "{t}");
}

#[test]
fn a_campaign_row_is_reproducible_from_its_seed_stream() {
    let spec = legacy();
    let cases = [Case::IndexExtra, Case::AdcBusError];
    let a = campaign(&spec, &cases, 3).unwrap();
    let b = campaign(&spec, &cases, 3).unwrap();
    let c = campaign(&spec, &cases, 4).unwrap();
    for k in 0..cases.len() {
        assert_eq!(a[k].row, b[k].row);
        assert_eq!(a[k].trace, b[k].trace);
        assert_ne!(a[k].trace, c[k].trace, "another seed stream, another noise");
    }
}
