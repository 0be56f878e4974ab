//! `zslide tune`'s predicted margins against a closed form the code under
//! test does not build, and its refusal of a design below the minimums.
//!
//! The closed form (continuous time, written out here from the design's
//! documented laws, `zslide::servo::design` and `::observer`):
//!
//! ```text
//! plant       P(s) = G·g·Kf / (s·((M s + B)(L s + R) + Kf·Kb)) · mode(s)
//! controller  observer x̂' = (A − L C) x̂ + B u + L y,  x = [z, v, d]
//!             A = [[0, 1, 0], [0, −a, K], [0, 0, 0]], B = [0, K, 0]ᵀ, C = [1, 0, 0]
//!             L: the triple pole at −ωₒ: l1 = 3ωₒ − a, l2 = 3ωₒ² − a·l1, l3 = ωₒ³/K
//!             u = −N(s)·F x̂,  F = [ω²/K, (2ζω − a)/K, 1],  N = hum canceller · mode notch
//!             (the observer sees the DAC code written, after the notches)
//!             ⇒ C(s) = N·FΦL / (1 + N·FΦB),  Φ = (sI − A + LC)⁻¹
//! loop        L(jω) = P·C·e^{−jω(d + h/2)}   (DAC latency d, zero-order hold h/2)
//! ```
//!
//! K and a are the design's model of the slide (its own mass and gain);
//! P is the fitted plant with the data sheet's motor, electrical pole
//! included (the design neglects it). The notches are the analog
//! prototypes (s² + ω₀²)/(s² + ω₀/Q·s + ω₀²); the mode is the pole/zero
//! pair of docs/PLANT.md (the zero damped like the pole: below 400 Hz its
//! share is under 0.01 dB).
//!
//! Tolerance, derived: the firmware samples this loop at h = 1/rate_hz;
//! the delays of the sampling are in the closed form (ZOH as h/2), what is
//! left is the sampled estimator and notches against their continuous
//! models, a relative error of at most ω·h at the frequency read (first
//! order: one step of the model's prediction over h). At a crossover fc
//! that is 2π·fc·h in phase (rad) and in relative frequency; at the phase
//! crossover fp, 20·log10(1 + 2π·fp·h) dB of gain and 2π·fp·h in relative
//! frequency; the gain margin also moves by |L|'s slope (dB/Hz) times
//! the shift of the crossing that a phase error of ω·h makes (ω·h over
//! the phase's slope, rad/Hz): steep beside a narrow notch, where the
//! crossing can fall. (legacy-hw at 20 kHz: 1.7° and 3 % at 94 Hz.)

use std::f64::consts::TAU;
use std::time::Duration;

use nalgebra::{Complex, Matrix3, Vector3};
use zslide::servo::design::ServoDesign;
use zslide_host::cli::run_line;
use zslide_host::client::Link;
use zslide_host::fit::Plant;
use zslide_host::identify::{design_on, known_from_scenario, plant_text};
use zslide_host::predict::{check_margins, margins, MIN_GAIN_MARGIN_DB, MIN_PHASE_MARGIN_DEG};
use zslide_plant::slide::ZSlideParams;

mod machine;
use machine::Machine;

type C = Complex<f64>;

/// A notch at `f0` of quality `q`, its poles turned by `turn_rad` (the
/// hum canceller, `zslide::servo::filters::Canceller`; 0: the plain
/// notch): the continuous prototype `(s² + ω₀²) / ((1 − sin θ / Q) s² +
/// (ω₀/Q) cos θ · s + ω₀²)`.
fn notch(s: C, f0: f64, q: f64, turn_rad: f64) -> C {
    if q == 0.0 {
        return C::new(1.0, 0.0);
    }
    let w0 = TAU * f0;
    (s * s + w0 * w0)
        / (s * s * (1.0 - turn_rad.sin() / q) + s * (w0 / q * turn_rad.cos()) + w0 * w0)
}

/// L(j2πf) of `d` on the data sheet `sheet` with the fit `p`.
fn loop_gain(d: &ServoDesign, sheet: &ZSlideParams, p: &Plant, f: f64) -> C {
    let s = C::new(0.0, TAU * f);
    let h = 1.0 / f64::from(d.rate_hz);
    // The design's model of the slide (its own parameters).
    let m = &d.slide;
    let k = m.amp_gain * m.kf_lbf_per_a / (m.r_ohm * m.mass_lbf_s2_per_in) * m.gauge_v_per_in;
    let a = (m.b_lbf_s_per_in + m.kf_lbf_per_a * m.kb_v_s_per_in / m.r_ohm) / m.mass_lbf_s2_per_in;
    let w = TAU * d.bandwidth_hz;
    let wo = TAU * d.observer_hz;
    let (l1, f1) = (3.0 * wo - a, w * w / k);
    let l = Vector3::new(l1, 3.0 * wo * wo - a * l1, wo * wo * wo / k).map(|x| C::new(x, 0.0));
    let fb = Vector3::new(f1, (2.0 * d.damping * w - a) / k, 1.0).map(|x| C::new(x, 0.0));
    let b = Vector3::new(0.0, k, 0.0).map(|x| C::new(x, 0.0));
    let a_lc = Matrix3::new(-l[0].re, 1.0, 0.0, -l[1].re, -a, k, -l[2].re, 0.0, 0.0);
    let phi = (Matrix3::from_diagonal_element(s) - a_lc.map(|x| C::new(x, 0.0)))
        .try_inverse()
        .unwrap();
    let n = notch(
        s,
        d.hum_notch_hz,
        d.hum_notch_q,
        d.hum_notch_turn_deg.to_radians(),
    ) * notch(s, d.mode_notch_hz, d.mode_notch_q, 0.0);
    let fpl = (fb.transpose() * phi * l)[0];
    let fpb = (fb.transpose() * phi * b)[0];
    let ctrl = n * fpl / (C::new(1.0, 0.0) + n * fpb);
    // The fitted plant: the data sheet's motor with the fit's gain, mass
    // and mode.
    let (mm, gauge) = (p.mass_lbf_s2_per_in, d.slide.gauge_v_per_in);
    let el = (s * mm + sheet.b_lbf_s_per_in) * (s * sheet.l_h + sheet.r_ohm)
        + sheet.kf_lbf_per_a * sheet.kb_v_s_per_in;
    let mut plant = p.amp_gain * gauge * sheet.kf_lbf_per_a / (s * el);
    let (wp, wz, z) = (TAU * p.mode_pole_hz, TAU * p.mode_zero_hz, p.mode_zeta);
    plant *= (wp * wp / (wz * wz)) * (s * s + s * (2.0 * z * wz) + wz * wz)
        / (s * s + s * (2.0 * z * wp) + wp * wp);
    plant * ctrl * (-s * (p.delay_s + h / 2.0)).exp()
}

/// Crossover (Hz), phase margin (deg), and the first −180° crossing above
/// the crossover (Hz) with its gain margin (dB), as `host_sim`'s margins
/// define them, read off 20 000 log-spaced points and bisected.
fn closed_form(d: &ServoDesign, sheet: &ZSlideParams, p: &Plant) -> (f64, f64, Option<(f64, f64)>) {
    let l = |f: f64| loop_gain(d, sheet, p, f);
    let n = 20_000;
    let fs: Vec<f64> = (0..n)
        .map(|i| 10.0 * 640f64.powf(i as f64 / (n - 1) as f64))
        .collect();
    let mut ph = Vec::with_capacity(n);
    for (i, &f) in fs.iter().enumerate() {
        let raw = l(f).arg().to_degrees();
        ph.push(if i == 0 {
            raw
        } else {
            let prev: f64 = ph[i - 1];
            raw - 360.0 * ((raw - prev) / 360.0).round()
        });
    }
    let bisect = |mut lo: f64, mut hi: f64, above: &dyn Fn(f64) -> bool| {
        let want = above(lo);
        for _ in 0..60 {
            let mid = (lo * hi).sqrt();
            if above(mid) == want {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        (lo * hi).sqrt()
    };
    let i = (1..n)
        .find(|&i| l(fs[i - 1]).norm() >= 1.0 && l(fs[i]).norm() < 1.0)
        .expect("no crossover");
    let fc = bisect(fs[i - 1], fs[i], &|f| l(f).norm() >= 1.0);
    // The phase there, unwrapped next to the bracket's.
    let unwrapped = |f: f64, near: f64| {
        let raw = l(f).arg().to_degrees();
        raw - 360.0 * ((raw - near) / 360.0).round()
    };
    let pm = 180.0 + unwrapped(fc, ph[i - 1]);
    let pc = (i + 1..n)
        .find(|&j| (ph[j - 1] + 180.0 > 0.0) != (ph[j] + 180.0 > 0.0))
        .map(|j| {
            let near = ph[j - 1];
            let f = bisect(fs[j - 1], fs[j], &|f| unwrapped(f, near) + 180.0 > 0.0);
            (f, -20.0 * l(f).norm().log10())
        });
    (fc, pm, pc)
}

/// `tune`'s prediction for `d` on `p` against the closed form, within the
/// tolerances derived in the module docs; the two margins returned.
fn agrees(what: &str, d: &ServoDesign, p: &Plant) -> (f64, f64) {
    let (known, _) = known_from_scenario("legacy-hw").unwrap();
    let sheet = host_sim::scenario::load("legacy-hw").unwrap();
    let h = 1.0 / f64::from(d.rate_hz);
    let m = margins(&sheet, p, d).unwrap();
    let (fc, pm, pc) = closed_form(d, &known.slide, p);
    eprintln!("{what}: predicted {m:?}; closed form crossover {fc:.2} Hz, PM {pm:.2}, {pc:?}");
    let got_fc = m.crossover_hz.unwrap();
    let wh = TAU * fc * h;
    assert!(
        (got_fc / fc - 1.0).abs() <= wh,
        "{what}: crossover {got_fc} vs {fc} (±{wh})"
    );
    let got_pm = m.phase_margin_deg.unwrap();
    assert!(
        (got_pm - pm).abs() <= wh.to_degrees(),
        "{what}: phase margin {got_pm} vs {pm} (±{:.2}°)",
        wh.to_degrees()
    );
    let (fp, gm) = pc.expect("a phase crossover above the crossover");
    let got_fp = m.phase_crossover_hz.unwrap();
    let got_gm = m.gain_margin_db.unwrap();
    let wh = TAU * fp * h;
    assert!(
        (got_fp / fp - 1.0).abs() <= wh,
        "{what}: phase crossover {got_fp} vs {fp} (±{wh})"
    );
    // The gain there moves by the relative error itself, and by the slope
    // of |L| over the shift of the crossing that a phase error of ω·h
    // makes (steep beside a narrow notch).
    let l = |f: f64| loop_gain(d, &known.slide, p, f);
    let df = fp * 1e-5;
    let slope_db = 20.0 * (l(fp + df).norm() / l(fp - df).norm()).log10() / (2.0 * df);
    let dphase = {
        let d = (l(fp + df) / l(fp - df)).arg();
        d / (2.0 * df)
    };
    let shift_hz = wh / dphase.abs();
    let db = 20.0 * (1.0 + wh).log10() + slope_db.abs() * shift_hz;
    assert!(
        (got_gm - gm).abs() <= db,
        "{what}: gain margin {got_gm} vs {gm} (±{db:.2} dB)"
    );
    (pm, gm)
}

/// The data sheet's plant and design, a machine 15 % weaker and 10 %
/// heavier with its mode 5 % higher (the commissioning test's) under the
/// design in force and under the design `tune` makes for it.
#[test]
fn the_predicted_margins_match_the_continuous_time_loop_of_the_design() {
    let sheet = host_sim::scenario::load("legacy-hw").unwrap();
    let (_, start) = known_from_scenario("legacy-hw").unwrap();
    let nominal = sheet.servo_design;
    agrees("data sheet", &nominal, &start);
    let fit = Plant {
        amp_gain: start.amp_gain * 0.85,
        mass_lbf_s2_per_in: start.mass_lbf_s2_per_in * 1.10,
        mode_pole_hz: start.mode_pole_hz * 1.05,
        mode_zero_hz: start.mode_zero_hz * 1.05,
        ..start
    };
    agrees("perturbed, design in force", &nominal, &fit);
    let mut tuned = nominal;
    for (name, v) in zslide_host::identify::tuned(&fit) {
        zslide::params::by_name(name).unwrap().set(&mut tuned, v);
    }
    agrees("perturbed, tuned", &tuned, &fit);
}

/// The minimums in force, each side of them.
#[test]
fn margins_below_the_minimums_are_refused() {
    use host_sim::cmd::response::Margins;
    let m = |pm: f64, gm: Option<f64>| Margins {
        crossover_hz: Some(90.0),
        phase_margin_deg: Some(pm),
        phase_crossover_hz: gm.map(|_| 270.0),
        gain_margin_db: gm,
        peak_sensitivity_db: 6.0,
    };
    assert!(check_margins(&m(
        MIN_PHASE_MARGIN_DEG + 0.1,
        Some(MIN_GAIN_MARGIN_DB + 0.1)
    ))
    .is_ok());
    assert!(check_margins(&m(MIN_PHASE_MARGIN_DEG + 0.1, None)).is_ok());
    let e = check_margins(&m(MIN_PHASE_MARGIN_DEG - 0.1, Some(20.0))).unwrap_err();
    assert!(e.contains("phase margin"), "{e}");
    let e = check_margins(&m(40.0, Some(MIN_GAIN_MARGIN_DB - 0.1))).unwrap_err();
    assert!(e.contains("gain margin"), "{e}");
    let none = Margins {
        crossover_hz: None,
        phase_margin_deg: None,
        ..m(40.0, None)
    };
    assert!(check_margins(&none).is_err());
}

/// A machine running a design whose margins are below the minimums
/// (TUNING.md's 80 Hz / 400 Hz / hum Q 8 row on legacy-hw, 18°): `tune`
/// with the data sheet's own plant predicts it, the closed form agrees it
/// is below the minimum, and `tune` refuses and sets nothing.
#[test]
fn tune_refuses_a_design_below_the_minimum_margins_and_sets_nothing() {
    let mut sc = host_sim::scenario::load("legacy-hw").unwrap();
    sc.servo_design.bandwidth_hz = 80.0;
    sc.servo_design.observer_hz = 400.0;
    sc.servo_design.hum_notch_q = 8.0;
    // The plain notch (the canceller's poles not turned), as in that row.
    sc.servo_design.hum_notch_turn_deg = 0.0;
    sc.servo = sc.servo_design.config().unwrap();
    let (known, start) = known_from_scenario("legacy-hw").unwrap();
    let (_, pm, _) = closed_form(&sc.servo_design, &known.slide, &start);
    assert!(pm < MIN_PHASE_MARGIN_DEG, "closed form {pm:.1}°");

    let dir =
        std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/zslide-host-test");
    std::fs::create_dir_all(&dir).unwrap();
    let plant = dir.join("tune-refused.plant");
    std::fs::write(&plant, plant_text(&start, "legacy-hw")).unwrap();
    let m = Machine::start("tune-refused", host_sim::serve::Setup::new(sc.clone()));
    let mut link = Link::new(&m.addr, Duration::from_secs(10));
    let before = design_on(link.client().unwrap()).unwrap();
    let e = run_line(&mut link, &format!("tune {}", plant.display())).unwrap_err();
    assert!(
        e.contains("phase margin") && e.contains("nothing set"),
        "{e}"
    );
    let after = design_on(link.client().unwrap()).unwrap();
    assert_eq!(format!("{before:?}"), format!("{after:?}"));
    assert_eq!(after.bandwidth_hz, 80.0);
}
