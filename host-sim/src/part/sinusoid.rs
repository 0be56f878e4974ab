//! Sinusoidal grid: `z = amplitude_in · sin(2π x / period_x_in) · sin(2π y / period_y_in)`.
//!
//! Its φ-harmonics at radius X are Bessel-function coefficients (Jacobi–
//! Anger: `sin(a X cos φ) = 2 Σ_m (−1)^m J_{2m+1}(aX) cos (2m+1)φ`,
//! `sin(b X sin φ) = 2 Σ_m J_{2m+1}(bX) sin (2m+1)φ`), so the harmonics a
//! table needs grow with `2πX/period`: [`SinusoidalGrid::harmonics_needed`].

use super::Sag;
use std::f64::consts::TAU;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SinusoidalGrid {
    pub amplitude: f64,
    pub period_x: f64,
    pub period_y: f64,
}

impl SinusoidalGrid {
    pub fn new(amplitude: f64, period_x: f64, period_y: f64) -> Result<Self, String> {
        if !amplitude.is_finite() {
            return Err(format!(
                "surface.amplitude_in = {amplitude}: must be finite"
            ));
        }
        for (f, v) in [("period_x_in", period_x), ("period_y_in", period_y)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("surface.{f} = {v}: must be a finite number > 0"));
            }
        }
        Ok(Self {
            amplitude,
            period_x,
            period_y,
        })
    }

    fn kx(&self) -> f64 {
        TAU / self.period_x
    }
    fn ky(&self) -> f64 {
        TAU / self.period_y
    }
}

impl Sag for SinusoidalGrid {
    fn sag(&self, x: f64, y: f64) -> f64 {
        self.amplitude * (self.kx() * x).sin() * (self.ky() * y).sin()
    }

    fn grad(&self, x: f64, y: f64) -> (f64, f64) {
        let (sx, cx) = (self.kx() * x).sin_cos();
        let (sy, cy) = (self.ky() * y).sin_cos();
        (
            self.amplitude * self.kx() * cx * sy,
            self.amplitude * self.ky() * sx * cy,
        )
    }

    fn describe(&self) -> String {
        format!(
            "sinusoidal grid {} in × sin(2πx/{} in) sin(2πy/{} in)",
            self.amplitude, self.period_x, self.period_y
        )
    }
}
