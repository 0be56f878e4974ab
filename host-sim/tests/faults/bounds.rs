//! The physical bounds the rows are held to: the part's spring, the
//! release, the ramp to null, the push (docs/SAFETY.md, "Fault campaign").

use super::*;

/// Chapter 5's depth of cut, in: the stock the finishing pass removes.
pub(crate) const DEPTH_OF_CUT_IN: f64 = 0.0003;

pub(crate) fn legacy() -> host_sim::cut::CutSpec {
    spec(host_sim::scenario::load("legacy-hw").unwrap()).unwrap()
}

/// The cut's process spring at chapter 5's depth, lbf/in: dF/dd of the
/// edge force k_e·√(2·r_t·d) at d = 0.0003 in (≈ 2200, docs/CUT.md).
pub(crate) const PART_STIFFNESS_LBF_PER_IN: f64 = 2200.0;

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
pub(crate) fn release_carry_in(
    spec: &host_sim::cut::CutSpec,
    w_in_s: f64,
    net_out_lbf: f64,
) -> f64 {
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
pub(crate) fn release_state(
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
/// command at null, s, in closed form: the slew profile restarts the
/// command from rest at the latch (the x-glitch-storm trace: the command's
/// step falls from 6.3 to 0.17 µin a 100 µs in the tick that latched) and
/// moves it the distance D = |c0| with velocity ≤ v and acceleration ≤ a:
/// a triangle, 2·√(D/a), where D < v²/a, else a trapezoid, D/v + v/a;
/// and a tick either side for the sampling.
pub(crate) fn ramp_to_null_s(spec: &host_sim::cut::CutSpec, command_in: f64) -> f64 {
    let d = &spec.scenario.servo_design;
    let (v, a, dist) = (d.slew_in_per_s, d.slew_accel_in_per_s2, command_in.abs());
    let profile = if dist < v * v / a {
        2.0 * (dist / a).sqrt()
    } else {
        dist / v + v / a
    };
    profile + 2.0 / f64::from(d.rate_hz)
}

/// From the command's arrival at null, how long the slide takes to come
/// within `NULL_HOLD_IN` of it, s: the loop's error dynamics (ζ < 1 at
/// ω_c) from the slide's offset `z_in` at the arrival, by their envelope
/// D·(ω_c/ω_d)·e^(−ζω_c t); none if it is already within.
pub(crate) fn settle_to_hold_s(spec: &host_sim::cut::CutSpec, z_in: f64) -> f64 {
    let d = &spec.scenario.servo_design;
    let (zeta, w) = (d.damping, std::f64::consts::TAU * d.bandwidth_hz);
    let envelope = 1.0 / (1.0 - zeta * zeta).sqrt();
    let hold = host_sim::faults::NULL_HOLD_IN;
    if z_in.abs() <= hold {
        return 0.0;
    }
    (z_in.abs() * envelope / hold).ln() / (zeta * w) + 1.0 / f64::from(d.rate_hz)
}

/// How long the campaign watches the spindle-speed row, s.
pub(crate) const SPINDLE_WINDOW_S: f64 = 2.5;

/// The following-error push (`Case::FollowingError`'s profile in
/// `host_sim::faults`: 20 lbf at 5 ms, falling to 0 at 45 ms).
pub(crate) const PUSH_END_S: f64 = 0.045;
pub(crate) const PUSH_FALL_LBF_PER_S: f64 = 20.0 / 0.040;

/// The slide's offset from its command the loop returns it from after the
/// push, in: the offset at the push's end plus what the force estimate
/// still owes: a triple-pole observer lags a falling force by r·3/ω_o, and
/// the cutting force it cancels vanishes when the returning tool lifts out
/// of the stock, which the loop's stiffness m·ω_c² turns into an offset.
pub(crate) fn push_offset_in(
    spec: &host_sim::cut::CutSpec,
    o: &host_sim::faults::Outcome,
    t_inj: u64,
) -> f64 {
    let (outward, owed) = push_offset_parts_in(spec, o, t_inj);
    outward + owed
}

/// [`push_offset_in`]'s two parts, in: the slide's offset from its command
/// at the push's end (outward, away from the part) and the offset the
/// force the estimate still owes drives through the loop's stiffness
/// (inward, once the push has gone).
pub(crate) fn push_offset_parts_in(
    spec: &host_sim::cut::CutSpec,
    o: &host_sim::faults::Outcome,
    t_inj: u64,
) -> (f64, f64) {
    use std::f64::consts::TAU;
    let d = &spec.scenario.servo_design;
    let end_ns = t_inj + (PUSH_END_S * 1e9) as u64;
    let at_end = o
        .trace
        .iter()
        .find(|x| x.t_ns >= end_ns)
        .expect("the trace runs past the push");
    let (w, w_o) = (TAU * d.bandwidth_hz, TAU * d.observer_hz);
    // And the cutting force the loop is cancelling at the push's end: the
    // returning tool passes null and lifts out of the stock (where null is
    // below the stock's top: X = 3 in, 360 rpm, the tool 880 µin below
    // null at 47 ms, 1.2 lbf falling to 0 by 51 ms), a step the estimate
    // owes in full at first.
    let owed_lbf = PUSH_FALL_LBF_PER_S * 3.0 / w_o + at_end.force_lbf.abs();
    (
        (at_end.z_in - at_end.command_in).abs(),
        owed_lbf / (d.slide.mass_lbf_s2_per_in * w * w),
    )
}

/// When the slide is back within `NULL_HOLD_IN` of null after the push,
/// s from the injection: the push's end, the observer's settling (its
/// triple pole: 3/ω_o), then the loop's return from [`push_offset_in`] by
/// the envelope of its error dynamics (ζ < 1 at ω_c),
/// D·(ω_c/ω_d)·e^(−ζω_c t) ≤ NULL_HOLD_IN; and two ticks for the sampling.
pub(crate) fn push_return_s(
    spec: &host_sim::cut::CutSpec,
    o: &host_sim::faults::Outcome,
    t_inj: u64,
) -> f64 {
    use std::f64::consts::TAU;
    let d = &spec.scenario.servo_design;
    let (zeta, w, w_o) = (d.damping, TAU * d.bandwidth_hz, TAU * d.observer_hz);
    let offset = push_offset_in(spec, o, t_inj);
    let envelope = 1.0 / (1.0 - zeta * zeta).sqrt();
    let ret = ((offset * envelope / host_sim::faults::NULL_HOLD_IN).ln() / (zeta * w)).max(0.0);
    PUSH_END_S + 3.0 / w_o + ret + 2.0 / f64::from(d.rate_hz)
}

/// How far the loop's return from an offset D overshoots past its command,
/// in: a second-order loop (ζ < 1) passes its target by D·e^(−ζπ/√(1−ζ²)).
pub(crate) fn return_overshoot_in(spec: &host_sim::cut::CutSpec, offset_in: f64) -> f64 {
    let zeta = spec.scenario.servo_design.damping;
    offset_in * (-zeta * std::f64::consts::PI / (1.0 - zeta * zeta).sqrt()).exp()
}

/// The slew profile from rest toward a goal `dist_in` away, after `t_s`:
/// `[distance (in), velocity (in/s), acceleration (in/s²)]`: accelerate at
/// a to v, cruise, brake at a, arrive at rest (`SlewProfile`'s trapezoid,
/// or its triangle where dist < v²/a).
pub(crate) fn slew_from_rest(spec: &host_sim::cut::CutSpec, dist_in: f64, t_s: f64) -> [f64; 3] {
    let d = &spec.scenario.servo_design;
    let (v, a) = (d.slew_in_per_s, d.slew_accel_in_per_s2);
    let t1 = (v / a).min((dist_in / a).sqrt());
    let vp = a * t1;
    let cruise = (dist_in - a * t1 * t1) / vp;
    let end = 2.0 * t1 + cruise;
    match t_s {
        t if t <= 0.0 => [0.0; 3],
        t if t <= t1 => [a * t * t / 2.0, a * t, a],
        t if t <= t1 + cruise => [a * t1 * t1 / 2.0 + vp * (t - t1), vp, 0.0],
        t if t < end => [dist_in - a * (end - t) * (end - t) / 2.0, a * (end - t), -a],
        _ => [dist_in, 0.0, 0.0],
    }
}

/// The loop of the scenario's design on the cut's spring
/// (`host_sim::loopmodel`: the sampled f64 design, not the firmware's code).
pub(crate) fn loop_model(spec: &host_sim::cut::CutSpec) -> host_sim::loopmodel::LoopModel {
    let sc = &spec.scenario;
    host_sim::loopmodel::LoopModel::new(
        &sc.servo_design,
        sc.file.motor.l_over_r_ms * 1e-3,
        sc.rig.dac_latency_ns as f64 * 1e-9,
        PART_STIFFNESS_LBF_PER_IN,
    )
}

/// What the ramp to null adds to the tool's depth below the exact command,
/// beyond the cut's own following error, in: `(the ramp's dip, the held
/// correction's)` at the tick where their sum is largest (from the latch
/// on; none where it is never positive).
///
/// The loop is linear (`loop_model`), so the tool's path after the latch is
/// the path the cut would have taken (its own error against the exact
/// command: the revolution before's) plus the loop's response to the
/// reference's departure from the path it was on, δr = r_cut − r, with
/// the feedforward's rates departing likewise. At the latch the learned
/// correction joins the command and the slew profile restarts the command
/// from rest toward null (`Servo::update`): the reference rises by the
/// profile ρ(t) from where it was, its feedforward velocity ρ̇ (from 0: the
/// path's velocity is dropped, with no acceleration to match) and
/// acceleration ρ̈, while the cut's would have moved with the exact command
/// n(t) and its rates, and the correction c(t). So
/// δr = (n(t) − n(t₀)) − ρ(t) + (c(t) − c(t₀)), δv = ṅ − ρ̇, δa = n̈ − ρ̈:
/// n is the part's geometry (the exact command under the tool, read from
/// the trace, its rates by differences), ρ the profile's closed form
/// ([`slew_from_rest`]) started a tick late (its first step may fall in the
/// latching tick or the next); the loop's response to them is the dip.
///
/// The correction's departure u = c(t) − c(t₀) is not known after the
/// latch, but the cut would have read it from the same table at the same
/// X, so it stays within what the revolution before showed
/// (`Outcome::correction_before`): it moves at most its largest step ċ per
/// tick, and never by more than the table's range R (greatest less
/// least). Counting from the tick before the latch (the correction that
/// joined the command may be that tick's or the latching tick's),
/// |u_i| ≤ min(R, ċ·(i + 1)) and |u_i − u_(i−1)| ≤ ċ. The loop passes
/// y_k = Σ_i g_(k−i)·u_i of it (g its impulse response, the step
/// response's differences), so |y_k| ≤ Σ_i |g_(k−i)|·min(R, ċ·(i + 1)),
/// which stops growing at ‖g‖₁·R; and, by steps, |y_k| ≤ ċ·Σ_(m≤k) |s_m|
/// (s the step response, with its rates), the tighter while the
/// departure is young. The held correction's term is the smaller of the
/// two.
pub(crate) fn ramp_dip_in(
    spec: &host_sim::cut::CutSpec,
    o: &host_sim::faults::Outcome,
    t_inj: u64,
    latch: usize,
) -> (f64, f64) {
    let trace = &o.trace;
    let j = latch.saturating_sub(1);
    let h = 1.0 / f64::from(spec.scenario.servo_design.rate_hz);
    let exact = |x: &host_sim::faults::Sample| x.z_in - x.err_in;
    let dist = trace[latch]
        .command_in
        .abs()
        .min(trace[j].reference_in.abs());
    let after = &trace[j..];
    let n: Vec<f64> = trace[j.saturating_sub(2)..].iter().map(exact).collect();
    let off = n.len() - after.len();
    let dr: Vec<[f64; 3]> = after
        .iter()
        .enumerate()
        .map(|(i, x)| {
            let t = (x.t_ns - trace[j].t_ns) as f64 * 1e-9;
            let [p, v, a] = slew_from_rest(spec, dist, t - h);
            let k = i + off;
            let n_v = (n[k] - n[k - 1]) / h;
            let n_a = (n[k] - 2.0 * n[k - 1] + n[k - 2]) / (h * h);
            [n[k] - n[off] - p, n_v - v, n_a - a]
        })
        .collect();
    let model = loop_model(spec);
    let dip = model.reference_departure_in(&dr);
    let span = o
        .correction_before
        .unwrap_or_else(|| panic!("{}: no revolution cut before the injection", o.row.fault));
    assert!(
        trace[..latch].iter().all(|x| {
            let c = x.reference_in - x.command_in;
            x.t_ns >= t_inj || (c >= span.least_in - 1e-12 && c <= span.greatest_in + 1e-12)
        }),
        "{}: the correction left the revolution's range before the injection",
        o.row.fault
    );
    let (range, rate) = (span.greatest_in - span.least_in, span.largest_step_in);
    // The step response (1 µin, with its rates), per inch.
    let mut unit = vec![[1e-6, 0.0, 0.0]; after.len()];
    unit[0] = [1e-6, 1e-6 / h, 1e-6 / (h * h)];
    if unit.len() > 1 {
        unit[1][2] = -1e-6 / (h * h);
    }
    let s: Vec<f64> = model
        .reference_departure_in(&unit)
        .iter()
        .map(|y| y / 1e-6)
        .collect();
    let g: Vec<f64> = (0..s.len())
        .map(|m| (s[m] - if m > 0 { s[m - 1] } else { 0.0 }).abs())
        .collect();
    // Ticks until the rate has spent the range, and Σ|g| up to each tick.
    // (A correction that never moved has no range either: nothing held.)
    let young = if rate > 0.0 {
        ((range / rate).ceil() as usize).min(g.len())
    } else {
        0
    };
    let g_sum: Vec<f64> = g
        .iter()
        .scan(0.0, |a, x| {
            *a += x;
            Some(*a)
        })
        .collect();
    let mut by_steps = 0.0;
    dip.iter()
        .enumerate()
        .map(|(k, &y)| {
            by_steps += rate * s[k].abs();
            let ramping: f64 = (0..=k.min(young.saturating_sub(1)))
                .map(|i| g[k - i] * (rate * (i + 1) as f64).min(range))
                .sum();
            let spent = if k >= young {
                range * g_sum[k - young]
            } else {
                0.0
            };
            (y, by_steps.min(ramping + spent))
        })
        .fold((0.0, 0.0), |m, p| if p.0 + p.1 > m.0 + m.1 { p } else { m })
}
