//! The fault campaign (`host-sim faults`) on the legacy machine: every
//! fault injected into a cut at X = 5 in is detected with its own reason,
//! ends in the safe state its reaction defines, and never takes the tool
//! deeper into the part than the depth of cut (docs/SAFETY.md, "Fault
//! campaign", derives the bound).

use host_sim::faults::{campaign, run_case, run_case_at, spec, sweep, Case, Inject};
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
        assert_eq!(r.detected, Some(true), "{r:?}");
        assert_eq!(r.safe_state, Some(true), "{r:?}");
        let e = r.max_excursion_uin.unwrap();
        if !case.expects_fault() {
            // The malformed frames: refused, no fault, the cut unchanged.
            assert_eq!(o.latched, None, "{r:?}");
            assert_eq!(r.time_to_safe_ms, Some(0.0));
            assert_eq!(Some(e), r.excursion_undisturbed_uin, "{r:?}");
            assert!(e < DEPTH_OF_CUT_IN * 1e6);
            continue;
        }
        let f = o
            .latched
            .unwrap_or_else(|| panic!("{}: not detected", r.fault));
        assert!(case.expects(f), "{}: latched {f:?}", r.fault);
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
        assert!(
            e < DEPTH_OF_CUT_IN * 1e6,
            "{}: {e} µin into the part, beyond the depth of cut",
            r.fault
        );
    }
}

/// The following-error fault ramps the command to null; the learning had
/// taken in the push (0.3 of a 5000 µin error) before the fault latched,
/// so a loop that kept adding the learned correction would drive the tool
/// into the part one revolution later (415 µin, before the servo dropped
/// the correction on a latched fault; docs/SAFETY.md).
#[test]
fn a_following_error_fault_keeps_the_tool_within_the_depth_of_cut() {
    let o = run_case(&legacy(), Case::FollowingError, 0).unwrap();
    let e = o.row.max_excursion_uin.unwrap();
    assert!(e < DEPTH_OF_CUT_IN * 1e6, "{e} µin into the part");
}

/// The following-error row is the following-error check's: the push takes
/// the slide past 0.004 in short of the gauge's range and ends before the
/// current limit has been held for its 20 ms.
#[test]
fn a_push_beyond_the_loop_force_is_caught_by_the_following_error_check() {
    let o = run_case(&legacy(), Case::FollowingError, 0).unwrap();
    assert_eq!(o.latched, Some(zslide::safety::Fault::FollowingError));
    let t_inj = (o.row.injected_at_s.unwrap() * 1e9) as u64;
    // When the fault latched: the slide had been beyond the limit for the
    // monitor's 2 ms, and beyond the limit means 0.004 in off the loop's
    // reference, measured from the plant's true position.
    let first = o.trace.iter().find(|x| x.fault).unwrap();
    let latched_ms = (first.t_ns - t_inj) as f64 * 1e-6;
    assert!((5.0..20.0).contains(&latched_ms), "{latched_ms} ms");
    let over: Vec<_> = o
        .trace
        .iter()
        .filter(|x| x.t_ns <= first.t_ns && (x.reference_in - x.z_in).abs() > 0.004)
        .collect();
    let span_ms = (over.last().unwrap().t_ns - over[0].t_ns) as f64 * 1e-6;
    // 2 ms persistence, the gauge noise and the gauge's own filter aside.
    assert!(
        (1.5..=2.5).contains(&span_ms),
        "{span_ms} ms beyond 0.004 in"
    );
    // Never near the gauge's ±0.010 in.
    assert!(o.trace.iter().all(|x| x.z_in.abs() < 0.009));
}

#[test]
fn malformed_host_frames_are_refused_and_counted_and_leave_the_cut_unchanged() {
    use host_sim::faults::link;
    let o = run_case(&legacy(), Case::MalformedHostFrame, 0).unwrap();
    let l = o.row.link.as_ref().unwrap();
    let c = &l.counters;
    let sent = link::GARBAGE
        + link::TRUNCATED
        + link::CORRUPT
        + link::UNKNOWN_COMMAND
        + link::OTHER_VERSION
        + link::UNDECODABLE
        + link::OVERSIZE;
    assert_eq!(l.malformed_sent, sent);
    assert_eq!(l.valid_sent, 4);
    // Every frame accounted for, each in its own counter where the kind
    // decides it (garbage, truncation and a flipped bit can each land in
    // COBS, length or CRC).
    assert_eq!(c.ok + c.empty + l.refused, l.frames_sent);
    assert_eq!(l.refused, sent);
    assert_eq!(c.bad_version, link::OTHER_VERSION);
    assert_eq!(c.unknown_command, link::UNKNOWN_COMMAND);
    assert_eq!(c.oversize, link::OVERSIZE);
    assert_eq!(c.empty, link::EMPTY);
    assert_eq!(c.ok, 4);
    assert!(c.malformed >= link::UNDECODABLE);
    // One reply per non-empty frame, a refusal for each malformed one, the
    // valid requests answered by number, the status from mid-flood with
    // the loop engaged and no fault; the host's bytes all taken.
    assert_eq!(l.replies, sent + 4);
    assert_eq!(l.refusal_replies, sent);
    assert!(l.valid_answered);
    assert_eq!(l.status_phase.as_deref(), Some("Engaged"));
    assert_eq!(l.status_fault.as_deref(), Some("None"));
    assert_eq!(l.unread_bytes, 0);
    // The machine: no fault, and the tool's path the same, sample for
    // sample, as in the same cut without the flood.
    assert_eq!(o.latched, None);
    assert_eq!(o.row.max_excursion_uin, o.row.excursion_undisturbed_uin);
    assert!(o.trace.iter().all(|x| !x.fault && x.amp_enabled));
    assert!(
        o.row.reason.contains("sample for sample"),
        "{}",
        o.row.reason
    );
}

#[test]
fn the_watchdog_resets_the_chip_five_milliseconds_after_the_loop_stops() {
    let o = run_case(&legacy(), Case::StalledLoop, 0).unwrap();
    let t = o.row.time_to_safe_ms.unwrap();
    // IWDG1: 40 counts of 125 µs (LSI 32 kHz / 4, RLR = 39) after the last
    // feed (the last tick ran within one loop period, 50 µs, before the
    // stall; the count that sees no feed is at most one count late).
    assert!((5.0..=5.0 + 0.125 + 0.05 + 0.125).contains(&t), "{t}");
}

/// The stalled loop at 16 instants over one revolution (the part's 2/rev
/// command and the cutting force at every phase, each held by the frozen
/// DAC code for the watchdog's 5 ms), on two seed streams: each is caught
/// by the watchdog 5 ms after the last feed, ends with the amplifier
/// disabled and leaves the tool within the depth of cut. (The worst of 128
/// instants on 16 seed streams: docs/SAFETY.md.)
#[test]
fn a_loop_stalled_at_any_phase_of_the_revolution_is_reset_safe_within_the_depth_of_cut() {
    const PHASES: usize = 16;
    let spec = legacy();
    let rev_s = 60.0 / spec.rpm;
    for seed in [0, 2] {
        let out = sweep(&spec, Case::StalledLoop, PHASES, seed).unwrap();
        assert_eq!(out.len(), PHASES);
        let t0 = out[0].row.injected_at_s.unwrap();
        for (k, o) in out.iter().enumerate() {
            let r = &o.row;
            // Evenly over one revolution, to the nanosecond.
            let at = r.injected_at_s.unwrap() - t0;
            assert!(
                (at - k as f64 * rev_s / PHASES as f64).abs() < 1e-9,
                "{r:?}"
            );
            assert_eq!(o.latched, Some(zslide::safety::Fault::Watchdog), "{r:?}");
            assert_eq!(r.detected, Some(true), "{r:?}");
            assert_eq!(r.safe_state, Some(true), "{r:?}");
            assert!(!o.trace.last().unwrap().amp_enabled, "{r:?}");
            // 40 counts of 125 µs after the last feed; the last tick ran
            // within one loop period (50 µs) before the stall, the feed at
            // the first count after it, the reset seen at the next tick.
            let t = r.time_to_safe_ms.unwrap();
            assert!(
                (5.0 - 0.05..=5.0 + 0.125 + 0.05).contains(&t),
                "{t} ms: {r:?}"
            );
            let e = r.max_excursion_uin.unwrap();
            assert!(
                e < DEPTH_OF_CUT_IN * 1e6,
                "seed stream {seed}, stalled {k}/{PHASES} of a turn in: {e} µin into the part"
            );
        }
    }
}

/// An injection instant the case cannot have is refused, not ignored.
#[test]
fn an_injection_instant_outside_the_cut_is_refused() {
    let spec = legacy();
    let at = |after_turns| Inject { after_turns };
    for bad in [-0.5, f64::NAN, f64::INFINITY] {
        let e = run_case_at(&spec, Case::StalledLoop, 0, at(bad)).unwrap_err();
        assert!(e.to_string().contains("revolutions"), "{e}");
    }
    // Injected at boot or at arm: no instant in the cut to move.
    let e = run_case_at(&spec, Case::CorruptTable, 0, at(0.25)).unwrap_err();
    assert!(e.to_string().contains("at boot"), "{e}");
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
