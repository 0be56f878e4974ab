//! `host-sim cut`: the finishing pass of chapter 5 on the simulated machine
//! and the CMM measurement of the part (`cargo sim` runs the default).
//!
//! Prints the CMM table (φ rows, X columns, µin, positive = excess stock,
//! like Table 5-2) and a summary; `--json` the fields of brief §5;
//! `--out DIR` the plots (PNG, SVG, CSV) and a VCD. The model and its
//! conventions: docs/CUT.md.

use crate::cut::part::cmm_phi_deg;
use crate::cut::plot::{column, write_plot, Series};
use crate::cut::{run_pass, Controller, CutOutcome, CutSpec, Extras, Holes};
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: crate::scenario::ScenarioArg,
    /// Loop driving the amplifier.
    #[arg(long, value_enum, default_value_t = Controller::Digital)]
    pub controller: Controller,
    /// Spindle speed, rpm (default: the scenario's; the 1983 shop had to
    /// run 360).
    #[arg(long)]
    pub rpm: Option<f64>,
    /// Bolt holes of the part face (default: the scenario's).
    #[arg(long, value_enum)]
    pub holes: Option<Holes>,
    /// Simulate the whole pass (7.25 in to the axis) instead of bands
    /// around the measured radii.
    #[arg(long)]
    pub full: bool,
    /// Print JSON instead of the table and summary.
    #[arg(long)]
    pub json: bool,
    /// Write plots (PNG, SVG, CSV) and a VCD window into this directory.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Half width of each band, in of tool-centre X.
    #[arg(long, default_value_t = 0.01)]
    pub band_in: f64,
    /// Revolutions simulated before each band's recording starts.
    #[arg(long, default_value_t = 60.0)]
    pub preroll_revs: f64,
    /// Depth of cut, in (default: the scenario's `[servo]
    /// depth_of_cut_uin`, 300 µin): the pass cuts it and the firmware's
    /// part program says it (`depth_of_cut_uin`).
    #[arg(long)]
    pub depth_in: Option<f64>,
    /// Offset added to the firmware's Z command, µin (positive: the tool
    /// stays off the part and leaves that much stock).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub z_offset_uin: f64,
    /// Cut this part (a part file, docs/PARTS.md) instead of the default
    /// table's: its table is `--table`, else the `.zsct` beside the part
    /// file, else made from it.
    #[arg(long)]
    pub part: Option<PathBuf>,
    /// The table image the firmware runs: the part's (with `--part`), or
    /// one for the default part (a compensated table, `compensate`). A
    /// compensation record beside it (`NAME.compensation.json`) puts the
    /// axial slide on the compensated program and makes the cut the next
    /// pass on the same machine (the noise new, wear and drifts repeating).
    #[arg(long)]
    pub table: Option<PathBuf>,
    /// Measure the part on a rectangular grid of NX × NY points over the
    /// square inscribed in the null circle instead of the polar CMM grid
    /// (with `--part`; docs/PARTS.md).
    #[arg(
        long,
        value_name = "NX,NY",
        requires = "part",
        conflicts_with = "budget"
    )]
    pub grid: Option<String>,
    /// Error sources beyond the loop at the scenario's `[errors]` levels
    /// (default: `all` for legacy-analog, the 1983 shop; `none` for
    /// digital, the loop's own contribution). docs/CUT.md.
    #[arg(long, value_enum)]
    pub errors: Option<crate::cut::errors::Selection>,
    /// The command generator's sign: `reversed` is the 1983 first part's
    /// mistake, measured against the reversed nominal.
    #[arg(long, value_enum, default_value_t = crate::cut::sign::CommandSign::Normal)]
    pub command_sign: crate::cut::sign::CommandSign,
    /// How the grid is measured: the true surface, or as chapter 5's CMM
    /// reads it (1 µm steps, repeatability, alignment and angle-datum
    /// residuals; `cut::cmm`).
    #[arg(long, value_enum, default_value_t = crate::cut::cmm::Measure::Exact)]
    pub measure: crate::cut::cmm::Measure,
    /// With `--measure cmm`: average this many readings of the part, each
    /// with the CMM's own noise (the mean's noise is one reading's over
    /// √N; `cut::cmm::read_averaged`).
    #[arg(long, default_value_t = 1)]
    pub cmm_readings: u32,
    /// The error budget instead of one cut: the loop alone, each source of
    /// the scenario's `[errors]` alone, all together, and the tolerance per
    /// source the goal needs (`cut::budget`).
    #[arg(long)]
    pub budget: bool,
    /// The force model's sensitivity instead of one cut: the contour band
    /// with k_t and k_e each scaled × 0.25 .. × 4 (`cut::sensitivity`).
    #[arg(long, conflicts_with = "budget")]
    pub force_sensitivity: bool,
    /// Measure the hole zone: the surface across the bolt circle's ring on
    /// a dense grid, by distance from the hole edges (`cut::holezone`;
    /// its own band runs, about five times the CMM bands' machine time).
    #[arg(long, value_enum, default_value_t = OnOff::On)]
    pub hole_zone: OnOff,
    /// Scale the force model's edge constant k_e by this factor (the
    /// process stiffness the loop does not know exactly; `--force-sensitivity`
    /// sweeps it for the CMM band alone).
    #[arg(long, default_value_t = 1.0)]
    pub ke_scale: f64,
    /// The digital firmware anticipates the open holes' edges of the
    /// part's interruption block (`zslide::servo::edges`); `off`: the same
    /// block with `edge_feedforward` 0 (the hole zone's "before"; contour
    /// monitoring still knows the holes).
    #[arg(long, value_enum, default_value_t = OnOff::On)]
    pub anticipate: OnOff,
    /// Turn every hole in the firmware's interruption block by this many
    /// degrees (not in the part): a part program with the holes in the
    /// wrong place.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub block_angle_error_deg: f64,
}

/// A switch of `cut` (`--hole-zone`, `--anticipate`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    On,
    Off,
}

/// The JSON summary (brief §5).
#[derive(serde::Serialize, Debug)]
pub struct Summary {
    pub scenario: String,
    /// The part cut (`--part`), or null for the default table's.
    pub part: Option<String>,
    pub controller: Controller,
    pub rpm: f64,
    pub holes: Holes,
    pub full: bool,
    pub contour_error_min_uin: Option<f64>,
    pub contour_error_max_uin: Option<f64>,
    pub following_error_rms_uin: f64,
    pub following_error_peak_uin: f64,
    /// The tool's lowest point against the finished surface while it cut,
    /// engagements and prerolls included, µin (null: it never cut).
    pub deepest_uin: Option<f64>,
    /// The same over the pass's one engagement, at the stock's rim
    /// (`cut::rim_stretch`), µin.
    pub rim_deepest_uin: Option<f64>,
    pub finish_rms_uin: Option<f64>,
    /// Finish by CMM radius, µin RMS.
    pub finish_rms_by_x_uin: Vec<Option<f64>>,
    pub simulated_s: f64,
    /// The simulation's wall time.
    pub wall_s: f64,
    /// The whole command's wall time to the summary: the simulation and
    /// what came before it (a part's table made, the scenario loaded).
    pub command_wall_s: f64,
    /// `simulated_s / wall_s`.
    pub real_time_factor: f64,
    /// Σ of the stretches' wall times: `simulated_s / cpu_s` is the
    /// one-core real-time factor.
    pub cpu_s: f64,
    pub faults: Vec<String>,
    pub phi_deg: Vec<f64>,
    pub x_in: Vec<f64>,
    /// 36 rows (φ) × 7 columns (X), µin, positive = excess stock; null
    /// where the probe cannot measure (inside an open bolt hole).
    pub cmm_grid_uin: Vec<Vec<Option<f64>>>,
    /// The brief's contour goal for the scenario (±µin; none for a
    /// scenario file of one's own) and whether the band is within it.
    pub contour_goal_uin: Option<f64>,
    pub contour_goal_met: Option<bool>,
    pub depth_in: f64,
    pub feed_per_rev_in: f64,
    pub mean_force_lbf: f64,
    /// Error sources applied (`none`, `all`) and the command's sign.
    pub errors: crate::cut::errors::Selection,
    pub command_sign: crate::cut::sign::CommandSign,
    /// How `cmm_grid_uin` was measured (`exact`, `cmm`), and how many
    /// CMM readings it is the mean of (1 for `exact`).
    pub measure: crate::cut::cmm::Measure,
    pub cmm_readings: u32,
    /// The rectangular grid (`--grid`), row by row: `{kind, nx, ny,
    /// points: [{x_in, y_in, radius_in, phi_deg, error_uin, absent}]}`;
    /// the polar fields above are then empty.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grid: Option<crate::cut::gridcut::RectMeasured>,
    /// The hole zone (`cut::holezone`): null where the scenario has no
    /// holes, or with `--hole-zone off` (`hole_zone_measured` false).
    pub hole_zone: Option<crate::cut::holezone::HoleZone>,
    pub hole_zone_measured: bool,
    /// The edge constant k_e the cut used, lbf/in (`--ke-scale`).
    pub k_e_lbf_per_in: f64,
    /// Largest |coil current| while recording (the CMM bands and the hole
    /// zone), A, and the amplifier's limit.
    pub current_peak_a: f64,
    pub current_limit_a: f64,
    /// With `--measure cmm`: the true contour band on the same grid, µin
    /// (the part the CMM measured, as `--measure exact` reports it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exact_contour_error_min_uin: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exact_contour_error_max_uin: Option<f64>,
}

fn summarise(spec: &CutSpec, o: &CutOutcome) -> Summary {
    let band = o.rect.as_ref().map_or(o.grid.band(), |r| r.band());
    let polar = o.rect.is_none();
    Summary {
        scenario: spec.scenario.file.name.clone(),
        part: spec.part.as_ref().map(|p| p.name.clone()),
        controller: spec.controller,
        rpm: spec.rpm,
        holes: spec.holes,
        full: spec.full,
        contour_error_min_uin: band.map(|b| b.0),
        contour_error_max_uin: band.map(|b| b.1),
        following_error_rms_uin: o.following_error_rms_uin,
        following_error_peak_uin: o.following_error_peak_uin,
        deepest_uin: o.deepest_uin.is_finite().then_some(o.deepest_uin),
        rim_deepest_uin: o.rim_deepest_uin.is_finite().then_some(o.rim_deepest_uin),
        finish_rms_uin: o
            .rect
            .as_ref()
            .map_or(o.grid.finish_rms_uin(), |r| r.finish_rms_uin()),
        finish_rms_by_x_uin: if polar {
            o.grid.finish_by_x_uin.clone()
        } else {
            vec![]
        },
        simulated_s: o.simulated_s,
        wall_s: o.wall_s,
        command_wall_s: o.wall_s,
        real_time_factor: o.simulated_s / o.wall_s,
        cpu_s: o.cpu_s,
        faults: o.faults.clone(),
        phi_deg: if polar { cmm_phi_deg() } else { vec![] },
        x_in: if polar { spec.cmm_x() } else { vec![] },
        cmm_grid_uin: if polar {
            o.grid.err_uin.clone()
        } else {
            vec![]
        },
        contour_goal_uin: contour_goal_uin(&spec.scenario.file.name),
        contour_goal_met: contour_goal_uin(&spec.scenario.file.name)
            .zip(band)
            .map(|(g, (lo, hi))| lo >= -g && hi <= g),
        depth_in: spec.depth_in,
        feed_per_rev_in: spec.feed_per_rev_in,
        mean_force_lbf: o.mean_force_lbf,
        errors: spec.errors,
        command_sign: spec.command_sign,
        measure: spec.measure,
        cmm_readings: spec.cmm_readings,
        grid: o.rect.clone(),
        hole_zone: o.zone.as_ref().map(|z| z.summary()),
        hole_zone_measured: spec.hole_zone,
        k_e_lbf_per_in: spec.scenario.cutting.k_e_lbf_per_in,
        current_peak_a: o.current_peak_a,
        current_limit_a: spec.scenario.file.amplifier.current_limit_a,
        exact_contour_error_min_uin: o.exact.as_ref().and_then(|g| g.band()).map(|b| b.0),
        exact_contour_error_max_uin: o.exact.as_ref().and_then(|g| g.band()).map(|b| b.1),
    }
}

fn spec_of(args: &Args, controller: Controller) -> anyhow::Result<CutSpec> {
    let sc = args.scenario.load()?;
    let mut spec = CutSpec::chapter5(sc, controller, args.rpm, args.holes, args.full)?;
    anyhow::ensure!(
        args.band_in > 0.0 && args.band_in <= 0.5,
        "--band-in {}: must be in (0, 0.5] in",
        args.band_in
    );
    anyhow::ensure!(
        args.preroll_revs >= 0.0 && args.preroll_revs <= 10_000.0,
        "--preroll-revs {}: must be in 0..10000",
        args.preroll_revs
    );
    spec.band_half_in = args.band_in;
    spec.preroll_revs = args.preroll_revs;
    anyhow::ensure!(
        args.z_offset_uin.abs() <= 5000.0,
        "--z-offset-uin {}: must be within ±5000 µin (half the gauge range)",
        args.z_offset_uin
    );
    spec.z_offset_in = args.z_offset_uin * 1e-6;
    if let Some(t) = &args.table {
        compensated_pass(&mut spec, t, args.part.as_deref())?;
    }
    if let Some(path) = &args.part {
        let part = crate::cmd::parttable::part_cut(path, args.table.as_ref())?;
        if let Some(g) = &args.grid {
            let (x_min, x_null) = (part.x_min, part.x_null);
            spec.grid = Some(std::sync::Arc::new(crate::cut::rectgrid::RectGrid::parse(
                g, x_min, x_null,
            )?));
        }
        spec.part = Some(part);
    }
    if let Some(e) = args.errors {
        spec.errors = e;
    }
    spec.command_sign = args.command_sign;
    spec.measure = args.measure;
    anyhow::ensure!(
        (1..=crate::cut::cmm::MAX_READINGS).contains(&args.cmm_readings),
        "--cmm-readings {}: must be 1 ..= {}",
        args.cmm_readings,
        crate::cut::cmm::MAX_READINGS
    );
    anyhow::ensure!(
        args.cmm_readings == 1 || args.measure == crate::cut::cmm::Measure::Cmm,
        "--cmm-readings {}: averages CMM readings, it needs --measure cmm (the exact grid has no noise to average)",
        args.cmm_readings
    );
    spec.cmm_readings = args.cmm_readings;
    anyhow::ensure!(
        args.ke_scale.is_finite() && args.ke_scale > 0.0 && args.ke_scale <= 10.0,
        "--ke-scale {}: must be in (0, 10]",
        args.ke_scale
    );
    spec.scenario.cutting.k_e_lbf_per_in *= args.ke_scale;
    let depth_in = args.depth_in.unwrap_or(spec.depth_in);
    check_depth(&spec, depth_in)?;
    spec.set_depth_in(depth_in)?;
    // The budget and the sweep compare the CMM grid run by run; the zone
    // is the single cut's.
    spec.hole_zone = args.hole_zone == OnOff::On && !args.budget && !args.force_sensitivity;
    spec.anticipate = args.anticipate == OnOff::On;
    anyhow::ensure!(
        args.block_angle_error_deg.is_finite() && args.block_angle_error_deg.abs() <= 360.0,
        "--block-angle-error-deg {}: must be within ±360",
        args.block_angle_error_deg
    );
    spec.block_angle_error_deg = args.block_angle_error_deg;
    Ok(spec)
}

/// Deepest cut `cut` takes, in: chapter 5's roughing passes (0.005 ..
/// 0.010 in), and the capacitance gauge's ±0.010 in range, over which the
/// slide can lift the tool clear of the stock.
pub const MAX_DEPTH_IN: f64 = 0.010;

/// Refuses a depth of cut the machine cannot take, with the reason: deeper
/// than [`MAX_DEPTH_IN`], or a steady cutting force whose current (at the
/// scenario's force constant) exceeds the amplifier's limit or the
/// firmware's (`current_limit_a`, which faults after `current_limit_ms`).
fn check_depth(spec: &CutSpec, depth_in: f64) -> anyhow::Result<()> {
    anyhow::ensure!(
        depth_in > 0.0 && depth_in <= MAX_DEPTH_IN,
        "--depth-in {depth_in}: must be in (0, {MAX_DEPTH_IN}] in (chapter 5's roughing passes \
         reach 0.010 in, the gauge's range; deeper, the slide cannot lift the tool clear of the stock)"
    );
    let f = &spec.scenario.file;
    let force = spec
        .scenario
        .cutting
        .thrust_lbf(depth_in, spec.feed_per_rev_in);
    let amps = force / f.motor.kf_lbf_per_a;
    anyhow::ensure!(
        amps <= f.amplifier.current_limit_a,
        "--depth-in {depth_in}: the steady cutting force {force:.1} lbf needs {amps:.1} A, beyond the \
         amplifier's {} A limit (scenario {}: motor.kf_lbf_per_a {}, amplifier.current_limit_a)",
        f.amplifier.current_limit_a,
        f.name,
        f.motor.kf_lbf_per_a
    );
    let fw_limit_a = spec.scenario.servo_design.current_limit_a;
    anyhow::ensure!(
        amps <= fw_limit_a,
        "--depth-in {depth_in}: the steady cutting force {force:.1} lbf needs {amps:.1} A, beyond the \
         firmware's current limit {fw_limit_a} A (servo.current_limit_a; the loop would fault CurrentLimit \
         mid-pass; scenario {}: motor.kf_lbf_per_a {})",
        f.name,
        f.motor.kf_lbf_per_a
    );
    Ok(())
}

/// `--table T`: the default part's table image (without `--part`), and,
/// when a compensation record is beside it, the axial program and the
/// pass number.
fn compensated_pass(
    spec: &mut CutSpec,
    table: &std::path::Path,
    part: Option<&std::path::Path>,
) -> anyhow::Result<()> {
    use crate::compensate::{compensated, default_part, Record};
    use crate::part::axial::AxialProgram;
    let image = crate::cmd::accuracy::load_table(Some(&table.to_path_buf()))?;
    let record = Record::beside(table, &image)?;
    let lp = match part {
        Some(p) => crate::part::config::load_part(p)?,
        None => {
            let lp = default_part().map_err(|e| anyhow::anyhow!("{e}"))?;
            let g = zslide::table::CoeffTable::parse(&image)
                .map_err(|e| anyhow::anyhow!("{e}"))?
                .header()
                .geometry;
            let r_t = spec.scenario.cutting.tool_radius_in;
            anyhow::ensure!(
                (g.tool_radius_nin as f64 * 1e-9 - r_t).abs() < 1e-9,
                "table {}: made for a {} in nose, the scenario's tool is {r_t} in",
                table.display(),
                g.tool_radius_nin as f64 * 1e-9
            );
            spec.table_image = Some(Box::leak(image.into_boxed_slice()));
            lp
        }
    };
    let Some(r) = record else {
        eprintln!(
            "table {}: no compensation record beside it: the axial slide runs the nominal program",
            table.display()
        );
        return Ok(());
    };
    anyhow::ensure!(
        r.part == lp.name,
        "table {}: its record compensates part {:?}, this cut is of {:?}",
        table.display(),
        r.part,
        lp.name
    );
    let program = compensated(&lp, r.corrections().map_err(|e| anyhow::anyhow!("{e}"))?);
    let axial = AxialProgram::new(&lp.part, &program.part, lp.table.x_min, lp.table.x_max)
        .map_err(|e| anyhow::anyhow!("table {}: the axial program: {e}", table.display()))?;
    spec.axial = Some(std::sync::Arc::new(axial));
    spec.set_pass(r.steps.len() as u64);
    eprintln!(
        "table {}: compensation pass {} ({}), the axial slide on its program",
        table.display(),
        r.steps.len(),
        r.table_crc
    );
    Ok(())
}

fn progress_bar(spec: &CutSpec) -> anyhow::Result<ProgressBar> {
    let total: f64 = crate::cut::plan(spec, spec.contact_gain()?)
        .iter()
        .map(|s| s.seconds(spec))
        .sum();
    let pb = ProgressBar::new(total.ceil() as u64);
    pb.set_style(
        ProgressStyle::with_template(
            "{msg} [{bar:40}] {pos}/{len} s simulated, {elapsed} ({eta} left)",
        )?
        .progress_chars("=> "),
    );
    pb.set_message(format!(
        "cut {} {}",
        spec.scenario.file.name,
        spec.controller.name()
    ));
    Ok(pb)
}

fn simulate(spec: &CutSpec, extras: &Extras) -> anyhow::Result<CutOutcome> {
    let pb = progress_bar(spec)?;
    let acc = std::sync::Mutex::new(0.0f64);
    let progress = |ds: f64| {
        let mut a = acc.lock().unwrap_or_else(|p| p.into_inner());
        *a += ds;
        pb.set_position(*a as u64);
    };
    // The VCD goes to the outermost band (X = 7 in, where the slide moves
    // most), or to the full pass; every band keeps its trace, so that the
    // plot can show the radius with the largest error.
    let outer = spec.cmm_x().len() as u64;
    let o = run_pass(
        spec,
        |st| {
            if spec.full || st.index == outer {
                extras.clone()
            } else {
                Extras {
                    vcd: None,
                    trace_s: extras.trace_s,
                }
            }
        },
        &progress,
    );
    pb.finish_and_clear();
    o
}

/// One cut as `run` makes it without plots (`compensate-iterate`'s
/// passes): its summary and outcome.
pub fn cut_once(args: &Args) -> anyhow::Result<(Summary, CutOutcome)> {
    let wall0 = std::time::Instant::now();
    let spec = spec_of(args, args.controller)?;
    let o = simulate(&spec, &Extras::default())?;
    let mut s = summarise(&spec, &o);
    s.command_wall_s = wall0.elapsed().as_secs_f64();
    Ok((s, o))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let wall0 = std::time::Instant::now();
    let spec = spec_of(&args, args.controller)?;
    if args.budget {
        let b = crate::cut::budget::run(&spec, &|s| eprintln!("budget: {s}"))?;
        if args.json {
            println!("{}", serde_json::to_string_pretty(&b)?);
        } else {
            print!("{}", crate::cut::budget::table(&b));
        }
        return Ok(());
    }
    if args.force_sensitivity {
        let rows = crate::cut::sensitivity::run(&spec, &|s| eprintln!("sensitivity: {s}"))?;
        if args.json {
            println!("{}", serde_json::to_string_pretty(&rows)?);
        } else {
            print!("{}", crate::cut::sensitivity::table(&spec, &rows));
        }
        return Ok(());
    }
    let mut extras = Extras::default();
    if let Some(dir) = &args.out {
        crate::outpath::check_dir("--out", dir)?;
        extras.vcd = Some((dir.join("window.vcd"), 0.0, 0.25));
        extras.trace_s = 0.5;
    }
    let o = simulate(&spec, &extras)?;
    let mut s = summarise(&spec, &o);
    if let Some(dir) = &args.out {
        write_outputs(dir, &args, &spec, &o)?;
    }
    s.command_wall_s = wall0.elapsed().as_secs_f64();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        match &s.grid {
            Some(g) => print!("{}", crate::cut::gridcut::table(g)),
            None => print_table(&s),
        }
        print_summary(&s, &o);
    }
    Ok(())
}

fn print_table(s: &Summary) {
    print!(
        "{}",
        cmm_table(&s.x_in, &s.phi_deg, &s.cmm_grid_uin, s.part.is_none())
    );
}

/// The CMM grid as text: a column per radius wide enough for its heading
/// and its values, with the decimals the values' size needs (a part
/// within a µin reads in tenths and hundredths, the 1983 part's hundreds
/// in whole µin).
pub fn cmm_table(x_in: &[f64], phi_deg: &[f64], grid: &[Vec<Option<f64>>], holes: bool) -> String {
    use std::fmt::Write as _;
    let max_abs = grid
        .iter()
        .flatten()
        .flatten()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let digits = if max_abs >= 100.0 {
        0
    } else if max_abs >= 10.0 {
        1
    } else {
        2
    };
    let heads: Vec<String> = x_in.iter().map(|x| format!("{x} in")).collect();
    let w = heads
        .iter()
        .map(|h| h.chars().count())
        .chain(std::iter::once(format!("{:.digits$}", -max_abs).len()))
        .max()
        .unwrap_or(4)
        + 2;
    let mut t = format!(
        "CMM contour error, µin (positive = excess stock; φ rows, X columns{})\n",
        if holes {
            "; 'hole' = inside an open bolt hole"
        } else {
            ""
        }
    );
    let _ = write!(t, "{:>6}", "φ\\X");
    for h in &heads {
        let _ = write!(t, "{h:>w$}");
    }
    t.push('\n');
    for (phi, row) in phi_deg.iter().zip(grid) {
        let _ = write!(t, "{:>6}", format!("{phi}°"));
        for v in row {
            let _ = match v {
                Some(e) => {
                    let v = format!("{e:.digits$}");
                    // No "-0.00": a value that rounds to zero has no sign.
                    let v = if v.trim_start_matches(['-', '0', '.']).is_empty() {
                        v.trim_start_matches('-').to_string()
                    } else {
                        v
                    };
                    write!(t, "{v:>w$}")
                }
                None => write!(t, "{:>w$}", "hole"),
            };
        }
        t.push('\n');
    }
    t
}

/// The brief's contour goal (§6), µin either side: the same for both parts.
pub fn contour_goal_uin(scenario: &str) -> Option<f64> {
    match scenario {
        "legacy-hw" => Some(30.0),
        "modern-hw" => Some(5.0),
        _ => None,
    }
}

/// The 1983 part cut the same way (chapter 5): the open holes were the
/// first part, the filled holes the second.
fn part_1983(holes: Holes) -> &'static str {
    match holes {
        Holes::Open => "1983, first part, holes open: -600 .. +600",
        Holes::Filled => "1983, second part, holes filled: -500 .. +900",
    }
}

fn opt(v: Option<f64>) -> String {
    v.map_or("-".to_string(), |v| format!("{v:.1}"))
}

fn print_summary(s: &Summary, o: &CutOutcome) {
    println!();
    println!(
        "{} / {} / {} rpm / {} / {} ({} stretch{}), depth {} in, feed {:.1} µin/rev",
        s.scenario,
        s.controller.name(),
        s.rpm,
        match &s.part {
            Some(p) => format!("part {p}"),
            None => format!("holes {}", s.holes.name()),
        },
        if s.full { "full pass" } else { "bands" },
        o.stretches,
        if o.stretches == 1 { "" } else { "es" },
        s.depth_in,
        s.feed_per_rev_in * 1e6
    );
    // The 1983 figures are of the 1983 part: a part of one's own has none.
    let (part_1983, finish_1983) = match s.part {
        Some(_) => (String::new(), ""),
        None => (
            format!(" ({})", part_1983(s.holes)),
            " (1983: 7 centre .. 60 edge)",
        ),
    };
    println!(
        "contour error      {} .. {} µin{}{part_1983}",
        opt(s.contour_error_min_uin),
        opt(s.contour_error_max_uin),
        match (s.contour_goal_uin, s.contour_goal_met) {
            (Some(g), Some(true)) => format!(": goal ±{g} µin met"),
            (Some(g), Some(false)) => format!(": goal ±{g} µin MISSED"),
            _ => String::new(),
        },
    );
    let by_x: Vec<String> = s
        .finish_rms_by_x_uin
        .iter()
        .zip(&s.x_in)
        .map(|(f, x)| format!("{x}: {}", opt(*f)))
        .collect();
    if let (Some(lo), Some(hi)) = (s.exact_contour_error_min_uin, s.exact_contour_error_max_uin) {
        println!("true contour error {lo:.1} .. {hi:.1} µin (the surface the CMM read)");
    }
    println!(
        "finish             {} µin RMS (by X in: {}){finish_1983}",
        opt(s.finish_rms_uin),
        by_x.join(", ")
    );
    println!(
        "following error    {:.1} µin RMS, {:.1} µin peak (tool minus the exact command)",
        s.following_error_rms_uin, s.following_error_peak_uin
    );
    println!(
        "cutting force      {:.2} lbf mean; coil current {:.2} A peak (amplifier limit {} A)",
        s.mean_force_lbf, s.current_peak_a, s.current_limit_a
    );
    match (&s.hole_zone, s.hole_zone_measured) {
        (Some(z), _) => println!(
            "hole zone          {}",
            crate::cut::holezone::summary_line(z)
        ),
        (None, true) => println!("hole zone          none (the part has no holes)"),
        (None, false) => println!("hole zone          not measured (--hole-zone off)"),
    }
    println!(
        "errors             {} (beyond the loop); command sign {}; measured {}",
        s.errors.name(),
        s.command_sign.name(),
        if s.cmm_readings > 1 {
            format!("{} (mean of {} readings)", s.measure.name(), s.cmm_readings)
        } else {
            s.measure.name().to_string()
        }
    );
    println!(
        "faults             {}",
        if s.faults.is_empty() {
            "none".to_string()
        } else {
            s.faults.join(", ")
        }
    );
    println!(
        "simulated          {:.1} s in {:.1} s wall: {:.0}x real time ({:.0}x per core); \
         {:.1} s wall for the whole command{}",
        s.simulated_s,
        s.wall_s,
        s.real_time_factor,
        s.simulated_s / s.cpu_s,
        s.command_wall_s,
        if s.part.is_some() {
            " (with the part's table and the plots)"
        } else {
            ""
        }
    );
}

/// "holes open" / "holes filled", as the option is written.
fn holes_words(h: Holes) -> &'static str {
    match h {
        Holes::Open => "holes open",
        Holes::Filled => "holes filled",
    }
}

/// The CMM column (index into the spec's radii) with the largest |error|.
fn worst_column(grid: &crate::cut::part::CmmGrid) -> Option<usize> {
    let mut worst: Option<(usize, f64)> = None;
    for row in &grid.err_uin {
        for (j, v) in row.iter().enumerate() {
            if let Some(v) = v {
                if worst.is_none_or(|(_, w)| v.abs() > w) {
                    worst = Some((j, v.abs()));
                }
            }
        }
    }
    worst.map(|(j, _)| j)
}

fn write_outputs(
    dir: &std::path::Path,
    args: &Args,
    spec: &CutSpec,
    o: &CutOutcome,
) -> anyhow::Result<()> {
    // A part of one's own has no bolt holes: its name says what was cut.
    let setting = match &spec.part {
        Some(p) => format!("part {}", p.name),
        None => holes_words(spec.holes).to_string(),
    };
    let what = format!(
        "{}, {}, {} rpm, {setting}",
        spec.scenario.file.name,
        spec.controller.name(),
        spec.rpm,
    );
    if let Some(r) = &o.rect {
        // A rectangular grid: its points as CSV, and the trace of the
        // first band (the grid's innermost radii).
        crate::cut::gridcut::write_csv(dir, r)?;
        let x_in = crate::cut::plan(spec, 1.0)
            .first()
            .map_or(0.0, |st| 0.5 * (st.windows[0].0 + st.windows[0].1));
        return write_trace(dir, &what, "the grid's innermost band", x_in, &o.trace);
    }
    if let Some(z) = &o.zone {
        crate::cut::zoneplot::write(dir, z, &format!("{what}: the hole zone (+ = excess stock)"))?;
    }
    crate::cut::errmap::write(
        dir,
        &o.grid,
        &spec.cmm_x(),
        &format!("{what}: CMM contour error (+ = excess stock)"),
    )?;
    // X = 7 in for both controllers (the other one run the same way).
    let j7 = spec.cmm_x().len() - 1;
    let mut x7 = vec![Series {
        label: spec.controller.name().to_string(),
        points: column(&o.grid, j7),
    }];
    for other in [Controller::Digital, Controller::LegacyAnalog] {
        if other == spec.controller {
            continue;
        }
        let oo = spec_of(args, other)
            .and_then(|mut sp| {
                // Only its CMM column is drawn.
                sp.hole_zone = false;
                simulate(&sp, &Extras::default())
            })
            .with_context(|| format!("error_x7: the {} run", other.name()))?;
        x7.push(Series {
            label: other.name().to_string(),
            points: column(&oo.grid, j7),
        });
    }
    write_plot(
        dir,
        "error_x7",
        &format!(
            "{}, {} rpm, {}: contour error at X = {} in",
            spec.scenario.file.name,
            spec.rpm,
            setting,
            spec.cmm_x()[j7]
        ),
        "φ, deg",
        "error, µin (+ = excess stock)",
        &x7,
    )?;
    // The trace of the band with the largest error (the bands are the CMM
    // radii in order; a full pass keeps one trace, at its first radius).
    let (x_in, trace) = match worst_column(&o.grid) {
        Some(j) if !spec.full && o.traces.get(j).is_some_and(|t| !t.is_empty()) => {
            (spec.cmm_x()[j], &o.traces[j])
        }
        _ => (spec.cmm_x()[j7], &o.trace),
    };
    write_trace(
        dir,
        &what,
        "the radius with the largest CMM error",
        x_in,
        trace,
    )
}

/// The following error and the cutting force tick by tick at `x_in`.
fn write_trace(
    dir: &std::path::Path,
    what: &str,
    which: &str,
    x_in: f64,
    trace: &[(f64, f64, f64)],
) -> anyhow::Result<()> {
    let t0 = trace.first().map_or(0.0, |p| p.0);
    let ms = |p: &(f64, f64, f64)| (p.0 - t0) * 1e3;
    let panels = [
        crate::scope::Panel::analog(
            "following error",
            "µin",
            vec![Series {
                label: "tool − exact command".into(),
                points: trace.iter().map(|p| (ms(p), p.1)).collect(),
            }],
        ),
        crate::scope::Panel::analog(
            "cutting force",
            "lbf",
            vec![Series {
                label: "force on the tool (+Z: out of the part)".into(),
                points: trace.iter().map(|p| (ms(p), p.2)).collect(),
            }],
        ),
    ];
    crate::scope::write(
        dir,
        "following_error",
        &crate::scope::Figure {
            title: &format!("following error and cutting force at X = {x_in} in"),
            subtitle: &format!(
                "{what}; {which}, tick by tick over {:.0} ms of the recording",
                trace.last().map_or(0.0, ms)
            ),
            x_label: "time, ms",
            panels: &panels,
            markers: &[],
        },
    )
}

#[cfg(test)]
mod tests {
    use super::cmm_table;

    #[test]
    fn a_sub_microinch_grid_reads_in_hundredths_under_separated_headings() {
        let t = cmm_table(
            &[0.1875, 0.375],
            &[0.0, 10.0],
            &[vec![Some(-0.7), Some(-0.1)], vec![Some(-0.004), None]],
            false,
        );
        let lines: Vec<&str> = t.lines().collect();
        assert!(!lines[0].contains("hole"), "{t}");
        let head: Vec<&str> = lines[1].split_whitespace().collect();
        assert_eq!(head, ["φ\\X", "0.1875", "in", "0.375", "in"], "{t}");
        assert_eq!(
            lines[2].split_whitespace().collect::<Vec<_>>(),
            ["0°", "-0.70", "-0.10"]
        );
        assert_eq!(
            lines[3].split_whitespace().collect::<Vec<_>>(),
            ["10°", "0.00", "hole"]
        );
        // The 1983 part's hundreds of µin stay whole.
        let t = cmm_table(&[1.0], &[0.0], &[vec![Some(-523.4)]], true);
        assert!(t.lines().nth(2).unwrap().ends_with(" -523"), "{t}");
        assert!(t.lines().next().unwrap().contains("'hole'"), "{t}");
    }
}
