//! Tool-nose compensation and the split of eq 2-8 for any surface.
//!
//! # The tool centre
//!
//! A lathe tool's nose is an arc of radius `r_t` in the meridional plane
//! (the plane of the axis and the radius at angle φ; tool on centre
//! height). At one φ the tool passes once a revolution at successive X, so
//! the surface it leaves there is the envelope of those arcs: the tool
//! centre lies on the offset of the meridional profile
//! `f_φ(r) = z(r cos φ, r sin φ)` along its normal. For a tool centre at
//! radius X the contact point `x_c` solves `x_c − r_t sin β(x_c) = X`,
//! `tan β = f_φ'(x_c)`, and the centre is at axial `T(X, φ) = f_φ(x_c) +
//! r_t cos β` (`Compensation::ProfileNormal`, exact for this tool; eq 2-15's
//! offset, done per φ).
//!
//! `Compensation::Forex4` is the dissertation's: one contact radius `x1`
//! for all φ, from the normal of the ridge `Y(x) = max_φ f_φ(x)`:
//! `x1 − r_t sin α = X`, `tan α = Y'(x1)`, `T = f_φ(x1) + r_t cos α`. With
//! the paraboloid it is Table 2-2's model (`crate::surface`); it differs
//! from the exact envelope by `r_t ε²/2`, ε the angle between the normals.
//! `nose_radius_in = 0` (a sharp tool) makes both `T = f_φ(X)`.
//!
//! # The split (eq 2-8)
//!
//! `Y(X) = max_φ T(X, φ)` is the axial slide's smooth motion and
//! `Z(X, φ) = T(X, φ) − Y(X)` the Z slide's, so `Z ≤ 0` with `max_φ Z = 0`:
//! the sign the firmware's load check demands (eq 2-14's choice of the
//! maximum for `Y`). The maximum is found from 256 samples a turn, every
//! sampled local maximum refined by golden section.

use super::Sag;
use crate::coeffgen::Harmonics;
pub use crate::surface::Compensation;
use std::f64::consts::{PI, TAU};
use std::sync::Arc;

/// Samples per turn for the maximum and the Fourier transform.
pub const SAMPLES: usize = 256;

/// The tool.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tool {
    /// Nose radius r_t, in (0: sharp).
    pub nose_radius: f64,
    /// Clearance angle below the cutting edge, degrees (plan's slope check).
    pub clearance_deg: f64,
    pub compensation: Compensation,
}

/// A surface and the tool that cuts it.
#[derive(Clone, Debug)]
pub struct Part {
    pub sag: Arc<dyn Sag>,
    pub tool: Tool,
}

/// The motion at one tool-centre X.
#[derive(Clone, Debug)]
pub struct Section {
    pub x: f64,
    /// Axial slide `Y(X)`, in (tool centre).
    pub y: f64,
    /// FOREX4's contact radius and `r_t cos α` (unused for the profile normal).
    x1: f64,
    rt_cos_a: f64,
    /// `Z` at `SAMPLES` equispaced φ.
    pub z_samples: Vec<f64>,
}

fn undefined(x: f64, phi: f64, what: &str) -> String {
    format!(
        "the surface is not defined at radius {x:.6} in, φ = {:.3}°{what}",
        phi.to_degrees().rem_euclid(360.0)
    )
}

/// Maximum of a function of φ from `SAMPLES` samples: every sampled local
/// maximum refined by golden section. Returns (max, φ at max).
fn max_over_phi(samples: &[f64], f: impl Fn(f64) -> f64) -> (f64, f64) {
    let n = samples.len();
    let h = TAU / n as f64;
    let (mut best, mut at) = (f64::NEG_INFINITY, 0.0);
    for i in 0..n {
        let (a, b, c) = (samples[(i + n - 1) % n], samples[i], samples[(i + 1) % n]);
        if !(b >= a && b >= c) {
            continue;
        }
        let (mut lo, mut hi) = ((i as f64 - 1.0) * h, (i as f64 + 1.0) * h);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let (mut m1, mut m2) = (hi - g * (hi - lo), lo + g * (hi - lo));
        let (mut f1, mut f2) = (f(m1), f(m2));
        for _ in 0..60 {
            if f1 < f2 {
                lo = m1;
                m1 = m2;
                f1 = f2;
                m2 = lo + g * (hi - lo);
                f2 = f(m2);
            } else {
                hi = m2;
                m2 = m1;
                f2 = f1;
                m1 = hi - g * (hi - lo);
                f1 = f(m1);
            }
        }
        let (v, p) = [(b, i as f64 * h), (f1, m1), (f2, m2)].into_iter().fold(
            (f64::NEG_INFINITY, 0.0),
            |acc, c| if c.0 > acc.0 { c } else { acc },
        );
        if v > best {
            best = v;
            at = p;
        }
    }
    (best, at)
}

impl Part {
    /// `(f_φ(r), f_φ'(r))` of the meridional profile.
    pub fn profile(&self, r: f64, phi: f64) -> (f64, f64) {
        let (s, c) = phi.sin_cos();
        let (x, y) = (r * c, r * s);
        let (gx, gy) = self.sag.grad(x, y);
        (self.sag.sag(x, y), gx * c + gy * s)
    }

    /// Tool-centre axial position with the profile-normal offset, and the
    /// contact radius.
    fn centre_profile_normal(&self, x: f64, phi: f64) -> Result<(f64, f64), String> {
        let rt = self.tool.nose_radius;
        let mut xc = x;
        for _ in 0..100 {
            let (f, d) = self.profile(xc, phi);
            if !(f.is_finite() && d.is_finite()) {
                return Err(undefined(xc, phi, ""));
            }
            let hyp = d.hypot(1.0);
            let next = x + rt * d / hyp;
            if (next - xc).abs() <= 4.0 * f64::EPSILON * next.abs().max(1.0) || rt == 0.0 {
                let (f, d) = self.profile(next, phi);
                return Ok((f + rt / d.hypot(1.0), next));
            }
            xc = next;
        }
        Err(format!(
            "the tool-nose contact at X = {x} in, φ = {:.3}° does not converge: the {} in nose \
             is too large for the surface's curvature there (it would undercut)",
            phi.to_degrees(),
            rt
        ))
    }

    /// The ridge `max_φ f_φ(x)` and its slope (envelope theorem: the
    /// profile's slope at the maximising φ).
    fn ridge(&self, x: f64) -> Result<(f64, f64), String> {
        let s: Vec<f64> = (0..SAMPLES)
            .map(|j| self.profile(x, TAU * j as f64 / SAMPLES as f64).0)
            .collect();
        if let Some(j) = s.iter().position(|v| !v.is_finite()) {
            return Err(undefined(x, TAU * j as f64 / SAMPLES as f64, ""));
        }
        let (y, at) = max_over_phi(&s, |p| self.profile(x, p).0);
        Ok((y, self.profile(x, at).1))
    }

    /// The section at tool-centre radius `x` (≥ 0).
    pub fn section(&self, x: f64) -> Result<Section, String> {
        if !(x.is_finite() && x >= 0.0) {
            return Err(format!("X = {x}: must be a finite radius >= 0"));
        }
        let rt = self.tool.nose_radius;
        let phis: Vec<f64> = (0..SAMPLES)
            .map(|j| TAU * j as f64 / SAMPLES as f64)
            .collect();
        match self.tool.compensation {
            Compensation::ProfileNormal => {
                let t = phis
                    .iter()
                    .map(|&p| self.centre_profile_normal(x, p).map(|v| v.0))
                    .collect::<Result<Vec<_>, _>>()?;
                let (y, _) = max_over_phi(&t, |p| {
                    self.centre_profile_normal(x, p)
                        .map_or(f64::NEG_INFINITY, |v| v.0)
                });
                Ok(Section {
                    x,
                    y,
                    x1: x,
                    rt_cos_a: 0.0,
                    z_samples: t.iter().map(|v| v - y).collect(),
                })
            }
            Compensation::Forex4 => {
                let mut x1 = x;
                let mut conv = false;
                for _ in 0..100 {
                    let (_, d) = self.ridge(x1)?;
                    let next = x + rt * d / d.hypot(1.0);
                    let done = (next - x1).abs() <= 4.0 * f64::EPSILON * next.abs().max(1.0);
                    x1 = next;
                    if done || rt == 0.0 {
                        conv = true;
                        break;
                    }
                }
                if !conv {
                    return Err(format!(
                        "FOREX4's contact radius at X = {x} in does not converge (nose {rt} in)"
                    ));
                }
                let (ry, d) = self.ridge(x1)?;
                let rt_cos_a = rt / d.hypot(1.0);
                let z: Vec<f64> = phis.iter().map(|&p| self.profile(x1, p).0 - ry).collect();
                Ok(Section {
                    x,
                    y: ry + rt_cos_a,
                    x1,
                    rt_cos_a,
                    z_samples: z,
                })
            }
        }
    }

    /// `Z(X, φ)`, in.
    pub fn z(&self, x: f64, phi: f64) -> Result<f64, String> {
        self.section(x)?.z(self, phi)
    }
}

impl Section {
    /// The tool-centre axial position `T(X, φ)` (= `Y(X) + Z(X, φ)`, eq 2-8).
    pub fn t(&self, part: &Part, phi: f64) -> Result<f64, String> {
        match part.tool.compensation {
            Compensation::ProfileNormal => Ok(part.centre_profile_normal(self.x, phi)?.0),
            Compensation::Forex4 => {
                let f = part.profile(self.x1, phi).0;
                if f.is_finite() {
                    Ok(f + self.rt_cos_a)
                } else {
                    Err(undefined(self.x1, phi, ""))
                }
            }
        }
    }

    /// `Z(X, φ) = T − Y`, in (≤ 0).
    pub fn z(&self, part: &Part, phi: f64) -> Result<f64, String> {
        Ok(self.t(part, phi)? - self.y)
    }

    /// Fourier coefficients of `Z` up to harmonic `k_max` (≤ SAMPLES/4):
    /// every harmonic, cos and sin (a general surface has no symmetry).
    pub fn harmonics(&self, k_max: usize) -> Harmonics {
        let m = self.z_samples.len();
        let mut c = vec![0.0; k_max + 1];
        let mut s = vec![0.0; k_max + 1];
        c[0] = self.z_samples.iter().sum::<f64>() / m as f64;
        for k in 1..=k_max {
            let (mut ck, mut sk) = (0.0, 0.0);
            for (j, z) in self.z_samples.iter().enumerate() {
                let a = 2.0 * PI * ((j * k) % m) as f64 / m as f64;
                let (sa, ca) = a.sin_cos();
                ck += z * ca;
                sk += z * sa;
            }
            c[k] = 2.0 * ck / m as f64;
            s[k] = 2.0 * sk / m as f64;
        }
        Harmonics { c, s }
    }
}
