//! Spindle-synchronous repetitive (learning) control, indexed by spindle
//! angle.
//!
//! The error that repeats every revolution (what the feedforward's rigid
//! model misses, the per-revolution part of the cutting force, the bolt
//! holes, the tachometer's once-per-rev ripple) is learned into a table of
//! 256 bins per revolution and added to the reference the loop follows:
//!
//! ```text
//! r'(φ) = r(φ) + c(φ)          c: the table, linearly interpolated in φ
//! c(θ) ← Q[ c(θ) + κ · sat_C(e(θ + lead)) ]    once per revolution per bin
//! ```
//!
//! Because the correction enters as *reference*, it passes through the
//! same plant-inverse feedforward as the command (its angular derivatives,
//! from the table's slopes, times the measured angle step), so the learned
//! reference is followed at every harmonic the model is good for, not only
//! inside the feedback bandwidth. The table is indexed by angle, not time:
//! when the spindle sags a few percent under cutting torque, a bin still
//! holds the same place on the part (a time-indexed buffer of one nominal
//! period would slide along the part and learn the error into the wrong
//! place). The learning is spread over the ticks inside a bin in proportion
//! to the angle each covers (Σ Δφ over a bin = one bin), so κ is per
//! revolution whatever the speed.
//!
//! Robustness: the lead (in bins) compensates the loop's residual lag; the
//! error taken in passes a first-order low-pass (`learning_lowpass_hz`,
//! 80 Hz): the minimum lead, 3 bins, is 105° at the 25th harmonic (125 Hz
//! at 300 rpm), more than the loop's own lag there, and the engaged part's
//! spring turns the loop's phase further forward around 100..200 Hz; the
//! low-pass's lag (−57° at 125 Hz, and −31° .. −7° for harmonics 10..2,
//! where the lead gives +42° .. +8°) keeps the learning's turn below 90°
//! where its gain is not small (docs/TUNING.md, "The process spring"); the
//! Q-filter `t[k] += (t[k−1] − 2t[k] + t[k+1]) / 2^shift`, applied twice
//! to each bin per revolution when it is complete (for shift 2 the kernel
//! [1 4 6 4 1]/16: gain cos⁴(πh/256) at harmonic h, 0.9976 at h = 2,
//! 0.87 at h = 21, 0.25 at h = 64), limits the learning to low
//! harmonics (zero phase in angle) and makes it forget slowly, which is
//! also how the table follows X as the feed moves the radius. Entries are
//! clamped to ± a quarter of the gauge range (memory bounded in size and
//! value). Learning freezes, with a reason, whenever the angle cannot be
//! trusted or the machine jumped.
//!
//! What does not repeat: the learning cannot tell a one-off transient from
//! an error that will be there again next revolution, and a revolution
//! later it replays whatever it took in. A push the loop holds within the
//! following-error limit (20 lbf, 3000 µin on `modern-hw`) learned at κ
//! came back as a −760 µin correction, 707 µin into the part
//! (docs/SAFETY.md, "A transient learned and replayed"). So each tick's
//! error is clipped to ±C (`learning_clip_uin`) before it is learned: a
//! bin's update is the mean of its ticks' κ·sat_C(e), so one revolution
//! moves a bin by at most κ·C, and the Q-filter (a positive kernel of
//! sum one) does not enlarge it; the replayed correction is then unlearned,
//! revolution by revolution, since the loop following it makes the error
//! −c. C sits above the largest error that does repeat, an interrupted
//! cut's edges before they are learned (269 µin on `legacy-hw`, 116 on
//! `modern-hw`, docs/TUNING.md), so the cut's learning is not touched
//! there; a periodic error beyond C is still learned, by κ·C a
//! revolution until it is inside the clip (a freeze on a large error
//! instead would never learn it, and would drop whole revolutions).
//!
//! # Two priorities
//! The loop tick uses the correction, expanded below it at the predicted
//! angle after the learning's update ([`LearnedTable::ahead`], stepped by
//! [`CorrectionAhead::step`]; read directly, [`LearnedTable::correction`],
//! without a fresh expansion); the learning itself (the hum notch on the error, the update, the Q-filter)
//! runs below it, in its own handler ([`Learner`], driven by
//! `crate::firmware::learning`), on the samples each tick hands over
//! ([`LearnSample`]). The table is shared as atomic words. The update
//! writes bins i − lead and i − lead + 1 and the Q-filter bins up to
//! i − lead + 1, all below the bins i − 1 .. i + 2 the tick reads at
//! bin i (lead ≥ [`MIN_LEAD`]), so as long as the learner runs within a
//! bin of the tick (it runs after every tick on the boards, and in the
//! `Firmware` bundle) the tick reads, or is handed, exactly what the
//! update would have left had it run inside the tick.
//!
//! # Number formats
//! Table entries: gauge codes Q8 (`i32`, |entry| ≤ 2²⁵). Angle: the binary
//! spindle angle (2³² per revolution); a bin is 2²⁴. Outputs: position Q8
//! codes, velocity Q16 codes per tick, acceleration Q16 codes per tick², all
//! `i32`. Products of an entry difference (< 2²⁷) and a fraction or an
//! angle step (< 2²²) are single 32×32 → 64-bit multiplies, shifted back to
//! 32 bits once.

use super::design::ServoConfig;
use super::filters::Canceller;
use super::fixed::sat_i32;
use crate::units::SpindleAngle;
use core::sync::atomic::{AtomicI32, Ordering};

/// Largest |φ − φ₀| a value made ahead of the tick (this
/// correction, the command's expansion: `crate::command::expansion`) is
/// stepped over: 3·2²², 1/341 turn
/// (two ticks at 1800 rpm and 20 kHz).
pub const DELTA_LIMIT: i32 = 3 << 22;

/// Bins per revolution.
pub const BINS: usize = 256;
const BIN_BITS: u32 = 24;
const MASK: usize = BINS - 1;
/// |entry| ≤ 2¹⁷ codes (a quarter of the gauge range), Q8.
const ENTRY_LIMIT: i32 = 1 << 25;
/// The correction at bin i reads bins i−1..i+2; an update at i − lead
/// (and the bin after it) must not touch them in the same revolution, or
/// the learning would feed back within the revolution (an integrator at
/// the tick rate that amplifies gauge noise) instead of from one
/// revolution to the next.
pub const MIN_LEAD: usize = 3;
/// Largest angle step per tick the learning accepts (1/4 bin: 1170 rpm at
/// 20 kHz); larger steps are a jump, not motion.
const MAX_DPHI: i32 = 1 << (BIN_BITS - 2);

/// Why the learning is not running.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Freeze {
    /// Learning gain 0 in the configuration.
    Disabled,
    /// The loop is not engaged on the table (arming, ramping, disarmed).
    NotEngaged,
    /// No spindle angle (before the first index, or no spindle).
    NoAngle,
    /// The angle stepped backwards or by more than a quarter bin in a tick.
    SpindleJump,
    /// X moved by more than the configured step between two updates.
    XJump,
    /// A fault is latched.
    Fault,
    /// The table's command is null (X in the null zone, no X or no angle
    /// yet): the slide is held at zero, nothing periodic to learn, and
    /// learning would only write gauge noise into the table.
    Null,
}

impl Freeze {
    const ALL: [Freeze; 7] = [
        Freeze::Disabled,
        Freeze::NotEngaged,
        Freeze::NoAngle,
        Freeze::SpindleJump,
        Freeze::XJump,
        Freeze::Fault,
        Freeze::Null,
    ];

    /// A code 1..=7 (0: none), for a sample packed into words.
    pub(crate) fn code(f: Option<Freeze>) -> u32 {
        f.map_or(0, |f| f as u32 + 1)
    }

    pub(crate) fn from_code(c: u32) -> Option<Freeze> {
        Self::ALL.get((c as usize).wrapping_sub(1)).copied()
    }
}

/// What one loop tick hands the learner: the command's error as the gauge
/// measures it (codes Q8, before the hum notch: that is the learner's),
/// where and how fast the spindle was, why the learning must not run now,
/// and the tick's requests (forget the table, hold the learning frozen);
/// and the observer's disturbance estimate, for the hole edges' learning
/// (`super::edges`).
///
/// Packed in six words, the form the hand-off ring carries (so the loop
/// tick builds it with a few bit operations): `[error, angle, angle step,
/// flags, disturbance, gauge]`, flags = freeze code (bits 0..2,
/// [`Freeze::code`]), angle known (3), clear (4), hold reason code (5..7),
/// hold ticks (8..31, at most 2²⁴ − 1: 14 minutes at 20 kHz); the gauge's
/// code is contour monitoring's (`servo::monitor`: a frozen gauge), not
/// the learner's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LearnSample(pub(crate) [u32; SAMPLE_WORDS]);

/// Words of a [`LearnSample`].
pub const SAMPLE_WORDS: usize = 6;

const S_ANGLE: u32 = 1 << 3;
const S_CLEAR: u32 = 1 << 4;
const S_HOLD_SHIFT: u32 = 5;
const S_TICKS_SHIFT: u32 = 8;
/// The longest hold a sample carries.
const S_TICKS_MAX: u32 = (1 << 24) - 1;

impl LearnSample {
    pub fn new(
        error_q8: i32,
        angle: Option<(SpindleAngle, i32)>,
        freeze: Option<Freeze>,
        requests: LearnRequests,
    ) -> Self {
        let (phi, dphi, a) = match angle {
            Some((p, d)) => (p.0, d, S_ANGLE),
            None => (0, 0, 0),
        };
        Self([
            error_q8 as u32,
            phi,
            dphi as u32,
            Freeze::code(freeze) | a | requests.0,
            0,
            0,
        ])
    }
    /// The sample with the observer's disturbance estimate `d̂` (DAC codes
    /// Q8) of its tick.
    pub fn with_disturbance(mut self, d_q8: i32) -> Self {
        self.0[4] = d_q8 as u32;
        self
    }
    /// The observer's disturbance estimate of the tick, DAC codes Q8.
    pub fn disturbance_q8(&self) -> i32 {
        self.0[4] as i32
    }
    /// The sample with the tick's gauge code (+Z, as the servo takes it).
    #[inline(always)]
    pub fn with_gauge(mut self, gauge_code: i32) -> Self {
        self.0[5] = gauge_code as u32;
        self
    }
    /// The tick's gauge code.
    pub fn gauge_code(&self) -> i32 {
        self.0[5] as i32
    }
    /// Command − gauge, codes Q8.
    pub fn error_q8(&self) -> i32 {
        self.0[0] as i32
    }
    /// The spindle angle and its step over the tick, when known.
    pub fn angle(&self) -> Option<(SpindleAngle, i32)> {
        (self.0[3] & S_ANGLE != 0).then_some((SpindleAngle(self.0[1]), self.0[2] as i32))
    }
    pub fn freeze(&self) -> Option<Freeze> {
        Freeze::from_code(self.0[3] & 7)
    }
    pub fn requests(&self) -> LearnRequests {
        LearnRequests(self.0[3] & S_REQUESTS)
    }
}

/// What the loop asks of the learning besides learning: forget everything
/// learned first (arming), hold it frozen for a number of ticks
/// (engagement, an X jump). Kept as the sample's flag bits (clear, hold
/// reason and ticks: [`LearnSample`]), so that the tick hands them over
/// with one load and one store.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LearnRequests(u32);

const S_REQUESTS: u32 = S_CLEAR | (7 << S_HOLD_SHIFT) | (S_TICKS_MAX << S_TICKS_SHIFT);

impl LearnRequests {
    pub const NONE: Self = Self(0);

    /// Forget the table first.
    pub fn clear(&mut self) {
        self.0 |= S_CLEAR;
    }

    /// Hold the learning frozen for `ticks` (at most 2²⁴ − 1 kept). Two
    /// holds before one sample: the longer time, the later reason (what
    /// two holds in a row leave in the learner).
    pub fn hold(&mut self, reason: Freeze, ticks: u32) {
        let ticks = ticks.min(S_TICKS_MAX);
        let t = self.held().map_or(ticks, |(_, t)| t.max(ticks));
        self.0 =
            (self.0 & S_CLEAR) | Freeze::code(Some(reason)) << S_HOLD_SHIFT | t << S_TICKS_SHIFT;
    }

    pub fn clears(&self) -> bool {
        self.0 & S_CLEAR != 0
    }

    pub fn held(&self) -> Option<(Freeze, u32)> {
        Freeze::from_code((self.0 >> S_HOLD_SHIFT) & 7).map(|r| (r, self.0 >> S_TICKS_SHIFT))
    }
}

/// The learned reference correction at one angle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Correction {
    /// Gauge codes Q8.
    pub position_q8: i32,
    /// Gauge codes per tick Q16.
    pub velocity_q16: i32,
    /// Gauge codes per tick² Q16.
    pub accel_q16: i32,
}

/// The learned correction expanded at one angle φ₀ (by the handler below
/// the tick, at the angle the next tick is predicted to read:
/// `crate::handoff::ahead`), and stepped in the tick to the angle φ = φ₀ + δ it
/// reads ([`CorrectionAhead::step`]).
///
/// Inside φ₀'s bin the correction is linear in φ (the interpolation
/// between two entries) and so is its slope (between the centred slopes
/// at the bin's nodes): the step is the direct evaluation at φ up to the
/// rounding, 1 + |t₂ − t₁|/2¹⁶ Q8 of position (the direct one drops φ's
/// low 8 bits) and one Q16 LSB of velocity. Across a bin boundary (|δ| is
/// below a bin, so at most one) the step continues φ₀'s bin's straight
/// lines where the direct one bends at the node k crossed. With
/// `D₂ = |t(k+1) − 2t(k) + t(k−1)|` and
/// `D₃ = |t(k+2) − 2t(k+1) + 2t(k−1) − t(k−2)|` (the table's second and
/// third centred differences there) and ε = the part of |δ| past the
/// node in bins (ε < |δ|/2²⁴ ≤ 3/4) and β = |Δφ|/2²⁴ the tick's step in
/// bins, in gauge codes:
///
/// ```text
/// position     |Δc| ≤ D₂·ε
/// velocity     |Δv| ≤ D₃·ε·β/2      per tick
/// acceleration |Δa| ≤ D₃·β²/2       per tick²
/// ```
///
/// (the acceleration is piecewise constant per bin: the one of φ₀'s bin
/// at the predicted step Δφ₀; for the step Δφ the tick measures it is off
/// by a further |s₂ − s₁|·|β² − β₀²|/2). The differences scale with the
/// learned shape: a harmonic h of amplitude A codes has D₂ ≤ Aω² and
/// D₃ ≤ 2Aω³, ω = 2πh/256. For 100 codes (1.9 µin) at h = 8 stepped a
/// quarter bin past a node (one tick at 1200 rpm, β = ¼): position 0.96
/// codes, velocity 0.05 codes per tick, acceleration 0.05 codes per tick²
/// (the command's own Taylor step at that δ: 0.045 codes, 0.14 codes per
/// tick; `crate::handoff::ahead`). Tested against the direct evaluation
/// (`correction_step_is_the_direct_evaluation_within_its_bound`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CorrectionAhead {
    /// φ₀.
    pub phi: SpindleAngle,
    /// c(φ₀), gauge codes Q8.
    pub position_q8: i32,
    /// The position's slope in φ₀'s bin, t₂ − t₁: Q8 codes per bin.
    pub bin_slope_q8: i32,
    /// The centred slope at φ₀ (Q8 codes per bin, times 2).
    pub slope2_q8: i32,
    /// Its change per bin in φ₀'s bin, s₂ − s₁.
    pub slope2_per_bin_q8: i32,
    /// The acceleration of φ₀'s bin at the step the expansion was made
    /// for, Q16 codes per tick².
    pub accel_q16: i32,
}

impl CorrectionAhead {
    /// The correction at `phi` with its rates for the step `dphi` (None
    /// beyond `DELTA_LIMIT` from φ₀).
    #[inline(always)]
    pub fn step(&self, phi: SpindleAngle, dphi: i32) -> Option<Correction> {
        let d = phi.0.wrapping_sub(self.phi.0) as i32;
        if !(-DELTA_LIMIT..=DELTA_LIMIT).contains(&d) {
            return None;
        }
        Some(self.at(d, dphi))
    }

    /// The correction δ = `d` from φ₀ (|d| ≤ 2²⁴: the products below stay
    /// within 2⁵¹ before their shifts, 2²⁷ after).
    #[inline(always)]
    fn at(&self, d: i32, dphi: i32) -> Correction {
        let c_q8 =
            self.position_q8 + ((i64::from(self.bin_slope_q8) * i64::from(d)) >> BIN_BITS) as i32;
        let slope2 = self.slope2_q8
            + ((i64::from(self.slope2_per_bin_q8) * i64::from(d)) >> BIN_BITS) as i32;
        let dd = dphi.clamp(-MAX_DPHI, MAX_DPHI);
        // slope/2 · dphi / 2²⁴ codes Q8 per tick → Q16: ·2⁸ → >> 17
        // (< 2³²: saturated).
        let v = sat_i32((i64::from(slope2) * i64::from(dd)) >> (BIN_BITS - 7));
        Correction {
            position_q8: c_q8,
            velocity_q16: v,
            accel_q16: self.accel_q16,
        }
    }
}

/// The learned table (gauge codes Q8 per bin): the loop tick reads it, the
/// learner writes it. Atomic words (single loads and stores on the M4), so
/// it can live in the `Shared` hand-off between the two priorities.
pub struct LearnedTable {
    t: [AtomicI32; BINS],
}

impl Default for LearnedTable {
    fn default() -> Self {
        Self::new()
    }
}

impl LearnedTable {
    pub const fn new() -> Self {
        Self {
            t: [const { AtomicI32::new(0) }; BINS],
        }
    }

    #[inline(always)]
    fn get(&self, k: usize) -> i32 {
        self.t[k & MASK].load(Ordering::Relaxed)
    }

    #[inline(always)]
    fn set(&self, k: usize, v: i32) {
        self.t[k & MASK].store(v, Ordering::Relaxed);
    }

    /// The correction to add to the reference at `phi`, with its rates for
    /// an angle step of `dphi` per tick (the feedforward's input): the
    /// expansion at `phi` taken there (the tick's fallback when no fresh
    /// expansion from below it is at hand, `crate::handoff::ahead`).
    #[inline]
    pub fn correction(&self, phi: SpindleAngle, dphi: i32) -> Correction {
        self.ahead(phi, dphi).at(0, dphi)
    }

    /// The correction's expansion at `phi` for a step `dphi` (the handler
    /// below the tick makes it at the predicted angle; see
    /// [`CorrectionAhead`]).
    #[inline]
    pub fn ahead(&self, phi: SpindleAngle, dphi: i32) -> CorrectionAhead {
        let i = (phi.0 >> BIN_BITS) as usize;
        // The position inside the bin, Q16.
        let f = ((phi.0 >> (BIN_BITS - 16)) & 0xFFFF) as i32;
        let (t0, t1, t2, t3) = (
            self.get(i + MASK),
            self.get(i),
            self.get(i + 1),
            self.get(i + 2),
        );
        // |entries| ≤ 2²⁵: differences < 2²⁶, slopes' differences < 2²⁷.
        let c_q8 = t1 + ((i64::from(t2 - t1) * i64::from(f)) >> 16) as i32;
        // Slopes at the nodes (codes Q8 per bin, times 2), interpolated.
        let (s1, s2) = (t2 - t0, t3 - t1);
        let slope2 = s1 + ((i64::from(s2 - s1) * i64::from(f)) >> 16) as i32;
        let d = dphi.clamp(-MAX_DPHI, MAX_DPHI);
        // (s2 − s1)/2 per bin² · dphi² / 2⁴⁸, Q8 → Q16: >> 41 in two
        // steps (< 2²⁹, then < 2³⁰).
        let a1 = ((i64::from(s2 - s1) * i64::from(d)) >> 20) as i32;
        let a = ((i64::from(a1) * i64::from(d)) >> (2 * BIN_BITS - 27)) as i32;
        CorrectionAhead {
            phi,
            position_q8: c_q8,
            bin_slope_q8: t2 - t1,
            slope2_q8: slope2,
            slope2_per_bin_q8: s2 - s1,
            accel_q16: a,
        }
    }

    #[inline(always)]
    fn add(&self, k: usize, inc: i32) {
        let v = self.get(k).saturating_add(inc);
        self.set(k, v.clamp(-ENTRY_LIMIT, ENTRY_LIMIT));
    }

    #[inline(always)]
    fn q_filter(&self, k: usize, q_shift: u32) {
        // |entries| ≤ 2²⁵: the second difference is below 2²⁷.
        let d = (self.get(k + MASK) - 2 * self.get(k) + self.get(k + 1)) >> q_shift;
        self.add(k, d);
    }

    fn clear(&self) {
        for t in &self.t {
            t.store(0, Ordering::Relaxed);
        }
    }

    /// Largest |entry|, gauge codes (reports: the table must not grow
    /// without bound).
    pub fn peak_code(&self) -> i32 {
        self.t
            .iter()
            .map(|v| v.load(Ordering::Relaxed).unsigned_abs())
            .max()
            .unwrap_or(0) as i32
            >> 8
    }

    /// The table, gauge codes Q8 (reports, plots).
    pub fn snapshot(&self) -> [i32; BINS] {
        core::array::from_fn(|k| self.get(k))
    }
}

/// The learning: its state and its update, applied to the learned table
/// one tick's sample at a time, below the loop tick's priority.
#[derive(Clone, Debug)]
pub struct Learner {
    gain_q16: i32,
    lead: usize,
    q_shift: u32,
    /// The clip on the error taken in, codes Q8 (1 ..= 2²⁸).
    clip_q8: i32,
    /// The hum canceller on the error (at 300 rpm the 120 Hz hum is exactly
    /// the 24th spindle harmonic: learned, it would move the slide).
    hum: Option<Canceller>,
    /// The low-pass on the error: `α` Q16 (0 = off) and its output,
    /// codes Q8 ([`lowpass`]).
    lowpass_q16: i32,
    lowpass_q8: i32,
    last_bin: Option<usize>,
    frozen: Option<Freeze>,
    /// Ticks to stay frozen after a jump.
    hold: u32,
    hold_reason: Freeze,
    passes: u32,
}

/// One step of the learning's first-order low-pass, `y ← y + α·(x − y)`:
/// `y`, `x` codes Q8, `α` Q16 in (0, 2¹⁶]. `y` stays between its last value
/// and `x` (a convex combination, rounded), so it never leaves the range of
/// its inputs and the clip's bound (`learning_clip_uin`) holds after it as
/// before. The rounding leaves `y` short of a constant `x` by at most
/// 2¹⁵/α LSB (20 LSB, 0.0015 µin, at 80 Hz and 20 kHz).
#[inline(always)]
fn lowpass(y_q8: i32, x_q8: i32, alpha_q16: i32) -> i32 {
    let d = i64::from(x_q8) - i64::from(y_q8);
    y_q8 + ((d * i64::from(alpha_q16) + (1 << 15)) >> 16) as i32
}

impl Learner {
    /// The learning of the design `cfg`.
    pub fn new(cfg: &ServoConfig) -> Self {
        let gain_q16 = cfg.learning_gain_q16;
        Self {
            gain_q16: gain_q16.clamp(0, 65_535),
            lead: (cfg.learning_lead_bins as usize).clamp(MIN_LEAD, MASK),
            q_shift: cfg.learning_q_shift.clamp(1, 16),
            clip_q8: cfg.learning_clip_q8.clamp(1, 1 << 28),
            hum: cfg.hum_canceller.map(Canceller::from_bits),
            lowpass_q16: cfg.learning_lowpass_q16.clamp(0, 65_536),
            lowpass_q8: 0,
            last_bin: None,
            frozen: if gain_q16 > 0 {
                None
            } else {
                Some(Freeze::Disabled)
            },
            hold: 0,
            hold_reason: Freeze::SpindleJump,
            passes: 0,
        }
    }

    /// One tick's sample: its requests, the hum notch on its error, then
    /// the update (or the freeze it asks for).
    #[inline]
    pub fn apply(&mut self, s: &LearnSample, table: &LearnedTable) {
        let r = s.requests();
        if r.clears() {
            table.clear();
            self.last_bin = None;
            self.passes = 0;
            self.lowpass_q8 = 0;
        }
        if let Some((reason, ticks)) = r.held() {
            self.hold_for(reason, ticks);
        }
        let error_q8 = match &mut self.hum {
            Some(n) => n.process(s.error_q8()),
            None => s.error_q8(),
        };
        let error_q8 = if self.lowpass_q16 > 0 {
            self.lowpass_q8 = lowpass(self.lowpass_q8, error_q8, self.lowpass_q16);
            self.lowpass_q8
        } else {
            error_q8
        };
        match s.angle() {
            Some((phi, dphi)) => self.learn(table, phi, dphi, error_q8, s.freeze()),
            None => self.hold_for(Freeze::NoAngle, 0),
        }
    }

    /// Learns the tracking error `error_q8` (command − measured, gauge
    /// codes Q8) seen at `phi` after a step `dphi`, unless `freeze` says
    /// why not.
    #[inline]
    fn learn(
        &mut self,
        table: &LearnedTable,
        phi: SpindleAngle,
        dphi: i32,
        error_q8: i32,
        freeze: Option<Freeze>,
    ) {
        if self.gain_q16 == 0 {
            self.frozen = Some(Freeze::Disabled);
            return;
        }
        let freeze = freeze.or(if dphi <= 0 || dphi > MAX_DPHI {
            Some(Freeze::SpindleJump)
        } else {
            None
        });
        if let Some(r) = freeze {
            if matches!(r, Freeze::SpindleJump | Freeze::XJump) {
                self.hold_for(r, 0);
            }
            self.frozen = Some(r);
            self.last_bin = None;
            return;
        }
        if self.hold > 0 {
            self.hold -= 1;
            self.frozen = Some(self.hold_reason);
            self.last_bin = None;
            return;
        }
        self.frozen = None;
        let i = (phi.0 >> BIN_BITS) as usize;
        if let Some(b) = self.last_bin {
            if b != i {
                // Bin b is left: the bin whose last update it was is complete;
                // smooth it, and its predecessor a second time (two passes of
                // the 3-tap kernel = a 5-tap binomial for shift 2).
                let k = (b + BINS - self.lead) & MASK;
                table.q_filter(k, self.q_shift);
                table.q_filter(k + MASK, self.q_shift);
                if i == 0 {
                    self.passes = self.passes.saturating_add(1);
                }
            }
        }
        self.last_bin = Some(i);
        let j = (i + BINS - self.lead) & MASK;
        let f = ((phi.0 >> (BIN_BITS - 16)) & 0xFFFF) as i32;
        // κ · e · Δφ / bin: Σ over a bin is κ·ē. κ·Δφ/2⁷ < 2³¹ (κ < 1 in
        // Q16, 0 < Δφ ≤ 2²²), and its product with e (|e| ≤ 2²⁸, Q8) over
        // 2³³ is below 2²⁶. The clip (`learning_clip_uin`, ≤ 2²⁸) bounds
        // what one revolution adds to a bin to κ·clip, whatever the error
        // did: a one-off transient (a push the loop holds within the
        // following-error limit) is replayed a revolution later by at most
        // that, while an error that repeats is still learned, at that rate
        // per revolution until it is inside the clip.
        // (max/min, not clamp: clamp's min ≤ max assertion is a panic path
        // the handler must not have; clip_q8 ≥ 1 by construction.)
        let e_q8 = error_q8.max(-self.clip_q8).min(self.clip_q8);
        let k_dphi = (dphi >> 7) * self.gain_q16;
        let inc = ((i64::from(e_q8) * i64::from(k_dphi)) >> (BIN_BITS + 9)) as i32;
        // Shared between the two bins around the angle (|inc| < 2²⁶).
        let lo = ((i64::from(inc) * i64::from(65_536 - f)) >> 16) as i32;
        let hi = inc - lo;
        table.add(j, lo);
        table.add(j + 1, hi);
    }

    /// Keeps the learning frozen for `ticks` more ticks (after a jump of
    /// the spindle phase or of X: the next revolution is not comparable).
    fn hold_for(&mut self, reason: Freeze, ticks: u32) {
        self.hold = self.hold.max(ticks);
        self.hold_reason = reason;
        self.frozen = Some(reason);
        self.last_bin = None;
    }

    /// A gap in the samples (the learner fell behind and the tick dropped
    /// some): the bin accounting starts again, as after a spindle jump.
    pub(crate) fn lost_samples(&mut self) {
        self.hold_for(Freeze::SpindleJump, 0);
    }

    /// Why the learning is not running now (`None`: it is).
    pub fn frozen(&self) -> Option<Freeze> {
        self.frozen
    }

    /// Completed learning revolutions since the last clear.
    pub fn revolutions(&self) -> u32 {
        self.passes
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;
    use super::*;

    const TURN: f64 = 4_294_967_296.0;

    /// The learning's low-pass follows a step as its closed form
    /// `y_n = x·(1 − (1 − α)ⁿ)`, within the rounding's bound: each step
    /// rounds by ≤ ½ LSB and the filter forgets it by (1 − α) a step, so
    /// the error stays below ½/α LSB (20 LSB at 80 Hz, 20 kHz).
    #[test]
    fn learning_lowpass_follows_the_closed_form_step() {
        let alpha_q16 = 1_626; // 1 − e^{−2π·80/20000}
        let a = f64::from(alpha_q16) / 65_536.0;
        let x = 3 << 20;
        let mut y = 0;
        for n in 1..=3_000 {
            y = lowpass(y, x, alpha_q16);
            let exact = f64::from(x) * (1.0 - (1.0 - a).powi(n));
            assert!(
                (f64::from(y) - exact).abs() <= 0.5 / a + 1.0,
                "n {n}: {y} vs {exact}"
            );
        }
        // Never past its input: the clip's bound holds after it.
        assert!(y <= x);
    }

    /// A learner of the default design at 20 kHz with these learning
    /// parameters and no hum notch.
    fn learner(gain_q16: i32, lead: u32, q_shift: u32) -> Learner {
        let mut cfg = ServoConfig::at_rate(20_000).unwrap();
        cfg.learning_gain_q16 = gain_q16;
        cfg.learning_lead_bins = lead;
        cfg.learning_q_shift = q_shift;
        cfg.hum_canceller = None;
        Learner::new(&cfg)
    }

    fn sample(phi: u32, dphi: i32, error_q8: i32, freeze: Option<Freeze>) -> LearnSample {
        LearnSample::new(
            error_q8,
            Some((SpindleAngle(phi), dphi)),
            freeze,
            LearnRequests::default(),
        )
    }

    /// A constant error at every angle is learned to κ·e per revolution
    /// per bin, and the table ends at the error (the loop is not closed
    /// here: the "plant" is the table itself, y = c).
    #[test]
    fn learning_converges_on_a_periodic_error_at_any_speed() {
        for ticks_per_rev in [3000u32, 4000, 5000] {
            let mut r = learner((0.3 * 65536.0) as i32, 3, 2);
            let t = LearnedTable::new();
            let dphi = (TURN / f64::from(ticks_per_rev)) as u32;
            let mut phi = 0u32;
            for _ in 0..(ticks_per_rev * 40) {
                let ph = SpindleAngle(phi);
                let target =
                    1000.0 * libm::sin(2.0 * core::f64::consts::TAU * f64::from(phi) / TURN);
                let c = f64::from(t.correction(ph, dphi as i32).position_q8) / 256.0;
                let e = ((target - c) * 256.0) as i32;
                r.apply(&sample(phi, dphi as i32, e, None), &t);
                phi = phi.wrapping_add(dphi);
            }
            // residual after 40 revolutions at κ = 0.3: (0.7)^40 ~ 6e-7 plus
            // the Q-filter's steady forgetting at harmonic 2:
            // (1 − cos⁴(2π/256))/κ ≈ 0.8 %.
            let mut worst: f64 = 0.0;
            for k in 0..360 {
                let p = (k as f64 / 360.0 * TURN) as u32;
                let target = 1000.0 * libm::sin(2.0 * core::f64::consts::TAU * f64::from(p) / TURN);
                let c = f64::from(t.correction(SpindleAngle(p), 0).position_q8) / 256.0;
                worst = worst.max((target - c).abs());
            }
            assert!(worst < 10.0, "{ticks_per_rev}: {worst} codes of 1000");
            assert_eq!(r.revolutions(), 40 - 1);
        }
    }

    /// The learning of the design with `learning_clip_uin` = `clip_uin`
    /// (κ 0.3, lead 3, Q-filter shift 2: the scenarios'), no hum notch,
    /// and the Q8 codes of one µin.
    fn clipped_learner(clip_uin: f64) -> (Learner, f64) {
        let mut d = crate::servo::ServoDesign::brief(20_000);
        d.learning_clip_uin = clip_uin;
        d.hum_notch_q = 0.0;
        let cfg = d.config().unwrap();
        (Learner::new(&cfg), d.slide.codes_per_in() * 1e-6 * 256.0)
    }

    /// Runs `revs` revolutions of 4000 ticks (300 rpm at 20 kHz) with the
    /// loop following the learned reference exactly (y = c, so the error
    /// is `target(rev, tick) − c`, as in the convergence test above);
    /// returns the table's largest |entry| after each revolution, µin.
    fn run_revolutions(
        r: &mut Learner,
        t: &LearnedTable,
        per_uin: f64,
        revs: u32,
        target_uin: impl Fn(u32, u32) -> f64,
    ) -> std::vec::Vec<f64> {
        const TICKS: u32 = 4000;
        let dphi = (TURN / f64::from(TICKS)) as u32;
        let mut peaks = std::vec::Vec::new();
        for rev in 0..revs {
            for k in 0..TICKS {
                let phi = k * dphi;
                let c = f64::from(t.correction(SpindleAngle(phi), dphi as i32).position_q8);
                let e = target_uin(rev, k) * per_uin - c;
                r.apply(&sample(phi, dphi as i32, e as i32, None), t);
            }
            let peak = t.snapshot().iter().map(|v| v.unsigned_abs()).max().unwrap();
            peaks.push(f64::from(peak) / per_uin);
        }
        peaks
    }

    /// A one-off transient of the following-error push's size (3000 µin
    /// for 40 ms, the slide pushed out of the cut: command − gauge < 0) in
    /// revolution 2 of a cut whose error is otherwise zero: one
    /// revolution's update is at most κ·C per bin (the mean of clipped
    /// errors), so the correction replayed never exceeds κ·C (45 µin at
    /// C = 150, against κ·3000 = 900 unclipped; one LSB of rounding), and
    /// the revolutions after, in which the loop following the correction
    /// makes the error −c, unlearn it.
    #[test]
    fn a_one_off_transient_is_replayed_by_at_most_the_gain_times_the_clip() {
        let clip_uin = 150.0;
        let (mut r, per_uin) = clipped_learner(clip_uin);
        let t = LearnedTable::new();
        // 40 ms at 20 kHz, from a fifth of the revolution on.
        let push = |rev: u32, k: u32| {
            if rev == 2 && (800..1600).contains(&k) {
                -3000.0
            } else {
                0.0
            }
        };
        let peaks = run_revolutions(&mut r, &t, per_uin, 8, push);
        let bound = 0.3 * clip_uin + 1.0 / per_uin;
        let worst = peaks.iter().copied().fold(0.0, f64::max);
        assert!(
            worst <= bound,
            "the push replayed as {worst:.1} µin of correction, beyond κ·C = {bound:.1} µin (per revolution: {peaks:.1?})"
        );
        // It was learned up to the clip, not ignored: a fresh plateau
        // takes 0.84·κ of the error in its first revolution, clipped or
        // not (the Q-filter smooths each completed bin against its
        // successor while that is still half updated).
        assert!(peaks[2] >= 0.8 * 0.3 * clip_uin, "{peaks:.1?}");
        // Then unlearned: less every revolution, under half after five.
        assert!(
            peaks[3..].windows(2).all(|w| w[1] < w[0]) && peaks[3] < peaks[2],
            "{peaks:.1?}"
        );
        assert!(peaks[7] <= 0.5 * peaks[2], "{peaks:.1?}");
    }

    /// An error that repeats, with peaks 2.5 times the clip (the clip
    /// rate-limits the learning to κ·C per revolution, it does not stop
    /// it), is still learned: after 40 revolutions the table is the error
    /// within 2 % (the Q-filter's forgetting at harmonic 2 leaves 0.8 %).
    #[test]
    fn a_periodic_error_beyond_the_clip_is_still_learned() {
        let clip_uin = 150.0;
        let (mut r, per_uin) = clipped_learner(clip_uin);
        let t = LearnedTable::new();
        let amp = 2.5 * clip_uin;
        let shape = |k: u32| amp * libm::sin(2.0 * core::f64::consts::TAU * f64::from(k) / 4000.0);
        let peaks = run_revolutions(&mut r, &t, per_uin, 40, |_, k| shape(k));
        // The first revolution's update is clipped to κ·C.
        assert!(peaks[0] <= 0.3 * clip_uin + 1.0 / per_uin, "{peaks:.1?}");
        let dphi = (TURN / 4000.0) as u32;
        let worst = (0..4000u32)
            .map(|k| {
                let c = f64::from(t.correction(SpindleAngle(k * dphi), 0).position_q8) / per_uin;
                (shape(k) - c).abs()
            })
            .fold(0.0, f64::max);
        assert!(worst < 0.02 * amp, "{worst:.2} µin left of {amp} µin");
    }

    /// The velocity and acceleration of the correction are the angular
    /// derivatives of the learned shape times the angle step: for a learned
    /// A·sin(kθ) they match A·k·ω and −A·k²·ω² within the table's
    /// resolution.
    #[test]
    fn correction_rates_are_derivatives_of_the_table() {
        let t = LearnedTable::new();
        let a = 10_000.0;
        for i in 0..BINS {
            let v = a * 256.0 * libm::sin(2.0 * core::f64::consts::TAU * i as f64 / BINS as f64);
            t.set(i, v as i32);
        }
        let dphi = (TURN / 4000.0) as i32;
        let w = core::f64::consts::TAU / 4000.0; // rad per tick
        for k in 0..64 {
            let p = (k as f64 / 64.0 * TURN) as u32;
            let th = core::f64::consts::TAU * f64::from(p) / TURN;
            let c = t.correction(SpindleAngle(p), dphi);
            let v = f64::from(c.velocity_q16) / 65536.0;
            let acc = f64::from(c.accel_q16) / 65536.0;
            let v_exact = a * 2.0 * w * libm::cos(2.0 * th);
            let a_exact = -a * 4.0 * w * w * libm::sin(2.0 * th);
            assert!(
                (v - v_exact).abs() < 0.002 * a * 2.0 * w + 0.01,
                "{k}: {v} vs {v_exact}"
            );
            assert!(
                (acc - a_exact).abs() < 0.05 * a * 4.0 * w * w + 1e-4,
                "{k}: {acc} vs {a_exact}"
            );
        }
    }

    /// The table's second and third centred differences at node `k`
    /// (the module docs' D₂, D₃), Q8.
    fn differences(t: &LearnedTable, k: usize) -> (f64, f64) {
        let g = |j: usize| f64::from(t.get(j));
        let (m2, m1, p1, p2) = (k + BINS - 2, k + MASK, k + 1, k + 2);
        (
            (g(p1) - 2.0 * g(k) + g(m1)).abs(),
            (g(p2) - 2.0 * g(p1) + 2.0 * g(m1) - g(m2)).abs(),
        )
    }

    /// The correction expanded at φ₀ and stepped to φ against the table
    /// read at φ: the same bits at δ = 0 (the tick's fallback is the
    /// expansion's arithmetic), within the rounding inside φ₀'s bin, and
    /// within `CorrectionAhead`'s bound across a node, on smooth learned
    /// shapes and on a rough table, for steps up to the limit and a
    /// measured step off the predicted one.
    #[test]
    fn correction_step_is_the_direct_evaluation_within_its_bound() {
        let limit = DELTA_LIMIT;
        let mut seed = 0x2545_f491u32;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        let smooth = LearnedTable::new();
        let rough = LearnedTable::new();
        for i in 0..BINS {
            let th = core::f64::consts::TAU * i as f64 / BINS as f64;
            let v = 400.0 * libm::sin(th + 0.3)
                + 150.0 * libm::cos(3.0 * th)
                + 100.0 * libm::sin(8.0 * th + 1.0)
                + 20.0 * libm::sin(21.0 * th);
            smooth.set(i, (v * 256.0) as i32);
            rough.set(i, (rnd() % 512_000) as i32 - 256_000);
        }
        let mut crossed = 0;
        let mut worst = [0f64; 3];
        for t in [&smooth, &rough] {
            for _ in 0..4000 {
                let phi0 = SpindleAngle(rnd());
                let dphi0 = (rnd() % (1 << 22)) as i32 + 1;
                let dphi = dphi0 + (rnd() % 2001) as i32 - 1000;
                let e = t.ahead(phi0, dphi0);
                assert_eq!(e.step(phi0, dphi0), Some(t.correction(phi0, dphi0)));
                let d = (rnd() % (2 * limit as u32 + 1)) as i32 - limit;
                let phi = SpindleAngle(phi0.0.wrapping_add(d as u32));
                let s = e.step(phi, dphi).unwrap();
                let c = t.correction(phi, dphi);
                let (b0, b) = (phi0.0 >> BIN_BITS, phi.0 >> BIN_BITS);
                // The node crossed and the part of the step past it, bins.
                let (d2, d3, eps) = if b0 == b {
                    (0.0, 0.0, 0.0)
                } else {
                    crossed += 1;
                    let k = if d > 0 { b } else { b0 };
                    let past = phi.0.wrapping_sub(k << BIN_BITS) as i32;
                    let (d2, d3) = differences(t, k as usize);
                    (d2, d3, f64::from(past).abs() / f64::from(1u32 << BIN_BITS))
                };
                let i = phi0.0 >> BIN_BITS;
                let (t1, t2, t0, t3) = (
                    t.get(i as usize),
                    t.get(i as usize + 1),
                    t.get(i as usize + MASK),
                    t.get(i as usize + 2),
                );
                let ck = f64::from((t3 - t1) - (t2 - t0)).abs();
                let dd = f64::from(dphi.clamp(-MAX_DPHI, MAX_DPHI)).abs();
                let pos = f64::from(s.position_q8 - c.position_q8).abs();
                // The direct one drops φ's low 8 bits: a 2⁻¹⁶ of the slope
                // of φ's bin (φ₀'s, or it plus D₂).
                let pos_bound = d2 * eps + 2.0 + (f64::from(t2 - t1).abs() + d2) / 65_536.0;
                assert!(pos <= pos_bound, "position {pos} > {pos_bound}");
                let vel = f64::from(s.velocity_q16 - c.velocity_q16).abs();
                let vel_bound = (d3 * eps + 2.0 + (ck + d3) / 65_536.0) * dd / 131_072.0 + 1.0;
                assert!(vel <= vel_bound, "velocity {vel} > {vel_bound}");
                let acc = f64::from(s.accel_q16 - c.accel_q16).abs();
                let dd0 = f64::from(dphi0);
                // Each side's two truncations: below |Δφ|/2²¹ + 1.
                let acc_bound = (d3 * dd * dd + ck * (dd * dd - dd0 * dd0).abs()) / 2f64.powi(41)
                    + dd.max(dd0) / 2_097_152.0
                    + 1.0;
                assert!(acc <= acc_bound, "acceleration {acc} > {acc_bound}");
                if core::ptr::eq(t, &smooth) {
                    worst = [
                        worst[0].max(pos - pos_bound + d2 * eps),
                        worst[1].max(vel),
                        worst[2].max(acc),
                    ];
                }
            }
        }
        // Both sides of the bound were exercised: crossings, and within a
        // bin.
        assert!(crossed > 1000 && crossed < 7000, "{crossed}");
        std::println!(
            "smooth table: worst position {} Q8, velocity {} Q16, acceleration {} Q16",
            worst[0],
            worst[1],
            worst[2]
        );
    }

    /// Leaving a bin smooths the bin `lead` behind it with the 3-tap kernel
    /// d = (t[k−1] − 2t[k] + t[k+1]) >> q, then the bin before that a
    /// second time. An impulse of 2²⁰ in bin 100, lead 3, q = 2: leaving bin
    /// 104 gives bin 101 2²⁰/4 = 2¹⁸, then bin 100 2²⁰ + (−2²¹ + 2¹⁸)/4 =
    /// 2¹⁹ + 2¹⁶ (worked by hand from the kernel).
    #[test]
    fn leaving_a_bin_smooths_the_bin_lead_behind_and_its_predecessor() {
        let mut r = learner(20_000, 3, 2);
        let t = LearnedTable::new();
        t.set(100, 1 << 20);
        r.apply(&sample(104 << 24, 1 << 20, 0, None), &t);
        r.apply(&sample(105 << 24, 1 << 20, 0, None), &t);
        let snap = t.snapshot();
        assert_eq!(snap[101], 1 << 18);
        assert_eq!(snap[100], (1 << 19) + (1 << 16));
        assert_eq!(snap[99], 0);
        assert_eq!(snap.iter().filter(|&&v| v != 0).count(), 2);
    }

    /// One sample adds κ·e·Δφ/bin (κ = 20 000/2¹⁶, e = 2¹⁸ Q8, Δφ = 2²⁰ of a
    /// 2²⁴ bin: 5000 Q8) to the bin `lead` behind its angle and the next,
    /// shared by where in its bin the angle lies: a quarter of the way in,
    /// 3/4 (3750) to the first and 1/4 (1250) to the second.
    #[test]
    fn a_sample_is_shared_between_two_bins_by_its_place_in_its_bin() {
        // The error as it comes (no time low-pass): one sample's share.
        let mut cfg = ServoConfig::at_rate(20_000).unwrap();
        cfg.learning_gain_q16 = 20_000;
        cfg.learning_lead_bins = 3;
        cfg.learning_q_shift = 2;
        cfg.hum_canceller = None;
        cfg.learning_lowpass_q16 = 0;
        let mut r = Learner::new(&cfg);
        let t = LearnedTable::new();
        r.apply(&sample((104 << 24) + (1 << 22), 1 << 20, 1 << 18, None), &t);
        let snap = t.snapshot();
        assert_eq!((snap[101], snap[102]), (3750, 1250));
        assert_eq!(snap.iter().filter(|&&v| v != 0).count(), 2);
    }

    /// The fastest spindle the learning follows is a quarter bin per tick,
    /// 1171.875 rpm at 20 kHz (a turn is 2³² counts): a step of exactly
    /// that is motion and is learned; one count more is a jump.
    #[test]
    fn a_quarter_bin_step_is_learned_and_one_count_more_is_a_jump() {
        let quarter_bin = (1171.875 / 60.0 / 20_000.0 * 2f64.powi(32)) as i32;
        let mut r = learner(20_000, 3, 2);
        let t = LearnedTable::new();
        r.apply(&sample(1 << 24, quarter_bin, 1 << 20, None), &t);
        assert_eq!(r.frozen(), None);
        assert!(t.peak_code() > 0);
        let t = LearnedTable::new();
        r.apply(&sample(1 << 25, quarter_bin + 1, 1 << 20, None), &t);
        assert_eq!(r.frozen(), Some(Freeze::SpindleJump));
        assert_eq!(t.peak_code(), 0);
    }

    #[test]
    fn backward_or_huge_angle_steps_freeze_the_learning() {
        let mut r = learner(20_000, 0, 8);
        let t = LearnedTable::new();
        r.apply(&sample(1000, -5, 1 << 12, None), &t);
        assert_eq!(r.frozen(), Some(Freeze::SpindleJump));
        r.apply(&sample(1000, 1 << 23, 1 << 12, None), &t);
        assert_eq!(r.frozen(), Some(Freeze::SpindleJump));
        assert_eq!(t.peak_code(), 0);
        r.apply(&sample(1000, 1000, 1 << 12, Some(Freeze::NoAngle)), &t);
        assert_eq!(r.frozen(), Some(Freeze::NoAngle));
        let mut req = LearnRequests::default();
        req.hold(Freeze::XJump, 3);
        let hold = LearnSample::new(1 << 12, Some((SpindleAngle(1000), 1000)), None, req);
        // The hold applies from its own sample on: three ticks frozen.
        r.apply(&hold, &t);
        assert_eq!(r.frozen(), Some(Freeze::XJump));
        for _ in 0..2 {
            r.apply(&sample(1000, 1000, 1 << 12, None), &t);
            assert_eq!(r.frozen(), Some(Freeze::XJump));
        }
        r.apply(&sample(1000, 1 << 20, 1 << 24, None), &t);
        assert_eq!(r.frozen(), None);
        // No angle: frozen with that reason; a clear forgets the table.
        let none = LearnSample::new(0, None, None, LearnRequests::default());
        r.apply(&none, &t);
        assert_eq!(r.frozen(), Some(Freeze::NoAngle));
        assert!(t.peak_code() > 0);
        let mut clear = LearnRequests::NONE;
        clear.clear();
        r.apply(&LearnSample::new(0, None, None, clear), &t);
        assert_eq!(t.peak_code(), 0);
    }

    /// A constant error forever drives every bin to the clamp and no
    /// further: the learning integrates the error (gain 60 000/2¹⁶, 97
    /// revolutions of 4096 samples) up to +ENTRY_LIMIT (the error is
    /// positive: the command above the gauge). The Q-filter then takes at
    /// most 1 LSB (Q8) off an entry per pass, twice a revolution: its
    /// arithmetic shift floors a second difference of −1 or −2 (a
    /// neighbour a step below the clamp) to −1. So every entry ends within
    /// 2 LSB below the clamp, never above it. A learner that learned
    /// nothing (or half), or one that wrapped past the clamp, would not.
    #[test]
    fn table_is_bounded() {
        let mut r = learner(60_000, 0, 16);
        let t = LearnedTable::new();
        let mut phi = 0u32;
        for _ in 0..400_000 {
            r.apply(&sample(phi, 1 << 20, i32::MAX / 4, None), &t);
            phi = phi.wrapping_add(1 << 20);
        }
        assert!(t.peak_code() >= (ENTRY_LIMIT - 2) >> 8);
        let s = t.snapshot();
        assert!(
            s.iter()
                .all(|&v| (ENTRY_LIMIT - 2..=ENTRY_LIMIT).contains(&v)),
            "entries off the clamp: {:?}",
            s.iter()
                .filter(|&&v| !(ENTRY_LIMIT - 2..=ENTRY_LIMIT).contains(&v))
                .take(4)
                .collect::<std::vec::Vec<_>>()
        );
    }

    /// Two holds before one sample leave the longer time and the later
    /// reason, a clear survives a hold, and a hold beyond the sample's
    /// 24 bits is carried as the longest it can say (14 minutes at 20 kHz),
    /// not wrapped into a short one.
    #[test]
    fn requests_merge_holds_and_cap_their_ticks() {
        let mut r = LearnRequests::NONE;
        assert_eq!((r.clears(), r.held()), (false, None));
        r.hold(Freeze::NotEngaged, 400);
        r.clear();
        r.hold(Freeze::XJump, 20);
        assert_eq!((r.clears(), r.held()), (true, Some((Freeze::XJump, 400))));
        r.hold(Freeze::NotEngaged, 20_000);
        assert_eq!(r.held(), Some((Freeze::NotEngaged, 20_000)));
        let mut long = LearnRequests::NONE;
        long.hold(Freeze::XJump, u32::MAX);
        let s = LearnSample::new(0, None, None, long);
        assert_eq!(s.requests().held(), Some((Freeze::XJump, (1 << 24) - 1)));
        assert!(!s.requests().clears());
    }

    #[test]
    fn samples_round_trip_through_their_words() {
        assert_eq!(Freeze::from_code(Freeze::code(None)), None);
        for f in Freeze::ALL {
            assert_eq!(Freeze::from_code(Freeze::code(Some(f))), Some(f));
        }
        for (angle, freeze, clear, hold) in [
            (None, None, false, None),
            (
                Some((SpindleAngle(u32::MAX), -7)),
                Some(Freeze::Null),
                true,
                Some((Freeze::XJump, 20_000)),
            ),
            (
                Some((SpindleAngle(12_345), 1 << 22)),
                Some(Freeze::Disabled),
                false,
                Some((Freeze::NotEngaged, 786)),
            ),
        ] {
            let mut req = LearnRequests::NONE;
            if clear {
                req.clear();
            }
            if let Some((r, t)) = hold {
                req.hold(r, t);
            }
            let s = LearnSample::new(-123_456, angle, freeze, req);
            assert_eq!(
                (s.error_q8(), s.angle(), s.freeze()),
                (-123_456, angle, freeze)
            );
            assert_eq!((s.requests().clears(), s.requests().held()), (clear, hold));
        }
    }
}
