//! Bit-exact replacements for std float functions that are slow on the
//! baseline x86-64 target (no SSE4.1 `roundsd`, so `f64::round` is a
//! software routine of ≈ 40 instructions on the per-tick path). The
//! rounding ones live with the plant model, whose gauge ADC quantisation
//! uses them too.
pub use zslide_plant::fastmath::{round_i32, round_i64};

/// `x.floor() as i64` (saturating, NaN → 0), bit for bit: `floor` is a
/// software routine on the baseline target too.
#[inline]
pub fn floor_i64(x: f64) -> i64 {
    if x.abs() < 4_503_599_627_370_496.0 {
        let t = x as i64;
        if (t as f64) > x {
            t - 1
        } else {
            t
        }
    } else {
        x.floor() as i64
    }
}

/// `x.rem_euclid(1.0)`, bit for bit (the sign of a zero included), without
/// the software `fmod` the std form calls: below 2⁵² the fraction
/// `x − trunc(x)` is exact and is what `fmod(x, 1)` returns, with `x`'s sign.
#[inline]
pub fn frac(x: f64) -> f64 {
    if x.abs() < 4_503_599_627_370_496.0 {
        let r = (x - (x as i64) as f64).copysign(x);
        if r < 0.0 {
            r + 1.0
        } else {
            r
        }
    } else {
        x.rem_euclid(1.0)
    }
}

/// sin(ω·t) at sample instants, by rotating a phasor when the spacing
/// repeats (no `sin` per sample), recomputed exactly every
/// [`Phasor::EXACT_EVERY`] samples and on any change of spacing, so the
/// rounding drift stays below 1e-12.
#[derive(Clone, Copy, Debug)]
pub struct Phasor {
    /// ω, rad/s.
    w: f64,
    /// (sin, cos) of ω·t at `t_ns`.
    sc: (f64, f64),
    t_ns: Option<u64>,
    /// (spacing ns, sin, cos) of the rotation.
    rot: (u64, f64, f64),
    n: u32,
}

impl Phasor {
    pub const EXACT_EVERY: u32 = 4096;

    pub fn new(w_rad_s: f64) -> Self {
        Self {
            w: w_rad_s,
            sc: (0.0, 1.0),
            t_ns: None,
            rot: (0, 0.0, 1.0),
            n: 0,
        }
    }

    /// sin(ω·t) at `t_ns` (non-decreasing).
    #[inline]
    pub fn sin_at(&mut self, t_ns: u64) -> f64 {
        let h = self.t_ns.map(|l| t_ns.saturating_sub(l));
        match h {
            Some(h) if h == self.rot.0 && self.n < Self::EXACT_EVERY => {
                let (s0, c0) = self.sc;
                let (_, rs, rc) = self.rot;
                self.sc = (s0 * rc + c0 * rs, c0 * rc - s0 * rs);
                self.n += 1;
            }
            _ => {
                self.sc = (self.w * (t_ns as f64 * 1e-9)).sin_cos();
                if let Some(h) = h {
                    if h != self.rot.0 {
                        let (rs, rc) = (self.w * h as f64 * 1e-9).sin_cos();
                        self.rot = (h, rs, rc);
                    }
                }
                self.n = 0;
            }
        }
        self.t_ns = Some(t_ns);
        self.sc.0
    }
}

#[cfg(test)]
mod tests;
