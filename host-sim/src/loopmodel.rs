//! The digital loop as a linear sampled-data model with the engaged part's
//! spring: an independent check of what `response --loop digital
//! --process-stiffness` measures through the firmware, and the learning's
//! convergence factor per spindle harmonic, which a swept sine cannot
//! measure (no spindle).
//!
//! Built from the f64 design (`ServoDesign`), not from the firmware's
//! integer code: the plant `M z̈ + B ż + k z = Kf i`, `L di/dt = V − Kb ż −
//! R i` (rigid: the coil frame's mode is left out), sampled exactly with the
//! board's DAC latency τ (the previous output holds for τ into each period),
//! the current estimator of `servo::observer` with its gains by pole
//! placement (the same formula as the firmware's design, re-derived here on
//! the sampled matrices), the state feedback, the hum canceller on the
//! feedback (as its equivalent notch, from its continuous prototype: not
//! the firmware's z-domain design) and the mode notch on the output. With the loop broken at
//! the gauge reading, `L(e^{jωh})` gives the margins; with the reference
//! driven (position, and its rates through the plant-inverse feedforward),
//! `T(e^{jωh})` gives what the learning's correction moves.
//!
//! The learning per harmonic `f` of the spindle (`servo::repetitive`): a
//! bin's update is spread over two bins and read back by linear
//! interpolation (sinc⁴ at the bin rate), led by `lead` bins, low-passed
//! (`learning_lowpass_hz`) and notched (the hum notch) in time, and
//! smoothed by the Q-filter `cos⁴(πf/f_bin)` (shift 2): the table's
//! revolution-to-revolution factor is
//! `Q·(1 − κ·W·e^{j2πf·lead/f_bin}·N·F·T)`; the learning converges where its
//! modulus is below 1 at every harmonic.

use nalgebra::{Complex, DMatrix, DVector, Matrix4};
use zslide::servo::ServoDesign;

type C = Complex<f64>;

/// Gauge and DAC codes per volt.
const CODES_PER_V: f64 = 524_288.0 / 10.0;

/// The loop at one process stiffness.
pub struct LoopModel {
    h: f64,
    /// Closed loop (reference → states) and open loop (gauge injection →
    /// states), and the gauge's row.
    a_cl: DMatrix<f64>,
    a_ol: DMatrix<f64>,
    b_ol: DVector<f64>,
    c_y: DVector<f64>,
    /// The reference's input columns: position, velocity per tick,
    /// acceleration per tick².
    b_r: [DVector<f64>; 3],
    hum: Option<[f64; 5]>,
    design: ServoDesign,
}

/// A notch `[b0, b1, b2, a1, a2]` (a0 = 1) by the bilinear transform,
/// prewarped at `f0`, of the continuous prototype `(s² + ω₀²) / ((1 − sin θ
/// / Q) s² + (ω₀/Q) cos θ · s + ω₀²)`: the RBJ notch at θ = 0, and for θ ≠
/// 0 the synchronous canceller with phase advance θ that
/// `zslide::servo::filters::Notch::design_turned` designs in z directly
/// (poles turned about the zeros; the two agree to first order in the
/// notch's width, not exactly).
fn notch(f0: f64, fs: f64, q: f64, turn_rad: f64) -> [f64; 5] {
    let w = std::f64::consts::TAU * f0;
    let k = w / (std::f64::consts::PI * f0 / fs).tan();
    let (a, b) = (1.0 - turn_rad.sin() / q, w / q * turn_rad.cos());
    let (k2, w2) = (k * k, w * w);
    let d0 = a * k2 + b * k + w2;
    [
        (k2 + w2) / d0,
        2.0 * (w2 - k2) / d0,
        (k2 + w2) / d0,
        2.0 * (w2 - a * k2) / d0,
        (a * k2 - b * k + w2) / d0,
    ]
}

fn biquad_at(c: &[f64; 5], z: C) -> C {
    let zi = z.inv();
    (c[0] + c[1] * zi + c[2] * zi * zi) / (1.0 + c[3] * zi + c[4] * zi * zi)
}

const N: usize = 15;

impl LoopModel {
    /// The loop of `design` on its slide with the electrical time constant
    /// `l_over_r_s`, a DAC latency `latency_s` after the gauge's sample,
    /// and the part's spring `stiffness_lbf_per_in` on the slide.
    pub fn new(
        design: &ServoDesign,
        l_over_r_s: f64,
        latency_s: f64,
        stiffness_lbf_per_in: f64,
    ) -> Self {
        let s = &design.slide;
        let fs = f64::from(design.rate_hz);
        let h = 1.0 / fs;
        let (m, b, kf, kb, r) = (
            s.mass_lbf_s2_per_in,
            s.b_lbf_s_per_in,
            s.kf_lbf_per_a,
            s.kb_v_s_per_in,
            s.r_ohm,
        );
        let l = l_over_r_s * r;
        // Continuous plant, states z (in), ż, i; input the DAC code.
        let mut ac = Matrix4::<f64>::zeros();
        ac[(0, 1)] = 1.0;
        ac[(1, 0)] = -stiffness_lbf_per_in / m;
        ac[(1, 1)] = -b / m;
        ac[(1, 2)] = kf / m;
        ac[(2, 1)] = -kb / l;
        ac[(2, 2)] = -r / l;
        ac[(2, 3)] = s.amp_gain / CODES_PER_V / l;
        let disc = |t: f64| {
            let e = (ac * t).exp();
            let phi = e.fixed_view::<3, 3>(0, 0).into_owned();
            let gam = e.fixed_view::<3, 1>(0, 3).into_owned();
            (phi, gam)
        };
        let (phi, _) = disc(h);
        let (p1, g1) = disc(h - latency_s);
        let (_, g0) = disc(latency_s);
        let gam0 = p1 * g0;
        let cy = s.gauge_v_per_in * CODES_PER_V;

        // The design's rigid model and gains (servo::design).
        let k = s.gain_per_s2();
        let a = s.pole_per_s();
        let w = std::f64::consts::TAU * design.bandwidth_hz;
        let kp = w * w / k;
        let kd = (2.0 * design.damping * w - a) / (k * h);
        let kff = a / (k * h);
        let ka = 1.0 / (k * h * h);
        let e = (-a * h).exp();
        let am = nalgebra::Matrix3::new(
            1.0,
            (1.0 - e) / (a * h),
            k * (h / a - (1.0 - e) / (a * a)),
            0.0,
            e,
            k * h * (1.0 - e) / a,
            0.0,
            0.0,
            1.0,
        );
        let bm = nalgebra::Vector3::new(am[(0, 2)], am[(1, 2)], 0.0);
        // Current estimator: (A, CA) observable; Ackermann with (z − p)³.
        let p = (-std::f64::consts::TAU * design.observer_hz * h).exp();
        let ca = am.row(0).into_owned();
        let o = nalgebra::Matrix3::from_rows(&[ca, ca * am, ca * am * am]);
        let id = nalgebra::Matrix3::<f64>::identity();
        let poly = am * am * am - 3.0 * p * am * am + 3.0 * p * p * am - p * p * p * id;
        let lg =
            poly * o.try_inverse().expect("observable") * nalgebra::Vector3::new(0.0, 0.0, 1.0);

        let hum = (design.hum_notch_q > 0.0).then(|| {
            notch(
                design.hum_notch_hz,
                fs,
                design.hum_notch_q,
                design.hum_notch_turn_deg.to_radians(),
            )
        });
        let mode = (design.mode_notch_q > 0.0)
            .then(|| notch(design.mode_notch_hz, fs, design.mode_notch_q, 0.0));

        // One tick as a linear map of (state, gauge injection, reference).
        // State: plant (3), last output, estimate (3), hum notch (x1, x2,
        // y1, y2), mode notch (x1, x2, y1, y2).
        let step = |x: &DVector<f64>, inj: f64, r: [f64; 3], open: bool| -> DVector<f64> {
            let xp = nalgebra::Vector3::new(x[0], x[1], x[2]);
            let um = x[3];
            let xh = nalgebra::Vector3::new(x[4], x[5], x[6]);
            // Open: the controller reads the injection alone (the loop
            // broken at the gauge reading).
            let y = if open { inj } else { cy * xp[0] + inj };
            let pred = am * xh + bm * um;
            let inn = y - pred[0];
            let xh2 = pred + lg * inn;
            let fb = kp * (r[0] - xh2[0]) + kd * (r[1] - xh2[1]) - xh2[2];
            let ff = kff * r[1] + ka * r[2];
            let (v, hs) = match &hum {
                Some(c) => {
                    let yv = c[0] * fb + c[1] * x[7] + c[2] * x[8] - c[3] * x[9] - c[4] * x[10];
                    (yv, [fb, x[7], yv, x[9]])
                }
                None => (fb, [0.0; 4]),
            };
            let v = v + ff;
            let (u, ms) = match &mode {
                Some(c) => {
                    let u = c[0] * v + c[1] * x[11] + c[2] * x[12] - c[3] * x[13] - c[4] * x[14];
                    (u, [v, x[11], u, x[13]])
                }
                None => (v, [0.0; 4]),
            };
            let xn = phi * xp + gam0 * um + g1 * u;
            let mut out = DVector::zeros(N);
            out.rows_mut(0, 3).copy_from(&xn);
            out[3] = u;
            out.rows_mut(4, 3).copy_from(&xh2);
            for i in 0..4 {
                out[7 + i] = hs[i];
                out[11 + i] = ms[i];
            }
            out
        };
        let zero = DVector::zeros(N);
        let matrix = |open: bool| {
            DMatrix::from_fn(N, N, |i, j| {
                let mut x = DVector::zeros(N);
                x[j] = 1.0;
                step(&x, 0.0, [0.0; 3], open)[i]
            })
        };
        let mut c_y = DVector::zeros(N);
        c_y[0] = cy;
        Self {
            h,
            a_cl: matrix(false),
            a_ol: matrix(true),
            b_ol: step(&zero, 1.0, [0.0; 3], true),
            c_y,
            b_r: [
                step(&zero, 0.0, [1.0, 0.0, 0.0], false),
                step(&zero, 0.0, [0.0, 1.0, 0.0], false),
                step(&zero, 0.0, [0.0, 0.0, 1.0], false),
            ],
            hum,
            design: *design,
        }
    }

    fn solve(&self, a: &DMatrix<f64>, b: &DVector<C>, f_hz: f64) -> C {
        let z = C::from_polar(1.0, std::f64::consts::TAU * f_hz * self.h);
        let m = DMatrix::<C>::from_fn(N, N, |i, j| {
            let d = if i == j { z } else { C::new(0.0, 0.0) };
            d - C::new(a[(i, j)], 0.0)
        });
        let x = m.lu().solve(b).expect("not on a pole");
        self.c_y.map(|v| C::new(v, 0.0)).dot(&x)
    }

    /// The loop gain at `f_hz`, broken at the gauge reading (`L = T/S` of
    /// `response --loop digital`).
    pub fn loop_gain(&self, f_hz: f64) -> C {
        -self.solve(&self.a_ol, &self.b_ol.map(|v| C::new(v, 0.0)), f_hz)
    }

    /// The sensitivity `1/(1 + L)`.
    pub fn sensitivity(&self, f_hz: f64) -> C {
        (C::new(1.0, 0.0) + self.loop_gain(f_hz)).inv()
    }

    /// The largest closed-loop pole modulus (< 1: stable), by Gelfand's
    /// formula `ρ = lim ‖Aⁿ‖^{1/n}` with n = 2²⁴ by repeated squaring
    /// (normalised at each step): the notch's poles sit within 10⁻³ of the
    /// unit circle, closer than a general eigenvalue routine resolves.
    pub fn spectral_radius(&self) -> f64 {
        let mut b = self.a_cl.clone();
        let mut log = 0.0;
        let steps = 24;
        for _ in 0..steps {
            b = &b * &b;
            let n = b.norm();
            if n == 0.0 {
                return 0.0;
            }
            b /= n;
            log = 2.0 * log + n.ln();
        }
        (log / f64::from(1u32 << steps)).exp()
    }

    /// The gauge's response to the reference (with its rates) at `f_hz`.
    pub fn reference_to_gauge(&self, f_hz: f64) -> C {
        let jwh = C::new(0.0, std::f64::consts::TAU * f_hz * self.h);
        let b = self.b_r[0].map(|v| C::new(v, 0.0))
            + self.b_r[1].map(|v| C::new(v, 0.0) * jwh)
            + self.b_r[2].map(|v| C::new(v, 0.0) * jwh * jwh);
        self.solve(&self.a_cl, &b, f_hz)
    }

    /// The slide's departure (in, after each tick) from the path it was on
    /// when, from rest, the reference leaves that path by `[position (in),
    /// velocity (in/s), acceleration (in/s²)]` at tick k: the rates are
    /// what the feedforward is given, which need not be the position's
    /// differences (a slew profile that restarts from rest drops the
    /// command's velocity without an acceleration to match). By
    /// superposition on the linear loop this is what the loop passes of a
    /// change of reference, whatever its own error on the path was; the
    /// part's spring (`stiffness_lbf_per_in`) is in the plant, so the
    /// cutting force released as the tool leaves its depth is in it.
    pub fn reference_departure_in(&self, dr: &[[f64; 3]]) -> Vec<f64> {
        let cy = self.c_y[0];
        let mut x = DVector::zeros(N);
        dr.iter()
            .map(|&[r, v, a]| {
                x = &self.a_cl * &x
                    + &self.b_r[0] * (cy * r)
                    + &self.b_r[1] * (cy * v * self.h)
                    + &self.b_r[2] * (cy * a * self.h * self.h);
                x[0]
            })
            .collect()
    }

    /// The learning's largest revolution-to-revolution factor over the
    /// harmonics below the table's Nyquist at `rpm`, and where (Hz).
    pub fn learning_factor(&self, rpm: f64) -> (f64, f64) {
        let d = &self.design;
        let fs = f64::from(d.rate_hz);
        let rps = rpm / 60.0;
        let f_bin = zslide::servo::repetitive::BINS as f64 * rps;
        let lead = f64::from(d.learning_lead_bins);
        let alpha = if d.learning_lowpass_hz > 0.0 {
            1.0 - (-std::f64::consts::TAU * d.learning_lowpass_hz / fs).exp()
        } else {
            1.0
        };
        let mut worst = (0.0, 0.0);
        for n in 1..zslide::servo::repetitive::BINS / 2 {
            let f = rps * n as f64;
            let x = std::f64::consts::PI * f / f_bin;
            let q = x.cos().powi(4);
            let w = (x.sin() / x).powi(4);
            let z = C::from_polar(1.0, std::f64::consts::TAU * f / fs);
            let lp = C::new(alpha, 0.0) / (C::new(1.0, 0.0) - (1.0 - alpha) * z.inv());
            let nh = self
                .hum
                .as_ref()
                .map_or(C::new(1.0, 0.0), |c| biquad_at(c, z));
            let turn = C::from_polar(1.0, std::f64::consts::TAU * f * lead / f_bin);
            let g = (q
                * (C::new(1.0, 0.0)
                    - d.learning_gain * w * turn * nh * lp * self.reference_to_gauge(f)))
            .norm();
            if g > worst.0 {
                worst = (g, f);
            }
        }
        worst
    }

    /// The largest |S| over `f_lo..f_hi` (log grid of `n`), dB, and where.
    pub fn peak_sensitivity_db(&self, f_lo: f64, f_hi: f64, n: usize) -> (f64, f64) {
        (0..n)
            .map(|i| {
                let f = f_lo * (f_hi / f_lo).powf(i as f64 / (n - 1) as f64);
                (20.0 * self.sensitivity(f).norm().log10(), f)
            })
            .fold(
                (f64::NEG_INFINITY, 0.0),
                |a, b| if b.0 > a.0 { b } else { a },
            )
    }
}
