//! One row checked against its mechanism.

use super::*;

/// Checks one row against its mechanism (returns what it held it to).
pub(crate) fn check_row(
    spec: &host_sim::cut::CutSpec,
    case: Case,
    o: &host_sim::faults::Outcome,
) -> String {
    let r = &o.row;
    assert_eq!(r.fault, case.name());
    assert_eq!(r.detected, Some(true), "{r:?}");
    assert_eq!(r.safe_state, Some(true), "{r:?}");
    let e = r.max_excursion_uin.unwrap();
    if expected(case).faults.is_empty() {
        // The malformed frames: refused, no fault, the cut unchanged.
        assert_eq!(o.latched, None, "{r:?}");
        assert_eq!(r.time_to_safe_ms, Some(0.0));
        assert_eq!(Some(e), r.excursion_undisturbed_uin, "{r:?}");
        return format!("{}: {e:.1} µin = undisturbed", r.fault);
    }
    let f = o
        .latched
        .unwrap_or_else(|| panic!("{}: not detected", r.fault));
    let x = expected(case);
    let &(_, reaction, words) =
        x.faults.iter().find(|(is, _, _)| is(f)).unwrap_or_else(|| {
            panic!("{}: latched {f:?}, not a fault SAFETY.md gives it", r.fault)
        });
    assert!(
        r.reason.to_lowercase().contains(words),
        "{}: the reason {:?} does not say {words:?}",
        r.fault,
        r.reason
    );
    assert_eq!(r.reason.contains("board model"), x.board_model, "{r:?}");
    assert_eq!(
        r.reaction.as_deref(),
        Some(match reaction {
            Reaction::RampToNull => "RampToNull",
            Reaction::DisableAmplifier => "DisableAmplifier",
            Reaction::Retract => "Retract",
        }),
        "{r:?}"
    );
    // Detected within its mechanism's deadline, not the window's.
    let took =
        detected_ms(case, o).unwrap_or_else(|| panic!("{}: no sample shows the fault", r.fault));
    let deadline = detection_deadline_ms(spec, x.detect, o)
        .unwrap_or_else(|| panic!("{}: no deadline for {:?}", r.fault, x.detect));
    assert!(
        took <= deadline,
        "{}: detected {took} ms after the injection, beyond its {:?} deadline of {deadline} ms",
        r.fault,
        x.detect
    );
    eprintln!(
        "{}: detected {took:.2} ms after the injection (deadline {deadline:.2} ms, {:?})",
        r.fault, x.detect
    );
    let t_safe_ms = r.time_to_safe_ms.expect("time to safe");
    if x.board_model {
        // The watchdog's reset and the panic handler take the outputs off
        // as they detect: safe at the detection, within its deadline.
        assert!(
            (t_safe_ms - took).abs() < 1e-9,
            "{}: safe {t_safe_ms} ms, the amplifier seen off at {took} ms",
            r.fault
        );
    }
    let t_inj = (r.injected_at_s.unwrap() * 1e9).round() as u64;
    let ms = |t: u64| (t as f64 - t_inj as f64) * 1e-6;
    let last = o.trace.last().unwrap();
    match reaction {
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
            // The command at the latch: the larger of the sample showing
            // it and the one before (the ramp may have taken its first
            // step in the latching tick).
            let k = o.trace.iter().position(|x| std::ptr::eq(x, from)).unwrap();
            let at_ms = |t_ms: f64| {
                o.trace
                    .iter()
                    .find(|x| ms(x.t_ns) >= t_ms)
                    .unwrap_or_else(|| o.trace.last().unwrap())
            };
            let mut allowed_ms = if matches!(expected(case).detect, Detect::Boot) {
                // Refused at boot, the command null from the start: the arm
                // drives the sign check's doublet open loop (2 ×
                // sign_check_ms), then the loop takes the slide from where
                // the doublet left it to null by the same slew profile.
                let d = &spec.scenario.servo_design;
                let closed_ms = ms(from.t_ns) + 2.0 * d.sign_check_ms;
                let off = at_ms(closed_ms).z_in;
                let arrive_ms = closed_ms + ramp_to_null_s(spec, off) * 1e3;
                arrive_ms - ms(from.t_ns) + settle_to_hold_s(spec, at_ms(arrive_ms).z_in) * 1e3
            } else {
                let c0 = from
                    .command_in
                    .abs()
                    .max(o.trace[k.saturating_sub(1)].command_in.abs());
                let command_ms = ramp_to_null_s(spec, c0) * 1e3;
                let at_null = o.trace[k..]
                    .iter()
                    .find(|x| x.command_in == 0.0)
                    .expect("the command reaches null");
                assert!(
                    ms(at_null.t_ns) - ms(from.t_ns) <= command_ms,
                    "{}: the command reached null {} ms after the latch; the slew profile from rest takes at most {command_ms} ms from {c0} in",
                    r.fault,
                    ms(at_null.t_ns) - ms(from.t_ns)
                );
                command_ms + settle_to_hold_s(spec, at_null.z_in) * 1e3
            };
            if case == Case::FollowingError {
                // The push holds the slide off null beyond the loop's force
                // until it dies away; from then the loop returns it.
                allowed_ms = allowed_ms.max(push_return_s(spec, o, t_inj) * 1e3 - ms(from.t_ns));
            }
            assert!(
                t_safe_ms - ms(from.t_ns) <= allowed_ms,
                "{}: safe {t_safe_ms} ms, {} ms after the latch; the slew profile and the loop's settling take at most {allowed_ms} ms from {} in",
                r.fault,
                t_safe_ms - ms(from.t_ns),
                from.command_in
            );
            // The loop stays closed and the command leaves the part (from
            // Z ≤ 0 toward 0): the tool departs from the exact command by
            // no more than the cut's own following error, measured over
            // the revolution before the injection on the same seeds, plus
            // what the loop passes of the ramp (below).
            // At boot (a refused table, no cut before): the slide is held
            // at null once armed; before that the arm's sign-check doublet
            // drives it open loop, at most 2·z(T) (a double integrator
            // pushed +a for T then −a for T moves a·T² = 2·z(T); damping
            // only shortens it). So the tool is at most that below null,
            // and null is at most the exact surface's largest height
            // above Z = 0 over the run above the part.
            // The ramp to null: what the loop passes of the reference's
            // departure from the path the cut was on (the profile from rest
            // against the exact command's own motion, and the learned
            // correction held where it was): `ramp_dip_in`. At boot (a
            // refused table) the loop never followed the part: the
            // doublet's bound below holds the slide instead.
            let (dip_in, held_in) = if matches!(expected(case).detect, Detect::Boot) {
                (0.0, 0.0)
            } else {
                ramp_dip_in(spec, o, t_inj, k)
            };
            let (dip_uin, held_uin) = (dip_in * 1e6, held_in * 1e6);
            let exact = |x: &host_sim::faults::Sample| x.z_in - x.err_in;
            // The push row: the push holds the tool out of the part; the
            // loop's return from its offset passes the command by its
            // overshoot, toward the part.
            // The push row: after the push the loop holds the command at
            // null, and the slide dips below it by at most the offset it
            // returns from (what the force estimate still owes, through
            // the loop's stiffness) and that return's overshoot; the tool
            // is into the part where the surface lies less deep below
            // null than that: by D + Z_exact at most, Z_exact ≤ 0.
            let overshoot_uin = if case == Case::FollowingError {
                // The outward offset's return overshoots inward; the owed
                // force's offset is inward, and overshoots too.
                let (outward, owed) = push_offset_parts_in(spec, o, t_inj);
                let dip =
                    return_overshoot_in(spec, outward) + owed + return_overshoot_in(spec, owed);
                let end_ns = t_inj + (PUSH_END_S * 1e9) as u64;
                o.trace
                    .iter()
                    .filter(|x| x.t_ns >= end_ns)
                    .map(|x| (dip + exact(x).min(0.0)).max(0.0))
                    .fold(0.0f64, f64::max)
                    * 1e6
            } else {
                0.0
            };
            // The spindle-speed row cuts on through the coast until the
            // latch (2.2 s at 100 rpm/s), the feed per revolution growing as
            // the spindle slows: its own following error is the larger of
            // the revolution before the injection and the coast up to the
            // latch (measured on the plant's truth, not bounded here).
            let coast_uin = if case == Case::SpindleSpeed {
                o.trace
                    .iter()
                    .filter(|x| x.t_ns >= t_inj && x.t_ns < from.t_ns)
                    .map(|x| -x.err_in * 1e6)
                    .fold(0.0f64, f64::max)
            } else {
                0.0
            };
            let own = dip_uin
                + held_uin
                + overshoot_uin
                + r.excursion_before_uin
                    .map(|b| b.max(coast_uin))
                    .unwrap_or_else(|| {
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
                "{}: {e} µin into the part, beyond the cut's own following error and what the loop passes of the ramp ({own} µin: {dip_uin} of the ramp's dip, {held_uin} of the held correction); deepest at {worst:?}",
                r.fault
            );
            format!(
                "{}: {e:.1} ≤ {own:.1} µin (own FE {:.1}, the ramp's dip {dip_uin:.1}, held correction {held_uin:.1}, overshoot {overshoot_uin:.1}), null {:.1} ≤ {allowed_ms:.1} ms after the latch",
                r.fault,
                own - dip_uin - held_uin - overshoot_uin,
                t_safe_ms - ms(from.t_ns)
            )
        }
    }
}
