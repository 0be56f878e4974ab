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
//! `Y(X)` is the axial slide's smooth motion and `Z(X, φ) = T(X, φ) −
//! Y(X)` the Z slide's. Eq 2-14 takes `Y = max_φ T`, so `Z ≤ 0` with
//! `max_φ Z = 0`: the sign the firmware's load check demands. Where the
//! maximum jumps between lobes of `T(X, ·)` that `Y` has a kink, so `Y`
//! here is a smooth upper envelope of the lobe maxima ([`Envelope`]):
//! `Z ≤ 0` still, `max_φ Z` within `τ ln n` of 0 (n lobes), and exactly
//! `max_φ T` for a surface with one lobe (the paraboloid). The lobes are
//! found from 256 samples a turn, every sampled local maximum refined by
//! golden section.

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

/// Smoothing length of the upper envelope `Y(X)`, in (see [`Envelope`]).
pub const ENVELOPE_TAU_IN: f64 = 40e-6;

/// The local maxima ("lobes") of a function of φ from `SAMPLES` samples:
/// every sampled local maximum refined by golden section, maxima within
/// 1.5 sample steps of each other (a plateau, a peak between two samples)
/// merged into their highest. Returns (value, φ, prominence) in the order
/// of φ, the prominence being the height above the higher of the two
/// minima that part it from its neighbours (above the lowest sample for a
/// lone lobe; minima located by a parabola through three samples).
fn lobes(samples: &[f64], f: impl Fn(f64) -> f64) -> Vec<(f64, f64, f64)> {
    let n = samples.len();
    let h = TAU / n as f64;
    let mut found: Vec<(f64, f64, usize)> = Vec::new();
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
        found.push((v, p, i));
    }
    // Clusters of sampled maxima at adjacent samples (wrapping) are one lobe.
    let mut out: Vec<(f64, f64, usize)> = Vec::new();
    let mut first_start: Option<usize> = None;
    let mut prev_i: Option<usize> = None;
    for &(v, p, i) in &found {
        match prev_i {
            Some(pi) if i - pi <= 1 => {
                let last = out.last_mut().expect("a cluster is open");
                if v > last.0 {
                    *last = (v, p, i);
                }
            }
            _ => {
                if first_start.is_none() {
                    first_start = Some(i);
                }
                out.push((v, p, i));
            }
        }
        prev_i = Some(i);
    }
    // The last cluster wraps onto the first (samples n−1 and 0 adjacent).
    if out.len() > 1 && first_start == Some(0) && prev_i == Some(n - 1) {
        let last = out.pop().expect("len > 1");
        if last.0 > out[0].0 {
            out[0] = last;
        }
    }
    out.sort_by_key(|l| l.2);
    // The lowest sample strictly between samples a and b (cyclic, b = a:
    // the whole turn), its value refined by the parabola through it and
    // its neighbours.
    let valley = |a: usize, b: usize| {
        let span = if b > a { b - a } else { b + n - a };
        let j = (1..span)
            .map(|k| (a + k) % n)
            .min_by(|&p, &q| samples[p].total_cmp(&samples[q]))
            .unwrap_or(a);
        let (l, c, r) = (samples[(j + n - 1) % n], samples[j], samples[(j + 1) % n]);
        let curv = l - 2.0 * c + r;
        if curv > 0.0 {
            c - (l - r) * (l - r) / (8.0 * curv)
        } else {
            c
        }
    };
    let k = out.len();
    (0..k)
        .map(|i| {
            let (v, p, at) = out[i];
            let left = valley(out[(i + k - 1) % k].2, at);
            let right = valley(at, out[(i + 1) % k].2);
            (v, p, v - left.max(right))
        })
        .collect()
}

/// Prominence (in) below which a lobe hardly counts in the envelope (see
/// [`Envelope`]): a lobe born as X grows enters it as it rises.
pub const ENVELOPE_PROMINENCE_IN: f64 = ENVELOPE_TAU_IN;

/// Slope difference (in/in) below which two lobes' crossing is left as it
/// is (see [`Envelope`]): a kink of this slope jump costs a table at most
/// `S0·h/4`, 0.02 µin at the finest binary step.
pub const ENVELOPE_SLOPE_IN_PER_IN: f64 = 1e-5;

/// The axial slide's `Y(X)` from the lobes of `T(X, ·)`: a smooth upper
/// envelope.
///
/// `max_φ T` has a kink wherever the maximum jumps from one lobe to
/// another as X changes, and a table's mean column inherits it (linear
/// interpolation across a kink errs by the slope jump times the step). So
/// `Y` is a log-sum-exp of the lobe maxima `M_i` about the highest, `m`:
///
/// ```text
/// Y = m + τ ln(1 + Σ_{i ≠ top} ω_i exp((M_i − m)/τ)),
/// ω_i = Δ_i²/(Δ_i² + S0²) · P_i²/(P_i² + P0²),
/// Δ_i = ∂M_i/∂X − ∂M_top/∂X,  P_i the lobe's prominence,
/// τ = ENVELOPE_TAU_IN,  S0 = ENVELOPE_SLOPE_IN_PER_IN,  P0 = ENVELOPE_PROMINENCE_IN
/// ```
///
/// Where two lobes cross (`M_a = M_b`; ω the same from either side) it is
/// continuous whichever is on top, and smooth but for the factor `(1 −
/// ω)/(1 + ω)` of the slope jump: a crossing with a slope jump well above
/// S0 is rounded over `~τ/Δ` of X (curvature `Δ²/4τ`). Lobes that rise
/// together (a symmetric part's twins, every lobe near the axis) have ω ≈ 0
/// and leave `Y = m`; a lobe born as X grows (prominence 0) enters as it
/// rises instead of at once (a jump of up to `τ ln 2` else). And `m ≤ Y ≤ m + τ ln n` (n lobes): `Z = T − Y ≤ 0`
/// stays (the firmware's sign check), with `max_φ Z` between `−τ ln n` and
/// 0 (the stated margin: 0 with one lobe or twins, the paraboloid's case,
/// where `Y = m` to the bit).
#[derive(Clone, Debug, PartialEq)]
pub struct Envelope {
    pub y: f64,
    /// Each lobe's share of `Y`'s slope (`∂Y/∂M_i` with the weights ω held;
    /// Σ = 1) and its φ.
    pub lobes: Vec<(f64, f64)>,
}

/// A lobe of `T(X, ·)`: its maximum, the φ of it, and `∂M/∂X` there.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Lobe {
    m: f64,
    phi: f64,
    slope: f64,
    prominence: f64,
}

impl Envelope {
    fn of(lobes: &[Lobe]) -> Self {
        let top = lobes
            .iter()
            .enumerate()
            .fold(0, |b, (i, l)| if l.m > lobes[b].m { i } else { b });
        let (m, s) = (lobes[top].m, lobes[top].slope);
        let (tau, s0) = (ENVELOPE_TAU_IN, ENVELOPE_SLOPE_IN_PER_IN);
        let w: Vec<f64> = lobes
            .iter()
            .enumerate()
            .map(|(i, l)| {
                if i == top {
                    0.0
                } else {
                    let d = l.slope - s;
                    let p = l.prominence;
                    let p0 = ENVELOPE_PROMINENCE_IN;
                    d * d / (d * d + s0 * s0)
                        * (p * p / (p * p + p0 * p0))
                        * ((l.m - m) / tau).exp()
                }
            })
            .collect();
        let rest: f64 = w.iter().sum();
        let sum = 1.0 + rest;
        Self {
            y: m + tau * rest.ln_1p(),
            lobes: lobes
                .iter()
                .zip(&w)
                .enumerate()
                .map(|(i, (l, w))| (if i == top { 1.0 } else { *w } / sum, l.phi))
                .collect(),
        }
    }

    /// The stated margin: `Y − max_φ T ≤ τ ln n`.
    pub fn margin_bound_in(&self) -> f64 {
        ENVELOPE_TAU_IN * (self.lobes.len() as f64).ln()
    }
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

    /// The ridge (the smooth envelope of `f_φ(x)`'s lobes, [`Envelope`]),
    /// its slope (envelope theorem: the profile's slope at each lobe's φ,
    /// weighted) and the number of lobes.
    fn ridge(&self, x: f64) -> Result<(f64, f64, usize), String> {
        let s: Vec<f64> = (0..SAMPLES)
            .map(|j| self.profile(x, TAU * j as f64 / SAMPLES as f64).0)
            .collect();
        if let Some(j) = s.iter().position(|v| !v.is_finite()) {
            return Err(undefined(x, TAU * j as f64 / SAMPLES as f64, ""));
        }
        let lb: Vec<Lobe> = lobes(&s, |p| self.profile(x, p).0)
            .into_iter()
            .map(|(m, phi, prominence)| Lobe {
                m,
                phi,
                slope: self.profile(x, phi).1,
                prominence,
            })
            .collect();
        let env = Envelope::of(&lb);
        // The envelope's slope: Σ w_i ∂M_i/∂x, each lobe's by the envelope
        // theorem (the profile's slope at its maximising φ).
        let d = env
            .lobes
            .iter()
            .map(|&(w, at)| w * self.profile(x, at).1)
            .sum::<f64>();
        Ok((env.y, d, env.lobes.len()))
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
                // ∂T/∂X at fixed φ is the profile's slope at the contact
                // (the offset curve is parallel to the profile).
                let lb = lobes(&t, |p| {
                    self.centre_profile_normal(x, p)
                        .map_or(f64::NEG_INFINITY, |v| v.0)
                })
                .into_iter()
                .map(|(m, phi, prominence)| {
                    let xc = self.centre_profile_normal(x, phi)?.1;
                    Ok(Lobe {
                        m,
                        phi,
                        slope: self.profile(xc, phi).1,
                        prominence,
                    })
                })
                .collect::<Result<Vec<_>, String>>()?;
                let y = Envelope::of(&lb).y;
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
                    let (_, d, env_lobes) = self.ridge(x1)?;
                    let next = x + rt * d / d.hypot(1.0);
                    // The ridge's slope comes from located maxima (each φ
                    // to ~1e-8 rad): x1 settles to ~1e-13 in with one
                    // lobe, to ~1e-11 with several weighted (`Envelope`),
                    // not to the last bit.
                    let done =
                        (next - x1).abs() <= 1e-12 || (env_lobes > 1 && (next - x1).abs() <= 1e-10);
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
                let (ry, d, _) = self.ridge(x1)?;
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
