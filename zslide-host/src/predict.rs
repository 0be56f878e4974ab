//! What `zslide tune` predicts for a design before it sets it: the digital
//! loop's margins and the 10 Hz × 0.004 in following error, measured on the
//! fitted plant by the same simulation of the firmware that
//! `host-sim response --loop digital` and `host-sim track` run. The
//! prediction is the identified slide with the data sheet's motor, gauge
//! and board timing (the scenario `identify` was given), so it is as good
//! as the fit: it says nothing of what the fit cannot see (friction, the
//! cut's forces).

use host_sim::cmd::response::{fmt_opt as opt, sweep_digital_on, Margins, DIGITAL_AMPLITUDE_IN};
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

/// The least phase margin `tune` sets a design with, degrees
/// (docs/TUNING.md, "The margins `tune` asks for"): below the shipped
/// designs' least (modern-hw, 29.5°) by more than the prediction's error
/// against the machine (±1.5°, `tests/identify.rs`); at 25° the peak of
/// |S| is at least 1/(2 sin(PM/2)) = 7.7 dB.
pub const MIN_PHASE_MARGIN_DEG: f64 = 25.0;
/// The least gain margin, dB: a factor 2 of loop gain (the shipped
/// designs' least is modern-hw's 7.7 dB).
pub const MIN_GAIN_MARGIN_DB: f64 = 6.0;

/// Why `tune` refuses a design's predicted margins: `Ok` when they meet
/// the minimums above. A loop without a crossover, or whose phase margin
/// cannot be read, is refused; no phase crossover above the crossover is
/// an unbounded gain margin.
pub fn check_margins(m: &Margins) -> std::result::Result<(), String> {
    let (Some(fc), Some(pm)) = (m.crossover_hz, m.phase_margin_deg) else {
        return Err("the predicted loop gain never crosses 1 in the sweep: no phase margin".into());
    };
    if pm < MIN_PHASE_MARGIN_DEG {
        return Err(format!(
            "predicted phase margin {pm:.1} deg at {fc:.1} Hz is below the {MIN_PHASE_MARGIN_DEG} \
             deg minimum"
        ));
    }
    if let (Some(gm), Some(at)) = (m.gain_margin_db, m.phase_crossover_hz) {
        if gm < MIN_GAIN_MARGIN_DB {
            return Err(format!(
                "predicted gain margin {gm:.1} dB at {at:.0} Hz is below the {MIN_GAIN_MARGIN_DB} \
                 dB minimum"
            ));
        }
    }
    Ok(())
}

/// The sweep for `design`: [`SWEEP`], and across each notch of the design
/// (f₀·(1 ± 2/Q), where its phase swings through ±90° within a few per cent
/// of f₀) 16 points more, so that a narrow notch's phase excursion, which
/// can carry the loop's phase through −180° above the crossover, is
/// bracketed and not stepped over.
pub fn sweep_for(design: &ServoDesign) -> Vec<f64> {
    let mut f = host_sim::analyser::log_freqs(SWEEP.0, SWEEP.1, SWEEP.2);
    for (f0, q) in [
        (design.hum_notch_hz, design.hum_notch_q),
        (design.mode_notch_hz, design.mode_notch_q),
    ] {
        if q > 0.0 {
            let half = (2.0 / q).min(0.5);
            f.extend((0..16).map(|k| f0 * (1.0 - half + 2.0 * half * f64::from(k) / 15.0)));
        }
    }
    f.retain(|&x| (SWEEP.0..=SWEEP.1).contains(&x));
    f.sort_by(f64::total_cmp);
    f.dedup();
    f
}

/// The digital loop's margins for `design` on the fitted plant.
pub fn margins(data_sheet: &Scenario, p: &Plant, design: &ServoDesign) -> Result<Margins> {
    margins_in_cut(data_sheet, p, design, 0.0)
}

/// [`margins`] with the tool engaged in a part of stiffness
/// `stiffness_lbf_per_in` (0: in air), as `host-sim response --loop
/// digital --process-stiffness` measures them.
pub fn margins_in_cut(
    data_sheet: &Scenario,
    p: &Plant,
    design: &ServoDesign,
    stiffness_lbf_per_in: f64,
) -> Result<Margins> {
    let sc = fitted_machine(data_sheet, p, design)?;
    Ok(sweep_digital_on(
        &sc,
        &sweep_for(design),
        DIGITAL_AMPLITUDE_IN,
        false,
        stiffness_lbf_per_in,
    )
    .1)
}

/// The figures of `design` on the fitted plant.
pub fn predict(data_sheet: &Scenario, p: &Plant, design: &ServoDesign) -> Result<Prediction> {
    let sc = fitted_machine(data_sheet, p, design)?;
    let margins = margins(data_sheet, p, design)?;
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
