//! A part of one's own in the simulated cut (`cut --part`): its table
//! image for the firmware, its exact command for the cutter and the CMM,
//! and the radii the CMM measures.
//!
//! The CMM grid is polar like chapter 5's (36 angles), at seven radii
//! spread over the part's table range, `x_min + (x_null − x_min)·k/8`,
//! k = 1..7. The radii are tool-centre radii: with the profile-normal
//! compensation the contact point of a tool centre moves with φ, so the
//! envelope is read at the tool centre (the default part reads it at the
//! surface radius through FOREX4's constant contact gain).

use crate::part::split::Part;
use crate::part::table::columns;
use std::f64::consts::TAU;
use std::sync::Arc;
use zslide::table::CoeffTable;

/// Harmonics of the per-tick nominal (the most a table holds).
const K: usize = crate::part::table::MAX_HARMONICS;
/// Spacing of the per-tick nominal's X nodes, in (as `nominal::NODE_IN`:
/// the interpolation errs by H²/8·|∂²Z/∂X²|, below 0.01 µin for the
/// example parts).
const NODE_IN: f64 = 0.005;

/// Number of CMM radii.
pub const CMM_RADII: usize = 7;

#[derive(Debug)]
pub struct PartCut {
    pub name: String,
    pub part: Part,
    /// The table image the firmware runs (leaked: it lives as long as the
    /// run, like `zslide::DEFAULT_TABLE`).
    pub table: &'static [u8],
    /// X beyond which the table nulls the slide, in.
    pub x_null: f64,
    /// The table's first node, in (the cut range is `x_min ≤ X < x_null`).
    pub x_min: f64,
    /// CMM radii (tool centre), in.
    pub cmm_x: Vec<f64>,
}

impl PartCut {
    pub fn new(name: &str, part: Part, image: Vec<u8>) -> anyhow::Result<Self> {
        let t = CoeffTable::parse(&image)
            .map_err(|e| anyhow::anyhow!("table of part {name} refused: {e}"))?;
        let x_null = t.x_null().to_f64();
        let x_min = t.node_x(0).to_f64();
        let rt = t.header().geometry.tool_radius_nin as f64 / 1e9;
        anyhow::ensure!(
            (rt - part.tool.nose_radius).abs() < 1e-9,
            "the table was made for a {rt} in nose, the part file says tool.nose_radius_in = {}",
            part.tool.nose_radius
        );
        let cmm_x = (1..=CMM_RADII)
            .map(|k| x_min + (x_null - x_min) * k as f64 / (CMM_RADII + 1) as f64)
            .collect();
        Ok(Self {
            name: name.to_string(),
            part,
            table: Box::leak(image.into_boxed_slice()),
            x_null,
            x_min,
            cmm_x,
        })
    }
}

/// The part's command at the true X and φ: exact, and per tick.
pub struct PartNominal {
    cut: Arc<PartCut>,
    lo: i64,
    at_lo: Vec<f64>,
    slope: Vec<f64>,
    at_hi: Vec<f64>,
}

impl PartNominal {
    pub fn new(cut: Arc<PartCut>) -> Self {
        Self {
            cut,
            lo: i64::MIN,
            at_lo: vec![0.0; 2 * K + 1],
            slope: vec![0.0; 2 * K + 1],
            at_hi: vec![0.0; 2 * K + 1],
        }
    }

    fn null(&self, x: f64) -> bool {
        x >= self.cut.x_null || x < 0.0
    }

    /// Exact Z at tool-centre `x`, part angle `phi_turns` (the CMM's
    /// frame); zero beyond the null.
    pub fn exact(&self, x: f64, phi_turns: f64) -> f64 {
        if self.null(x) {
            return 0.0;
        }
        self.cut.part.z(x, phi_turns * TAU).unwrap_or(0.0)
    }

    fn expand(&self, k: i64) -> Vec<f64> {
        self.cut
            .part
            .section(k as f64 * NODE_IN)
            .map_or(vec![0.0; 2 * K + 1], |s| columns(&s, K))
    }

    /// Z from node expansions interpolated in X (per tick), at the
    /// firmware's angle `phi_turns` (the table's columns: `table::columns`).
    pub fn fast(&mut self, x: f64, phi_turns: f64) -> f64 {
        if self.null(x) {
            return 0.0;
        }
        let k = crate::fastmath::floor_i64(x / NODE_IN);
        if k != self.lo {
            if Some(k) == self.lo.checked_sub(1) {
                self.at_hi = std::mem::take(&mut self.at_lo);
            } else {
                self.at_hi = self.expand(k + 1);
            }
            self.at_lo = self.expand(k);
            for ((s, hi), lo) in self.slope.iter_mut().zip(&self.at_hi).zip(&self.at_lo) {
                *s = (hi - lo) / NODE_IN;
            }
            self.lo = k;
        }
        let u = x - k as f64 * NODE_IN;
        let col = |j: usize| self.at_lo[j] + self.slope[j] * u;
        // libm's sincos (the same bits on every x86-64, as `Nominal`), the
        // harmonics by the Chebyshev recurrence.
        let (s1, c1) = libm::sincos(phi_turns * TAU);
        let (mut sp, mut cp, mut sk, mut ck) = (0.0, 1.0, s1, c1);
        let mut z = col(0);
        for h in 1..=K {
            z += col(2 * h - 1) * ck + col(2 * h) * sk;
            let (sn, cn) = (2.0 * c1 * sk - sp, 2.0 * c1 * ck - cp);
            (sp, cp, sk, ck) = (sk, ck, sn, cn);
        }
        z
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::part::config::PartFile;

    /// The per-tick nominal against the exact command across the part,
    /// feeding inward: within 0.01 µin.
    #[test]
    fn fast_part_nominal_is_within_a_hundredth_of_a_microinch_of_the_exact_one() {
        let lp = PartFile::from_toml(
            "[surface]\nkind = \"sinusoidal-grid\"\namplitude_in = 0.0002\nperiod_x_in = 4.0\nperiod_y_in = 4.0\n\
             [tool]\nnose_radius_in = 0.125\nclearance_deg = 7.0\n[table]\nx_max_in = 2.0\nbound_uin = 0.1\n",
        )
        .unwrap()
        .load("s", std::path::Path::new("."))
        .unwrap();
        let spec = crate::part::table::PartTableSpec {
            step: 0.25,
            harmonics: 12,
            ..lp.table.clone()
        };
        let image = crate::part::table::generate(&lp.part, &spec)
            .unwrap()
            .image()
            .unwrap();
        let cut = Arc::new(PartCut::new("s", lp.part.clone(), image).unwrap());
        let mut n = PartNominal::new(cut);
        let mut worst = 0.0f64;
        for k in 0..200 {
            let x = 1.99 - 1.9 * f64::from(k) / 200.0;
            for j in 0..8 {
                let phi = (f64::from(j) + 0.37) / 8.0;
                // `fast` in the firmware's angle, `exact` in the part's.
                let exact = n.exact(x, crate::cut::frame::part_turns(phi));
                worst = worst.max((n.fast(x, phi) - exact).abs());
            }
        }
        assert!(worst < 0.01e-6, "{} µin", worst * 1e6);
    }
}
