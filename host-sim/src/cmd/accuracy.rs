//! `host-sim accuracy`: the firmware's own command path (the `zslide` core's
//! fixed-point interpolation, sine and series, bit-exact with the target)
//! against the exact surface of eq 2-15 with FOREX4's tool compensation
//! (`host_sim::surface`), over X = 0..x_null (7.2 in) and all φ; or, with
//! `--part FILE.toml`, against that part's surface (`host_sim::part`: a
//! table from `part-table`, whose header cannot name its surface).
//!
//! Sampling: every grid node, `--per-interval` points inside each interval
//! (the interpolation error peaks near the middle), X = x_null itself, and
//! `--phi` angles per turn; then, around the worst φ of each X, a sweep 64×
//! finer, so the reported maximum is the true one to well under 0.001 µin.
//! Inputs are the nominal X and φ (so X→`I8F24` and φ→binary-angle
//! quantisation are included, as is Z's `I2F30` quantisation).

use crate::part::reference::Reference;
use anyhow::Context;
use serde::Serialize;
use std::path::PathBuf;
use zslide::command::CommandGen;
use zslide::table::CoeffTable;
use zslide::units::{SpindleAngle, XInches};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print a JSON summary instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Table image to measure (default: the firmware's default table).
    #[arg(long)]
    pub table: Option<PathBuf>,
    /// X samples inside each grid interval (besides the nodes).
    #[arg(long, default_value_t = 8)]
    pub per_interval: usize,
    /// φ samples per turn (before refinement around each X's worst φ).
    #[arg(long, default_value_t = 1440)]
    pub phi: usize,
    /// Measure against this part file's surface (a table made by
    /// `part-table`) instead of the paraboloid the header names.
    #[arg(long)]
    pub part: Option<PathBuf>,
}

/// The numbers of the report (the acceptance interface's two first).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub max_error_uin: f64,
    pub max_error_at_nodes_uin: f64,
    pub worst_x_in: f64,
    pub worst_phi_deg: f64,
    /// Firmware path against the same table evaluated in f64 (interpolation
    /// and series in double precision): the fixed-point arithmetic's share.
    pub fixed_point_max_uin: f64,
    pub x_max_in: f64,
    pub table: TableInfo,
    pub samples: u64,
}

#[derive(Clone, Debug, Serialize)]
pub struct TableInfo {
    pub representation: String,
    pub columns: u8,
    pub nodes: u32,
    pub step_in: f64,
    pub coeff_frac_bits: u8,
    pub x_null_in: f64,
}

/// The table image the firmware uses by default, or the one given.
pub fn load_table(path: Option<&PathBuf>) -> anyhow::Result<Vec<u8>> {
    match path {
        Some(p) => {
            let image =
                std::fs::read(p).with_context(|| format!("reading table {}", p.display()))?;
            // Refused here, where the file's name is known.
            if let Err(e) = CoeffTable::parse(&image) {
                anyhow::bail!("table {} refused: {e}", p.display());
            }
            Ok(image)
        }
        None => default_table(),
    }
}

/// The firmware's default table image (`zslide::DEFAULT_TABLE`).
pub fn default_table() -> anyhow::Result<Vec<u8>> {
    Ok(zslide::DEFAULT_TABLE.to_vec())
}

/// The same table in f64: interpolated columns and series in double precision.
fn f64_command(t: &CoeffTable, x: f64, phi: f64) -> f64 {
    let h = t.header();
    let scale = f64::from(h.coeff_frac_bits).exp2();
    let xs = f64::from(h.x_frac_bits).exp2();
    let x0 = f64::from(h.x0_raw) / xs;
    let dx = f64::from(h.dx_raw) / xs;
    let u = ((x - x0) / dx).max(0.0);
    let i = (u.floor() as u32).min(h.node_count - 1);
    let f = u - f64::from(i);
    let col = |j: u8| {
        let a = f64::from(t.coeff_raw(i, j)) / scale;
        let b = f64::from(t.coeff_raw(i + 1, j)) / scale;
        a + (b - a) * f
    };
    match t.representation() {
        zslide::table::Representation::SinPower => {
            let s = phi.sin();
            (0..h.terms).rev().fold(0.0, |acc, j| acc * s + col(j))
        }
        zslide::table::Representation::Harmonic => {
            let mut z = col(0);
            for k in 1..=(h.terms / 2) {
                let kf = f64::from(k);
                z += col(2 * k - 1) * (kf * phi).cos() + col(2 * k) * (kf * phi).sin();
            }
            z
        }
    }
}

/// Error of the firmware path at one X over a set of angles (degrees);
/// returns (max error µin, its φ, max fixed-point error µin).
fn sweep(
    gen: &CommandGen,
    t: &CoeffTable,
    surface: &Reference,
    x: f64,
    phis: impl Iterator<Item = f64>,
) -> anyhow::Result<(f64, f64, f64, u64)> {
    let sec = surface.at(x)?;
    let xi = XInches::from_f64(x);
    let c = gen
        .coefficients(xi)
        .map_err(|f| anyhow::anyhow!("firmware fault {f:?} at X = {x}"))?;
    let (mut worst, mut at, mut fp, mut n) = (0.0f64, 0.0, 0.0f64, 0u64);
    for deg in phis {
        let a = SpindleAngle::from_degrees(deg);
        let z = gen.evaluate(&c, a).z.to_f64();
        let rad = deg.to_radians();
        let e = (z - sec.z(rad)).abs() * 1e6;
        fp = fp.max((z - f64_command(t, x, rad)).abs() * 1e6);
        if e > worst {
            worst = e;
            at = deg;
        }
        n += 1;
    }
    Ok((worst, at, fp, n))
}

/// One X of the sweep: (x, is a node, max error µin, its φ, fixed-point
/// share µin, samples).
type XResult = (f64, bool, f64, f64, f64, u64);

/// Measures a table image through the firmware path against the
/// paraboloid its header names.
pub fn measure(image: &[u8], per_interval: usize, phi: usize) -> anyhow::Result<Report> {
    let t = CoeffTable::parse(image).map_err(|e| anyhow::anyhow!("table refused: {e}"))?;
    measure_against(
        image,
        &Reference::of_header(&t.header().geometry)?,
        per_interval,
        phi,
    )
}

/// Measures a table image through the firmware path against `surface`.
pub fn measure_against(
    image: &[u8],
    surface: &Reference,
    per_interval: usize,
    phi: usize,
) -> anyhow::Result<Report> {
    let t = CoeffTable::parse(image).map_err(|e| anyhow::anyhow!("table refused: {e}"))?;
    let gen = CommandGen::new(t);
    let x_max = t.x_null().to_f64();
    let phi = phi.max(8);
    let per = per_interval.max(1);
    // Every X to visit, with a flag for nodes.
    let mut xs: Vec<(f64, bool)> = Vec::new();
    for i in 0..t.node_count() {
        let x0 = t.node_x(i).to_f64();
        if x0 > x_max {
            break;
        }
        xs.push((x0, true));
        let x1 = t.node_x(i + 1).to_f64();
        for k in 1..per {
            let x = x0 + (x1 - x0) * k as f64 / per as f64;
            if x <= x_max {
                xs.push((x, false));
            }
        }
    }
    xs.push((x_max, false));
    let threads = std::thread::available_parallelism()
        .map_or(2, |n| n.get())
        .min(8);
    let chunk = xs.len().div_ceil(threads);
    let step = 360.0 / phi as f64;
    let results: Vec<anyhow::Result<Vec<XResult>>> = std::thread::scope(|s| {
        let handles: Vec<_> = xs
            .chunks(chunk)
            .map(|part| {
                let (gen, t) = (&gen, &t);
                s.spawn(move || {
                    part.iter()
                        .map(|&(x, node)| {
                            let coarse = (0..phi).map(|j| j as f64 * step);
                            let (e, at, fp, n) = sweep(gen, t, surface, x, coarse)?;
                            let fine = (-64..=64).map(|j| at + f64::from(j) * step / 64.0);
                            let (e2, at2, fp2, n2) = sweep(gen, t, surface, x, fine)?;
                            let (e, at) = if e2 > e { (e2, at2) } else { (e, at) };
                            Ok((x, node, e, at, fp.max(fp2), n + n2))
                        })
                        .collect()
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err(anyhow::anyhow!("worker panicked")))
            })
            .collect()
    });
    let h = t.header();
    let xs_scale = f64::from(h.x_frac_bits).exp2();
    let mut r = Report {
        max_error_uin: 0.0,
        max_error_at_nodes_uin: 0.0,
        worst_x_in: 0.0,
        worst_phi_deg: 0.0,
        fixed_point_max_uin: 0.0,
        x_max_in: x_max,
        table: TableInfo {
            // The configuration file's words (`representation = "sin-power"`).
            representation: match t.representation() {
                zslide::table::Representation::SinPower => "sin-power",
                zslide::table::Representation::Harmonic => "harmonic",
            }
            .to_string(),
            columns: t.terms(),
            nodes: t.node_count(),
            step_in: f64::from(h.dx_raw) / xs_scale,
            coeff_frac_bits: h.coeff_frac_bits,
            x_null_in: x_max,
        },
        samples: 0,
    };
    for part in results {
        for (x, node, e, at, fp, n) in part? {
            if e > r.max_error_uin {
                r.max_error_uin = e;
                r.worst_x_in = x;
                r.worst_phi_deg = at.rem_euclid(360.0);
            }
            if node {
                r.max_error_at_nodes_uin = r.max_error_at_nodes_uin.max(e);
            }
            r.fixed_point_max_uin = r.fixed_point_max_uin.max(fp);
            r.samples += n;
        }
    }
    Ok(r)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let image = load_table(args.table.as_ref())?;
    let r = match &args.part {
        Some(p) => {
            let lp = crate::part::config::load_part(p)?;
            measure_against(
                &image,
                &Reference::Part(lp.part),
                args.per_interval,
                args.phi,
            )?
        }
        None => measure(&image, args.per_interval, args.phi)?,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!(
            "table: {} columns {}, {} nodes, step {} in, coefficients 2^-{} in",
            r.table.representation,
            r.table.columns,
            r.table.nodes,
            r.table.step_in,
            r.table.coeff_frac_bits
        );
        // X is an I8F24 value: 7.2 is 7.199999988 in binary, which says
        // nothing to the reader; a micro-inch is far below the table's step.
        println!(
            "X range 0..{} in, {} samples",
            trim_decimals(r.x_max_in, 6),
            r.samples
        );
        println!(
            "max error            {:.4} µin  (X = {:.5} in, φ = {:.3}°)",
            r.max_error_uin, r.worst_x_in, r.worst_phi_deg
        );
        println!("max error at nodes   {:.4} µin", r.max_error_at_nodes_uin);
        println!("fixed-point share    {:.5} µin", r.fixed_point_max_uin);
    }
    Ok(())
}

/// `v` with `digits` decimals, trailing zeros dropped ("7.2", not "7.200000").
fn trim_decimals(v: f64, digits: usize) -> String {
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}
