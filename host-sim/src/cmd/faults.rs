//! `host-sim faults`: the fault campaign during a cut (`faults`), one row
//! per fault; `--out DIR` a trace plot (PNG, SVG, CSV) per fault and the
//! table as CSV. Bound and rows: docs/SAFETY.md ("Fault campaign").

use crate::faults::{campaign_at, spec_at, Case, Inject, Outcome, Row};
use crate::scope::{Figure, Marker, Panel, Series};
use anyhow::Context;
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: crate::scenario::ScenarioArg,
    /// Run only these faults (repeatable; default: all).
    #[arg(long, value_enum)]
    pub fault: Vec<Case>,
    /// Seed stream: 0 = the scenario's own seeds; any other value is mixed
    /// into every random stream (gauge noise, X, spindle).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Write a trace plot per fault and `faults.csv` into this directory.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Inject this many spindle revolutions after the pre-roll (default 0:
    /// the campaign's instant; refused for the faults injected at boot).
    #[arg(long, value_name = "TURNS", default_value_t = 0.0)]
    pub after_turns: f64,
    /// Inject with the tool centre at this radius, in (0 < X ≤ 7.2).
    #[arg(long, value_name = "IN", default_value_t = crate::faults::X_INJECT_IN)]
    pub x_in: f64,
    /// Spindle speed, rpm (default: the scenario's; within its band).
    #[arg(long)]
    pub rpm: Option<f64>,
    /// Instead of the campaign: the stalled loop injected at N instants
    /// evenly spread over one revolution after the pre-roll, one row per
    /// instant, what drove the tool until the reset, and the worst.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1000), conflicts_with_all = ["fault", "out", "after_turns"])]
    pub stall_sweep: Option<u32>,
    /// Instead of one campaign: every fault on legacy-hw and modern-hw at
    /// X = 1, 3, 5, 7 in, at each scenario's speed and at 360 rpm, with a
    /// stall sweep of `--phases` instants at each point; prints, per fault
    /// and machine, the outcome and the worst excursion (docs/SAFETY.md).
    #[arg(long, conflicts_with_all = ["fault", "out", "after_turns", "stall_sweep", "x_in", "rpm"])]
    pub matrix: bool,
    /// Stall instants a revolution at each point of `--matrix`.
    #[arg(long, default_value_t = 16, requires = "matrix")]
    pub phases: usize,
}

/// The matrix of `--matrix`.
pub const MATRIX_SCENARIOS: [&str; 2] = ["legacy-hw", "modern-hw"];
pub const MATRIX_X_IN: [f64; 4] = [1.0, 3.0, 5.0, 7.0];
pub const MATRIX_RPM: [Option<f64>; 2] = [None, Some(360.0)];

fn run_matrix(args: &Args) -> anyhow::Result<()> {
    let wall0 = std::time::Instant::now();
    // Each machine on its own (the same runs as both together): a row per
    // fault and machine, and the worst over both.
    let mut per: Vec<(&str, Vec<crate::faults::matrix::Worst>)> = Vec::new();
    for name in MATRIX_SCENARIOS {
        let w =
            crate::faults::matrix::run(&[name], &MATRIX_X_IN, &MATRIX_RPM, args.phases, args.seed)?;
        per.push((name, w));
    }
    let wall_s = wall0.elapsed().as_secs_f64();
    if args.json {
        let doc: Vec<_> = per
            .iter()
            .map(|(name, w)| serde_json::json!({ "scenario": name, "faults": w }))
            .collect();
        println!("{}", serde_json::to_string_pretty(&doc)?);
        return Ok(());
    }
    println!(
        "fault matrix: {} × X {:?} in × rpm (scenario's, 360), stall sweep {} instants a point, seed stream {}: {wall_s:.1} s wall",
        MATRIX_SCENARIOS.join(", "),
        MATRIX_X_IN,
        args.phases,
        args.seed
    );
    println!("| fault | machine | runs | n/a | all detected, safe | worst into the part, µin | where | slowest to safe, ms | where |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let at = |p: &Option<crate::faults::matrix::Point>| {
        p.as_ref()
            .map_or("-".into(), |p| format!("X {} in, {} rpm", p.x_in, p.rpm))
    };
    for k in 0..Case::ALL.len() {
        for (name, worst) in &per {
            let w = &worst[k];
            if w.runs == 0 {
                println!(
                    "| {} | {name} | 0 | {} | not applicable | - | - | - | - |",
                    w.fault, w.not_applicable
                );
                continue;
            }
            println!(
                "| {} | {name} | {} | {} | {} | {:.1} | {} | {:.2} | {} |",
                w.fault,
                w.runs,
                w.not_applicable,
                w.all_detected_and_safe,
                w.worst_excursion_uin,
                at(&w.worst_at),
                w.slowest_safe_ms,
                at(&w.slowest_at)
            );
        }
    }
    Ok(())
}

/// The JSON document.
#[derive(serde::Serialize, Debug)]
pub struct Summary<'a> {
    pub scenario: String,
    pub seed: u64,
    pub x_in: f64,
    pub rpm: f64,
    pub wall_s: f64,
    pub rows: Vec<&'a Row>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.matrix {
        return run_matrix(&args);
    }
    let sc = args.scenario.load()?;
    let name = sc.file.name.clone();
    let spec = spec_at(sc, args.rpm)?;
    if let Some(n) = args.stall_sweep {
        return run_sweep(&spec, &name, n as usize, args.seed, args.x_in, args.json);
    }
    let cases: Vec<Case> = if args.fault.is_empty() {
        Case::ALL.iter().chain(&Case::PROCESS).copied().collect()
    } else {
        args.fault.clone()
    };
    if let Some(dir) = &args.out {
        crate::outpath::check_dir("--out", dir)?;
    }
    let wall0 = std::time::Instant::now();
    let at = Inject {
        after_turns: args.after_turns,
        x_in: args.x_in,
    };
    let out = campaign_at(&spec, &cases, args.seed, at)?;
    let wall_s = wall0.elapsed().as_secs_f64();
    if let Some(dir) = &args.out {
        write_csv(&dir.join("faults.csv"), &out)?;
        for o in &out {
            write_trace(dir, o)?;
        }
    }
    if args.json {
        let s = Summary {
            scenario: name,
            seed: args.seed,
            x_in: args.x_in,
            rpm: spec.rpm,
            wall_s,
            rows: out.iter().map(|o| &o.row).collect(),
        };
        println!("{}", serde_json::to_string_pretty(&s)?);
        return Ok(());
    }
    println!(
        "fault campaign on {name}, digital loop, cut at X = {} in, {} rpm (seed stream {}): {:.1} s wall",
        args.x_in, spec.rpm, args.seed, wall_s
    );
    println!(
        "{:<21} {:>8} {:<17} {:<24} {:>10} {:>6} {:>10}  reason",
        "fault", "detected", "reaction", "latched", "excur µin", "safe", "to safe ms"
    );
    for o in &out {
        let r = &o.row;
        println!(
            "{:<21} {:>8} {:<17} {:<24} {:>10} {:>6} {:>10}  {}",
            r.fault,
            detected(r),
            r.reaction.as_deref().unwrap_or("-"),
            r.latched.as_deref().map_or("-".into(), |s| short(s, 24)),
            r.max_excursion_uin
                .map_or("-".into(), |v| format!("{v:.1}")),
            opt(r.safe_state),
            r.time_to_safe_ms.map_or("-".into(), |v| format!("{v:.2}")),
            r.reason
        );
    }
    Ok(())
}

/// One instant of the stall sweep: the row and what drove the tool from
/// the stall to the reset.
#[derive(serde::Serialize, Debug)]
pub struct SweepRow<'a> {
    /// Spindle turns after the pre-roll at the stall (its phase).
    pub after_turns: f64,
    pub row: &'a Row,
    pub drive: Option<Drive>,
}

/// The stall sweep's JSON document.
#[derive(serde::Serialize, Debug)]
pub struct SweepSummary<'a> {
    pub scenario: String,
    pub seed: u64,
    pub x_in: f64,
    pub rpm: f64,
    pub phases: usize,
    pub wall_s: f64,
    pub worst_excursion_uin: f64,
    pub worst_after_turns: f64,
    pub rows: Vec<SweepRow<'a>>,
}

fn run_sweep(
    spec: &crate::cut::CutSpec,
    name: &str,
    phases: usize,
    seed: u64,
    x_in: f64,
    json: bool,
) -> anyhow::Result<()> {
    let wall0 = std::time::Instant::now();
    let out = crate::faults::sweep_at(spec, Case::StalledLoop, phases, seed, x_in)?;
    let wall_s = wall0.elapsed().as_secs_f64();
    let rows: Vec<SweepRow> = out
        .iter()
        .enumerate()
        .map(|(k, o)| SweepRow {
            after_turns: k as f64 / phases as f64,
            row: &o.row,
            drive: Drive::of(o),
        })
        .collect();
    let excursion = |r: &SweepRow| r.row.max_excursion_uin.unwrap_or(f64::NAN);
    let worst = rows
        .iter()
        .max_by(|a, b| excursion(a).total_cmp(&excursion(b)))
        .context("no rows")?;
    let (worst_excursion_uin, worst_after_turns) = (excursion(worst), worst.after_turns);
    if json {
        let s = SweepSummary {
            scenario: name.to_string(),
            seed,
            x_in,
            rpm: spec.rpm,
            phases,
            wall_s,
            worst_excursion_uin,
            worst_after_turns,
            rows,
        };
        println!("{}", serde_json::to_string_pretty(&s)?);
        return Ok(());
    }
    println!(
        "stalled loop swept over one revolution on {name}, {phases} instants, cut at X = {x_in} in, {} rpm (seed stream {seed}): {wall_s:.1} s wall",
        spec.rpm
    );
    println!(
        "{:>6} {:>9} {:>8} {:>6} {:>10} {:>10} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>8} {:>8} {:>8}",
        "turn",
        "t_inj s",
        "detected",
        "safe",
        "to safe ms",
        "excur µin",
        "held V",
        "I A",
        "F0 lbf",
        "ΔF lbf",
        "Δcmd µin",
        "Δz µin",
        "rel µin",
        "v in/s",
        "peak ms"
    );
    for r in &rows {
        let d = r.drive.as_ref();
        let f = |v: Option<f64>, p: usize| v.map_or("-".into(), |v| format!("{v:.p$}"));
        println!(
            "{:>6.4} {:>9.4} {:>8} {:>6} {:>10} {:>10.1} {:>8} {:>8} {:>9} {:>9} {:>9} {:>9} {:>8} {:>8} {:>8}",
            r.after_turns,
            r.row.injected_at_s.unwrap_or(f64::NAN),
            opt(r.row.detected),
            opt(r.row.safe_state),
            f(r.row.time_to_safe_ms, 2),
            excursion(r),
            f(d.map(|d| d.held_v), 4),
            f(d.map(|d| d.current_a), 3),
            f(d.map(|d| d.force_at_stall_lbf), 3),
            f(d.map(|d| d.force_change_lbf), 3),
            f(d.map(|d| d.command_move_uin), 1),
            f(d.map(|d| d.slide_move_uin), 1),
            f(d.map(|d| d.at_release_uin), 1),
            f(d.map(|d| d.release_velocity_in_s), 4),
            f(d.map(|d| d.peak_at_ms), 2),
        );
    }
    println!(
        "worst: {worst_excursion_uin:.1} µin into the part, stalled {worst_after_turns:.4} turn after the pre-roll (bound: the depth of cut, 300 µin)"
    );
    Ok(())
}

/// What drove the tool from the stall to the release (the last sample
/// with the amplifier enabled): the DAC output held, the coil current,
/// the cutting force and its change, the exact command's move (the part's
/// surface under the tool) and the slide's; the tool goes into the part by
/// the command's move minus the slide's (+: toward +Z, out of the part).
#[derive(serde::Serialize, Debug, Clone, Copy)]
pub struct Drive {
    pub held_v: f64,
    /// Coil current at the release, A.
    pub current_a: f64,
    pub force_at_stall_lbf: f64,
    pub force_change_lbf: f64,
    pub command_move_uin: f64,
    pub slide_move_uin: f64,
    /// Into the part at the release, µin (< 0: out of it).
    pub at_release_uin: f64,
    /// The slide's velocity at the release, in/s (against the surface's
    /// own, it carries the released slide on: docs/SAFETY.md, "The
    /// released slide's carry").
    pub release_velocity_in_s: f64,
    /// When the tool was deepest, ms after the stall.
    pub peak_at_ms: f64,
}

impl Drive {
    fn of(o: &Outcome) -> Option<Drive> {
        let t_inj = (o.row.injected_at_s? * 1e9).round() as u64;
        let after = || o.trace.iter().filter(|x| x.t_ns >= t_inj);
        let first = after().next()?;
        let last = after().rev().find(|x| x.amp_enabled)?;
        let deepest = after().max_by(|a, b| b.err_in.total_cmp(&a.err_in))?;
        // The exact command under the tool: the slide minus its error.
        let exact = |x: &crate::faults::Sample| x.z_in - x.err_in;
        Some(Drive {
            held_v: last.dac_v,
            current_a: last.current_a,
            force_at_stall_lbf: first.force_lbf,
            force_change_lbf: last.force_lbf - first.force_lbf,
            command_move_uin: (exact(last) - exact(first)) * 1e6,
            slide_move_uin: (last.z_in - first.z_in) * 1e6,
            at_release_uin: -last.err_in * 1e6,
            release_velocity_in_s: last.velocity_in_s,
            peak_at_ms: (deepest.t_ns - t_inj) as f64 * 1e-6,
        })
    }
}

/// A row judged with nothing to detect (a change of the cut the loop
/// rode out) reads "none due", not "n/a" (a case the machine cannot have).
fn detected(r: &Row) -> String {
    match (r.detected, r.safe_state) {
        (None, Some(_)) => "none due".into(),
        (d, _) => opt(d),
    }
}

fn opt(b: Option<bool>) -> String {
    b.map_or("n/a".into(), |b| b.to_string())
}

fn short(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else {
        let t: String = s.chars().take(n - 1).collect();
        format!("{t}…")
    }
}

fn write_csv(path: &Path, out: &[Outcome]) -> anyhow::Result<()> {
    crate::outpath::replace_with(path, |tmp| write_csv_to(tmp, out))
        .with_context(|| format!("cannot write {}", path.display()))
}

fn write_csv_to(path: &Path, out: &[Outcome]) -> anyhow::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(
        f,
        "fault,detected,latched,reaction,max_excursion_uin,excursion_before_uin,excursion_undisturbed_uin,safe_state,time_to_safe_ms,reason"
    )?;
    let s = |o: Option<String>| o.unwrap_or_default();
    for o in out {
        let r = &o.row;
        writeln!(
            f,
            "{},{},{},{},{},{},{},{},{},\"{}\"",
            r.fault,
            s(r.detected.map(|b| b.to_string())),
            s(r.latched.as_ref().map(|l| format!("\"{l}\""))),
            s(r.reaction.clone()),
            s(r.max_excursion_uin.map(|v| format!("{v:.3}"))),
            s(r.excursion_before_uin.map(|v| format!("{v:.3}"))),
            s(r.excursion_undisturbed_uin.map(|v| format!("{v:.3}"))),
            s(r.safe_state.map(|b| b.to_string())),
            s(r.time_to_safe_ms.map(|v| format!("{v:.3}"))),
            r.reason.replace('"', "'")
        )?;
    }
    f.flush()?;
    Ok(())
}

/// Most points a plotted series keeps (every k-th sample beyond).
const MAX_POINTS: usize = 4000;

fn write_trace(dir: &Path, o: &Outcome) -> anyhow::Result<()> {
    if o.trace.is_empty() {
        return Ok(());
    }
    let t_inj = o.row.injected_at_s.unwrap_or(0.0);
    let step = o.trace.len().div_ceil(MAX_POINTS).max(1);
    let pts = |f: &dyn Fn(&crate::faults::Sample) -> f64| -> Vec<(f64, f64)> {
        o.trace
            .iter()
            .step_by(step)
            .map(|x| ((x.t_ns as f64 * 1e-9 - t_inj) * 1e3, f(x)))
            .collect()
    };
    let dig = |f: &dyn Fn(&crate::faults::Sample) -> bool| -> Vec<(f64, bool)> {
        o.trace
            .iter()
            .step_by(step)
            .map(|x| ((x.t_ns as f64 * 1e-9 - t_inj) * 1e3, f(x)))
            .collect()
    };
    let one = |label: &str, points| Series {
        label: label.into(),
        points,
    };
    // One panel per quantity and unit: the excursion (µin) is read against
    // its own scale, not against the command's 60 000-90 000 µin.
    let err = pts(&|x| x.err_in * 1e6);
    let (lo, hi) = err
        .iter()
        .fold((0.0f64, 0.0f64), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let mut err_panel = Panel::analog(
        "tool − exact command",
        "µin",
        vec![one("tool − exact command (< 0: into the part)", err)],
    );
    // After a ramp to null or a disabled amplifier the tool leaves the
    // part and this error grows to thousands of µin; the safety question
    // is how far it went *into* the part first, so the scale is kept to
    // that, and what went off it is said.
    let top = (5.0 * lo.abs()).max(25.0);
    if hi > 1.5 * top {
        let pad = 0.08 * (top - lo);
        err_panel = err_panel.limited(
            lo - pad,
            top,
            format!(
                "off scale above {top:.0} µin: up to {hi:.0} µin, the tool out of the part after the reaction"
            ),
        );
    }
    let panels = [
        err_panel,
        Panel::analog(
            "position",
            "µin",
            vec![
                one("firmware command", pts(&|x| x.command_in * 1e6)),
                one("slide position", pts(&|x| x.z_in * 1e6)),
            ],
        ),
        Panel::analog(
            "learned correction",
            "µin",
            vec![one(
                "loop reference − command",
                pts(&|x| (x.reference_in - x.command_in) * 1e6),
            )],
        ),
        Panel::analog(
            "DAC output",
            "V",
            vec![one("DAC output (amplifier input)", pts(&|x| x.dac_v))],
        ),
        Panel::digital("fault latched", dig(&|x| x.fault)),
        Panel::digital("amplifier enabled", dig(&|x| x.amp_enabled)),
    ];
    let markers = [Marker {
        x: 0.0,
        label: "fault injected".into(),
    }];
    crate::scope::write(
        dir,
        &format!("fault_{}", o.row.fault),
        &Figure {
            title: &format!("fault: {}", o.row.fault),
            subtitle: o.row.injection,
            x_label: "time after the injection, ms",
            panels: &panels,
            markers: &markers,
        },
    )
}
