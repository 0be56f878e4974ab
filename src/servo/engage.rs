//! Arming, the commissioning sign check, bumpless engagement and disarming.
//!
//! The amplifier is never enabled on its own: the loop starts
//! [`Phase::Disarmed`] and leaves it only on an explicit arm request.
//!
//! ```text
//! Disarmed ──arm──▶ SignCheck ──pass──▶ Engaging ──command reached goal──▶ Engaged
//!    ▲                 │fail: Fault::SignCheck                │disarm            │disarm
//!    │                 ▼                                       ▼                  ▼
//!    └──────────── (fault reaction) ◀──────────────── Disarming (ramp to null) ◀─┘
//! ```
//!
//! **Sign check** (chapter 5: the first part was cut with the command sign
//! reversed, "error = twice the command"): with the loop open, the DAC
//! drives a doublet, +p for n ticks then −p for n ticks (the second half
//! takes back the velocity the first gave). The gauge must have moved by
//! the model's `z(nh) = K·p·(t/a − (1 − e^{−at})/a²)` at the end of the
//! first half, in the same sign, within a factor of three either way. A
//! reversed gauge, reversed amplifier or motor wiring, a dead amplifier or
//! a stuck slide all fail it, before the loop is ever closed on the wrong
//! sign.
//!
//! **Bumpless**: the loop engages with its command at the slide's measured
//! position and its estimator at rest there, then the command ramps to the
//! goal at the slew limit. Nothing jumps, wherever the slide was (in 1983
//! the slide had to be nulled by hand or the amplifier tripped).

/// Where the loop is in its engagement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Phase {
    /// Amplifier disabled, output zero.
    Disarmed,
    /// Open-loop doublet in progress (tick count within it).
    SignCheck,
    /// Loop closed, command ramping from where the slide was to the goal.
    Engaging,
    /// Loop closed on the goal; learning runs.
    Engaged,
    /// Loop closed, command ramping to null; then disarmed.
    Disarming,
}

/// What the sign check asks of the loop this tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SignStep {
    /// Drive this DAC code (open loop).
    Drive(i32),
    /// The check passed: engage now.
    Passed,
    /// The gauge moved this much (codes) where the model expected
    /// `expected` codes.
    Failed { moved: i32, expected: i32 },
}

/// The open-loop doublet and its verdict.
#[derive(Clone, Debug)]
pub struct SignCheck {
    pulse_code: i32,
    half_ticks: u32,
    expected_code: i32,
    tick: u32,
    y0_q8: i32,
    moved_q8: i32,
}

impl SignCheck {
    pub fn new(pulse_code: i32, half_ticks: u32, expected_code: i32) -> Self {
        Self {
            pulse_code,
            half_ticks: half_ticks.max(1),
            expected_code,
            tick: 0,
            y0_q8: 0,
            moved_q8: 0,
        }
    }

    /// Whether the check is configured (a zero pulse disables it).
    pub fn enabled(&self) -> bool {
        self.pulse_code != 0 && self.expected_code != 0
    }

    pub fn start(&mut self, y_q8: i32) {
        self.tick = 0;
        self.y0_q8 = y_q8;
        self.moved_q8 = 0;
    }

    /// One tick of the doublet with the gauge reading `y_q8` (Q8 codes,
    /// |y| < 2²⁸).
    #[inline]
    pub fn step(&mut self, y_q8: i32) -> SignStep {
        let t = self.tick;
        self.tick = t.saturating_add(1);
        if t == self.half_ticks {
            self.moved_q8 = y_q8.saturating_sub(self.y0_q8);
        }
        if t < self.half_ticks {
            SignStep::Drive(self.pulse_code)
        } else if t < 2 * self.half_ticks {
            SignStep::Drive(-self.pulse_code)
        } else {
            let moved = self.moved_q8 >> 8;
            let e = i64::from(self.expected_code);
            let m = i64::from(moved);
            // Same sign and within ×3 of the model either way.
            let ok = e != 0
                && m.signum() == e.signum()
                && 3 * m.abs() >= e.abs()
                && m.abs() <= 3 * e.abs();
            if ok {
                SignStep::Passed
            } else {
                SignStep::Failed {
                    moved,
                    expected: self.expected_code,
                }
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::*;

    fn run(check: &mut SignCheck, response: impl Fn(i32) -> i32) -> SignStep {
        check.start(0);
        let mut y = 0i32;
        let mut last = 0;
        for _ in 0..1000 {
            match check.step(y) {
                SignStep::Drive(u) => {
                    y += response(u);
                    last = u;
                }
                done => return done,
            }
        }
        let _ = last;
        panic!("the check never ended");
    }

    #[test]
    fn a_slide_that_moves_as_modelled_passes() {
        let mut c = SignCheck::new(1000, 10, 500);
        assert_eq!(run(&mut c, |u| u << 4), SignStep::Passed);
    }

    #[test]
    fn a_reversed_gauge_fails_with_the_measured_move() {
        let mut c = SignCheck::new(1000, 10, 500);
        let r = run(&mut c, |u| -(u << 4));
        assert!(
            matches!(r, SignStep::Failed { moved, expected: 500 } if moved < 0),
            "{r:?}"
        );
    }

    #[test]
    fn a_dead_amplifier_fails() {
        let mut c = SignCheck::new(1000, 10, 500);
        assert!(matches!(
            run(&mut c, |_| 0),
            SignStep::Failed { moved: 0, .. }
        ));
    }
}
