//! Off-axis conic (eq 2-1..2-4 generalised to any conic constant).
//!
//! Parent conic of revolution, vertex radius `R`, conic constant `k`:
//! `x1² + y1² − 2R·z1 + (1+k)·z1² = 0` (`k = −1`: the paraboloid
//! `x1² + y1² = c·z1` with `c = 2R`). The sector is centred at `y1 = S_y`,
//! `z1 = S_z` (the conic's sag there). The part frame is the parent frame
//! moved to that point and rotated by θ about x (eq 2-2, 2-3):
//!
//! ```text
//! x1 = x,  y1 = y cos θ − z sin θ + S_y,  z1 = y sin θ + z cos θ + S_z
//! ```
//!
//! and θ is the dissertation's tilt, `tan θ = ∂z1/∂y1` at the sector centre
//! (the turning axis is the surface normal there), unless `tilt_deg` gives
//! another. The sag `z(x, y)` is the root of the quadratic this gives near
//! the sector, in a form without the cancellation of eq 2-4.

use super::Sag;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffAxisConic {
    /// Vertex radius R, in (> 0: concave toward +z).
    pub r: f64,
    /// Conic constant k.
    pub k: f64,
    /// Off-axis distance of the sector centre S_y, in (≥ 0).
    pub s_y: f64,
    /// Sag of the parent at the sector centre, in.
    s_z: f64,
    sin_t: f64,
    cos_t: f64,
    /// Whether θ is the dissertation's (the normal at the sector centre).
    natural_tilt: bool,
}

impl OffAxisConic {
    /// `tilt`: θ in radians, or `None` for the dissertation's.
    pub fn new(r: f64, k: f64, s_y: f64, tilt: Option<f64>) -> Result<Self, String> {
        if !(r.is_finite() && r > 0.0) {
            return Err(format!(
                "surface.vertex_radius_in = {r}: must be a finite number > 0"
            ));
        }
        if !k.is_finite() {
            return Err(format!("surface.conic_constant = {k}: must be finite"));
        }
        if !(s_y.is_finite() && s_y >= 0.0) {
            return Err(format!(
                "surface.off_axis_in = {s_y}: must be a finite number >= 0"
            ));
        }
        let kk = 1.0 + k;
        let w = kk * (s_y / r).powi(2);
        if w >= 1.0 {
            return Err(format!(
                "surface.off_axis_in = {s_y}: beyond the edge of this conic (R = {r} in, k = {k})"
            ));
        }
        let s_z = s_y * s_y / (r * (1.0 + (1.0 - w).sqrt()));
        // Slope of the parent at the sector centre: y1 / (R − (1+k) z1).
        let slope = s_y / (r - kk * s_z);
        let theta = match tilt {
            Some(t) if !(t.is_finite() && t.abs() < std::f64::consts::FRAC_PI_2) => {
                return Err(format!(
                    "surface.tilt_deg = {}: must lie strictly between -90 and 90",
                    t.to_degrees()
                ))
            }
            Some(t) => t,
            None => slope.atan(),
        };
        let (sin_t, cos_t) = theta.sin_cos();
        Ok(Self {
            r,
            k,
            s_y,
            s_z,
            sin_t,
            cos_t,
            natural_tilt: tilt.is_none(),
        })
    }

    /// The parent's frame coordinates of part-frame `(x, y, z)`.
    fn parent(&self, y: f64, z: f64) -> (f64, f64) {
        (
            y * self.cos_t - z * self.sin_t + self.s_y,
            y * self.sin_t + z * self.cos_t + self.s_z,
        )
    }
}

impl Sag for OffAxisConic {
    fn sag(&self, x: f64, y: f64) -> f64 {
        let (s, c) = (self.sin_t, self.cos_t);
        let kk = 1.0 + self.k;
        let (sy, sz, r) = (self.s_y, self.s_z, self.r);
        // F(z) = qa z² + qb z + qc = 0 with p = y cos θ + S_y, q = y sin θ + S_z.
        let p = y * c + sy;
        let q = y * s + sz;
        let qa = s * s + kk * c * c;
        let qb = -2.0 * p * s - 2.0 * r * c + 2.0 * kk * q * c;
        // qc = x² + p² − 2Rq + K q², less its value at the sector centre
        // (zero: the centre is on the conic), written without cancelling.
        let yc = y * c;
        let ys = y * s;
        let qc = x * x + yc * (yc + 2.0 * sy) - 2.0 * r * ys + kk * ys * (ys + 2.0 * sz);
        let disc = qb * qb - 4.0 * qa * qc;
        if disc < 0.0 {
            return f64::NAN;
        }
        // The root near the sector (qb < 0 there): 2qc / (−qb + √disc).
        2.0 * qc / (-qb + disc.sqrt())
    }

    fn grad(&self, x: f64, y: f64) -> (f64, f64) {
        let z = self.sag(x, y);
        let (y1, z1) = self.parent(y, z);
        let kk = 1.0 + self.k;
        let (fy1, fz1) = (2.0 * y1, -2.0 * self.r + 2.0 * kk * z1);
        let gx = 2.0 * x;
        let gy = fy1 * self.cos_t + fz1 * self.sin_t;
        let gz = -fy1 * self.sin_t + fz1 * self.cos_t;
        (-gx / gz, -gy / gz)
    }

    fn describe(&self) -> String {
        format!(
            "off-axis conic R = {} in, k = {}, S_y = {} in, θ = {:.6}°",
            self.r,
            self.k,
            self.s_y,
            self.sin_t.atan2(self.cos_t).to_degrees()
        )
    }

    fn paraboloid_geometry(&self) -> Option<(f64, f64)> {
        (self.k == -1.0 && self.natural_tilt && self.s_y > 0.0).then_some((2.0 * self.r, self.s_y))
    }
}
