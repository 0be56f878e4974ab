//! The 1983 loop driving the amplifier from the world's advance.

use super::emulation::AnalogController;
use super::exact::ClosedLoopExact;
use super::transfer::PositionLoop1983;

/// The 1983 loop driving the amplifier from the world's advance: exact
/// closed-loop steps ([`ClosedLoopExact`]) while it is linear, the
/// co-simulation against the rig ([`AnalogController`] every `substep_ns`,
/// with the amplifier's limit and trip and the gauge's saturation) from
/// the first step that leaves the linear range until the loop has been
/// back inside it for [`RELINEAR_NS`]. The reference (the firmware's
/// command, V = mil) is held from tick to tick.
pub struct AnalogDrive {
    pub ctrl: AnalogController,
    exact: Option<ClosedLoopExact>,
    /// The exact steps carry the loop now.
    in_exact: bool,
    /// Co-simulating: since when the loop is linear again, ns.
    linear_since: Option<u64>,
    next_substep_ns: u64,
    pub reference_v: f64,
    /// The command generator's sign (−1: the 1983 first part's mistake,
    /// `cut --command-sign reversed`).
    pub reference_sign: f64,
    /// The command generator's output (V = mil) when it is not the
    /// firmware's command (`cut::command1983`: the 1983 generator).
    pub command_v: Option<std::rc::Rc<std::cell::Cell<f64>>>,
    /// The command path's lag ahead of the summing junction
    /// (`[errors] cmd_lag_us`, [`super::lag`]); `None`: none.
    pub reference_lag: Option<super::lag::FirstOrderLag>,
    /// Hand-overs to the co-simulation so far.
    pub nonlinear_spells: u64,
}

/// Time the co-simulated loop must stay linear before the exact steps take
/// over again, ns.
pub const RELINEAR_NS: u64 = 2_000_000;

impl AnalogDrive {
    /// The 1983 position loop on `rig`; `exact`: exact steps while linear
    /// (else the co-simulation throughout).
    pub fn position_loop(rig: &crate::plant::Rig, exact: bool, seed: u64) -> Self {
        let ctrl = AnalogController::position_loop(&PositionLoop1983::default());
        let exact =
            exact.then(|| ClosedLoopExact::new(ctrl.cache.system(), ctrl.x.as_slice(), rig, seed));
        // The first substep one substep after the hand-over (as a
        // periodic source added now would fire).
        let next_substep_ns = (rig.t_ns / ctrl.substep_ns + 1) * ctrl.substep_ns;
        Self {
            ctrl,
            in_exact: exact.is_some(),
            exact,
            linear_since: None,
            next_substep_ns,
            reference_v: 0.0,
            reference_sign: 1.0,
            command_v: None,
            reference_lag: None,
            nonlinear_spells: 0,
        }
    }

    /// Whether the exact steps carry the loop now.
    pub fn is_exact(&self) -> bool {
        self.in_exact
    }

    /// Advances the rig and the loop to `t_ns`.
    pub fn advance(&mut self, rig: &mut crate::plant::Rig, t_ns: u64) {
        let reference = match self.reference_lag.as_mut() {
            Some(l) => l.at(t_ns, self.reference_v),
            None => self.reference_v,
        };
        if self.in_exact {
            let Some(ex) = self.exact.as_mut() else {
                return;
            };
            if t_ns > rig.t_ns {
                ex.step(t_ns - rig.t_ns, reference, rig.f_ext);
                rig.slide.x = ex.plant_x();
                rig.t_ns = t_ns;
                rig.steps += 1;
                rig.v_in = ex.amp_input_v(reference);
                // The firmware's DAC is not connected; enable edges still
                // reach the amplifier.
                rig.take_changes_to(t_ns);
                if !ex.linear(rig, reference) || rig.gauge_injection_in != 0.0 {
                    // Hand over: the rig carries the plant, the controller
                    // its state, the gauge the noise.
                    self.ctrl.x.copy_from_slice(ex.controller_x());
                    rig.gauge.continue_noise_from(ex.noise_in(), t_ns);
                    self.next_substep_ns =
                        t_ns.div_ceil(self.ctrl.substep_ns) * self.ctrl.substep_ns;
                    self.in_exact = false;
                    self.linear_since = None;
                    self.nonlinear_spells += 1;
                }
            }
            return;
        }
        while self.next_substep_ns < t_ns {
            rig.advance_to(self.next_substep_ns);
            self.ctrl.reference_v = reference;
            self.ctrl.tick(rig);
            self.next_substep_ns += self.ctrl.substep_ns;
        }
        rig.advance_to(t_ns);
        let Some(ex) = self.exact.as_mut() else {
            return;
        };
        // Back to the exact steps once linear long enough (with the same
        // margins; the amplifier in voltage control).
        let p = &rig.amp.params;
        let linear = rig.slide.current_a().abs() < 0.5 * p.current_limit_a
            && (p.gain * rig.v_in).abs() < 0.5 * p.rail_v
            && rig
                .gauge
                .volts_noiseless(rig.slide.gauge_position_in())
                .abs()
                < rig.gauge.params.range_v - 0.5
            && rig.amp.regime() == crate::plant::amplifier::AmpRegime::Voltage
            && rig.gauge_injection_in == 0.0;
        if !linear {
            self.linear_since = None;
            return;
        }
        let since = *self.linear_since.get_or_insert(t_ns);
        if t_ns - since >= RELINEAR_NS {
            ex.load(
                &rig.slide.x,
                self.ctrl.x.as_slice(),
                rig.gauge.noise_state(),
                rig,
            );
            // The rig's queues are taken over from here.
            rig.take_changes_to(t_ns);
            self.in_exact = true;
        }
    }

    /// The gauge's output now as the ADC converts it (saturated), V.
    pub fn gauge_volts(&self, rig: &crate::plant::Rig) -> Option<f64> {
        if !self.in_exact {
            return None;
        }
        let ex = self.exact.as_ref()?;
        let r = rig.gauge.params.range_v;
        Some(ex.gauge_v().clamp(-r, r))
    }
}
