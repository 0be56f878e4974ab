//! The encoder + index source (module docs of `spindle`, "Encoder + index").

use super::{period_ticks, slowest_revolution_fits, Estimate};
use crate::safety::Fault;
use crate::units::SpindleAngle;

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
    pub(super) per_count_q32: u64,
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

/// Fraction of a count since the edge, Q32: `since_edge · recip`, its
/// magnitude capped at 2³² − 1 (just below one count). Exactly the 64-bit
/// product saturated and then clamped (tested against the exact product),
/// with one 32×32 multiply: a rate of 2³² or more (a count per clock tick:
/// a glitch) caps any nonzero time, a smaller one fits the multiply. The
/// cap matters: a stall (since_edge up to 2³²) times a glitch's rate
/// would wrap the product into an arbitrary angle.
#[inline(always)]
pub(super) fn frac_since_edge(since_edge: u32, recip: i64) -> i64 {
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
pub(super) fn angle_q32(delta: i64, frac: i64, per_count: u64) -> u64 {
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
        // An edge stamped after the read (a board that reads its clock
        // before the count sees an edge land between the two) has just
        // happened: no time since it, not a wrapped stall of 2³² ticks.
        let since_edge = match now.wrapping_sub(self.last_edge) {
            d if (d as i32) < 0 => 0,
            d => d,
        };
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
