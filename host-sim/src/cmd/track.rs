//! `host-sim track`: closed-loop tracking of a spindle-synchronous sinusoid
//! on the scenario's machine (logic in `crate::track`).

use crate::fwrig::Controller;
use crate::scenario::ScenarioArg;
use crate::track::{run as run_track, TrackSpec};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Command frequency, Hz (a whole number of cycles per revolution near
    /// the scenario's spindle speed; the speed is adjusted to it).
    #[arg(long, default_value_t = 10.0)]
    pub freq: f64,
    /// Command half amplitude, in (Z = A·(sin kφ − 1)).
    #[arg(long, default_value_t = 0.004)]
    pub amplitude: f64,
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// Which loop drives the amplifier.
    #[arg(long, value_enum, default_value_t = Controller::Digital)]
    pub controller: Controller,
    /// Revolutions of learning (or settling) before the measurement.
    #[arg(long, default_value_t = 40)]
    pub learn_revs: u32,
    /// Revolutions measured (≥ 10).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(10..))]
    pub measure_revs: u32,
    /// Print the JSON summary.
    #[arg(long)]
    pub json: bool,
    /// The plant's differences from the scenario's model (the loop keeps
    /// the model unless `--param` changes it).
    #[command(flatten)]
    pub perturb: crate::perturb::Perturbation,
    /// A servo parameter of the loop's design (`zslide params show` names
    /// them), e.g. one `zslide tune` set; repeat for several.
    #[arg(long = "param", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub params: Vec<String>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut sc = args.scenario.load()?;
    args.perturb.apply(&mut sc)?;
    crate::perturb::set_params(&mut sc, &args.params)?;
    let r = run_track(
        &sc,
        &TrackSpec {
            freq_hz: args.freq,
            amplitude_in: args.amplitude,
            controller: args.controller,
            learn_revs: args.learn_revs,
            measure_revs: args.measure_revs,
        },
    )?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!(
            "track {} Hz × {} in on {} ({}), harmonic {} at {:.1} rpm",
            r.freq_hz, r.amplitude_in, r.scenario, r.controller, r.harmonic, r.rpm
        );
        println!(
            "  following error: {:.2} µin peak, {:.2} µin RMS (slide − command at the true angle, {} revolutions)",
            r.following_error_peak_uin, r.following_error_rms_uin, r.measured_revs
        );
        println!("  gauge error:     {:.2} µin RMS", r.gauge_error_rms_uin);
        println!(
            "  settled after {:.3} s; {} revolutions learned; faults: {}",
            r.settle_s,
            r.learning_revs,
            if r.faults.is_empty() {
                "none".to_string()
            } else {
                r.faults.join("; ")
            }
        );
    }
    Ok(())
}
