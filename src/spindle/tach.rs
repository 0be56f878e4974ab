//! The tachometer + index source (module docs of `spindle`, "Tachometer + index").

use super::{period_ticks, slowest_revolution_fits, Estimate};
use crate::safety::Fault;
use crate::units::SpindleAngle;

/// Tachometer + index configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TachConfig {
    pub ticks_per_s: u32,
    /// Tachometer millivolts at 300 rpm (5000 in chapter 3).
    pub mv_at_300_rpm: u32,
    pub min_rpm: u32,
    pub max_rpm: u32,
    /// Accepted deviation of the integrated angle between two indices, in
    /// thousandths of a turn (also bounds one gain correction).
    pub index_tolerance_permille: u32,
    /// φ (eq 2-5) at which the index fires.
    pub index_angle: SpindleAngle,
}

/// Tachometer + index angle estimator. Angle state in Q48 turns (2³² per
/// turn with 16 more fraction bits), signed so re-phasing can look back.
#[derive(Clone, Debug)]
pub struct TachAngle {
    cfg: TachConfig,
    /// Q48-turn increment per (mV · tick), Q16, nominal.
    k_nominal_q16: i64,
    /// Calibrated gain, Q30 (1.0 = 2³⁰).
    gain_q30: i64,
    /// k_nominal · gain, Q16.
    k_q16: i64,
    /// Angle since the last accepted index, Q48 turns.
    acc: i64,
    /// Last rate, Q48 turns per tick.
    w: i64,
    last_tick: Option<u32>,
    last_index_edge: Option<u32>,
    calibrated: bool,
    /// Tach reading below which the spindle is too slow to follow.
    mv_stall: i64,
    min_period: u32,
    max_period: u32,
}

const TURN_Q48: i64 = 1 << 48;

/// Smallest `mv_at_300_rpm · ticks_per_s` a [`TachAngle`] accepts: the
/// per-(mV·tick) increment k = 5·2⁶⁴/(mv300·ticks) must stay ≤ 2⁴⁵, so
/// that a full-scale reading (2¹⁶ mV) times k times the largest gain (4)
/// fits an i64. Real tachometers are far above it (5000 mV at 1 MHz:
/// 5·10⁹).
pub const TACH_MIN_MV_TICKS: u64 = 5 << 19;

impl TachAngle {
    /// `None` for a configuration that cannot work: rates of 0, an empty
    /// speed band, a revolution at `min_rpm` longer than the 32-bit clock
    /// can time, an index tolerance above a quarter turn (250 ‰: an extra
    /// index could no longer be told from a real one), or a tachometer and
    /// clock so coarse (`mv_at_300_rpm · ticks_per_s` < [`TACH_MIN_MV_TICKS`])
    /// that the rate of a full-scale reading does not fit the Q48 state.
    pub fn new(cfg: TachConfig) -> Option<Self> {
        if cfg.ticks_per_s == 0
            || cfg.mv_at_300_rpm == 0
            || cfg.min_rpm == 0
            || cfg.max_rpm < cfg.min_rpm
            || !slowest_revolution_fits(cfg.ticks_per_s, cfg.min_rpm)
            || cfg.index_tolerance_permille > 250
            || u64::from(cfg.mv_at_300_rpm) * u64::from(cfg.ticks_per_s) < TACH_MIN_MV_TICKS
        {
            return None;
        }
        // 300 rpm = 5 turns/s at mv_at_300_rpm: per mV per tick,
        // 5 / (mv300 · ticks_per_s) turns, in Q48, times 2^16.
        let k =
            ((5u128 << 64) / (u128::from(cfg.mv_at_300_rpm) * u128::from(cfg.ticks_per_s))) as i64;
        Some(Self {
            cfg,
            k_nominal_q16: k,
            gain_q30: 1 << 30,
            k_q16: k,
            acc: 0,
            w: 0,
            last_tick: None,
            last_index_edge: None,
            calibrated: false,
            // u32·u32 fits u64 (not i64), and /600 fits i64.
            mv_stall: (u64::from(cfg.mv_at_300_rpm) * u64::from(cfg.min_rpm) / 600) as i64,
            min_period: period_ticks(cfg.ticks_per_s, cfg.max_rpm),
            max_period: period_ticks(cfg.ticks_per_s, cfg.min_rpm),
        })
    }

    /// Accepted deviation of one revolution's integral: the configured one
    /// once calibrated, a quarter turn before (the nominal tach gain may be
    /// off by that much).
    fn tol_q48(&self) -> i64 {
        if self.calibrated {
            (TURN_Q48 / 1000) * i64::from(self.cfg.index_tolerance_permille)
        } else {
            TURN_Q48 / 4
        }
    }

    /// Whether an index has set the phase.
    pub fn referenced(&self) -> bool {
        self.last_index_edge.is_some()
    }

    /// The loop tick: tachometer millivolts and the clock now.
    pub fn tick(&mut self, millivolts: i32, now: u32) -> Estimate {
        let mut fault = None;
        let mv = i64::from(millivolts.clamp(-(1 << 16), 1 << 16));
        self.w = (mv * self.k_q16) >> 16;
        if let Some(t) = self.last_tick {
            let dt = i64::from(now.wrapping_sub(t).min(1 << 24));
            self.acc = self.acc.saturating_add(self.w.saturating_mul(dt));
        }
        self.last_tick = Some(now);
        if self.referenced() && self.acc > TURN_Q48 + self.tol_q48() {
            fault = Some(Fault::IndexMissing);
            self.acc -= TURN_Q48;
        }
        if mv < self.mv_stall {
            // Below half the slowest speed (or reversed).
            fault = fault.or(Some(Fault::SpindleSpeed));
        }
        Estimate {
            angle: self.angle(),
            fault,
        }
    }

    /// Current angle φ (the index angle plus the angle since the index).
    pub fn angle(&self) -> SpindleAngle {
        SpindleAngle((self.acc >> 16) as u32).wrapping_add(self.cfg.index_angle)
    }

    /// The index event, with the edge's timestamp.
    pub fn on_index(&mut self, edge_ticks: u32) -> Result<(), Fault> {
        // The angle at the edge: the integral up to the last tick, corrected
        // by the rate for the time between that tick and the edge.
        let back = match self.last_tick {
            Some(t) => i64::from(edge_ticks.wrapping_sub(t) as i32),
            None => 0,
        };
        let at_edge = self.acc.saturating_add(self.w.saturating_mul(back));
        let Some(prev_edge) = self.last_index_edge else {
            self.acc = self.acc.saturating_sub(at_edge);
            self.last_index_edge = Some(edge_ticks);
            return Ok(());
        };
        let tol = self.tol_q48();
        if at_edge < TURN_Q48 - tol {
            // Too early: noise on the index line. Keep the phase.
            return Err(Fault::IndexExtra);
        }
        // Re-phase to the edge (saturating: both terms may be saturated).
        self.acc = self.acc.saturating_sub(at_edge);
        self.last_index_edge = Some(edge_ticks);
        if at_edge > TURN_Q48 + tol {
            return Err(Fault::IndexMissing);
        }
        // One turn was integrated as `at_edge`: scale the gain by
        // turn/at_edge (once per revolution: the division is here).
        if at_edge > 0 {
            // Clamped before the cast: a tiny integral (a tolerance near a
            // quarter turn) gives a ratio beyond i64.
            let measured = ((i128::from(self.gain_q30) << 48) / i128::from(at_edge))
                .clamp(1 << 28, 1 << 32) as i64;
            // First revolution: take it; then average to smooth tach noise.
            self.gain_q30 = if self.calibrated {
                (self.gain_q30 + measured) / 2
            } else {
                measured
            }
            .clamp(1 << 28, 1 << 32);
            self.k_q16 =
                ((i128::from(self.k_nominal_q16) * i128::from(self.gain_q30)) >> 30) as i64;
            self.calibrated = true;
        }
        let period = edge_ticks.wrapping_sub(prev_edge);
        if period < self.min_period || period > self.max_period {
            return Err(Fault::SpindleSpeed);
        }
        Ok(())
    }

    /// Speed, Q48 turns per tick (for feedforward).
    pub fn rate_q48(&self) -> i64 {
        self.w
    }

    /// Calibrated tachometer gain relative to nominal, Q30.
    pub fn gain_q30(&self) -> i64 {
        self.gain_q30
    }
}
