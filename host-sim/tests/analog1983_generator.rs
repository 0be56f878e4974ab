//! The 1983 command generator's error sources (`analog1983::generator`),
//! the circuit stepped in time against the closed forms derived from it.
//!
//! With the tachometer steady at `E` the two multiplied integrators obey
//! `dc/dt = −a(E+e₁)s`, `ds/dt = a(E+e₂)c`; from the reset (s = 0,
//! c = c₀) the sine is `s(t) = c₀ √((E+e₂)/(E+e₁)) sin(a √((E+e₁)(E+e₂)) t)`.
//! The shop trimmed `a` and `c₀` at the calibration tach voltage
//! `E_c = 5 V` (300 rpm) for one turn per revolution and 10 V. So at the
//! spindle speed Ω, with θ the spindle's angle since the index and `t_r`
//! the reset pulse:
//!
//! ```text
//! s/10 V = g sin(r (θ − Ω t_r)),   E = E_c (1 + ε) Ω/Ω_c,
//! g = √((E+e₂)(E_c+e₁) / ((E+e₁)(E_c+e₂))),
//! r = (Ω_c/Ω) √((E+e₁)(E+e₂) / ((E_c+e₁)(E_c+e₂)))
//! ```
//!
//! (ε the tachometer's rate error, `e₁ = +m/2`, `e₂ = −m/2`). To first
//! order `g ≈ 1 + m(1/E_c − 1/E)/2` and `r ≈ 1 + ε`.

use host_sim::analog1983::generator::{command_v, GeneratorLevels, SineGenerator};
use std::f64::consts::TAU;

const DT: f64 = 100e-6;

/// The sine over `revs` revolutions at `rpm`, ticks of 100 µs, reset at
/// every index when `reset`: (spindle angle since the last index, rad,
/// sine as a fraction of 10 V) at each tick.
fn run(lv: GeneratorLevels, rpm: f64, revs: f64, reset: bool) -> Vec<(f64, f64)> {
    let mut g = SineGenerator::new(lv);
    g.index();
    let omega = rpm / 60.0 * TAU;
    let n = (revs * TAU / omega / DT).round() as usize;
    let mut out = Vec::with_capacity(n);
    let mut turns = 0.0f64;
    for _ in 0..n {
        let next = turns + omega * DT / TAU;
        if reset && next.floor() > turns.floor() {
            let w = (turns.floor() + 1.0 - turns) / (next - turns);
            g.advance(w * DT, rpm);
            g.index();
            g.advance((1.0 - w) * DT, rpm);
        } else {
            g.advance(DT, rpm);
        }
        turns = next;
        let since = if reset { turns - turns.floor() } else { turns };
        out.push((since * TAU, g.sine()));
    }
    out
}

fn closed_form(lv: &GeneratorLevels, rpm: f64) -> (f64, f64) {
    let ec = 5.0;
    let (e1, e2) = (lv.multiplier_offset_v / 2.0, -lv.multiplier_offset_v / 2.0);
    let e = ec * (1.0 + lv.tach_rate_error) * rpm / lv.calibrated_rpm;
    let g = ((e + e2) * (ec + e1) / ((e + e1) * (ec + e2))).sqrt();
    let r = (lv.calibrated_rpm / rpm) * ((e + e1) * (e + e2) / ((ec + e1) * (ec + e2))).sqrt();
    (g, r)
}

fn worst(samples: &[(f64, f64)], f: impl Fn(f64) -> f64) -> f64 {
    samples
        .iter()
        .map(|&(th, s)| (s - f(th)).abs())
        .fold(0.0, f64::max)
}

#[test]
fn a_tach_rate_error_eps_turns_the_sine_through_1_plus_eps_times_the_spindle_angle() {
    let eps = 0.01;
    let lv = GeneratorLevels {
        tach_rate_error: eps,
        ..GeneratorLevels::ideal(300.0)
    };
    let s = run(lv, 300.0, 0.999, true);
    let w = worst(&s, |th| ((1.0 + eps) * th).sin());
    assert!(w < 1e-6, "sine against sin((1+ε)θ): {w:.2e}");
    // The error against the spindle's sine grows to ≈ 2πε by the end of
    // the revolution (the sawtooth the reset cuts off).
    let end = s.last().unwrap();
    let err = end.1 - end.0.sin();
    let expect = ((1.0 + eps) * end.0).sin() - end.0.sin();
    assert!(
        (err - expect).abs() < 1e-6 && expect.abs() > 0.05,
        "end of revolution: {err:.4} against {expect:.4}"
    );
}

#[test]
fn the_index_reset_keeps_the_tach_error_to_one_revolution() {
    let eps = 0.01;
    let lv = GeneratorLevels {
        tach_rate_error: eps,
        ..GeneratorLevels::ideal(300.0)
    };
    // Twenty revolutions, reset at each index: the last revolution is the
    // first one again, sin((1+ε)θ), θ since its index.
    let s = run(lv, 300.0, 19.999, true);
    let last: Vec<(f64, f64)> = s[s.len() - s.len() / 20..].to_vec();
    let w = worst(&last, |th| ((1.0 + eps) * th).sin());
    assert!(w < 1e-6, "20th revolution with the reset: {w:.2e}");
    // Without the reset the angle error accumulates: 20·2π·ε = 72° by the
    // twentieth revolution, sin((1+ε)θ) with θ the whole angle.
    let free = run(lv, 300.0, 19.999, false);
    let w = worst(&free, |th| ((1.0 + eps) * th).sin());
    assert!(w < 1e-5, "free running against sin((1+ε)θ): {w:.2e}");
    let drift = worst(&free[free.len() - free.len() / 20..], |th| {
        ((1.0 + eps) * (th - th.div_euclid(TAU) * TAU)).sin()
    });
    assert!(
        drift > 0.9,
        "free running drifts from the one-revolution error: {drift:.3}"
    );
}

#[test]
fn the_reset_pulse_delays_the_sine_by_the_angle_the_spindle_turns_during_it() {
    let t_r = 1e-3;
    let lv = GeneratorLevels {
        reset_hold_s: t_r,
        ..GeneratorLevels::ideal(300.0)
    };
    for rpm in [300.0, 360.0] {
        let lag = rpm / 60.0 * TAU * t_r;
        let s = run(lv, rpm, 0.999, true);
        let w = worst(&s, |th| if th < lag { 0.0 } else { (th - lag).sin() });
        // The tick that ends inside the pulse is within one tick's turn.
        let tick = rpm / 60.0 * TAU * DT;
        assert!(w < tick, "{rpm} rpm: against sin(θ − Ωt_r): {w:.2e}");
        let w_after = worst(
            &s.iter()
                .copied()
                .filter(|&(th, _)| th > lag + tick)
                .collect::<Vec<_>>(),
            |th| (th - lag).sin(),
        );
        assert!(w_after < 1e-6, "{rpm} rpm after the pulse: {w_after:.2e}");
    }
}

#[test]
fn an_amplitude_trimmed_at_300_rpm_has_gain_g_at_360_rpm() {
    let m = 0.5;
    let lv = GeneratorLevels {
        multiplier_offset_v: m,
        ..GeneratorLevels::ideal(300.0)
    };
    let (g300, r300) = closed_form(&lv, 300.0);
    assert!((g300 - 1.0).abs() < 1e-15 && (r300 - 1.0).abs() < 1e-15);
    let s = run(lv, 300.0, 0.999, true);
    assert!(
        worst(&s, f64::sin) < 1e-6,
        "at the calibration speed the sine is exact"
    );

    let (g, r) = closed_form(&lv, 360.0);
    // First order: g − 1 ≈ m (1/5 − 1/6)/2 = m/60 (+0.83 % here).
    assert!((g - 1.0 - m / 60.0).abs() < 1e-4, "g = {g}");
    let s = run(lv, 360.0, 0.999, true);
    let w = worst(&s, |th| g * (r * th).sin());
    assert!(w < 1e-6, "360 rpm against g·sin(rθ): {w:.2e}");
    let peak = s.iter().map(|p| p.1).fold(f64::MIN, f64::max);
    assert!((peak - g).abs() < 1e-5, "peak {peak} against g = {g}");
}

/// The command of the multiplier network with the scenario's generator at
/// the shop's 360 rpm, C0j at the part's edge (chapter 3's maxima), against
/// `Σ C0j (g sin(r(θ − Ωt_r)))^j`.
#[test]
fn the_1983_command_at_360_rpm_carries_the_gain_and_phase_of_its_sine() {
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    let lv = host_sim::cut::command1983::levels(&sc.file.errors)
        .expect("legacy-hw states the generator");
    let rpm = 360.0;
    let (g, r) = closed_form(&lv, rpm);
    let lag = rpm / 60.0 * TAU * lv.reset_hold_s;
    // C00..C03 at X = 7.25 in, mil = V (chapter 3).
    let c = [-0.1195, -1.6976, -6.0195, 0.0514];
    let s = run(lv, rpm, 0.999, true);
    let tick = rpm / 60.0 * TAU * DT;
    let mut worst_uin = 0.0f64;
    let mut peak_err_uin = 0.0f64;
    for &(th, sv) in s.iter().filter(|p| p.0 > lag + tick) {
        let z = command_v(c, sv);
        let expect = command_v(c, g * (r * (th - lag)).sin());
        worst_uin = worst_uin.max((z - expect).abs() * 1e3);
        peak_err_uin = peak_err_uin.max((z - command_v(c, th.sin())).abs() * 1e3);
    }
    assert!(
        worst_uin < 0.01,
        "against the closed form: {worst_uin:.4} µin"
    );
    eprintln!(
        "360 rpm, the scenario's generator: g − 1 = {:.4} %, r − 1 = {:.4} %, reset lag {:.3}°; \
         command error against the ideal generator up to {peak_err_uin:.1} µin",
        (g - 1.0) * 100.0,
        (r - 1.0) * 100.0,
        lag.to_degrees()
    );
}
