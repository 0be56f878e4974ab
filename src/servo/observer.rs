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
//! States are `i64` Q16 (position in gauge codes·2¹⁶, velocity in codes per
//! tick·2¹⁶, disturbance in DAC codes·2¹⁶); coefficients are `i32` Q30
//! (each |c| < 2), except the disturbance gains `l3`, Q24 (|l3| < 128). Inputs are bounded before the products (innovation to
//! ±2¹⁴ codes, velocity to ±2¹⁴ codes per tick, `u + d` to ±2²⁰ codes), so
//! every product is below 2⁶² and the sums cannot overflow.

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
    /// |innovation| beyond which the fast gains take over, codes Q16.
    pub switch_q16: i64,
    /// Ticks the fast gains stay after the innovation was last large.
    pub hold_ticks: u32,
}

/// The estimate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Estimate {
    /// Position, gauge codes Q16.
    pub z_q16: i64,
    /// Velocity, gauge codes per tick Q16.
    pub v_q16: i64,
    /// Input disturbance, DAC codes Q16 (the DAC code that would cancel
    /// it is `−d`).
    pub d_q16: i64,
}

/// The estimator with its state.
#[derive(Clone, Debug)]
pub struct Observer {
    k: ObserverCoeffs,
    x: Estimate,
    /// Ticks left on the fast gains.
    fast_left: u32,
}

const INNOVATION_LIMIT: i64 = 1 << 30;
const VELOCITY_LIMIT: i64 = 1 << 30;
const INPUT_LIMIT: i64 = 1 << 36;
/// |d| stays within two full DAC scales.
const DISTURBANCE_LIMIT: i64 = 1 << 36;

#[inline(always)]
fn mul_q30(c: i32, x: i64) -> i64 {
    (i64::from(c) * x + (1 << 29)) >> 30
}

/// The disturbance gain is larger (DAC codes per gauge code: up to ~100
/// for fast poles), so it is Q24; the innovation is bounded to 2³⁰ so the
/// product stays below 2⁶¹.
#[inline(always)]
fn mul_q24(c: i32, x: i64) -> i64 {
    (i64::from(c) * x + (1 << 23)) >> 24
}

impl Observer {
    pub fn new(k: ObserverCoeffs) -> Self {
        Self {
            k,
            x: Estimate::default(),
            fast_left: 0,
        }
    }

    /// Starts from rest at `y_q16` with no disturbance (engagement).
    pub fn reset(&mut self, y_q16: i64) {
        self.x = Estimate {
            z_q16: y_q16,
            v_q16: 0,
            d_q16: 0,
        };
    }

    /// One tick: `u_prev` is the DAC code written on the previous tick
    /// (Q16), `y_q16` the gauge (after the hum notch) now.
    #[inline]
    pub fn update(&mut self, u_prev_q16: i64, y_q16: i64) -> Estimate {
        let k = &self.k;
        let x = &mut self.x;
        let v = x.v_q16.clamp(-VELOCITY_LIMIT, VELOCITY_LIMIT);
        let w = (u_prev_q16 + x.d_q16).clamp(-INPUT_LIMIT, INPUT_LIMIT);
        let z_pred = x.z_q16 + v - mul_q30(k.c1, v) + mul_q30(k.b1, w);
        let v_pred = v - mul_q30(k.c2, v) + mul_q30(k.b2, w);
        let innovation = (y_q16 - z_pred).clamp(-INNOVATION_LIMIT, INNOVATION_LIMIT);
        if innovation.abs() > k.switch_q16 {
            self.fast_left = k.hold_ticks;
        }
        let (l1, l2, l3) = if self.fast_left > 0 {
            self.fast_left -= 1;
            (k.fast[0], k.fast[1], k.fast[2])
        } else {
            (k.l1, k.l2, k.l3)
        };
        x.z_q16 = z_pred + mul_q30(l1, innovation);
        x.v_q16 = v_pred + mul_q30(l2, innovation);
        x.d_q16 = (x.d_q16 + mul_q24(l3, innovation)).clamp(-DISTURBANCE_LIMIT, DISTURBANCE_LIMIT);
        *x
    }

    pub fn estimate(&self) -> Estimate {
        self.x
    }

    /// Whether the fast gains are in use.
    pub fn fast(&self) -> bool {
        self.fast_left > 0
    }
}
