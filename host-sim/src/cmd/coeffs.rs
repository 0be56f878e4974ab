//! `host-sim coeffs`: the coefficient generator (FOREX4's successor).
//!
//! * `coeffs [--csv]`: Table 2-2 (or the table of `--config FILE`) as CSV,
//!   `x_in,c00_in,c01_in,..`, exact (unquantised) coefficients at the decimal
//!   grid nodes, 13 significant digits.
//! * `coeffs --json`: the same as JSON, with the geometry and the series.
//! * `coeffs --fourier --x X [--tool-radius R] [--terms N]`: Fourier terms of
//!   `Z(X, φ)` at one X, CSV `k,c_in,s_in`, k = 0..N.
//! * `--out FILE.zsct`: also writes the firmware table image (quantised, at
//!   the image's binary nodes), checked by the firmware's parser.
//! * `--report`: error split (truncation, interpolation, quantisation) over
//!   `[x_min, x_null]` (or `--x-lo/--x-hi`), in µin, as text or `--json`.
//! * `--bound-uin B`: picks the smallest grid/terms of the configured
//!   representation meeting B (with `--firmware-allowance-uin`), then acts on
//!   the picked table.
//!
//! Diagnostics go to stderr; stdout carries only the requested data.

use crate::coeffgen::{self, ErrorSplit, Generated, Sampling, TableSpec};
use crate::geometry::Config;
use anyhow::Context;
use std::io::Write;
use std::path::PathBuf;
use zslide::table::Representation;

/// Full range of the 1983 capacitance gauge (±0.010 in): a surface whose Z
/// motion exceeds it cannot be cut by this slide.
const SLIDE_RANGE_IN: f64 = 0.020;

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// CSV output (the default format; kept for the acceptance interface).
    #[arg(long)]
    pub csv: bool,
    /// JSON output instead of CSV.
    #[arg(long, conflicts_with = "csv")]
    pub json: bool,
    /// Fourier expansion of Z at one X (`--x`), CSV `k,c_in,s_in`.
    #[arg(long)]
    pub fourier: bool,
    /// Tool-centre X for `--fourier`, inches.
    #[arg(long, requires = "fourier", allow_hyphen_values = true)]
    pub x: Option<f64>,
    /// Tool-nose radius for `--fourier`, inches (default: the config's).
    #[arg(long, requires = "fourier", allow_hyphen_values = true)]
    pub tool_radius: Option<f64>,
    /// Highest harmonic for `--fourier` (default 19, Table 2-1's); otherwise
    /// overrides the config's `series.terms`.
    #[arg(long)]
    pub terms: Option<usize>,
    /// Table configuration (TOML); missing fields take the dissertation's values.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Write the firmware table image here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the accuracy report instead of the table.
    #[arg(long)]
    pub report: bool,
    /// Pick grid step and terms for this total error bound, µin.
    #[arg(long)]
    pub bound_uin: Option<f64>,
    /// With `--bound-uin`: try only binary-fraction grid steps (1/4..1/128 in).
    #[arg(long)]
    pub binary_grid: bool,
    /// Allowance for the firmware's own arithmetic inside the bound, µin.
    #[arg(long, default_value_t = 0.01)]
    pub firmware_allowance_uin: f64,
    /// Report range start, inches (default: the grid's x_min).
    #[arg(long)]
    pub x_lo: Option<f64>,
    /// Report range end, inches (default: the null-zone start x_null).
    #[arg(long)]
    pub x_hi: Option<f64>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // Range errors of a configuration name its file: the value is in it.
    let mut spec = match &args.config {
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            // A part file (docs/PARTS.md) has its own path to a table.
            if text
                .parse::<toml::Table>()
                .is_ok_and(|t| t.contains_key("tool") && t.contains_key("table"))
            {
                anyhow::bail!(
                    "{0} is a part file (docs/PARTS.md), not a table configuration: its table is \
                     `host-sim part-table {0} --out TABLE.zsct` (or `zslide table build --config \
                     {0} --out TABLE.zsct`)",
                    p.display()
                );
            }
            Config::from_toml(&text)
                .and_then(|c| Ok(c.to_spec()?))
                .with_context(|| format!("table configuration {}", p.display()))?
        }
        None => Config::default().to_spec()?,
    };
    if let Some(path) = &args.out {
        crate::outpath::check_file("--out", path)?;
    }
    let stdout = std::io::stdout();
    let mut out = stdout.lock();

    if args.fourier {
        let x = args
            .x
            .context("--fourier needs --x X (tool-centre radius, inches)")?;
        let surf = match args.tool_radius {
            Some(r) => spec
                .surface
                .with_tool_radius(r)
                .with_context(|| format!("--tool-radius {r}"))?,
            None => spec.surface,
        };
        let k_max = args.terms.unwrap_or(19);
        anyhow::ensure!(
            (1..=1000).contains(&k_max),
            "--terms = {k_max}: must be 1..=1000 harmonics"
        );
        let sec = surf.section(x).with_context(|| format!("--x {x}"))?;
        let h = coeffgen::harmonics(&sec, k_max);
        writeln!(out, "k,c_in,s_in")?;
        for k in 0..=k_max {
            writeln!(out, "{k},{:.12e},{:.12e}", h.c[k], h.s[k])?;
        }
        return Ok(());
    }

    if let Some(t) = args.terms {
        spec.terms = t;
        spec.validate()?;
    }
    let x_lo = args.x_lo.unwrap_or(spec.x_min);
    let x_hi = args.x_hi.unwrap_or(spec.x_null);
    anyhow::ensure!(
        x_lo >= spec.x_min && x_hi <= spec.x_max && x_lo <= x_hi,
        "--x-lo/--x-hi = {x_lo}..{x_hi}: must lie within the grid {}..{} in",
        spec.x_min,
        spec.x_max
    );

    if let Some(bound) = args.bound_uin {
        anyhow::ensure!(
            bound.is_finite() && bound > args.firmware_allowance_uin,
            "--bound-uin = {bound}: must exceed --firmware-allowance-uin = {}",
            args.firmware_allowance_uin
        );
        let max_terms = match spec.representation {
            Representation::SinPower => 12,
            Representation::Harmonic => 15,
        };
        let steps = if args.binary_grid {
            coeffgen::BINARY_STEPS
        } else {
            coeffgen::CANDIDATE_STEPS
        };
        let picked = coeffgen::pick(
            &spec,
            steps,
            bound,
            args.firmware_allowance_uin,
            x_lo,
            x_hi,
            max_terms,
            Sampling::default(),
        )?
        .with_context(|| format!("no grid/terms combination meets {bound} µin"))?;
        eprintln!(
            "picked: step {} in, {} terms ({} columns, {} bytes): total {:.4} µin \
             (truncation {:.4}, interpolation {:.4}, quantisation {:.4}) + firmware allowance {}",
            picked.step_in,
            picked.terms,
            picked.columns,
            picked.bytes,
            picked.errors.total_uin,
            picked.errors.truncation_uin,
            picked.errors.interpolation_uin,
            picked.errors.quantization_uin,
            args.firmware_allowance_uin
        );
        spec.step = picked.step_in;
        spec.terms = picked.terms;
    }

    let g = coeffgen::generate(&spec)?;
    if let Some(path) = &args.out {
        let img = g
            .image()
            .map_err(|e| anyhow::anyhow!("table image: {e:?}"))?;
        crate::outpath::replace(path, &img)?;
        eprintln!("wrote {} ({} bytes)", path.display(), img.len());
    }

    if args.report {
        let e = coeffgen::error_split(&g, x_lo, x_hi, Sampling::default())?;
        if e.z_peak_to_peak_in > SLIDE_RANGE_IN {
            eprintln!(
                "warning: Z moves {:.6} in peak to peak, more than the slide's {SLIDE_RANGE_IN} in \
                 gauge range (±0.010 in)",
                e.z_peak_to_peak_in
            );
        }
        return report(&mut out, &g, &e, x_lo, x_hi, args.json);
    }
    if args.json {
        table_json(&mut out, &spec)
    } else {
        table_csv(&mut out, &spec)
    }
}

/// Column names: sin-power `c00..c{N-1}` (eq 2-19's C00..C03 for N = 4),
/// harmonic `c0, c1, s1, .., cK, sK`.
pub fn column_names(spec: &TableSpec) -> Vec<String> {
    match spec.representation {
        Representation::SinPower => (0..spec.terms).map(|j| format!("c{j:02}_in")).collect(),
        Representation::Harmonic => {
            let mut v = vec!["c0_in".to_string()];
            for k in 1..=spec.terms {
                v.push(format!("c{k}_in"));
                v.push(format!("s{k}_in"));
            }
            v
        }
    }
}

/// X printed without binary noise (0.1·3 is "0.3").
fn fmt_x(x: f64) -> String {
    let r = (x * 1e9).round() / 1e9;
    let s = format!("{r}");
    if s.contains('.') {
        s
    } else {
        format!("{s}.0")
    }
}

fn table_csv(out: &mut impl Write, spec: &TableSpec) -> anyhow::Result<()> {
    writeln!(out, "x_in,{}", column_names(spec).join(","))?;
    for x in spec.nodes_decimal() {
        let cols = spec.columns_at(x)?;
        let cells: Vec<String> = cols.iter().map(|c| format!("{c:.12e}")).collect();
        writeln!(out, "{},{}", fmt_x(x), cells.join(","))?;
    }
    Ok(())
}

fn table_json(out: &mut impl Write, spec: &TableSpec) -> anyhow::Result<()> {
    let nodes = spec
        .nodes_decimal()
        .into_iter()
        .map(|x| Ok(serde_json::json!({ "x_in": x, "coeffs_in": spec.columns_at(x)? })))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let v = serde_json::json!({
        "surface": {
            "c_in": spec.surface.c(),
            "s_y_in": spec.surface.s_y(),
            "tool_radius_in": spec.surface.tool_radius(),
        },
        "grid": {
            "x_min_in": spec.x_min, "x_max_in": spec.x_max,
            "step_in": spec.step, "x_null_in": spec.x_null,
        },
        "series": {
            "representation": rep_name(spec.representation),
            "terms": spec.terms,
            "columns": column_names(spec),
        },
        "nodes": nodes,
    });
    writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
    Ok(())
}

fn rep_name(r: Representation) -> &'static str {
    match r {
        Representation::SinPower => "sin-power",
        Representation::Harmonic => "harmonic",
    }
}

fn report(
    out: &mut impl Write,
    g: &Generated,
    e: &ErrorSplit,
    x_lo: f64,
    x_hi: f64,
    json: bool,
) -> anyhow::Result<()> {
    let spec = &g.spec;
    let qbound = coeffgen::quantization_bound_uin(spec);
    if json {
        let v = serde_json::json!({
            "x_lo_in": x_lo, "x_hi_in": x_hi,
            "step_in": spec.step,
            "representation": rep_name(spec.representation),
            "terms": spec.terms,
            "columns": spec.columns(),
            "nodes": g.x.len(),
            "image_bytes": g.header.image_len(),
            "coeff_frac_bits": spec.coeff_frac_bits,
            "x_frac_bits": spec.x_frac_bits,
            "quantization_bound_uin": qbound,
            "errors": e,
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(());
    }
    writeln!(
        out,
        "table: {} {} terms ({} columns), step {} in, {} nodes, {} bytes; \
         coefficients I{}F{}, X {} fraction bits",
        rep_name(spec.representation),
        spec.terms,
        spec.columns(),
        spec.step,
        g.x.len(),
        g.header.image_len(),
        32 - spec.coeff_frac_bits,
        spec.coeff_frac_bits,
        spec.x_frac_bits
    )?;
    writeln!(out, "max |error| over X {x_lo}..{x_hi} in, all phi (µin):")?;
    writeln!(out, "  truncation (terms)         {:.4}", e.truncation_uin)?;
    writeln!(
        out,
        "  interpolation (grid)       {:.4}",
        e.interpolation_uin
    )?;
    writeln!(
        out,
        "  quantisation (fixed point) {:.4}   (format bound {:.4})",
        e.quantization_uin, qbound
    )?;
    writeln!(
        out,
        "  total                      {:.4}   at X = {:.4} in, phi = {:.1} deg",
        e.total_uin, e.worst_x_in, e.worst_phi_deg
    )?;
    writeln!(
        out,
        "  total at nodes             {:.4}",
        e.total_at_nodes_uin
    )?;
    writeln!(
        out,
        "  total midway               {:.4}",
        e.total_midway_uin
    )?;
    writeln!(
        out,
        "Z motion: up to {:.7} in peak to peak over phi",
        e.z_peak_to_peak_in
    )?;
    Ok(())
}
