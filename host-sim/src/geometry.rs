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
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        Config::from_toml(text)
            .and_then(|c| c.to_spec().map_err(anyhow::Error::from))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn empty_file_is_the_dissertation() {
        let s = Config::from_toml("").unwrap().to_spec().unwrap();
        assert_eq!(s, TableSpec::dissertation());
        let f = Config::from_toml("[surface]\nfocal_length_in = 79.175\n")
            .unwrap()
            .to_spec()
            .unwrap();
        assert!((f.surface.c() - 316.7).abs() < 1e-12);
        let p = Config::from_toml("[surface]\ncompensation = \"profile-normal\"\n")
            .unwrap()
            .to_spec()
            .unwrap();
        assert_eq!(p.surface.compensation(), Compensation::ProfileNormal);
        assert!(Config::from_toml("[surface]\ncompensation = \"exact\"\n").is_err());
    }

    #[test]
    fn invalid_fields_are_named_with_their_limit() {
        for (text, starts) in [
            ("[surface]\nc_in = 0.0", "surface.c_in"),
            ("[surface]\nc_in = -316.7", "surface.c_in"),
            ("[surface]\nc_in = nan", "surface.c_in"),
            (
                "[surface]\nfocal_length_in = -1.0",
                "surface.focal_length_in",
            ),
            (
                "[surface]\nc_in = 316.7\nfocal_length_in = 79.0",
                "surface.focal_length_in",
            ),
            ("[surface]\ns_y_in = 0.0", "surface.s_y_in"),
            (
                "[surface]\ntool_radius_in = -0.125",
                "surface.tool_radius_in",
            ),
            ("[grid]\nstep_in = 0.0", "grid.step_in"),
            ("[grid]\nstep_in = -0.1", "grid.step_in"),
            ("[grid]\nstep_in = 0.3", "grid.step_in"),
            ("[grid]\nx_min_in = -1.0", "grid.x_min_in"),
            ("[grid]\nx_max_in = inf", "grid.x_max_in"),
            ("[grid]\nx_max_in = 70.0\nx_null_in = 7.2", "grid.x_max_in"),
            ("[grid]\nx_null_in = 9.0", "grid.x_null_in"),
            ("[series]\nterms = 0", "series.terms"),
            ("[series]\nterms = 32", "series.terms"),
            (
                "[series]\nrepresentation = \"harmonic\"\nterms = 16",
                "series.terms",
            ),
            ("[format]\ncoeff_frac_bits = 40", "format.coeff_frac_bits"),
        ] {
            let e = err(text);
            assert!(e.starts_with(starts), "{text:?} gave {e:?}");
        }
        // The domain message carries the limit.
        let e = err("[grid]\nx_max_in = 70.0\nstep_in = 0.5\nx_null_in = 7.0");
        assert!(
            e.contains("defined for X <= 5") && e.contains(" in at this geometry"),
            "{e}"
        );
        let e = err("[grid]\nstep_in = 0.3");
        assert!(e.contains("whole steps"), "{e}");
        // Misspelt keys are refused, not defaulted.
        assert!(err("[grid]\nstep = 0.1").contains("unknown field"));
    }

    /// Found by the geometry fuzz target: a deep paraboloid (f = 5 in) needs
    /// coefficients beyond the firmware's ±1/8 in; clamped, the command
    /// was +331 µin at X = 6.9 in, and the firmware's load check refused
    /// the table. The generator refuses it instead, naming the field;
    /// likewise a quantisation too coarse for a command that is never
    /// positive.
    #[test]
    fn tables_the_firmware_would_refuse_are_refused_by_name() {
        let gen = |text: &str| {
            crate::coeffgen::generate(&Config::from_toml(text).unwrap().to_spec().unwrap())
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        let e = gen("[surface]\nfocal_length_in = 5\n").unwrap_err();
        assert!(
            e.starts_with("grid.x_max_in = 8: at X = ")
                && e.contains("beyond the firmware's ±0.125 in"),
            "{e}"
        );
        gen("[surface]\nfocal_length_in = 5\n[grid]\nx_max_in = 2.0\nx_null_in = 2.0\n").unwrap();
        let e = gen("[format]\ncoeff_frac_bits = 10\n[series]\nrepresentation = \"harmonic\"\n")
            .unwrap_err();
        assert!(
            e.starts_with("format.coeff_frac_bits = 10: quantised coefficients give Z = +"),
            "{e}"
        );
        gen("").unwrap();
        gen("[format]\ncoeff_frac_bits = 28\n").unwrap();
    }
}
