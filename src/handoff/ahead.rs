//! The command ahead of the loop tick, handed from the handler below it
//! (`crate::firmware::learning`, which evaluates it: `crate::command::expansion`)
//! to the tick: the tick posts its angle request, the handler publishes
//! the expansion and the learned correction at the predicted angle.
//!
//! # The learned correction
//! [`Ahead::correction`] is the learned correction by spindle angle at the
//! same φ₀ (`servo::repetitive::CorrectionAhead`: the table's value, its
//! slopes and its acceleration there), made after the handler applied the
//! samples of the ticks before (the table the next tick would have read:
//! the updates touch bins a lead behind the angle, never the four it
//! reads). The loop steps it to its angle when it applies it
//! (`Servo::update`: when is unchanged) and reads the table itself when
//! none is at hand. Inside φ₀'s bin the step is the direct evaluation up to
//! the rounding; across a bin boundary it is off by the table's second
//! (position) and third (rates) differences times the part of δ past the
//! node: for a learned 100 codes at harmonic 8, a quarter bin past it
//! (one tick at 1200 rpm), 0.96 codes of position and 0.05 codes per
//! tick of velocity (`CorrectionAhead`'s docs; tested against the direct
//! evaluation).
//!
//! # Freshness
//! The tick uses an expansion only if it was made for a tick at most
//! [`MAX_AGE`] ticks ago and |δ| ≤ [`DELTA_LIMIT`](crate::servo::repetitive::DELTA_LIMIT); otherwise (the handler
//! starved by higher priorities) the tick evaluates the command itself
//! (`Expansion::direct`, the same arithmetic at δ = 0), so a late handler
//! costs instructions, never accuracy. While the command was null (no
//! angle yet, no coefficients), it stays null until the first expansion
//! arrives (one or two ticks): no jump, the slew profile joins it.

use super::coeffs::NULL_META;
use super::seqlock::Seqlock;
use crate::command::expansion::Expansion;
use crate::servo::fixed::ssat;
use crate::servo::repetitive::CorrectionAhead;
use crate::units::SpindleAngle;
use core::sync::atomic::{AtomicU32, Ordering};

/// Oldest expansion the tick uses, in ticks after the one it was made for.
pub const MAX_AGE: u32 = 4;

/// What the tick takes from the hand-off: the expansion and the learned
/// correction, for which tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ahead {
    /// The tick it was predicted for ([`crate::firmware::looptick::LoopState::ticks`]).
    pub tick: u32,
    /// `None`: the command is null (null zone, no table).
    pub expansion: Option<Expansion>,
    /// The learned correction at the same φ₀ (whether or not the command
    /// is null: the loop decides whether it applies).
    pub correction: CorrectionAhead,
    /// The hole edges' expected disturbance at the tick's angle (a half
    /// tick on: the middle of the interval its DAC code holds), DAC codes
    /// Q8 (`crate::servo::edges`; 0 without interruptions).
    pub edge_q8: i32,
}

/// Words of one published expansion: tick, φ₀, Z, p1, p2, the
/// acceleration, null flag, and the correction's position, bin slope,
/// slope, slope change and acceleration, and the hole edges' expected
/// disturbance. (The X and the generation of the
/// coefficients it was made from were published too until nothing read
/// them: two loads a tick.)
const WORDS: usize = 13;

/// The hand-off of [`crate::handoff::Shared`] between the tick (angle
/// requests in, expansions out) and `crate::firmware::learning::AheadState`:
/// the tick's request is four words (a torn one only moves φ₀, which the
/// tick checks, or the acceleration by a tick's change of Δφ or Δ²φ), the
/// expansion a [`Seqlock`].
pub(crate) struct AheadHandoff {
    /// [φ, Δφ, Δ²φ (Q4), tick]: the tick's angle, step and smoothed
    /// step's change; tick 0 = none yet.
    request: [AtomicU32; 4],
    expansion: Seqlock<WORDS>,
}

impl AheadHandoff {
    pub(crate) const fn new() -> Self {
        Self {
            request: [const { AtomicU32::new(0) }; 4],
            expansion: Seqlock::new([0; WORDS]),
        }
    }

    /// The tick's angle, step and Δ²φ (the tick; `tick` ≠ 0).
    #[inline(always)]
    pub(crate) fn post(&self, tick: u32, phi: SpindleAngle, dphi: i32, alpha_q4: i32) {
        self.request[0].store(phi.0, Ordering::Relaxed);
        self.request[1].store(dphi as u32, Ordering::Relaxed);
        self.request[2].store(alpha_q4 as u32, Ordering::Relaxed);
        self.request[3].store(tick, Ordering::Release);
    }

    pub(crate) fn request(&self) -> Option<(u32, u32, i32, i32)> {
        let tick = self.request[3].load(Ordering::Acquire);
        if tick == 0 {
            return None;
        }
        let phi = self.request[0].load(Ordering::Relaxed);
        let dphi = self.request[1].load(Ordering::Relaxed) as i32;
        // Within the bounds the tick gives it, whatever a torn read holds.
        let alpha = ssat::<25>(self.request[2].load(Ordering::Relaxed) as i32);
        Some((tick, phi, dphi, alpha))
    }

    pub(crate) fn publish(&self, g: u32, a: &Ahead) {
        let slot = self.expansion.begin(g);
        let e = a.expansion.unwrap_or_default();
        let c = &a.correction;
        let words = [
            a.tick,
            c.phi.0,
            e.z_q8 as u32,
            e.p1 as u32,
            e.p2 as u32,
            e.accel_q16 as u32,
            if a.expansion.is_some() { 0 } else { NULL_META },
            c.position_q8 as u32,
            c.bin_slope_q8 as u32,
            c.slope2_q8 as u32,
            c.slope2_per_bin_q8 as u32,
            c.accel_q16 as u32,
            a.edge_q8 as u32,
        ];
        for (w, v) in slot.iter().zip(words) {
            w.store(v, Ordering::Relaxed);
        }
        self.expansion.publish(g);
    }

    /// The latest expansion (the tick; `None` before the first or when
    /// overwritten while read).
    #[inline(always)]
    pub(crate) fn latest(&self) -> Option<Ahead> {
        let g = self.expansion.latest();
        if g == 0 {
            return None;
        }
        let w: [u32; WORDS] = self
            .expansion
            .read(g, |slot| {
                core::array::from_fn(|k| slot[k].load(Ordering::Relaxed))
            })
            .ok()?;
        let phi = SpindleAngle(w[1]);
        Some(Ahead {
            tick: w[0],
            expansion: (w[6] & NULL_META == 0).then_some(Expansion {
                phi,
                z_q8: w[2] as i32,
                p1: w[3] as i32,
                p2: w[4] as i32,
                accel_q16: w[5] as i32,
            }),
            correction: CorrectionAhead {
                phi,
                position_q8: w[7] as i32,
                bin_slope_q8: w[8] as i32,
                slope2_q8: w[9] as i32,
                slope2_per_bin_q8: w[10] as i32,
                accel_q16: w[11] as i32,
            },
            edge_q8: w[12] as i32,
        })
    }
}
