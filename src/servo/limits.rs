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
    near_q8: u32,
    /// v_max², Q32.
    v_max_sq: u64,
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
            near_q8: ((2 * a_max_q16).min(v_max_q16) >> 8) as u32,
            v_max_sq: u64::from(v_max_q16.unsigned_abs()) * u64::from(v_max_q16.unsigned_abs()),
            v_q16: 0,
        }
    }

    /// One tick of the command at `offset_q8` from its goal: the new offset
    /// and the command's velocity and acceleration relative to the goal (Q16
    /// per tick, per tick²). It arrives on the goal (offset 0) without
    /// overshooting, landing from at most 2a.
    #[inline]
    pub fn step(&mut self, offset_q8: i32) -> (i32, i32, i32) {
        let offset_q8 = offset_q8.clamp(-(1 << 29) + 1, (1 << 29) - 1);
        let v0 = self.v_q16;
        if offset_q8 == 0 {
            // On the goal (the steady state of every tick while tracking):
            // the arrival below, without the root it would not use.
            self.v_q16 = 0;
            return (0, 0, -v0);
        }
        // Everything in the direction toward the goal: the distance to go
        // (Q8, < 2²⁹) and the speed toward it (|v₀| ≤ v_max ≤ 2³⁰).
        let up_goal = offset_q8 < 0;
        let dist = offset_q8.unsigned_abs();
        let a = self.a_max_q16;
        let u0 = if up_goal { v0 } else { -v0 };
        let (down, up) = (u0 - a, u0 + a);
        // The speed steps from u₀ toward the braking speed S = min(v_max,
        // √(2·a·|d|)) by at most a: u = clamp(S, u₀ − a, u₀ + a).
        let u = if dist <= self.near_q8 {
            // Near the goal (while tracking, the goal's moves differ from
            // its velocity by a fraction of a code each tick): S ≥ |d|, so
            // either u₀ + a reaches the goal (arrival below) or u₀ + a < |d|
            // ≤ S and the step is u₀ + a: no root.
            up
        } else {
            // 2·a·|d| in Q32 (a Q16, |d| Q8·2⁸): below 2⁶⁴. The squares
            // decide without the root where S ≥ u₀ + a (accelerating, or at
            // the rate limit), where the root's truncation could put it
            // below u₀ + a or v_max.
            let x = 2 * u64::from(a.unsigned_abs()) * (u64::from(dist) << 8);
            let sq = |v: i32| u64::from(v.unsigned_abs()) * u64::from(v.unsigned_abs());
            let s = if self.v_max_sq <= x {
                self.v_max_q16
            } else if up <= 0 || sq(up) <= x {
                up
            } else {
                // Braking on the curve, or beyond it at the limit (S ≤ u₀ −
                // a: the clamp below gives u₀ − a, as the root is no more
                // than S). No test for the latter: it would lengthen the
                // root's path, the tick's longest, by its own cost.
                sqrt_u64(x) as i32
            };
            s.max(down).min(up)
        };
        // u ≥ |d|·2⁸ exactly when ⌊u/2⁸⌋ ≥ |d|.
        if u > 0 && (u >> 8).unsigned_abs() >= dist {
            // Arrives this tick (from at most about 2a): stop on the goal.
            self.v_q16 = 0;
            let v = -(offset_q8 << 8);
            return (0, v, v - v0);
        }
        let v = if up_goal { u } else { -u };
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

/// Seeds of [`sqrt_u64`]: √((i + ½)·2²⁶), the root at the middle of the
/// bucket of an argument normalised to [2²⁹, 2³¹) by its top five bits
/// (buckets 8..32 occur): within 3.1 % of the root.
const ROOT_SEEDS: [u16; 32] = {
    let mut t = [0u16; 32];
    let mut i = 0;
    while i < 32 {
        t[i] = ((2 * i as u64 + 1) << 25).isqrt() as u16;
        i += 1;
    }
    t
};

/// √x for the braking speed: ⌊√x⌋ exactly for x < 2³¹, else the floor root
/// of x with its low bits dropped to 31 significant bits (an even shift
/// 2k), times 2ᵏ: below the true root by less than 2ᵏ⁺¹, a relative 2⁻¹⁴
/// at most (the braking curve is followed that much below its limit).
/// Two Newton steps on hardware division from a tabled seed (3.1 %: the
/// error after them is 10⁻⁷ of the root), which land on the floor root or
/// one above it for every 31-bit argument (checked exhaustively; the test
/// checks a sample), then at most one decrement. Its cost does not depend
/// on where the slew profile is, as a seed from the speed did (two to five
/// rounds). Integer only, no panic path.
#[inline]
pub fn sqrt_u64(x: u64) -> u64 {
    let bits = 64 - x.leading_zeros();
    let k = bits.saturating_sub(30) / 2;
    let xs = (x >> (2 * k)) as u32;
    let mut g = root_or_above(xs);
    // g ≥ ⌊√xs⌋: down to it (once at most, see above; g = 0 ends it).
    while u64::from(g) * u64::from(g) > u64::from(xs) {
        g -= 1;
    }
    u64::from(g) << k
}

/// The two Newton steps of [`sqrt_u64`] for xs < 2³¹: ⌊√xs⌋ or one more.
#[inline(always)]
fn root_or_above(xs: u32) -> u32 {
    // xs·2²ʲ lies in [2²⁹, 2³¹) (xs ≠ 0): its top five bits pick the seed,
    // scaled back by 2ʲ (at least 1 for xs ≠ 0; 0 for xs = 0). j = 0 for
    // every x ≥ 2²⁹: no shift to find for the braking speed's argument at
    // the default design's limits (beyond the near window it exceeds 2³⁶).
    let seed = if xs >> 29 != 0 {
        u32::from(ROOT_SEEDS[(xs >> 26) as usize & 31])
    } else {
        let j = xs.leading_zeros().saturating_sub(1) / 2;
        u32::from(ROOT_SEEDS[((xs << (2 * j)) >> 26) as usize & 31]) >> j
    };
    // xs < 2³¹ and g < 2³¹: g + xs/g never overflows. Each step from any
    // g ≥ 1 lands at or above the floor root (the arithmetic-geometric
    // mean).
    let step = |g: u32| match core::num::NonZeroU32::new(g) {
        Some(nz) => (g + xs / nz) >> 1,
        None => 0,
    };
    step(step(seed))
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

    /// ⌊√x⌋ at every perfect square below 2³¹ and its neighbours.
    #[test]
    fn sqrt_is_the_floor_root_at_every_square() {
        for r in 0..46_341u64 {
            for x in [r * r, (r * r).saturating_sub(1), r * r + 1] {
                let got = sqrt_u64(x);
                assert!(got * got <= x && (got + 1) * (got + 1) > x, "{x}: {got}");
            }
        }
    }

    proptest::proptest! {
        /// ⌊√x⌋ below 2³¹, and within the stated bound below the true root
        /// at any magnitude.
        #[test]
        fn sqrt_is_the_floor_root_or_within_its_bound(x in proptest::num::u64::ANY, shift in 0u32..64) {
            let x = x >> shift;
            let r = u128::from(sqrt_u64(x));
            let xx = u128::from(x);
            proptest::prop_assert!(r * r <= xx);
            let k = (64 - x.leading_zeros()).saturating_sub(30) / 2;
            let slack = 2u128 << k;
            proptest::prop_assert!((r + slack) * (r + slack) > xx, "{x}: {r}");
            if x >> 31 == 0 {
                proptest::prop_assert!((r + 1) * (r + 1) > xx);
            }
        }
    }

    /// The two Newton steps from the tabled seed end on the floor root
    /// (core's `isqrt`) or one above it: every argument below 2¹⁸, every
    /// seed bucket's edges at every normalising shift, and a stride through
    /// the 31-bit range. (All 2³¹ arguments were checked once the same
    /// way: 97 049 end one above, none further.)
    #[test]
    fn two_newton_steps_from_the_seed_end_at_most_one_above_the_root() {
        let check = |xs: u32| {
            let (g, r) = (root_or_above(xs), xs.isqrt());
            assert!(g == r || g == r + 1, "{xs}: {g} against {r}");
        };
        (0..1 << 18).for_each(check);
        for j in 0..15u32 {
            for i in 8..32u32 {
                let edge = (i << 26) >> (2 * j);
                [edge.saturating_sub(1), edge, edge + 1]
                    .into_iter()
                    .for_each(check);
            }
        }
        (0..1u32 << 31).step_by(4_093).for_each(check);
        check((1 << 31) - 1);
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

    /// Beyond the near region, the step against the braking formula with
    /// the exact root: the same, or (where the root drops bits, x ≥ 2³¹)
    /// at most the root's stated shortfall below it; never beyond the
    /// acceleration limit.
    #[test]
    fn slew_step_follows_the_braking_speed() {
        let (vm, am) = (42_949_672i32, 171_798i32);
        for d in (1..2_000_000i32).step_by(9_973).flat_map(|d| [d, -d]) {
            for v0 in (-vm..=vm).step_by(2_147_483).chain([0, am, -am]) {
                let mut p = SlewProfile::new(vm.into(), am.into());
                p.set_velocity(v0);
                let (_, v, acc) = p.step(-d);
                let x = 2 * u64::from(am.unsigned_abs()) * (u64::from(d.unsigned_abs()) << 8);
                let s = isqrt_slow(x).min(vm as u64) as i32;
                let want = step_toward(v0, if d > 0 { s } else { -s }, am);
                let k = (64 - x.leading_zeros()).saturating_sub(30) / 2;
                let arrived = v == d << 8;
                if !arrived {
                    assert!((v - want).abs() < 2 << k, "d {d} v0 {v0}: {v} vs {want}");
                    assert!(acc.abs() <= am, "d {d} v0 {v0}");
                }
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

    /// A command exactly on the window's edge is inside the limit (the
    /// estimated current equals the configured one): it passes unchanged,
    /// is not reported limited and never becomes a fault, however long it
    /// is held; one code beyond the edge is limited.
    #[test]
    fn a_command_on_the_current_window_edge_is_not_limited() {
        let mut c = CurrentLimit::new(1000, 0, 2);
        for _ in 0..10 {
            assert_eq!(c.apply(1000, 0), (1000, false, None));
            assert_eq!(c.apply(-1000, 0), (-1000, false, None));
        }
        assert_eq!(c.apply(1001, 0), (1000, true, None));
        assert_eq!(c.apply(-1001, 0), (-1000, true, None));
    }

    /// `reset` (engagement, a cleared fault) starts the persistence count
    /// again: after it the limit may be held `ticks_allowed` ticks more.
    #[test]
    fn current_limit_reset_restarts_the_persistence_count() {
        let mut c = CurrentLimit::new(1000, 0, 3);
        for _ in 0..3 {
            assert_eq!(c.apply(5000, 0).2, None);
        }
        c.reset();
        for _ in 0..3 {
            assert_eq!(c.apply(5000, 0).2, None, "3 ticks after the reset");
        }
        assert_eq!(c.apply(5000, 0).2, Some(Fault::CurrentLimit));
    }

    /// An error of exactly the limit is not beyond it: no fault however
    /// long it lasts; one Q8 step more is.
    #[test]
    fn a_following_error_of_exactly_the_limit_is_not_a_fault() {
        let mut f = FollowingError::new(100, 2);
        for _ in 0..10 {
            assert_eq!(f.check(100 << 8), None);
            assert_eq!(f.check(-(100 << 8)), None);
        }
        for _ in 0..2 {
            assert_eq!(f.check((100 << 8) + 1), None);
        }
        assert_eq!(f.check((100 << 8) + 1), Some(Fault::FollowingError));
    }

    /// `reset` starts the persistence count again.
    #[test]
    fn following_error_reset_restarts_the_persistence_count() {
        let mut f = FollowingError::new(100, 2);
        let big = 200i32 << 8;
        assert_eq!(f.check(big), None);
        assert_eq!(f.check(big), None);
        f.reset();
        assert_eq!(f.check(big), None, "1 tick after the reset");
        assert_eq!(f.check(big), None, "2 ticks after the reset");
        assert_eq!(f.check(big), Some(Fault::FollowingError));
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
