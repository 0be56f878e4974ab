//! A design refusal with the values that broke it: "bandwidth_fast_hz = 150
//! must be at least bandwidth_hz = 160", not the rule alone. The rule in
//! words is [`DesignError::reason`] (what the firmware can say over the link
//! without the design at hand); this is what a tool that holds the design
//! prints. `core::fmt` only: no allocation.

use super::design::{DesignError, ServoDesign};
use core::fmt;

/// [`ServoDesign::refusal`]'s result: `Display` names the violated relation
/// and the values on both sides of it.
#[derive(Clone, Copy, Debug)]
pub struct Refusal<'a> {
    pub error: DesignError,
    pub design: &'a ServoDesign,
}

impl ServoDesign {
    /// Why `config()` refused this design, with its values.
    pub fn refusal(&self, error: DesignError) -> Refusal<'_> {
        Refusal {
            error,
            design: self,
        }
    }
}

impl fmt::Display for Refusal<'_> {
    // `!(a >= b)` so that a NaN takes the first branch, as in `config()`.
    #[allow(clippy::nonminimal_bool)]
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use DesignError as E;
        let d = self.design;
        let fs = f64::from(d.rate_hz);
        match self.error {
            E::Rate => write!(f, "rate_hz = {} must be 1000..=200000", d.rate_hz),
            E::Bandwidth => write!(
                f,
                "bandwidth_hz = {} must be > 0 and below rate_hz / 20 = {} / 20 = {}",
                d.bandwidth_hz,
                d.rate_hz,
                fs / 20.0
            ),
            E::BandwidthFast => {
                // Negated so that a NaN takes the first message too.
                #[allow(clippy::neg_cmp_op_on_partial_ord)]
                let below = !(d.bandwidth_fast_hz >= d.bandwidth_hz);
                if below {
                    write!(
                        f,
                        "bandwidth_fast_hz = {} must be at least bandwidth_hz = {} (raise bandwidth_fast_hz with it)",
                        d.bandwidth_fast_hz, d.bandwidth_hz
                    )
                } else {
                    write!(
                        f,
                        "bandwidth_fast_hz = {} must be below rate_hz / 20 = {} / 20 = {}",
                        d.bandwidth_fast_hz,
                        d.rate_hz,
                        fs / 20.0
                    )
                }
            }
            E::Damping => write!(f, "damping = {} must be in (0, 5]", d.damping),
            E::Observer => write!(
                f,
                "observer_hz = {} must be > 0 and below rate_hz / 10 = {}",
                d.observer_hz,
                fs / 10.0
            ),
            E::ObserverFast => write!(
                f,
                "observer_fast_hz = {} must be in [observer_hz = {}, rate_hz / 10 = {}), observer_switch_uin = {} in (0, 10000], observer_hold_ms = {} in [0, 10000]",
                d.observer_fast_hz,
                d.observer_hz,
                fs / 10.0,
                d.observer_switch_uin,
                d.observer_hold_ms
            ),
            E::HumNotch => write!(
                f,
                "hum_notch_hz = {} must be in (0, rate_hz / 2 = {}), hum_notch_q = {} > 0 (0 = off), and hum_notch_turn_deg = {} must be inside (−90, 90) with the hum canceller's poles inside the unit circle",
                d.hum_notch_hz,
                fs / 2.0,
                d.hum_notch_q,
                d.hum_notch_turn_deg
            ),
            E::ModeNotch => write!(
                f,
                "mode_notch_hz = {} must be in (0, rate_hz / 2 = {}) and mode_notch_q = {} > 0 (0 = off)",
                d.mode_notch_hz,
                fs / 2.0,
                d.mode_notch_q
            ),
            E::Learning => write!(
                f,
                "learning_gain = {} in [0, 1), learning_lead_bins = {} in 3..=32, learning_q_shift = {} in 1..=3, learning_clip_uin = {} in (0, 10000], learning_lowpass_hz = {} in [0, rate_hz / 10 = {}): {}",
                d.learning_gain,
                d.learning_lead_bins,
                d.learning_q_shift,
                d.learning_clip_uin,
                d.learning_lowpass_hz,
                fs / 10.0,
                E::Learning.reason()
            ),
            E::Slew => write!(
                f,
                "slew_in_per_s = {} must be in (0, 10] and slew_accel_in_per_s2 = {} in (0, 1000]",
                d.slew_in_per_s, d.slew_accel_in_per_s2
            ),
            E::CommandLimit => write!(
                f,
                "command_limit_in = {} must be in (0, 0.010]",
                d.command_limit_in
            ),
            E::CurrentLimit => write!(
                f,
                "current_limit_a = {} must be in (0, 100] and current_limit_ms = {} in (0, 10000]",
                d.current_limit_a, d.current_limit_ms
            ),
            E::FollowingError => write!(
                f,
                "following_error_in = {} must be in (0, 0.010] and following_error_ms = {} in [0, 10000]",
                d.following_error_in, d.following_error_ms
            ),
            E::SignCheck => write!(
                f,
                "sign_check_v = {} must be in [0, 2] and sign_check_ms = {} in (0, 20]",
                d.sign_check_v, d.sign_check_ms
            ),
            E::Monitor => write!(
                f,
                "depth_of_cut_uin = {} (depth guard {:.1} µin), oscillation_uin = {}, gauge_frozen_ms = {}, x_stall_revs = {}, retract_z_in = {}: {}",
                d.depth_of_cut_uin,
                d.depth_guard_uin(),
                d.oscillation_uin,
                d.gauge_frozen_ms,
                d.x_stall_revs,
                d.retract_z_in,
                E::Monitor.reason()
            ),
            E::GainRange => write!(
                f,
                "bandwidth_hz = {}, bandwidth_fast_hz = {}, damping = {} at rate_hz = {}: {}",
                d.bandwidth_hz,
                d.bandwidth_fast_hz,
                d.damping,
                d.rate_hz,
                E::GainRange.reason()
            ),
            E::DepthOfCut => write!(
                f,
                "depth_of_cut_uin = {} must be in [1, 10000] µin (0.010 in: the gauge's range, over which the slide lifts the tool clear of the stock)",
                d.depth_of_cut_uin
            ),
            E::EdgeFeedforward => write!(
                f,
                "edge_feedforward = {}: {}",
                d.edge_feedforward,
                E::EdgeFeedforward.reason()
            ),
            E::Slide => f.write_str(E::Slide.reason()),
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;
    use super::*;

    /// The case: 160 Hz is below rate_hz / 20, but above the fast
    /// bandwidth of the brief's design (150 Hz). The refusal must name that
    /// relation and both values, not the rate.
    #[test]
    fn a_bandwidth_above_the_fast_bandwidth_names_both_values() {
        let mut d = ServoDesign::brief(20_000);
        d.bandwidth_hz = 160.0;
        let e = d.config().unwrap_err();
        assert_eq!(e, DesignError::BandwidthFast);
        let m = std::format!("{}", d.refusal(e));
        assert!(
            m.contains("bandwidth_fast_hz = 150") && m.contains("bandwidth_hz = 160"),
            "{m}"
        );
        assert!(!m.contains("rate_hz"), "{m}");
    }

    #[test]
    fn a_bandwidth_beyond_the_rate_names_the_rate_and_its_twentieth() {
        let mut d = ServoDesign::brief(20_000);
        d.bandwidth_hz = 1000.0;
        let e = d.config().unwrap_err();
        assert_eq!(e, DesignError::Bandwidth);
        let m = std::format!("{}", d.refusal(e));
        assert!(m.contains("bandwidth_hz = 1000"), "{m}");
        assert!(m.contains("rate_hz / 20 = 20000 / 20 = 1000"), "{m}");
    }
}
