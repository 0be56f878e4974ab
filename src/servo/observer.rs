//! Position, velocity and disturbance of the slide, estimated from the
//! gauge and from what the loop told the amplifier.
//!
//! The model is the rigid slide of chapter 4 (eq 4-33 with the electrical
//! pole neglected) plus a constant input disturbance `d`, in the loop's own
//! units: positions in gauge codes, the input in amplifier-DAC codes (both
//! scales are 2¹⁹ codes per 10 V, so P(s) = K / (s (s + a)) is in codes per
//! code), sampled exactly (zero-order hold) at the loop period h:
//!
//! ```text
//! z⁺ = z + (1 − c1)·v + b1·(u + d)        v: codes per tick
//! v⁺ = (1 − c2)·v     + b2·(u + d)        c1 = 1 − (1 − e^{−ah})/(ah), c2 = 1 − e^{−ah}
//! d⁺ = d                                  b1 = K(h/a − (1 − e^{−ah})/a²), b2 = K h (1 − e^{−ah})/a
//! ```
//!
//! It runs as a *current* estimator: each tick predicts from the last
//! estimate and the DAC code actually written (after every limit, so the
//! disturbance state cannot wind up while the output is saturated: it
//! integrates the gauge's disagreement with the model, not the loop's
//! wishes), then corrects with the innovation `y − ẑ⁻` through the gains
//! `l1..l3` (pole placement, [`super::design`]). The velocity estimate is
//! therefore never a difference of raw gauge samples: at low frequency it
//! is the model's, and gauge noise enters only through `l2`, whose noise
//! gain the design reports. `d` is the loop's integral action (it absorbs
//! cutting force, amplifier offset and model error), in DAC codes.
//!
//! Two sets of gains: slow poles (40 Hz by default) while the innovation is
//! within a few gauge-noise σ, so that gauge noise barely reaches the
//! slide, and fast poles (400 Hz) for a hold time after the innovation
//! exceeds the switch level, so that a sudden force (the tool leaving a
//! bolt hole) is estimated and cancelled within a millisecond or two, not
//! tens. With gauge noise alone the switch level is a > 5σ event.
//!
//! # Number formats
//! States are `i32`: position Q8 (gauge codes·2⁸, |ẑ| < 2²⁹), velocity Q16
//! (codes per tick·2¹⁶, |v̂| < 2³⁰: 16 384 codes per tick, 6 in/s),
//! disturbance Q8 (DAC codes·2⁸, |d̂| < 2²⁸: two full DAC scales).
//! Coefficients are `i32` Q30, except the disturbance gains `l3`, Q24
//! (|l3| < 128). Each product is one 32×32 → 64-bit multiply of bounded
//! operands (innovation < 2²⁸, `u + d` < 2²⁹), rounded once to the state's
//! format; the model's own coefficients `1 − c1`, `1 − c2` lie in (0, 1)
//! (a > 0, h > 0), so the predictions cannot overflow, and every state is
//! saturated to its bound (one `SSAT` each).

use super::fixed::{mul_shr, qadd_mul, ssat};

/// Observer coefficients, `Q2.30` bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct ObserverCoeffs {
    pub c1: i32,
    pub c2: i32,
    pub b1: i32,
    pub b2: i32,
    pub l1: i32,
    pub l2: i32,
    pub l3: i32,
    /// Gains of the fast observer, used while the innovation is large.
    pub fast: [i32; 3],
    /// |innovation| beyond which the fast gains take over, codes Q8.
    pub switch_q8: i32,
    /// Ticks the fast gains stay after the innovation was last large.
    pub hold_ticks: u32,
}

/// The estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Estimate {
    /// Position, gauge codes Q8.
    pub z_q8: i32,
    /// Velocity, gauge codes per tick Q16.
    pub v_q16: i32,
    /// Input disturbance, DAC codes Q8 (the DAC code that would cancel
    /// it is `−d`).
    pub d_q8: i32,
}

/// The estimator with its state.
#[derive(Clone, Debug)]
pub struct Observer {
    k: ObserverCoeffs,
    /// `1 − c1`, `1 − c2` (Q30): the model's own velocity terms.
    a12: i32,
    a22: i32,
    /// |innovation| (Q8) beyond which the fast gains take over.
    switch: u32,
    x: Estimate,
    /// Ticks left on the fast gains.
    fast_left: u32,
}

impl Observer {
    pub fn new(k: ObserverCoeffs) -> Self {
        Self {
            a12: (1i32 << 30).saturating_sub(k.c1),
            a22: (1i32 << 30).saturating_sub(k.c2),
            switch: k.switch_q8.unsigned_abs(),
            k,
            x: Estimate::default(),
            fast_left: 0,
        }
    }

    /// Starts from rest at `y_q8` with no disturbance (engagement).
    pub fn reset(&mut self, y_q8: i32) {
        self.x = Estimate {
            z_q8: ssat::<30>(y_q8),
            v_q16: 0,
            d_q8: 0,
        };
    }

    /// One tick: `u_prev_q8` is the DAC code written on the previous tick
    /// (Q8), `y_q8` the gauge now (Q8, |y| < 2²⁸).
    #[inline(always)]
    pub fn update(&mut self, u_prev_q8: i32, y_q8: i32) -> Estimate {
        let k = &self.k;
        let x = &mut self.x;
        let v = x.v_q16;
        let w = ssat::<29>(u_prev_q8.saturating_add(x.d_q8));
        // |a12·v|/2³⁸ < 2²², |b1·w|/2³⁰ < 2²⁹, |ẑ| < 2²⁹: no overflow.
        let z_pred = x.z_q8 + mul_shr::<38>(self.a12, v) as i32 + mul_shr::<30>(k.b1, w) as i32;
        // |a22·v|/2³⁰ < 2³⁰; the input's term saturates at 2³⁰.
        let v_pred = qadd_mul::<22>(mul_shr::<30>(self.a22, v) as i32, k.b2, w);
        let innovation = ssat::<29>(y_q8.saturating_sub(z_pred));
        if innovation.unsigned_abs() > self.switch {
            self.fast_left = k.hold_ticks;
        }
        let (l1, l2, l3) = if self.fast_left > 0 {
            self.fast_left -= 1;
            (k.fast[0], k.fast[1], k.fast[2])
        } else {
            (k.l1, k.l2, k.l3)
        };
        // |l1·innovation|/2³⁰ < 2²⁹, |z_pred| < 2³⁰·¹: no overflow.
        x.z_q8 = ssat::<30>(z_pred + mul_shr::<30>(l1, innovation) as i32);
        x.v_q16 = ssat::<31>(qadd_mul::<22>(v_pred, l2, innovation));
        x.d_q8 = ssat::<29>(qadd_mul::<24>(x.d_q8, l3, innovation));
        *x
    }

    pub fn estimate(&self) -> Estimate {
        self.x
    }

    /// Moves the disturbance state by a change known to happen now (the
    /// hole edges' feedforward, `super::edges`): the model then predicts
    /// it, so it raises no innovation, and the control law's −d̂ cancels
    /// it at once.
    #[inline(always)]
    pub fn shift_disturbance(&mut self, delta_q8: i32) -> Estimate {
        self.x.d_q8 = ssat::<29>(self.x.d_q8.saturating_add(delta_q8));
        self.x
    }

    /// Whether the fast gains are in use.
    pub fn fast(&self) -> bool {
        self.fast_left > 0
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::servo::ServoDesign;

    /// The design's observer on the exact sampled rigid plant it models
    /// (f64, zero-order hold, a constant input disturbance, a 20 Hz input),
    /// started at rest with no disturbance known: after 40 ms (ten time
    /// constants of its 250 Hz triple pole, whose error then is
    /// e^{−x}(1 + x + x²/2) ≈ 10⁻⁴ of the start, x = 2π·250·0.04) its
    /// position is within a code, its velocity within 0.1 % of the
    /// velocity's swing, and its disturbance within 0.1 % of the true one.
    #[test]
    fn the_estimate_converges_to_the_sampled_plant_it_models() {
        let d = ServoDesign::brief(20_000);
        let cfg = d.config().unwrap();
        let mut o = Observer::new(cfg.observer);
        let (k, a) = (d.slide.gain_per_s2(), d.slide.pole_per_s());
        let h = 1.0 / f64::from(d.rate_hz);
        let e = libm::exp(-a * h);
        let (b1, b2) = (k * (h / a - (1.0 - e) / (a * a)), k * (1.0 - e) / a);
        let dist = 2000.0;
        let (mut z, mut v) = (1000.0, 0.0);
        o.reset((z * 256.0) as i32);
        let mut u_prev = 0i32;
        let mut vmax = 0.0f64;
        for n in 0..800 {
            let u = libm::round(5000.0 * libm::sin(core::f64::consts::TAU * 20.0 * n as f64 * h));
            // The plant over the last tick, driven by what was written.
            let w = f64::from(u_prev) + dist;
            let z1 = z + (1.0 - e) / a * v + b1 * w;
            v = e * v + b2 * w;
            z = z1;
            vmax = vmax.max(v.abs());
            let est = o.update(u_prev << 8, libm::round(z * 256.0) as i32);
            u_prev = u as i32;
            if n >= 800 - 1 {
                let z_hat = f64::from(est.z_q8) / 256.0;
                let v_hat = f64::from(est.v_q16) / 65_536.0 / h;
                let d_hat = f64::from(est.d_q8) / 256.0;
                assert!((z_hat - z).abs() < 1.0, "z {z_hat} vs {z}");
                assert!(
                    (v_hat - v).abs() < 1e-3 * vmax,
                    "v {v_hat} vs {v} (swing {vmax})"
                );
                assert!((d_hat - dist).abs() < 1e-3 * dist, "d {d_hat} vs {dist}");
            }
        }
    }

    /// The fast gains take over exactly when |innovation| exceeds the
    /// switch level (an innovation equal to it does not), and stay for
    /// `hold_ticks` updates, the one that saw it included.
    #[test]
    fn the_fast_gains_hold_for_their_ticks_after_an_innovation_beyond_the_switch() {
        let cfg = ServoDesign::brief(20_000).config().unwrap();
        let k = cfg.observer;
        assert!(k.hold_ticks > 2 && k.switch_q8 > 0);
        for (step, fast) in [(k.switch_q8, false), (k.switch_q8 + 1, true)] {
            let mut o = Observer::new(k);
            o.reset(0);
            // At rest with no input the prediction is 0: the innovation
            // is the reading itself.
            o.update(0, step);
            assert_eq!(o.fast(), fast, "innovation {step} (switch {})", k.switch_q8);
            if fast {
                let mut on = 1;
                while o.fast() {
                    let y = o.estimate().z_q8;
                    o.update(0, y);
                    on += 1;
                    assert!(on <= k.hold_ticks, "still fast after {on} ticks");
                }
                assert_eq!(on, k.hold_ticks);
            }
        }
    }
}
