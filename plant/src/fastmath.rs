//! Bit-exact replacements for std float functions that are slow on the
//! baseline x86-64 target (no SSE4.1 `roundsd`, so `f64::round` is a
//! software routine of ≈ 40 instructions on the per-tick path).

/// `x.round() as i64` (half away from zero, saturating, NaN → 0), bit for
/// bit, with a hardware truncation in the common case.
#[inline]
pub fn round_i64(x: f64) -> i64 {
    // Below 2^52 the fraction `x - trunc(x)` is exact, so comparing it with
    // ±0.5 decides the rounding exactly as `f64::round` does.
    if x.abs() < 4_503_599_627_370_496.0 {
        let t = x as i64;
        let r = x - t as f64;
        if r >= 0.5 {
            t + 1
        } else if r <= -0.5 {
            t - 1
        } else {
            t
        }
    } else {
        num_traits::Float::round(x) as i64
    }
}

/// `x.round() as i32` (saturating, NaN → 0), bit for bit.
#[inline]
pub fn round_i32(x: f64) -> i32 {
    round_i64(x).clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

/// `x.clamp(-limit, limit)` for a `limit` read from parameters, without
/// `f64::clamp`'s panic on an inverted range (`limit` < 0 gives `limit`'s
/// side, NaN stays NaN): the QEMU image steps the plant in an interrupt
/// handler, where no panic path may be reachable (`cargo xtask no-panic`).
#[inline]
pub fn clamp_symmetric(x: f64, limit: f64) -> f64 {
    // `f64::clamp`'s own body, without its assertion.
    let mut x = x;
    if x < -limit {
        x = -limit;
    }
    if x > limit {
        x = limit;
    }
    x
}

#[cfg(test)]
mod tests;
