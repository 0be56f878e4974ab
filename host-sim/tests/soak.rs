//! A short soak (3 minutes of machine time) with every disturbance on: the
//! long runs are reported (`host-sim soak --hours 8`, docs/RELIABILITY.md).

use host_sim::soak::{run, SoakSpec};

/// Glitching X latches, index jitter, speed noise and force noise are the
/// shop floor, not faults: none is raised. The firmware's spindle phase
/// stays unbiased (mean within 0.01°) and within the bound its index
/// jitter and tachometer noise allow (`phase_error_bound_deg`; the
/// learning's bins are 1.4° wide); the tool's following error is the
/// force and gauge noise through the design's loop (its RMS within ±20 %
/// of the closed form) and stays within the 300 µin depth of cut of its
/// command (it never leaves the cut or plunges a depth).
///
/// The latch catches a carry mid-ripple only on an *up*-count 9 → 0 of
/// the ten-thousandths digit (`machine::xslide`), once per 0.001 in of X
/// going out; the soak's default traverse (1..7 in at 0.03 in/min) spends
/// its first 200 minutes going in, so 3 minutes of it could never glitch.
/// Here X traverses 6.97..7.0 in: one minute in, one out (30 carries at
/// 0.2 each: none at all has probability 0.8³⁰ ≈ 0.1 %), one in.
#[test]
fn a_short_soak_raises_no_false_fault_and_keeps_phase_and_tool_bounded() {
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    let mut spec = SoakSpec::new(sc, 0.05);
    spec.glitch_prob = 0.2;
    spec.x_lo_in = 6.97;
    spec.x_hi_in = 7.0;
    let h = run(&spec, &|_| {}).unwrap();
    assert_eq!(h.len(), 1);
    let h = &h[0];
    assert!(h.faults.is_empty(), "{:?}", h.faults);
    assert!(h.x_glitched_latches > 0, "no latch glitched: {h:?}");
    assert!(
        h.x_min_in < 6.975 && h.x_max_in > 6.995,
        "X went out and in: {h:?}"
    );
    assert!(h.phase_error_mean_deg.abs() < 0.01, "{h:?}");
    let bound = phase_error_bound_deg(&spec, h.rpm_max);
    eprintln!(
        "phase error {:.4}° max, bound {bound:.4}°",
        h.phase_error_max_deg
    );
    assert!(h.phase_error_max_deg <= bound, "bound {bound:.4}°: {h:?}");
    // The following error is the force and gauge noise through the loop
    // (without either it is 0.3 µin), held to the design's closed form
    // (`following_error_rms_predicted_uin`) within ±20 %: the continuous-
    // time model leaves out the loop's sampling and 8.5 µs latency, the
    // notches, the coil's L/R and the small sources (X, spindle, learning).
    let predicted = following_error_rms_predicted_uin(&spec);
    let ratio = h.following_error_rms_uin / predicted;
    eprintln!(
        "following error {:.2} µin RMS, {:.1} peak; the closed form {predicted:.2} µin RMS (×{ratio:.3})",
        h.following_error_rms_uin, h.following_error_peak_uin
    );
    assert!(
        (0.8..=1.2).contains(&ratio),
        "following error {:.2} µin RMS against the closed form's {predicted:.2} µin (×{ratio:.3}): {h:?}",
        h.following_error_rms_uin
    );
    // Near-Gaussian: over 3.6 M samples (a few thousand independent ones
    // at the 50 Hz force bandwidth) a Gaussian's largest stays below
    // 6 standard deviations (P ≈ 2·10⁻⁹ each). A spike (a glitch that
    // moved the tool, a fault's transient) does not.
    assert!(
        h.following_error_peak_uin <= 6.0 * h.following_error_rms_uin,
        "{h:?}"
    );
    assert!(h.following_error_peak_uin < 300.0, "{h:?}");
    assert!(h.x_events > 150 && h.index_events > 850, "{h:?}");
    assert!(h.rpm_max - h.rpm_min > 2.0, "speed noise present: {h:?}");
}

/// The following error the design's loop leaves from the soak's force
/// noise and the scenario's broadband gauge noise, µin RMS, in closed form
/// (docs/RELIABILITY.md, "Soak"): the continuous-time loop of
/// `ServoDesign` on a rigid slide of mass m: error dynamics
/// s² + 2ζω_c·s + ω_c² on the observer's estimates, and the triple-pole
/// (s + ω_o)³ position/velocity/disturbance observer whose force estimate
/// is subtracted. Its force-estimate error is
/// E_d/D = s(s² + l₁s + l₂)/(s + ω_o)³ (l₁ = 3ω_o, l₂ = 3ω_o²), the
/// estimate errors drive the loop through its gains, and together
/// Z/D = s·(s² + (3ω_o + 2ζω_c)s + 3ω_o² + ω_c² + 6ζω_cω_o)
///       / (m·(s + ω_o)³·(s² + 2ζω_c·s + ω_c²)),
/// so a slow force leaves an error that grows with its rate (3/ω_o·ḟ over
/// the loop's stiffness), not zero. The gauge noise moves the slide by the
/// complementary sensitivity T = 1 − m·s²·Z/D. Both noises are first-order
/// (Gauss–Markov: the soak's force, the gauge's Ornstein–Uhlenbeck
/// broadband part, `plant::gauge`), one-sided PSD 4σ²a/(a² + ω²) per Hz,
/// a = 2π·bandwidth; the two are independent, so their RMS add in
/// quadrature. The gauge's 120 Hz hum is left out: the hum notch takes it
/// out of the feedback.
fn following_error_rms_predicted_uin(spec: &SoakSpec) -> f64 {
    use std::f64::consts::TAU;
    let d = &spec.scenario.servo_design;
    let m = d.slide.mass_lbf_s2_per_in;
    let (wc, zeta, wo) = (TAU * d.bandwidth_hz, d.damping, TAU * d.observer_hz);
    // Complex numbers as (re, im).
    let mul = |a: (f64, f64), b: (f64, f64)| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
    let div = |a: (f64, f64), b: (f64, f64)| {
        let n = b.0 * b.0 + b.1 * b.1;
        ((a.0 * b.0 + a.1 * b.1) / n, (a.1 * b.0 - a.0 * b.1) / n)
    };
    let quad = |w: f64, b: f64, c: f64| (c - w * w, b * w);
    // Z/D (in/lbf) at s = jω.
    let z_per_d = |w: f64| {
        let num = mul(
            (0.0, w),
            quad(
                w,
                3.0 * wo + 2.0 * zeta * wc,
                3.0 * wo * wo + wc * wc + 6.0 * zeta * wc * wo,
            ),
        );
        let p = (wo, w);
        let den = mul(mul(mul(p, p), p), quad(w, 2.0 * zeta * wc, wc * wc));
        let h = div(num, den);
        (h.0 / m, h.1 / m)
    };
    let psd = |sigma: f64, bw_hz: f64, w: f64| {
        let a = TAU * bw_hz;
        4.0 * sigma * sigma * a / (a * a + w * w)
    };
    let g = &spec.scenario.rig.gauge;
    let (mut force, mut gauge) = (0.0, 0.0);
    // To 100 kHz in 0.5 Hz steps: both integrands have fallen by then.
    let df = 0.5;
    for k in 1..200_000 {
        let w = TAU * k as f64 * df;
        let h = z_per_d(w);
        let t = (1.0 + m * w * w * h.0, m * w * w * h.1);
        force += (h.0 * h.0 + h.1 * h.1) * psd(spec.force_noise_lbf, spec.force_noise_hz, w) * df;
        gauge += (t.0 * t.0 + t.1 * t.1) * psd(g.white_rms_in, g.white_bw_hz, w) * df;
    }
    (force + gauge).sqrt() * 1e6
}

/// The largest phase error of the tachometer + index estimator
/// (`zslide::spindle::tach`), degrees, at speeds up to `rpm_max`:
///
/// * Each index re-phases the angle to its edge, which the soak jitters by
///   j, uniform in ±√3·J (`machine::spindle`): an error ω·j at once.
/// * Each index also recalibrates the tach gain: the turn integrated
///   between two edges is off by ω·(j_k − j_{k−1}) whatever the old gain
///   (its error cancels), and the gain is the mean of the old and that:
///   ε_k = (ε_{k−1} − ω(j_k − j_{k−1})/turn)/2. Over the next turn the
///   angle drifts by ε_k·turn, so just before the next index the error is
///   −ω·(3/2·j_k − Σ_{i≥1} 2^{−(i+1)} j_{k−i}): at most 2·ω·√3·J.
/// * The tachometer's noise (σ_n mV RMS, a new draw each loop tick, `N`
///   ticks a turn) integrates over a turn to σ_n/mV·√N/N turns, and
///   reaches the angle through the same two paths, the variance weights
///   9/4 + Σ 4^{−(i+1)} = 7/3: at 5σ (a per-turn probability below 10⁻⁶)
///   5·√(7/3)·σ_n/(mV·√N) turns.
fn phase_error_bound_deg(spec: &SoakSpec, rpm_max: f64) -> f64 {
    let sp = &spec.scenario.file.spindle;
    let rev_per_s = rpm_max / 60.0;
    let jitter = 2.0 * rev_per_s * 3f64.sqrt() * spec.index_jitter_us * 1e-6;
    let mv = sp.tach_mv_per_rpm * sp.rpm;
    let ticks_per_turn = f64::from(spec.scenario.loop_hz) * 60.0 / sp.rpm;
    let tach = 5.0 * (7.0f64 / 3.0).sqrt() * sp.tach_noise_mv / (mv * ticks_per_turn.sqrt());
    (jitter + tach) * 360.0
}

/// The run is reproducible from the scenario's seed, and another seed
/// gives another run.
#[test]
fn the_same_soak_twice_gives_the_same_summary_and_another_seed_another() {
    let sc = host_sim::scenario::load("modern-hw").unwrap();
    let spec = SoakSpec::new(sc.clone(), 0.01);
    let a = run(&spec, &|_| {}).unwrap();
    let b = run(&spec, &|_| {}).unwrap();
    assert_eq!(format!("{a:?}"), format!("{b:?}"));
    let mut other = sc;
    other.rig.seed ^= 1;
    let c = run(&SoakSpec::new(other, 0.01), &|_| {}).unwrap();
    assert_ne!(
        a[0].following_error_rms_uin, c[0].following_error_rms_uin,
        "another seed, the same run"
    );
}
