//! `host-sim compensate MEASURED --out F.zsct [--from T.zsct] [--gain G]
//! [--part P.toml] [--json]` (and `zslide table compensate`, the same
//! code): the table that cuts the measured part's repeatable error away
//! (`crate::compensate`, docs/PARTS.md "Compensating a measured part").
//! Exits 1 with the reason when the data cannot support a fit or the
//! compensated surface is refused by the table generator or the plan's
//! stroke and slope checks.

use crate::compensate::fit::{self, FitReport, Limits, OrderScore};
use crate::compensate::measured::{self, Measurement};
use crate::compensate::{
    compensated, crc_of, default_part, record_path, Record, Step, DEFAULT_PART,
};
use crate::part::config::{load_part, LoadedPart};
use anyhow::{anyhow, bail, Context};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// The measured part: `cut --json` output, `cut --out`'s error_map.csv
    /// or grid_error.csv, or a CSV `x_in,y_in,error_uin` in the part frame
    /// (x = X cos φ, y = X sin φ; error positive = excess stock).
    pub measured: PathBuf,
    /// Write the compensated table here (and its record beside it,
    /// `NAME.compensation.json`).
    #[arg(long)]
    pub out: PathBuf,
    /// The table the measured part was cut with (default: the part's
    /// nominal table): a second iteration corrects the first.
    #[arg(long)]
    pub from: Option<PathBuf>,
    /// Share of the fitted error taken off, 0 < G <= 1.
    #[arg(long, default_value_t = 1.0)]
    pub gain: f64,
    /// The part file (default: the dissertation's paraboloid, the default table's part).
    #[arg(long)]
    pub part: Option<PathBuf>,
    /// The table's command-error bound, µin (default: the part file's
    /// `bound_uin`; 0.5 for the default part).
    #[arg(long)]
    pub bound_uin: Option<f64>,
    /// The instrument's noise, 1σ µin (default: what the file states, `cut
    /// --json`'s `measure`; else chapter 5's CMM, 23 µin).
    #[arg(long)]
    pub noise_uin: Option<f64>,
    /// Take the fitted tilt off the part too. By default it is fitted but
    /// left on: a CMM aligned to the part's face leaves a tilt of its own
    /// (`cut::cmm`: 3 µin per in, a new direction each measurement, and
    /// the face's own levelling error, the scenario's face tilt), which
    /// one measurement cannot tell from the part's.
    #[arg(long)]
    pub keep_tilt: bool,
    /// The machine the stroke and slope are checked against.
    #[command(flatten)]
    pub scenario: crate::scenario::ScenarioArg,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(serde::Serialize)]
pub struct Report {
    pub part: String,
    pub measurement: String,
    pub kind: measured::Kind,
    pub sha256: String,
    pub points: usize,
    pub absent: usize,
    pub instrument_noise_uin: f64,
    pub limits: Limits,
    pub largest_hole_in: f64,
    pub fit: fit::ErrorFit,
    /// The fitted tilt's height at the fit's radius, µin, and the most
    /// the set-up leaves there ((the CMM's alignment residual + the
    /// scenario's face tilt) × the radius).
    pub tilt_edge_uin: f64,
    pub setup_tilt_edge_uin: f64,
    /// Whether the tilt is in the correction (`--keep-tilt`).
    pub tilt_compensated: bool,
    /// Leave-one-out error of every order tried.
    pub orders: Vec<OrderScore>,
    pub gain: f64,
    /// Steps the table compensates (this one and those of `--from`).
    pub iteration: usize,
    pub table: crate::cmd::parttable::Report,
    /// The plan's stroke, current, voltage, slope and X-range checks on the
    /// compensated surface (the following error is `plan`'s, with the loop).
    pub checks: Vec<crate::part::plan::Check>,
    pub record: String,
}

/// The part and the steps already in `from`.
fn base(args: &Args) -> anyhow::Result<(LoadedPart, Vec<Step>)> {
    let lp = match &args.part {
        Some(p) => load_part(p)?,
        None => default_part().map_err(|e| anyhow!("the default part: {e}"))?,
    };
    let Some(from) = &args.from else {
        return Ok((lp, vec![]));
    };
    let image = crate::cmd::accuracy::load_table(Some(from))?;
    match Record::beside(from, &image)? {
        Some(r) => {
            anyhow::ensure!(
                r.part == lp.name,
                "--from {}: its record compensates part {:?}, not {:?}",
                from.display(),
                r.part,
                lp.name
            );
            Ok((lp, r.steps))
        }
        None if args.part.is_none() && image != zslide::DEFAULT_TABLE => bail!(
            "--from {}: not the default table and no record beside it ({}): what it cut cannot be told",
            from.display(),
            record_path(from).display()
        ),
        None => {
            eprintln!(
                "--from {}: no compensation record beside it: taken as the part's nominal table",
                from.display()
            );
            Ok((lp, vec![]))
        }
    }
}

/// Fits, generates, checks; returns the image, its record and the report.
pub fn make(args: &Args) -> anyhow::Result<(Vec<u8>, Record, Report)> {
    anyhow::ensure!(
        args.gain.is_finite() && args.gain > 0.0 && args.gain <= 1.0,
        "--gain {}: must be in (0, 1]",
        args.gain
    );
    let (mut lp, mut steps) = base(args)?;
    let bytes = std::fs::read(&args.measured)
        .with_context(|| format!("reading {}", args.measured.display()))?;
    let m: Measurement = measured::parse(&bytes)
        .map_err(|e| anyhow!("{}: refused: {e}", args.measured.display()))?;
    let noise = match args.noise_uin {
        Some(n) if n.is_finite() && n > 0.0 => n,
        Some(n) => bail!("--noise-uin {n}: must be > 0"),
        None => m.stated_noise_uin.unwrap_or_else(measured::cmm_noise_uin),
    };
    let limits = Limits::default();
    let FitReport {
        mut fit,
        orders,
        largest_hole_in,
    } = fit::fit(&m.points, lp.table.x_null, noise, &limits)
        .map_err(|e| anyhow!("{}: no fit: {e}", args.measured.display()))?;
    if !args.keep_tilt {
        fit.excluded = fit::TILT
            .into_iter()
            .filter(|&j| j <= fit.coefficients_uin.len())
            .collect();
    }
    // The most the set-up tilts the reading: the CMM's alignment residual
    // and the levelling on the part's face (the scenario's face tilt).
    let face_tilt_uin_per_in = args.scenario.load()?.file.errors.face_tilt_uin_per_in.abs();
    let setup_tilt_edge_uin = (crate::cut::cmm::CmmLevels::renault().tilt_in_per_in * 1e6
        + face_tilt_uin_per_in)
        * fit.radius_in;
    steps.push(Step {
        measurement: args.measured.display().to_string(),
        sha256: m.sha256.clone(),
        kind: format!("{:?}", m.kind),
        points: m.points.len(),
        absent: m.absent,
        instrument_noise_uin: noise,
        gain: args.gain,
        fit: fit.clone(),
    });
    if let Some(b) = args.bound_uin {
        anyhow::ensure!(b.is_finite() && b > 0.0, "--bound-uin {b}: must be > 0");
        lp.bound_uin = b;
    }
    let corrections = steps
        .iter()
        .map(|s| s.fit.surface().map(|z| (s.gain, z)))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| anyhow!("{e}"))?;
    let cp = compensated(&lp, corrections);
    let (_, image, table) = crate::cmd::parttable::make(&cp)?;
    let checks = plan_checks(&cp, &args.scenario)?;
    let failed: Vec<String> = checks.iter().filter_map(|c| c.reason.clone()).collect();
    if !failed.is_empty() {
        bail!(
            "the compensated surface is not feasible on {}:\n  - {}",
            args.scenario.scenario,
            failed.join("\n  - ")
        );
    }
    let record = Record {
        part: lp.name.clone(),
        table_crc: crc_of(&image)?,
        bound_uin: lp.bound_uin,
        steps,
    };
    let report = Report {
        part: lp.name.clone(),
        measurement: args.measured.display().to_string(),
        kind: m.kind,
        sha256: m.sha256,
        points: m.points.len(),
        absent: m.absent,
        instrument_noise_uin: noise,
        limits,
        largest_hole_in,
        tilt_edge_uin: fit.tilt_edge_uin(),
        setup_tilt_edge_uin,
        tilt_compensated: args.keep_tilt,
        fit,
        orders,
        gain: args.gain,
        iteration: record.steps.len(),
        table,
        checks,
        record: record_path(&args.out).display().to_string(),
    };
    Ok((image, record, report))
}

/// The plan's machine checks on the compensated surface (not the
/// following error, which needs the loop's measured sensitivity: `plan`).
fn plan_checks(
    cp: &LoadedPart,
    sc: &crate::scenario::ScenarioArg,
) -> anyhow::Result<Vec<crate::part::plan::Check>> {
    use crate::part::plan::{plan, sections, Machine};
    let sc = sc.load()?;
    let s = sections(cp, 33).map_err(|e| anyhow!("{e}"))?;
    let p = plan(cp, &s, &Machine::of(&sc), sc.file.spindle.rpm, &|_| {
        nalgebra::Complex::new(0.0, 0.0)
    });
    Ok(p.checks
        .into_iter()
        .filter(|c| c.name != "predicted_following_error" && c.name != "rpm_band")
        .collect())
}

fn write(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}

/// Writes the table and its record beside it.
pub fn save(out: &Path, image: &[u8], record: &Record) -> anyhow::Result<()> {
    write(out, image)?;
    write(
        &record_path(out),
        serde_json::to_string_pretty(record)?.as_bytes(),
    )
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (image, record, r) = make(&args)?;
    save(&args.out, &image, &record)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
        return Ok(());
    }
    let f = &r.fit;
    println!(
        "measurement {} ({:?}): {} points fitted, {} marked unmeasured; SHA-256 {}",
        r.measurement, r.kind, r.points, r.absent, r.sha256
    );
    println!(
        "fit: Zernike to radial order {} ({} terms) on {} in, chosen by leave-one-out ({:.2} µin RMS); \
         residual {:.2} µin RMS, σ̂ {:.2} µin against the instrument's {:.2} µin: {:.1} % of the \
         measured variance treated as noise; largest coverage hole {:.2} in",
        f.order,
        f.coefficients_uin.len(),
        f.radius_in,
        f.loo_rms_uin,
        f.residual_rms_uin,
        f.noise_estimate_uin,
        r.instrument_noise_uin,
        f.noise_share * 100.0,
        r.largest_hole_in
    );
    println!(
        "tilt: {:.1} µin at {} in ({}); the set-up (the CMM's alignment, the face's levelling) leaves up to {:.1} µin there{}",
        r.tilt_edge_uin,
        f.radius_in,
        if r.tilt_compensated {
            "compensated, --keep-tilt"
        } else {
            "left on the part: a set-up term"
        },
        r.setup_tilt_edge_uin,
        if !r.tilt_compensated && r.tilt_edge_uin > 2.0 * r.setup_tilt_edge_uin {
            ": more than twice that, the part's own tilt? level it on the faceplate, or --keep-tilt"
        } else {
            ""
        }
    );
    let t = &r.table;
    println!(
        "table (iteration {}, gain {}): harmonic, {} harmonics, step {} in, {} nodes, {} bytes, CRC {}; \
         error {:.4} µin (bound {})",
        r.iteration,
        r.gain,
        t.harmonics,
        t.step_in,
        t.nodes,
        t.bytes,
        t.crc,
        t.errors.total_uin,
        t.bound_uin
    );
    for c in &r.checks {
        println!(
            "  {:<20} {:>12.6} {:<6} limit {}",
            c.name, c.value, c.unit, c.limit
        );
    }
    println!("wrote {} and {}", args.out.display(), r.record);
    if r.part == DEFAULT_PART {
        println!("cut it: host-sim cut --table {}", args.out.display());
    }
    Ok(())
}
