//! The table computed and quantised, refused where the firmware would
//! refuse it, and its image from the format's one encoder.

use super::fit::eval_columns;
use super::spec::{field, SpecError, TableSpec};
use std::f64::consts::PI;
use zslide::table::{CoeffTable, Geometry, TableHeader};

/// The generated table: f64 columns at the image's nodes, their quantised
/// values, and the header.
#[derive(Clone, Debug)]
pub struct Generated {
    pub spec: TableSpec,
    /// Node X (the image's exact binary nodes).
    pub x: Vec<f64>,
    /// Exact columns at those nodes, node-major.
    pub cols: Vec<Vec<f64>>,
    /// Quantised columns, `coeff_frac_bits` fraction bits, node-major.
    pub raw: Vec<i32>,
    pub header: TableHeader,
}

/// Computes and quantises the table. Fails (naming the field) if the spec is
/// invalid or a coefficient does not fit the chosen fixed-point format.
pub fn generate(spec: &TableSpec) -> Result<Generated, SpecError> {
    spec.validate()?;
    let x = spec.nodes_fixed();
    let cols = x
        .iter()
        .map(|&xi| spec.columns_at(xi))
        .collect::<Result<Vec<_>, _>>()?;
    let scale = f64::from(spec.coeff_frac_bits).exp2();
    let limit = 2f64.powi(31) / scale;
    let mut raw = Vec::with_capacity(cols.len() * spec.columns());
    for c in cols.iter().flatten() {
        let r = (c * scale).round();
        if !(f64::from(i32::MIN)..=f64::from(i32::MAX)).contains(&r) {
            return Err(field(
                "format.coeff_frac_bits",
                f64::from(spec.coeff_frac_bits),
                format!("a coefficient of {c:e} in exceeds the format's ±{limit} in; use fewer fraction bits"),
            ));
        }
        raw.push(r as i32);
    }
    check_coefficient_range(spec, &x, &cols)?;
    check_sign(spec, &x, &raw)?;
    let (x0_raw, dx_raw) = spec.grid_raw();
    let geometry = Geometry {
        c_nin: (spec.surface.c() * 1e9).round() as i64,
        s_y_nin: (spec.surface.s_y() * 1e9).round() as i64,
        tool_radius_nin: (spec.surface.tool_radius() * 1e9).round() as i64,
    };
    let header = TableHeader {
        representation: spec.representation,
        terms: spec.columns() as u8,
        coeff_frac_bits: spec.coeff_frac_bits,
        x_frac_bits: spec.x_frac_bits,
        node_count: x.len() as u32,
        x0_raw,
        dx_raw,
        // A null zone at x_max may round past a last node that a non-binary
        // step left short of x_max: clamp it onto the grid.
        x_null_raw: ((spec.x_null * spec.x_scale()).round() as i32)
            .clamp(x0_raw, x0_raw + dx_raw * (x.len() as i32 - 1)),
        geometry,
    };
    Ok(Generated {
        spec: spec.clone(),
        x,
        cols,
        raw,
        header,
    })
}

/// Refuses a table with a coefficient beyond what the firmware's command
/// path represents (`zslide::command::COEFF_LIMIT`, ±1/8 in, which it
/// clamps to): the clamped series would be another, possibly positive,
/// command. Found by the geometry fuzz target (a 5 in focal length).
pub(crate) fn check_coefficient_range(
    spec: &TableSpec,
    x: &[f64],
    cols: &[Vec<f64>],
) -> Result<(), SpecError> {
    let limit = f64::from(zslide::command::COEFF_LIMIT) / f64::from(1u32 << 30);
    for (xi, c) in x.iter().zip(cols) {
        if let Some(v) = c.iter().find(|v| v.abs() > limit) {
            return Err(field(
                "grid.x_max_in",
                spec.x_max,
                format!(
                    "at X = {xi:.4} in this surface needs a coefficient of {v:.4} in, beyond the \
                     firmware's ±{limit} in (twelve times the slide's travel): lower \
                     grid.x_max_in or choose a flatter surface"
                ),
            ));
        }
    }
    Ok(())
}

/// Largest Z, in, the generator lets a table command: the firmware's load
/// check (`zslide::firmware::load_table`) refuses a table whose command
/// exceeds 1 µin at any node before the null zone at any of 16 angles (a
/// correct command has `max_φ Z = 0`). The generator stops at 0.9 µin, so
/// that its f64 evaluation and the firmware's fixed point cannot disagree
/// at the edge.
const SIGN_LIMIT_IN: f64 = 0.9e-6;

/// Refuses a table the firmware would refuse at load: its quantised
/// coefficients give a positive command. (The exact series of a table
/// within the coefficient range is never positive; its quantisation can be
/// with too few fraction bits.)
pub(crate) fn check_sign(spec: &TableSpec, x: &[f64], raw: &[i32]) -> Result<(), SpecError> {
    let n = spec.columns();
    let scale = f64::from(spec.coeff_frac_bits).exp2();
    for (i, &xi) in x.iter().enumerate() {
        if xi > spec.x_null + 1e-9 {
            break;
        }
        let q: Vec<f64> = raw[i * n..(i + 1) * n]
            .iter()
            .map(|&r| f64::from(r) / scale)
            .collect();
        // The firmware's 16 angles, every 22.5°.
        for k in 0..16 {
            let phi = f64::from(k) * PI / 8.0;
            let z = eval_columns(spec.representation, &q, phi);
            if z > SIGN_LIMIT_IN {
                return Err(field(
                    "format.coeff_frac_bits",
                    f64::from(spec.coeff_frac_bits),
                    format!(
                        "quantised coefficients give Z = {:+.3} µin at X = {xi:.4} in, φ = {:.1}° \
                         (a correct command is never positive; the firmware refuses a table above \
                         1 µin): use more fraction bits",
                        z * 1e6,
                        phi.to_degrees()
                    ),
                ));
            }
        }
    }
    Ok(())
}

impl Generated {
    /// The table image (header + payload) from the format's one encoder,
    /// checked by parsing it back.
    pub fn image(&self) -> Result<Vec<u8>, zslide::table::TableError> {
        let mut out = vec![0u8; self.header.image_len()];
        self.header.encode(&self.raw, &mut out)?;
        CoeffTable::parse(&out)?;
        Ok(out)
    }

    /// Quantised columns of node `i`, inches.
    pub fn quantised(&self, i: usize) -> Vec<f64> {
        let n = self.spec.columns();
        let scale = f64::from(self.spec.coeff_frac_bits).exp2();
        self.raw[i * n..(i + 1) * n]
            .iter()
            .map(|&r| f64::from(r) / scale)
            .collect()
    }
}
