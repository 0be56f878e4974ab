//! The plant model fitted to a measured frequency response (`zslide
//! identify`).
//!
//! The model is the simulator's own plant (`zslide_plant::slide`, state
//! `[i, v, z, q, q̇]`, `docs/PLANT.md`) behind the amplifier, from the DAC
//! code the loop writes to the gauge code it reads (both 2¹⁹ codes per
//! 10 V), with the board's sampling:
//!
//! ```text
//! H(e^{jωT}) = G·g · (1 − e^{−jωT}) · Σₘ P(j(ω + mωₛ)) e^{−j(ω + mωₛ)d} / (j(ω + mωₛ)T)
//! ```
//!
//! P: coil volts to gauge inches; G: amplifier gain; g: gauge V/in; the
//! DAC's zero-order hold starts `d` after the gauge sample (the handler's
//! DAC latency), and the sum over m = −3..3 is the aliasing of the sampled
//! gauge (the images of a plant falling as 1/ω³ above its electrical pole).
//!
//! Fitted: G, the moving mass M, the mode's pole and zero frequencies and
//! damping, and d. Taken from the motor's data sheet (the scenario): Kf,
//! Kb, R, L and the air film's B. Mass and gain are told apart by the
//! rigid pole a = (B + Kf·Kb/R)/M, which depends on M and not on G, while
//! the gain above it is G·Kf/(R·M).
//!
//! Least squares on the logarithm of H (log-magnitude and phase, each
//! point weighted by its measured signal-to-noise ratio), by
//! Levenberg–Marquardt with a finite-difference Jacobian, from the data
//! sheet's values.

use nalgebra::{Complex, DMatrix, DVector, Matrix5, Vector5};
use zslide_plant::slide::{ModeParams, ZSlideParams};
use zslide_plant::statespace::st;

/// One measured point of the response.
#[derive(Clone, Copy, Debug)]
pub struct Point {
    pub f_hz: f64,
    /// Gauge codes per DAC code.
    pub h: Complex<f64>,
    /// Standard deviation of `h`'s relative error (from the noise in the
    /// capture): the point's weight is its inverse.
    pub rel_sigma: f64,
}

/// What the fit adjusts, in the plant's units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plant {
    pub amp_gain: f64,
    pub mass_lbf_s2_per_in: f64,
    pub mode_pole_hz: f64,
    pub mode_zero_hz: f64,
    pub mode_zeta: f64,
    /// Gauge sample to the DAC's update, s.
    pub delay_s: f64,
}

/// The data sheet's part of the model, and the board's sampling.
#[derive(Clone, Debug)]
pub struct Known {
    /// Kf, Kb, R, L, B (its mass and mode are the starting point).
    pub slide: ZSlideParams,
    pub gauge_v_per_in: f64,
    pub loop_hz: f64,
}

impl Known {
    /// The plant with `p`'s fitted values.
    pub fn slide_with(&self, p: &Plant) -> ZSlideParams {
        ZSlideParams {
            mass_lbf_s2_per_in: p.mass_lbf_s2_per_in,
            mode: Some(ModeParams {
                pole_hz: p.mode_pole_hz,
                zero_hz: p.mode_zero_hz,
                zeta: p.mode_zeta,
            }),
            ..self.slide.clone()
        }
    }

    /// The model's response at `f_hz`, gauge codes per DAC code.
    pub fn response(&self, p: &Plant, f_hz: f64) -> Complex<f64> {
        self.response_engaged(p, 0.0, 0.0, f_hz)
    }

    /// [`Known::response`] with the tool engaged in a part: a spring of
    /// `k_lbf_per_in` and a damper of `c_lbf_s_per_in` between the slide's
    /// carriage (where the tool rides and the motor's force acts) and the
    /// frame.
    pub fn response_engaged(
        &self,
        p: &Plant,
        k_lbf_per_in: f64,
        c_lbf_s_per_in: f64,
        f_hz: f64,
    ) -> Complex<f64> {
        let slide = self.slide_with(p);
        let (mut a, b) = slide.continuous(false);
        a[st::V][st::Z] -= k_lbf_per_in / slide.mass_lbf_s2_per_in;
        a[st::V][st::V] -= c_lbf_s_per_in / slide.mass_lbf_s2_per_in;
        let a = Matrix5::from_fn(|r, c| Complex::new(a[r][c], 0.0));
        let b = Vector5::from_fn(|r, _| Complex::new(b[r][0], 0.0));
        let t = 1.0 / self.loop_hz;
        let w = std::f64::consts::TAU * f_hz;
        let ws = std::f64::consts::TAU * self.loop_hz;
        let j = Complex::new(0.0, 1.0);
        let hold = Complex::new(1.0, 0.0) - (-j * w * t).exp();
        let mut sum = Complex::new(0.0, 0.0);
        for m in -3..=3 {
            let wm = w + f64::from(m) * ws;
            let s = j * wm;
            let x = (Matrix5::identity() * s - a)
                .lu()
                .solve(&b)
                .unwrap_or_else(Vector5::zeros);
            let gauge = x[st::Z] + x[st::Q];
            sum += gauge * (-j * wm * p.delay_s).exp() / (j * wm * t);
        }
        hold * sum * p.amp_gain * self.gauge_v_per_in
    }
}

/// The fit's outcome.
#[derive(Clone, Debug)]
pub struct Fit {
    pub plant: Plant,
    /// Weighted RMS of the log residual (1: the noise's level).
    pub rms_weighted: f64,
    /// One-sigma uncertainty of each fitted value, relative (from the
    /// Jacobian at the solution and the residual's level), in the order of
    /// [`Plant`]'s fields.
    pub rel_sigma: [f64; 6],
    pub iterations: u32,
}

fn to_vec(p: &Plant) -> [f64; 6] {
    [
        p.amp_gain.ln(),
        p.mass_lbf_s2_per_in.ln(),
        p.mode_pole_hz.ln(),
        p.mode_zero_hz.ln(),
        p.mode_zeta.ln(),
        p.delay_s * 1e5,
    ]
}

fn from_vec(x: &[f64]) -> Plant {
    Plant {
        amp_gain: x[0].exp(),
        mass_lbf_s2_per_in: x[1].exp(),
        mode_pole_hz: x[2].exp(),
        mode_zero_hz: x[3].exp(),
        mode_zeta: x[4].exp(),
        delay_s: x[5] * 1e-5,
    }
}

/// Weighted residuals: log-magnitude and phase of measured / model.
fn residuals(known: &Known, pts: &[Point], x: &[f64]) -> DVector<f64> {
    let p = from_vec(x);
    let mut r = DVector::zeros(2 * pts.len());
    for (k, pt) in pts.iter().enumerate() {
        let q = pt.h / known.response(&p, pt.f_hz);
        let w = 1.0 / pt.rel_sigma.max(1e-6);
        r[2 * k] = q.norm().ln() * w;
        r[2 * k + 1] = q.arg() * w;
    }
    r
}

/// Fits the model to `pts`, starting at `start`.
pub fn fit(known: &Known, pts: &[Point], start: &Plant) -> Result<Fit, String> {
    if pts.len() < 6 {
        return Err(format!(
            "{} measured points: the fit needs at least 6",
            pts.len()
        ));
    }
    let mut x = to_vec(start).to_vec();
    let mut r = residuals(known, pts, &x);
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let n = x.len();
    let jacobian = |x: &[f64], r: &DVector<f64>| {
        let mut jm = DMatrix::zeros(r.len(), n);
        for c in 0..n {
            let mut xp = x.to_vec();
            let h = 1e-6;
            xp[c] += h;
            let rp = residuals(known, pts, &xp);
            jm.set_column(c, &((rp - r) / h));
        }
        jm
    };
    for _ in 0..200 {
        iterations += 1;
        let jm = jacobian(&x, &r);
        let jtj = jm.transpose() * &jm;
        let g = jm.transpose() * &r;
        let mut improved = false;
        for _ in 0..20 {
            let mut a = jtj.clone();
            for d in 0..n {
                a[(d, d)] += lambda * jtj[(d, d)].max(1e-12);
            }
            let Some(step) = a.lu().solve(&(-&g)) else {
                lambda *= 10.0;
                continue;
            };
            let xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            let rn = residuals(known, pts, &xn);
            let cn = rn.norm_squared();
            if cn.is_finite() && cn < cost {
                let small = (cost - cn) < 1e-10 * cost;
                x = xn;
                r = rn;
                cost = cn;
                lambda = (lambda / 3.0).max(1e-12);
                improved = !small;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let dof = (r.len() as f64 - n as f64).max(1.0);
    let s2 = cost / dof;
    let jm = jacobian(&x, &r);
    let cov = (jm.transpose() * &jm)
        .try_inverse()
        .ok_or("the fit is singular: the points do not determine the model")?;
    let mut rel_sigma = [0.0; 6];
    for (d, s) in rel_sigma.iter_mut().enumerate() {
        *s = (cov[(d, d)] * s2).sqrt();
    }
    // The delay's parameter is absolute (×1e5 s): as a fraction of itself.
    rel_sigma[5] *= 1e-5 / from_vec(&x).delay_s.abs().max(1e-9);
    Ok(Fit {
        plant: from_vec(&x),
        rms_weighted: (cost / r.len() as f64).sqrt(),
        rel_sigma,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn known() -> Known {
        Known {
            slide: ZSlideParams::model15(),
            gauge_v_per_in: 1000.0,
            loop_hz: 20_000.0,
        }
    }

    fn nominal() -> Plant {
        let s = ZSlideParams::model15();
        let m = s.mode.unwrap_or(ModeParams::DISSERTATION);
        Plant {
            amp_gain: 10.0,
            mass_lbf_s2_per_in: s.mass_lbf_s2_per_in,
            mode_pole_hz: m.pole_hz,
            mode_zero_hz: m.zero_hz,
            mode_zeta: m.zeta,
            delay_s: 8.5e-6,
        }
    }

    /// Below the electrical pole and above the rigid pole the model is the
    /// closed form G·Kf·g/(R·M·s²) (× the hold's half-period delay).
    #[test]
    fn the_response_is_the_rigid_closed_form_between_the_poles() {
        let k = known();
        let p = nominal();
        let f = 200.0;
        let h = k.response(&p, f);
        let s = k.slide.clone();
        let w = std::f64::consts::TAU * f;
        let a =
            (s.b_lbf_s_per_in + s.kf_lbf_per_a * s.kb_v_s_per_in / s.r_ohm) / p.mass_lbf_s2_per_in;
        let we = s.r_ohm / s.l_h;
        let closed = 10.0 * s.kf_lbf_per_a * 1000.0
            / (s.r_ohm * p.mass_lbf_s2_per_in)
            / (w * (w * w + a * a).sqrt())
            / (1.0 + (w / we).powi(2)).sqrt();
        assert!(
            (h.norm() / closed - 1.0).abs() < 0.02,
            "|H| {} against {closed}",
            h.norm()
        );
    }

    /// The fit recovers a perturbed plant from its own noiseless response.
    #[test]
    fn the_fit_recovers_a_perturbed_plant_from_its_response() {
        let k = known();
        let n = nominal();
        let truth = Plant {
            amp_gain: n.amp_gain * 0.85,
            mass_lbf_s2_per_in: n.mass_lbf_s2_per_in * 1.1,
            mode_pole_hz: n.mode_pole_hz * 1.05,
            mode_zero_hz: n.mode_zero_hz * 1.05,
            mode_zeta: 0.02,
            delay_s: 9e-6,
        };
        let pts: Vec<Point> = [20.0, 40.0, 80.0, 160.0, 500.0, 1000.0, 2000.0]
            .into_iter()
            .chain((0..30).map(|i| 2800.0 + 25.0 * f64::from(i)))
            .map(|f| Point {
                f_hz: f,
                h: k.response(&truth, f),
                rel_sigma: 0.01,
            })
            .collect();
        let fit = fit(&k, &pts, &n).unwrap();
        let p = fit.plant;
        assert!((p.amp_gain / truth.amp_gain - 1.0).abs() < 1e-4, "{p:?}");
        assert!((p.mass_lbf_s2_per_in / truth.mass_lbf_s2_per_in - 1.0).abs() < 1e-4);
        assert!((p.mode_pole_hz / truth.mode_pole_hz - 1.0).abs() < 1e-4);
        assert!((p.mode_zero_hz / truth.mode_zero_hz - 1.0).abs() < 1e-4);
    }
}
