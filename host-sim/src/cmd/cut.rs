//! `host-sim cut` (and `cargo sim`): the finishing cut by bands around the
//! CMM radii, the part measured on the CMM grid (logic in `crate::cut`).

use crate::cut::{run as run_cut, CutSpec, Holes};
use crate::fwrig::Controller;
use crate::scenario::ScenarioArg;
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// Which loop drives the amplifier.
    #[arg(long, value_enum, default_value_t = Controller::Digital)]
    pub controller: Controller,
    /// Spindle speed, rpm (default: the scenario's; the shop had to run 360).
    #[arg(long)]
    pub rpm: Option<f64>,
    /// The part's bolt holes: open (first part) or filled (second part).
    #[arg(long, value_enum, default_value_t = Holes::Filled)]
    pub holes: Holes,
    /// Simulate the whole pass instead of bands (not available yet).
    #[arg(long)]
    pub full: bool,
    /// Print the JSON report.
    #[arg(long)]
    pub json: bool,
    /// Write the CMM grid, the X = 7 in error against φ and an SVG error plot here.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        !args.full,
        "--full (the whole 3.4 h pass) is not available yet: run the default bands"
    );
    let sc = args.scenario.load()?;
    let spec = CutSpec::new(&sc, args.controller, args.rpm, args.holes);
    anyhow::ensure!(
        spec.rpm >= f64::from(sc.file.spindle.min_rpm)
            && spec.rpm <= f64::from(sc.file.spindle.max_rpm),
        "--rpm {}: outside the scenario's {}..{} rpm",
        spec.rpm,
        sc.file.spindle.min_rpm,
        sc.file.spindle.max_rpm
    );
    let bar = indicatif::ProgressBar::new(crate::cut::CMM_X_IN.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} bands, {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message(format!("cutting ({:?}, {} rpm)", args.controller, spec.rpm));
    let (r, bands) = run_cut(&sc, &spec, Some(&bar));
    bar.finish_and_clear();
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let mut csv = String::from("phi_deg");
        for x in &r.x_in {
            csv.push_str(&format!(",x{x}_uin"));
        }
        csv.push('\n');
        for (j, row) in r.cmm_grid_uin.iter().enumerate() {
            csv.push_str(&format!("{}", r.phi_deg[j]));
            for v in row {
                csv.push_str(&v.map_or(",".to_string(), |v| format!(",{v:.3}")));
            }
            csv.push('\n');
        }
        std::fs::write(dir.join("cmm_grid.csv"), csv)?;
        let b7 = bands.last().context("no band")?;
        let mut t = String::from("phi_deg,excess_uin\n");
        for (p, e) in &b7.trace {
            t.push_str(&format!("{p},{:.4}\n", e * 1e6));
        }
        std::fs::write(dir.join("x7_error.csv"), t)?;
        plot_grid(&dir.join("cmm_error.svg"), &r)?;
        std::fs::write(dir.join("report.json"), serde_json::to_string_pretty(&r)?)?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
        return Ok(());
    }
    println!(
        "CMM error of the simulated part, µin, positive = excess stock ({}, {}, {} rpm, holes {:?})",
        r.scenario, r.controller, r.rpm, r.holes
    );
    print!("  phi\\X ");
    for x in &r.x_in {
        print!("{:>9}", format!("{x} in"));
    }
    println!();
    for (j, row) in r.cmm_grid_uin.iter().enumerate() {
        print!("{:>6}° ", r.phi_deg[j]);
        for v in row {
            match v {
                Some(v) => print!("{v:>9.1}"),
                None => print!("{:>9}", "hole"),
            }
        }
        println!();
    }
    println!(
        "contour band {:.1} .. {:.1} µin (goal ±30 legacy-hw, ±5 modern-hw; 1983: -500 .. +900)",
        r.contour_error_min_uin, r.contour_error_max_uin
    );
    println!(
        "finish {:.2} µin RMS (by radius 1..7 in: {}); following error {:.2} µin RMS, {:.1} peak",
        r.finish_rms_uin,
        r.finish_rms_by_radius_uin
            .iter()
            .map(|v| format!("{v:.2}"))
            .collect::<Vec<_>>()
            .join(", "),
        r.following_error_rms_uin,
        r.following_error_peak_uin
    );
    println!(
        "faults: {}; {:.1} s of machine time in {:.2} s ({:.0}× real time, 7 bands on {} threads)",
        if r.faults.is_empty() {
            "none".into()
        } else {
            r.faults.join("; ")
        },
        r.simulated_s,
        r.wall_s,
        r.simulated_s / r.wall_s.max(1e-9),
        rayon::current_num_threads()
    );
    Ok(())
}

fn plot_grid(path: &std::path::Path, r: &crate::cut::CutReport) -> anyhow::Result<()> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (900, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let vals: Vec<f64> = r.cmm_grid_uin.iter().flatten().flatten().copied().collect();
    let lo = vals.iter().copied().fold(0.0, f64::min).floor() - 1.0;
    let hi = vals.iter().copied().fold(0.0, f64::max).ceil() + 1.0;
    let mut ch = ChartBuilder::on(&root)
        .caption(
            format!(
                "CMM error by radius against φ, µin, + = excess stock ({}, {})",
                r.scenario, r.controller
            ),
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..360.0, lo..hi)?;
    ch.configure_mesh().x_desc("φ (deg)").y_desc("µin").draw()?;
    for (i, x) in r.x_in.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        ch.draw_series(LineSeries::new(
            r.cmm_grid_uin
                .iter()
                .enumerate()
                .filter_map(|(j, row)| row[i].map(|v| (r.phi_deg[j], v))),
            color,
        ))?
        .label(format!("X = {x} in"))
        .legend(move |(a, b)| PathElement::new(vec![(a, b), (a + 20, b)], color));
    }
    ch.configure_series_labels().border_style(BLACK).draw()?;
    root.present()?;
    Ok(())
}
