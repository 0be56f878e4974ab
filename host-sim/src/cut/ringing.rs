//! The part's overhang as a spring (chapter 5): the 15 in disc, 2 in
//! thick, bolted on an 8 in faceplate, "unsupported over its outer 3.5
//! inches"; the cutting force rang it at "the natural frequency of the
//! part as supported by the spindle" while the tool cut beyond the
//! faceplate, and the ringing stopped once the cut passed inside it.
//!
//! Model: an annular plate clamped at the faceplate's radius `a`, free at
//! the part's rim `b`, in its first axisymmetric mode. The mode shape is
//! the trial function `ψ(ξ) = ξ²(3 − ξ)/2`, `ξ = (r − a)/(b − a)` (a
//! cantilever's static shape under a tip load: zero deflection and slope
//! at the clamp, normalised to 1 at the rim), zero inside the faceplate.
//! Its modal stiffness and mass at the rim are the Rayleigh–Ritz integrals
//! of classical (Kirchhoff) plate theory,
//!
//! ```text
//! K = D ∫ [(w'' + w'/r)² − 2(1−ν) w'' w'/r] 2πr dr,   M = ρh ∫ ψ² 2πr dr,
//! D = E h³ / (12 (1 − ν²))
//! ```
//!
//! an upper bound on the frequency (one trial function; a 2 in plate over
//! 3.5 in is thick, and shear would lower it further). The force `F` on
//! the tool at radius `r` acts on the part as the generalised force
//! `ψ(r)·F`; the mode's rim deflection `q` moves the part under the tool
//! by `ψ(r)·q` away from it (positive thrust pushes the part toward −Y_t:
//! excess stock). One mode: the diametral modes a point force also
//! excites are left out (labelled in docs/CUT.md).

use crate::error_levels::ErrorLevels;
use std::f64::consts::{PI, TAU};

/// g, in/s²: pounds of mass to lbf·s²/in.
const G_IN_PER_S2: f64 = 386.088;

/// The first mode of the overhang, referred to the rim.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PlateMode {
    /// Clamp (faceplate) and rim radius, in.
    pub support_r_in: f64,
    pub rim_r_in: f64,
    /// Modal stiffness at the rim, lbf/in, and modal mass, lbf·s²/in.
    pub k_lbf_per_in: f64,
    pub m: f64,
    pub zeta: f64,
}

impl PlateMode {
    /// The mode of `[errors]`'s plate, `None` when the part is rigid
    /// (`part_thickness_in = 0`).
    pub fn of(l: &ErrorLevels) -> Option<Self> {
        if l.part_thickness_in <= 0.0 {
            return None;
        }
        let (a, b, h) = (
            l.part_support_radius_in,
            l.part_outer_radius_in,
            l.part_thickness_in,
        );
        let nu = l.part_poisson;
        let d = l.part_modulus_psi * h.powi(3) / (12.0 * (1.0 - nu * nu));
        let rho_h = l.part_density_lb_per_in3 / G_IN_PER_S2 * h;
        let len = b - a;
        // Simpson over the annulus (the integrands are polynomials in ξ
        // over r: 2000 panels leave < 1e-12 relative).
        let n = 2000;
        let (mut k, mut m) = (0.0, 0.0);
        for i in 0..=n {
            let xi = i as f64 / n as f64;
            let r = a + xi * len;
            let w = xi * xi * (3.0 - xi) / 2.0;
            let w1 = (6.0 * xi - 3.0 * xi * xi) / 2.0 / len;
            let w2 = (6.0 - 6.0 * xi) / 2.0 / (len * len);
            let ke = ((w2 + w1 / r).powi(2) - 2.0 * (1.0 - nu) * w2 * w1 / r) * TAU * r;
            let me = w * w * TAU * r;
            let c = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            k += c * ke;
            m += c * me;
        }
        let step = len / n as f64 / 3.0;
        Some(Self {
            support_r_in: a,
            rim_r_in: b,
            k_lbf_per_in: d * k * step,
            m: rho_h * m * step,
            zeta: l.part_mode_zeta,
        })
    }

    /// Natural frequency, Hz.
    pub fn freq_hz(&self) -> f64 {
        (self.k_lbf_per_in / self.m).sqrt() / TAU
    }

    /// Mode shape at radius `r`, 0 inside the faceplate, 1 at the rim.
    pub fn shape(&self, r: f64) -> f64 {
        let xi = ((r - self.support_r_in) / (self.rim_r_in - self.support_r_in)).clamp(0.0, 1.0);
        xi * xi * (3.0 - xi) / 2.0
    }
}

/// The mode's state, stepped exactly for a force held over each step.
#[derive(Clone, Debug)]
pub struct Ringing {
    pub mode: PlateMode,
    /// Rim deflection, in, and its rate, in/s.
    pub q: f64,
    pub v: f64,
}

impl Ringing {
    pub fn new(mode: PlateMode) -> Self {
        Self {
            mode,
            q: 0.0,
            v: 0.0,
        }
    }

    /// Advances by `dt` s with the generalised force `f_lbf` (the force at
    /// the tool times the shape there) held: the exact solution of
    /// `m q'' + 2ζ√(km) q' + k q = f` about its static point `f/k`.
    pub fn step(&mut self, dt: f64, f_lbf: f64) {
        if dt <= 0.0 {
            return;
        }
        let md = &self.mode;
        let wn = (md.k_lbf_per_in / md.m).sqrt();
        let sigma = md.zeta * wn;
        let wd = wn * (1.0 - md.zeta * md.zeta).sqrt();
        let qs = f_lbf / md.k_lbf_per_in;
        let (x0, v0) = (self.q - qs, self.v);
        let e = (-sigma * dt).exp();
        let (s, c) = (wd * dt).sin_cos();
        self.q = qs + e * (x0 * c + (v0 + sigma * x0) / wd * s);
        self.v = e * (v0 * c - (wn * wn * x0 + sigma * v0) / wd * s);
    }

    /// The part's deflection away from the tool at radius `r`, in.
    pub fn at(&self, r: f64) -> f64 {
        self.mode.shape(r) * self.q
    }
}

/// The RMS response of the mode to a white force of RMS `sigma_f` held
/// over steps of `dt` (band π/dt), in: `σ_F·√(π/(2 ζ ω_n³ m² · (π/dt)))`
/// for `ζ ≪ 1` and a mode well inside the band. Used by the docs' level
/// argument and its test.
pub fn white_rms_response(mode: &PlateMode, sigma_f: f64, dt: f64) -> f64 {
    let wn = (mode.k_lbf_per_in / mode.m).sqrt();
    // One-sided PSD of a held white sequence near 0 Hz .. ωn ≪ π/dt:
    // σ²·dt/π per rad/s; the oscillator's ∫|H|² dω = π/(2 ζ ωn³ m²).
    let psd = sigma_f * sigma_f * dt / PI;
    (psd * PI / (2.0 * mode.zeta * wn.powi(3) * mode.m * mode.m)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn levels(a: f64, b: f64, h: f64) -> ErrorLevels {
        ErrorLevels {
            part_support_radius_in: a,
            part_outer_radius_in: b,
            part_thickness_in: h,
            part_modulus_psi: 10.0e6,
            part_density_lb_per_in3: 0.098,
            part_poisson: 0.33,
            part_mode_zeta: 0.02,
            ..ErrorLevels::default()
        }
    }

    /// A narrow annulus far out is a cantilever strip of width 2πr: with
    /// the same trial function its Rayleigh quotient is closed form,
    /// `ω² = (D/ρh)·∫ψ''²/∫ψ² / L⁴ = (D/ρh)·3/(33/140)/L⁴`.
    #[test]
    fn a_far_out_annulus_has_the_cantilever_strips_rayleigh_frequency() {
        let (a, len, h) = (10_000.0, 3.5, 0.5);
        let l = levels(a, a + len, h);
        let md = PlateMode::of(&l).unwrap();
        let d = 10.0e6 * h.powi(3) / (12.0 * (1.0 - 0.33f64.powi(2)));
        let rho_h = 0.098 / G_IN_PER_S2 * h;
        let w = (3.0f64 / (33.0 / 140.0)).sqrt() / (len * len) * (d / rho_h).sqrt();
        let f = w / TAU;
        assert!(
            (md.freq_hz() - f).abs() < 2e-3 * f,
            "{} Hz vs {f} Hz",
            md.freq_hz()
        );
        // The rim stiffness of the strip: D·(2πb)·∫ψ''² /L³ (shape at r ≈ b).
        let k = d * TAU * (a + 0.5 * len) * 3.0 / len.powi(3);
        assert!((md.k_lbf_per_in - k).abs() < 2e-3 * k);
    }

    #[test]
    fn a_step_force_settles_at_f_over_k_after_overshooting_by_the_damping() {
        let l = levels(4.0, 7.5, 2.0);
        let md = PlateMode::of(&l).unwrap();
        let mut r = Ringing::new(md);
        let f = 1.0;
        let wn = TAU * md.freq_hz();
        let wd = wn * (1.0 - md.zeta * md.zeta).sqrt();
        // Step over irregular sub-steps up to the first peak, t = π/ωd.
        let tp = PI / wd;
        let mut t = 0.0;
        let mut i = 0;
        while t < tp {
            let h = (tp - t).min(if i % 2 == 0 { 1e-6 } else { 3.7e-6 });
            r.step(h, f);
            t += h;
            i += 1;
        }
        let qs = f / md.k_lbf_per_in;
        let peak = qs * (1.0 + (-md.zeta * PI / (1.0 - md.zeta * md.zeta).sqrt()).exp());
        assert!((r.q - peak).abs() < 1e-9 * peak, "{} vs {peak}", r.q);
        for _ in 0..20_000 {
            r.step(1e-5, f);
        }
        assert!((r.q - qs).abs() < 1e-6 * qs);
    }

    #[test]
    fn a_force_at_resonance_drives_the_rim_to_f_over_2_zeta_k() {
        let l = levels(4.0, 7.5, 2.0);
        let md = PlateMode::of(&l).unwrap();
        let mut r = Ringing::new(md);
        let wn = TAU * md.freq_hz();
        let dt = 1e-6;
        let f0 = 1.0;
        let n = (0.2 / dt) as usize;
        let mut peak = 0.0f64;
        for i in 0..n {
            let t = i as f64 * dt;
            r.step(dt, f0 * (wn * (t + 0.5 * dt)).sin());
            if t > 0.15 {
                peak = peak.max(r.q.abs());
            }
        }
        let expect = f0 / (2.0 * md.zeta * md.k_lbf_per_in);
        assert!(
            (peak - expect).abs() < 0.01 * expect,
            "{peak:e} vs {expect:e}"
        );
    }

    #[test]
    fn the_shape_is_zero_inside_the_faceplate_and_one_at_the_rim() {
        let md = PlateMode::of(&levels(4.0, 7.5, 2.0)).unwrap();
        assert_eq!(md.shape(3.0), 0.0);
        assert_eq!(md.shape(4.0), 0.0);
        assert!((md.shape(7.5) - 1.0).abs() < 1e-15);
        assert!(PlateMode::of(&levels(4.0, 7.5, 0.0)).is_none());
    }
}
