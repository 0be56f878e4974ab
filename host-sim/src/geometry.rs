//! Table configuration file (TOML): the surface, the grid, the series and the
//! number formats of a coefficient table. Every field has the dissertation's
//! value as default, so an empty file is Table 2-2's scheme. Unknown keys are
//! refused (a misspelt field must not silently fall back to a default).
//!
//! ```toml
//! [surface]
//! c_in = 316.7            # or focal_length_in = 79.175 (c = 4 f); not both
//! s_y_in = 28.0
//! tool_radius_in = 0.125
//! compensation = "forex4" # or "profile-normal" (docs/COEFFICIENTS.md)
//!
//! [grid]
//! x_min_in = 0.0
//! x_max_in = 8.0
//! step_in = 0.1
//! x_null_in = 7.2         # the firmware nulls the slide beyond this X
//!
//! [series]
//! representation = "sin-power"   # or "harmonic"
//! terms = 4               # sin-power: powers 0..terms-1; harmonic: highest harmonic
//!
//! [format]
//! coeff_frac_bits = 30    # I2F30, the firmware's ZInches
//! x_frac_bits = 24        # I8F24, the firmware's XInches
//! ```

use crate::coeffgen::{SpecError, TableSpec};
use crate::surface::{self, Compensation, Surface};
use serde::Deserialize;
use zslide::table::Representation;

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    #[serde(default)]
    pub surface: SurfaceCfg,
    #[serde(default)]
    pub grid: GridCfg,
    #[serde(default)]
    pub series: SeriesCfg,
    #[serde(default)]
    pub format: FormatCfg,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceCfg {
    pub c_in: Option<f64>,
    pub focal_length_in: Option<f64>,
    pub s_y_in: Option<f64>,
    pub tool_radius_in: Option<f64>,
    pub compensation: Option<Compensation>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridCfg {
    pub x_min_in: Option<f64>,
    pub x_max_in: Option<f64>,
    pub step_in: Option<f64>,
    pub x_null_in: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeriesCfg {
    pub representation: Option<RepCfg>,
    pub terms: Option<usize>,
}

#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum RepCfg {
    SinPower,
    Harmonic,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FormatCfg {
    pub coeff_frac_bits: Option<u8>,
    pub x_frac_bits: Option<u8>,
}

impl Config {
    /// Parses TOML text; syntax and unknown-key errors carry the position.
    pub fn from_toml(text: &str) -> anyhow::Result<Self> {
        Ok(toml::from_str(text)?)
    }

    /// The table specification, with the dissertation's defaults for missing
    /// fields, validated.
    pub fn to_spec(&self) -> Result<TableSpec, SpecError> {
        let d = TableSpec::dissertation();
        let c = match (self.surface.c_in, self.surface.focal_length_in) {
            (Some(_), Some(f)) => {
                return Err(SpecError::Field {
                    field: "surface.focal_length_in",
                    value: f,
                    rule: "give either surface.c_in or surface.focal_length_in, not both".into(),
                })
            }
            (Some(c), None) => c,
            (None, Some(f)) => {
                if !(f.is_finite() && f > 0.0) {
                    return Err(SpecError::Field {
                        field: "surface.focal_length_in",
                        value: f,
                        rule: "must be a finite number > 0".into(),
                    });
                }
                4.0 * f
            }
            (None, None) => surface::DISSERTATION_C_IN,
        };
        let s = Surface::new(
            c,
            self.surface.s_y_in.unwrap_or(surface::DISSERTATION_SY_IN),
            self.surface
                .tool_radius_in
                .unwrap_or(surface::DISSERTATION_TOOL_RADIUS_IN),
        )?
        .with_compensation(self.surface.compensation.unwrap_or_default());
        let spec = TableSpec {
            surface: s,
            x_min: self.grid.x_min_in.unwrap_or(d.x_min),
            x_max: self.grid.x_max_in.unwrap_or(d.x_max),
            step: self.grid.step_in.unwrap_or(d.step),
            x_null: self.grid.x_null_in.unwrap_or(d.x_null),
            representation: match self.series.representation {
                None | Some(RepCfg::SinPower) => Representation::SinPower,
                Some(RepCfg::Harmonic) => Representation::Harmonic,
            },
            terms: self.series.terms.unwrap_or(d.terms),
            coeff_frac_bits: self.format.coeff_frac_bits.unwrap_or(d.coeff_frac_bits),
            x_frac_bits: self.format.x_frac_bits.unwrap_or(d.x_frac_bits),
        };
        spec.validate()?;
        Ok(spec)
    }
}

#[cfg(test)]
mod tests;
