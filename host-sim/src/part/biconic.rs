//! Biconic and toric surfaces, vertex at the turning axis.
//!
//! * Biconic: `z = (cx x² + cy y²) / (1 + √(1 − (1+kx) cx² x² − (1+ky) cy² y²))`,
//!   `cx = 1/Rx`, `cy = 1/Ry` (Zemax's biconic).
//! * Toric: the circle of radius `Ry` in the y–z plane,
//!   `f(y) = Ry − √(Ry² − y²)`, swept about the axis parallel to y at
//!   `z = Rx`: `z = Rx − √((Rx − f(y))² − x²)` (a torus: sections along x
//!   are circles of radius `Rx − f(y)`).

use super::Sag;

fn radius(field: &str, v: f64) -> Result<f64, String> {
    if v.is_finite() && v != 0.0 {
        Ok(1.0 / v)
    } else {
        Err(format!(
            "surface.{field} = {v}: must be a finite non-zero number (negative: convex)"
        ))
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Biconic {
    pub cx: f64,
    pub cy: f64,
    pub kx: f64,
    pub ky: f64,
}

impl Biconic {
    pub fn new(rx: f64, ry: f64, kx: f64, ky: f64) -> Result<Self, String> {
        for (f, v) in [("conic_x", kx), ("conic_y", ky)] {
            if !v.is_finite() {
                return Err(format!("surface.{f} = {v}: must be finite"));
            }
        }
        Ok(Self {
            cx: radius("radius_x_in", rx)?,
            cy: radius("radius_y_in", ry)?,
            kx,
            ky,
        })
    }
}

impl Sag for Biconic {
    fn sag(&self, x: f64, y: f64) -> f64 {
        let w =
            1.0 - (1.0 + self.kx) * (self.cx * x).powi(2) - (1.0 + self.ky) * (self.cy * y).powi(2);
        if w < 0.0 {
            return f64::NAN;
        }
        (self.cx * x * x + self.cy * y * y) / (1.0 + w.sqrt())
    }

    fn grad(&self, x: f64, y: f64) -> (f64, f64) {
        let ax = (1.0 + self.kx) * self.cx * self.cx;
        let ay = (1.0 + self.ky) * self.cy * self.cy;
        let w = 1.0 - ax * x * x - ay * y * y;
        if w <= 0.0 {
            return (f64::NAN, f64::NAN);
        }
        let sw = w.sqrt();
        let n = self.cx * x * x + self.cy * y * y;
        let d = 1.0 + sw;
        (
            (2.0 * self.cx * x * d + n * ax * x / sw) / (d * d),
            (2.0 * self.cy * y * d + n * ay * y / sw) / (d * d),
        )
    }

    fn describe(&self) -> String {
        format!(
            "biconic Rx = {} in, Ry = {} in, kx = {}, ky = {}",
            1.0 / self.cx,
            1.0 / self.cy,
            self.kx,
            self.ky
        )
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Toric {
    pub rx: f64,
    pub ry: f64,
}

impl Toric {
    pub fn new(rx: f64, ry: f64) -> Result<Self, String> {
        for (f, v) in [("radius_x_in", rx), ("radius_y_in", ry)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "surface.{f} = {v}: must be a finite number > 0 (concave toward +z)"
                ));
            }
        }
        Ok(Self { rx, ry })
    }

    /// `f(y)` and `f'(y)` of the y–z circle.
    fn profile(&self, y: f64) -> (f64, f64) {
        let w = (self.ry - y) * (self.ry + y);
        if w < 0.0 {
            return (f64::NAN, f64::NAN);
        }
        let s = w.sqrt();
        (y * y / (self.ry + s), y / s)
    }
}

impl Sag for Toric {
    fn sag(&self, x: f64, y: f64) -> f64 {
        let (f, _) = self.profile(y);
        let u = self.rx - f;
        let w = (u - x) * (u + x);
        if w < 0.0 {
            return f64::NAN;
        }
        // Rx − √(u² − x²) = f + x²/(u + √(u² − x²)).
        f + x * x / (u + w.sqrt())
    }

    fn grad(&self, x: f64, y: f64) -> (f64, f64) {
        let (f, df) = self.profile(y);
        let u = self.rx - f;
        let s = ((u - x) * (u + x)).sqrt();
        (x / s, u / s * df)
    }

    fn describe(&self) -> String {
        format!(
            "toric Rx = {} in (swept), Ry = {} in (profile)",
            self.rx, self.ry
        )
    }
}
