//! Issue 24's commissioning test: a machine whose plant differs from the
//! data sheet (legacy-hw with the amplifier gain −15 %, the moving mass
//! +10 % and the coil-frame mode 5 % higher; the firmware still designed
//! for the data sheet) identified through the link by `zslide identify`,
//! tuned by `zslide tune`, then tracking 10 Hz × 0.004 in as well as the
//! nominal design does on the nominal machine.
//!
//! Tolerances, against the perturbation (not against a captured run):
//! * gain and mass ±2 %: the fit's one-sigma from the measured noise is
//!   0.2 % each (gauge noise 10 µin RMS against ≥ 80 µin of motion below
//!   the mode band, 2 windows of 1024 ticks per frequency); the run's
//!   timing against the simulation (wall clock) is not reproducible, so
//!   the bound keeps ten sigmas, and it is still a fifth of the smallest
//!   error it must see (the 10 % mass);
//! * mode pole ±0.7 % and zero ±1 %: one-sigma 0.07 % and 0.2 % (the mode
//!   band's response is 1-6 µin at the 2.5 V bound, 6 windows); both well
//!   inside the 5 % shift;
//! * mode damping ±25 % (one-sigma 5 %; not perturbed);
//! * what `tune` predicts on the fitted plant against the true machine:
//!   the tuned loop's crossover ±2 %, phase margin ±1.5°, gain margin
//!   ±0.5 dB, the 10 Hz × 0.004 in figures ±5 % (the fit's 0.3 % moves the
//!   crossover by about as much; the tracking figures differ by the noise
//!   sequence's share, a few per cent).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use host_sim::fwrig::Controller;
use host_sim::perturb::Perturbation;
use host_sim::serve::Setup;
use host_sim::track::{run as track, TrackSpec};
use zslide::link::proto::LoopPhase;
use zslide_host::cli::run_line;
use zslide_host::client::Link;
use zslide_host::identify::{design_on, read_plant};

mod machine;
mod phase;
use machine::Machine;
use phase::wait_phase;

fn within(what: &str, got: f64, want: f64, rel: f64) {
    assert!(
        (got / want - 1.0).abs() <= rel,
        "{what}: identified {got}, the machine has {want} ({:+.2} %, allowed ±{} %)",
        100.0 * (got / want - 1.0),
        100.0 * rel
    );
}

#[test]
fn identify_recovers_a_perturbed_plant_and_tune_tracks_as_the_nominal_design() {
    let nominal = host_sim::scenario::load("legacy-hw").unwrap();
    let perturbation = Perturbation {
        gain: -0.15,
        mass: 0.10,
        mode: 0.05,
    };
    let mut machine = nominal.clone();
    perturbation.apply(&mut machine).unwrap();
    // The truth, from the data sheet and the perturbation.
    let mode = nominal.rig.slide.mode.unwrap();
    let gain = nominal.rig.amplifier.gain * 0.85;
    let mass = nominal.rig.slide.mass_lbf_s2_per_in * 1.10;
    let (pole, zero) = (mode.pole_hz * 1.05, mode.zero_hz * 1.05);

    let mut setup = Setup::new(machine.clone());
    // Machine time runs with the requests, not the wall clock: the same
    // figures on every run, however loaded the test machine.
    setup.lockstep = true;
    let m = Machine::start("identify", setup);
    let mut link = Link::new(&m.addr, Duration::from_secs(10));
    run_line(&mut link, "link arm").unwrap();
    wait_phase(&mut link, LoopPhase::Engaged);

    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/zslide-host-test");
    let stem = dir.join("identify-perturbed");
    let t0 = Instant::now();
    let report = run_line(&mut link, &format!("identify --out {}", stem.display())).unwrap();
    eprintln!("{report}identify took {:.1} s", t0.elapsed().as_secs_f64());
    let fit = read_plant(&stem.with_extension("plant")).unwrap();
    within("amplifier gain", fit.amp_gain, gain, 0.02);
    within("moving mass", fit.mass_lbf_s2_per_in, mass, 0.02);
    within("mode pole", fit.mode_pole_hz, pole, 0.007);
    within("mode zero", fit.mode_zero_hz, zero, 0.01);
    within("mode damping", fit.mode_zeta, mode.zeta, 0.25);
    let csv = std::fs::read_to_string(stem.with_extension("csv")).unwrap();
    assert!(csv.starts_with("f_hz,mag_db,phase_deg,coherence"), "{csv}");
    assert!(csv.lines().count() > 30, "{csv}");

    run_line(&mut link, "link disarm").unwrap();
    wait_phase(&mut link, LoopPhase::Disarmed);
    let tune = run_line(
        &mut link,
        &format!("tune {}", stem.with_extension("plant").display()),
    )
    .unwrap();
    eprintln!("{tune}");
    // What the machine runs now, read back from it.
    let design = design_on(link.client().unwrap()).unwrap();
    assert_eq!(design.slide.mass_lbf_s2_per_in, fit.mass_lbf_s2_per_in);
    assert_eq!(design.slide.amp_gain, fit.amp_gain);
    assert_eq!(design.mode_notch_hz, fit.mode_pole_hz);
    drop(m);

    // `track --freq 10 --amplitude 0.004`, as the issue asks, and the
    // same with the learning off: with it on, the learning removes what a
    // wrong model leaves and the figure is the gauge noise the loop passes
    // (the untuned loop, slower on the lighter-gain plant, passes less);
    // with it off the figure is the loop's own design, feedforward and
    // error dynamics, which the model sets.
    let mut tuned_machine = machine.clone();
    tuned_machine.servo_design = design;
    tuned_machine.servo = design.config().unwrap();
    // What `tune` predicted on the fitted plant against what the true
    // (perturbed) machine does: the margins of the tuned loop, and the
    // tracking of the design in force and of the tuned one (below).
    let (_, predicted_crossover) = tune_row(&tune, "crossover, Hz");
    // The prediction's own frequencies (its crossings bracketed alike).
    let freqs = zslide_host::predict::sweep_for(&design);
    let (_, truth) = host_sim::cmd::response::sweep_digital(
        &tuned_machine,
        &freqs,
        host_sim::cmd::response::DIGITAL_AMPLITUDE_IN,
        false,
    );
    eprintln!("the tuned loop on the true machine: {truth:?}");
    within(
        "predicted crossover of the tuned loop",
        predicted_crossover.parse().unwrap(),
        truth.crossover_hz.unwrap(),
        0.02,
    );
    let pm: f64 = tune_row(&tune, "phase margin, deg").1.parse().unwrap();
    let gm: f64 = tune_row(&tune, "gain margin, dB").1.parse().unwrap();
    assert!(
        (pm - truth.phase_margin_deg.unwrap()).abs() <= 1.5
            && (gm - truth.gain_margin_db.unwrap()).abs() <= 0.5,
        "predicted {pm} deg / {gm} dB, the true machine {truth:?}"
    );
    for learning in [true, false] {
        let spec = TrackSpec {
            freq_hz: 10.0,
            amplitude_in: 0.004,
            controller: Controller::Digital,
            learn_revs: 40,
            measure_revs: 10,
        };
        let run = |sc: &host_sim::scenario::Scenario| {
            let mut sc = sc.clone();
            if !learning {
                host_sim::perturb::set_params(&mut sc, &["learning_gain=0".into()]).unwrap();
            }
            track(&sc, &spec).unwrap()
        };
        let reference = run(&nominal);
        let untuned = run(&machine);
        let tuned = run(&tuned_machine);
        eprintln!(
            "track 10 Hz x 0.004 in, learning {}: following error peak / RMS, uin: the nominal \
             design on the nominal machine {:.2} / {:.2}; on the perturbed machine untuned {:.2} / \
             {:.2}, tuned {:.2} / {:.2}",
            if learning { "on" } else { "off" },
            reference.following_error_peak_uin,
            reference.following_error_rms_uin,
            untuned.following_error_peak_uin,
            untuned.following_error_rms_uin,
            tuned.following_error_peak_uin,
            tuned.following_error_rms_uin
        );
        assert!(tuned.faults.is_empty(), "{:?}", tuned.faults);
        // Within 5 % of the nominal figure: the tuned loop is the nominal
        // design up to the fit's 0.3 %, on another mode and noise sequence.
        assert!(
            tuned.following_error_peak_uin <= 1.05 * reference.following_error_peak_uin
                && tuned.following_error_rms_uin <= 1.05 * reference.following_error_rms_uin,
            "learning {learning}: tuned {:.2} peak / {:.2} RMS µin, nominal {:.2} / {:.2}",
            tuned.following_error_peak_uin,
            tuned.following_error_rms_uin,
            reference.following_error_peak_uin,
            reference.following_error_rms_uin
        );
        // The prediction (the fitted plant) against the true machine,
        // 5 %: the fit's 0.3 % in the model plus the noise sequence's
        // share of the figure.
        let row = if learning {
            "10 Hz x 0.004 in error, uin pk/RMS"
        } else {
            "learning off, uin pk/RMS"
        };
        let (in_force, after) = tune_row(&tune, row);
        for (what, predicted, measured) in
            [("in force", in_force, &untuned), ("tuned", after, &tuned)]
        {
            let (pk, rms) = predicted.split_once(" / ").unwrap();
            within(
                &format!("predicted peak, {what}, learning {learning}"),
                pk.parse().unwrap(),
                measured.following_error_peak_uin,
                0.05,
            );
            within(
                &format!("predicted RMS, {what}, learning {learning}"),
                rms.parse().unwrap(),
                measured.following_error_rms_uin,
                0.05,
            );
        }
        if !learning {
            // The perturbation matters to the loop: untuned, the error is
            // several times the nominal one.
            assert!(
                untuned.following_error_rms_uin > 2.0 * reference.following_error_rms_uin,
                "untuned {:.2} µin RMS against nominal {:.2}",
                untuned.following_error_rms_uin,
                reference.following_error_rms_uin
            );
        }
    }
}

/// The row `name` of `tune`'s prediction: its two columns (the design in
/// force, the tuned one).
fn tune_row(tune: &str, name: &str) -> (String, String) {
    let line = tune
        .lines()
        .find(|l| l.trim_start().starts_with(name))
        .unwrap_or_else(|| panic!("no row {name:?} in:\n{tune}"));
    let rest = line.trim_start()[name.len()..].trim();
    let cols: Vec<&str> = rest
        .split("  ")
        .map(str::trim)
        .filter(|c| !c.is_empty())
        .collect();
    assert_eq!(cols.len(), 2, "row {name:?}: {line:?}");
    (cols[0].to_string(), cols[1].to_string())
}
