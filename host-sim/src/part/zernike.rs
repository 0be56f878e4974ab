//! Zernike surface on a normalisation radius, optionally on a base sphere.
//!
//! `z = base(r) + Σ_j a_j Z_j(ρ, θ)`, `ρ = r / normalization_radius_in`,
//! `θ = atan2(y, x)`, coefficients in inches, `j` from 1. Two orderings:
//!
//! * `standard`: Noll's index and normalisation (`Z_j = √(2(n+1)) R_n^m(ρ)
//!   cos mθ` for even j, `sin mθ` for odd j, `√(n+1) R_n^0` for m = 0; unit
//!   RMS over the disc). Z4 = √3 (2ρ² − 1).
//! * `fringe`: the Fringe (University of Arizona) index, unnormalised (peak
//!   1 on the edge): Z4 = 2ρ² − 1, Z9 = 6ρ⁴ − 6ρ² + 1; within a group of
//!   equal `(n + m)/2` the higher `m` first, cos before sin, `m = 0` last.
//!
//! The base is a sphere of `base_radius_in` (none: a plane).

use super::Sag;

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Ordering {
    Standard,
    Fringe,
}

/// One term: radial order n, azimuthal m ≥ 0, cos (true) or sin, scale,
/// and `R_n^m` as (power, coefficient) pairs.
#[derive(Clone, Debug, PartialEq)]
pub struct Term {
    pub n: u32,
    pub m: u32,
    pub cos: bool,
    pub norm: f64,
    pub radial: Vec<(i32, f64)>,
}

/// Highest index accepted (Fringe's usual 37; Noll to radial order 14).
pub const MAX_INDEX: usize = 120;

/// `(n, m, cos)` of Noll index `j ≥ 1`.
pub fn noll(j: usize) -> (u32, u32, bool) {
    let mut n = 0u32;
    let mut first = 1usize; // first index of radial order n
    while first + (n as usize) < j {
        first += n as usize + 1;
        n += 1;
    }
    // |m| ascending from n % 2; each m > 0 takes two indices (even j cos).
    let mut idx = first;
    let mut m = n % 2;
    loop {
        let count = if m == 0 { 1 } else { 2 };
        if j < idx + count {
            return (n, m, m == 0 || j % 2 == 0);
        }
        idx += count;
        m += 2;
    }
}

/// `(n, m, cos)` of Fringe index `j ≥ 1`.
pub fn fringe(j: usize) -> (u32, u32, bool) {
    let mut idx = 1usize;
    let mut d = 0u32;
    loop {
        for m in (0..=d).rev() {
            let n = 2 * d - m;
            let count = if m == 0 { 1 } else { 2 };
            if j < idx + count {
                return (n, m, j == idx);
            }
            idx += count;
        }
        d += 1;
    }
}

/// `R_n^m` as (power, coefficient) pairs:
/// `Σ_k (−1)^k (n−k)! / (k! ((n+m)/2−k)! ((n−m)/2−k)!) ρ^(n−2k)`.
pub fn radial_terms(n: u32, m: u32) -> Vec<(i32, f64)> {
    let fact = |v: u32| (1..=v).fold(1.0f64, |a, b| a * f64::from(b));
    (0..=(n - m) / 2)
        .map(|k| {
            let c = if k % 2 == 0 { 1.0 } else { -1.0 } * fact(n - k)
                / (fact(k) * fact((n + m) / 2 - k) * fact((n - m) / 2 - k));
            ((n - 2 * k) as i32, c)
        })
        .collect()
}

/// `R(ρ)` and `R'(ρ)` of (power, coefficient) pairs.
fn radial(terms: &[(i32, f64)], rho: f64) -> (f64, f64) {
    terms.iter().fold((0.0, 0.0), |(r, dr), &(p, c)| {
        let d = if p > 0 {
            c * f64::from(p) * rho.powi(p - 1)
        } else {
            0.0
        };
        (r + c * rho.powi(p), dr + d)
    })
}

#[derive(Clone, Debug, PartialEq)]
pub struct Zernike {
    pub ordering: Ordering,
    pub r_norm: f64,
    /// Base sphere curvature, 1/in (0: plane).
    pub base_c: f64,
    pub coeffs: Vec<(Term, f64)>,
}

impl Zernike {
    pub fn new(
        ordering: Ordering,
        r_norm: f64,
        base_radius: Option<f64>,
        coefficients: &[f64],
    ) -> Result<Self, String> {
        if !(r_norm.is_finite() && r_norm > 0.0) {
            return Err(format!(
                "surface.normalization_radius_in = {r_norm}: must be a finite number > 0"
            ));
        }
        if coefficients.is_empty() || coefficients.len() > MAX_INDEX {
            return Err(format!(
                "surface.coefficients_in: {} coefficients; 1..={MAX_INDEX} expected",
                coefficients.len()
            ));
        }
        let base_c = match base_radius {
            None => 0.0,
            Some(r) if r.is_finite() && r != 0.0 => 1.0 / r,
            Some(r) => {
                return Err(format!(
                    "surface.base_radius_in = {r}: must be a finite non-zero number"
                ))
            }
        };
        let mut coeffs = Vec::new();
        for (i, &a) in coefficients.iter().enumerate() {
            if !a.is_finite() {
                return Err(format!(
                    "surface.coefficients_in[{i}] = {a}: must be finite"
                ));
            }
            let j = i + 1;
            let (n, m, cos) = match ordering {
                Ordering::Standard => noll(j),
                Ordering::Fringe => fringe(j),
            };
            let norm = match ordering {
                Ordering::Fringe => 1.0,
                Ordering::Standard if m == 0 => f64::from(n + 1).sqrt(),
                Ordering::Standard => (2.0 * f64::from(n + 1)).sqrt(),
            };
            if a != 0.0 {
                coeffs.push((
                    Term {
                        n,
                        m,
                        cos,
                        norm,
                        radial: radial_terms(n, m),
                    },
                    a,
                ));
            }
        }
        Ok(Self {
            ordering,
            r_norm,
            base_c,
            coeffs,
        })
    }

    /// Value and `(∂/∂ρ, ∂/∂θ)` of the Zernike sum.
    fn polar(&self, rho: f64, th: f64) -> (f64, f64, f64) {
        let (mut z, mut zr, mut zt) = (0.0, 0.0, 0.0);
        for (t, a) in &self.coeffs {
            let a = *a;
            let (r, dr) = radial(&t.radial, rho);
            let mt = f64::from(t.m) * th;
            let (ang, dang) = if t.cos {
                (mt.cos(), -f64::from(t.m) * mt.sin())
            } else {
                (mt.sin(), f64::from(t.m) * mt.cos())
            };
            z += a * t.norm * r * ang;
            zr += a * t.norm * dr * ang;
            zt += a * t.norm * r * dang;
        }
        (z, zr, zt)
    }

    fn base(&self, r2: f64) -> (f64, f64) {
        // Sphere sag c r²/(1 + √(1 − c² r²)) and its d/d(r²)·2 factor.
        let w = 1.0 - self.base_c * self.base_c * r2;
        if w < 0.0 {
            return (f64::NAN, f64::NAN);
        }
        let s = w.sqrt();
        // dz/dr = c r / s: returned as c / s (times r by the caller).
        (self.base_c * r2 / (1.0 + s), self.base_c / s)
    }
}

impl Sag for Zernike {
    fn sag(&self, x: f64, y: f64) -> f64 {
        let r2 = x * x + y * y;
        let rho = r2.sqrt() / self.r_norm;
        self.base(r2).0 + self.polar(rho, y.atan2(x)).0
    }

    fn grad(&self, x: f64, y: f64) -> (f64, f64) {
        let r = x.hypot(y);
        // The sum is a polynomial in x, y: at the axis take the limit along
        // x (a nudge of 1e-9 of the radius changes the slope by ~1e-9).
        let (x, y, r) = if r < 1e-9 * self.r_norm {
            let e = 1e-9 * self.r_norm;
            (e, 0.0, e)
        } else {
            (x, y, r)
        };
        let (_, zr, zt) = self.polar(r / self.r_norm, y.atan2(x));
        let (c, s) = (x / r, y / r);
        let dzdr = zr / self.r_norm;
        let (_, b) = self.base(r * r);
        (b * x + c * dzdr - s * zt / r, b * y + s * dzdr + c * zt / r)
    }

    fn describe(&self) -> String {
        format!(
            "zernike ({:?} ordering) on {} in, {} non-zero terms{}",
            self.ordering,
            self.r_norm,
            self.coeffs.len(),
            if self.base_c == 0.0 {
                String::new()
            } else {
                format!(", base sphere R = {} in", 1.0 / self.base_c)
            }
        )
    }
}
