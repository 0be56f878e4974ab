//! `host-sim center`: automatic part centring (Y-1594, Feezell 1967) on the
//! simulated machine, through the firmware's own sequence.

use crate::centring::{self, Lobe, Mechanics, Outcome, Setup};
use anyhow::Context;
use std::path::{Path, PathBuf};
use zslide::centring::{LoopDesign, Method};

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum MethodArg {
    /// Four samples per revolution (the 1967 machine).
    Quadrant,
    /// Least-squares first harmonic of every sample of the revolution.
    Lsq,
    /// The same, correcting during the revolution: revolutions back to back,
    /// readings compensated for the slides' motion.
    LsqMoving,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum DesignArg {
    /// Ch. V: critically damped tachometer loop (A = 700, K1 = 0.01).
    Critical,
    /// Ch. VI-VII: compensated loop of Fig. 26 (A = 2000, lead networks).
    Compensated,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Initial off-centre of the part along the X' slide, inches.
    #[arg(long, default_value_t = 0.25, allow_hyphen_values = true)]
    pub offset_x: f64,
    /// Initial off-centre along the Y' slide, inches.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub offset_y: f64,
    #[arg(long, value_enum, default_value_t = MethodArg::Lsq)]
    pub method: MethodArg,
    #[arg(long, value_enum, default_value_t = DesignArg::Compensated)]
    pub design: DesignArg,
    /// Correction ratio K (default: quadrant 0.95 critical, 0.966 compensated; LSQ 1.0).
    #[arg(long)]
    pub k: Option<f64>,
    /// Level detector: centred when both axes measure below this, inches.
    #[arg(long, default_value_t = 0.0001)]
    pub level_in: f64,
    /// Free play between each slide and its nut, inches (random seating).
    #[arg(long, default_value_t = 0.0)]
    pub free_play_in: f64,
    /// Elastic windup of each slide drive, inches (slide stops short by it).
    #[arg(long, default_value_t = 0.0)]
    pub deflection_in: f64,
    /// Transducer noise, µin rms per sample.
    #[arg(long, default_value_t = 0.0)]
    pub noise_uin: f64,
    /// Out-of-roundness of the part: a 3-lobe amplitude, µin.
    #[arg(long, default_value_t = 0.0)]
    pub lobes3_uin: f64,
    /// Table speed, rpm (1-25).
    #[arg(long, default_value_t = 25.0)]
    pub rpm: f64,
    #[arg(long, default_value_t = 10)]
    pub max_cycles: u32,
    /// Seed of the noise and free-play draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[arg(long)]
    pub json: bool,
    /// Write plots (PNG and SVG) and the CSV behind them here.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn setup(a: &Args) -> anyhow::Result<Setup> {
    for (name, v) in [
        ("--offset-x", a.offset_x),
        ("--offset-y", a.offset_y),
        ("--free-play-in", a.free_play_in),
        ("--deflection-in", a.deflection_in),
        ("--noise-uin", a.noise_uin),
        ("--lobes3-uin", a.lobes3_uin),
        ("--rpm", a.rpm),
        ("--level-in", a.level_in),
    ] {
        anyhow::ensure!(v.is_finite(), "{name} = {v} is not a number");
    }
    anyhow::ensure!(a.noise_uin >= 0.0, "--noise-uin must not be negative");
    let method = match a.method {
        MethodArg::Quadrant => Method::Quadrant,
        MethodArg::Lsq => Method::Lsq,
        MethodArg::LsqMoving => Method::LsqMoving,
    };
    let design = match a.design {
        DesignArg::Critical => LoopDesign::Critical,
        DesignArg::Compensated => LoopDesign::Compensated,
    };
    let mut s = Setup::seed([a.offset_x, a.offset_y], method, design);
    if let Some(k) = a.k {
        s.k = k;
    }
    s.level_in = a.level_in;
    s.max_cycles = a.max_cycles;
    s.rpm = a.rpm;
    s.seed = a.seed;
    s.gauge_noise_in = a.noise_uin * 1e-6;
    s.mechanics = Mechanics {
        free_play_in: a.free_play_in,
        deflection_in: a.deflection_in,
        reversed: false,
        jammed: false,
    };
    if a.lobes3_uin != 0.0 {
        s.part.lobes.push(Lobe {
            k: 3,
            amp_in: a.lobes3_uin * 1e-6,
            phase_rad: 0.3,
        });
    }
    Ok(s)
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let s = setup(&a)?;
    if let Some(dir) = &a.out {
        crate::outpath::check_dir("--out", dir)?;
    }
    let o = centring::run(&s)?;
    if let Some(dir) = &a.out {
        write_plots(dir, &o, s.level_in)
            .with_context(|| format!("writing plots to {}", dir.display()))?;
    }
    if a.json {
        let v = serde_json::json!({
            "method": format!("{:?}", s.method).to_lowercase(),
            "design": format!("{:?}", s.design).to_lowercase(),
            "k": s.k,
            "offset_in": s.part.offset_in,
            "free_play_in": s.mechanics.free_play_in,
            "deflection_in": s.mechanics.deflection_in,
            "level_in": s.level_in,
            "rpm": s.rpm,
            "centred": o.centred,
            "refusal": o.refusal,
            "final_residual_in": o.final_residual_in,
            "final_measured_in": o.final_measured_in,
            "cycles": o.cycles,
            "time_s": o.time_s,
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("cycle  measured_x_in  measured_y_in  residual_before_in  residual_after_in  correction_s  t_s");
        for c in &o.cycles {
            println!(
                "{:5}  {:13.9}  {:13.9}  {:18.9}  {:17.9}  {:12.3}  {:8.3}",
                c.cycle,
                c.measured_x_in,
                c.measured_y_in,
                c.residual_before_in,
                c.residual_in,
                c.correction_s,
                c.corrected_at_s
            );
        }
        match &o.refusal {
            None => println!(
                "centred: final residual {:.9} in ({:.2} µin) after {} correction cycles, {:.2} s",
                o.final_residual_in,
                o.final_residual_in * 1e6,
                o.cycles.len(),
                o.time_s
            ),
            Some(r) => println!(
                "refused after {:.2} s: {r}; residual {:.9} in",
                o.time_s, o.final_residual_in
            ),
        }
    }
    // A refused run is a failed run for scripts too (the report above
    // stays: it says where the sequence stopped).
    if let Some(r) = &o.refusal {
        anyhow::bail!(
            "centring refused after {:.2} s ({r}); the part is not centred, residual {:.6} in",
            o.time_s,
            o.final_residual_in
        );
    }
    Ok(())
}

fn write_plots(dir: &Path, o: &Outcome, level_in: f64) -> anyhow::Result<()> {
    use std::fmt::Write as _;
    std::fs::create_dir_all(dir)?;
    let mut csv =
        String::from("cycle,residual_before_in,residual_in,measured_at_s,corrected_at_s\n");
    for c in &o.cycles {
        writeln!(
            csv,
            "{},{:e},{:e},{},{}",
            c.cycle, c.residual_before_in, c.residual_in, c.measured_at_s, c.corrected_at_s
        )?;
    }
    crate::outpath::replace(&dir.join("center_residual.csv"), csv)?;
    let mut csv = String::from("t_s,slide_x_in,slide_y_in,motor_x_rad_s,motor_y_rad_s\n");
    for p in &o.trace {
        writeln!(
            csv,
            "{},{:e},{:e},{},{}",
            p.t_s, p.slide_x_in, p.slide_y_in, p.motor_x_rad_s, p.motor_y_rad_s
        )?;
    }
    crate::outpath::replace(&dir.join("center_slides.csv"), csv)?;
    let residual: Vec<(f64, f64)> = std::iter::once((
        0.0,
        o.cycles
            .first()
            .map_or(o.final_residual_in, |c| c.residual_before_in),
    ))
    .chain(o.cycles.iter().map(|c| (f64::from(c.cycle), c.residual_in)))
    // µin: the residuals span 0.25 in to a few µin, a log axis in µin reads
    // as whole numbers where inches would need nine decimals.
    .map(|(n, r)| (n, (r * 1e6).max(1e-3)))
    .collect();
    let level_uin = level_in * 1e6;
    crate::plot::write_svg_png(
        dir,
        "center_residual",
        (800, 500),
        |a| plot_residual(&a, &residual, level_uin),
        |a| plot_residual(&a, &residual, level_uin),
    )?;
    crate::plot::write_svg_png(
        dir,
        "center_slides",
        (800, 500),
        |a| plot_slides(&a, o),
        |a| plot_slides(&a, o),
    )
}

/// A log-axis tick: three significant digits, no exponent ("0.5", "12",
/// "250000").
fn log_tick(v: f64) -> String {
    if v <= 0.0 || !v.is_finite() {
        return String::new();
    }
    let digits = (2 - v.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

fn plot_residual<DB: plotters::prelude::DrawingBackend>(
    root: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    residual: &[(f64, f64)],
    level_uin: f64,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
    let cycles = residual.len().saturating_sub(1).max(1);
    let lo = residual
        .iter()
        .map(|p| p.1)
        .chain([level_uin])
        .fold(f64::INFINITY, f64::min)
        / 3.0;
    let hi = residual
        .iter()
        .map(|p| p.1)
        .chain([level_uin])
        .fold(0.0, f64::max)
        * 3.0;
    let mut b = ChartBuilder::on(root);
    b.margin(14);
    b.caption(
        "off-centre left after each correction cycle",
        ("sans-serif", 20),
    )
    .x_label_area_size(44)
    .y_label_area_size(80);
    let mut ch = b
        .build_cartesian_2d((0u32..cycles as u32).into_segmented(), (lo..hi).log_scale())
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    ch.configure_mesh()
        .x_desc("correction cycle (0 = as loaded)")
        .y_desc("residual off-centre, µin")
        .x_labels(cycles + 1)
        .x_label_formatter(&|v| match v {
            SegmentValue::CenterOf(n) | SegmentValue::Exact(n) => n.to_string(),
            SegmentValue::Last => String::new(),
        })
        .y_label_formatter(&|v| log_tick(*v))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let at = |n: f64| SegmentValue::CenterOf(n.round() as u32);
    let level = RGBColor(200, 0, 0);
    ch.draw_series(DashedLineSeries::new(
        vec![
            (SegmentValue::Exact(0), level_uin),
            (SegmentValue::Last, level_uin),
        ],
        8,
        5,
        level.stroke_width(2),
    ))
    .map_err(|e| anyhow::anyhow!("{e}"))?
    .label(format!(
        "level detector: centred below {} µin",
        log_tick(level_uin)
    ))
    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], level.stroke_width(2)));
    ch.draw_series(LineSeries::new(
        residual.iter().map(|&(n, r)| (at(n), r)),
        BLUE.stroke_width(2),
    ))
    .map_err(|e| anyhow::anyhow!("{e}"))?
    .label("residual after the cycle")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(2)));
    ch.draw_series(
        residual
            .iter()
            .map(|&(n, r)| Circle::new((at(n), r), 4, BLUE.filled())),
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    ch.configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}

fn plot_slides<DB: plotters::prelude::DrawingBackend>(
    root: &plotters::prelude::DrawingArea<DB, plotters::coord::Shift>,
    o: &Outcome,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    use plotters::prelude::*;
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
    let t1 = o.trace.last().map_or(1.0, |p| p.t_s).max(1e-3);
    let lo = o
        .trace
        .iter()
        .flat_map(|p| [p.slide_x_in, p.slide_y_in])
        .fold(0.0, f64::min);
    let hi = o
        .trace
        .iter()
        .flat_map(|p| [p.slide_x_in, p.slide_y_in])
        .fold(0.0, f64::max);
    let pad = ((hi - lo) * 0.05).max(1e-6);
    let mut b = ChartBuilder::on(root);
    b.margin(10);
    b.caption("slide positions during the centring", ("sans-serif", 20))
        .x_label_area_size(44)
        .y_label_area_size(80);
    let mut ch = b
        .build_cartesian_2d(0.0..t1, lo - pad..hi + pad)
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let span = hi - lo + 2.0 * pad;
    ch.configure_mesh()
        .x_desc("time, s")
        .y_desc("slide position, in")
        .y_label_formatter(&|v| crate::plot::tick_label(*v, span))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    ch.draw_series(LineSeries::new(
        o.trace.iter().map(|p| (p.t_s, p.slide_x_in)),
        &BLUE,
    ))
    .map_err(|e| anyhow::anyhow!("{e}"))?
    .label("X' slide")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    ch.draw_series(LineSeries::new(
        o.trace.iter().map(|p| (p.t_s, p.slide_y_in)),
        &RED,
    ))
    .map_err(|e| anyhow::anyhow!("{e}"))?
    .label("Y' slide")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
    ch.configure_series_labels()
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}
