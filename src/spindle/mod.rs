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

mod encoder;
mod tach;

pub use encoder::{EdgeStamps, EncoderAngle, EncoderConfig};
pub use tach::{TachAngle, TachConfig, TACH_MIN_MV_TICKS};

use crate::safety::Fault;
use crate::units::SpindleAngle;

/// Angle estimate of one tick, and a fault detected on the way (the angle
/// is still the best estimate; the supervisor decides what to do).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Estimate {
    pub angle: SpindleAngle,
    pub fault: Option<Fault>,
}

fn period_ticks(ticks_per_s: u32, rpm: u32) -> u32 {
    let p = u64::from(ticks_per_s) * 60 / u64::from(rpm.max(1));
    p.min(u64::from(u32::MAX)) as u32
}

/// Whether a revolution at `min_rpm` fits the 32-bit clock: a longer one
/// cannot be timed before the clock wraps (at 480 MHz, 8.9 s: 6.7 rpm), and
/// clamping it would silently raise the configured lowest speed.
fn slowest_revolution_fits(ticks_per_s: u32, min_rpm: u32) -> bool {
    u64::from(ticks_per_s) * 60 / u64::from(min_rpm.max(1)) <= u64::from(u32::MAX)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests;
