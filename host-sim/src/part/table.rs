//! A harmonic table for a part: generation, the error split, and the
//! picker of grid step and harmonics for a stated bound.
//!
//! A general surface has every harmonic, cos and sin, so the table is the
//! harmonic representation (eq 2-17): `C_0, C_1, S_1, .., C_K, S_K` per
//! node, `K ≤ 15` (the format's 31 columns). The number formats, the
//! coefficient-range and sign checks and the error split's definitions are
//! coeffgen's (`docs/COEFFICIENTS.md`); only the columns come from the
//! part's section ([`super::split`]).

use super::split::{Part, Section};
use crate::coeffgen::{
    check_coefficient_range, check_sign, split_of, ErrorSplit, PickResult, Sampling, SectionSource,
    SpecError, TableColumns, TableSpec,
};
use zslide::table::{CoeffTable, Geometry, Representation, TableHeader, HEADER_LEN, MAX_TERMS};

/// Most harmonics a table can hold (2K + 1 ≤ 31 columns).
pub const MAX_HARMONICS: usize = (MAX_TERMS as usize - 1) / 2;

/// Grid, harmonics and formats of a part's table.
#[derive(Clone, Debug, PartialEq)]
pub struct PartTableSpec {
    pub x_min: f64,
    pub x_max: f64,
    pub step: f64,
    pub x_null: f64,
    /// Highest harmonic K.
    pub harmonics: usize,
    pub coeff_frac_bits: u8,
    pub x_frac_bits: u8,
}

impl PartTableSpec {
    /// coeffgen's spec with the same grid and formats: its field checks and
    /// node arithmetic are the format's. (Its surface is a placeholder the
    /// part's table never reads; the part's own domain is checked node by
    /// node by the split.)
    pub fn format_spec(&self) -> TableSpec {
        TableSpec {
            x_min: self.x_min,
            x_max: self.x_max,
            step: self.step,
            x_null: self.x_null,
            representation: Representation::Harmonic,
            terms: self.harmonics,
            coeff_frac_bits: self.coeff_frac_bits,
            x_frac_bits: self.x_frac_bits,
            ..TableSpec::dissertation()
        }
    }

    pub fn bytes(&self) -> usize {
        let f = self.format_spec();
        HEADER_LEN + f.node_count() * f.columns() * 4
    }
}

/// A generated part table.
#[derive(Clone, Debug)]
pub struct PartTable {
    pub spec: PartTableSpec,
    /// Node X (the image's binary nodes).
    pub x: Vec<f64>,
    /// Exact columns, node-major.
    pub cols: Vec<Vec<f64>>,
    pub raw: Vec<i32>,
    pub header: TableHeader,
}

/// The columns `C_0, C_1, S_1, ..` of a section in the firmware's angle
/// φ_c ([`super::part_angle`]: the part-frame φ = π − φ_c), which the
/// table holds: `cos k(π − φ_c) = (−1)^k cos kφ_c`, `sin k(π − φ_c) =
/// −(−1)^k sin kφ_c`.
pub fn columns(sec: &Section, k: usize) -> Vec<f64> {
    let h = sec.harmonics(k);
    let mut v = vec![h.c[0]];
    let mut sign = 1.0;
    for i in 1..=k {
        sign = -sign;
        v.push(sign * h.c[i]);
        v.push(-sign * h.s[i]);
    }
    v
}

fn spec_err(e: SpecError) -> String {
    e.to_string()
}

/// Computes and quantises the table; refuses (with the reason) a grid
/// outside the format or the surface, a coefficient beyond the firmware's
/// range, a quantisation whose command would be positive.
pub fn generate(part: &Part, spec: &PartTableSpec) -> Result<PartTable, String> {
    let g = generate_unsigned(part, spec)?;
    check_sign(&spec.format_spec(), &g.x, &g.raw).map_err(spec_err)?;
    Ok(g)
}

/// [`generate`] without the sign check: what the picker measures (a
/// candidate with too few harmonics may command a positive Z; it fails the
/// bound, it is not a reason to stop the search).
fn generate_unsigned(part: &Part, spec: &PartTableSpec) -> Result<PartTable, String> {
    let fs = spec.format_spec();
    fs.validate().map_err(spec_err)?;
    let x = fs.nodes_fixed();
    let cols = x
        .iter()
        .map(|&xi| part.section(xi).map(|s| columns(&s, spec.harmonics)))
        .collect::<Result<Vec<_>, _>>()?;
    let scale = f64::from(spec.coeff_frac_bits).exp2();
    let mut raw = Vec::with_capacity(cols.len() * fs.columns());
    check_coefficient_range(&fs, &x, &cols).map_err(spec_err)?;
    for c in cols.iter().flatten() {
        raw.push((c * scale).round() as i32);
    }
    let (x0_raw, dx_raw) = fs.grid_raw();
    let nin = |v: f64| (v * 1e9).round() as i64;
    let (c_nin, s_y_nin) = part.sag.paraboloid_geometry().map_or(
        (super::NOT_A_PARABOLOID_NIN, super::NOT_A_PARABOLOID_NIN),
        |(c, s)| (nin(c), nin(s)),
    );
    let header = TableHeader {
        representation: Representation::Harmonic,
        terms: fs.columns() as u8,
        coeff_frac_bits: spec.coeff_frac_bits,
        x_frac_bits: spec.x_frac_bits,
        node_count: x.len() as u32,
        x0_raw,
        dx_raw,
        x_null_raw: ((spec.x_null * f64::from(spec.x_frac_bits).exp2()).round() as i32)
            .clamp(x0_raw, x0_raw + dx_raw * (x.len() as i32 - 1)),
        geometry: Geometry {
            c_nin,
            s_y_nin,
            tool_radius_nin: nin(part.tool.nose_radius),
        },
    };
    Ok(PartTable {
        spec: spec.clone(),
        x,
        cols,
        raw,
        header,
    })
}

impl PartTable {
    /// The image through the format's one encoder, parsed back.
    pub fn image(&self) -> Result<Vec<u8>, String> {
        let mut out = vec![0u8; self.header.image_len()];
        self.header
            .encode(&self.raw, &mut out)
            .map_err(|e| e.to_string())?;
        CoeffTable::parse(&out).map_err(|e| e.to_string())?;
        Ok(out)
    }

    fn quantised(&self, i: usize) -> Vec<f64> {
        let n = 2 * self.spec.harmonics + 1;
        let scale = f64::from(self.spec.coeff_frac_bits).exp2();
        self.raw[i * n..(i + 1) * n]
            .iter()
            .map(|&r| f64::from(r) / scale)
            .collect()
    }
}

/// The part as the error split's reference: its section, the harmonic
/// columns of `harmonics`, the split's Z, all in the firmware's angle.
struct PartSource<'a> {
    part: &'a Part,
    harmonics: usize,
}

impl SectionSource for PartSource<'_> {
    type Section = Section;
    type Error = String;
    fn section(&self, x: f64) -> Result<Section, String> {
        self.part.section(x)
    }
    fn columns(&self, sec: &Section) -> Vec<f64> {
        columns(sec, self.harmonics)
    }
    fn z(&self, sec: &Section, phi: f64) -> Result<f64, String> {
        sec.z(self.part, super::part_angle(phi))
    }
}

/// The error split (coeffgen's, [`split_of`]) of a part table over
/// `[x_lo, x_hi]`.
pub fn error_split(
    part: &Part,
    g: &PartTable,
    x_lo: f64,
    x_hi: f64,
    sampling: Sampling,
) -> Result<ErrorSplit, String> {
    let quant: Vec<Vec<f64>> = (0..g.x.len()).map(|i| g.quantised(i)).collect();
    let table = TableColumns {
        representation: Representation::Harmonic,
        x: &g.x,
        exact: &g.cols,
        quantised: &quant,
    };
    let src = PartSource {
        part,
        harmonics: g.spec.harmonics,
    };
    split_of(&src, &table, x_lo, x_hi, sampling)
}

/// Picks the smallest table (bytes) of `base`'s range and formats whose
/// total error over `[x_lo, x_hi]` plus `allowance_uin` (the firmware's
/// arithmetic) is within `bound_uin`: coeffgen's search
/// ([`crate::coeffgen::pick_smallest`]) over `steps` and 1..=15
/// harmonics. `Err` says why no table within the format meets it (or why
/// the part cannot be tabled at all).
#[allow(clippy::too_many_arguments)]
pub fn pick(
    part: &Part,
    base: &PartTableSpec,
    steps: &[f64],
    bound_uin: f64,
    allowance_uin: f64,
    x_lo: f64,
    x_hi: f64,
    sampling: Sampling,
) -> Result<(PartTableSpec, PickResult), String> {
    let budget = bound_uin - allowance_uin;
    if budget.is_nan() || budget <= 0.0 {
        return Err(format!(
            "the bound {bound_uin} µin leaves nothing after the firmware's allowance of {allowance_uin} µin"
        ));
    }
    let with = |step, harmonics| PartTableSpec {
        step,
        harmonics,
        ..base.clone()
    };
    let mut tried: Vec<(usize, f64, ErrorSplit)> = Vec::new();
    let best = crate::coeffgen::pick_smallest(
        steps,
        MAX_HARMONICS,
        budget,
        |step, k| {
            let s = with(step, k);
            s.format_spec()
                .validate()
                .is_ok()
                .then(|| (s.bytes(), 2 * k + 1))
        },
        |step, k| {
            let s = with(step, k);
            let e = error_split(part, &generate_unsigned(part, &s)?, x_lo, x_hi, sampling)?;
            tried.push((k, step, e.clone()));
            Ok::<_, String>(e)
        },
    )?;
    if let Some(r) = best {
        return Ok((with(r.step_in, r.terms), r));
    }
    let finest = steps.iter().cloned().fold(f64::INFINITY, f64::min);
    let mut why = format!(
        "no table within the format (at most {MAX_HARMONICS} harmonics, grid steps down to {finest} in) \
         meets {bound_uin} µin (a budget of {} µin after the firmware's {allowance_uin} µin)",
        (budget * 1e6).round() / 1e6
    );
    let least_trunc = tried
        .iter()
        .min_by(|a, b| a.2.truncation_uin.total_cmp(&b.2.truncation_uin));
    if let Some((k, _, e)) = least_trunc {
        if e.truncation_uin > budget {
            why += &format!(
                ": truncation alone is {:.4} µin with {k} harmonics (the surface's φ-content is too rich for the format)",
                e.truncation_uin
            );
        }
    }
    if let Some((k, s, e)) = tried
        .iter()
        .min_by(|a, b| a.2.total_uin.total_cmp(&b.2.total_uin))
    {
        why += &format!(
            "; the best tried, {k} harmonics at {s} in, errs {:.4} µin (truncation {:.4}, interpolation {:.4}, quantisation {:.4})",
            e.total_uin, e.truncation_uin, e.interpolation_uin, e.quantization_uin
        );
    }
    if tried.is_empty() {
        // Not one candidate was a table the format holds: the finest
        // step's refusal says why (a range no step divides, most often).
        if let Some(e) = with(finest, 1).format_spec().validate().err() {
            why += &format!(
                ": no grid step gives a table the format accepts over X {x_lo}..{x_hi} in; \
                 the finest, {finest} in: {e}"
            );
        }
    }
    Err(why)
}
