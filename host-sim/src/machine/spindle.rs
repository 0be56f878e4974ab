//! The spindle as the firmware sees it: speed (set point, acceleration limit,
//! sag under cutting torque with a per-revolution ripple), the once-per-rev
//! index (photodiode; optional loss and noise pulses), the tachometer (5 V
//! at 300 rpm, chapter 3, with gain error, noise and 1 mV quantisation), and
//! a rotary encoder with index (count, hardware edge timestamp, count
//! latched at the index).
//!
//! The true angle is integrated exactly per step (trapezoid on the speed);
//! events inside a step are placed by linear interpolation of the angle, so
//! a step of a few µs gives edge times to a fraction of a µs. Angle is φ of
//! eq 2-5 in turns, zero at the index mark plus `index_phase_turns`.
//! Randomness: seeded ChaCha8.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use zslide::hw::EncoderSample;

/// Configuration of the spindle model.
#[derive(Clone, Debug, PartialEq)]
pub struct SpindleConfig {
    /// Speed at t = 0, rpm.
    pub rpm0: f64,
    /// Acceleration limit towards the set point, rpm/s.
    pub accel_rpm_per_s: f64,
    /// Speed lost under full cutting load, rpm (no speed regulation in 1983).
    pub sag_rpm: f64,
    /// Per-revolution ripple of the speed (torque varying with φ), rpm.
    pub ripple_rpm: f64,
    /// Probability that an index pulse is lost.
    pub index_loss_prob: f64,
    /// Mean spurious index pulses per revolution (Poisson).
    pub index_noise_per_rev: f64,
    /// Angle of the index mark, turns (φ at which the index fires).
    pub index_phase_turns: f64,
    /// Encoder counts per revolution (after quadrature).
    pub encoder_cpr: u32,
    /// Tachometer: millivolts per rpm (5000/300 nominal), relative gain error.
    pub tach_mv_per_rpm: f64,
    pub tach_gain_error: f64,
    /// Tachometer noise, mV rms (uniform).
    pub tach_noise_mv: f64,
    /// Timing jitter of the true index edge, µs rms (uniform): the
    /// photodiode's threshold on a slow edge, the mark's contamination.
    pub index_jitter_us: f64,
    /// Random drift of the speed, rpm rms (uniform): a new offset of the
    /// speed's target every revolution (drive and belt), approached at the
    /// acceleration limit.
    pub speed_noise_rpm: f64,
    /// Clock of the timestamps, ticks per second (wraps at 2³²): the
    /// board's free-running timer, whose count an input capture latches.
    pub ticks_per_s: f64,
    /// Pin to capture, ns: the board's input filter and resynchronisation
    /// (the encoder counter sees its edges as late, so a count and its
    /// capture change together).
    pub capture_delay_ns: u64,
    pub seed: u64,
}

impl SpindleConfig {
    /// The board's input capture of an edge at `t_ns` (exact): the clock's
    /// count when the filtered edge reaches the timer, ⌊(t + delay)·f⌋,
    /// wrapping at 2³² (the timer counts 0, 1, … from t = 0).
    pub fn capture_ticks(&self, t_ns: f64) -> u32 {
        let ticks = crate::fastmath::floor_i64(
            (t_ns + self.capture_delay_ns as f64) * 1e-9 * self.ticks_per_s,
        );
        ticks as u32
    }
}

impl Default for SpindleConfig {
    fn default() -> Self {
        Self {
            rpm0: 300.0,
            accel_rpm_per_s: 100.0,
            sag_rpm: 0.0,
            ripple_rpm: 0.0,
            index_loss_prob: 0.0,
            index_noise_per_rev: 0.0,
            index_phase_turns: 0.0,
            encoder_cpr: 10_000,
            tach_mv_per_rpm: 5000.0 / 300.0,
            tach_gain_error: 0.0,
            tach_noise_mv: 0.0,
            index_jitter_us: 0.0,
            speed_noise_rpm: 0.0,
            ticks_per_s: 1.0e6,
            capture_delay_ns: 0,
            seed: 1,
        }
    }
}

/// An index pulse (true or spurious) as the board captures it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IndexPulse {
    /// When the capture raises the interrupt (the edge plus the capture
    /// delay), ns.
    pub t_ns: u64,
    /// The captured time of the edge, clock ticks (wrapping).
    pub edge_ticks: u32,
    /// Encoder count captured at the edge (behind the same filter).
    pub count: u32,
    pub spurious: bool,
}

/// The spindle model.
pub struct Spindle {
    cfg: SpindleConfig,
    rng: ChaCha8Rng,
    t_ns: u64,
    /// Total angle, turns (not wrapped), relative to the index mark.
    turns: f64,
    rpm: f64,
    set_rpm: f64,
    load: f64,
    /// This revolution's random speed offset (`speed_noise_rpm`), rpm.
    speed_offset_rpm: f64,
    /// Exact time of the last encoder edge the model has passed, ns.
    last_edge_ns: f64,
}

impl Spindle {
    pub fn new(cfg: SpindleConfig) -> Self {
        let rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        Self {
            rpm: cfg.rpm0,
            set_rpm: cfg.rpm0,
            cfg,
            rng,
            t_ns: 0,
            turns: 0.0,
            load: 0.0,
            speed_offset_rpm: 0.0,
            last_edge_ns: 0.0,
        }
    }

    /// Speed set point (the drive's), rpm.
    pub fn set_rpm(&mut self, rpm: f64) {
        self.set_rpm = rpm;
    }

    /// Cutting load, 0..1 (scales the sag).
    pub fn set_load(&mut self, load: f64) {
        self.load = load;
    }

    pub fn rpm(&self) -> f64 {
        self.rpm
    }

    pub fn config(&self) -> &SpindleConfig {
        &self.cfg
    }

    /// The configuration from now on (index loss and noise rates take
    /// effect at the next step; a fault campaign's injection).
    pub fn config_mut(&mut self) -> &mut SpindleConfig {
        &mut self.cfg
    }

    /// Total angle since t = 0, turns relative to the index mark (not
    /// wrapped): the state the hardware bindings interpolate between steps.
    pub fn turns(&self) -> f64 {
        self.turns
    }

    /// Time the model state refers to, ns.
    pub fn time_ns(&self) -> u64 {
        self.t_ns
    }

    /// Exact time of the last encoder edge the model has passed, ns.
    pub fn last_edge_ns(&self) -> f64 {
        self.last_edge_ns
    }

    /// True spindle angle φ, turns in [0, 1).
    pub fn angle_turns(&self) -> f64 {
        (self.turns + self.cfg.index_phase_turns).rem_euclid(1.0)
    }

    /// The free-running clock's count at `t_ns` (as the firmware reads it).
    pub fn ticks_at(&self, t_ns: u64) -> u32 {
        crate::fastmath::floor_i64(t_ns as f64 * 1e-9 * self.cfg.ticks_per_s) as u32
    }

    /// Encoder count of a total angle.
    fn count_of(&self, turns: f64) -> u32 {
        crate::fastmath::floor_i64(turns * f64::from(self.cfg.encoder_cpr)) as u32
    }

    /// The encoder as a board capturing every edge presents it now (the
    /// count and its captured edge; with a capture delay the count itself
    /// is as late: `SpindleLink` models that).
    pub fn encoder(&self) -> EncoderSample {
        EncoderSample {
            count: self.count_of(self.turns),
            edge_ticks: self.cfg.capture_ticks(self.last_edge_ns),
        }
    }

    /// The tachometer now, millivolts (quantised to 1 mV).
    pub fn tach_mv(&mut self) -> i32 {
        let noise = if self.cfg.tach_noise_mv > 0.0 {
            // Uniform with the given rms.
            self.rng.random_range(-1.0..1.0) * self.cfg.tach_noise_mv * 3f64.sqrt()
        } else {
            0.0
        };
        crate::fastmath::round_i32(
            self.rpm * self.cfg.tach_mv_per_rpm * (1.0 + self.cfg.tach_gain_error) + noise,
        )
    }

    fn target_rpm(&self, turns: f64) -> f64 {
        self.set_rpm - self.cfg.sag_rpm * self.load
            + self.cfg.ripple_rpm * (std::f64::consts::TAU * turns).sin()
            + self.speed_offset_rpm
    }

    /// Advances to `t_ns` in steps of `step_ns`, appending index pulses.
    pub fn advance(&mut self, t_ns: u64, step_ns: u64, out: &mut Vec<IndexPulse>) {
        let step = step_ns.max(1);
        while self.t_ns < t_ns {
            let t1 = (self.t_ns + step).min(t_ns);
            let dt = (t1 - self.t_ns) as f64 * 1e-9;
            let r0 = self.rpm;
            let want = self.target_rpm(self.turns);
            let max_dr = self.cfg.accel_rpm_per_s * dt;
            let r1 = r0 + (want - r0).clamp(-max_dr, max_dr);
            let a0 = self.turns;
            let a1 = a0 + (r0 + r1) / 2.0 / 60.0 * dt;
            // Exact time (ns) at which the angle reaches `a` in this step.
            let at = |a: f64| -> f64 {
                let f = if a1 > a0 { (a - a0) / (a1 - a0) } else { 0.0 };
                self.t_ns as f64 + (t1 - self.t_ns) as f64 * f.clamp(0.0, 1.0)
            };
            let delay = self.cfg.capture_delay_ns as f64;
            // Encoder edge: the last count boundary crossed in the step.
            let cpr = f64::from(self.cfg.encoder_cpr);
            if self.count_of(a1) != self.count_of(a0) {
                let edge_turns = crate::fastmath::floor_i64(a1 * cpr) as f64 / cpr;
                self.last_edge_ns = at(edge_turns);
            }
            // True index: each whole turn crossed.
            let mut k = crate::fastmath::floor_i64(a0) as f64 + 1.0;
            while k <= a1 {
                if !self
                    .rng
                    .random_bool(self.cfg.index_loss_prob.clamp(0.0, 1.0))
                {
                    // The jittered edge: its time and the angle the spindle
                    // has reached then. No draw when off, so the other
                    // random streams are unchanged.
                    let (t, a) = if self.cfg.index_jitter_us > 0.0 {
                        let j_s = self.rng.random_range(-1.0..1.0)
                            * self.cfg.index_jitter_us
                            * 3f64.sqrt()
                            * 1e-6;
                        let t = (at(k) + j_s * 1e9).max(self.t_ns as f64);
                        (t, k + r0 / 60.0 * j_s)
                    } else {
                        (at(k), k)
                    };
                    out.push(IndexPulse {
                        t_ns: (t + delay).ceil() as u64,
                        edge_ticks: self.cfg.capture_ticks(t),
                        count: self.count_of(a),
                        spurious: false,
                    });
                }
                if self.cfg.speed_noise_rpm > 0.0 {
                    self.speed_offset_rpm =
                        self.rng.random_range(-1.0..1.0) * self.cfg.speed_noise_rpm * 3f64.sqrt();
                }
                k += 1.0;
            }
            // Spurious pulses: Poisson in angle.
            let p = self.cfg.index_noise_per_rev * (a1 - a0);
            if p > 0.0 && self.rng.random_bool(p.clamp(0.0, 1.0)) {
                let a = self.rng.random_range(a0..=a1);
                let t = at(a);
                out.push(IndexPulse {
                    t_ns: (t + delay).ceil() as u64,
                    edge_ticks: self.cfg.capture_ticks(t),
                    count: self.count_of(a),
                    spurious: true,
                });
            }
            self.turns = a1;
            self.rpm = r1;
            self.t_ns = t1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_every_turn_and_encoder_counts_one_turn_between() {
        let mut s = Spindle::new(SpindleConfig {
            rpm0: 300.0,
            ..SpindleConfig::default()
        });
        let mut ev = Vec::new();
        s.advance(1_010_000_000, 5_000, &mut ev);
        assert_eq!(ev.len(), 5, "300 rpm for 1.01 s");
        for w in ev.windows(2) {
            assert_eq!(w[1].count.wrapping_sub(w[0].count), 10_000);
            assert!((w[1].t_ns as i64 - w[0].t_ns as i64 - 200_000_000).abs() < 10);
        }
        assert_eq!(s.tach_mv(), 5000);
    }

    #[test]
    fn acceleration_is_limited_and_sag_slows() {
        let mut s = Spindle::new(SpindleConfig {
            rpm0: 100.0,
            accel_rpm_per_s: 300.0,
            sag_rpm: 20.0,
            ..SpindleConfig::default()
        });
        s.set_rpm(400.0);
        let mut ev = Vec::new();
        s.advance(500_000_000, 10_000, &mut ev);
        assert!((s.rpm() - 250.0).abs() < 0.1, "{}", s.rpm());
        s.advance(2_000_000_000, 10_000, &mut ev);
        assert!((s.rpm() - 400.0).abs() < 1e-9);
        s.set_load(1.0);
        s.advance(3_000_000_000, 10_000, &mut ev);
        assert!((s.rpm() - 380.0).abs() < 1e-9);
    }
}
