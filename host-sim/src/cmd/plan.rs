//! `host-sim plan PART.toml [--scenario S] [--rpm R] [--json] [--out DIR]`:
//! the feasibility check before cutting (`host_sim::part::plan`). Exits
//! non-zero with every reason in words when the part is infeasible; `--out`
//! writes the predicted following-error map (PNG, SVG, CSV).

use crate::cmd::response::measure_digital;
use crate::part::config::load_part;
use crate::part::plan::{plan, sections, Machine, Plan, SensitivityTable, PHI};
use crate::plot::{write_plot, Series};
use anyhow::bail;
use rayon::prelude::*;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Part file (TOML; docs/PARTS.md).
    pub part: PathBuf,
    #[command(flatten)]
    pub scenario: crate::scenario::ScenarioArg,
    /// Spindle speed, rpm (default: the scenario's).
    #[arg(long)]
    pub rpm: Option<f64>,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// Write the predicted following-error map here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// X sections across the table's range.
    #[arg(long, default_value_t = 33)]
    pub x_points: usize,
}

/// The digital loop's sensitivity, measured as `response --loop digital`
/// does, from 1 to 200 Hz (15 harmonics at up to 800 rpm).
pub fn measure_sensitivity(sc: &crate::scenario::Scenario) -> SensitivityTable {
    let n = 25;
    let f_hz: Vec<f64> = (0..n)
        .map(|i| 200f64.powf(i as f64 / (n - 1) as f64))
        .collect();
    let s = f_hz
        .par_iter()
        .map(|&f| measure_digital(sc, f, 20e-6, false).s)
        .collect();
    SensitivityTable { f_hz, s }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let lp = load_part(&args.part)?;
    let sc = args.scenario.load()?;
    let rpm = args.rpm.unwrap_or(sc.file.spindle.rpm);
    anyhow::ensure!(rpm.is_finite() && rpm > 0.0, "--rpm {rpm}: must be > 0");
    let s = sections(&lp, args.x_points).map_err(|e| anyhow::anyhow!("part {}: {e}", lp.name))?;
    let sens = measure_sensitivity(&sc);
    let p = plan(&lp, &s, &Machine::of(&sc), rpm, &|f| sens.at(f));
    if let Some(dir) = &args.out {
        crate::outpath::check_dir("--out", dir)?;
        write_map(dir, &p)?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&p)?);
    } else {
        print(&p);
    }
    if !p.feasible {
        let reasons: Vec<String> = p.checks.iter().filter_map(|c| c.reason.clone()).collect();
        bail!(
            "part {} is not feasible on {} at {} rpm:\n  - {}",
            p.part,
            p.machine.scenario,
            p.rpm,
            reasons.join("\n  - ")
        );
    }
    Ok(())
}

fn print(p: &Plan) {
    println!("part {}: {}", p.part, p.surface);
    println!(
        "machine {} at {} rpm, X {}..{} in",
        p.machine.scenario, p.rpm, p.x_range_in.0, p.x_range_in.1
    );
    for c in &p.checks {
        println!(
            "  {:<26} {:>12.6} {:<18} limit {:<10} {}",
            c.name,
            c.value,
            c.unit,
            c.limit,
            if c.ok { "ok" } else { "FAIL" }
        );
    }
    println!(
        "predicted following error {:.2} µin peak, {:.2} µin RMS (loop sensitivity only: an upper estimate); highest significant harmonic {:.1} Hz, loop bandwidth {} Hz",
        p.predicted_error_peak_uin,
        p.predicted_error_rms_uin,
        p.highest_significant_hz,
        p.machine.bandwidth_hz
    );
    match p.max_rpm_for_bound {
        Some(r) => println!(
            "highest spindle speed keeping the predicted error within {} µin: {:.0} rpm",
            p.error_bound_uin, r
        ),
        None => println!(
            "no speed in the band {}..{} rpm keeps the predicted error within {} µin",
            p.machine.min_rpm, p.machine.max_rpm, p.error_bound_uin
        ),
    }
    println!(
        "{}",
        if p.feasible {
            "feasible"
        } else {
            "NOT feasible"
        }
    );
}

fn write_map(dir: &std::path::Path, p: &Plan) -> anyhow::Result<()> {
    // One curve per X (at most 8 of them, evenly spread), error vs φ.
    let n = p.x_in.len();
    let k = 8.min(n).max(2);
    let pick: Vec<usize> = (0..k).map(|i| i * (n - 1) / (k - 1)).collect();
    let series: Vec<Series> = pick
        .into_iter()
        .map(|i| Series {
            label: format!("X = {:.3} in", p.x_in[i]),
            points: (0..PHI)
                .map(|j| (360.0 * j as f64 / PHI as f64, p.error_map_uin[i][j]))
                .collect(),
        })
        .collect();
    write_plot(
        dir,
        "predicted_error_map",
        &format!(
            "{} on {} at {} rpm: predicted following error (µin)",
            p.part, p.machine.scenario, p.rpm
        ),
        "φ, deg",
        "predicted following error, µin",
        &series,
    )
}
