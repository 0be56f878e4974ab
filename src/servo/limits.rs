//! Run-time limits of the loop: command slew and range, the estimated coil
//! current, and the following error.
//!
//! The board has no current sense. The coil current is estimated from the
//! amplifier command and the back-EMF of the observer's velocity:
//! `i ≈ (G·V_dac − Kb·v) / R` (the coil's L/R = 0.26 ms is neglected: the
//! estimate leads the true current by that much). The DAC code is limited
//! so that the estimate stays within the configured current, which keeps the
//! amplifier out of its own 8 A limit and trip; a limit held longer than
//! the configured time is a fault (something is pushing the slide that the
//! loop cannot hold).

use crate::safety::Fault;

/// Steps `from` toward `to` by at most `max_step` (> 0).
#[inline(always)]
pub const fn step_toward(from: i64, to: i64, max_step: i64) -> i64 {
    if to > from + max_step {
        from + max_step
    } else if to < from - max_step {
        from - max_step
    } else {
        to
    }
}

/// The current limit with its persistence counter.
#[derive(Clone, Debug)]
pub struct CurrentLimit {
    limit_code: i64,
    k_emf_q24: i64,
    ticks_allowed: u32,
    ticks_in_limit: u32,
}

impl CurrentLimit {
    pub fn new(limit_code: i32, k_emf_q24: i32, ticks_allowed: u32) -> Self {
        Self {
            limit_code: i64::from(limit_code.max(0)),
            k_emf_q24: i64::from(k_emf_q24),
            ticks_allowed,
            ticks_in_limit: 0,
        }
    }

    /// The DAC code `u` limited so that the estimated current at velocity
    /// `v_q16` (gauge codes per tick) stays within the limit; whether it
    /// was limited; a fault when the limit has been held too long.
    #[inline]
    pub fn apply(&mut self, u: i64, v_q16: i64) -> (i64, bool, Option<Fault>) {
        let v = v_q16.clamp(-(1 << 34), 1 << 34) >> 8;
        let emf = (self.k_emf_q24 * v) >> 32;
        let hi = emf + self.limit_code;
        let lo = emf - self.limit_code;
        let limited = u > hi || u < lo;
        let out = u.max(lo).min(hi);
        if limited {
            self.ticks_in_limit = self.ticks_in_limit.saturating_add(1);
        } else {
            self.ticks_in_limit = 0;
        }
        let fault = (self.ticks_in_limit > self.ticks_allowed).then_some(Fault::CurrentLimit);
        (out, limited, fault)
    }

    pub fn reset(&mut self) {
        self.ticks_in_limit = 0;
    }
}

/// Following-error monitor: |reference − position| beyond the limit for
/// longer than allowed.
#[derive(Clone, Debug)]
pub struct FollowingError {
    limit_q16: i64,
    ticks_allowed: u32,
    ticks_over: u32,
}

impl FollowingError {
    pub fn new(limit_code: i32, ticks_allowed: u32) -> Self {
        Self {
            limit_q16: i64::from(limit_code.max(1)) << 16,
            ticks_allowed,
            ticks_over: 0,
        }
    }

    #[inline]
    pub fn check(&mut self, error_q16: i64) -> Option<Fault> {
        if error_q16.abs() > self.limit_q16 {
            self.ticks_over = self.ticks_over.saturating_add(1);
        } else {
            self.ticks_over = 0;
        }
        (self.ticks_over > self.ticks_allowed).then_some(Fault::FollowingError)
    }

    pub fn reset(&mut self) {
        self.ticks_over = 0;
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::*;

    /// At rest the limit is the configured code either way; moving at v the
    /// window shifts by the back-EMF k·v (a slide running forward may be
    /// driven harder forward before the coil current reaches the limit).
    #[test]
    fn current_window_follows_back_emf() {
        let mut c = CurrentLimit::new(44_040, 1 << 24, 100);
        assert_eq!(c.apply(50_000, 0).0, 44_040);
        assert_eq!(c.apply(-50_000, 0).0, -44_040);
        // v = 1000 codes/tick, k = 1: window [−43 040, 45 040]
        let v = 1000i64 << 16;
        assert_eq!(c.apply(50_000, v).0, 45_040);
        assert_eq!(c.apply(-50_000, v).0, -43_040);
    }

    #[test]
    fn current_limit_held_too_long_is_a_fault_and_a_brief_one_is_not() {
        let mut c = CurrentLimit::new(1000, 0, 3);
        for _ in 0..3 {
            assert_eq!(c.apply(5000, 0).2, None);
        }
        assert_eq!(c.apply(0, 0).2, None);
        for _ in 0..3 {
            assert_eq!(c.apply(5000, 0).2, None);
        }
        assert_eq!(c.apply(5000, 0).2, Some(Fault::CurrentLimit));
    }

    #[test]
    fn following_error_needs_persistence() {
        let mut f = FollowingError::new(100, 2);
        let big = 200i64 << 16;
        assert_eq!(f.check(big), None);
        assert_eq!(f.check(-big), None);
        assert_eq!(f.check(big), Some(Fault::FollowingError));
        f.reset();
        assert_eq!(f.check(50 << 16), None);
    }
}
