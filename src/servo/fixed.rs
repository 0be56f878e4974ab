//! The loop's 32-bit fixed-point primitives, each a few instructions on the
//! Cortex-M4 (the loop tick's budget is counted in instructions): rounded
//! products of two `i32` (one `SMULL`), saturation to a bit width (one
//! `SSAT`), a product added with saturation (on the M4 a compare of the
//! product's high word with its sign, then `QADD`, not a 64-bit clamp), and
//! saturation of a 64-bit value to `i32`.

/// `x` saturated to `BITS`-bit two's complement, `[−2^(BITS−1), 2^(BITS−1))`:
/// one `SSAT`.
#[inline(always)]
pub(crate) fn ssat<const BITS: u32>(x: i32) -> i32 {
    x.clamp(-(1 << (BITS - 1)), (1 << (BITS - 1)) - 1)
}

/// `c·x / 2^SHIFT`, rounded to nearest (ties up): one `SMULL`, the rounding
/// add and the shift.
#[inline(always)]
pub(crate) fn mul_shr<const SHIFT: u32>(c: i32, x: i32) -> i64 {
    (i64::from(c) * i64::from(x) + (1 << (SHIFT - 1))) >> SHIFT
}

/// The high word of `a·k`, rounded: one `SMMULR`.
#[inline(always)]
pub(crate) fn mul_hi(a: i32, k: i32) -> i32 {
    ((i64::from(a) * i64::from(k) + (1 << 31)) >> 32) as i32
}

/// `v` saturated to `i32`: on the M4 by comparing the high word with the
/// sign of the low word, on a 64-bit host by a clamp (tested equal).
#[inline(always)]
pub(crate) fn sat_i32(v: i64) -> i32 {
    #[cfg(target_arch = "arm")]
    {
        sat_i32_words(v)
    }
    #[cfg(not(target_arch = "arm"))]
    {
        v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
    }
}

/// [`sat_i32`] by words: `v` fits when its high word is the sign of its
/// low word.
#[inline(always)]
#[cfg_attr(all(not(target_arch = "arm"), not(test)), allow(dead_code))]
fn sat_i32_words(v: i64) -> i32 {
    let lo = v as i32;
    let hi = (v >> 32) as i32;
    if hi == lo >> 31 {
        lo
    } else {
        (hi >> 31) ^ i32::MAX
    }
}

/// `y + c·x / 2^SHIFT` (the product rounded to nearest and saturated to
/// ±2³⁰, the sum saturated to `i32`), for 2 ≤ SHIFT ≤ 33. The same
/// integer on every target; the instructions are each target's cheapest
/// (both forms are tested equal on the host): on the Cortex-M one
/// `SMLAL`, the shift, a compare of the product's high word with its sign
/// (does the shifted product fit 31 bits?) and one `QADD`, where a 64-bit
/// clamp would take two compare-and-select pairs on word halves; on a
/// 64-bit host the clamp itself.
#[inline(always)]
pub(crate) fn qadd_mul<const SHIFT: u32>(y: i32, c: i32, x: i32) -> i32 {
    #[cfg(target_arch = "arm")]
    {
        qadd_mul_words::<SHIFT>(y, c, x)
    }
    #[cfg(not(target_arch = "arm"))]
    {
        qadd_mul_clamp::<SHIFT>(y, c, x)
    }
}

/// [`qadd_mul`] by the high word of the product (32-bit targets).
#[inline(always)]
#[cfg_attr(all(not(target_arch = "arm"), not(test)), allow(dead_code))]
fn qadd_mul_words<const SHIFT: u32>(y: i32, c: i32, x: i32) -> i32 {
    const { assert!(SHIFT >= 2 && SHIFT <= 33) };
    let p = i64::from(c) * i64::from(x) + (1 << (SHIFT - 1));
    let hi = (p >> 32) as i32;
    // p >> SHIFT lies in [−2³⁰, 2³⁰) exactly when bits 63..SHIFT+30 of p
    // all equal its sign.
    let v = if hi >> (SHIFT - 2) == hi >> 31 {
        (p >> SHIFT) as i32
    } else {
        (hi >> 31) ^ ((1 << 30) - 1)
    };
    y.saturating_add(v)
}

/// [`qadd_mul`] by a 64-bit clamp (64-bit targets).
#[inline(always)]
#[cfg_attr(all(target_arch = "arm", not(test)), allow(dead_code))]
fn qadd_mul_clamp<const SHIFT: u32>(y: i32, c: i32, x: i32) -> i32 {
    const { assert!(SHIFT >= 2 && SHIFT <= 33) };
    let p = (i64::from(c) * i64::from(x) + (1 << (SHIFT - 1))) >> SHIFT;
    y.saturating_add(p.clamp(-(1 << 30), (1 << 30) - 1) as i32)
}

/// `x` (Q8) rounded to an integer (ties up).
#[inline(always)]
pub(crate) fn round_q8(x: i32) -> i32 {
    (x >> 8) + ((x >> 7) & 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_match_their_wide_definitions() {
        let edges = [
            i64::MIN,
            -(1 << 40),
            i64::from(i32::MIN) - 1,
            i64::from(i32::MIN),
            -1,
            0,
            1,
            i64::from(i32::MAX),
            i64::from(i32::MAX) + 1,
            1 << 40,
            i64::MAX,
        ];
        for v in edges {
            let want = v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
            assert_eq!(sat_i32(v), want, "{v}");
            assert_eq!(sat_i32_words(v), want, "{v}");
        }
        for x in [
            i32::MIN,
            -(1 << 20) - 1,
            -129,
            -128,
            -127,
            -1,
            0,
            1,
            127,
            128,
            1 << 20,
            i32::MAX,
        ] {
            assert_eq!(ssat::<21>(x), x.clamp(-(1 << 20), (1 << 20) - 1));
            let exact = f64::from(x) / 256.0;
            assert_eq!(round_q8(x), libm::floor(exact + 0.5) as i32, "{x}");
            for k in [i32::MIN, -3, 3, 1 << 30, i32::MAX] {
                let p = i128::from(x) * i128::from(k);
                assert_eq!(i128::from(mul_hi(x, k)), (p + (1 << 31)) >> 32);
                assert_eq!(i128::from(mul_shr::<24>(x, k)), (p + (1 << 23)) >> 24);
                for y in [i32::MIN, -1, 0, 1 << 29, i32::MAX] {
                    let want = |s: u32| {
                        let t = ((p + (1 << (s - 1))) >> s).clamp(-(1 << 30), (1 << 30) - 1);
                        (i128::from(y) + t).clamp(i128::from(i32::MIN), i128::from(i32::MAX))
                    };
                    for (w, c, s) in [
                        (
                            qadd_mul_words::<2>(y, x, k),
                            qadd_mul_clamp::<2>(y, x, k),
                            2,
                        ),
                        (
                            qadd_mul_words::<22>(y, x, k),
                            qadd_mul_clamp::<22>(y, x, k),
                            22,
                        ),
                        (
                            qadd_mul_words::<33>(y, x, k),
                            qadd_mul_clamp::<33>(y, x, k),
                            33,
                        ),
                    ] {
                        assert_eq!(i128::from(w), want(s));
                        assert_eq!(i128::from(c), want(s));
                    }
                }
            }
        }
    }

    proptest::proptest! {
        #[test]
        fn qadd_mul_is_the_saturated_sum(y in proptest::num::i32::ANY, c in proptest::num::i32::ANY, x in proptest::num::i32::ANY) {
            let p = i128::from(c) * i128::from(x);
            let both = |w: i32, k: i32| {
                assert_eq!(w, k, "the target forms differ");
                w
            };
            for (got, s) in [
                (both(qadd_mul_words::<22>(y, c, x), qadd_mul_clamp::<22>(y, c, x)), 22),
                (both(qadd_mul_words::<24>(y, c, x), qadd_mul_clamp::<24>(y, c, x)), 24),
                (both(qadd_mul_words::<30>(y, c, x), qadd_mul_clamp::<30>(y, c, x)), 30),
                (both(qadd_mul_words::<32>(y, c, x), qadd_mul_clamp::<32>(y, c, x)), 32),
            ] {
                let t = ((p + (1 << (s - 1))) >> s).clamp(-(1 << 30), (1 << 30) - 1);
                let want = (i128::from(y) + t).clamp(i128::from(i32::MIN), i128::from(i32::MAX));
                proptest::prop_assert_eq!(i128::from(got), want);
            }
        }

        #[test]
        fn sat_i32_is_the_clamp(v in proptest::num::i64::ANY, shift in 0u32..63) {
            let v = v >> shift;
            let want = v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
            proptest::prop_assert_eq!(sat_i32(v), want);
            proptest::prop_assert_eq!(sat_i32_words(v), want);
        }
    }
}
