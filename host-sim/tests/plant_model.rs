//! The plant against the dissertation's numbers and against closed-form
//! solutions of its linear dynamics.

use host_sim::plant::linear::{LinearSystem, StateSpace};
use host_sim::plant::zslide::st;
use host_sim::plant::{ZSlide, ZSlideParams};
use nalgebra::DMatrix;

/// Real roots of s² + a1 s + a0 by the quadratic formula.
fn quad_roots(a1: f64, a0: f64) -> (f64, f64) {
    let d = (a1 * a1 - 4.0 * a0).sqrt();
    ((-a1 + d) / 2.0, (-a1 - d) / 2.0)
}

#[test]
fn eq_4_33_4_34_poles_from_model14_parameters() {
    // Eq 4-33 is formed with the Model 14 motor (Kf 4.0, Kb 5.52, R 3.2),
    // M = 0.194 slug, L/R = 0.26 ms and B = 51.2 lbf·s/ft.
    let p = ZSlideParams::model14();
    let (a1, a0) = p.eq4_11_denominator();
    assert!((a1 - 4110.1).abs() < 0.1, "s coefficient {a1}");
    assert!((a0 / 1151836.3 - 1.0).abs() < 5e-5, "constant {a0}");
    // numerator in ft/(V s²): inch units are 12× larger
    assert!((p.eq4_11_numerator() / 12.0 - 24781.9).abs() < 0.5);
    // Eigenvalues of the state-space model itself (rigid: the modal
    // states are decoupled at −1, the position integrator at 0).
    let poles: Vec<f64> = p
        .state_space(false)
        .poles()
        .iter()
        .filter(|z| z.re < -10.0)
        .map(|z| z.re)
        .collect();
    assert_eq!(poles.len(), 2);
    assert!((poles[0] + 3807.6).abs() < 0.1, "{poles:?}");
    assert!((poles[1] + 302.5).abs() < 0.1, "{poles:?}");
}

#[test]
fn eq_4_13_without_friction() {
    // B = 0 (the first model): s² + 3846 s + 136791, roots −35.9 and −3810.
    let mut p = ZSlideParams::model14();
    p.b_lbf_s_per_in = 0.0;
    let (a1, a0) = p.eq4_11_denominator();
    assert!((a1 - 3846.0).abs() < 0.5);
    assert!((a0 - 136791.0).abs() < 10.0);
    let (r1, r2) = quad_roots(a1, a0);
    assert!(
        (r1 + 35.9).abs() < 0.05 && (r2 + 3810.0).abs() < 0.5,
        "{r1} {r2}"
    );
}

#[test]
fn model15_plant_and_mode() {
    let p = ZSlideParams::model15();
    // 6.25 lbm in slug, per inch
    assert!((p.mass_lbf_s2_per_in * 12.0 - 0.19426).abs() < 1e-4);
    assert!((p.l_h - 3.64e-4).abs() < 1e-9);
    let poles = p.state_space(false).poles();
    // rigid part: roots of eq 4-11 with the Model 15 numbers
    let (a1, a0) = p.eq4_11_denominator();
    let (r1, r2) = quad_roots(a1, a0);
    for r in [r1, r2] {
        assert!(
            poles
                .iter()
                .any(|z| (z.re - r).abs() < 1e-6 * r.abs() && z.im == 0.0),
            "{r} not in {poles:?}"
        );
    }
    // mode: lightly damped pair at 3150 Hz
    let wp = std::f64::consts::TAU * 3150.0;
    assert!(poles
        .iter()
        .any(|z| ((z.norm() / wp) - 1.0).abs() < 1e-9 && (-z.re / z.norm() - 0.02).abs() < 1e-9));
    // zero pair of the gauge response at 2950 Hz: |force → gauge| vanishes
    // there up to the damping (anti-resonance)
    let sys = p.state_space(true); // current held: force input = Kf i
    let mut x = sys.clone();
    // drive the modal + mechanical part through the external force column
    // as a proxy is wrong (the mode is driven by the motor force only), so
    // use the current state as input: B column = A column of i.
    x.b = DMatrix::from_fn(st::N, 1, |r, _| sys.a[(r, st::I)]);
    x.d = DMatrix::zeros(4, 1);
    // |gauge/current| × f² removes the rigid-body roll-off: its minimum is
    // the zero pair, its maximum the pole pair.
    let h = |f: f64| x.freq_response(std::f64::consts::TAU * f, 0, 0).norm() * f * f;
    let fs: Vec<f64> = (0..=2000).map(|k| 2000.0 + k as f64).collect();
    let fmin = fs
        .iter()
        .copied()
        .min_by(|a, b| h(*a).partial_cmp(&h(*b)).unwrap())
        .unwrap();
    let fmax = fs
        .iter()
        .copied()
        .max_by(|a, b| h(*a).partial_cmp(&h(*b)).unwrap())
        .unwrap();
    assert!((fmin - 2950.0).abs() <= 20.0, "zero pair at {fmin} Hz");
    assert!((fmax - 3150.0).abs() <= 20.0, "pole pair at {fmax} Hz");
    assert!(
        h(fmax) > 3.0 * h(2000.0),
        "lightly damped: peak {} vs {}",
        h(fmax),
        h(2000.0)
    );
}

/// Irregular event spacing: 1 ns .. 1 ms, deterministic.
fn spacings() -> Vec<u64> {
    let mut v = Vec::new();
    let mut s: u64 = 12345;
    for _ in 0..400 {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let e = (s >> 33) % 7; // decade 1 ns .. 1 ms
        let m = 1 + (s >> 40) % 9;
        v.push(m * 10u64.pow(e as u32));
    }
    v
}

fn rel_err(sim: &[f64], exact: &[f64]) -> f64 {
    let peak = exact.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    sim.iter()
        .zip(exact)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / peak
}

#[test]
fn zoh_voltage_step_matches_closed_form() {
    let p = ZSlideParams::model15().rigid();
    let (kf, kb, r, l) = (p.kf_lbf_per_a, p.kb_v_s_per_in, p.r_ohm, p.l_h);
    let (m, b) = (p.mass_lbf_s2_per_in, p.b_lbf_s_per_in);
    let e = 2.0;
    // v(s)/E(s) = (Kf/(ML)) / ((s − p1)(s − p2)); step E/s.
    let (a1, a0) = p.eq4_11_denominator();
    let (p1, p2) = quad_roots(a1, a0);
    let k = kf / (m * l) * e;
    let v = |t: f64| {
        k * (1.0 / (p1 * p2)
            + (p1 * t).exp() / (p1 * (p1 - p2))
            + (p2 * t).exp() / (p2 * (p2 - p1)))
    };
    let z = |t: f64| {
        k * (t / (p1 * p2)
            + ((p1 * t).exp() - 1.0) / (p1 * p1 * (p1 - p2))
            + ((p2 * t).exp() - 1.0) / (p2 * p2 * (p2 - p1)))
    };
    // current from M v' + B v = Kf i
    let vd = |t: f64| k * ((p1 * t).exp() / (p1 - p2) + (p2 * t).exp() / (p2 - p1));
    let i = |t: f64| (m * vd(t) + b * v(t)) / kf;
    let _ = (kb, r);
    let mut s = ZSlide::new(p);
    let mut t_ns = 0u64;
    let (mut sv, mut ev, mut sz, mut ez, mut si, mut ei) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    for dt in spacings() {
        s.step(dt, e, 0.0, false);
        t_ns += dt;
        let t = t_ns as f64 * 1e-9;
        sv.push(s.velocity_in_s());
        ev.push(v(t));
        sz.push(s.position_in());
        ez.push(z(t));
        si.push(s.current_a());
        ei.push(i(t));
    }
    assert!(t_ns > 10_000_000, "covers the slow pole");
    for (name, a, b) in [("v", &sv, &ev), ("z", &sz, &ez), ("i", &si, &ei)] {
        let r = rel_err(a, b);
        assert!(r < 1e-9, "{name}: relative error {r:e}");
    }
}

#[test]
fn zoh_held_current_with_mode_matches_closed_form() {
    // Current held at 3 A: constant motor force F = Kf i on the slide and
    // on the mode; gauge = rigid motion + underdamped modal step.
    let p = ZSlideParams::model15();
    let (m, b, kf) = (p.mass_lbf_s2_per_in, p.b_lbf_s_per_in, p.kf_lbf_per_a);
    let i0 = 3.0;
    let f = kf * i0;
    let alpha = p.mode_alpha();
    let mode = p.mode.unwrap();
    let wn = std::f64::consts::TAU * mode.pole_hz;
    let zeta = mode.zeta;
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    let gauge = |t: f64| {
        let tau = m / b;
        let z = f / b * (t - tau * (1.0 - (-t / tau).exp()));
        let q = alpha * f / (wn * wn)
            * (1.0 - (-zeta * wn * t).exp() * ((wd * t).cos() + zeta * wn / wd * (wd * t).sin()));
        z + q
    };
    let q_only = |t: f64| {
        alpha * f / (wn * wn)
            * (1.0 - (-zeta * wn * t).exp() * ((wd * t).cos() + zeta * wn / wd * (wd * t).sin()))
    };
    let mut s = ZSlide::new(p);
    s.x[st::I] = i0;
    let mut t_ns = 0u64;
    let (mut sim, mut ex, mut sq, mut eq) = (vec![], vec![], vec![], vec![]);
    for dt in spacings().into_iter().take(120) {
        s.step(dt, 0.0, 0.0, true);
        t_ns += dt;
        let t = t_ns as f64 * 1e-9;
        sim.push(s.gauge_position_in());
        ex.push(gauge(t));
        sq.push(s.x[st::Q]);
        eq.push(q_only(t));
        assert_eq!(s.current_a(), i0);
    }
    assert!(rel_err(&sim, &ex) < 1e-9, "gauge {:e}", rel_err(&sim, &ex));
    assert!(rel_err(&sq, &eq) < 1e-9, "mode {:e}", rel_err(&sq, &eq));
}

#[test]
fn zoh_sinusoid_response_matches_closed_form() {
    // Velocity response of the rigid Model 15 plant to E sin ωt from rest,
    // the sinusoid generated exactly by an oscillator appended to the state.
    let p = ZSlideParams::model15().rigid();
    let sys = p.state_space(false);
    let (e, f_hz) = (1.5, 180.0);
    let w = std::f64::consts::TAU * f_hz;
    let n = sys.states();
    let mut a = DMatrix::zeros(n + 2, n + 2);
    a.view_mut((0, 0), (n, n)).copy_from(&sys.a);
    for r in 0..n {
        a[(r, n + 1)] = sys.b[(r, 0)] * e; // input = E · sin
    }
    a[(n, n + 1)] = -w;
    a[(n + 1, n)] = w;
    let aug = LinearSystem::new(
        a,
        DMatrix::zeros(n + 2, 1),
        DMatrix::zeros(1, n + 2),
        DMatrix::zeros(1, 1),
    );
    let (a1, a0) = p.eq4_11_denominator();
    let (p1, p2) = quad_roots(a1, a0);
    let kn = p.eq4_11_numerator();
    let g = |s: nalgebra::Complex<f64>| kn / ((s - p1) * (s - p2));
    let v = |t: f64| {
        let jw = nalgebra::Complex::new(0.0, w);
        let ss = (g(jw) * e * nalgebra::Complex::new(0.0, w * t).exp()).im;
        // residues of G(s) E ω/(s² + ω²) at the plant poles
        let r1 = kn / (p1 - p2) * e * w / (p1 * p1 + w * w);
        let r2 = kn / (p2 - p1) * e * w / (p2 * p2 + w * w);
        ss + r1 * (p1 * t).exp() + r2 * (p2 * t).exp()
    };
    let mut x = nalgebra::DVector::zeros(n + 2);
    x[n] = 1.0;
    let mut t_ns = 0u64;
    let (mut sim, mut ex) = (vec![], vec![]);
    for dt in spacings().into_iter().take(250) {
        let d = aug.zoh(dt as f64 * 1e-9);
        x = &d.phi * &x;
        t_ns += dt;
        sim.push(x[st::V]);
        ex.push(v(t_ns as f64 * 1e-9));
    }
    let r = rel_err(&sim, &ex);
    assert!(r < 1e-9, "relative error {r:e}");
}

#[test]
fn cached_and_uncached_steps_agree() {
    let mut a = ZSlide::new(ZSlideParams::model15());
    let mut b = a.clone();
    for k in 0..50 {
        let e = if k % 7 < 3 { 1.0 } else { -0.5 };
        a.step(50_000, e, 0.3, false);
        b.step_uncached(50e-6, e, 0.3, false);
    }
    for k in 0..st::N {
        assert!((a.x[k] - b.x[k]).abs() <= 1e-12 * a.x[k].abs().max(1e-9));
    }
    assert_eq!(a.expm_count(), 1);
}
