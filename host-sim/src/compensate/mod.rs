//! Measure, compensate, cut again (docs/PARTS.md, "Compensating a measured
//! part"): the table that cuts a part's measured, repeatable error away.
//!
//! * [`measured`] reads and checks a measurement (the cut's CMM grid,
//!   its rectangular grid, a shop's own points);
//! * [`fit`] fits a smooth error surface `ê(x, y)` to it (Zernike terms,
//!   order by cross-validation) or says why the data cannot carry one;
//! * here: the compensated surface `z − g·ê` (nominal minus gain × fitted
//!   error: where the part has excess stock `e` the tool goes `g·e` deeper),
//!   its table from the part tables' own generator and picker
//!   (`part::table`, the bound, the coefficient and sign checks), the
//!   stroke and slope checks of `part::plan` on it, and the record of what
//!   it compensates ([`Record`], beside the table as
//!   `NAME.compensation.json`: each measurement's SHA-256, fit and gain,
//!   and the table's CRC).
//!
//! A second iteration (`--from` a compensated table) adds its correction
//! to the first's: the measured part was cut with the first, so what it
//! shows is what the first left.
//!
//! The split puts the φ-independent part of a correction on the axial
//! slide (`Y(X)`, `part::split`): the Z command alone moves by `−g·e` less
//! the change of `Y`. `cut --table` reads the record to drive the axial
//! slide on the compensated program (`part::axial::AxialProgram`).

pub mod fit;
pub mod measured;
#[cfg(test)]
mod tests;

use crate::part::config::LoadedPart;
use crate::part::conic::OffAxisConic;
use crate::part::split::{Compensation, Part, Tool};
use crate::part::table::PartTableSpec;
use crate::part::zernike::Zernike;
use crate::part::Sag;
use fit::ErrorFit;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The table bound for the default part's compensated table, µin: the
/// harmonic table of the paraboloid plus a correction, a hundredth of
/// `modern-hw`'s ±5 µin goal... within 0.5 µin (the default sin-power
/// table's 0.06 µin needs a sin-power series the correction lacks).
pub const DEFAULT_BOUND_UIN: f64 = 0.5;

/// The part file name the record gives the default part.
pub const DEFAULT_PART: &str = "default";

/// A nominal surface less the gain-weighted fitted errors.
#[derive(Debug)]
pub struct Compensated {
    pub base: Arc<dyn Sag>,
    /// (gain, fitted error surface in inches).
    pub corrections: Vec<(f64, Zernike)>,
}

impl Sag for Compensated {
    fn sag(&self, x: f64, y: f64) -> f64 {
        self.corrections
            .iter()
            .fold(self.base.sag(x, y), |z, (g, e)| z - g * e.sag(x, y))
    }
    fn grad(&self, x: f64, y: f64) -> (f64, f64) {
        self.corrections
            .iter()
            .fold(self.base.grad(x, y), |(a, b), (g, e)| {
                let (ex, ey) = e.grad(x, y);
                (a - g * ex, b - g * ey)
            })
    }
    fn describe(&self) -> String {
        format!(
            "{} compensated by {} measured error fit{}",
            self.base.describe(),
            self.corrections.len(),
            if self.corrections.len() == 1 { "" } else { "s" }
        )
    }
}

/// One compensation step: what was measured, how it was fitted, the gain.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Step {
    /// The measurement file as given.
    pub measurement: String,
    pub sha256: String,
    pub kind: String,
    /// Points fitted, and points the file marked unmeasured.
    pub points: usize,
    pub absent: usize,
    pub instrument_noise_uin: f64,
    pub gain: f64,
    pub fit: ErrorFit,
}

/// What a compensated table compensates (`NAME.compensation.json`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Record {
    /// `default`, or the part file's name.
    pub part: String,
    /// The image's CRC (its identity), `0x........`.
    pub table_crc: String,
    pub bound_uin: f64,
    /// Every step, the first iteration's first.
    pub steps: Vec<Step>,
}

/// The record beside a table: `F.zsct` → `F.compensation.json`.
pub fn record_path(table: &Path) -> PathBuf {
    table.with_extension("compensation.json")
}

impl Record {
    /// The record beside `table`, if any, checked against the image's CRC.
    pub fn beside(table: &Path, image: &[u8]) -> anyhow::Result<Option<Self>> {
        let p = record_path(table);
        if !p.exists() {
            return Ok(None);
        }
        let r: Record = serde_json::from_str(
            &std::fs::read_to_string(&p).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?,
        )
        .map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?;
        let crc = crc_of(image)?;
        anyhow::ensure!(
            r.table_crc == crc,
            "{} describes the table with CRC {}, but {} has CRC {crc}: not its record",
            p.display(),
            r.table_crc,
            table.display()
        );
        Ok(Some(r))
    }

    /// The corrections as surfaces.
    pub fn corrections(&self) -> Result<Vec<(f64, Zernike)>, String> {
        self.steps
            .iter()
            .map(|s| s.fit.surface().map(|z| (s.gain, z)))
            .collect()
    }
}

pub fn crc_of(image: &[u8]) -> anyhow::Result<String> {
    let t = zslide::table::CoeffTable::parse(image).map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(format!("{:#010x}", t.identity().crc))
}

/// The dissertation's part as a part of one's own: the off-axis
/// paraboloid (k = −1, c = 316.7 in, S_y = 28 in, eq 2-15), FOREX4's
/// compensation of the 0.125 in nose, tabled over the cut's range (X 0..7.25
/// in, nulled beyond 7.2 in) at [`DEFAULT_BOUND_UIN`].
pub fn default_part() -> Result<LoadedPart, String> {
    let g = zslide::table::CoeffTable::parse(zslide::DEFAULT_TABLE)
        .map_err(|e| e.to_string())?
        .header()
        .geometry;
    let c = g.c_nin as f64 * 1e-9;
    let sag = OffAxisConic::new(c / 2.0, -1.0, g.s_y_nin as f64 * 1e-9, None)?;
    Ok(LoadedPart {
        name: DEFAULT_PART.into(),
        description: "the dissertation's paraboloid sector (the default table's part)".into(),
        part: Part {
            sag: Arc::new(sag),
            tool: Tool {
                nose_radius: g.tool_radius_nin as f64 * 1e-9,
                clearance_deg: 7.0,
                compensation: Compensation::Forex4,
            },
        },
        table: PartTableSpec {
            x_min: 0.0,
            x_max: 7.25,
            step: 7.25,
            x_null: 7.2,
            harmonics: 1,
            coeff_frac_bits: 30,
            x_frac_bits: 24,
        },
        bound_uin: DEFAULT_BOUND_UIN,
        allowance_uin: 0.01,
        binary_grid: true,
        plan_error_bound_uin: 25.0,
    })
}

/// `lp` with its surface compensated by `corrections`.
pub fn compensated(lp: &LoadedPart, corrections: Vec<(f64, Zernike)>) -> LoadedPart {
    LoadedPart {
        part: Part {
            sag: Arc::new(Compensated {
                base: lp.part.sag.clone(),
                corrections,
            }),
            tool: lp.part.tool,
        },
        description: format!("{} (compensated)", lp.description),
        ..lp.clone()
    }
}
