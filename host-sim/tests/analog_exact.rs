//! The 1983 loop's exact closed-loop steps (`analog1983::AnalogDrive`)
//! against independent references: the co-simulation at a fine substep
//! (deterministic response), the stationary covariance of the continuous
//! loop from its Lyapunov equation (noise response), and the hand-over to
//! the co-simulation when the loop leaves its linear range.

use host_sim::analog1983::{close_loop, AnalogDrive, PositionLoop1983};
use host_sim::plant::zslide::st;
use host_sim::plant::{GaugeParams, Rig, RigConfig};
use nalgebra::DMatrix;

fn rig(gauge: GaugeParams) -> Rig {
    let mut r = Rig::new(RigConfig {
        gauge,
        ..RigConfig::legacy(7)
    });
    // The 1983 loop owns the amplifier: enabled from the start.
    r.amp.set_enabled(true);
    r
}

/// Runs the drive for `ticks` loop periods of 50 µs with the reference
/// `r(t)` held per period; the slide position at each period's end.
fn run(drive: &mut AnalogDrive, rig: &mut Rig, ticks: u64, r: impl Fn(f64) -> f64) -> Vec<f64> {
    let mut z = Vec::new();
    for k in 0..ticks {
        drive.reference_v = r(k as f64 * 50e-6);
        drive.advance(rig, (k + 1) * 50_000);
        z.push(rig.slide.x[st::Z]);
    }
    z
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn exact_steps_follow_the_finely_co_simulated_loop_without_noise() {
    let sine = |t: f64| 0.5 * (std::f64::consts::TAU * 40.0 * t).sin();
    let ticks = 4000;
    let mut ra = rig(GaugeParams::noiseless());
    let mut exact = AnalogDrive::position_loop(&ra, true, 1);
    let ze = run(&mut exact, &mut ra, ticks, sine);
    assert!(exact.is_exact() && exact.nonlinear_spells == 0);
    // The co-simulation samples the gauge and holds the controller output
    // every substep: it tends to the continuous loop as the substep shrinks.
    let mut errs = Vec::new();
    for sub in [5_000u64, 1_000, 200] {
        let mut rb = rig(GaugeParams::noiseless());
        let mut co = AnalogDrive::position_loop(&rb, false, 1);
        co.ctrl.substep_ns = sub;
        let zc = run(&mut co, &mut rb, ticks, sine);
        errs.push(max_abs_diff(&ze, &zc));
    }
    // 0.5 V = 0.5 mil amplitude; the differences in µin.
    let uin: Vec<f64> = errs.iter().map(|e| e * 1e6).collect();
    assert!(
        // Measured: 0.45, 0.08, 0.016 µin: the co-simulation's error is
        // first order in its substep and goes to zero.
        uin[2] < 0.05 && uin[0] > 10.0 * uin[2] && uin[1] < uin[0],
        "exact vs co-simulation at 5, 1, 0.2 µs: {uin:?} µin"
    );
}

/// Stationary covariance P of `x' = A x + G w` (A P + P Aᵀ + G Gᵀ = 0),
/// by the Kronecker form.
fn lyapunov(a: &DMatrix<f64>, g: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.nrows();
    let id = DMatrix::<f64>::identity(n, n);
    let k = id.kronecker(a) + a.kronecker(&id);
    let q = g * g.transpose();
    let rhs = nalgebra::DVector::from_iterator(n * n, q.iter().map(|v| -v));
    let p = k.lu().solve(&rhs).expect("a stable loop");
    DMatrix::from_column_slice(n, n, p.as_slice())
}

#[test]
fn exact_noise_response_has_the_continuous_loops_stationary_variance() {
    // White gauge noise only (the hum is deterministic): 10 µin RMS in a
    // 5 kHz first-order band.
    let gauge = GaugeParams {
        white_rms_in: 10e-6,
        hum_amp_in: 0.0,
        hum2_amp_in: 0.0,
        ..GaugeParams::legacy()
    };
    // The reference: `close_loop` (the frequency-domain closed loop,
    // inputs [r, f, gauge noise in]) with the noise filter appended.
    let p = RigConfig::legacy(7).slide;
    let cl = close_loop(&p, 10.0, &PositionLoop1983::default().controller());
    let n = cl.states();
    let tau = 1.0 / (std::f64::consts::TAU * gauge.white_bw_hz);
    let mut a = DMatrix::zeros(n + 1, n + 1);
    a.view_mut((0, 0), (n, n)).copy_from(&cl.a);
    a.view_mut((0, n), (n, 1)).copy_from(&cl.b.column(2));
    a[(n, n)] = -1.0 / tau;
    let mut g = DMatrix::zeros(n + 1, 1);
    g[(n, 0)] = gauge.white_rms_in * (2.0 / tau).sqrt();
    let cov = lyapunov(&a, &g);
    let want_rms = cov[(st::Z, st::Z)].sqrt();

    let mut r = rig(gauge);
    let mut drive = AnalogDrive::position_loop(&r, true, 11);
    let z = run(&mut drive, &mut r, 400_000, |_| 0.0);
    assert!(drive.is_exact());
    let z = &z[2000..];
    let mean = z.iter().sum::<f64>() / z.len() as f64;
    let rms = (z.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / z.len() as f64).sqrt();
    // 20 s against a correlation time of a few ms: ≈ 1 % statistical.
    assert!(
        (rms / want_rms - 1.0).abs() < 0.05,
        "slide noise {:.4} µin RMS, Lyapunov {:.4} µin",
        rms * 1e6,
        want_rms * 1e6
    );
}

#[test]
fn a_loop_driven_into_its_current_limit_hands_over_to_the_co_simulation() {
    // A 6 mil step of the reference: the 1983 loop drives the coil into
    // the amplifier's 8 A limit (the exact steps cannot model it), then
    // settles.
    let step = |t: f64| if t > 0.01 { 6.0 } else { 0.0 };
    let ticks = 3000;
    let mut ra = rig(GaugeParams::noiseless());
    let mut exact = AnalogDrive::position_loop(&ra, true, 1);
    let ze = run(&mut exact, &mut ra, ticks, step);
    assert!(exact.nonlinear_spells >= 1, "left the linear range");
    assert!(ra.amp.limit_entries >= 1, "the co-simulation met the limit");
    assert!(exact.is_exact(), "back to the exact steps once settled");
    let mut rb = rig(GaugeParams::noiseless());
    let mut co = AnalogDrive::position_loop(&rb, false, 1);
    let zc = run(&mut co, &mut rb, ticks, step);
    // The same trajectory as the co-simulation throughout, within the
    // 5 µs co-simulation's own error (0.1 % of the motion, as for the
    // sinusoid above).
    let worst = max_abs_diff(&ze, &zc);
    assert!(worst < 6e-6, "{} µin", worst * 1e6);
    // It got there (the lag compensator's slow pole leaves a tail of tens
    // of µin after 0.14 s).
    let end = ze[ticks as usize - 1];
    assert!((end - 0.006).abs() < 60e-6, "at {end} in");
}
