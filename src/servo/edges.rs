//! Anticipating the hole edges: the force step the loop will meet where
//! the nose enters or leaves an interruption the part program listed
//! (`crate::table::interrupt`), fed forward into the observer's
//! disturbance state at the tick that meets it.
//!
//! Chapter 5: at each bolt-hole edge the cutting force vanishes or returns
//! at once, and a loop that learns of it only through the gauge overshoots
//! (Figure 5-4). Where the holes are is known; how large the step is, is
//! learned from the loop's own disturbance estimate, so it does not
//! depend on knowing the cutting constants.
//!
//! # What runs where
//! * Below the tick (the learning handler, `crate::firmware::learning`):
//!   [`Edges::set_x`] when X moves (the profile of every hole at the new X
//!   is refreshed one hole per run, [`Edges::refresh_step`]: bounded work),
//!   [`Edges::expected_q8`] at the angle the next tick will meet (handed to
//!   the tick with the command ahead, `crate::handoff::ahead`), and
//!   [`Edges::learn`] on every tick's sample.
//! * In the tick (`super::Servo::update`): the change of the expected
//!   disturbance since the last tick is added to the observer's
//!   disturbance state `d̂` (one subtraction and two saturating adds). The
//!   control law's `−d̂` then cancels the step at the tick it happens, and
//!   the observer, whose model now holds the step, sees no innovation from
//!   it. A wrong estimate leaves only its error to the observer, which
//!   corrects it as it corrects any force.
//!
//! # The shape: the nose's contact against the rim
//! The nose touches the stock along a radial chord from `X − inside` to
//! `X + outside` (`X` the tool centre's radius; the feed is toward the
//! axis, so the fresh stock ahead is inside, its chord √(2 r_t d) of the
//! table's nose radius r_t and the part program's depth of cut d
//! ([`contact_chord_uin`]: 0.0087 in finishing, 0.050 in at 0.010 in
//! deep); behind, half a feed). The force falls in proportion to the part of that chord
//! over a hole. A point at radius r, angle δ from a hole's centre (bolt
//! circle radius R, hole radius ρ) is over the hole when
//! `1 − cos δ < v(r) = (ρ² − (r − R)²) / (2 r R)`: the versine of the
//! hole's half-width at r. Over the chord, v spans `[v_lo, v_hi]` (its ends
//! and, when the chord crosses R, its peak there): at versines below v_lo
//! the whole chord (or the part of it on the holes' annulus) is over the
//! hole, above v_hi none of it, and in between the fraction is taken
//! linear in the versine. Versines avoid an arccosine: the handler takes
//! one fixed-point cosine of the angle to the nearest hole (`crate::trig`).
//!
//! # The step's size: learned at every crossing
//! Where the whole chord crosses a hole, the force the cut drops is the
//! one it held just before: the handler averages `d̂` over a window before
//! the entry (from the chord's first touch out to twice its angle, the
//! stock cut steadily, the observer settled on it) and takes the step as
//! its negative, `A ← A + (−d̂_pre − A) / 2`, once the chord has lain
//! wholly over the hole (the crossing happened while learning). The step
//! is the DAC code the force needs, measured: it does not depend on the
//! cutting constants (k_e, k_t) or the motor's force constant. One
//! amplitude for all holes (one depth of cut). `d̂` also holds what the
//! model misses at rest (an amplifier offset): that is taken as part of
//! the step (on `legacy-hw` the learned step is within 3 % of the force
//! model's, `host-sim/tests/hole_edges.rs`).
//!
//! The step is not taken from `d̂` inside the hole: the observer's slow
//! gains, in use while the anticipation leaves it little innovation,
//! first move `d̂` away from a small force error before they turn (over
//! the middle half of a bolt-circle crossing on `legacy-hw`, −0.07 of the
//! error, against +0.70 with the fast gains a large error trips). A
//! step learned from `d̂` there had its fixed point unstable once close:
//! it wandered 5..20 % from the true step over hundreds of revolutions
//! (docs/CUT.md, the hole zone).
//!
//! # Number formats
//! Lengths µin (`i64` in the profile's arithmetic: (10 in)² fits); the
//! contact chord whole µin, `⌊√(2 r_t d)⌋` in integers (r_t nin, d µin:
//! below 1 µin short, 0.012 % of the finishing pass's); versines
//! `u32` Q31 (LSB 4.7e-10; a hole's half-width versine at the bolt circle
//! is ~6e-3, one tick of angle at 300 rpm ~1.2e-6); fractions `u32` Q16;
//! disturbances DAC codes Q8 `i32` (the observer's `d̂`), the amplitude
//! saturated to ±[`AMPLITUDE_MAX_Q8`]. Divisions only below the tick and
//! checked (no panic path).

use crate::table::interrupt::{Interruptions, MAX_HOLES};
use crate::trig;
use crate::units::{SpindleAngle, XInches};

/// The nose's contact with the stock inside the tool centre (toward the
/// axis, the fresh stock), whole µin: the chord `⌊√(2 r_t d)⌋` a nose of
/// radius `nose_radius_nin` (nin, the table's `Geometry::tool_radius_nin`)
/// cuts at `depth_uin` deep (the part program's `depth_of_cut_uin`). The
/// brief's 0.125 in nose: 8660 µin at 300 µin (finishing), 50 000 at
/// 10 000 (roughing). Both saturate (a radius below 0 is 0; the product
/// at `u64::MAX`, a chord of 2³² µin), so no input panics; the chord of
/// a radius of more than 4 300 in (i64 nin's range) is meaningless but
/// bounded.
pub fn contact_chord_uin(depth_uin: u32, nose_radius_nin: i64) -> i64 {
    let r = nose_radius_nin.max(0) as u64;
    // 2 r d in nin·µin; / 1000: µin².
    let sq_uin2 = r.saturating_mul(2 * u64::from(depth_uin)) / 1_000;
    sq_uin2.isqrt() as i64
}

/// The contact chord outside the tool centre (the previous revolution's
/// stock: half a feed of 100 µin a revolution), µin.
pub const CONTACT_OUTSIDE_UIN: i64 = 50;
/// Largest |amplitude| (DAC codes Q8): a quarter of the DAC's span, about
/// 4 A of coil current, beyond any hole step the amplifier can drive.
pub const AMPLITUDE_MAX_Q8: i32 = 1 << 25;
/// Fewest samples in each window for a crossing to be learned.
const MIN_WINDOW_SAMPLES: u32 = 8;
/// Q16 one.
const ONE_Q16: u32 = 1 << 16;

/// One hole at the current X: the versines bounding the chord's crossing
/// and the part of the chord on the holes' annulus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct HoleAtX {
    /// Below this versine the chord is over the hole as far as it ever is.
    v_lo_q31: u32,
    /// Above this versine none of the chord is over the hole (0: the hole
    /// does not reach the chord at this X).
    v_hi_q31: u32,
    /// The part of the chord over the hole at its centre angle, Q16.
    full_q16: u32,
}

/// The learning of the step at one crossing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Crossing {
    hole: usize,
    pre_sum: i64,
    pre_n: u32,
    /// Samples with the whole chord over the hole: the crossing happened.
    in_n: u32,
}

/// The edges' anticipation (lives in the learning handler's state).
#[derive(Clone, Debug)]
pub struct Edges {
    holes: Interruptions,
    /// The nose's contact chord inside the tool centre, µin
    /// ([`contact_chord_uin`]).
    contact_inside_uin: i64,
    /// X the profile is for, µin (`None`: no X yet).
    x_uin: Option<i64>,
    at_x: [HoleAtX; MAX_HOLES],
    /// The next hole whose profile is refreshed (= count: all fresh).
    refresh: usize,
    amplitude_q8: i32,
    crossing: Option<Crossing>,
    /// Crossings learned so far.
    learned: u32,
}

/// Versine of the half-width of a hole (bolt circle `rc`, radius `rho`) at
/// radius `r` (all µin), Q31, saturated to `u32::MAX` (half-widths beyond
/// 90°); 0 off the hole's annulus or at r ≤ 0.
fn versine_at(r: i64, rc: i64, rho: i64) -> u32 {
    if r <= 0 || rc <= 0 {
        return 0;
    }
    let off = r - rc;
    let num = rho
        .saturating_mul(rho)
        .saturating_sub(off.saturating_mul(off));
    if num <= 0 {
        return 0;
    }
    let den = (2 * r).saturating_mul(rc) as u64;
    let num = num as u64;
    // num · 2³¹ / den without overflow: num < 2⁴⁴ (ρ ≤ 2 in), so shift
    // num up as far as it goes and den down by the rest.
    let up = (num.leading_zeros().saturating_sub(1)).min(31);
    let down = 31 - up;
    let q = (num << up).checked_div(den >> down).unwrap_or(u64::MAX);
    q.min(u64::from(u32::MAX)) as u32
}

impl Edges {
    /// The anticipation of `holes` (none: it never acts) for a nose whose
    /// contact chord into the fresh stock is `contact_inside_uin`
    /// ([`contact_chord_uin`]).
    pub fn new(holes: Interruptions, contact_inside_uin: i64) -> Self {
        Self {
            holes,
            contact_inside_uin,
            x_uin: None,
            at_x: [HoleAtX::default(); MAX_HOLES],
            refresh: 0,
            amplitude_q8: 0,
            crossing: None,
            learned: 0,
        }
    }

    pub fn holes(&self) -> &Interruptions {
        &self.holes
    }

    /// The contact chord inside the tool centre the profile uses, µin.
    pub fn contact_inside_uin(&self) -> i64 {
        self.contact_inside_uin
    }

    /// The learned step, DAC codes Q8 (the change of `d̂` when the whole
    /// chord is over a hole).
    pub fn amplitude_q8(&self) -> i32 {
        self.amplitude_q8
    }

    /// Crossings learned so far.
    pub fn crossings_learned(&self) -> u32 {
        self.learned
    }

    /// X moved: the profile is refreshed, one hole per
    /// [`Self::refresh_step`].
    pub fn set_x(&mut self, x: XInches) {
        let x_uin = (i64::from(x.to_bits()) * 1_000_000) >> 24;
        if self.x_uin != Some(x_uin) {
            self.x_uin = Some(x_uin);
            self.refresh = 0;
        }
    }

    /// Refreshes one hole's profile at the current X (bounded work per
    /// handler run: one hole, three divisions).
    pub fn refresh_step(&mut self) {
        let Some(x) = self.x_uin else { return };
        let k = self.refresh;
        let Some(h) = self.holes.holes().get(k) else {
            return;
        };
        self.refresh = k + 1;
        let rc = i64::from(h.centre_radius_uin);
        let rho = i64::from(h.diameter_uin / 2);
        let (ra, rb) = (
            x.saturating_sub(self.contact_inside_uin),
            x + CONTACT_OUTSIDE_UIN,
        );
        let (va, vb) = (versine_at(ra, rc, rho), versine_at(rb, rc, rho));
        let vc = if ra < rc && rc < rb {
            versine_at(rc, rc, rho)
        } else {
            0
        };
        let v_hi = va.max(vb).max(vc);
        let v_lo = va.min(vb);
        // The part of the chord on the annulus [rc − ρ, rc + ρ].
        let on = (rb.min(rc + rho) - ra.max(rc - rho)).max(0);
        let len = rb - ra;
        let full = if v_lo > 0 {
            ONE_Q16
        } else {
            ((on << 16).checked_div(len).unwrap_or(0) as u32).min(ONE_Q16)
        };
        if let Some(slot) = self.at_x.get_mut(k) {
            *slot = HoleAtX {
                v_lo_q31: v_lo,
                v_hi_q31: v_hi,
                full_q16: full,
            };
        }
    }

    /// The hole nearest `phi` among those that reach the chord at this X:
    /// its index and the signed angle from its centre (> 0: past it).
    fn nearest(&self, phi: SpindleAngle) -> Option<(usize, i32)> {
        let mut best: Option<(usize, i32)> = None;
        for (k, (h, p)) in self.holes.holes().iter().zip(&self.at_x).enumerate() {
            if p.v_hi_q31 == 0 {
                continue;
            }
            let d = phi.0.wrapping_sub(h.angle.0) as i32;
            match best {
                Some((_, b)) if b.unsigned_abs() <= d.unsigned_abs() => {}
                _ => best = Some((k, d)),
            }
        }
        best
    }

    /// The versine of `delta` (binary angle), Q31.
    fn versine(delta: i32) -> u32 {
        let c = trig::sin_cos(SpindleAngle(delta as u32)).cos;
        // 1 − cos in Q30 is in [0, 2³¹]: Q31 saturates at 2 (δ = π).
        let v_q30 = (i64::from(trig::ONE) - i64::from(c)).max(0) as u64;
        (v_q30 << 1).min(u64::from(u32::MAX)) as u32
    }

    /// The part of the chord over hole `p` at versine `v`, Q16.
    fn fraction(p: &HoleAtX, v: u32) -> u32 {
        if v >= p.v_hi_q31 {
            0
        } else if v <= p.v_lo_q31 {
            p.full_q16
        } else {
            let span = u64::from(p.v_hi_q31 - p.v_lo_q31);
            let f = (u64::from(p.v_hi_q31 - v) << 16)
                .checked_div(span)
                .unwrap_or(0);
            ((f * u64::from(p.full_q16)) >> 16) as u32
        }
    }

    /// The change of the observer's disturbance the cut will make at
    /// `phi`, DAC codes Q8 (0 off the holes).
    pub fn expected_q8(&self, phi: SpindleAngle) -> i32 {
        if self.amplitude_q8 == 0 {
            return 0;
        }
        let Some((k, d)) = self.nearest(phi) else {
            return 0;
        };
        let Some(p) = self.at_x.get(k) else { return 0 };
        let f = Self::fraction(p, Self::versine(d));
        ((i64::from(self.amplitude_q8) * i64::from(f)) >> 16) as i32
    }

    /// Whether any of the nose's contact chord is over a hole at `phi`
    /// (the cut's force is short there): contour monitoring's depth and
    /// ring checks stand down (`super::monitor`).
    pub fn over_hole(&self, phi: SpindleAngle) -> bool {
        let Some((k, d)) = self.nearest(phi) else {
            return false;
        };
        self.at_x
            .get(k)
            .is_some_and(|p| Self::versine(d) < p.v_hi_q31)
    }

    /// One tick's sample: the angle it was taken at, the observer's
    /// disturbance estimate then (after the tick's feedforward), and
    /// whether the loop was closed on the cut and learning (a frozen
    /// sample abandons the crossing).
    pub fn learn(&mut self, phi: SpindleAngle, d_q8: i32, learning: bool) {
        if !learning {
            self.crossing = None;
            return;
        }
        let Some((k, d)) = self.nearest(phi) else {
            self.crossing = None;
            return;
        };
        let Some(p) = self.at_x.get(k).copied() else {
            return;
        };
        if p.full_q16 != ONE_Q16 || p.v_lo_q31 == 0 {
            // The chord never lies wholly over this hole here: no clean
            // step to measure.
            self.crossing = None;
            return;
        }
        let v = Self::versine(d);
        let c = match &mut self.crossing {
            Some(c) if c.hole == k => c,
            _ => {
                self.crossing = Some(Crossing {
                    hole: k,
                    ..Crossing::default()
                });
                match &mut self.crossing {
                    Some(c) => c,
                    None => return,
                }
            }
        };
        // Windows by versine (≈ δ²/2): before the entry, from the chord's
        // first touch out to twice that angle (four times the versine);
        // inside, the middle half of the full-chord span (a quarter of
        // its versine), counted only: the chord lay wholly over the hole.
        let v_pre_far = p.v_hi_q31.saturating_mul(4);
        if d < 0 && v > p.v_hi_q31 && v <= v_pre_far {
            c.pre_sum += i64::from(d_q8);
            c.pre_n += 1;
        } else if v < p.v_lo_q31 / 4 {
            c.in_n += 1;
        } else if d > 0 && v >= p.v_hi_q31 {
            // Out of the hole's far edge: the crossing is complete.
            let done = *c;
            self.crossing = None;
            if done.pre_n >= MIN_WINDOW_SAMPLES && done.in_n >= MIN_WINDOW_SAMPLES {
                // Checked divisions and max/min, not `clamp`: no panic
                // path in the handler (`cargo xtask no-panic`).
                let pre = done.pre_sum.checked_div(i64::from(done.pre_n)).unwrap_or(0);
                // The step: the steady cut's force, held in d̂ before the
                // entry, vanishes (module doc: the step's size).
                let step = pre.saturating_neg();
                let a = i64::from(self.amplitude_q8);
                let m = i64::from(AMPLITUDE_MAX_Q8);
                self.amplitude_q8 = (a + (step - a) / 2).max(-m).min(m) as i32;
                self.learned = self.learned.saturating_add(1);
            }
        }
    }
}

#[cfg(test)]
mod tests;
