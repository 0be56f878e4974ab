//! Spindle angle φ (eq 2-5) from either source, with index checks.
//!
//! # Encoder + index ([`EncoderAngle`])
//! The count gives the angle to one count, exactly and independently of
//! speed and acceleration: `φ = (count − count_at_index)·2³²/CPR`. Between
//! counts the angle is extrapolated by 1/T: the time since the last count
//! edge (hardware timestamp) over the last count period, *capped at one
//! count*, so the estimate never runs past the next edge it has not seen;
//! under acceleration it lags by less than one count and catches up at the
//! next edge. The reciprocal of the period is taken once per new edge (one
//! 32-bit division); a tick costs a few 32x32 multiplies.
//!
//! Index: the count latched at the index must be one revolution (CPR ±
//! `index_tolerance_counts`) after the last accepted one. Earlier is an
//! extra (noise) pulse: rejected, [`Fault::IndexExtra`], the phase is kept.
//! No index within CPR + tolerance counts is [`Fault::IndexMissing`]; the
//! count keeps the phase (the reference advances one revolution).
//!
//! # Tachometer + index ([`TachAngle`], the 1983 scheme made exact)
//! The 1983 sine generator integrated the tachometer voltage (5 V at
//! 300 rpm) and was reset at each index. Here the integral is taken in
//! fixed point over the real tick intervals (timestamps, not an assumed
//! rate), and at every accepted index the angle integrated since the
//! previous one, which must be exactly one turn, recalibrates the tach gain
//! (so a gain error of the tachometer, of its divider, or a speed-dependent
//! drift does not become a phase error), and the angle is re-phased to the
//! index *edge time* (the part integrated after the edge is kept), so the
//! phase at the index is independent of the interrupt latency and speed.
//! The same index checks apply in turns instead of counts.
//!
//! Speed band: a revolution period outside `[min_rpm, max_rpm]`, or (an
//! encoder) one count taking longer than a count's time at `min_rpm` and a
//! quarter (`count_limit_ticks`; at-read stamps: also the 20 ms baseline's
//! rate below one count in that time), is [`Fault::SpindleSpeed`].

use crate::safety::Fault;
use crate::units::SpindleAngle;

/// Angle estimate of one tick, and a fault detected on the way (the angle
/// is still the best estimate; the supervisor decides what to do).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Estimate {
    pub angle: SpindleAngle,
    pub fault: Option<Fault>,
}

/// Encoder + index configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EncoderConfig {
    /// Counts per revolution (after quadrature decoding), ≥ 4.
    pub counts_per_rev: u32,
    /// Rate of the [`crate::hw::Clock`] that timestamps edges and ticks.
    pub ticks_per_s: u32,
    pub min_rpm: u32,
    pub max_rpm: u32,
    /// Accepted deviation of the count between two indices.
    pub index_tolerance_counts: u32,
    /// φ (eq 2-5) at which the index fires: where the mark sits on the part.
    pub index_angle: SpindleAngle,
    /// What the board's edge timestamp is.
    pub edge_stamps: EdgeStamps,
}

/// What the timestamp of the encoder's last edge means on a board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum EdgeStamps {
    /// A timer input capture stamps each edge in hardware: the angle is the
    /// count plus the rate times the time since the edge (1/T).
    Captured,
    /// The count is read in software at the loop tick and a change is
    /// stamped with the read time (up to a loop period after the edge).
    /// The angle is then tracked: predicted by the baseline rate and held
    /// inside the count's interval [count, count + 1), so it stays smooth
    /// (the loop differentiates it twice) and within a count of the truth.
    AtRead,
}

/// Encoder + index angle estimator.
#[derive(Clone, Debug)]
pub struct EncoderAngle {
    cfg: EncoderConfig,
    /// Binary-angle units per count, Q32 (2⁶⁴/CPR).
    per_count_q32: u64,
    /// Count at the accepted index (`None` before the first one).
    reference: Option<u32>,
    last_count: u32,
    last_edge: u32,
    /// 2³²·counts/period (Q32 counts per tick), signed by direction: over
    /// the last count interval (captured edges; at-read stamps until a
    /// baseline has run), or over the baseline (at-read stamps).
    recip: i64,
    /// Start of the rate's baseline: count and edge time.
    base_count: u32,
    base_edge: u32,
    /// Baseline length, clock ticks (20 ms), and whether one has run.
    base_ticks: u32,
    base_done: bool,
    /// `AtRead`: the tracked position, Q32 counts (wrapping), and the clock
    /// at the last tick.
    track_q32: u64,
    last_now: u32,
    have_sample: bool,
    last_index_edge: Option<u32>,
    /// No edge for this many ticks: the count in progress is slower than
    /// `min_rpm` allows ([`count_limit_ticks`]).
    stall_ticks: u32,
    /// `AtRead`: the slowest baseline rate in the band, Q32 counts per
    /// tick (one count in `stall_ticks`).
    min_rate_q32: u64,
    min_period: u32,
    max_period: u32,
}

fn period_ticks(ticks_per_s: u32, rpm: u32) -> u32 {
    let p = u64::from(ticks_per_s) * 60 / u64::from(rpm.max(1));
    p.min(u64::from(u32::MAX)) as u32
}

/// The longest one count may take before the spindle is below its band:
/// a count's time at `min_rpm` (`max_period`/CPR) and a quarter more, for
/// the width error of a quadrature count (an edge's phase error up to
/// ±22.5° electrical of the 90° state), so the check trips below
/// 4/5·`min_rpm` over a single count. It was four counts (below
/// `min_rpm`/4), which let a coast-down run below the band, down to 25 of
/// modern-hw's 100 rpm, for up to 0.75 s before a whole revolution's
/// average tripped (issue 22). With at-read stamps the edge time is the
/// read (never before the edge), so the time since it is never longer
/// than the truth (never early) but quantised to the loop period; there
/// the 20 ms baseline's rate is held to the same limit.
fn count_limit_ticks(max_period: u32, counts_per_rev: u32) -> u32 {
    let per_count = u64::from(max_period) / u64::from(counts_per_rev.max(1));
    (per_count + per_count / 4).clamp(1, u64::from(u32::MAX)) as u32
}

/// Whether a revolution at `min_rpm` fits the 32-bit clock: a longer one
/// cannot be timed before the clock wraps (at 480 MHz, 8.9 s: 6.7 rpm), and
/// clamping it would silently raise the configured lowest speed.
fn slowest_revolution_fits(ticks_per_s: u32, min_rpm: u32) -> bool {
    u64::from(ticks_per_s) * 60 / u64::from(min_rpm.max(1)) <= u64::from(u32::MAX)
}

/// Fraction of a count since the edge, Q32: `since_edge · recip`, its
/// magnitude capped at 2³² − 1 (just below one count). Exactly the 64-bit
/// product saturated and then clamped (tested against the exact product),
/// with one 32×32 multiply: a rate of 2³² or more (a count per clock tick:
/// a glitch) caps any nonzero time, a smaller one fits the multiply. The
/// cap matters: a stall (since_edge up to 2³²) times a glitch's rate
/// would wrap the product into an arbitrary angle.
#[inline(always)]
fn frac_since_edge(since_edge: u32, recip: i64) -> i64 {
    const CAP: u64 = (1 << 32) - 1;
    let rate = recip.unsigned_abs();
    let mag = if rate > CAP {
        if since_edge == 0 {
            0
        } else {
            CAP
        }
    } else {
        (u64::from(since_edge) * u64::from(rate as u32)).min(CAP)
    };
    // mag < 2³²: the sign fits.
    if recip < 0 {
        -(mag as i64)
    } else {
        mag as i64
    }
}

/// The angle, Q32 binary-angle units (wrapping), of `delta` counts plus
/// `frac`/2³² of a count (|frac| < 2³²), at `per_count` (Q32 units per
/// count): `⌊(delta·2³² + frac)·per_count / 2³²⌋ mod 2⁶⁴`, bit-exact
/// (tested against the 128-bit product). The fraction's high word (−1 or
/// 0) joins the count, which leaves its low word f ≥ 0, and `f·per_count`
/// shifted down is `f·hi + ⌊f·lo/2³²⌋` over per_count's 32-bit words: two
/// 32×32 multiplies where the 128-bit product took a library call.
#[inline(always)]
fn angle_q32(delta: i64, frac: i64, per_count: u64) -> u64 {
    let whole = delta.wrapping_add(frac >> 32);
    let f = u64::from(frac as u32);
    let extra = (f * (per_count >> 32)).wrapping_add((f * (per_count & 0xffff_ffff)) >> 32);
    (whole as u64).wrapping_mul(per_count).wrapping_add(extra)
}

impl EncoderAngle {
    /// `None` for a configuration that cannot work (CPR < 4, rates of 0,
    /// an empty speed band, a revolution at `min_rpm` longer than the
    /// 32-bit clock can time).
    pub fn new(cfg: EncoderConfig) -> Option<Self> {
        if cfg.counts_per_rev < 4
            || cfg.ticks_per_s == 0
            || cfg.min_rpm == 0
            || cfg.max_rpm < cfg.min_rpm
            || !slowest_revolution_fits(cfg.ticks_per_s, cfg.min_rpm)
        {
            return None;
        }
        let per_count_q32 = (((1u128 << 64) + u128::from(cfg.counts_per_rev / 2))
            / u128::from(cfg.counts_per_rev)) as u64;
        let max_period = period_ticks(cfg.ticks_per_s, cfg.min_rpm);
        let stall_ticks = count_limit_ticks(max_period, cfg.counts_per_rev);
        Some(Self {
            cfg,
            per_count_q32,
            reference: None,
            last_count: 0,
            last_edge: 0,
            recip: 0,
            base_count: 0,
            base_edge: 0,
            base_ticks: (cfg.ticks_per_s / 50).max(1),
            base_done: false,
            track_q32: 0,
            last_now: 0,
            have_sample: false,
            last_index_edge: None,
            stall_ticks,
            min_rate_q32: (1u64 << 32) / u64::from(stall_ticks),
            min_period: period_ticks(cfg.ticks_per_s, cfg.max_rpm),
            max_period,
        })
    }

    /// Whether an index has set the phase (before it the angle is
    /// meaningless and the command must stay nulled).
    pub fn referenced(&self) -> bool {
        self.reference.is_some()
    }

    /// The loop tick: the encoder's count and last-edge timestamp, and the
    /// clock now (the instant the angle is wanted for).
    pub fn tick(&mut self, count: u32, edge_ticks: u32, now: u32) -> Estimate {
        let mut fault = None;
        if self.have_sample && count != self.last_count {
            let span = edge_ticks.wrapping_sub(self.base_edge);
            let at_read = self.cfg.edge_stamps == EdgeStamps::AtRead;
            if at_read && span >= self.base_ticks {
                // The rate over a 20 ms baseline: an edge stamped late (a
                // board that reads the count at the loop tick stamps a
                // change with the read time, up to a loop period after the
                // edge) errs by a loop period over the whole baseline, not
                // over one count's interval (a loop period of two or three
                // counts: the rate would swing by a third from tick to tick).
                let dc = i64::from(count.wrapping_sub(self.base_count) as i32);
                // span ≥ base_ticks ≥ 1; checked so no panic path exists.
                let q = (dc.unsigned_abs() << 32)
                    .checked_div(u64::from(span))
                    .unwrap_or(0);
                if q < self.min_rate_q32 {
                    // Below the band over the baseline: single counts,
                    // stamped at the read, cannot show it (the time since
                    // a stamp is quantised to the loop period, longer
                    // than a count's time near `min_rpm`).
                    fault = Some(Fault::SpindleSpeed);
                }
                let q = q.min(1 << 40) as i64;
                self.recip = if dc < 0 { -q } else { q };
                self.base_count = count;
                self.base_edge = edge_ticks;
                self.base_done = true;
            } else if !(at_read && self.base_done) {
                // Captured edges, or until the first baseline has run:
                // the last interval (exact with captured edges, and the
                // quickest to follow an acceleration).
                let dc = i64::from(count.wrapping_sub(self.last_count) as i32);
                let dt = edge_ticks.wrapping_sub(self.last_edge).max(1);
                // Q32 counts per tick; dc is a few counts, dt ≥ 1.
                self.recip = i64::from(u32::MAX / dt).saturating_mul(dc);
            }
        }
        if !self.have_sample {
            self.base_count = count;
            self.base_edge = edge_ticks;
            // Mid-count: the read says only that the position is in it.
            self.track_q32 = (u64::from(count) << 32) | (1 << 31);
            self.last_now = now;
        }
        let at_read_frac = match self.cfg.edge_stamps {
            EdgeStamps::AtRead => self.track(count, now),
            EdgeStamps::Captured => 0,
        };
        if !self.have_sample || count != self.last_count {
            self.last_count = count;
            self.last_edge = edge_ticks;
            self.have_sample = true;
        }
        let Some(reference) = self.reference else {
            return Estimate {
                angle: self.cfg.index_angle,
                fault: None,
            };
        };
        let mut delta = i64::from(count.wrapping_sub(reference) as i32);
        let cpr = i64::from(self.cfg.counts_per_rev);
        if delta > cpr + i64::from(self.cfg.index_tolerance_counts) {
            // A revolution went by without an index: keep the phase by count.
            fault = Some(Fault::IndexMissing);
            self.reference = Some(reference.wrapping_add(self.cfg.counts_per_rev));
            delta -= cpr;
        }
        let since_edge = now.wrapping_sub(self.last_edge);
        if since_edge > self.stall_ticks {
            fault = Some(Fault::SpindleSpeed);
        }
        let frac = match self.cfg.edge_stamps {
            EdgeStamps::Captured => frac_since_edge(since_edge, self.recip),
            EdgeStamps::AtRead => at_read_frac,
        };
        let q32 = angle_q32(delta, frac, self.per_count_q32);
        Estimate {
            angle: SpindleAngle((q32 >> 32) as u32).wrapping_add(self.cfg.index_angle),
            fault,
        }
    }

    /// `AtRead`: advances the tracked position by the baseline rate, pulls
    /// it slowly to the count's middle and holds it in [count, count + 1);
    /// the fraction of a count, Q32.
    fn track(&mut self, count: u32, now: u32) -> i64 {
        let dt = i64::from(now.wrapping_sub(self.last_now).min(1 << 20));
        self.last_now = now;
        let step = self.recip.clamp(-(1 << 40), 1 << 40) * dt;
        let pred = self.track_q32.wrapping_add(step as u64);
        let lo = u64::from(count) << 32;
        // Bounded first: a glitching count puts the prediction anywhere in
        // the wrapping range, and the pull below must not overflow
        // (found by the `spindle` fuzz target).
        let d = (pred.wrapping_sub(lo) as i64).clamp(-(1 << 34), 1 << 34);
        // Over time the truth is spread evenly across the count, so its
        // mean is the count's middle: a slow pull there (1/256 a tick,
        // 13 ms at 20 kHz) removes the offset the clamps alone would keep,
        // at under 0.002 count a tick.
        let d = d + (((1i64 << 31) - d) >> 8);
        let frac = d.clamp(0, (1 << 32) - 1);
        self.track_q32 = lo.wrapping_add(frac as u64);
        frac
    }

    /// The index event: the count the hardware latched at the index edge,
    /// and the edge's timestamp.
    pub fn on_index(&mut self, count_at_index: u32, edge_ticks: u32) -> Result<(), Fault> {
        let Some(reference) = self.reference else {
            self.reference = Some(count_at_index);
            self.last_index_edge = Some(edge_ticks);
            return Ok(());
        };
        let d = i64::from(count_at_index.wrapping_sub(reference) as i32);
        let cpr = i64::from(self.cfg.counts_per_rev);
        let tol = i64::from(self.cfg.index_tolerance_counts);
        if d < cpr - tol {
            // Too early: noise on the index line. Keep the phase.
            return Err(Fault::IndexExtra);
        }
        self.reference = Some(count_at_index);
        let prev = self.last_index_edge.replace(edge_ticks);
        if d > cpr + tol {
            return Err(Fault::IndexMissing);
        }
        if let Some(p) = prev {
            let period = edge_ticks.wrapping_sub(p);
            if period < self.min_period || period > self.max_period {
                return Err(Fault::SpindleSpeed);
            }
        }
        Ok(())
    }

    /// Speed (captured edges: the last count interval; at-read stamps: the
    /// last 20 ms baseline), binary-angle units per clock tick, Q16 (for feedforward: ω = this · 2π/2³² · ticks_per_s rad/s).
    pub fn rate_q16(&self) -> i64 {
        ((i128::from(self.recip) * i128::from(self.per_count_q32)) >> 48) as i64
    }
}

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

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests;
