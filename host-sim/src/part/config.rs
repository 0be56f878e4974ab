//! The part file (TOML): surface, tool, table bound and the plan's bound.
//! Unknown keys are refused (a misspelt field must not fall back to a
//! default); every error names the field.
//!
//! ```toml
//! [surface]
//! kind = "sinusoidal-grid"      # off-axis-conic | biconic | toric | xy-polynomial
//! amplitude_in = 0.0002         #   | zernike | sinusoidal-grid | sag-grid
//! period_x_in = 4.0
//! period_y_in = 4.0
//!
//! [tool]
//! nose_radius_in = 0.125        # 0: a sharp tool
//! clearance_deg = 7.0           # plan refuses a slope along the cut beyond it
//! compensation = "profile-normal"   # or "forex4" (the dissertation's)
//!
//! [table]
//! x_max_in = 2.0                # tool-centre X of the outermost node
//! x_null_in = 2.0               # default x_max_in
//! bound_uin = 0.5               # command error the picker must meet
//!
//! [plan]
//! error_bound_uin = 10.0        # predicted following error allowed
//! ```
//!
//! The keys of each kind are those of [`SurfaceCfg`]; `docs/PARTS.md`
//! lists them with their meaning.

use super::biconic::{Biconic, Toric};
use super::conic::OffAxisConic;
use super::saggrid::SagGrid;
use super::sinusoid::SinusoidalGrid;
use super::split::{Compensation, Part, Tool};
use super::table::PartTableSpec;
use super::xypoly::XyPolynomial;
use super::zernike::{Ordering, Zernike};
use super::Sag;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartFile {
    /// Free text for reports.
    #[serde(default)]
    pub description: Option<String>,
    pub surface: SurfaceCfg,
    pub tool: ToolCfg,
    pub table: TableCfg,
    #[serde(default)]
    pub plan: PlanCfg,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum SurfaceCfg {
    OffAxisConic {
        vertex_radius_in: Option<f64>,
        curvature_per_in: Option<f64>,
        conic_constant: f64,
        off_axis_in: f64,
        /// θ; default the dissertation's (normal at the sector centre).
        tilt_deg: Option<f64>,
    },
    Biconic {
        radius_x_in: f64,
        radius_y_in: f64,
        #[serde(default)]
        conic_x: f64,
        #[serde(default)]
        conic_y: f64,
    },
    Toric {
        radius_x_in: f64,
        radius_y_in: f64,
    },
    XyPolynomial {
        terms: Vec<PolyTerm>,
    },
    Zernike {
        ordering: Ordering,
        normalization_radius_in: f64,
        base_radius_in: Option<f64>,
        coefficients_in: Vec<f64>,
    },
    SinusoidalGrid {
        amplitude_in: f64,
        period_x_in: f64,
        period_y_in: f64,
    },
    SagGrid {
        /// CSV path, relative to the part file.
        file: PathBuf,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PolyTerm {
    pub x_power: u32,
    pub y_power: u32,
    pub coefficient: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolCfg {
    pub nose_radius_in: f64,
    pub clearance_deg: f64,
    #[serde(default = "profile_normal")]
    pub compensation: Compensation,
}

fn profile_normal() -> Compensation {
    Compensation::ProfileNormal
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableCfg {
    #[serde(default)]
    pub x_min_in: f64,
    pub x_max_in: f64,
    pub x_null_in: Option<f64>,
    pub bound_uin: f64,
    /// Share of the bound left to the firmware's arithmetic.
    #[serde(default = "allowance")]
    pub firmware_allowance_uin: f64,
    /// Binary grid steps only (the firmware finds the node by a shift).
    #[serde(default = "yes")]
    pub binary_grid: bool,
    #[serde(default = "thirty")]
    pub coeff_frac_bits: u8,
    #[serde(default = "twenty_four")]
    pub x_frac_bits: u8,
}

fn allowance() -> f64 {
    0.01
}
fn yes() -> bool {
    true
}
fn thirty() -> u8 {
    30
}
fn twenty_four() -> u8 {
    24
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanCfg {
    /// Predicted following error the plan accepts, µin.
    #[serde(default = "ten")]
    pub error_bound_uin: f64,
}

fn ten() -> f64 {
    10.0
}

impl Default for PlanCfg {
    fn default() -> Self {
        Self {
            error_bound_uin: ten(),
        }
    }
}

/// A part file read and checked.
#[derive(Clone, Debug)]
pub struct LoadedPart {
    pub name: String,
    pub description: String,
    pub part: Part,
    /// Grid and formats; step and harmonics are placeholders until picked.
    pub table: PartTableSpec,
    pub bound_uin: f64,
    pub allowance_uin: f64,
    pub binary_grid: bool,
    pub plan_error_bound_uin: f64,
}

fn finite(field: &str, v: f64) -> Result<f64, String> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{field} = {v}: must be finite"))
    }
}

impl SurfaceCfg {
    pub fn build(&self, dir: &Path) -> Result<Arc<dyn Sag>, String> {
        Ok(match self {
            Self::OffAxisConic {
                vertex_radius_in,
                curvature_per_in,
                conic_constant,
                off_axis_in,
                tilt_deg,
            } => {
                let r =
                    match (vertex_radius_in, curvature_per_in) {
                        (Some(r), None) => *r,
                        (None, Some(c)) if c.is_finite() && *c > 0.0 => 1.0 / c,
                        (None, Some(c)) => {
                            return Err(format!(
                                "surface.curvature_per_in = {c}: must be a finite number > 0"
                            ))
                        }
                        _ => return Err(
                            "surface: give exactly one of vertex_radius_in and curvature_per_in"
                                .into(),
                        ),
                    };
                Arc::new(OffAxisConic::new(
                    r,
                    *conic_constant,
                    *off_axis_in,
                    tilt_deg.map(f64::to_radians),
                )?)
            }
            Self::Biconic {
                radius_x_in,
                radius_y_in,
                conic_x,
                conic_y,
            } => Arc::new(Biconic::new(
                *radius_x_in,
                *radius_y_in,
                *conic_x,
                *conic_y,
            )?),
            Self::Toric {
                radius_x_in,
                radius_y_in,
            } => Arc::new(Toric::new(*radius_x_in, *radius_y_in)?),
            Self::XyPolynomial { terms } => Arc::new(XyPolynomial::new(
                terms
                    .iter()
                    .map(|t| (t.x_power, t.y_power, t.coefficient))
                    .collect(),
            )?),
            Self::Zernike {
                ordering,
                normalization_radius_in,
                base_radius_in,
                coefficients_in,
            } => Arc::new(Zernike::new(
                *ordering,
                *normalization_radius_in,
                *base_radius_in,
                coefficients_in,
            )?),
            Self::SinusoidalGrid {
                amplitude_in,
                period_x_in,
                period_y_in,
            } => Arc::new(SinusoidalGrid::new(
                *amplitude_in,
                *period_x_in,
                *period_y_in,
            )?),
            Self::SagGrid { file } => Arc::new(SagGrid::read(&dir.join(file))?),
        })
    }
}

/// An error inside `[surface]`, pointed at its key. The surface's kinds
/// are read through serde's buffer for internally tagged enums, which
/// keeps no positions: toml then points an unknown key or a value of the
/// wrong type at the section's header, and a wrong type names no field.
/// The key is found again in the document: the unknown one by its name,
/// the mistyped one by its value. `None`: not such an error.
fn at_the_key(text: &str, e: &toml::de::Error) -> Option<String> {
    use toml::de::{DeTable, DeValue};
    let msg = e.message();
    let doc = DeTable::parse(text).ok()?;
    let err_at = e.span()?.start;
    // The top-level table the error points into.
    let (section, table) = doc.get_ref().iter().find_map(|(k, v)| match v.get_ref() {
        DeValue::Table(t) if v.span().contains(&err_at) || k.span().contains(&err_at) => {
            Some((k.get_ref().to_string(), t))
        }
        _ => None,
    })?;
    let quoted = |after: &str| -> Option<String> {
        let rest = &msg[msg.find(after)? + after.len()..];
        let end = rest.find(['`', '"'])?;
        Some(rest[..end].to_string())
    };
    let (key, what) = if let Some(name) = quoted("unknown field `") {
        let key = table.iter().find(|(k, _)| k.get_ref() == &name)?.0;
        let hint = if name.ends_with("_in") || name.ends_with("_deg") || name == "kind" {
            ""
        } else {
            " (lengths are in inches: a name ends in `_in`; docs/PARTS.md)"
        };
        (key.span(), format!("{msg}{hint}"))
    } else if let Some(value) = quoted("invalid type: string \"") {
        let (k, _) = table
            .iter()
            .find(|(_, v)| matches!(v.get_ref(), DeValue::String(s) if *s == value))?;
        (
            k.span(),
            format!(
                "{section}.{}: {msg} (a bare number, in the unit its name ends with)",
                k.get_ref()
            ),
        )
    } else {
        return None;
    };
    let line = text[..key.start].matches('\n').count() + 1;
    let col = key.start - text[..key.start].rfind('\n').map_or(0, |n| n + 1) + 1;
    let src = text.lines().nth(line - 1).unwrap_or("");
    Some(format!(
        "TOML parse error at line {line}, column {col}\n  |\n{line} | {src}\n  |\n{what}"
    ))
}

impl PartFile {
    pub fn from_toml(text: &str) -> Result<Self, String> {
        toml::from_str(text).map_err(|e| at_the_key(text, &e).unwrap_or_else(|| e.to_string()))
    }

    /// Checks every field and builds the part; `dir` resolves a sag grid's
    /// file.
    pub fn load(&self, name: &str, dir: &Path) -> Result<LoadedPart, String> {
        let sag = self.surface.build(dir)?;
        let t = &self.tool;
        if !(t.nose_radius_in.is_finite() && t.nose_radius_in >= 0.0 && t.nose_radius_in < 1.0) {
            return Err(format!(
                "tool.nose_radius_in = {}: must be in [0, 1) in",
                t.nose_radius_in
            ));
        }
        if !(t.clearance_deg.is_finite() && t.clearance_deg > 0.0 && t.clearance_deg < 45.0) {
            return Err(format!(
                "tool.clearance_deg = {}: must be in (0, 45) degrees",
                t.clearance_deg
            ));
        }
        let tb = &self.table;
        finite("table.x_min_in", tb.x_min_in)?;
        finite("table.x_max_in", tb.x_max_in)?;
        if !(tb.bound_uin.is_finite() && tb.bound_uin > 0.0) {
            return Err(format!("table.bound_uin = {}: must be > 0", tb.bound_uin));
        }
        if !(tb.firmware_allowance_uin.is_finite()
            && tb.firmware_allowance_uin >= 0.0
            && tb.firmware_allowance_uin < tb.bound_uin)
        {
            return Err(format!(
                "table.firmware_allowance_uin = {}: must be in [0, table.bound_uin = {})",
                tb.firmware_allowance_uin, tb.bound_uin
            ));
        }
        let pe = self.plan.error_bound_uin;
        if !(pe.is_finite() && pe > 0.0) {
            return Err(format!("plan.error_bound_uin = {pe}: must be > 0"));
        }
        let table = PartTableSpec {
            x_min: tb.x_min_in,
            x_max: tb.x_max_in,
            step: tb.x_max_in - tb.x_min_in,
            x_null: tb.x_null_in.unwrap_or(tb.x_max_in),
            harmonics: 1,
            coeff_frac_bits: tb.coeff_frac_bits,
            x_frac_bits: tb.x_frac_bits,
        };
        table.format_spec().validate().map_err(|e| {
            // The placeholder grid is one interval: a refusal is the range's.
            format!("table: {e}").replace("grid.", "table.")
        })?;
        Ok(LoadedPart {
            name: name.to_string(),
            description: self.description.clone().unwrap_or_else(|| sag.describe()),
            part: Part {
                sag,
                tool: Tool {
                    nose_radius: t.nose_radius_in,
                    clearance_deg: t.clearance_deg,
                    compensation: t.compensation,
                },
            },
            table,
            bound_uin: tb.bound_uin,
            allowance_uin: tb.firmware_allowance_uin,
            binary_grid: tb.binary_grid,
            plan_error_bound_uin: pe,
        })
    }
}

/// Reads and checks a part file; errors name the file.
pub fn load_part(path: &Path) -> anyhow::Result<LoadedPart> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("reading part file {}: {e}", path.display()))?;
    let name = path
        .file_stem()
        .map_or("part".into(), |s| s.to_string_lossy().into_owned());
    let dir = path.parent().unwrap_or(Path::new("."));
    PartFile::from_toml(&text)
        .and_then(|f| f.load(&name, dir))
        .map_err(|e| anyhow::anyhow!("part file {}: {e}", path.display()))
}

impl LoadedPart {
    /// The smallest table that meets the part's bound (coeffgen's picker),
    /// or why none does.
    pub fn pick(&self) -> Result<(PartTableSpec, crate::coeffgen::PickResult), String> {
        let steps = if self.binary_grid {
            crate::coeffgen::BINARY_STEPS
        } else {
            crate::coeffgen::CANDIDATE_STEPS
        };
        super::table::pick(
            &self.part,
            &self.table,
            steps,
            self.bound_uin,
            self.allowance_uin,
            self.table.x_min,
            self.table.x_null,
            crate::coeffgen::Sampling::default(),
        )
    }
}
