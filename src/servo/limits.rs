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

/// The command's approach to a goal it is not on (engagement, disarming, a
/// target step, a fault's ramp to null): velocity limited to the slew rate
/// and acceleration limited, braking in time to arrive at rest, so that
/// the feedforward of the ramp (its acceleration through the plant
/// inverse) stays bounded and the slide does not overshoot at the end of
/// a ramp. No division: the braking test is `v² ≥ 2·a·|d|`.
#[derive(Clone, Debug)]
pub struct SlewProfile {
    v_max_q16: i64,
    a_max_q16: i64,
    /// Velocity of the command, codes per tick Q16.
    v_q16: i64,
}

impl SlewProfile {
    pub fn new(v_max_q16: i64, a_max_q16: i64) -> Self {
        Self {
            v_max_q16: v_max_q16.clamp(1, 1 << 31),
            a_max_q16: a_max_q16.clamp(1, (1 << 26) - 1),
            v_q16: 0,
        }
    }

    /// One tick from `cmd` toward `goal` (Q16 codes): the new command and
    /// its velocity and acceleration (Q16 per tick, per tick²). The speed
    /// toward the goal never exceeds √(2·a·distance) (it can always stop
    /// in time), so it arrives on the goal without overshooting, landing
    /// from at most 2a.
    #[inline]
    pub fn step(&mut self, cmd: i64, goal: i64) -> (i64, i64, i64) {
        let d = goal - cmd;
        let v0 = self.v_q16;
        if d == 0 {
            // On the goal (the steady state of every tick while tracking):
            // the arrival below, without the root it would not use.
            self.v_q16 = 0;
            return (goal, 0, -v0);
        }
        let a = self.a_max_q16;
        // 2·a·|d| < 2⁶⁴: a < 2²⁶ (the design's bound) and |d| < 2³⁷ (twice
        // the gauge's span, Q16); beyond that the speed is the rate limit.
        let dist = d.unsigned_abs().min((1 << 37) - 1);
        let vmax = self.v_max_q16.unsigned_abs();
        let two_a_d = 2 * a.unsigned_abs() * dist;
        // Far from the goal the rate limit holds and no root is needed.
        let speed = if vmax.saturating_mul(vmax) <= two_a_d {
            vmax
        } else {
            isqrt_u64(two_a_d).min(vmax)
        } as i64;
        let target_v = if d > 0 { speed } else { -speed };
        let v = step_toward(v0, target_v, a);
        let toward = (v > 0) == (d > 0);
        if toward && v.abs() >= d.abs() {
            // Arrives this tick (from at most about 2a): stop on the goal.
            self.v_q16 = 0;
            return (goal, d, d - v0);
        }
        self.v_q16 = v;
        (cmd + v, v, v - v0)
    }

    /// Starts from rest (engagement).
    pub fn reset(&mut self) {
        self.v_q16 = 0;
    }

    /// Sets the velocity relative to the goal (the command's velocity minus
    /// the goal's), bounded by the rate limit.
    #[inline(always)]
    pub fn set_velocity(&mut self, v_q16: i64) {
        self.v_q16 = v_q16.max(-self.v_max_q16).min(self.v_max_q16);
    }
}

/// ⌊√x⌋, digit by digit: no division, at most 32 rounds (the handler has
/// no panic path and a bounded cost), starting at x's top digit pair so a
/// small distance (the command a few codes off its goal, the usual case
/// while tracking) costs a few rounds.
#[inline]
pub fn isqrt_u64(x: u64) -> u64 {
    if x == 0 {
        return 0;
    }
    let mut rem = x;
    let mut root: u64 = 0;
    // The highest power of four not above x.
    let mut bit: u64 = 1 << ((63 - x.leading_zeros()) & !1);
    while bit != 0 {
        if rem >= root + bit {
            rem -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    root
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

    #[test]
    fn isqrt_is_the_floor_square_root() {
        for x in [
            0u64,
            1,
            2,
            3,
            4,
            15,
            16,
            17,
            1 << 40,
            (1 << 62) + 12345,
            u64::MAX,
        ] {
            let r = u128::from(isqrt_u64(x));
            let x = u128::from(x);
            assert!(r * r <= x && (r + 1) * (r + 1) > x, "{x}: {r}");
        }
    }

    proptest::proptest! {
        /// ⌊√x⌋ over the whole u64 range (the top digit pair is found from
        /// the leading zeros; an off-by-one there shows at some magnitude).
        #[test]
        fn isqrt_is_the_floor_square_root_at_any_magnitude(x in proptest::num::u64::ANY, shift in 0u32..64) {
            let x = x >> shift;
            let r = u128::from(isqrt_u64(x));
            let x = u128::from(x);
            proptest::prop_assert!(r * r <= x && (r + 1) * (r + 1) > x);
        }
    }

    /// A 100 000-code move at ≤ 655 codes/tick and ≤ 3 codes/tick²
    /// (reaching 655 would take 143 000 codes, so the profile is a
    /// triangle), and a 400 000-code move (a trapezoid): the closed-form
    /// durations within the discrete braking's slack, arriving at rest on
    /// the goal, never exceeding either limit or overshooting.
    #[test]
    fn slew_profile_is_a_bounded_trapezoid_that_arrives_at_rest() {
        let (vm, am) = (655i64 << 16, 3i64 << 16);
        // Triangle: t = 2√(d/a) = 365; trapezoid: t = d/vm + vm/a = 829.
        for (d, expected) in [(100_000i64, 365.0), (400_000, 829.0)] {
            let mut p = SlewProfile::new(vm, am);
            let (mut cmd, goal) = (0i64, d << 16);
            let mut ticks = 0;
            let mut v_prev = 0;
            while cmd != goal {
                let (c, v, a) = p.step(cmd, goal);
                assert!(v.abs() <= vm && a.abs() <= vm.max(am));
                assert!((v - v_prev).abs() <= am || c == goal);
                assert!(c <= goal, "no overshoot");
                v_prev = v;
                cmd = c;
                ticks += 1;
                assert!(ticks < 10_000);
            }
            let t = f64::from(ticks);
            assert!(
                (t / expected - 1.0).abs() < 0.06,
                "{d}: {ticks} vs {expected}"
            );
        }
    }

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
