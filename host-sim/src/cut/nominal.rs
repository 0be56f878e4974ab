//! The part's nominal tool-centre command at the true X and φ: exact (for
//! the CMM points) and fast (every loop tick: a sin-power expansion of the
//! section, re-expanded as X moves).

use crate::coeffgen::{eval_sin_power, harmonics};
use crate::surface::Surface;
use std::f64::consts::TAU;

/// Sin-power terms of the per-tick nominal (harmonics 0..8: below 1e-4 µin
/// truncation at 7.2 in, like the default table's five).
const TERMS: usize = 9;
/// X travel after which the per-tick nominal is re-expanded, in:
/// |∂Z/∂X| < 0.002 makes it < 0.1 µin. (At 5 µin the re-expansion was
/// 15 % of a simulated second under callgrind.)
const REFRESH_IN: f64 = 50e-6;

/// The nominal command of the firmware's table geometry.
pub struct Nominal {
    surf: Surface,
    /// X beyond which the table's command is null, in.
    x_null: f64,
    coeffs: [f64; TERMS],
    /// X of the current expansion, in (NaN: none yet).
    at_x: f64,
}

impl Nominal {
    pub fn new(surf: Surface, x_null: f64) -> Self {
        Self {
            surf,
            x_null,
            coeffs: [0.0; TERMS],
            at_x: f64::NAN,
        }
    }

    fn null(&self, x: f64) -> bool {
        x >= self.x_null || x < 0.0
    }

    /// Exact Z at tool-centre `x`, angle `phi_turns`; zero on the face
    /// beyond the table's null zone.
    pub fn exact(&self, x: f64, phi_turns: f64) -> f64 {
        if self.null(x) {
            return 0.0;
        }
        self.surf.z(x, phi_turns * TAU).unwrap_or(0.0)
    }

    /// Z within 0.1 µin of [`Self::exact`], cheap enough for every tick.
    pub fn fast(&mut self, x: f64, phi_turns: f64) -> f64 {
        if self.null(x) {
            return 0.0;
        }
        if (x - self.at_x).abs() >= REFRESH_IN || self.at_x.is_nan() {
            match self.surf.section(x) {
                Ok(sec) => {
                    let c = harmonics(&sec, TERMS - 1).sin_power(TERMS);
                    self.coeffs.iter_mut().zip(c).for_each(|(d, s)| *d = s);
                }
                Err(_) => self.coeffs = [0.0; TERMS],
            }
            self.at_x = x;
        }
        eval_sin_power(&self.coeffs, (phi_turns * TAU).sin())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The per-tick expansion against the exact surface across the part:
    /// within 0.1 µin (the refresh step times the largest slope, plus the
    /// series' truncation).
    #[test]
    fn fast_nominal_is_within_a_tenth_of_a_microinch_of_the_exact_one() {
        let t = zslide::table::CoeffTable::parse(zslide::DEFAULT_TABLE).unwrap();
        let surf = Surface::from_table_geometry(&t.header().geometry).unwrap();
        let mut n = Nominal::new(surf, t.x_null().to_f64());
        let mut worst = 0.0f64;
        for k in 0..2000 {
            let x = 7.2 - 7.1 * f64::from(k) / 2000.0;
            for j in 0..16 {
                let phi = (f64::from(j) + 0.37) / 16.0;
                worst = worst.max((n.fast(x, phi) - n.exact(x, phi)).abs());
            }
        }
        assert!(worst < 0.1e-6, "{} µin", worst * 1e6);
    }
}
