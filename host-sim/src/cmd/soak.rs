//! `host-sim soak`: hours of machine time with shop-floor disturbances,
//! a summary per simulated hour (logic in `crate::soak`).

use crate::scenario::ScenarioArg;
use crate::soak::{run as run_soak, HourSummary, SoakSpec};
use indicatif::{ProgressBar, ProgressStyle};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// Simulated hours.
    #[arg(long, default_value_t = 1.0)]
    pub hours: f64,
    /// Probability that the X latch catches a carry mid-ripple (legacy X).
    #[arg(long, default_value_t = 0.05)]
    pub glitch_prob: f64,
    /// Index edge timing jitter, µs RMS.
    #[arg(long, default_value_t = 20.0)]
    pub index_jitter_us: f64,
    /// Random spindle speed offset, new every revolution, rpm RMS.
    #[arg(long, default_value_t = 2.0)]
    pub speed_noise_rpm: f64,
    /// Cutting-force noise on top of the finishing cut's mean thrust, lbf RMS.
    #[arg(long, default_value_t = 0.1)]
    pub force_noise_lbf: f64,
    /// Bandwidth of the force noise, Hz.
    #[arg(long, default_value_t = 50.0)]
    pub force_noise_hz: f64,
    /// Print JSON (one object per hour and a verdict).
    #[arg(long)]
    pub json: bool,
}

#[derive(serde::Serialize)]
struct Report<'a> {
    scenario: &'a str,
    hours: &'a [HourSummary],
    false_faults: usize,
    learned_growth_uin: f64,
    phase_drift_deg: f64,
    following_error_peak_uin: f64,
    simulated_s: f64,
    wall_s: f64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let sc = args.scenario.load()?;
    let name = sc.file.name.clone();
    let mut spec = SoakSpec::new(sc, args.hours);
    spec.glitch_prob = args.glitch_prob;
    spec.index_jitter_us = args.index_jitter_us;
    spec.speed_noise_rpm = args.speed_noise_rpm;
    spec.force_noise_lbf = args.force_noise_lbf;
    spec.force_noise_hz = args.force_noise_hz;
    let total_s = args.hours * 3600.0;
    let pb = ProgressBar::new(total_s.ceil() as u64);
    pb.set_style(
        ProgressStyle::with_template(
            "soak [{bar:40}] {pos}/{len} s simulated, {elapsed} ({eta} left)",
        )?
        .progress_chars("=> "),
    );
    let t0 = std::time::Instant::now();
    let hours = run_soak(&spec, &|t| pb.set_position(t as u64))?;
    pb.finish_and_clear();
    let wall_s = t0.elapsed().as_secs_f64();
    let learned: Vec<f64> = hours.iter().map(|h| h.learned_peak_uin).collect();
    let report = Report {
        scenario: &name,
        false_faults: hours.iter().map(|h| h.faults.len()).sum(),
        learned_growth_uin: learned.last().copied().unwrap_or(0.0)
            - learned.first().copied().unwrap_or(0.0),
        phase_drift_deg: hours.last().map_or(0.0, |h| h.phase_error_mean_deg)
            - hours.first().map_or(0.0, |h| h.phase_error_mean_deg),
        following_error_peak_uin: hours
            .iter()
            .map(|h| h.following_error_peak_uin)
            .fold(0.0, f64::max),
        hours: &hours,
        simulated_s: total_s,
        wall_s,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "soak on {name}: X {}..{} in back and forth, glitch p {}, index jitter {} us, speed noise {} rpm, force {:.2} ± {} lbf ({} Hz)",
        spec.x_lo_in,
        spec.x_hi_in,
        spec.glitch_prob,
        spec.index_jitter_us,
        spec.speed_noise_rpm,
        spec.force_mean_lbf,
        spec.force_noise_lbf,
        spec.force_noise_hz
    );
    println!(
        "{:>4} {:>7} {:>9} {:>9} {:>10} {:>9} {:>10} {:>9} {:>8} {:>15}  faults",
        "hour",
        "FE rms",
        "FE peak",
        "phase",
        "phase max",
        "learned",
        "X events",
        "glitched",
        "index",
        "rpm"
    );
    println!(
        "{:>4} {:>7} {:>9} {:>9} {:>10} {:>9} {:>10} {:>9} {:>8} {:>15}",
        "", "µin", "µin", "mean °", "°", "peak µin", "", "latches", "", "min..max"
    );
    for h in &hours {
        println!(
            "{:>4} {:>7.2} {:>9.1} {:>9.4} {:>10.4} {:>9.1} {:>10} {:>9} {:>8} {:>7.1}..{:<7.1}  {}",
            h.hour,
            h.following_error_rms_uin,
            h.following_error_peak_uin,
            h.phase_error_mean_deg,
            h.phase_error_max_deg,
            h.learned_peak_uin,
            h.x_events,
            h.x_glitched_latches,
            h.index_events,
            h.rpm_min,
            h.rpm_max,
            if h.faults.is_empty() {
                "none".to_string()
            } else {
                h.faults.join("; ")
            }
        );
    }
    println!(
        "false faults {}, learned table growth {:+.1} µin, phase drift {:+.4}°, FE peak {:.1} µin; {:.0} s simulated in {:.1} s ({:.0}x real time)",
        report.false_faults,
        report.learned_growth_uin,
        report.phase_drift_deg,
        report.following_error_peak_uin,
        total_s,
        wall_s,
        total_s / wall_s
    );
    Ok(())
}
