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

/// The cut's process spring at chapter 5's depth, lbf/in: dF/dd of the
/// edge force k_e·√(2·r_t·d) at d = 0.0003 in (≈ 2200, docs/CUT.md).
const PART_STIFFNESS_LBF_PER_IN: f64 = 2200.0;

/// The tool's departure into the part a released slide can still make
/// beyond its depth at the release, in (docs/SAFETY.md, "Fault campaign").
///
/// Released (the plant's amplifier off: its output opens, the coil current
/// is zero from the edge, `plant::amplifier`), the carriage obeys
/// m·z̈ = F_c − B·ż with F_c the cutting force (+Z, out of the part). The
/// tool's depth below the exact surface n(t) is d = n − z, so
/// m·d̈ = m·n̈ + B·ṅ − B·ḋ − F_c: the part's surface keeps moving under the
/// tool (its velocity ṅ, dragged against the air film, and acceleration n̈
/// act as a force toward the part), the −B·ḋ term only takes energy out
/// while the tool goes deeper, and F_c grows with the depth at the
/// process spring k. From the release with the tool going deeper at
/// w = ṅ − ż, against the net outward force F = F_c − B·ṅ − m·n̈ and the
/// spring, the energy balance ½·m·w² = F·Δ + ½·k·Δ² gives the carry
/// Δ = (√(F² + k·m·w²) − F)/k (w·√(m/k) at F = 0; ½·m·w²/F when the cut's
/// preload dominates; a net force toward the part sinks the tool to
/// 2|F|/k and more).
fn release_carry_in(spec: &host_sim::cut::CutSpec, w_in_s: f64, net_out_lbf: f64) -> f64 {
    let m = spec.scenario.rig.slide.mass_lbf_s2_per_in;
    let (k, f, w) = (PART_STIFFNESS_LBF_PER_IN, net_out_lbf, w_in_s.max(0.0));
    ((f * f + k * m * w * w).sqrt() - f) / k
}

/// At the release (the first sample with the amplifier off, index `k`):
/// the tool's velocity into the part w and the net outward force F of
/// [`release_carry_in`], read from the trace on the side that makes the
/// carry larger. The release falls between samples k−1 and k: the slide's
/// velocity there is taken as the smaller of the two (before it the held
/// coil current pushes, after it the cutting force: each changes it
/// monotonically within the period), the cutting force as the smaller
/// (it is held from tick to tick); the surface's velocity and
/// acceleration (the exact command under the tool, z − err) as their
/// largest toward the tool over the carry's longest duration, a quarter
/// period of the spring-mass, π/2·√(m/k).
fn release_state(
    spec: &host_sim::cut::CutSpec,
    trace: &[host_sim::faults::Sample],
    k: usize,
) -> (f64, f64) {
    let slide = &spec.scenario.rig.slide;
    let (m, b) = (slide.mass_lbf_s2_per_in, slide.b_lbf_s_per_in);
    let j = k.saturating_sub(1);
    let dt = (trace[k].t_ns - trace[j].t_ns).max(1) as f64 * 1e-9;
    let quarter_s = std::f64::consts::FRAC_PI_2 * (m / PART_STIFFNESS_LBF_PER_IN).sqrt();
    let n = (quarter_s / dt).ceil() as usize + 2;
    let win = &trace[j..(k + n).min(trace.len())];
    let exact = |x: &host_sim::faults::Sample| x.z_in - x.err_in;
    let rates: Vec<f64> = win
        .windows(2)
        .map(|p| (exact(&p[1]) - exact(&p[0])) / ((p[1].t_ns - p[0].t_ns) as f64 * 1e-9))
        .collect();
    // +Z is out of the part (part_side = −1): a surface moving toward +Z
    // comes at the tool.
    let n_dot = rates.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let accels: Vec<f64> = rates.windows(2).map(|r| (r[1] - r[0]) / dt).collect();
    let n_ddot = accels.iter().copied().fold(0.0f64, f64::max);
    let n_ddot_abs = accels.iter().map(|a| a.abs()).fold(0.0f64, f64::max);
    let z_dot = trace[j].velocity_in_s.min(trace[k].velocity_in_s);
    let f_c = trace[j].force_lbf.min(trace[k].force_lbf);
    // The surface's rate at the release: the period's mean, and what its
    // acceleration can add within half a period.
    let w = rates[0] + n_ddot_abs * dt / 2.0 - z_dot;
    (w, f_c - b * n_dot.max(0.0) - m * n_ddot)
}

/// The longest a RampToNull reaction may take from the latch to the
/// command at null, s: the slew profile (velocity ≤ v, acceleration ≤ a)
/// first turns the command's velocity around (at most v/a from −v), then
/// accelerates to v (v/a), covers the distance to null at v and brakes
/// (v/a): 3·v/a + |c0|/v, and a tick either side for the sampling.
fn ramp_to_null_s(spec: &host_sim::cut::CutSpec, command_in: f64) -> f64 {
    let d = &spec.scenario.servo_design;
    let (v, a) = (d.slew_in_per_s, d.slew_accel_in_per_s2);
    3.0 * v / a + command_in.abs() / v + 2.0 / f64::from(d.rate_hz)
}

/// How long the campaign watches the spindle-speed row, s.
const SPINDLE_WINDOW_S: f64 = 2.5;

/// The following-error push (`Case::FollowingError`'s profile in
/// `host_sim::faults`: 20 lbf at 5 ms, falling to 0 at 45 ms).
const PUSH_END_S: f64 = 0.045;
const PUSH_FALL_LBF_PER_S: f64 = 20.0 / 0.040;

/// When the slide is back within `NULL_HOLD_IN` of null after the push,
/// s from the injection: the push's end, the observer's settling (its
/// triple pole: 3/ω_o), then the loop's return by the envelope of its
/// error dynamics (ζ < 1 at ω_c), D·(ω_c/ω_d)·e^(−ζω_c t) ≤ NULL_HOLD_IN,
/// from D = the slide's offset at the push's end plus what the force
/// estimate still owes: a triple-pole observer lags a falling force by
/// r·3/ω_o, and the cutting force it cancels vanishes when the returning
/// tool lifts out of the stock, which the loop's stiffness m·ω_c² turns
/// into an offset; and two ticks for the sampling.
fn push_return_s(spec: &host_sim::cut::CutSpec, o: &host_sim::faults::Outcome, t_inj: u64) -> f64 {
    use std::f64::consts::TAU;
    let d = &spec.scenario.servo_design;
    let end_ns = t_inj + (PUSH_END_S * 1e9) as u64;
    let at_end = o
        .trace
        .iter()
        .find(|x| x.t_ns >= end_ns)
        .expect("the trace runs past the push");
    let (zeta, w, w_o) = (d.damping, TAU * d.bandwidth_hz, TAU * d.observer_hz);
    // And the cutting force the loop is cancelling at the push's end: the
    // returning tool passes null and lifts out of the stock (where null is
    // below the stock's top: X = 3 in, 360 rpm, the tool 880 µin below
    // null at 47 ms, 1.2 lbf falling to 0 by 51 ms), a step the estimate
    // owes in full at first.
    let owed_lbf = PUSH_FALL_LBF_PER_S * 3.0 / w_o + at_end.force_lbf.abs();
    let offset =
        (at_end.z_in - at_end.command_in).abs() + owed_lbf / (d.slide.mass_lbf_s2_per_in * w * w);
    let envelope = 1.0 / (1.0 - zeta * zeta).sqrt();
    let ret = ((offset * envelope / host_sim::faults::NULL_HOLD_IN).ln() / (zeta * w)).max(0.0);
    PUSH_END_S + 3.0 / w_o + ret + 2.0 / f64::from(d.rate_hz)
}

/// Checks one row against its mechanism (returns what it held it to).
fn check_row(spec: &host_sim::cut::CutSpec, case: Case, o: &host_sim::faults::Outcome) -> String {
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
        return format!("{}: {e:.1} µin = undisturbed", r.fault);
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
    let t_safe_ms = r.time_to_safe_ms.expect("time to safe");
    let t_inj = (r.injected_at_s.unwrap() * 1e9).round() as u64;
    let ms = |t: u64| (t as f64 - t_inj as f64) * 1e-6;
    let last = o.trace.last().unwrap();
    match f.reaction() {
        Reaction::DisableAmplifier => {
            assert!(!last.amp_enabled, "{r:?}");
            // A row may latch a ramp-to-null fault first (following-error-
            // fast: FollowingError; current-limit: FollowingError while the
            // push holds the slide off) and the disabling fault later, which
            // replaces it: the check is made at the first tick whose latched
            // fault disables the amplifier.
            if !case.board_model() {
                // The tick that latched the fault writes the enable low
                // (after its DAC frame: the amplifier sees the edge
                // `dac_latency_ns` later, within the loop period), so the
                // amplifier is off at the next tick's instant: safe one
                // tick after the latch, not later. (A sample holds the
                // amplifier's view at its tick's instant, before that
                // tick's own write: the test once read that as "the
                // latching tick left the amplifier enabled".)
                let k = o
                    .trace
                    .iter()
                    .position(|x| x.fault_disables && x.t_ns >= t_inj)
                    .expect("a tick with a disabling fault latched");
                let (first, next) = (&o.trace[k], &o.trace[k + 1]);
                assert!(
                    !first.enable_written,
                    "{}: the tick that latched {f:?} left the enable line high",
                    r.fault
                );
                assert!(
                    spec.scenario.rig.dac_latency_ns < next.t_ns - first.t_ns,
                    "the enable's write lands within the loop period"
                );
                assert!(
                    !next.amp_enabled,
                    "{}: the amplifier still enabled at the tick after the latch",
                    r.fault
                );
                assert!(
                    (t_safe_ms - ms(next.t_ns)).abs() < 1e-9,
                    "{}: safe {t_safe_ms} ms, latched {} ms (the next tick {} ms)",
                    r.fault,
                    ms(first.t_ns),
                    ms(next.t_ns)
                );
            }
            // Released: the tool goes no deeper than it was at the release
            // plus what the released slide can still carry it
            // (`release_carry_in`). The release is the amplifier's
            // enabled-to-off edge after the injection (a row injected at
            // boot starts with the amplifier off, before the arm).
            let k = o
                .trace
                .windows(2)
                .position(|p| p[1].t_ns >= t_inj && p[0].amp_enabled && !p[1].amp_enabled)
                .expect("the amplifier released after the injection")
                + 1;
            let at_release = o.trace[..=k]
                .iter()
                .filter(|x| x.t_ns >= t_inj)
                .map(|x| -x.err_in)
                .fold(0.0f64, f64::max);
            let (w, f_net) = release_state(spec, &o.trace, k);
            let carry = release_carry_in(spec, w, f_net);
            let bound = (at_release + carry) * 1e6;
            assert!(
                e <= bound + 1e-9,
                "{}: {e} µin into the part, beyond {bound} µin: {at_release:e} in at the release + the carry {carry:e} in of the tool going in at {w} in/s against {f_net} lbf out",
                r.fault
            );
            format!(
                "{}: {e:.1} ≤ {bound:.1} µin (release {:.1} + carry {:.1}: w {w:.4} in/s against {f_net:.3} lbf), enable written low in the latching tick",
                r.fault,
                at_release * 1e6,
                carry * 1e6
            )
        }
        // The process rows' reaction: `faults_process.rs` judges them.
        Reaction::Retract => {
            assert!(last.amp_enabled, "{r:?}");
            format!("{}: retract {t_safe_ms:.1} ms", r.fault)
        }
        Reaction::RampToNull => {
            assert!(last.amp_enabled && last.command_in == 0.0, "{r:?}");
            // From the latch (or, a table refused at boot, from the arm:
            // nothing is driven before it) to the command at null.
            let from = o
                .trace
                .iter()
                .find(|x| x.fault && x.amp_enabled)
                .expect("latched with the loop closed");
            let mut allowed_ms = ramp_to_null_s(spec, from.command_in) * 1e3;
            if case == Case::FollowingError {
                // The push holds the slide off null beyond the loop's force
                // until it dies away; from then the loop returns it.
                allowed_ms = allowed_ms.max(push_return_s(spec, o, t_inj) * 1e3 - ms(from.t_ns));
            }
            assert!(
                t_safe_ms - ms(from.t_ns) <= allowed_ms,
                "{}: safe {t_safe_ms} ms, {} ms after the latch; the slew profile takes at most {allowed_ms} ms from {} in",
                r.fault,
                t_safe_ms - ms(from.t_ns),
                from.command_in
            );
            if case == Case::FollowingError {
                // The push row: a test of its own holds it (below).
                return format!("{}: {e:.1} µin (push; its own test)", r.fault);
            }
            // The loop stays closed and the command leaves the part (from
            // Z ≤ 0 toward 0): the tool departs from the exact command by
            // no more than the cut's own following error, measured over
            // the revolution before the injection on the same seeds, plus
            // the learned correction the latch takes out of the loop (it
            // joins the command, so the loop's error is again the
            // unlearned one until the command has left: at most the
            // correction's size more). At
            // boot there is no cut before: the slide is held at null, above
            // the part, never into it.
            // At boot (a refused table, no cut before): the slide is held
            // at null once armed; before that the arm's sign-check doublet
            // drives it open loop, at most 2·z(T) (a double integrator
            // pushed +a for T then −a for T moves a·T² = 2·z(T); damping
            // only shortens it). So the tool is at most that below null,
            // and null is at most the exact surface's largest height
            // above Z = 0 over the run above the part.
            let correction_uin = o
                .trace
                .iter()
                .take_while(|x| !x.fault)
                .map(|x| (x.reference_in - x.command_in).abs() * 1e6)
                .fold(0.0f64, f64::max);
            // And the slew profile's catch-up: the ramp to null starts the
            // command from rest (the x-glitch-storm trace: the command's
            // step falls from 6.3 to 0.17 µin a 100 µs in the tick that
            // latched), while the exact surface under the tool goes on
            // moving at the reference's rate v_s; where it rises (+Z, out
            // of the stock) the held command falls below it until the
            // ramp's velocity, growing at a, reaches v_s: by at most
            // ∫(v_s − a·t) dt over v_s/a = v_s²/(2a). v_s: the
            // reference's fastest rise in the trace before the latch.
            let a = spec.scenario.servo_design.slew_accel_in_per_s2;
            let pre: Vec<_> = o.trace.iter().take_while(|x| !x.fault).collect();
            let v_s = pre
                .windows(2)
                .map(|w| {
                    (w[1].reference_in - w[0].reference_in)
                        / ((w[1].t_ns - w[0].t_ns) as f64 * 1e-9)
                })
                .fold(0.0f64, f64::max);
            let catch_up_uin = v_s * v_s / (2.0 * a) * 1e6;
            let own = correction_uin
                + catch_up_uin
                + r.excursion_before_uin.unwrap_or_else(|| {
                    let d = &spec.scenario.servo_design;
                    let doublet_in = 2.0
                        * f64::from(spec.scenario.servo.sign_check_expected_code).abs()
                        / d.slide.codes_per_in();
                    let above_null = o
                        .trace
                        .iter()
                        .map(|x| (x.z_in - x.err_in).max(0.0))
                        .fold(0.0f64, f64::max);
                    (doublet_in + above_null) * 1e6
                });
            let worst = o
                .trace
                .iter()
                .filter(|x| x.t_ns >= t_inj)
                .max_by(|a, b| b.err_in.total_cmp(&a.err_in))
                .unwrap();
            assert!(
                e <= own,
                "{}: {e} µin into the part, beyond the cut's own following error, the correction taken out and the ramp's catch-up ({own} µin: {correction_uin} of correction, {catch_up_uin} of catch-up at {v_s} in/s); deepest at {worst:?}",
                r.fault
            );
            format!("{}: {e:.1} ≤ {own:.1} µin (own FE), null {:.1} ≤ {allowed_ms:.1} ms after the latch", r.fault, t_safe_ms - ms(from.t_ns))
        }
    }
}

#[test]
fn every_injected_fault_is_detected_with_its_reason_and_ends_safe_within_its_mechanisms_bound() {
    let spec = legacy();
    let out = campaign(&spec, &Case::ALL, 0).unwrap();
    assert_eq!(out.len(), Case::ALL.len());
    for (case, o) in Case::ALL.iter().zip(&out) {
        let held = check_row(&spec, *case, o);
        eprintln!("{held}");
        let e = o.row.max_excursion_uin.unwrap();
        assert!(
            e < DEPTH_OF_CUT_IN * 1e6,
            "{}: {e} µin into the part, beyond the depth of cut",
            o.row.fault
        );
    }
}

/// The following-error fault ramps the command to null; the learning had
/// taken in the push (0.3 of a 5000 µin error) before the fault latched,
/// so a loop that kept adding the learned correction would drive the tool
/// into the part one revolution later (415 µin, before the servo dropped
/// the correction on a latched fault; docs/SAFETY.md).
///
/// The push itself ends 45 ms after the injection; from then on nothing
/// forces the tool and the loop holds the command at null, above the part.
/// A correction replayed after the latch shows from one revolution after
/// the injection (where the learning put the push): from there to the end
/// of the run the tool departs from the exact command by no more than the
/// cut's own following error over the revolution before the injection.
#[test]
fn a_following_error_fault_keeps_the_tool_within_the_depth_of_cut() {
    let spec = legacy();
    let o = run_case(&spec, Case::FollowingError, 0).unwrap();
    let e = o.row.max_excursion_uin.unwrap();
    assert!(e < DEPTH_OF_CUT_IN * 1e6, "{e} µin into the part");
    let t_inj = (o.row.injected_at_s.unwrap() * 1e9).round() as u64;
    let rev_ns = (60.0 / spec.rpm * 1e9) as u64;
    let later = o
        .trace
        .iter()
        .filter(|x| x.t_ns >= t_inj + rev_ns)
        .map(|x| -x.err_in * 1e6)
        .fold(0.0f64, f64::max);
    let own = o.row.excursion_before_uin.unwrap();
    assert!(
        o.trace.last().unwrap().t_ns >= t_inj + rev_ns + 100_000_000,
        "the run must watch the revolution after"
    );
    assert!(
        later <= own,
        "{later} µin into the part a revolution after the push, beyond the cut's own {own} µin"
    );
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
fn a_loop_stalled_at_any_phase_of_the_revolution_is_reset_safe_within_its_release_bound_and_the_depth_of_cut(
) {
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
            // The release's carry at each instant (its own w and F).
            let held = check_row(&spec, Case::StalledLoop, o);
            eprintln!("seed stream {seed}, stalled {k}/{PHASES} of a turn in: {held}");
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
    let at = |after_turns| Inject {
        after_turns,
        ..Inject::default()
    };
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

/// The campaign on every machine, reduced (the full matrix, both machines
/// at X = 1, 3, 5, 7 in and 300 / 360 rpm with a stall sweep at each:
/// `host-sim faults --matrix`, docs/SAFETY.md): modern-hw at the
/// innermost and outermost radius, legacy-hw at 360 rpm in between. Each
/// row held to its mechanism's bound as above (spindle-speed on modern-hw
/// included: the encoder's speed check per count, issue 22); the fault a
/// machine cannot have is listed as not applicable, not an error.
#[test]
fn the_campaign_runs_on_every_machine_and_each_row_holds_its_mechanisms_bound() {
    let modern = spec(host_sim::scenario::load("modern-hw").unwrap()).unwrap();
    let fast =
        host_sim::faults::spec_at(host_sim::scenario::load("legacy-hw").unwrap(), Some(360.0))
            .unwrap();
    for (spec, x_in) in [(&modern, 1.0), (&modern, 7.0), (&fast, 3.0)] {
        let at = Inject {
            after_turns: 0.0,
            x_in,
        };
        let out = host_sim::faults::campaign_at(spec, &Case::ALL, 0, at).unwrap();
        for (case, o) in Case::ALL.iter().zip(&out) {
            let name = &spec.scenario.file.name;
            if let Some(why) = case.not_applicable(spec) {
                assert_eq!(o.row.detected, None, "{name}: {:?}", o.row);
                assert!(o.row.reason.contains(why), "{}", o.row.reason);
                continue;
            }
            if *case == Case::SpindleSpeed && o.row.detected == Some(false) {
                // The campaign watches the coast for 2.5 s (300 → 100 rpm
                // at 100 rpm/s, `faults::Case::observe_ns`). The firmware's
                // per-tick checks see it below a floor (encoder: one count
                // slower than at 4/5·min_rpm; tachometer: below
                // min_rpm/2), the index check at a revolution's average
                // below min_rpm, wherever the index falls: detection is
                // guaranteed only (rpm − floor)/accel after the failure.
                // Undetected is right only where that lies beyond the
                // window (360 rpm on the tachometer: 3.1 s); there the
                // loop still cuts, within the depth of cut.
                use host_sim::machine::SpindleSensor;
                let m = &spec.scenario.machine;
                let floor = f64::from(m.min_rpm)
                    * match m.sensor {
                        SpindleSensor::EncoderIndex => 0.8,
                        SpindleSensor::TachIndex => 0.5,
                    };
                let t_s = (spec.rpm - floor) / spec.scenario.file.spindle.accel_rpm_per_s;
                assert!(
                    t_s > SPINDLE_WINDOW_S,
                    "{name} X {x_in} in {} rpm: spindle-speed not detected, though the checks must see the coast {t_s} s after the failure: {:?}",
                    spec.rpm,
                    o.row
                );
                assert!(
                    o.row.max_excursion_uin.unwrap() < DEPTH_OF_CUT_IN * 1e6,
                    "{:?}",
                    o.row
                );
                eprintln!(
                    "{name} X {x_in} in {} rpm: spindle-speed not seen in the {SPINDLE_WINDOW_S} s window (guaranteed at {t_s:.2} s), the tool within the depth of cut",
                    spec.rpm
                );
                continue;
            }
            // Contour monitoring (issue 30) latches it where its ring or
            // rebound shows; undetected, the replay bound below holds.
            if *case == Case::FollowingError && name == "modern-hw" && o.latched.is_none() {
                // The stiffer loop holds the push within the following-
                // error limit (about 3000 µin of 4000), so nothing latches,
                // rightly, and the cut goes on. What the learning took of
                // the push is clipped (docs/SAFETY.md, "A transient learned
                // and replayed"): one revolution's update is at most κ·C,
                // and the revolution after replays no more than that.
                let r = &o.row;
                let d = &spec.scenario.servo_design;
                assert_eq!((r.detected, o.latched), (Some(false), None), "{r:?}");
                let held_off_in = o
                    .trace
                    .iter()
                    .map(|x| (x.reference_in - x.z_in).abs())
                    .fold(0.0f64, f64::max);
                assert!(
                    held_off_in < d.following_error_in,
                    "{name}: the push took the slide {held_off_in} in off its reference: beyond the limit, yet no fault"
                );
                let last = o.trace.last().unwrap();
                assert!(last.amp_enabled && !last.fault, "{r:?}");
                let t_inj = (r.injected_at_s.unwrap() * 1e9).round() as u64;
                let rev_ns = (60.0 / spec.rpm * 1e9) as u64;
                assert!(
                    last.t_ns >= t_inj + rev_ns + 50_000_000,
                    "the run must watch the replay a revolution after the push"
                );
                // The learned correction after the push against κ·C, on top
                // of what the cut had learned before it (and a Q8 LSB).
                let correction_uin = |from: u64, to: u64| {
                    o.trace
                        .iter()
                        .filter(|x| (from..to).contains(&x.t_ns))
                        .map(|x| (x.reference_in - x.command_in).abs() * 1e6)
                        .fold(0.0f64, f64::max)
                };
                let replay_uin = correction_uin(t_inj, u64::MAX);
                let replay_bound_uin =
                    d.learning_gain * d.learning_clip_uin + correction_uin(0, t_inj) + 0.01;
                assert!(
                    replay_uin <= replay_bound_uin,
                    "{name} X {x_in} in: the push learned and replayed as {replay_uin:.1} µin of correction, beyond κ·C = {replay_bound_uin:.1} µin"
                );
                // From a revolution after the push the tool meets the
                // surface the push and its dip left (stock the tool was
                // lifted off, stock it cut too deep): the same run with the
                // learning's clip at its least (1 µin: it replays ≤ κ·1 µin)
                // is that alone. The learning may add what it replays.
                let later_uin = |o: &host_sim::faults::Outcome| {
                    o.trace
                        .iter()
                        .filter(|x| x.t_ns >= t_inj + rev_ns)
                        .map(|x| -x.err_in * 1e6)
                        .fold(0.0f64, f64::max)
                };
                let mut unlearned = spec.clone();
                unlearned.scenario.servo_design.learning_clip_uin = 1.0;
                unlearned.scenario.servo = unlearned.scenario.servo_design.config().unwrap();
                let o_ref = run_case_at(&unlearned, *case, 0, at).unwrap();
                assert_eq!(o_ref.row.injected_at_s, r.injected_at_s);
                let (later, own) = (later_uin(o), later_uin(&o_ref));
                assert!(
                    later <= own + replay_uin,
                    "{name} X {x_in} in: {later:.1} µin into the part a revolution after the push, beyond the {own:.1} µin of the same cut without the replay + the {replay_uin:.1} µin replayed"
                );
                // During the push's fall the force estimate lags it and the
                // slide dips below the command (docs/SAFETY.md): held to
                // the depth of cut below.
                let e = r.max_excursion_uin.unwrap();
                eprintln!(
                    "{name} X {x_in} in {} rpm: following-error not detected (held {:.0} µin off, limit {:.0}): {e:.1} µin into the part; a revolution later {later:.1} ≤ {own:.1} unlearned + {replay_uin:.1} replayed (≤ κ·C {replay_bound_uin:.1})",
                    spec.rpm,
                    held_off_in * 1e6,
                    d.following_error_in * 1e6
                );
                assert!(e < DEPTH_OF_CUT_IN * 1e6, "{name} X {x_in}: {r:?}");
                continue;
            }
            let held = check_row(spec, *case, o);
            eprintln!("{name} X {x_in} in {} rpm: {held}", spec.rpm);
            let e = o.row.max_excursion_uin.unwrap();
            assert!(e < DEPTH_OF_CUT_IN * 1e6, "{name} X {x_in}: {held}");
        }
        let na = out.iter().filter(|o| o.row.detected.is_none()).count();
        // modern-hw: x-bad-bcd and x-glitch-storm (no legacy X line).
        let expect_na = if spec.scenario.file.name == "modern-hw" {
            2
        } else {
            0
        };
        assert_eq!(
            na, expect_na,
            "not applicable on {}",
            spec.scenario.file.name
        );
    }
}
