//! The part's nominal tool-centre command at the true X and φ: exact (for
//! the CMM points) and fast (every loop tick: a sin-power expansion of the
//! section, re-expanded as X moves).

use crate::coeffgen::harmonics;
use crate::surface::Surface;
use std::f64::consts::TAU;

/// Sin-power terms of the per-tick nominal (harmonics 0..8: below 1e-4 µin
/// truncation at 7.2 in, like the default table's five).
const TERMS: usize = 9;
/// Spacing of the X nodes whose expansions the per-tick nominal
/// interpolates linearly, in: the interpolation errs by H²/8·|∂²Z/∂X²|,
/// below 0.01 µin here (the test bounds the whole within 0.1 µin), and a
/// node is expanded once per 50 revolutions of the pass instead of every
/// half revolution (the re-expansion was ≈ 120 instructions a tick).
const NODE_IN: f64 = 0.005;

/// The nominal command of the firmware's table geometry.
pub struct Nominal {
    surf: Surface,
    /// X beyond which the table's command is null, in.
    x_null: f64,
    /// Expansions at the nodes `lo` and `lo + NODE_IN` (index of `lo` on
    /// the node grid; `i64::MIN`: none yet), and their difference.
    lo: i64,
    at_lo: [f64; TERMS],
    at_hi: [f64; TERMS],
    slope: [f64; TERMS],
}

impl Nominal {
    pub fn new(surf: Surface, x_null: f64) -> Self {
        Self {
            surf,
            x_null,
            lo: i64::MIN,
            at_lo: [0.0; TERMS],
            at_hi: [0.0; TERMS],
            slope: [0.0; TERMS],
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

    /// The sin-power expansion of the section at node `k`.
    fn expand(&self, k: i64) -> [f64; TERMS] {
        let mut out = [0.0; TERMS];
        if let Ok(sec) = self.surf.section(k as f64 * NODE_IN) {
            let c = harmonics(&sec, TERMS - 1).sin_power(TERMS);
            out.iter_mut().zip(c).for_each(|(d, s)| *d = s);
        }
        out
    }

    /// Z within 0.1 µin of [`Self::exact`], cheap enough for every tick.
    pub fn fast(&mut self, x: f64, phi_turns: f64) -> f64 {
        if self.null(x) {
            return 0.0;
        }
        let k = crate::fastmath::floor_i64(x / NODE_IN);
        if k != self.lo {
            // The pass feeds inward: the old lower node is the new upper.
            if Some(k) == self.lo.checked_sub(1) {
                self.at_hi = self.at_lo;
            } else {
                self.at_hi = self.expand(k + 1);
            }
            self.at_lo = self.expand(k);
            for j in 0..TERMS {
                self.slope[j] = (self.at_hi[j] - self.at_lo[j]) / NODE_IN;
            }
            self.lo = k;
        }
        let u = x - k as f64 * NODE_IN;
        // libm's sin: pure Rust, the same bits on every x86-64 (the C
        // library picks an FMA variant by CPU), and cheaper.
        let s = libm::sin(phi_turns * TAU);
        // `eval_sin_power` (Horner from the top term) on the interpolated
        // coefficients, in one pass.
        (0..TERMS)
            .rev()
            .fold(0.0, |acc, j| acc * s + (self.at_lo[j] + self.slope[j] * u))
    }
}

/// The command the cutter compares the slide with: the default table's
/// part, or a part of one's own (`super::partcut`).
pub enum Command {
    Default(Nominal),
    Part(super::partcut::PartNominal),
}

impl Command {
    pub fn exact(&self, x: f64, phi_turns: f64) -> f64 {
        match self {
            Self::Default(n) => n.exact(x, phi_turns),
            Self::Part(n) => n.exact(x, phi_turns),
        }
    }

    pub fn fast(&mut self, x: f64, phi_turns: f64) -> f64 {
        match self {
            Self::Default(n) => n.fast(x, phi_turns),
            Self::Part(n) => n.fast(x, phi_turns),
        }
    }
}

impl From<Nominal> for Command {
    fn from(n: Nominal) -> Self {
        Self::Default(n)
    }
}

impl From<super::partcut::PartNominal> for Command {
    fn from(n: super::partcut::PartNominal) -> Self {
        Self::Part(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The per-tick interpolated expansion against the exact surface
    /// across the part, feeding inward and outward: within 0.01 µin (the
    /// node interpolation's H²/8·|∂²Z/∂X²| plus the series' truncation).
    #[test]
    fn fast_nominal_is_within_a_hundredth_of_a_microinch_of_the_exact_one() {
        let t = zslide::table::CoeffTable::parse(zslide::DEFAULT_TABLE).unwrap();
        let surf = Surface::from_table_geometry(&t.header().geometry).unwrap();
        let mut n = Nominal::new(surf, t.x_null().to_f64());
        let mut worst = 0.0f64;
        for k in (0..2000).chain((0..2000).rev()) {
            let x = 7.2 - 7.1 * f64::from(k) / 2000.0;
            for j in 0..16 {
                let phi = (f64::from(j) + 0.37) / 16.0;
                worst = worst.max((n.fast(x, phi) - n.exact(x, phi)).abs());
            }
        }
        assert!(worst < 0.01e-6, "{} µin", worst * 1e6);
    }
}
