//! The servo's integer gains against their closed form, computed here from
//! the brief's physical numbers (chapter 4, `docs/PLANT.md`), not from the
//! design code's own helpers: a change to the plant constants, the units,
//! the law or the fixed-point scaling shows up as a mismatch.
//!
//! The law (`zslide::servo::design`): with the rigid plant
//! P(s) = K / (s (s + a)) in gauge codes per DAC code,
//!
//! ```text
//! u = (r̈ + a ṙ)/K + (ω²/K)(r − ẑ) + ((2ζω − a)/K)(ṙ − v̂) − d̂
//! ```
//!
//! so the error obeys ë + 2ζω ė + ω² e = 0. Per loop tick h (velocities in
//! codes per tick, accelerations in codes per tick²):
//! kp = ω²/K, kd = (2ζω − a)/(K h), kff = a/(K h), ka = 1/(K h²).

use zslide::servo::ServoDesign;

/// The brief's slide in its own units, converted here.
struct Brief {
    /// K, gauge codes per DAC code per s².
    k: f64,
    /// a, 1/s.
    a: f64,
}

fn brief() -> Brief {
    // Model 15 motor: Kf 2.9 lbf/A, Kb 4.002 V·s/ft, R 1.4 Ω; 6.25 lbm
    // moving; air film 51.2 lbf·s/ft; ×10 amplifier; gauge 1 V per mil.
    let kf = 2.9; // lbf/A
    let kb = 4.002 / 12.0; // V·s/in
    let r = 1.4; // Ω
    let m = 6.25 / 32.174 / 12.0; // lbf·s²/in (lbm → slug → per inch)
    let b = 51.2 / 12.0; // lbf·s/in
    let g_amp = 10.0; // V/V
    let gauge_v_per_in = 1000.0;
    // DAC and ADC both 2¹⁹ codes per 10 V: a DAC code is a gauge code's
    // volt, so the codes cancel and K is in gauge V per DAC V per s².
    let dac_codes_per_v = f64::from(1u32 << 19) / 10.0;
    let adc_codes_per_v = f64::from(1u32 << 19) / 10.0;
    let k = g_amp * kf / (r * m) * gauge_v_per_in * adc_codes_per_v / dac_codes_per_v;
    let a = (b + kf * kb / r) / m;
    Brief { k, a }
}

/// 45 Hz error dynamics, ζ 0.9, at 20 kHz: the brief's design.
#[test]
fn gains_are_the_closed_form_of_45_hz_and_zeta_0_9_on_the_briefs_slide() {
    let p = brief();
    let (fs, f_n, zeta) = (20_000.0, 45.0, 0.9);
    let h = 1.0 / fs;
    let w = std::f64::consts::TAU * f_n;
    let kp = w * w / p.k;
    let kd = (2.0 * zeta * w - p.a) / (p.k * h);
    let kff = p.a / (p.k * h);
    let ka = 1.0 / (p.k * h * h);

    // The design's inputs are the brief's: if they were not, the gains
    // below could agree by accident of another plant.
    let d = ServoDesign::brief(20_000);
    assert_eq!((d.bandwidth_hz, d.damping), (f_n, zeta));
    let cfg = d.config().unwrap();

    // Each gain is rounded once to its format (Q24, Q16): within half an
    // LSB of the exact value, plus the f64 ordering's few ulps.
    let q24 = f64::from(1u32 << 24);
    let q16 = f64::from(1u32 << 16);
    for (name, got, want) in [
        ("kp_q24", cfg.kp_q24, kp * q24),
        ("kd_q24", cfg.kd_q24, kd * q24),
        ("kff_q24", cfg.kff_q24, kff * q24),
        ("ka_q16", cfg.ka_q16, ka * q16),
    ] {
        assert!(
            (f64::from(got) - want).abs() <= 0.5 + want.abs() * 1e-12,
            "{name}: {got} against the closed form {want:.3}"
        );
    }
    // The fast-observer gains: the same law at 150 Hz.
    let wf = std::f64::consts::TAU * d.bandwidth_fast_hz;
    assert_eq!(d.bandwidth_fast_hz, 150.0);
    let kp_fast = wf * wf / p.k * q24;
    let kd_fast = (2.0 * zeta * wf - p.a) / (p.k * h) * q24;
    assert!((f64::from(cfg.kp_fast_q24) - kp_fast).abs() <= 0.5 + kp_fast * 1e-12);
    assert!((f64::from(cfg.kd_fast_q24) - kd_fast).abs() <= 0.5 + kd_fast.abs() * 1e-12);
}

/// The numbers themselves, by hand from the closed form (so that a wrong
/// plant constant in both the design and the function above would still
/// show): K = 10·2.9/(1.4·0.016188)·1000 = 1.2796e6 codes/code/s²,
/// a = (4.2667 + 2.9·0.3335/1.4)/0.016188 = 306.24 1/s; at 45 Hz:
/// kp = (282.74)²/K = 0.06248, kd = (2·0.9·282.74 − 306.24)/(K/20 000)
/// = 3.168, kff = 306.3·20 000/K = 4.787, ka = 20 000²/K = 312.6.
#[test]
fn gains_match_the_hand_computed_values() {
    let cfg = ServoDesign::brief(20_000).config().unwrap();
    let q24 = f64::from(1u32 << 24);
    let q16 = f64::from(1u32 << 16);
    for (name, got, want) in [
        ("kp", f64::from(cfg.kp_q24) / q24, 0.06248),
        ("kd", f64::from(cfg.kd_q24) / q24, 3.168),
        ("kff", f64::from(cfg.kff_q24) / q24, 4.787),
        ("ka", f64::from(cfg.ka_q16) / q16, 312.6),
    ] {
        // Four significant figures in the hand computation.
        assert!(
            ((got - want) / want).abs() < 1e-3,
            "{name}: {got} against {want}"
        );
    }
}
