//! The loop against the engaged part's spring: the firmware's measured
//! sensitivity against an independent sampled-data model of the design
//! (`host_sim::loopmodel`), and the learning's convergence over the
//! process stiffness.

use host_sim::cmd::response::measure_digital_on;
use host_sim::loopmodel::LoopModel;

fn model(sc: &host_sim::scenario::Scenario, k: f64) -> LoopModel {
    let latency = (sc.rig.dac_latency_ns as f64) * 1e-9;
    LoopModel::new(
        &sc.servo_design,
        sc.file.motor.l_over_r_ms * 1e-3,
        latency,
        k,
    )
}

/// At 6600 lbf/in (k_e × 3 on chapter 5's cut) the firmware on the rig
/// (fixed point, the slide with its coil-frame mode, a spring set at every
/// tick) and the linear model of the f64 design agree on |S| within 10 %
/// below, at and above the crossover: the margins `response
/// --process-stiffness` reports are the design's, not an artefact of the
/// measurement.
#[test]
fn measured_sensitivity_with_the_spring_matches_the_sampled_model() {
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    let k = 6600.0;
    let m = model(&sc, k);
    assert!(m.spectral_radius() < 1.0, "model unstable at {k}");
    // 117 Hz: beside the hum canceller, whose turned poles the firmware
    // designs in z and the model takes from the continuous prototype. On
    // its other side, 123 Hz, they differ by 14 % (0.151 measured, 0.132
    // model): the two designs agree only to first order in its width, and
    // which part of the 14 % that is has not been separated.
    for f in [30.0, 110.0, 117.0, 200.0] {
        let meas = measure_digital_on(&sc, f, 20e-6, false, k).s.norm();
        let pred = m.sensitivity(f).norm();
        assert!(
            (meas / pred - 1.0).abs() < 0.10,
            "{f} Hz: |S| measured {meas:.3}, model {pred:.3}"
        );
    }
}

/// The loop with the hum canceller (`legacy-hw`: 120 Hz, Q 20, turned
/// 45°) is stable from in air to 13 200 lbf/in (k_e × 6) with peak |S| at
/// most 7.2 dB (a log grid over 5 Hz .. 2 kHz and a 0.02 Hz grid over
/// 100 .. 140 Hz, where the canceller's poles are), in the sampled model.
/// Its poles' damping falls with the stiffness (ζ 0.030 in air, 0.011 at
/// 6600, 0.0046 at 11 000 lbf/in) and the spectral radius stays below one
/// to 17 600 lbf/in.
#[test]
fn hum_canceller_keeps_the_margins_over_the_process_stiffness() {
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    assert_eq!(sc.servo_design.hum_notch_turn_deg, 45.0);
    for k in [
        0.0, 2200.0, 4400.0, 6600.0, 8800.0, 11_000.0, 13_200.0, 17_600.0,
    ] {
        let m = model(&sc, k);
        assert!(m.spectral_radius() < 1.0, "unstable at {k} lbf/in");
        if k <= 13_200.0 {
            let (wide, fw) = m.peak_sensitivity_db(5.0, 2000.0, 300);
            let (near, fnear) = m.peak_sensitivity_db(100.0, 140.0, 2001);
            assert!(
                wide <= 7.2 && near <= 7.2,
                "{k} lbf/in: {wide:.2} dB at {fw:.0} Hz, {near:.2} dB at {fnear:.2} Hz"
            );
        }
    }
}

/// The learning without its low-pass (the minimum lead of 3 bins alone)
/// diverges against the engaged part at k_e × 2 (4400 lbf/in: the cut went
/// into a −560 .. −470 µin limit cycle), and converges with the default
/// 80 Hz low-pass at every harmonic from in air to 11 000 lbf/in (k_e × 5),
/// at 300 and 360 rpm, on both scenarios, with a factor ≤ 0.95 a revolution.
#[test]
fn learning_converges_over_the_process_stiffness_with_its_lowpass() {
    for name in ["legacy-hw", "modern-hw"] {
        let mut sc = host_sim::scenario::load(name).unwrap();
        for k in [0.0, 2200.0, 4400.0, 6600.0, 8800.0, 11_000.0] {
            let m = model(&sc, k);
            assert!(m.spectral_radius() < 1.0, "{name}: loop unstable at {k}");
            for rpm in [300.0, 360.0] {
                let (g, f) = m.learning_factor(rpm);
                assert!(g <= 0.95, "{name} {k} lbf/in {rpm} rpm: {g:.3} at {f} Hz");
            }
        }
        sc.servo_design.learning_lowpass_hz = 0.0;
        let (g, f) = model(&sc, 4400.0).learning_factor(360.0);
        assert!(g > 1.0, "{name}: without the low-pass {g:.3} at {f} Hz");
    }
}
