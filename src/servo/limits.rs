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
pub const fn step_toward(from: i32, to: i32, max_step: i32) -> i32 {
    if to > from.saturating_add(max_step) {
        from + max_step
    } else if to < from.saturating_sub(max_step) {
        from - max_step
    } else {
        to
    }
}

/// Largest slew rate, Q16 codes per tick (16 384 codes per tick, 6 in/s at
/// 20 kHz: far beyond the design's 10 in/s limit only at rates under
/// 12 kHz, where it then limits).
const V_MAX_LIMIT: i32 = 1 << 30;
/// Largest acceleration, Q16 codes per tick².
const A_MAX_LIMIT: i32 = (1 << 26) - 1;

/// The command's approach to a goal it is not on (engagement, disarming, a
/// target step, a fault's ramp to null): velocity limited to the slew rate
/// and acceleration limited, braking in time to arrive at rest on the
/// goal, so that the feedforward of the ramp (its acceleration through the
/// plant inverse) stays bounded and the slide does not overshoot at the
/// end of a ramp: the speed toward the goal never exceeds √(2·a·|d|).
///
/// Formats: the offset from the goal is Q8 codes (|offset| < 2²⁹),
/// velocities Q16 codes per tick and accelerations Q16 codes per tick²
/// (`i32`); the offset moves by the velocity rounded to Q8.
#[derive(Clone, Debug)]
pub struct SlewProfile {
    v_max_q16: i32,
    a_max_q16: i32,
    /// |offset| (Q8) within which the braking speed and the rate limit are
    /// both at least the distance: ⌊min(2a, v_max) / 2⁸⌋.
    near_q8: i32,
    /// Velocity of the command relative to the goal, Q16 codes per tick.
    v_q16: i32,
}

impl SlewProfile {
    pub fn new(v_max_q16: i64, a_max_q16: i64) -> Self {
        let v_max_q16 = v_max_q16.clamp(1, i64::from(V_MAX_LIMIT)) as i32;
        let a_max_q16 = a_max_q16.clamp(1, i64::from(A_MAX_LIMIT)) as i32;
        Self {
            v_max_q16,
            a_max_q16,
            near_q8: (2 * a_max_q16).min(v_max_q16) >> 8,
            v_q16: 0,
        }
    }

    /// One tick of the command at `offset_q8` from its goal: the new offset
    /// and the command's velocity and acceleration relative to the goal (Q16
    /// per tick, per tick²). It arrives on the goal (offset 0) without
    /// overshooting, landing from at most 2a.
    #[inline]
    pub fn step(&mut self, offset_q8: i32) -> (i32, i32, i32) {
        // The distance to go (toward the goal is the sign of `d`).
        let d = -offset_q8.clamp(-(1 << 29) + 1, (1 << 29) - 1);
        let v0 = self.v_q16;
        if d == 0 {
            // On the goal (the steady state of every tick while tracking):
            // the arrival below, without the root it would not use.
            self.v_q16 = 0;
            return (0, 0, -v0);
        }
        let a = self.a_max_q16;
        let dist_q8 = d.unsigned_abs();
        let v = if dist_q8 <= self.near_q8 as u32 {
            // Near the goal (while tracking, the goal's moves differ from
            // its velocity by a fraction of a code each tick): the braking
            // speed √(2·a·|d|) and the rate limit are both ≥ |d|, so with
            // u₀ the velocity toward the goal the step below arrives
            // exactly when u₀ + a ≥ |d| and otherwise gives u₀ + a: the
            // same result without the root. (|d|·2⁸ ≤ 2a < 2²⁷.)
            let u0 = if d > 0 { v0 } else { -v0 };
            let u = u0 + a;
            let dist_q16 = (dist_q8 << 8) as i32;
            if u >= dist_q16 {
                self.v_q16 = 0;
                return (0, d << 8, (d << 8) - v0);
            }
            if d > 0 {
                u
            } else {
                -u
            }
        } else {
            // 2·a·|d| in Q32 (a Q16, |d| Q8 · 2⁸): below 2⁶⁴ (a < 2²⁶,
            // |d| < 2²⁹).
            let two_a_d = 2 * u64::from(a.unsigned_abs()) * (u64::from(dist_q8) << 8);
            let vmax = u64::from(self.v_max_q16.unsigned_abs());
            // Far from the goal the rate limit holds and no root is needed.
            let speed = if vmax * vmax <= two_a_d {
                vmax
            } else {
                sqrt_u64(two_a_d).min(vmax)
            } as i32;
            step_toward(v0, if d > 0 { speed } else { -speed }, a)
        };
        let toward = (v > 0) == (d > 0);
        if toward && i64::from(v).abs() >= i64::from(d).abs() << 8 {
            // Arrives this tick (from at most about 2a): stop on the goal.
            self.v_q16 = 0;
            return (0, d << 8, (d << 8) - v0);
        }
        self.v_q16 = v;
        (offset_q8 + ((v + (1 << 7)) >> 8), v, v - v0)
    }

    /// Starts from rest (engagement).
    pub fn reset(&mut self) {
        self.v_q16 = 0;
    }

    /// Sets the velocity relative to the goal (the command's velocity minus
    /// the goal's), bounded by the rate limit.
    #[inline(always)]
    pub fn set_velocity(&mut self, v_q16: i32) {
        self.v_q16 = v_q16.max(-self.v_max_q16).min(self.v_max_q16);
    }
}

/// √x for the braking speed: ⌊√x⌋ exactly for x < 2³², else the root of x
/// with its low bits dropped to 32 significant bits (an even shift 2k),
/// times 2ᵏ: below the true root by less than 2ᵏ⁺¹, a relative 2⁻¹⁴ at
/// most (the braking curve is followed that much below its limit). Integer
/// only, no panic path, at most a handful of hardware divisions (Newton's
/// iteration from above, [`isqrt_u32`]).
#[inline]
pub fn sqrt_u64(x: u64) -> u64 {
    let bits = 64 - x.leading_zeros();
    let k = bits.saturating_sub(31) / 2;
    u64::from(isqrt_u32((x >> (2 * k)) as u32)) << k
}

/// ⌊√x⌋ by Newton's iteration `g ← (g + x/g)/2` from 2¹⁶ (above every
/// root of a u32): it decreases monotonically to ⌊√x⌋ and stops there
/// (the integer form of the iteration never undershoots the floor root).
/// Starting from above the root: at most 17 rounds, 8 for x ≥ 2¹⁶ (tested).
#[inline]
pub fn isqrt_u32(x: u32) -> u32 {
    if x == 0 {
        return 0;
    }
    // An upper bound from the bit length: 2^⌈bits/2⌉ > √x.
    let bits = 32 - x.leading_zeros();
    let mut g: u32 = 1 << bits.div_ceil(2);
    loop {
        let Some(nz) = core::num::NonZeroU32::new(g) else {
            return 0;
        };
        let y = (g + x / nz) >> 1;
        if y >= g {
            return g;
        }
        g = y;
    }
}

/// The current limit with its persistence counter.
#[derive(Clone, Debug)]
pub struct CurrentLimit {
    limit_code: i32,
    k_emf_q24: i32,
    ticks_allowed: u32,
    ticks_in_limit: u32,
}

impl CurrentLimit {
    pub fn new(limit_code: i32, k_emf_q24: i32, ticks_allowed: u32) -> Self {
        Self {
            // Below 2²⁴: the window stays inside i32 around any back-EMF.
            limit_code: limit_code.clamp(0, 1 << 24),
            k_emf_q24,
            ticks_allowed,
            ticks_in_limit: 0,
        }
    }

    /// The DAC code `u` limited so that the estimated current at velocity
    /// `v_q16` (gauge codes per tick Q16) stays within the limit; whether
    /// it was limited; a fault when the limit has been held too long.
    #[inline]
    pub fn apply(&mut self, u: i32, v_q16: i32) -> (i32, bool, Option<Fault>) {
        // Q24 × Q16 = Q40 → codes; |k·v| < 2⁶¹, so |emf| < 2²¹.
        let emf = ((i64::from(self.k_emf_q24) * i64::from(v_q16)) >> 40) as i32;
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
    limit_q8: u32,
    ticks_allowed: u32,
    ticks_over: u32,
}

impl FollowingError {
    pub fn new(limit_code: i32, ticks_allowed: u32) -> Self {
        Self {
            // The gauge's whole span at most (2²⁰ codes, Q8 < 2³²).
            limit_q8: (limit_code.clamp(1, 1 << 20) as u32) << 8,
            ticks_allowed,
            ticks_over: 0,
        }
    }

    /// One tick with the error `error_q8` (gauge codes Q8).
    #[inline]
    pub fn check(&mut self, error_q8: i32) -> Option<Fault> {
        if error_q8.unsigned_abs() > self.limit_q8 {
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

    /// The Newton rounds of [`isqrt_u32`] for x, counted the same way.
    fn rounds(x: u32) -> u32 {
        let bits = 32 - x.leading_zeros();
        let mut g: u64 = 1 << bits.div_ceil(2);
        let mut n = 0;
        loop {
            n += 1;
            let y = (g + u64::from(x) / g) >> 1;
            if y >= g {
                return n;
            }
            g = y;
        }
    }

    #[test]
    fn isqrt_u32_is_the_floor_square_root_in_few_rounds() {
        let edges = [0u32, 1, 2, 3, 4, 15, 16, 17, 65_535, 65_536, u32::MAX];
        let squares = (0..=65_535u32).flat_map(|r| [r * r, (r * r).wrapping_sub(1), r * r + 1]);
        let mut worst = 0;
        for x in edges.into_iter().chain(squares) {
            let r = u64::from(isqrt_u32(x));
            let xx = u64::from(x);
            assert!(r * r <= xx && (r + 1) * (r + 1) > xx, "{x}: {r}");
            if x > 0 {
                worst = worst.max(rounds(x));
            }
        }
        assert!(worst <= 8, "{worst} rounds");
    }

    proptest::proptest! {
        /// ⌊√x⌋ for every magnitude of a u32, and within the stated bound
        /// below the true root for a u64.
        #[test]
        fn sqrt_is_the_floor_root_or_within_its_bound(x in proptest::num::u64::ANY, shift in 0u32..64) {
            let x = x >> shift;
            let r = u128::from(sqrt_u64(x));
            let xx = u128::from(x);
            proptest::prop_assert!(r * r <= xx);
            let k = (64 - x.leading_zeros()).saturating_sub(31) / 2;
            let slack = 2u128 << k;
            proptest::prop_assert!((r + slack) * (r + slack) > xx, "{x}: {r}");
            if x >> 32 == 0 {
                proptest::prop_assert!((r + 1) * (r + 1) > xx);
            }
        }
    }

    /// The near-goal shortcut of [`SlewProfile::step`] gives what the
    /// general step (the braking speed from the exact root) gives, for
    /// offsets and velocities around the goal at the default design's
    /// limits.
    #[test]
    fn slew_near_goal_matches_the_general_step() {
        let (vm, am) = (42_949_672i32, 171_798i32);
        let near = (2 * am).min(vm) >> 8;
        for d in (-near..=near).step_by(7).chain([-1, 1, near, -near]) {
            for v0 in (-3 * am..=3 * am).step_by(1999) {
                let mut p = SlewProfile::new(vm.into(), am.into());
                p.set_velocity(v0);
                let got = p.step(-d);
                // The general step, written out.
                let dist = u64::from(d.unsigned_abs()) << 8;
                let s = isqrt_slow(2 * u64::from(am.unsigned_abs()) * dist).min(vm as u64) as i32;
                let v = step_toward(v0, if d > 0 { s } else { -s }, am);
                let want = if d == 0 {
                    (0, 0, -v0)
                } else if (v > 0) == (d > 0) && i64::from(v).abs() >= i64::from(d).abs() << 8 {
                    (0, d << 8, (d << 8) - v0)
                } else {
                    (-d + ((v + 128) >> 8), v, v - v0)
                };
                assert_eq!(got, want, "d {d} v0 {v0}");
            }
        }
    }

    fn isqrt_slow(x: u64) -> u64 {
        let mut r = (x as f64).sqrt() as u64;
        while r * r > x {
            r -= 1;
        }
        while (r + 1) * (r + 1) <= x {
            r += 1;
        }
        r
    }

    /// A 100 000-code move at ≤ 655 codes/tick and ≤ 3 codes/tick²
    /// (reaching 655 would take 143 000 codes, so the profile is a
    /// triangle), and a 400 000-code move (a trapezoid): the closed-form
    /// durations within the discrete braking's slack, arriving at rest on
    /// the goal, never exceeding either limit or overshooting.
    #[test]
    fn slew_profile_is_a_bounded_trapezoid_that_arrives_at_rest() {
        let (vm, am) = (655i32 << 16, 3i32 << 16);
        // Triangle: t = 2√(d/a) = 365; trapezoid: t = d/vm + vm/a = 829.
        for (d, expected) in [(100_000i32, 365.0), (400_000, 829.0)] {
            let mut p = SlewProfile::new(vm.into(), am.into());
            // The command starts d codes below its goal.
            let mut offset = -(d << 8);
            let mut ticks = 0;
            let mut v_prev = 0;
            while offset != 0 {
                let (o, v, a) = p.step(offset);
                assert!(v.abs() <= vm && a.abs() <= vm.max(am));
                assert!((v - v_prev).abs() <= am || o == 0);
                assert!(o <= 0, "no overshoot");
                v_prev = v;
                offset = o;
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
        let v = 1000i32 << 16;
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
        let big = 200i32 << 8;
        assert_eq!(f.check(big), None);
        assert_eq!(f.check(-big), None);
        assert_eq!(f.check(big), Some(Fault::FollowingError));
        f.reset();
        assert_eq!(f.check(50 << 8), None);
    }
}
