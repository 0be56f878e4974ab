//! Off-centre estimation from one revolution of transducer samples.
//!
//! The part centred at (x, y) in the table frame reads
//! `r(θ) = r₀ + x cos θ − y sin θ + (out-of-round harmonics k ≥ 2)` at the
//! transducer (sign conventions in `crate::units`).
//!
//! * [`Quadrant`] is the 1967 machine (Y-1594 ch. II): one sample as the
//!   table passes each of 0°, 90°, 180°, 270° (the cam switches S-1..S-4),
//!   `x = (r(0°) − r(180°))/2`, `y = (r(270°) − r(90°))/2`. The seed's
//!   `E = 2(E1 − E2)` is the same difference scaled to 280 V/in (140 V/in
//!   times the 2:1 capacitor ratio): 70 V for 0.250 in. Two samples per axis
//!   carry their noise in full, and every odd harmonic of the part's
//!   out-of-roundness aliases into them (cos 3θ is +1 at 0° and −1 at 180°).
//! * [`Harmonic`] fits the first harmonic by least squares to *every* loop
//!   tick of one revolution. Samples are averaged into [`BINS`] bins of equal
//!   angle (so a varying table speed does not weight the fit), then the
//!   first Fourier coefficient of the bin means is taken: for equally spaced
//!   bins that *is* the least-squares fit of `r₀ + a cos θ + b sin θ`, and
//!   it is blind to harmonics 2..BINS−2 of the part. Noise falls with the
//!   square root of the number of ticks in a revolution.
//!
//! Both refuse a sample at the end of the transducer's travel
//! ([`Fault::CentringOutOfRange`]).

use crate::safety::Fault;
use crate::trig;
use crate::units::{SpindleAngle, TableInches};

/// Half the transducer's travel, less the last 0.5 mil where the plunger
/// reaches its stop: a reading beyond this is not a measurement.
pub const RANGE_LIMIT: TableInches = TableInches::from_bits(536_334_041);

/// Angle bins of the harmonic fit (a power of two: the bin is the angle's
/// top bits).
pub const BINS: usize = 256;
const BIN_SHIFT: u32 = 32 - BINS.trailing_zeros();

/// Off-centre of the part in the table frame, inches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OffCentre {
    pub x: TableInches,
    pub y: TableInches,
}

impl OffCentre {
    /// Larger of |x| and |y| (what the 1967 level detector compares: each
    /// axis against the bias), I2F30 bits.
    pub fn max_abs_bits(self) -> i64 {
        i64::from(self.x.to_bits())
            .abs()
            .max(i64::from(self.y.to_bits()).abs())
    }
}

/// Progress of an estimator after one sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    Sampling,
    Done(OffCentre),
}

fn in_range(r: TableInches) -> Result<(), Fault> {
    if r.to_bits().saturating_abs() >= RANGE_LIMIT.to_bits() {
        Err(Fault::CentringOutOfRange)
    } else {
        Ok(())
    }
}

/// Four samples, one per quadrant switch, starting at the next 0°.
#[derive(Clone, Debug, Default)]
pub struct Quadrant {
    last: Option<SpindleAngle>,
    /// Samples at 0°, 90°, 180°, 270°, in I2F30 bits.
    got: [Option<i32>; 4],
}

impl Quadrant {
    pub fn new() -> Self {
        Self::default()
    }

    /// One loop tick: the table angle and the transducer reading at it.
    /// A switch "closes" on the first tick at or past its angle (a cam
    /// switch has the same one-sided latency).
    pub fn sample(&mut self, angle: SpindleAngle, r: TableInches) -> Result<Progress, Fault> {
        in_range(r)?;
        let Some(last) = self.last.replace(angle) else {
            return Ok(Progress::Sampling);
        };
        let step = angle.0.wrapping_sub(last.0);
        for q in 0..4 {
            let at = (q as u32) << 30;
            // Crossed `at` in (last, angle]: distance from last to `at`
            // (wrapping) is within this tick's step.
            let crossed = at.wrapping_sub(last.0).wrapping_sub(1) < step;
            // The sequence starts at S-1 (0°), as the relays did.
            let started = q == 0 || self.got[0].is_some();
            if crossed && started && self.got[q].is_none() {
                self.got[q] = Some(r.to_bits());
            }
        }
        Ok(match self.got {
            [Some(a), Some(b), Some(c), Some(d)] => Progress::Done(OffCentre {
                x: TableInches::from_bits(((i64::from(a) - i64::from(c)) / 2) as i32),
                y: TableInches::from_bits(((i64::from(d) - i64::from(b)) / 2) as i32),
            }),
            _ => Progress::Sampling,
        })
    }
}

/// `1/sinc(π/BINS)` in Q30: a bin mean of `cos θ` over its width is
/// `sinc(π/BINS)·cos θ_centre`, 25 ppm small, but 6 µin of 0.25 in.
const BIN_GAIN_Q30: i64 = 1_073_768_775;

/// Least-squares first harmonic over one revolution of every tick.
#[derive(Clone, Debug)]
pub struct Harmonic {
    sum: [i64; BINS],
    /// Σ of the samples' angles from their bin's start, binary-angle units:
    /// the samples' mean angle, not the bin centre, is where the bin mean
    /// was taken (one tick is a sizeable part of a bin at 25 rpm).
    phase: [u64; BINS],
    count: [u32; BINS],
    last: Option<SpindleAngle>,
    /// Angle turned since the first sample, binary-angle units.
    turned: u64,
}

impl Default for Harmonic {
    fn default() -> Self {
        Self::new()
    }
}

impl Harmonic {
    pub fn new() -> Self {
        Self {
            sum: [0; BINS],
            phase: [0; BINS],
            count: [0; BINS],
            last: None,
            turned: 0,
        }
    }

    /// One loop tick. Done after one full turn from the first sample;
    /// [`Fault::CentringTableStopped`] if a bin got no sample in that turn
    /// (the table turned faster than the tick rate resolves).
    pub fn sample(&mut self, angle: SpindleAngle, r: TableInches) -> Result<Progress, Fault> {
        in_range(r)?;
        if let Some(last) = self.last {
            // Forward motion only: a backlash jiggle of the table encoder
            // must not count as turning.
            let d = angle.0.wrapping_sub(last.0);
            if d < 1 << 31 {
                self.turned = self.turned.saturating_add(u64::from(d));
            }
        }
        self.last = Some(angle);
        if self.turned >= 1 << 32 {
            return self.finish().map(Progress::Done);
        }
        let k = (angle.0 >> BIN_SHIFT) as usize & (BINS - 1);
        self.sum[k] = self.sum[k].saturating_add(i64::from(r.to_bits()));
        self.phase[k] = self.phase[k].saturating_add(u64::from(angle.0 & ((1 << BIN_SHIFT) - 1)));
        self.count[k] = self.count[k].saturating_add(1);
        Ok(Progress::Sampling)
    }

    /// Least squares of `m_k = r₀ + a cos θ̄_k + b sin θ̄_k` over the bin
    /// means `m_k` at the bins' mean sample angles `θ̄_k` (3×3 normal
    /// equations by Cramer's rule in `i128`: trig in Q24, so the largest
    /// determinant is below 2¹⁰²). Once per revolution.
    fn finish(&self) -> Result<OffCentre, Fault> {
        // Normal matrix entries (Q24) and right-hand side (Q30 inches).
        let (mut sc, mut ss, mut scc, mut scs, mut sss) = (0i64, 0i64, 0i64, 0i64, 0i64);
        let (mut r1, mut rc, mut rs) = (0i64, 0i64, 0i64);
        for k in 0..BINS {
            let n = self.count[k];
            if n == 0 {
                return Err(Fault::CentringTableStopped);
            }
            let mean = self.sum[k] / i64::from(n);
            let offset = (self.phase[k] / u64::from(n)) as u32;
            let at = SpindleAngle(((k as u32) << BIN_SHIFT) | offset);
            let t = trig::sin_cos(at);
            let (c, s) = (i64::from(t.cos >> 6), i64::from(t.sin >> 6));
            sc += c;
            ss += s;
            scc += (c * c) >> 24;
            scs += (c * s) >> 24;
            sss += (s * s) >> 24;
            r1 += mean;
            rc += (mean * c) >> 24;
            rs += (mean * s) >> 24;
        }
        let n = (BINS as i128) << 24;
        let m = [
            [n, i128::from(sc), i128::from(ss)],
            [i128::from(sc), i128::from(scc), i128::from(scs)],
            [i128::from(ss), i128::from(scs), i128::from(sss)],
        ];
        let rhs = [i128::from(r1), i128::from(rc), i128::from(rs)];
        let det3 = |m: &[[i128; 3]; 3]| {
            m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
        };
        let with_col = |col: usize| {
            let mut a = m;
            for (row, v) in a.iter_mut().zip(rhs) {
                row[col] = v;
            }
            det3(&a)
        };
        let det = det3(&m);
        if det <= 0 {
            // Degenerate angle coverage; cannot happen with every bin filled.
            return Err(Fault::CentringTableStopped);
        }
        let solve = |col: usize| -> TableInches {
            // rhs Q30 over matrix Q24: divide by det/2²⁴ to land in Q30.
            let v = with_col(col) / (det >> 24).max(1);
            let v = (v * i128::from(BIN_GAIN_Q30)) >> 30;
            TableInches::from_bits(v.clamp(i32::MIN as i128, i32::MAX as i128) as i32)
        };
        // r = … + x cos θ − y sin θ.
        let y = solve(2);
        Ok(OffCentre {
            x: solve(1),
            y: TableInches::from_bits(y.to_bits().saturating_neg()),
        })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::*;

    fn reading(x: f64, y: f64, th: f64) -> TableInches {
        // Radius 0.1 in of stock plus a 3-lobe out-of-round of 200 µin.
        TableInches::from_f64(0.1 + x * th.cos() - y * th.sin() + 200e-6 * (3.0 * th).cos())
    }

    #[test]
    fn bin_gain_is_inverse_sinc_of_half_bin() {
        let h = core::f64::consts::PI / BINS as f64;
        let g = h / h.sin();
        assert!((BIN_GAIN_Q30 as f64 / (1u64 << 30) as f64 - g).abs() < 2e-9);
    }

    #[test]
    fn harmonic_fit_recovers_centre_and_ignores_three_lobes() {
        let mut h = Harmonic::new();
        let (x, y) = (0.123, -0.2);
        let steps = 7919u32; // not a multiple of the bins
        let mut out = None;
        for i in 0..=steps + 1 {
            let a = SpindleAngle((u64::from(i) * (1u64 << 32) / u64::from(steps)) as u32 + 12345);
            if let Progress::Done(o) = h.sample(a, reading(x, y, a.to_radians())).unwrap() {
                out = Some(o);
                break;
            }
        }
        let o = out.unwrap();
        assert!((o.x.to_f64() - x).abs() < 0.05e-6, "{}", o.x.to_f64());
        assert!((o.y.to_f64() - y).abs() < 0.05e-6, "{}", o.y.to_f64());
    }

    /// The 1967 estimator's defect, at its full size: the 3-lobe term's
    /// cos 3θ is +1 at 0° and −1 at 180°, so x carries all of its 200 µin;
    /// at 90° and 270° it is 0, so y carries none. The ticks land exactly
    /// on the four switch angles (2²⁰ binary-angle units a tick, a divisor
    /// of a quarter turn), so the sampling latency adds nothing and the
    /// only other error is the readings' quantisation: each reading within
    /// ½ LSB of I2F30 (0.93 nin), the halved difference truncated by at
    /// most 1 LSB more: 2 LSB ≈ 1.9 nin. Half the aliasing (100 µin) or a
    /// switch a degree late (0.02 in · 0.017 rad ≈ 350 µin of y into x's
    /// neighbour) is far outside it.
    #[test]
    fn quadrant_aliases_the_third_harmonic_fully() {
        let lsb = 1.0 / f64::from(1u32 << 30);
        let mut q = Quadrant::new();
        let (x, y) = (0.01, 0.02);
        let mut out = None;
        // A quarter turn to the first 0°, then one turn: 5120 ticks.
        for i in 0..6000u32 {
            let a = SpindleAngle((i << 20).wrapping_add(0xC000_0000));
            if let Progress::Done(o) = q.sample(a, reading(x, y, a.to_radians())).unwrap() {
                out = Some(o);
                break;
            }
        }
        let o = out.unwrap();
        assert!(
            (o.x.to_f64() - (x + 200e-6)).abs() <= 2.0 * lsb,
            "x {} against {} (the full 200 µin alias)",
            o.x.to_f64(),
            x + 200e-6
        );
        assert!((o.y.to_f64() - y).abs() <= 2.0 * lsb, "y {}", o.y.to_f64());
    }

    #[test]
    fn out_of_range_reading_is_refused() {
        let mut q = Quadrant::new();
        assert_eq!(
            q.sample(SpindleAngle(0), TableInches::from_f64(-0.5)),
            Err(Fault::CentringOutOfRange)
        );
        let mut h = Harmonic::new();
        assert_eq!(
            h.sample(SpindleAngle(0), TableInches::from_f64(0.4999)),
            Err(Fault::CentringOutOfRange)
        );
    }
}
