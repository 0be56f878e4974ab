//! The Z-slide position loop: what the loop tick does between reading the
//! gauge and writing the amplifier DAC. It knows nothing of tables,
//! interrupts or chips: it receives the gauge code, the reference from the
//! command path (position, velocity and acceleration from the analytic
//! derivatives), the spindle angle, and returns a DAC code and the
//! amplifier enable.
//!
//! ```text
//! gauge ─▶ hum canceller ─▶ observer (ẑ, v̂, d̂) ──────────────┐
//!                 │                                        ▼
//! reference r,ṙ,r̈ ─▶ slew/range ─▶ + learned c(φ) ─▶ state feedback + plant-inverse FF − d̂
//!                 │        ▲                                    │
//!                 └─ error ┴─ repetitive (by spindle angle)      ▼
//!                                           current limit ─▶ mode notch ─▶ DAC
//! ```
//!
//! One concept per file: [`design`] (f64 design → integer coefficients),
//! [`filters`] (idsp notches and the hum canceller), [`observer`] (position/velocity/disturbance
//! estimate), [`repetitive`] (angle-indexed learning), [`limits`] (slew,
//! range, current estimate, following error), [`engage`] (arming, sign
//! check, bumpless engagement). This file composes them.
//!
//! # Number formats
//! Gauge and DAC codes are 20-bit (2¹⁹ codes = 10 V; 1 gauge code =
//! 0.010 in / 2¹⁹ = 0.0191 µin). Inside the loop every signal is `i32`:
//! positions and DAC values Q8 codes (LSB 7.5e-5 µin; the gauge's span is
//! 2²⁸, so sums of a few stay far from 2³¹), velocities Q16 codes per tick
//! (|v| ≤ 2³⁰: 6 in/s at 20 kHz, 24 times the slew limit), accelerations
//! Q16 codes per tick². Gains are `i32` Q24 (Q16 for the acceleration
//! feedforward), coefficients of the observer and notches Q30. Every
//! product is one 32×32 → 64-bit multiply (`SMULL`) of bounded operands,
//! shifted back to 32 bits once; sums that an out-of-range input could
//! push past 2³¹ saturate (`QADD`, `SSAT`: one instruction each on the
//! M4). Q8 positions against the former Q16: the loop's resolution is
//! 7.5e-5 µin instead of 3e-7 µin, four orders of magnitude below the
//! quietest gauge's noise (0.2 µin RMS, `modern-hw`).

pub mod design;
pub mod edges;
pub mod engage;
pub mod filters;
pub(crate) mod fixed;
pub mod limits;
pub mod monitor;
pub mod observer;
pub mod parameters;
pub mod refusal;
pub mod repetitive;

pub use design::{DesignError, MonitorConfig, ServoConfig, ServoDesign, SlideModel};
pub use engage::Phase;
pub use repetitive::{
    Correction, CorrectionAhead, Freeze, LearnRequests, LearnSample, LearnedTable, Learner,
};

use crate::codes::CODE_MAX;
use crate::safety::Fault;
use crate::units::SpindleAngle;
use engage::{SignCheck, SignStep};
use filters::{Canceller, Notch};
use fixed::{mul_hi, qadd_mul, round_q8, ssat};
use limits::{CurrentLimit, FollowingError, SlewProfile};
use observer::{Estimate, Observer};

/// The reference the command path gives the loop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Reference {
    /// Position, gauge codes.
    pub code: i32,
    /// ∂Z/∂φ·Δφ, gauge codes per tick, Q16 (|v| ≤ 2³⁰).
    pub velocity_q16: i32,
    /// ∂²Z/∂φ²·Δφ², gauge codes per tick², Q16 (|a| ≤ 2²⁴).
    pub accel_q16: i32,
}

/// What the loop tick hands the servo.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServoInput {
    /// Gauge, codes, +Z (already corrected for a reversed gauge).
    pub gauge_code: i32,
    /// Where the command path wants the slide.
    pub reference: Reference,
    /// Spindle angle and its step over the last tick, when known.
    pub angle: Option<(SpindleAngle, i32)>,
    /// Why learning must not run this tick (besides the servo's own
    /// reasons), e.g. X jumped or a fault is latched.
    pub freeze: Option<Freeze>,
    /// The amplifier's fault line (it tripped).
    pub amplifier_tripped: bool,
    /// The learned correction expanded below the tick near this angle
    /// (`crate::handoff::ahead`), stepped to it when the correction applies;
    /// `None` (or too far from the angle): read from the table here.
    pub correction_ahead: Option<CorrectionAhead>,
    /// The change of the input disturbance the cut makes at this tick's
    /// angle (the hole edges, [`edges`]), DAC codes Q8, expected below the
    /// tick; `None` (no fresh expansion): the last one holds.
    pub edge_q8: Option<i32>,
}

/// What the servo decided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServoOutput {
    /// Amplifier DAC code.
    pub dac_code: i32,
    /// Whether the amplifier may be enabled.
    pub enable: bool,
    /// A fault the servo detected this tick.
    pub fault: Option<Fault>,
    /// This tick's sample for the learner ([`Learner::apply`], below the
    /// loop tick's priority), while the loop is closed.
    pub learn: Option<LearnSample>,
}

/// The sign check's last verdict, for the fault log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SignCheckResult {
    pub moved_code: i32,
    pub expected_code: i32,
}

/// The correction read from the table in the tick: rare (no fresh
/// expansion from below the tick), so out of line, where it does not crowd
/// the registers of every tick.
#[cold]
#[inline(never)]
fn correction_here(learned: &LearnedTable, phi: SpindleAngle, dphi: i32) -> Correction {
    learned.correction(phi, dphi)
}

/// The whole loop with its state.
#[derive(Clone, Debug)]
pub struct Servo {
    cfg: ServoConfig,
    phase: Phase,
    arm_requested: bool,
    hum: Option<Canceller>,
    mode: Option<Notch>,
    observer: Observer,
    /// Requests for the learner, sent with the next sample: forget the
    /// table (arming), hold the learning frozen (reason, ticks).
    learn_req: LearnRequests,
    /// Ticks of the engagement's settling left, during which the learning
    /// is held and the (freshly cleared) table gives no correction: it is
    /// not read then, which also keeps a learner that has not yet run its
    /// clear from handing an old table to the first engaged ticks.
    settle_left: u32,
    sign: SignCheck,
    current: CurrentLimit,
    following: FollowingError,
    slew: SlewProfile,
    /// The slew-limited command, gauge codes Q8, and its velocity (Q16
    /// codes per tick).
    command_q8: i32,
    command_v_q16: i32,
    /// The learned correction added on the last tick (position Q8,
    /// velocity Q16; zero when none was): folded into the command when the
    /// correction stops, so the reference does not step.
    correction_q8: i32,
    correction_v_q16: i32,
    /// The goal's velocity on the last tick, Q16.
    goal_v_q16: i32,
    /// The goal of the last tick, Q8.
    goal_q8: i32,
    /// The reference the loop followed on the last tick (command plus
    /// learned correction), Q8.
    reference_q8: i32,
    /// Gauge of the last tick, Q8.
    measured_q8: i32,
    /// DAC code written on the last tick, Q8 (the observer's input).
    output_q8: i32,
    current_limited: bool,
    last_sign_check: Option<SignCheckResult>,
    /// A quarter of the slew rate, Q16 codes per tick: a goal velocity
    /// jump beyond it is a jump, not motion.
    slew_quarter: u32,
    /// The hole edges' expected disturbance already in the observer's d̂,
    /// DAC codes Q8.
    edge_q8: i32,
}

impl Servo {
    pub fn new(cfg: ServoConfig) -> Self {
        Self {
            phase: Phase::Disarmed,
            arm_requested: false,
            hum: cfg.hum_canceller.map(Canceller::from_bits),
            mode: cfg.mode_notch.map(Notch::from_bits),
            observer: Observer::new(cfg.observer),
            learn_req: LearnRequests::NONE,
            settle_left: 0,
            correction_q8: 0,
            correction_v_q16: 0,
            sign: SignCheck::new(
                cfg.sign_check_code,
                cfg.sign_check_ticks,
                cfg.sign_check_expected_code,
            ),
            current: CurrentLimit::new(
                cfg.current_limit_code,
                cfg.k_emf_q24,
                cfg.current_limit_ticks,
            ),
            following: FollowingError::new(cfg.following_error_code, cfg.following_error_ticks),
            slew: SlewProfile::new(cfg.slew_q16, cfg.slew_accel_q16),
            command_q8: 0,
            command_v_q16: 0,
            goal_v_q16: 0,
            goal_q8: 0,
            reference_q8: 0,
            measured_q8: 0,
            output_q8: 0,
            current_limited: false,
            last_sign_check: None,
            slew_quarter: (cfg.slew_q16.clamp(0, 1 << 32) / 4) as u32,
            edge_q8: 0,
            cfg,
        }
    }

    /// Asks the loop to arm at its next tick (sign check, then bumpless
    /// engagement). Ignored while armed.
    pub fn arm(&mut self) {
        if self.phase == Phase::Disarmed {
            self.arm_requested = true;
        }
    }

    /// Ramps the command to null, then disables the amplifier.
    pub fn disarm(&mut self) {
        self.arm_requested = false;
        match self.phase {
            Phase::Engaging | Phase::Engaged => self.phase = Phase::Disarming,
            Phase::SignCheck => self.phase = Phase::Disarmed,
            Phase::Disarmed | Phase::Disarming => {}
        }
    }

    /// Freezes the learning for `ticks` (X jumped: the table belongs to
    /// another radius); sent to the learner with the next sample.
    pub fn freeze_learning(&mut self, reason: Freeze, ticks: u32) {
        self.learn_req.hold(reason, ticks);
    }

    /// Opens the loop at once (a fault that disables the amplifier).
    pub fn stop(&mut self) {
        self.arm_requested = false;
        self.phase = Phase::Disarmed;
        self.output_q8 = 0;
        self.current.reset();
        self.following.reset();
    }

    /// One loop tick; `learned` is the learner's table (the correction is
    /// read from it when `input` brings no usable expansion of it).
    #[inline]
    pub fn update(&mut self, input: &ServoInput, learned: &LearnedTable) -> ServoOutput {
        // A 20-bit code (the loop tick's gauge reading), Q8.
        let measured = input.gauge_code.clamp(-CODE_MAX - 1, CODE_MAX) << 8;
        self.measured_q8 = measured;

        if self.phase == Phase::Disarmed {
            self.observer.reset(measured);
            self.output_q8 = 0;
            if !self.arm_requested {
                return self.idle();
            }
            self.arm_requested = false;
            self.learn_req.clear();
            self.current.reset();
            self.following.reset();
            if self.sign.enabled() {
                self.sign.start(measured);
                self.phase = Phase::SignCheck;
            } else {
                self.engage(measured, true, input.reference.velocity_q16);
            }
        }
        if input.amplifier_tripped {
            self.stop();
            return ServoOutput {
                fault: Some(Fault::AmplifierTrip),
                ..self.idle()
            };
        }
        if self.phase == Phase::SignCheck {
            match self.sign.step(measured) {
                SignStep::Drive(code) => {
                    let code = code.clamp(-CODE_MAX, CODE_MAX);
                    self.observer.update(self.output_q8, measured);
                    self.output_q8 = code << 8;
                    return ServoOutput {
                        dac_code: code,
                        enable: true,
                        fault: None,
                        learn: None,
                    };
                }
                SignStep::Passed => self.engage(measured, false, input.reference.velocity_q16),
                SignStep::Failed { moved, expected } => {
                    self.last_sign_check = Some(SignCheckResult {
                        moved_code: moved,
                        expected_code: expected,
                    });
                    self.stop();
                    return ServoOutput {
                        fault: Some(Fault::SignCheck),
                        ..self.idle()
                    };
                }
            }
        }

        let mut est = self.observer.update(self.output_q8, measured);
        if let Some(e) = input.edge_q8 {
            // The step the cut makes now, into the observer's disturbance
            // before the control law reads it (`edges`).
            let delta = e.saturating_sub(self.edge_q8);
            self.edge_q8 = e;
            if delta != 0 {
                est = self.observer.shift_disturbance(delta);
            }
        }

        // The command: ramp at the slew limit toward the goal; on the goal,
        // follow the command path's analytic rates.
        let limit = self.cfg.command_limit_code.clamp(0, CODE_MAX);
        let goal_q8 = match self.phase {
            Phase::Disarming => 0,
            // max/min, not `clamp`: its min ≤ max assertion would be a panic
            // path in the handler (the limit comes from the configuration).
            _ => input.reference.code.max(-limit).min(limit) << 8,
        };
        // The command is the goal plus an offset that the slew profile
        // takes to zero (bounded relative velocity and acceleration,
        // arriving at rest on the goal): a goal that moves (the table's
        // command) is joined, not chased, and a goal that jumps (a target
        // step, a fault's null) is approached smoothly. The command's own
        // velocity stays continuous when the goal's rates change.
        let (v_goal, a_goal) = if self.phase == Phase::Disarming {
            (0, 0)
        } else {
            (
                ssat::<31>(input.reference.velocity_q16),
                ssat::<26>(input.reference.accel_q16),
            )
        };
        // Relative to the goal's previous velocity while the goal moves
        // smoothly (its own acceleration is in a_goal, and the angle
        // estimate's noise makes its velocity jitter by a code per tick with
        // a tachometer); re-expressed against its new velocity when that
        // jumps by more than a quarter of the slew rate (the rates of a
        // fault's null, a target step).
        let v_goal_then = if v_goal.abs_diff(self.goal_v_q16) > self.slew_quarter {
            v_goal
        } else {
            self.goal_v_q16
        };
        self.goal_v_q16 = v_goal;
        self.slew
            .set_velocity(self.command_v_q16.saturating_sub(v_goal_then));
        // Where the command stands against the new goal had it moved with
        // the goal's velocity this tick: 0 while tracking, the jump when
        // the goal jumped. (|command|, |goal| < 2²⁸, |v| < 2³⁰ Q16.)
        let offset = self.command_q8 + ((v_goal_then + (1 << 7)) >> 8) - goal_q8;
        let (offset, v_o, a_o) = self.slew.step(offset);
        self.command_q8 = goal_q8 + offset;
        let (mut v_ref, mut a_ref) = (v_goal.saturating_add(v_o), a_goal + a_o);
        self.command_v_q16 = v_ref;
        let on_goal = offset == 0;
        self.goal_q8 = goal_q8;
        match self.phase {
            Phase::Engaging if on_goal => {
                self.phase = Phase::Engaged;
                // The engagement transient is not a periodic error: let the
                // loop settle (ten of its time constants) before learning.
                self.freeze_learning(Freeze::NotEngaged, self.cfg.settle_ticks);
                self.settle_left = self.cfg.settle_ticks;
            }
            Phase::Disarming if self.command_q8 == 0 => {
                self.stop();
                return self.idle();
            }
            _ => {}
        }

        // Learned correction, by spindle angle (|c| ≤ 2²⁵ Q8), while the
        // loop follows the part: not during the settling, not on a latched
        // fault (the learning may have taken in what caused it: a hard spot
        // pushing the slide would be replayed into the part a revolution
        // later), not without an angle, not while disarming. When it stops,
        // the last correction joins the command, whose slew profile takes
        // it to the goal: the reference never steps.
        let mut reference = self.command_q8;
        let settled = self.settle_left == 0;
        self.settle_left = self.settle_left.saturating_sub(1);
        let corrected =
            self.phase == Phase::Engaged && settled && !matches!(input.freeze, Some(Freeze::Fault));
        match input.angle {
            Some((phi, dphi)) if corrected => {
                let c = match input.correction_ahead.and_then(|a| a.step(phi, dphi)) {
                    Some(c) => c,
                    None => correction_here(learned, phi, dphi),
                };
                reference += c.position_q8;
                v_ref = v_ref.saturating_add(c.velocity_q16);
                a_ref += c.accel_q16;
                self.correction_q8 = c.position_q8;
                self.correction_v_q16 = c.velocity_q16;
            }
            _ if self.correction_q8 != 0 || self.correction_v_q16 != 0 => {
                // |command| < 2²⁸, |c| ≤ 2²⁵ Q8: the sum fits.
                self.command_q8 += self.correction_q8;
                self.command_v_q16 = self.command_v_q16.saturating_add(self.correction_v_q16);
                reference = self.command_q8;
                v_ref = v_ref.saturating_add(self.correction_v_q16);
                self.correction_q8 = 0;
                self.correction_v_q16 = 0;
            }
            _ => {}
        }
        self.reference_q8 = reference;
        let error_q8 = reference - measured;
        // The learning drives the command's error to zero (not the error
        // to the corrected reference, which the loop itself removes), as
        // the gauge measures it (the observer's estimate would carry the
        // model's error into the table when the plant differs from it).
        // The learner runs below this priority: it gets the error, the
        // angle and why it must not learn now.
        let freeze = if self.phase != Phase::Engaged {
            Some(Freeze::NotEngaged)
        } else {
            input.freeze
        };
        let learn = LearnSample::new(
            self.command_q8 - measured,
            input.angle,
            freeze,
            core::mem::take(&mut self.learn_req),
        )
        .with_disturbance(est.d_q8)
        .with_gauge(input.gauge_code);
        let (fb_q8, ff_q8) = self.control(&est, reference, v_ref, a_ref);
        // The hum canceller (`filters::Canceller`: a notch whose poles are
        // turned to stay damped against the engaged part's spring) acts on
        // the feedback only: what the loop corrects
        // from the gauge loses its 120 Hz, while the feedforward (the
        // commanded motion) passes undistorted. A notch on the measurement
        // itself would distort the measured command (4° at 10 Hz for Q = 2:
        // hundreds of µin of tracking error on a 0.004 in command).
        // The hole edges' step sits in d̂ (and so in the feedback) but is
        // not measured hum: it passes the notch by, which would otherwise
        // ring at 120 Hz for its Q/(π·120 Hz) ≈ 50 ms after every edge.
        let fb_q8 = fb_q8.saturating_add(self.edge_q8);
        let fb_q8 = match &mut self.hum {
            Some(n) => n.process(fb_q8),
            None => fb_q8,
        };
        let u_q8 = fb_q8.saturating_add(ff_q8).saturating_sub(self.edge_q8);
        // Output: current limit on the estimate, mode notch, DAC range.
        let u_code = round_q8(u_q8);
        let (u_code, limited, i_fault) = self.current.apply(u_code, est.v_q16);
        self.current_limited = limited;
        let u_code = match &mut self.mode {
            Some(n) => {
                let y = n.process(ssat::<24>(u_code) << 8);
                round_q8(y)
            }
            None => u_code,
        };
        let u_code = u_code.clamp(-CODE_MAX, CODE_MAX);
        self.output_q8 = u_code << 8;
        let fault = i_fault.or_else(|| self.following.check(error_q8));
        ServoOutput {
            dac_code: u_code,
            enable: true,
            fault,
            learn: Some(learn),
        }
    }

    /// State feedback on the estimate, and the plant-inverse feedforward:
    /// `(feedback − d̂, feedforward)`, DAC codes Q8.
    #[inline(always)]
    fn control(&self, est: &Estimate, r_q8: i32, v_q16: i32, a_q16: i32) -> (i32, i32) {
        let c = &self.cfg;
        // |r|, |ẑ| < 2²⁹: the difference fits; saturated to 2²⁸ codes Q8.
        let e_q8 = ssat::<29>(r_q8 - est.z_q8);
        let ev_q16 = v_q16.saturating_sub(est.v_q16);
        let (kp, kd) = if self.observer.fast() {
            (c.kp_fast_q24, c.kd_fast_q24)
        } else {
            (c.kp_q24, c.kd_q24)
        };
        // Q24 gain × Q8 error → Q8 (>> 24); × Q16 velocity → Q8 (>> 32,
        // the rounded high word: below 2³⁰).
        let fb = qadd_mul::<24>(mul_hi(kd, ev_q16), kp, e_q8);
        let ff = qadd_mul::<24>(mul_hi(c.kff_q24, v_q16), c.ka_q16, a_q16);
        (fb.saturating_sub(est.d_q8), ff)
    }

    /// Closes the loop with the command where the slide is. After the
    /// sign check the observer has followed the doublet (it saw the DAC
    /// codes), so it keeps its estimate, velocity included; from rest it
    /// starts at rest.
    fn engage(&mut self, y_q8: i32, from_rest: bool, v_goal_q16: i32) {
        if from_rest {
            self.observer.reset(y_q8);
        }
        let z = self.observer.estimate().z_q8;
        self.command_q8 = z;
        self.command_v_q16 = 0;
        self.correction_q8 = 0;
        self.correction_v_q16 = 0;
        // The goal already moves: the command starts at rest and joins it.
        self.goal_v_q16 = v_goal_q16;
        self.goal_q8 = z;
        self.slew.reset();
        self.phase = Phase::Engaging;
        self.current.reset();
        self.following.reset();
    }

    fn idle(&self) -> ServoOutput {
        ServoOutput {
            dac_code: 0,
            enable: false,
            fault: None,
            learn: None,
        }
    }

    pub fn phase(&self) -> Phase {
        self.phase
    }
    /// The slew-limited command, gauge codes.
    pub fn command_code(&self) -> i32 {
        round_q8(self.command_q8)
    }
    /// The reference followed on the last tick (command + learned
    /// correction), gauge codes Q8.
    pub fn reference_q8(&self) -> i32 {
        self.reference_q8
    }
    /// Gauge, Q8.
    pub fn measured_q8(&self) -> i32 {
        self.measured_q8
    }
    pub fn estimate(&self) -> Estimate {
        self.observer.estimate()
    }
    pub fn current_limited(&self) -> bool {
        self.current_limited
    }
    pub fn last_sign_check(&self) -> Option<SignCheckResult> {
        self.last_sign_check
    }
    pub fn config(&self) -> &ServoConfig {
        &self.cfg
    }
}
