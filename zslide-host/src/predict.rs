//! What `zslide tune` predicts for a design before it sets it: the digital
//! loop's margins and the 10 Hz × 0.004 in following error, measured on the
//! fitted plant by the same simulation of the firmware that
//! `host-sim response --loop digital` and `host-sim track` run. The
//! prediction is the identified slide with the data sheet's motor, gauge
//! and board timing (the scenario `identify` was given), so it is as good
//! as the fit: it says nothing of what the fit cannot see (friction, the
//! cut's forces).

use host_sim::cmd::response::{fmt_opt as opt, sweep_digital, Margins, DIGITAL_AMPLITUDE_IN};
use host_sim::fwrig::Controller;
use host_sim::scenario::Scenario;
use host_sim::track::{run as track, TrackSpec};
use zslide::servo::design::ServoDesign;
use zslide_plant::ModeParams;

use crate::fit::Plant;
use crate::Result;

/// The figure the issue and the 1983 dissertation judge a loop by:
/// tracking a 10 Hz, 0.004 in command (BRIEF.md).
pub const TRACK_FREQ_HZ: f64 = 10.0;
pub const TRACK_AMPLITUDE_IN: f64 = 0.004;

/// The sweep that brackets the crossings (each then refined by bisection,
/// so the margins do not depend on its density): 10 Hz, below any
/// crossover a slide's loop has, to 6.4 kHz, past the Nyquist frequency of
/// a 10 kHz loop and the coil-frame mode.
const SWEEP: (f64, f64, usize) = (10.0, 6400.0, 40);

/// One design's predicted figures.
#[derive(Clone, Copy, Debug)]
pub struct Prediction {
    pub margins: Margins,
    /// 10 Hz × 0.004 in: following error peak and RMS, µin, with the
    /// learning as the design has it.
    pub track_uin: (f64, f64),
    /// The same with the learning gain 0 (what the loop's design alone
    /// gives, which the model sets).
    pub track_no_learning_uin: (f64, f64),
}

/// The scenario `data_sheet` with its slide replaced by the fit `p`
/// (amplifier gain, moving mass, the mode, the delay to the DAC) and its
/// loop designed by `design`.
pub fn fitted_machine(data_sheet: &Scenario, p: &Plant, design: &ServoDesign) -> Result<Scenario> {
    let mut sc = data_sheet.clone();
    sc.rig.amplifier.gain = p.amp_gain;
    sc.rig.slide.mass_lbf_s2_per_in = p.mass_lbf_s2_per_in;
    sc.rig.slide.mode = Some(ModeParams {
        pole_hz: p.mode_pole_hz,
        zero_hz: p.mode_zero_hz,
        zeta: p.mode_zeta,
    });
    // The rig's DAC frame cannot end before the handler has read its
    // inputs.
    sc.rig.dac_latency_ns = ((p.delay_s * 1e9).round() as u64).max(sc.rig.handler_entry_ns);
    sc.servo_design = *design;
    sc.servo = design
        .config()
        .map_err(|e| format!("the design is refused: {}", design.refusal(e)))?;
    Ok(sc)
}

/// The figures of `design` on the fitted plant.
pub fn predict(data_sheet: &Scenario, p: &Plant, design: &ServoDesign) -> Result<Prediction> {
    let sc = fitted_machine(data_sheet, p, design)?;
    let freqs = host_sim::analyser::log_freqs(SWEEP.0, SWEEP.1, SWEEP.2);
    let (_, margins) = sweep_digital(&sc, &freqs, DIGITAL_AMPLITUDE_IN, false);
    let spec = TrackSpec {
        freq_hz: TRACK_FREQ_HZ,
        amplitude_in: TRACK_AMPLITUDE_IN,
        controller: Controller::Digital,
        learn_revs: 40,
        measure_revs: 10,
    };
    let run = |sc: &Scenario| -> Result<(f64, f64)> {
        let r = track(sc, &spec).map_err(|e| format!("predicting the tracking: {e:#}"))?;
        if !r.faults.is_empty() {
            return Err(format!(
                "the design faults on the fitted plant while tracking {TRACK_FREQ_HZ} Hz × \
                 {TRACK_AMPLITUDE_IN} in: {}",
                r.faults.join("; ")
            ));
        }
        Ok((r.following_error_peak_uin, r.following_error_rms_uin))
    };
    let track_uin = run(&sc)?;
    let mut off = sc.clone();
    host_sim::perturb::set_params(&mut off, &["learning_gain=0".into()])
        .map_err(|e| format!("{e:#}"))?;
    let track_no_learning_uin = run(&off)?;
    Ok(Prediction {
        margins,
        track_uin,
        track_no_learning_uin,
    })
}

/// The prediction as `tune` prints it, the design in force beside the
/// tuned one.
pub fn table(before: &Prediction, after: &Prediction) -> Vec<String> {
    let row = |name: &str, f: &dyn Fn(&Prediction) -> String| {
        format!("  {name:<34} {:>16} {:>16}", f(before), f(after))
    };
    vec![
        format!("  {:<34} {:>16} {:>16}", "", "in force", "tuned"),
        row("crossover, Hz", &|p| opt(p.margins.crossover_hz, 1)),
        row("phase margin, deg", &|p| opt(p.margins.phase_margin_deg, 1)),
        row("gain margin, dB", &|p| opt(p.margins.gain_margin_db, 1)),
        row("  at, Hz", &|p| opt(p.margins.phase_crossover_hz, 0)),
        row("peak |S|, dB", &|p| {
            format!("{:.1}", p.margins.peak_sensitivity_db)
        }),
        row("10 Hz x 0.004 in error, uin pk/RMS", &|p| {
            format!("{:.2} / {:.2}", p.track_uin.0, p.track_uin.1)
        }),
        row("  learning off, uin pk/RMS", &|p| {
            format!(
                "{:.2} / {:.2}",
                p.track_no_learning_uin.0, p.track_no_learning_uin.1
            )
        }),
    ]
}
