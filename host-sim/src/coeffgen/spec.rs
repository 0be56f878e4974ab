//! What defines a table (surface, grid, series, number formats) and the
//! checks that refuse one that cannot be built, naming the field.

use super::fit::columns_of;
use crate::surface::{Surface, SurfaceError};
use std::fmt;
use zslide::table::{Representation, MAX_NODES, MAX_TERMS};

/// Everything that defines a table: surface, grid, series, number formats.
#[derive(Clone, Debug, PartialEq)]
pub struct TableSpec {
    pub surface: Surface,
    pub x_min: f64,
    pub x_max: f64,
    pub step: f64,
    /// Beyond this X the firmware nulls the slide.
    pub x_null: f64,
    pub representation: Representation,
    /// Sin-power: number of powers (columns) N, `sin^0..sin^(N−1)`.
    /// Harmonic: highest harmonic K (columns 2K+1). Same truncation for
    /// N = K + 1.
    pub terms: usize,
    pub coeff_frac_bits: u8,
    pub x_frac_bits: u8,
}

/// A table specification that cannot be built, naming the field and limit.
#[derive(Clone, Debug, PartialEq)]
pub enum SpecError {
    Surface(SurfaceError),
    Field {
        field: &'static str,
        value: f64,
        rule: String,
    },
}

impl fmt::Display for SpecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Surface(e) => e.fmt(f),
            Self::Field { field, value, rule } => write!(f, "{field} = {value}: {rule}"),
        }
    }
}

impl std::error::Error for SpecError {}

impl From<SurfaceError> for SpecError {
    fn from(e: SurfaceError) -> Self {
        Self::Surface(e)
    }
}

pub(super) fn field(field: &'static str, value: f64, rule: impl Into<String>) -> SpecError {
    SpecError::Field {
        field,
        value,
        rule: rule.into(),
    }
}

impl TableSpec {
    /// Table 2-2's scheme: dissertation surface, 0..8 in at 0.1 in, 4-term
    /// sin-power, null beyond 7.2 in, I2F30 coefficients, I8F24 X.
    pub fn dissertation() -> Self {
        Self {
            surface: Surface::dissertation(),
            x_min: 0.0,
            x_max: 8.0,
            step: 0.1,
            x_null: 7.2,
            representation: Representation::SinPower,
            terms: 4,
            coeff_frac_bits: 30,
            x_frac_bits: 24,
        }
    }

    /// Columns per node in the table image.
    pub fn columns(&self) -> usize {
        match self.representation {
            Representation::SinPower => self.terms,
            Representation::Harmonic => 2 * self.terms + 1,
        }
    }

    /// Number of grid intervals, once [`TableSpec::validate`] passed.
    pub fn intervals(&self) -> usize {
        ((self.x_max - self.x_min) / self.step).round() as usize
    }

    pub fn node_count(&self) -> usize {
        self.intervals() + 1
    }

    /// Checks every field; the first violation names the field and its limit.
    pub fn validate(&self) -> Result<(), SpecError> {
        let lim = self.surface.x_limit();
        let finite = |name: &'static str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(field(name, v, "must be a finite number"))
            }
        };
        finite("grid.x_min_in", self.x_min)?;
        finite("grid.x_max_in", self.x_max)?;
        finite("grid.step_in", self.step)?;
        finite("grid.x_null_in", self.x_null)?;
        if self.x_min < 0.0 {
            return Err(field(
                "grid.x_min_in",
                self.x_min,
                "must be >= 0 (X is a radius)",
            ));
        }
        if self.step <= 0.0 {
            return Err(field("grid.step_in", self.step, "must be > 0"));
        }
        if self.x_max <= self.x_min {
            return Err(field(
                "grid.x_max_in",
                self.x_max,
                format!("must be > grid.x_min_in = {}", self.x_min),
            ));
        }
        // Tool-centre X of the last node must lie in the surface's domain;
        // the fixed-point node may round up by half an X LSB.
        let x_lsb = (-f64::from(self.x_frac_bits)).exp2();
        if self.x_max + x_lsb > lim {
            return Err(field(
                "grid.x_max_in",
                self.x_max,
                format!("the surface is defined for X <= {lim:.6} in at this geometry (eq 2-11 maxima exist)"),
            ));
        }
        let n = (self.x_max - self.x_min) / self.step;
        if (n - n.round()).abs() > 1e-9 * n.max(1.0) {
            return Err(field(
                "grid.step_in",
                self.step,
                format!(
                    "must divide x_max_in - x_min_in = {} into whole steps ({n:.6} steps)",
                    self.x_max - self.x_min
                ),
            ));
        }
        if n.round() + 1.0 > f64::from(MAX_NODES) {
            return Err(field(
                "grid.step_in",
                self.step,
                format!(
                    "gives {} nodes; the table holds at most {MAX_NODES}",
                    n.round() + 1.0
                ),
            ));
        }
        if !(self.x_min..=self.x_max).contains(&self.x_null) {
            return Err(field(
                "grid.x_null_in",
                self.x_null,
                format!(
                    "must lie in [x_min_in, x_max_in] = [{}, {}]",
                    self.x_min, self.x_max
                ),
            ));
        }
        let max_terms = match self.representation {
            Representation::SinPower => usize::from(MAX_TERMS),
            Representation::Harmonic => (usize::from(MAX_TERMS) - 1) / 2,
        };
        if self.terms == 0 || self.terms > max_terms {
            return Err(field(
                "series.terms",
                self.terms as f64,
                format!("must be 1..={max_terms} for this representation"),
            ));
        }
        if self.coeff_frac_bits > 31 {
            return Err(field(
                "format.coeff_frac_bits",
                f64::from(self.coeff_frac_bits),
                "must be 0..=31",
            ));
        }
        if !(1..=31).contains(&self.x_frac_bits) {
            return Err(field(
                "format.x_frac_bits",
                f64::from(self.x_frac_bits),
                "must be 1..=31",
            ));
        }
        let x_range = (31.0 - f64::from(self.x_frac_bits)).exp2();
        if self.x_max + self.step >= x_range {
            return Err(field(
                "grid.x_max_in",
                self.x_max,
                format!(
                    "does not fit format.x_frac_bits = {} (X must stay below {x_range} in)",
                    self.x_frac_bits
                ),
            ));
        }
        let step_raw = self.step * (f64::from(self.x_frac_bits)).exp2();
        if step_raw < 1.0 {
            return Err(field(
                "grid.step_in",
                self.step,
                format!("is below one X LSB (2^-{} in)", self.x_frac_bits),
            ));
        }
        Ok(())
    }

    /// Decimal grid nodes `x_min + i·step` (CSV/JSON export).
    pub fn nodes_decimal(&self) -> Vec<f64> {
        (0..self.node_count())
            .map(|i| self.x_min + i as f64 * self.step)
            .collect()
    }

    pub(super) fn x_scale(&self) -> f64 {
        f64::from(self.x_frac_bits).exp2()
    }

    /// `(x0_raw, dx_raw)` of the image: the nodes the firmware interpolates
    /// between are `(x0_raw + i·dx_raw)/2^fx`, exact binary numbers.
    pub fn grid_raw(&self) -> (i32, i32) {
        let s = self.x_scale();
        (
            (self.x_min * s).round() as i32,
            (self.step * s).round() as i32,
        )
    }

    /// Node X values of the image (exactly the firmware's).
    pub fn nodes_fixed(&self) -> Vec<f64> {
        let (x0, dx) = self.grid_raw();
        let s = self.x_scale();
        (0..self.node_count())
            .map(|i| (f64::from(x0) + i as f64 * f64::from(dx)) / s)
            .collect()
    }

    /// The columns of one node for this representation, inches.
    pub fn columns_at(&self, x: f64) -> Result<Vec<f64>, SpecError> {
        let sec = self.surface.section(x)?;
        Ok(columns_of(&sec, self.representation, self.terms))
    }
}
