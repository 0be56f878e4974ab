//! The loop-tick handler (highest priority): takes what the X and index
//! handlers published, reads the gauge, forms the spindle angle, (modern X)
//! the coefficients, the setpoint with its analytic rates, hands them to
//! the servo and writes its DAC code. It only orchestrates: the loop
//! itself is `servo`, the command `command`/`setpoint`.

use crate::codes::{CODE_MAX, CODE_MIN};
use crate::command::expansion::Expansion;
use crate::command::setpoint::{setpoint, SetpointState};
use crate::command::{Coefficients, CommandGen};
use crate::handoff::ahead::{Ahead, MAX_AGE};
use crate::handoff::{Request, Shared, X_FAULTS};
use crate::hw::{AmplifierDac, EncoderSample, GaugeAdc};
use crate::safety::{Clearing, Device, Fault, Reaction};
use crate::servo::{Freeze, Phase, Reference, Servo, ServoConfig, ServoInput, ServoOutput};
use crate::spindle::{EncoderAngle, TachAngle};
use crate::units::{SpindleAngle, XInches};

/// One spindle reading, as the hw traits deliver it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpindleReading {
    /// No reading (no spindle configured).
    None,
    /// [`crate::hw::Encoder::sample`] of the spindle encoder.
    Encoder(EncoderSample),
    /// [`crate::hw::Tachometer::millivolts`].
    Tach(i32),
}

/// What the loop tick samples besides the gauge, read by the board from its
/// hw-trait implementations at the tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickInput {
    /// [`crate::hw::Clock::now_ticks`] at the sampling instant.
    pub now: u32,
    pub spindle: SpindleReading,
    /// Modern X mode: the X encoder's count at the tick
    /// ([`crate::hw::Encoder`]). The loop tick itself does not use it: the
    /// coefficients at the count's X are the X handler's work, at its
    /// lower priority ([`crate::firmware::xevent::EventState::x_count_event`]), and
    /// reach the tick through the same hand-off as a legacy X event. The
    /// `Firmware` bundle hands this count to that handler after the tick,
    /// as a board's lower-priority handler would take it.
    pub x_count: u32,
    /// The power amplifier's fault line (high: it tripped).
    pub amplifier_fault: bool,
}

impl TickInput {
    /// No spindle, no X: the bench's input.
    pub const NONE: Self = Self {
        now: 0,
        spindle: SpindleReading::None,
        x_count: 0,
        amplifier_fault: false,
    };
}

#[derive(Clone, Debug)]
pub(crate) enum Estimator {
    None,
    Encoder(EncoderAngle),
    Tach(TachAngle),
}

/// State of the loop-tick handler (highest priority).
#[derive(Clone, Debug)]
pub struct LoopState {
    pub(crate) gen: Option<CommandGen<'static>>,
    pub(crate) spindle: Estimator,
    /// Coefficients arrive from the X handler (an X source is configured).
    pub(crate) x_published: bool,
    pub(crate) gauge_reversed: bool,
    /// The last coefficient set is the null command (or none arrived).
    pub(crate) coeff_null: bool,
    /// Generation of the last coefficient set taken (its X and null flag).
    pub(crate) coeff_seen: u32,
    /// The values of a set, copied only when the tick evaluates the command
    /// itself (a stale expansion: `command_at`), and their generation.
    pub(crate) fallback: Coefficients,
    pub(crate) fallback_seen: u32,
    pub(crate) index_seen: u32,
    pub(crate) x_faults_seen: u32,
    /// Where a latched fault's reaction takes the command, gauge codes:
    /// null, or the retract (`Reaction::Retract`).
    pub(crate) fault_goal: i32,
    /// The angle history of the setpoint's rates.
    pub(crate) sp: SetpointState,
    /// The table command was live (not null) on the last tick.
    pub(crate) command_live: bool,
    /// X of the last coefficient set (learning freezes when it jumps).
    pub(crate) last_coeff_x: Option<XInches>,
    /// Offset added to the table command, gauge codes.
    pub(crate) target: i32,
    /// The offset on the last tick.
    pub(crate) last_target: i32,
    /// The slew rate, whole codes per tick (a target step within it is a
    /// motion, not a jump).
    pub(crate) slew_codes: u32,
    /// Table command of the last tick, gauge codes.
    pub(crate) table_code: i32,
    /// Velocity input of the last tick (∂Z/∂φ·Δφ), codes/tick Q16.
    pub(crate) ff_q16: i32,
    /// Acceleration input of the last tick, codes/tick², Q16.
    pub(crate) accel_q16: i32,
    pub(crate) servo: Servo,
    /// Gauge code of the last good sample (+Z).
    pub(crate) position: i32,
    /// Whether the last gauge sample was bad (range, rail, bus).
    pub(crate) gauge_bad: bool,
    pub(crate) ticks: u32,
    pub(crate) output: i32,
    pub(crate) fault: Option<Fault>,
    /// The last clear request was refused (the cause was still present).
    pub(crate) clear_refused: Option<Fault>,
    pub(crate) dac_clamped: bool,
    /// The DAC holds code 0 (disarmed).
    pub(crate) dac_zeroed: bool,
    /// Identification's sine on the DAC (`super::excite`).
    pub(crate) excite: super::excite::Excitation,
}

/// |ΔX| between two coefficient sets beyond which the learned table no
/// longer belongs to the radius: 0.01 in (the feed moves 100 µin per
/// revolution; a jump this size is a restart elsewhere or a bad count).
pub(crate) const X_JUMP_BITS: i32 = (0.01 * (1u64 << 24) as f64) as i32;

impl LoopState {
    pub(crate) fn new(cfg: ServoConfig) -> Self {
        Self {
            gen: None,
            spindle: Estimator::None,
            x_published: false,
            gauge_reversed: false,
            coeff_null: true,
            coeff_seen: 0,
            fallback: Coefficients::NULL,
            fallback_seen: 0,
            index_seen: 0,
            x_faults_seen: 0,
            fault_goal: 0,
            sp: SetpointState::default(),
            command_live: false,
            last_coeff_x: None,
            target: 0,
            last_target: 0,
            slew_codes: (cfg.slew_q16 >> 16).clamp(0, i64::from(u32::MAX)) as u32,
            table_code: 0,
            ff_q16: 0,
            accel_q16: 0,
            servo: Servo::new(cfg),
            position: 0,
            gauge_bad: false,
            ticks: 0,
            output: 0,
            fault: None,
            clear_refused: None,
            dac_clamped: false,
            dac_zeroed: false,
            excite: super::excite::Excitation::OFF,
        }
    }

    /// Latches `fault` unless a fault with an equally or more severe reaction
    /// is already latched (the first cause stays readable).
    pub fn trip(&mut self, fault: Fault) {
        match self.fault {
            Some(f) if f.reaction() >= fault.reaction() => {}
            _ => {
                self.fault = Some(fault);
                self.fault_goal = if fault.reaction() == Reaction::Retract {
                    self.servo.config().monitor.retract_code
                } else {
                    0
                };
            }
        }
    }

    /// Sets an offset added to the table command (with no table: where the
    /// slide should go); the command ramps there at the slew limit. Clamped
    /// to the gauge range.
    pub fn set_target_code(&mut self, code: i32) {
        self.target = code.clamp(CODE_MIN, CODE_MAX);
    }

    /// Picks up what the X / index / learning handlers published.
    #[inline(always)]
    pub(crate) fn take_published(&mut self, sh: &Shared) {
        let xf = sh.x_faults();
        if xf != self.x_faults_seen {
            let new = xf & !self.x_faults_seen;
            self.x_faults_seen = xf;
            for (bit, f) in X_FAULTS {
                if new & bit != 0 {
                    self.trip(f);
                }
            }
        }
        match sh.take_index(&mut self.index_seen) {
            Ok(None) => {}
            Err(()) => {
                // Overwritten while read (a writer that can preempt the
                // tick): the pulses came faster than the loop rate.
                self.trip(Fault::IndexExtra);
                return;
            }
            Ok(Some(p)) => {
                if p.missed {
                    // Two index pulses within one loop period: noise.
                    self.trip(Fault::IndexExtra);
                }
                let r = match &mut self.spindle {
                    Estimator::Encoder(e) => e.on_index(p.count_at_index, p.edge_ticks),
                    Estimator::Tach(t) => t.on_index(p.edge_ticks),
                    Estimator::None => Ok(()),
                };
                if let Err(f) = r {
                    self.trip(f);
                }
            }
        }
        if self.x_published {
            // The X and the null flag only: the values are copied if the
            // tick has to evaluate the command itself (`command_at`).
            match sh.coefficients().take_x(&mut self.coeff_seen) {
                Ok(Some((x, null))) => {
                    self.coeff_null = null;
                    self.note_x(x);
                }
                Err(x) => {
                    // Overwritten while read: null until the next one.
                    self.coeff_null = true;
                    self.note_x(x);
                }
                Ok(None) => {}
            }
        }
    }

    /// The loop-tick interrupt: gauge and spindle sample in, one DAC code out.
    /// It reads as the steps below, each inlined into it: what the other
    /// priorities handed over, the gauge (sense), the fault checks that
    /// hold the amplifier safe, the spindle angle (sense), the reference
    /// (the table's setpoint and the operator's target), the servo
    /// (control), and the amplifier DAC (output). (The trace and the link's
    /// tap run in the boards around it.)
    ///
    /// Never inlined, so that `cargo xtask isr-cost` finds it in the image
    /// and counts its instructions apart from the board's glue.
    #[inline(never)]
    pub fn loop_tick(
        &mut self,
        sh: &Shared,
        input: &TickInput,
        gauge: &mut impl GaugeAdc,
        dac: &mut impl AmplifierDac,
    ) {
        self.ticks = self.ticks.wrapping_add(1);
        self.take_published(sh);
        let read = self.sense_gauge(gauge);
        self.take_requests(sh, input.amplifier_fault);
        let Some(y) = self.fault_checks(read, dac) else {
            return;
        };
        let phi = self.sense_angle(input);
        let (reference, dphi, fresh) = self.reference(sh, phi);
        let out = self.control(sh, input, y, reference, phi, dphi, fresh);
        self.output(&out, dac);
    }

    /// Sense: the gauge, read even with the amplifier off (a clear request
    /// needs to see whether a gauge fault's cause is gone).
    #[inline(always)]
    fn sense_gauge(&mut self, gauge: &mut impl GaugeAdc) -> Result<i32, Fault> {
        let read = match gauge.read() {
            Err(_) => Err(Fault::Bus(Device::GaugeAdc)),
            Ok(s) if s.overrange => Err(Fault::GaugeRange),
            // A reading on a rail without OV: the gauge's own output is
            // pinned, so the loop cannot see where the slide is beyond it.
            // (Inside the rails the code is a 20-bit one.)
            Ok(s) if s.code <= CODE_MIN || s.code >= CODE_MAX => Err(Fault::GaugeSaturated),
            Ok(s) => Ok(s.code),
        };
        self.gauge_bad = read.is_err();
        read
    }

    /// Fault checks: a bad gauge reading or a fault that needs the
    /// amplifier off holds the output safe (`None`: the tick ends here);
    /// a cleared fault releases the DAC's clamp. Otherwise the slide's
    /// position, gauge codes along +Z.
    #[inline(always)]
    fn fault_checks(
        &mut self,
        read: Result<i32, Fault>,
        dac: &mut impl AmplifierDac,
    ) -> Option<i32> {
        let code = match read {
            Ok(c) => c,
            Err(f) => {
                self.trip(f);
                self.hold_safe(dac);
                return None;
            }
        };
        if self.amplifier_must_be_off() {
            self.hold_safe(dac);
            return None;
        }
        if self.dac_clamped && self.fault.is_none() {
            // The fault that clamped the converter was cleared: release the
            // clamp at zero volts before anything drives the output (the
            // servo has not written this tick yet).
            if dac.release_clamp().is_err() {
                self.trip(Fault::Bus(Device::AmplifierDac));
                self.hold_safe(dac);
                return None;
            }
            self.dac_clamped = false;
            self.dac_zeroed = true;
        }
        let y = if self.gauge_reversed { -code } else { code };
        self.position = y;
        Some(y)
    }

    /// Sense: the spindle angle (`None` before the estimator is
    /// referenced, or without a spindle); its fault latches.
    #[inline(always)]
    fn sense_angle(&mut self, input: &TickInput) -> Option<SpindleAngle> {
        let est = match (&mut self.spindle, input.spindle) {
            (Estimator::Encoder(e), SpindleReading::Encoder(s)) => {
                let est = e.tick(s.count, s.edge_ticks, input.now);
                e.referenced().then_some(est)
            }
            (Estimator::Tach(t), SpindleReading::Tach(mv)) => {
                let est = t.tick(mv, input.now);
                t.referenced().then_some(est)
            }
            _ => None,
        };
        match est {
            Some(e) => {
                if let Some(f) = e.fault {
                    self.trip(f);
                }
                Some(e.angle)
            }
            None => None,
        }
    }

    /// Reference: the command and its analytic rates at `phi` (the
    /// expansion made below the tick, stepped to this angle:
    /// `crate::handoff::ahead`), the next angle request posted, and the
    /// operator's target added; a latched fault ramps to null instead.
    /// Also the tick's angle step and what came from below the tick.
    #[inline(always)]
    fn reference(
        &mut self,
        sh: &Shared,
        phi: Option<SpindleAngle>,
    ) -> (Reference, i32, Option<Ahead>) {
        let dphi = self.sp.dphi(phi);
        let (rate_dphi, alpha_q4) = self.sp.advance(phi, dphi);
        let fresh = sh
            .ahead()
            .latest()
            .filter(|a| self.ticks.wrapping_sub(a.tick) <= MAX_AGE);
        let command = phi.and_then(|p| self.command_at(sh, fresh.as_ref(), p, rate_dphi, alpha_q4));
        self.command_live = command.is_some();
        let table = setpoint(command.as_ref(), rate_dphi);
        if let Some(p) = phi {
            sh.ahead().post(self.ticks, p, dphi, alpha_q4);
        }
        let (table_code, slope, accel) = (table.code, table.velocity_q16, table.accel_q16);
        self.table_code = table_code;
        self.ff_q16 = slope;
        self.accel_q16 = accel;
        let reference = if self.fault.is_some() {
            // RampToNull: the loop stays closed and ramps to null;
            // Retract: to the retract, out of the stock.
            Reference {
                code: self.fault_goal,
                ..Reference::default()
            }
        } else {
            // The target offset's own rate (a user signal, clean) joins the
            // table's analytic rate in the velocity feedforward when it is a
            // motion (a step is approached by the servo's slew profile).
            // Both within the gauge's range: the step fits an i32.
            let step = self.target - self.last_target;
            let target_step = if step != 0 && step.unsigned_abs() <= self.slew_codes {
                step
            } else {
                0
            };
            Reference {
                code: self
                    .target
                    .saturating_add(table_code)
                    .clamp(CODE_MIN, CODE_MAX),
                // A step of the target within the slew rate is motion (at
                // most 2¹⁴ codes per tick counted: 6 in/s at 20 kHz).
                velocity_q16: slope.saturating_add(target_step.clamp(-(1 << 14), 1 << 14) << 16),
                accel_q16: accel,
            }
        };
        self.last_target = self.target;
        (reference, dphi, fresh)
    }

    /// Control: the servo's update on the gauge and the reference, the
    /// learning frozen where the command is null or faulted; the learner's
    /// sample handed to the priority below.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn control(
        &mut self,
        sh: &Shared,
        input: &TickInput,
        y: i32,
        reference: Reference,
        phi: Option<SpindleAngle>,
        dphi: i32,
        fresh: Option<Ahead>,
    ) -> ServoOutput {
        let faulted = self.fault.is_some();
        let out = self.servo.update(
            &ServoInput {
                gauge_code: y,
                reference,
                angle: phi.map(|p| (p, dphi)),
                freeze: if faulted {
                    Some(Freeze::Fault)
                } else if self.coeff_null
                    || self.gen.is_none()
                    || (phi.is_some() && !self.command_live)
                {
                    Some(Freeze::Null)
                } else {
                    None
                },
                amplifier_tripped: input.amplifier_fault,
                correction_ahead: fresh.map(|a| a.correction),
                edge_q8: fresh.map(|a| a.edge_q8),
            },
            sh.learned(),
        );
        if let Some(s) = &out.learn {
            // The learner runs below this priority (`crate::firmware::learning`).
            sh.learn_queue().push(s);
        }
        out
    }

    /// Output: the servo's fault latched (the amplifier held safe where it
    /// must be off), zero volts once while disarmed, else the DAC code.
    #[inline(always)]
    fn output(&mut self, out: &ServoOutput, dac: &mut impl AmplifierDac) {
        if let Some(f) = out.fault {
            self.trip(f);
            if self.amplifier_must_be_off() {
                self.hold_safe(dac);
                return;
            }
        }
        if !out.enable {
            // Disarmed: DAC at zero volts (written once), enable low.
            if !self.dac_zeroed {
                match dac.write(0) {
                    Ok(()) => self.dac_zeroed = true,
                    Err(_) => {
                        self.trip(Fault::Bus(Device::AmplifierDac));
                        self.hold_safe(dac);
                    }
                }
            }
            self.output = 0;
            return;
        }
        self.dac_zeroed = false;
        let code = if self.excite.active() {
            self.excited(out.dac_code)
        } else {
            out.dac_code
        };
        match dac.write(code) {
            Ok(()) => self.output = code,
            Err(_) => {
                self.trip(Fault::Bus(Device::AmplifierDac));
                self.hold_safe(dac);
            }
        }
    }

    /// The command at `phi`: the freshest expansion from below the tick
    /// stepped to it; evaluated here when that is stale while the command
    /// was live (a starved handler costs instructions, not accuracy); null
    /// while it was null and none has arrived (the first tick or two after
    /// the angle or the coefficients appear).
    #[inline(always)]
    fn command_at(
        &mut self,
        sh: &Shared,
        fresh: Option<&Ahead>,
        phi: SpindleAngle,
        dphi: i32,
        alpha_q4: i32,
    ) -> Option<Expansion> {
        if let Some(a) = fresh {
            match a.expansion {
                None => return None,
                Some(e) => {
                    if let Some(s) = e.step(phi) {
                        return Some(s);
                    }
                }
            }
        }
        if !self.command_live || self.coeff_null {
            return None;
        }
        self.evaluate_here(sh, phi, dphi, alpha_q4)
    }

    /// The fallback of [`Self::command_at`]: rare (a handler below the
    /// tick starved), so out of line, where its copy and evaluation do
    /// not crowd the registers of every tick.
    #[cold]
    #[inline(never)]
    fn evaluate_here(
        &mut self,
        sh: &Shared,
        phi: SpindleAngle,
        dphi: i32,
        alpha_q4: i32,
    ) -> Option<Expansion> {
        let g = self.gen.as_ref()?;
        // The values of the set the tick took (no handler below the tick
        // runs between its take and this copy), copied once per set: the
        // only use of them in the tick.
        if sh
            .coefficients()
            .take(&mut self.fallback_seen, &mut self.fallback)
            .is_err()
            || self.fallback.null
        {
            return None;
        }
        Some(Expansion::direct(g, &self.fallback, phi, dphi, alpha_q4))
    }

    /// Remembers the X of a new coefficient set; a jump freezes learning
    /// for a second (the table belongs to another radius).
    #[inline(always)]
    pub(crate) fn note_x(&mut self, x: XInches) {
        if let Some(p) = self.last_coeff_x {
            let d = x.0.to_bits().wrapping_sub(p.0.to_bits());
            if !(-X_JUMP_BITS..=X_JUMP_BITS).contains(&d) {
                let hold = self.servo.config().rate_hz;
                self.servo.freeze_learning(Freeze::XJump, hold);
            }
        }
        self.last_coeff_x = Some(x);
    }

    /// Operator requests posted in [`Shared`].
    #[inline(always)]
    pub(crate) fn take_requests(&mut self, sh: &Shared, amplifier_fault: bool) {
        if !sh.requests_pending() {
            return;
        }
        let r = sh.take_requests();
        if r & Request::Disarm.bit() != 0 {
            self.servo.disarm();
        }
        if r & Request::ClearFault.bit() != 0 {
            self.clear_fault(amplifier_fault);
        }
        // Arming with a ramp-to-null fault latched is allowed: the loop then
        // holds the slide at null (a refused table, a lost X).
        if r & Request::Arm.bit() != 0
            && r & Request::Disarm.bit() == 0
            && !self.amplifier_must_be_off()
        {
            self.servo.arm();
        }
    }

    /// Clears the latched fault when the loop is disarmed and the cause is
    /// no longer seen; otherwise records the refusal.
    pub(crate) fn clear_fault(&mut self, amplifier_fault: bool) {
        let Some(f) = self.fault else {
            return;
        };
        let present = self.servo.phase() != Phase::Disarmed
            || match f.clearing() {
                Clearing::GaugeGood => self.gauge_bad,
                Clearing::AmplifierLineLow => amplifier_fault,
                Clearing::NextBoot => true,
                Clearing::Disarmed => false,
            };
        if present {
            self.clear_refused = Some(f);
        } else {
            self.fault = None;
            self.clear_refused = None;
        }
    }

    pub(crate) fn amplifier_must_be_off(&self) -> bool {
        matches!(self.fault, Some(f) if f.reaction() == Reaction::DisableAmplifier)
    }

    pub(crate) fn hold_safe(&mut self, dac: &mut impl AmplifierDac) {
        self.output = 0;
        self.servo.stop();
        self.dac_zeroed = false;
        if !self.dac_clamped && dac.clamp_to_ground().is_ok() {
            self.dac_clamped = true;
        }
    }

    /// Whether the board may drive the amplifier-enable line high: the loop
    /// is armed (never on its own: only after [`Request::Arm`]) and no
    /// fault demands it off.
    pub fn amplifier_enable(&self) -> bool {
        self.servo.phase() != Phase::Disarmed && !self.amplifier_must_be_off()
    }
    /// The servo (engagement phase, estimate, learning, configuration).
    pub fn servo(&self) -> &Servo {
        &self.servo
    }
    /// The fault a clear request could not clear (its cause was present or
    /// the loop armed), until the next successful clear.
    pub fn clear_refused(&self) -> Option<Fault> {
        self.clear_refused
    }
    /// Loop ticks run so far (wrapping), faulted ticks included.
    pub fn ticks(&self) -> u32 {
        self.ticks
    }
    /// The latched fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }
    /// The command the loop followed on the last tick, gauge codes.
    pub fn command_code(&self) -> i32 {
        self.servo.command_code()
    }
    /// The table's Z command of the last tick, gauge codes (0 when null).
    pub fn table_code(&self) -> i32 {
        self.table_code
    }
    /// The offset (no table: the target) the command ramps to, gauge codes.
    pub fn target_code(&self) -> i32 {
        self.target
    }
    /// The gauge code of the last good sample (Z sense).
    pub fn position_code(&self) -> i32 {
        self.position
    }
    /// The DAC code written on the last tick (0 when held safe).
    pub fn output_code(&self) -> i32 {
        self.output
    }
    /// Velocity feedforward input of the last tick, gauge codes per tick, Q16.
    pub fn feedforward_q16(&self) -> i32 {
        self.ff_q16
    }
    /// Acceleration feedforward input of the last tick (∂²Z/∂φ²·Δφ²),
    /// gauge codes per tick², Q16.
    pub fn accel_q16(&self) -> i32 {
        self.accel_q16
    }
    /// Whether the DAC has acknowledged its clamp to ground.
    pub fn dac_clamped(&self) -> bool {
        self.dac_clamped
    }
    /// Whether the last coefficient set is the null command (X in the
    /// null zone), or none has arrived. The values are the handler's below
    /// the tick ([`crate::firmware::learning::AheadState::coefficients`]).
    pub fn command_null(&self) -> bool {
        self.coeff_null
    }
    pub fn config(&self) -> &ServoConfig {
        self.servo.config()
    }
    /// The setpoint's angle history: the spindle angle of the last tick
    /// and its smoothed step (the speed), for status reports.
    pub fn setpoint_state(&self) -> &SetpointState {
        &self.sp
    }
    /// X of the last coefficient set (`None` before the first).
    pub fn last_x(&self) -> Option<XInches> {
        self.last_coeff_x
    }
    /// Runs the loop on `cfg` from now on (new parameters from the host
    /// link): only while disarmed, where replacing the servo (observer,
    /// notch states, learned table) bumps nothing; returns whether it did.
    pub fn reconfigure(&mut self, cfg: ServoConfig) -> bool {
        if self.servo.phase() != Phase::Disarmed {
            return false;
        }
        self.servo = Servo::new(cfg);
        true
    }
}

// Identification's sine (`super::excite`): the state checks live with
// the state they read.
impl LoopState {
    /// Engaged at null: the only state a sine may run in (module docs).
    pub(crate) fn at_null(&self) -> bool {
        self.servo.phase() == Phase::Engaged
            && self.fault.is_none()
            && self.coeff_null
            && self.target == 0
    }

    /// Starts the sine (the station's checked request), its phase 0 after
    /// `wait` ticks; false, and nothing started, when the loop is not
    /// engaged at null.
    pub fn excite(&mut self, step: u32, amplitude: u32, ticks: u32, wait: u32) -> bool {
        if !self.at_null() {
            self.excite.stop();
            return false;
        }
        self.excite.start(step, amplitude, ticks, wait);
        true
    }

    /// `code` plus this tick's sine, or `code` alone (and the sine stopped
    /// for good) when the loop left null.
    #[inline(always)]
    pub(crate) fn excited(&mut self, code: i32) -> i32 {
        if !self.at_null() {
            self.excite.stop();
            return code;
        }
        code.saturating_add(self.excite.sample())
            .clamp(CODE_MIN, CODE_MAX)
    }

    /// A sine is running.
    pub fn exciting(&self) -> bool {
        self.excite.active()
    }
}
