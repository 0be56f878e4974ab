//! `host-sim faults`: the fault campaign during a cut (`faults`), one row
//! per fault; `--out DIR` a trace plot (PNG, SVG, CSV) per fault and the
//! table as CSV. Bound and rows: docs/SAFETY.md ("Fault campaign").

use crate::faults::{campaign, spec, Case, Outcome, Row};
use crate::plot::{write_plot, Series};
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
}

/// The JSON document.
#[derive(serde::Serialize, Debug)]
pub struct Summary<'a> {
    pub scenario: String,
    pub seed: u64,
    pub x_in: f64,
    pub wall_s: f64,
    pub rows: Vec<&'a Row>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let sc = args.scenario.load()?;
    let name = sc.file.name.clone();
    let spec = spec(sc)?;
    let cases: Vec<Case> = if args.fault.is_empty() {
        Case::ALL.to_vec()
    } else {
        args.fault.clone()
    };
    let wall0 = std::time::Instant::now();
    let out = campaign(&spec, &cases, args.seed)?;
    let wall_s = wall0.elapsed().as_secs_f64();
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        write_csv(&dir.join("faults.csv"), &out)?;
        for o in &out {
            write_trace(dir, o)?;
        }
    }
    if args.json {
        let s = Summary {
            scenario: name,
            seed: args.seed,
            x_in: crate::faults::X_INJECT_IN,
            wall_s,
            rows: out.iter().map(|o| &o.row).collect(),
        };
        println!("{}", serde_json::to_string_pretty(&s)?);
        return Ok(());
    }
    println!(
        "fault campaign on {name}, digital loop, cut at X = {} in (seed stream {}): {:.1} s wall",
        crate::faults::X_INJECT_IN,
        args.seed,
        wall_s
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
            opt(r.detected),
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
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?,
    );
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
    let series = [
        Series {
            label: "tool - exact command, µin (< 0: into the part)".into(),
            points: pts(&|x| x.err_in * 1e6),
        },
        Series {
            label: "firmware command, µin".into(),
            points: pts(&|x| x.command_in * 1e6),
        },
        Series {
            label: "loop reference (command + learned correction), µin".into(),
            points: pts(&|x| x.reference_in * 1e6),
        },
        Series {
            label: "slide position, µin".into(),
            points: pts(&|x| x.z_in * 1e6),
        },
        Series {
            label: "DAC output (amplifier input), V × 100".into(),
            points: pts(&|x| x.dac_v * 100.0),
        },
        Series {
            label: "fault latched (0 / 500)".into(),
            points: pts(&|x| if x.fault { 500.0 } else { 0.0 }),
        },
        Series {
            label: "amplifier enabled (0 / 400)".into(),
            points: pts(&|x| if x.amp_enabled { 400.0 } else { 0.0 }),
        },
    ];
    write_plot(
        dir,
        &format!("fault_{}", o.row.fault),
        &format!("{}: {}", o.row.fault, o.row.injection),
        "ms after the injection",
        "µin (see legend)",
        &series,
    )
}
