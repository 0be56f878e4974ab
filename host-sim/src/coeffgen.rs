//! Coefficient generator: replaces FOREX4 (appendix B-1) and the EPROM burn.
//!
//! From the exact surface ([`crate::surface`]) it computes, at each node of a
//! uniform X grid, the series coefficients of `Z(X, φ)` in φ, quantises them
//! to the firmware's fixed point and writes the table image through the one
//! encoder, [`zslide::table::TableHeader::encode`]. It also measures what the
//! firmware's approximation of the command costs, split into truncation
//! (terms), interpolation (grid) and quantisation, and picks the smallest
//! table that meets a bound. The maths and the budget are in
//! `docs/COEFFICIENTS.md`.
//!
//! # Fourier expansion
//!
//! `Z(X, ·)` is smooth and 2π-periodic, so the equispaced trapezoid rule (a
//! DFT) converges geometrically: with [`FOURIER_SAMPLES`] samples the aliasing
//! error is below 1e-18 in for any harmonic this format can hold. FOREX4's
//! FORIF used 721 samples with π = 3.141593, which left ~1e-9 in of noise.
//!
//! `Z` depends on φ only through `sin φ` (eq 2-15 has `sin φ` and
//! `cos²φ = 1 − sin²φ`), so it is symmetric under `φ → π − φ`: `C_k = 0` for
//! odd k and `S_k = 0` for even k, exactly. They are returned as exact zeros.
//! With `s = sin φ`, `cos 2mφ = (−1)^m T_2m(s)` and
//! `sin (2m+1)φ = (−1)^m T_2m+1(s)` (Chebyshev polynomials), so the harmonic
//! series truncated after harmonic `N−1` *is* the degree `N−1` Chebyshev
//! expansion of `Z` in `s`; re-expanded in powers of `s` it is the N-term
//! sin-power form, eq 2-19..2-23 for N = 4. Both forms truncated at the same
//! degree are the same function, and linear interpolation of the columns
//! commutes with that change of basis, so they have the same truncation and
//! interpolation error; they differ only in table size and firmware work.

use crate::surface::{Section, Surface, SurfaceError};
use std::f64::consts::PI;
use std::fmt;
use zslide::table::{CoeffTable, Geometry, Representation, TableHeader, MAX_NODES, MAX_TERMS};

/// Samples per turn of the trapezoid-rule Fourier transform.
pub const FOURIER_SAMPLES: usize = 256;

/// Fourier coefficients of `Z(X, φ)` at one X: `Z = c[0] + Σ c[k] cos kφ +
/// s[k] sin kφ`, k = 1..=K; `s[0] = 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct Harmonics {
    pub c: Vec<f64>,
    pub s: Vec<f64>,
}

impl Harmonics {
    /// Highest harmonic K.
    pub fn k_max(&self) -> usize {
        self.c.len() - 1
    }

    /// The series evaluated at φ, truncated after harmonic `k_max` (≤ K).
    pub fn eval(&self, phi: f64, k_max: usize) -> f64 {
        let mut z = self.c[0];
        for k in 1..=k_max.min(self.k_max()) {
            let (sk, ck) = (k as f64 * phi).sin_cos();
            z += self.c[k] * ck + self.s[k] * sk;
        }
        z
    }

    /// Chebyshev coefficients `b_n` of `Z` in `s = sin φ`, n = 0..=K:
    /// `Z = Σ b_n T_n(s)`.
    pub fn chebyshev(&self) -> Vec<f64> {
        (0..=self.k_max())
            .map(|n| {
                let sign = if (n / 2) % 2 == 0 { 1.0 } else { -1.0 };
                sign * if n % 2 == 0 { self.c[n] } else { self.s[n] }
            })
            .collect()
    }

    /// The N-term sin-power form: `Z ≈ Σ_{j<N} a_j sin^j φ` (harmonics
    /// 0..N−1 rewritten in powers of `sin φ`; N = 4 is eq 2-19..2-23).
    pub fn sin_power(&self, n_terms: usize) -> Vec<f64> {
        let b = self.chebyshev();
        chebyshev_to_monomial(&b[..n_terms.min(b.len())], n_terms)
    }

    /// Table 2-2's columns from C0, S1, C2, S3 by eq 2-20..2-23.
    pub fn c00_c03(&self) -> [f64; 4] {
        [
            self.c[0] + self.c[2],
            self.s[1] + 3.0 * self.s[3],
            -2.0 * self.c[2],
            -4.0 * self.s[3],
        ]
    }
}

/// Monomial coefficients (length `n_out`) of `Σ b_n T_n(s)`.
fn chebyshev_to_monomial(b: &[f64], n_out: usize) -> Vec<f64> {
    let mut a = vec![0.0; n_out];
    // T_n coefficients by T_{n+1} = 2s T_n − T_{n−1}; integers, exact in f64
    // up to degree 30 (largest ≈ 3e11 < 2^53).
    let mut t_prev = vec![0.0; n_out.max(1)];
    let mut t_cur = vec![0.0; n_out.max(1)];
    t_prev[0] = 1.0; // T_0
    if n_out > 1 {
        t_cur[1] = 1.0; // T_1
    }
    for (n, &bn) in b.iter().enumerate() {
        let t = if n == 0 { &t_prev } else { &t_cur };
        for (aj, tj) in a.iter_mut().zip(t) {
            *aj += bn * tj;
        }
        if n >= 1 {
            let mut next = vec![0.0; n_out];
            for j in 0..n_out {
                let shifted = if j >= 1 { 2.0 * t_cur[j - 1] } else { 0.0 };
                next[j] = shifted - t_prev[j];
            }
            t_prev = std::mem::replace(&mut t_cur, next);
        }
    }
    a
}

/// Evaluates `Σ a_j s^j` (Horner).
pub fn eval_sin_power(a: &[f64], s: f64) -> f64 {
    a.iter().rev().fold(0.0, |acc, &aj| acc * s + aj)
}

/// Fourier coefficients of `Z` at a section up to harmonic `k_max`, by the
/// trapezoid rule on [`FOURIER_SAMPLES`] (or more, for high harmonics) points.
pub fn harmonics(sec: &Section, k_max: usize) -> Harmonics {
    let m = FOURIER_SAMPLES.max((4 * (k_max + 1)).next_power_of_two());
    harmonics_with(sec, k_max, m)
}

/// As [`harmonics`] with an explicit sample count `m` (convergence studies).
pub fn harmonics_with(sec: &Section, k_max: usize, m: usize) -> Harmonics {
    // One table of correctly rounded sin/cos(2πj/m), indexed by j·k mod m:
    // no angle recurrence (FORIF's accumulates rounding over the harmonics).
    let (sin_t, cos_t): (Vec<f64>, Vec<f64>) = (0..m)
        .map(|j| (2.0 * PI * j as f64 / m as f64).sin_cos())
        .unzip();
    let z: Vec<f64> = sin_t.iter().map(|&s| sec.z_of_sin(s)).collect();
    let mut c = vec![0.0; k_max + 1];
    let mut s = vec![0.0; k_max + 1];
    c[0] = z.iter().sum::<f64>() / m as f64;
    for k in 1..=k_max {
        let (mut ck, mut sk) = (0.0, 0.0);
        for (j, zj) in z.iter().enumerate() {
            let idx = (j * k) % m;
            ck += zj * cos_t[idx];
            sk += zj * sin_t[idx];
        }
        // Exact zeros by the φ → π − φ symmetry (module doc).
        if k % 2 == 0 {
            c[k] = 2.0 * ck / m as f64;
        } else {
            s[k] = 2.0 * sk / m as f64;
        }
    }
    Harmonics { c, s }
}

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

fn field(field: &'static str, value: f64, rule: impl Into<String>) -> SpecError {
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

    fn x_scale(&self) -> f64 {
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

/// Columns of one node: sin-power `a_0..a_{N−1}`, or harmonic
/// `C_0, C_1, S_1, .., C_K, S_K`.
pub fn columns_of(sec: &Section, rep: Representation, terms: usize) -> Vec<f64> {
    match rep {
        Representation::SinPower => harmonics(sec, terms.saturating_sub(1)).sin_power(terms),
        Representation::Harmonic => {
            let h = harmonics(sec, terms);
            let mut v = vec![h.c[0]];
            for k in 1..=terms {
                v.push(h.c[k]);
                v.push(h.s[k]);
            }
            v
        }
    }
}

/// Series value of one node's columns at φ.
pub fn eval_columns(rep: Representation, cols: &[f64], phi: f64) -> f64 {
    match rep {
        Representation::SinPower => eval_sin_power(cols, phi.sin()),
        Representation::Harmonic => {
            let mut z = cols[0];
            for (k, pair) in cols[1..].chunks_exact(2).enumerate() {
                let (sk, ck) = ((k + 1) as f64 * phi).sin_cos();
                z += pair[0] * ck + pair[1] * sk;
            }
            z
        }
    }
}

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

/// Linear interpolation of node-major columns at X (f64 mirror of the
/// firmware's fixed-point interpolation), clamped to the grid.
pub fn interpolate(x_nodes: &[f64], cols: &[Vec<f64>], x: f64) -> Vec<f64> {
    let n = x_nodes.len();
    let x0 = x_nodes[0];
    let dx = (x_nodes[n - 1] - x0) / (n - 1) as f64;
    let f = ((x - x0) / dx).clamp(0.0, (n - 1) as f64);
    let i = (f.floor() as usize).min(n - 2);
    let t = f - i as f64;
    cols[i]
        .iter()
        .zip(&cols[i + 1])
        .map(|(a, b)| a + t * (b - a))
        .collect()
}

/// Maximum errors of the command approximation, microinches, over the X range
/// of the report and all φ.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ErrorSplit {
    /// Series truncated to the table's terms, exact coefficients at X.
    pub truncation_uin: f64,
    /// Linear interpolation of exact nodal coefficients vs exact at X (series
    /// level, same terms).
    pub interpolation_uin: f64,
    /// Quantised vs exact nodal coefficients, interpolated.
    pub quantization_uin: f64,
    /// Everything: interpolated quantised series vs the exact surface.
    pub total_uin: f64,
    /// `total` restricted to the grid nodes.
    pub total_at_nodes_uin: f64,
    /// `total` midway between nodes.
    pub total_midway_uin: f64,
    /// Largest peak-to-peak Z motion over φ in the range, inches (the slide
    /// must be able to make it: ±0.010 in for the 1983 gauge).
    pub z_peak_to_peak_in: f64,
    /// Where `total` peaks.
    pub worst_x_in: f64,
    pub worst_phi_deg: f64,
}

/// Sampling density of the error report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampling {
    /// X samples per grid interval (≥ 2; 0 and ½ are always included).
    pub per_interval: usize,
    /// φ samples per turn.
    pub phi: usize,
}

impl Default for Sampling {
    fn default() -> Self {
        Self {
            per_interval: 4,
            phi: 720,
        }
    }
}

/// Measures the error split of a generated table over `[x_lo, x_hi]`.
pub fn error_split(
    g: &Generated,
    x_lo: f64,
    x_hi: f64,
    sampling: Sampling,
) -> Result<ErrorSplit, SpecError> {
    let spec = &g.spec;
    let rep = spec.representation;
    let quant: Vec<Vec<f64>> = (0..g.x.len()).map(|i| g.quantised(i)).collect();
    let n_iv = g.x.len() - 1;
    let dx = (g.x[n_iv] - g.x[0]) / n_iv as f64;
    let per = sampling.per_interval.max(2);
    let phis: Vec<f64> = (0..sampling.phi)
        .map(|j| 2.0 * PI * j as f64 / sampling.phi as f64)
        .collect();
    let mut e = ErrorSplit {
        truncation_uin: 0.0,
        interpolation_uin: 0.0,
        quantization_uin: 0.0,
        total_uin: 0.0,
        total_at_nodes_uin: 0.0,
        total_midway_uin: 0.0,
        z_peak_to_peak_in: 0.0,
        worst_x_in: x_lo,
        worst_phi_deg: 0.0,
    };
    for iv in 0..=n_iv {
        for k in 0..per {
            if iv == n_iv && k > 0 {
                break;
            }
            let x = g.x[0] + (iv as f64 + k as f64 / per as f64) * dx;
            if x < x_lo - 1e-12 || x > x_hi + 1e-12 {
                continue;
            }
            let sec = spec.surface.section(x)?;
            let exact_cols = columns_of(&sec, rep, spec.terms);
            let interp_cols = interpolate(&g.x, &g.cols, x);
            let interp_q = interpolate(&g.x, &quant, x);
            let at_node = k == 0;
            let midway = 2 * k == per;
            let (mut z_lo, mut z_hi) = (f64::MAX, f64::MIN);
            for &phi in &phis {
                let z = sec.z(phi);
                z_lo = z_lo.min(z);
                z_hi = z_hi.max(z);
                let s_exact = eval_columns(rep, &exact_cols, phi);
                let s_interp = eval_columns(rep, &interp_cols, phi);
                let s_q = eval_columns(rep, &interp_q, phi);
                let tr = (s_exact - z).abs() * 1e6;
                let ip = (s_interp - s_exact).abs() * 1e6;
                let qu = (s_q - s_interp).abs() * 1e6;
                let to = (s_q - z).abs() * 1e6;
                e.truncation_uin = e.truncation_uin.max(tr);
                e.interpolation_uin = e.interpolation_uin.max(ip);
                e.quantization_uin = e.quantization_uin.max(qu);
                if to > e.total_uin {
                    e.total_uin = to;
                    e.worst_x_in = x;
                    e.worst_phi_deg = phi.to_degrees();
                }
                if at_node {
                    e.total_at_nodes_uin = e.total_at_nodes_uin.max(to);
                }
                if midway {
                    e.total_midway_uin = e.total_midway_uin.max(to);
                }
            }
            e.z_peak_to_peak_in = e.z_peak_to_peak_in.max(z_hi - z_lo);
        }
    }
    Ok(e)
}

/// Worst-case bound of the quantisation error from the format alone:
/// half an LSB per column times the column's largest basis value (1).
pub fn quantization_bound_uin(spec: &TableSpec) -> f64 {
    spec.columns() as f64 * 0.5 * (-f64::from(spec.coeff_frac_bits)).exp2() * 1e6
}

/// Grid steps the picker tries, coarse to fine (binary fractions first at
/// equal size: the firmware then finds the node by a shift).
pub const CANDIDATE_STEPS: &[f64] = &[
    0.25, 0.2, 0.125, 0.1, 0.0625, 0.05, 0.04, 0.03125, 0.025, 0.02, 0.015625, 0.0125, 0.01,
];

/// Binary-fraction steps only: with them the firmware finds the node and
/// the interpolation fraction of a binary X by a shift, not a division.
pub const BINARY_STEPS: &[f64] = &[0.25, 0.125, 0.0625, 0.03125, 0.015625, 0.0078125];

/// One candidate the picker measured.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PickResult {
    pub step_in: f64,
    pub terms: usize,
    pub columns: usize,
    pub bytes: usize,
    pub errors: ErrorSplit,
}

/// Picks the smallest table (bytes) of `base`'s representation and formats
/// whose total error over `[x_lo, x_hi]`, plus `firmware_allowance_uin` for
/// the firmware's own arithmetic, is within `bound_uin`. Tries the steps of
/// `steps` (e.g. [`CANDIDATE_STEPS`] or [`BINARY_STEPS`]) that divide the
/// range, and terms up to `max_terms`. Returns `None` if nothing meets the
/// bound.
#[allow(clippy::too_many_arguments)]
pub fn pick(
    base: &TableSpec,
    steps: &[f64],
    bound_uin: f64,
    firmware_allowance_uin: f64,
    x_lo: f64,
    x_hi: f64,
    max_terms: usize,
    sampling: Sampling,
) -> Result<Option<PickResult>, SpecError> {
    let spec_of = |step, terms| {
        let spec = TableSpec {
            step,
            terms,
            ..base.clone()
        };
        spec.validate().is_ok().then_some(spec)
    };
    pick_smallest(
        steps,
        max_terms,
        bound_uin - firmware_allowance_uin,
        |step, terms| {
            spec_of(step, terms).map(|s| {
                let bytes = zslide::table::HEADER_LEN + s.node_count() * s.columns() * 4;
                (bytes, s.columns())
            })
        },
        |step, terms| {
            let spec = TableSpec {
                step,
                terms,
                ..base.clone()
            };
            error_split(&generate(&spec)?, x_lo, x_hi, sampling)
        },
    )
}

/// The picker's search, for any table builder: for each term count
/// (1..=`max_terms`), grids from coarse to fine; the first that meets
/// `budget_uin` is the smallest table with those terms. Truncation does
/// not depend on the grid, so a term count whose truncation alone exceeds
/// the budget is abandoned at once. `size(step, terms)` gives the table's
/// bytes and columns per node (`None`: a grid the format refuses);
/// `measure(step, terms)` its errors, called only for a table smaller than
/// the best so far.
pub fn pick_smallest<E>(
    steps: &[f64],
    max_terms: usize,
    budget_uin: f64,
    size: impl Fn(f64, usize) -> Option<(usize, usize)>,
    mut measure: impl FnMut(f64, usize) -> Result<ErrorSplit, E>,
) -> Result<Option<PickResult>, E> {
    let mut best: Option<PickResult> = None;
    for terms in 1..=max_terms {
        for &step in steps {
            let Some((bytes, columns)) = size(step, terms) else {
                continue;
            };
            if best.as_ref().is_some_and(|b| b.bytes <= bytes) {
                continue;
            }
            let errors = measure(step, terms)?;
            if errors.truncation_uin > budget_uin {
                break; // no grid fixes truncation
            }
            if errors.total_uin <= budget_uin {
                best = Some(PickResult {
                    step_in: step,
                    terms,
                    columns,
                    bytes,
                    errors,
                });
                break; // finer grids with these terms are only bigger
            }
        }
    }
    Ok(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chebyshev_conversion_is_eq_2_20_to_2_23() {
        let h = Harmonics {
            c: vec![0.3, 0.0, -0.7, 0.0],
            s: vec![0.0, 1.1, 0.0, 0.13],
        };
        let a = h.sin_power(4);
        let e = h.c00_c03();
        for j in 0..4 {
            assert!((a[j] - e[j]).abs() < 1e-15, "{a:?} vs {e:?}");
        }
        // And the two forms agree as functions of φ.
        for i in 0..50 {
            let phi = i as f64 * 0.13;
            assert!((eval_sin_power(&a, phi.sin()) - h.eval(phi, 3)).abs() < 1e-14);
        }
    }

    #[test]
    fn high_order_sin_power_equals_harmonic_series() {
        let sec = Surface::dissertation().section(8.0).unwrap();
        let h = harmonics(&sec, 9);
        let a = h.sin_power(10);
        for i in 0..100 {
            let phi = i as f64 * 0.0628;
            let d = eval_sin_power(&a, phi.sin()) - h.eval(phi, 9);
            assert!(d.abs() < 1e-17, "{d}");
        }
    }
}
