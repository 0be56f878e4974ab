//! The servo parameters, declared once: every field of the loop's design
//! with its wire id, type, unit, default, limits and meaning.
//!
//! Everything that names a parameter is generated from this one table by
//! passing it to a macro of its own:
//! * the design's fields and the built-in defaults: [`ServoDesign`] and
//!   [`ServoDesign::brief`], [`SlideModel`] and [`SlideModel::BRIEF`]
//!   (`servo::design`);
//! * the parameter table the flash block and the host link's `set` use,
//!   with its wire ids, units and limits (`params::PARAMS`, and the field
//!   accessors behind `Param::get`/`set`);
//! * the scenario's `[servo]` section (host-sim's `scenario::ServoSection`:
//!   one optional key per design field, the slide's come from `[motor]`).
//!
//! The integer configuration the loop runs (`ServoConfig`) is designed from
//! a `ServoDesign` by `ServoDesign::config` (the f64 design work, with the
//! rate-dependent checks), and the firmware's configuration holds it
//! (`FirmwareConfig::loop_cfg`): neither restates a parameter. Adding a
//! parameter is one line here (its limits included) plus its use in
//! `config`.
//!
//! The ids are the parameter block's and the link's wire format
//! (`params`, format version 1): never renumber one, only add (a new
//! design parameter ends the design list with the next free id, so the
//! table is not in id order; a block that does not name it keeps the
//! default). The limits
//! are the design's own where it has static ones (`ServoDesign::config`),
//! narrowed to the machine where the brief sets a bound (the amplifier's
//! 8 A, the gauge's ±0.010 in); the design's rate-dependent checks
//! (bandwidth below rate/20, observer below rate/10, notch below Nyquist)
//! run on top, with their own reasons.
//!
//! [`ServoDesign`]: super::ServoDesign
//! [`ServoDesign::brief`]: super::ServoDesign::brief
//! [`SlideModel`]: super::SlideModel
//! [`SlideModel::BRIEF`]: super::SlideModel::BRIEF

/// Passes the servo parameter table (module `servo::parameters`) to the
/// macro `$then`, as two lists:
///
/// ```text
/// design { (id, name, type, unit, default, min, max, doc), ... }
/// slide  { (id, name, field of SlideModel, type, unit, default, min, max, doc), ... }
/// ```
///
/// `type` is `f64` or `u32` (whole numbers: bins, shifts); limits are
/// inclusive.
#[macro_export]
macro_rules! servo_parameters {
    ($then:ident) => {
        $then! {
            design {
                (1, bandwidth_hz, f64, "Hz", 45.0, 1.0, 1000.0,
                    "Natural frequency of the tracking-error dynamics, Hz."),
                (2, damping, f64, "", 0.9, 0.1, 5.0,
                    "Damping ratio of the tracking-error dynamics."),
                (3, bandwidth_fast_hz, f64, "Hz", 150.0, 1.0, 1000.0,
                    "Natural frequency of the error dynamics while the fast observer is on (a sudden force was seen), Hz."),
                (4, observer_hz, f64, "Hz", 250.0, 1.0, 2000.0,
                    "Observer poles (triple, real), Hz."),
                (5, observer_fast_hz, f64, "Hz", 800.0, 1.0, 2000.0,
                    "Fast observer poles, Hz, used while |innovation| > `observer_switch_uin` and for `observer_hold_ms` after."),
                (6, observer_switch_uin, f64, "uin", 150.0, 1.0, 10_000.0,
                    "|Innovation| above which the fast observer takes over, µin."),
                (7, observer_hold_ms, f64, "ms", 20.0, 0.0, 10_000.0,
                    "How long the fast observer stays on after the innovation falls back, ms."),
                (8, hum_notch_hz, f64, "Hz", 120.0, 1.0, 9_999.0,
                    "Measurement notch for the power-supply hum, Hz."),
                (9, hum_notch_q, f64, "(0 = off)", 20.0, 0.0, 100.0,
                    "The hum notch's Q (0 = off)."),
                (10, mode_notch_hz, f64, "Hz", 3150.0, 1.0, 9_999.0,
                    "Output notch for the coil-frame mode, Hz."),
                (11, mode_notch_q, f64, "(0 = off)", 0.7, 0.0, 100.0,
                    "The mode notch's Q (0 = off)."),
                (12, learning_gain, f64, "per rev (0 = off)", 0.3, 0.0, 0.95,
                    "Repetitive learning: fraction of a revolution's error learned per revolution (0 = off, < 1)."),
                (13, learning_lead_bins, u32, "bins of 1/256 rev", 3, 3.0, 32.0,
                    "Phase lead of the learning, in bins of 1/256 revolution (≥ 3: see `servo::repetitive::MIN_LEAD`)."),
                (14, learning_q_shift, u32, "", 2, 1.0, 3.0,
                    "Q-filter: each pass smooths a bin with its neighbours by `(t[j−1] − 2t[j] + t[j+1]) / 2^shift` (2 = [1 2 1]/4; larger = weaker)."),
                (15, slew_in_per_s, f64, "in/s", 0.25, 0.001, 10.0,
                    "Command slew limit, in/s."),
                (16, slew_accel_in_per_s2, f64, "in/s^2", 20.0, 0.01, 1000.0,
                    "The command slew's acceleration limit, in/s²."),
                (17, command_limit_in, f64, "in", 0.0095, 0.0001, 0.010,
                    "|command| limit, in."),
                (18, current_limit_a, f64, "A", 6.0, 0.1, 8.0,
                    "Estimated coil current limit, A (the board has no current sense: the current is estimated from the DAC output and the back-EMF of the estimated velocity)."),
                (19, current_limit_ms, f64, "ms", 20.0, 0.1, 1000.0,
                    "Time at the current limit before it is a fault, ms."),
                (20, following_error_in, f64, "in", 0.004, 0.000_001, 0.010,
                    "Following-error limit, in."),
                (21, following_error_ms, f64, "ms", 2.0, 0.0, 1000.0,
                    "How long the following error may exceed its limit, ms."),
                (22, sign_check_v, f64, "V (0 = no check)", 0.35, 0.0, 2.0,
                    "Commissioning sign check at every arm: the DAC pulse, volts (0 = no check)."),
                (23, sign_check_ms, f64, "ms", 1.0, 0.1, 20.0,
                    "Duration of each half of the sign check's doublet, ms."),
                (31, learning_clip_uin, f64, "uin", 300.0, 1.0, 10_000.0,
                    "Repetitive learning: the error it takes in is clipped to ± this, µin, so one revolution moves the learned correction by at most `learning_gain` × this (what a one-off transient can be replayed by); a periodic error beyond it is still learned, at that rate. Above the largest periodic error of the cut before it is learned (an interrupted cut's edges): docs/TUNING.md."),
                (32, hum_notch_turn_deg, f64, "deg", 45.0, -80.0, 80.0,
                    "The hum notch's poles turned about its zeros, degrees (0 = the plain notch): the notch of a synchronous hum canceller with this phase advance. It keeps the notch's closed-loop poles damped while |arg S(120 Hz) − turn| < 90°; the engaged part's spring sweeps arg S, docs/TUNING.md."),
                (33, depth_of_cut_uin, f64, "uin", 300.0, 1.0, 10_000.0,
                    "The part program's depth of cut, µin: the stock the pass removes (chapter 5: 300 finishing, 5 000..10 000 roughing). The contour monitoring's depth guard and the hole edges' contact chord follow from it."),
                (34, oscillation_uin, f64, "uin RMS", 40.0, 0.1, 10_000.0,
                    "Contour monitoring: the following error's RMS about its slow mean, over a 12.8 ms window (256 ticks at 20 kHz), above this is `Oscillation` (retract), µin RMS. Above the cut's own following error (legacy-hw 2.4 µin RMS, 13 µin peak) by the error budget's factor (docs/SAFETY.md)."),
                (35, gauge_frozen_ms, f64, "ms", 5.0, 0.1, 1_000.0,
                    "Contour monitoring: the gauge's code unchanged for this long while the loop is closed is `GaugeFrozen` (amplifier off), ms. A 20-bit reading with ≥ 0.2 µin RMS noise (10 codes) repeats a code on the next tick with probability < 3 %."),
                (36, x_stall_revs, u32, "rev (0 = off)", 0, 0.0, 10_000.0,
                    "Contour monitoring: revolutions with the table command live and no new X before `XStalled` (retract); 0 = off, the default: only the part program knows that X feeds (a dwell is legal). 20 for a pass that feeds ≥ 25 µin/rev: four half-mil X steps at the finishing feed of 100 µin/rev."),
                (37, retract_z_in, f64, "in", 0.009, -0.010, 0.010,
                    "Where the command goes on a `Retract` fault, in along +Z; its sign names the side away from the stock (chapter 5's stock lies toward −Z, `cut.part_side = −1`), which the depth guard watches the other way."),
                (38, edge_feedforward, u32, "(0 = off)", 1, 0.0, 1.0,
                    "The hole edges' anticipation: 1 = the force change expected at each edge of the part's interruption block goes into the observer's disturbance estimate at the tick it happens (`servo::edges`); 0 = it does not, while the block still tells contour monitoring where the holes are (`cut --anticipate off`)."),
                (40, learning_lowpass_hz, f64, "Hz (0 = off)", 80.0, 0.0, 1000.0,
                    "Repetitive learning: first-order low-pass on the error it takes in, Hz (0 = off). Its lag takes back the lead's excess above ≈ 60 Hz, where the engaged part's spring turns the loop's phase forward: the learning converges at every harmonic from in air to 11 000 lbf/in (k_e × 5), docs/TUNING.md."),
            }
            slide {
                (24, motor_kf_lbf_per_a, kf_lbf_per_a, f64, "lbf/A", 2.9, 0.1, 100.0,
                    "Motor force constant, lbf/A."),
                (25, motor_kb_v_s_per_in, kb_v_s_per_in, f64, "V s/in", 4.002 / 12.0, 0.01, 10.0,
                    "Back-EMF constant, V·s/in."),
                (26, coil_r_ohm, r_ohm, f64, "ohm", 1.4, 0.1, 100.0,
                    "Coil resistance, Ω."),
                (27, mass_lbf_s2_per_in, mass_lbf_s2_per_in, f64, "lbf s^2/in", 6.25 / 32.174 / 12.0, 0.001, 1.0,
                    "Moving mass, lbf·s²/in."),
                (28, air_film_b_lbf_s_per_in, b_lbf_s_per_in, f64, "lbf s/in", 51.2 / 12.0, 0.01, 1000.0,
                    "Air-film viscous friction, lbf·s/in."),
                (29, amp_gain, amp_gain, f64, "V/V", 10.0, 0.1, 100.0,
                    "Amplifier voltage gain, V/V."),
                (30, gauge_v_per_in, gauge_v_per_in, f64, "V/in", 1000.0, 1.0, 100_000.0,
                    "Gauge sensitivity, V/in (1000: 1 V per mil)."),
            }
        }
    };
}
