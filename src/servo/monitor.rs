//! Contour monitoring: a fault whenever the tool is not where the loop
//! means it to be, though the gauge, the converters and the amplifier are
//! all sound (docs/SAFETY.md, "Contour monitoring").
//!
//! It runs on the loop tick's samples in the learning handler, one
//! priority below the tick (`crate::firmware::learning`): nothing here
//! has to finish before the DAC write, and the tick's own budget is spent
//! on the loop. A fault found here reaches the tick through the hand-off
//! (a bit of `crate::handoff::Shared`'s fault word, `Shared::raise`) and is latched there one
//! tick later (50 µs at 20 kHz), with its reaction:
//!
//! * **depth guard**: the command's error (command − gauge) toward the
//!   stock beyond the depth guard on 3 consecutive ticks → retract: the
//!   part program's `depth_of_cut_uin` less the retract's stopping
//!   distance (`ServoDesign::depth_guard_uin`). The stock lies opposite
//!   the retract (`retract_z_in`'s sign).
//! * **oscillation**: the error's mean square about its mean (an
//!   exponential window of 2⁸ ticks; the mean's of 2⁶) above
//!   `oscillation_uin`² for a whole window (2⁸ ticks: a step's transient
//!   decays within it, a ring does not) → retract. A loop that rings
//!   against the process spring stops ringing once the tool is out of
//!   the cut.
//! * **frozen gauge**: the gauge's code identical for `gauge_frozen_ms`
//!   → amplifier off (a loop on a stale reading holds a number, not the
//!   slide).
//! * **X stalled**: `x_stall_revs` revolutions with the table command live
//!   and no new X → retract.
//!
//! Each fault is raised once per arming. The contour checks (depth,
//! oscillation, X) watch the engaged loop only: while it engages or
//! disarms (the command a slew profile, not the surface) and while a
//! fault is latched (its reaction runs) only the frozen gauge is still
//! watched: the approach and the retract are driven on the gauge. The
//! depth and oscillation checks start [`SETTLE_REVS`] revolutions of
//! live command after the engagement (docs/SAFETY.md, "Contour
//! monitoring": the spindle angle's first index correction). Where the
//! nose is over one of the part's interruptions (the part program's
//! holes, `super::edges`) and for the edges' transient after, the depth
//! and oscillation checks stand down: no stock is under the tool there,
//! and the force's steps are the cut's, not a fault's.

use super::design::{MonitorConfig, DEPTH_GUARD_TICKS};
use super::repetitive::{Freeze, LearnSample};
use crate::safety::Fault;

/// Revolutions of live command after the engagement before the depth
/// and oscillation checks judge the error. Until the spindle angle has
/// been corrected at an index pulse with a measured period, the command
/// is the contour at an angle the tachometer integrated (1 % gain error,
/// 2 % sag under the cut): at the first index after the command goes
/// live the angle steps and the command with it, by the contour's slope
/// times the step (406 µin of command − gauge for ~12 ms at X = 5 in on
/// legacy-hw, the tool itself 114 µin into the part). That index falls
/// within the first live revolution; its transient within the second.
pub const SETTLE_REVS: u32 = 2;
/// The oscillation window, ticks as a power of two (2⁸ = 12.8 ms at
/// 20 kHz: three periods of the slowest loop ring, the 250 Hz observer's).
pub const OSC_SHIFT: u32 = 8;
/// The mean the oscillation is measured about (2⁶ ticks, 3.2 ms: a
/// corner at 50 Hz, below the loop's rings and above the table's
/// 10 Hz): a steady offset (a constant force the loop leaves) is not a
/// ring.
pub const MEAN_SHIFT: u32 = 6;

/// The monitor's state (in the learning handler).
#[derive(Clone, Debug)]
pub struct Monitor {
    cfg: MonitorConfig,
    /// Consecutive samples beyond the depth guard.
    deep: u32,
    /// The error's slow mean, codes Q8 × 2^MEAN_SHIFT.
    mean: i64,
    /// The error's mean square about that mean, codes² × 2^OSC_SHIFT.
    ms: u64,
    /// Consecutive samples with the mean square above the limit.
    ringing: u32,
    /// The first sample after a reset seeds the mean.
    seeded: bool,
    last_gauge: i32,
    /// Consecutive samples with the gauge's code unchanged.
    same: u32,
    /// The spindle angle of the last live sample.
    last_phi: Option<u32>,
    /// Revolutions with the command live since the last new X.
    revs: u32,
    /// The spindle angle of the last live sample (settling count).
    live_phi: Option<u32>,
    /// Revolutions with the command live since the engagement (up to
    /// [`SETTLE_REVS`]).
    live_revs: u32,
    /// Ticks left in which the depth and ring checks stand down (a hole
    /// and its edges' transient).
    quiet: u32,
    /// The faults raised since the arming (a bit each: [`Self::once`]).
    raised: u8,
}

impl Monitor {
    pub fn new(cfg: MonitorConfig) -> Self {
        Self {
            cfg,
            deep: 0,
            mean: 0,
            ms: 0,
            ringing: 0,
            seeded: false,
            last_gauge: 0,
            same: 0,
            last_phi: None,
            revs: 0,
            live_phi: None,
            live_revs: 0,
            quiet: 0,
            raised: 0,
        }
    }

    fn reset(&mut self) {
        *self = Self::new(self.cfg);
    }

    /// Forgets what the contour checks have seen (a reaction runs).
    fn reset_contour(&mut self) {
        self.deep = 0;
        self.mean = 0;
        self.ms = 0;
        self.ringing = 0;
        self.seeded = false;
        self.last_phi = None;
        self.revs = 0;
        self.live_phi = None;
        self.live_revs = 0;
        self.quiet = 0;
    }

    /// A new coefficient set (X moved) reached the handler.
    pub fn new_x(&mut self) {
        self.revs = 0;
    }

    /// One tick's sample; the fault it shows, each fault once per arming.
    /// `over_hole`: the nose's contact touches one of the part's
    /// interruptions at the sample's angle (`super::edges::Edges::over_hole`).
    #[inline]
    pub fn sample(&mut self, s: &LearnSample, over_hole: bool) -> Option<Fault> {
        if s.requests().clears() {
            self.reset();
        }
        let frozen = self.frozen(s.gauge_code());
        if matches!(s.freeze(), Some(Freeze::Fault | Freeze::NotEngaged)) {
            // A latched fault's reaction runs, or the loop is not yet (or
            // no longer) engaged on the table: the command is a slew
            // profile to or from the goal, not the part's surface, and the
            // loop's closing transient after the sign check's open-loop
            // doublet is its own (the following-error and current limits
            // watch it). The contour checks start afresh at the
            // engagement. A gauge that stops following the slide must
            // still turn the amplifier off (a retract, an approach, are
            // driven on the gauge).
            self.reset_contour();
            return self.once(frozen);
        }
        let stalled = self.stalled(s);
        if !self.settled(s) {
            return self.once(frozen.or(stalled));
        }
        if self.interrupted(over_hole) {
            // Over a hole the force is gone and the loop meets the edges'
            // steps: its error there is the cut's, not a dig-in, and the
            // tool is over no stock. Neither check judges it, nor the
            // edges' transient after (`edge_settle_ticks`); the ring's
            // window keeps what it held before the hole.
            self.deep = 0;
            self.ringing = 0;
            return self.once(frozen.or(stalled));
        }
        let e_q8 = s.error_q8();
        let depth = self.depth(e_q8);
        let osc = self.oscillation(e_q8);
        self.once(frozen.or(depth).or(osc).or(stalled))
    }

    /// Whether the depth and ring checks stand down: over a hole, and for
    /// `edge_settle_ticks` after it.
    #[inline(always)]
    fn interrupted(&mut self, over_hole: bool) -> bool {
        if over_hole {
            self.quiet = self.cfg.edge_settle_ticks;
            return true;
        }
        if self.quiet > 0 {
            self.quiet -= 1;
            return true;
        }
        false
    }

    /// `f` unless it was raised since the last arming.
    #[inline(always)]
    fn once(&mut self, f: Option<Fault>) -> Option<Fault> {
        let bit = match f? {
            Fault::DepthGuard => 1,
            Fault::Oscillation => 2,
            Fault::GaugeFrozen => 4,
            _ => 8,
        };
        if self.raised & bit != 0 {
            return None;
        }
        self.raised |= bit;
        f
    }

    /// Retract's sign: the stock lies the other way.
    #[inline(always)]
    fn depth(&mut self, e_q8: i32) -> Option<Fault> {
        // error = command − gauge: positive when the tool is below the
        // command, toward −Z, the stock's side for a retract toward +Z.
        let into = if self.cfg.retract_code >= 0 {
            e_q8
        } else {
            e_q8.saturating_neg()
        };
        if into > self.cfg.depth_guard_q8 {
            self.deep = self.deep.saturating_add(1);
        } else {
            self.deep = 0;
        }
        (self.deep >= DEPTH_GUARD_TICKS).then_some(Fault::DepthGuard)
    }

    #[inline(always)]
    fn oscillation(&mut self, e_q8: i32) -> Option<Fault> {
        let e = i64::from(e_q8);
        if !self.seeded {
            self.mean = e << MEAN_SHIFT;
            self.seeded = true;
        }
        self.mean += e - (self.mean >> MEAN_SHIFT);
        // Whole codes about the mean: |dev| < 2²⁴, dev² < 2⁴⁸, and the
        // window's sum below 2⁵⁶.
        let dev = ((e - (self.mean >> MEAN_SHIFT)) >> 8).clamp(-(1 << 23), 1 << 23);
        let sq = (dev * dev) as u64;
        self.ms = self.ms + sq - (self.ms >> OSC_SHIFT);
        if (self.ms >> OSC_SHIFT) > self.cfg.oscillation_sq {
            self.ringing = self.ringing.saturating_add(1);
        } else {
            self.ringing = 0;
        }
        (self.ringing >= 1 << OSC_SHIFT).then_some(Fault::Oscillation)
    }

    #[inline(always)]
    fn frozen(&mut self, code: i32) -> Option<Fault> {
        if code == self.last_gauge {
            self.same = self.same.saturating_add(1);
        } else {
            self.same = 0;
            self.last_gauge = code;
        }
        (self.same >= self.cfg.gauge_frozen_ticks).then_some(Fault::GaugeFrozen)
    }

    #[inline(always)]
    fn stalled(&mut self, s: &LearnSample) -> Option<Fault> {
        if self.cfg.x_stall_revs == 0 {
            return None;
        }
        let phi = match (s.freeze(), s.angle()) {
            (None, Some((p, _))) => p.0,
            // Not live (null command, not engaged, no angle): no
            // revolution counts, and the next live one starts afresh.
            _ => {
                self.last_phi = None;
                return None;
            }
        };
        if self.last_phi.is_some_and(|last| wrapped(last, phi)) {
            self.revs = self.revs.saturating_add(1);
        }
        self.last_phi = Some(phi);
        (self.revs >= self.cfg.x_stall_revs).then_some(Fault::XStalled)
    }

    /// Counts live revolutions since the engagement; whether
    /// [`SETTLE_REVS`] have passed. A sample that is not live (a frozen
    /// learning, a null command) only breaks the count's angle chain.
    #[inline(always)]
    fn settled(&mut self, s: &LearnSample) -> bool {
        if self.live_revs >= SETTLE_REVS {
            return true;
        }
        match (s.freeze(), s.angle()) {
            (None, Some((p, _))) => {
                if self.live_phi.is_some_and(|last| wrapped(last, p.0)) {
                    self.live_revs += 1;
                }
                self.live_phi = Some(p.0);
            }
            _ => self.live_phi = None,
        }
        self.live_revs >= SETTLE_REVS
    }

    /// Revolutions counted since the last new X (for status and tests).
    pub fn revs_since_x(&self) -> u32 {
        self.revs
    }
}

/// A forward step of the spindle angle across 0: it fell by more than
/// half a turn.
#[inline(always)]
fn wrapped(last: u32, phi: u32) -> bool {
    phi < last && last - phi > 1 << 31
}

#[cfg(test)]
mod tests;
