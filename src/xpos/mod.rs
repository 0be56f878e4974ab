//! X-slide position: the legacy half-mil interrupt of the 1983 machine, and a
//! modern count-based position.
//!
//! # Legacy interface (chapter 3, appendix A)
//! The interferometer's BCD up/down counter chain raises an interrupt each
//! time its ten-thousandths digit *becomes* 0 or 5 (from either side), and
//! the board latches the units, tenths, hundredths and thousandths digits
//! plus two flags ([`XLatchWord`]). What [`LegacyX::on_interrupt`] does,
//! in the order of the 8080 program (`NTYS` ff.), and what it adds:
//!
//! 1. **Debounce** (appendix A lines 114-118): the 8080 compared the latched
//!    flag byte with the previous one and ignored the interrupt if it was
//!    unchanged. Fast direction reversals of the counters across a 4|5 or
//!    9|0 boundary re-enter the same 0/5 state and fire again with the same
//!    flags: those are the false interrupts. Same rule here (both flags).
//! 2. **BCD validation** (new): a nibble above 9, or a bit outside the
//!    layout, is [`Fault::XBadBcd`]: a number must never be made from it.
//! 3. **Null zone** (lines 125-140): at X ≥ the null-zone start (7.2 in; the
//!    8080 tested the two most significant digits ≥ 72) every coefficient is
//!    set to zero and strobed.
//! 4. **Schedule** (lines 182-191): C02 at every accepted interrupt; C01 when
//!    the ten-thousandths digit is 0; C00 and C03 when, in addition, the
//!    thousandths digit is 0. Then one strobe. (Line 224 `JZ $+4` adds the
//!    half step on the *other* polarity of bit 6 than the C01 test of line
//!    185 uses; read literally that counts every whole mil as an odd
//!    half-mil, a one-step sawtooth the text and Figure 2-5 do not show, so
//!    we read it as a slip of the listing: position = 2·mils + half.)
//! 5. **Glitch watch** (new): accepted positions normally move by exactly one
//!    half-mil. A repeat (debounced), a step of 2..=`max_jump` half-mils
//!    (a missed interrupt or a carry caught mid-ripple), or a latch whose
//!    mil-zero flag contradicts its thousandths digit is an *anomaly*;
//!    `storm_count` anomalies within `storm_window_ticks` is
//!    [`Fault::XGlitchStorm`], and so is any step beyond `max_jump` (the
//!    counter chain is no longer believable). Reaction: ramp to null.
//! 6. **Re-sync** (new, configurable): the 8080 refreshed C01, C00, C03 only
//!    on their schedule, so after start-up or on leaving the null zone they
//!    kept stale values for up to 10 mil of travel (C00 at 7.2 in is
//!    −79 µin). With `refresh_all_on_entry` every coefficient is refreshed on
//!    those events; off, the 8080's exact behaviour.
//!
//! Cost: a handful of shifts and compares, no division but one by the
//! constant 1000 (a multiply): well inside the X-event budget.
//!
//! # Modern interface
//! [`CountX`] maps a quadrature/interferometer count to X with a
//! configurable counts-per-inch (sign = direction) and zero offset, by one
//! multiply by a reciprocal computed at configuration. The loop tick
//! re-interpolates the coefficients at that X every tick
//! ([`crate::command::CommandGen::coefficients_into`]); when the count has
//! not changed since the last tick X is bit-identical, so skipping the
//! re-interpolation then changes nothing but the cost.

pub mod columns;
pub mod legacy_output;

use crate::hw::XLatchWord;
use crate::safety::Fault;
use crate::units::XInches;
use fixed::types::I8F24;

/// Coefficient update set: bit j = C0j of eq 2-19.
pub type UpdateMask = u8;
pub const C00: UpdateMask = 1 << 0;
pub const C01: UpdateMask = 1 << 1;
pub const C02: UpdateMask = 1 << 2;
pub const C03: UpdateMask = 1 << 3;
pub const ALL: UpdateMask = C00 | C01 | C02 | C03;

/// Half-mils (0.0005 in) per inch.
pub const HALF_MILS_PER_INCH: u32 = 2000;
/// Positions the latched digits can show: 0.0000 ..= 9.9995 in.
pub const DISPLAY_HALF_MILS: u32 = 20_000;

/// Legacy X configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LegacyConfig {
    /// Null zone from this position on (half-mils; 14400 = 7.2 in).
    pub null_from_half_mils: u32,
    /// Anomalies that make a storm when they fall within the window.
    pub storm_count: u8,
    /// Window of the storm test, in [`crate::hw::Clock`] ticks.
    pub storm_window_ticks: u32,
    /// Largest believable step between accepted interrupts, half-mils.
    pub max_jump_half_mils: u32,
    /// Refresh all four coefficients on the first interrupt and on leaving
    /// the null zone (the 8080 did not).
    pub refresh_all_on_entry: bool,
}

impl LegacyConfig {
    /// Null zone at `x_null` (rounded to the nearest half-mil, so the
    /// table's 7.2 in in `I8F24` gives exactly the 8080's "≥ 72").
    pub fn new(x_null: XInches, ticks_per_s: u32) -> Self {
        let hm = (i64::from(x_null.to_bits()) * i64::from(HALF_MILS_PER_INCH) + (1 << 23)) >> 24;
        Self {
            null_from_half_mils: hm.clamp(0, i64::from(u32::MAX)) as u32,
            storm_count: 16,
            // 16 anomalies within 2 ms: 8 kHz of false interrupts, far above
            // any dither of a healthy slide yet far below a broken line.
            storm_window_ticks: ticks_per_s / 500,
            max_jump_half_mils: 8,
            refresh_all_on_entry: true,
        }
    }
}

/// What an interrupt changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct XUpdate {
    /// Latched position in half-mils (0.0005 in) from the counter's zero.
    pub half_mils: u32,
    /// The same position in the core's X format.
    pub x: XInches,
    /// Which of C00..C03 to recompute and write before the strobe.
    pub update: UpdateMask,
    /// X is in the null zone: all coefficients are zero.
    pub null: bool,
}

/// Outcome of one legacy interrupt.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum XEvent {
    /// Debounced (same half-mil state): nothing to output, no strobe.
    Ignored,
    /// Accepted: recompute the coefficients in `update`, write, strobe once.
    Update(XUpdate),
}

const RING: usize = 32;

/// Latched-digit decoder, debounce, schedule and glitch watch of the legacy
/// X interface. Holds its state between interrupts; no allocation.
#[derive(Clone, Debug)]
pub struct LegacyX {
    cfg: LegacyConfig,
    last_flags: Option<u32>,
    last_half_mils: Option<u32>,
    in_null: bool,
    anomalies: [u32; RING],
    next: usize,
    seen: usize,
}

/// Half-mils of a latch word, or `None` if a digit is not BCD or a bit
/// outside the layout is set.
pub fn decode(word: XLatchWord) -> Option<u32> {
    let w = word.0;
    if w >> 18 != 0 {
        return None;
    }
    let d = w & 0xFFFF;
    // A nibble above 9 carries into the next one when 6 is added to it:
    // the carry bits are where the sum differs from the carry-less sum.
    let carries = (d + 0x6666) ^ d ^ 0x6666;
    if carries & 0x1_1110 != 0 {
        return None;
    }
    // BCD to binary by nibble arithmetic (two multiplies, no loop): each
    // byte hi·16 + lo → hi·10 + lo, then the two bytes h·256 + l → h·100 + l.
    let bytes = d - ((d >> 4) & 0x0F0F) * 6;
    let mils = (bytes & 0xFF) + (bytes >> 8) * 100;
    Some(mils * 2 + u32::from(w & XLatchWord::HALF_MIL != 0))
}

/// X in `I8F24` of a position in half-mils (rounded to the nearest LSB).
pub fn half_mils_to_x(half_mils: u32) -> XInches {
    // 0.0005 in = 8388.608 LSB: the integer part times hm is exact, the
    // fraction is rounded with 32-bit arithmetic only (a division by a
    // constant is a multiply; a 64-bit one would be a library call).
    let hm = half_mils.min(200_000);
    let bits = hm * 8388 + (hm * 608 + 500) / 1000;
    XInches(I8F24::from_bits(bits.min(i32::MAX as u32) as i32))
}

impl LegacyX {
    pub fn new(cfg: LegacyConfig) -> Self {
        Self {
            cfg,
            last_flags: None,
            last_half_mils: None,
            in_null: false,
            anomalies: [0; RING],
            next: 0,
            seen: 0,
        }
    }

    pub fn config(&self) -> &LegacyConfig {
        &self.cfg
    }

    /// Last accepted position, half-mils.
    pub fn half_mils(&self) -> Option<u32> {
        self.last_half_mils
    }

    /// Records an anomaly at `now`; `Err` if it completes a storm.
    fn anomaly(&mut self, now: u32) -> Result<(), Fault> {
        let n = usize::from(self.cfg.storm_count).clamp(1, RING);
        if let Some(slot) = self.anomalies.get_mut(self.next % RING) {
            *slot = now;
        }
        self.next = (self.next + 1) % RING;
        self.seen = self.seen.saturating_add(1);
        if self.seen >= n {
            // The anomaly n−1 before this one.
            let oldest = self
                .anomalies
                .get((self.next + RING - n) % RING)
                .copied()
                .unwrap_or(now);
            if now.wrapping_sub(oldest) < self.cfg.storm_window_ticks {
                return Err(Fault::XGlitchStorm);
            }
        }
        Ok(())
    }

    /// The half-mil interrupt. `now` is the [`crate::hw::Clock`] reading at
    /// the interrupt (only used for the storm window).
    pub fn on_interrupt(&mut self, word: XLatchWord, now: u32) -> Result<XEvent, Fault> {
        let flags = word.0 & (XLatchWord::HALF_MIL | XLatchWord::MIL_ZERO);
        if self.last_flags == Some(flags) {
            self.anomaly(now)?;
            return Ok(XEvent::Ignored);
        }
        let hm = decode(word).ok_or(Fault::XBadBcd)?;
        self.last_flags = Some(flags);
        let thousandths = word.0 & 0xF;
        if (word.0 & XLatchWord::MIL_ZERO != 0) != (thousandths == 0) {
            self.anomaly(now)?;
        }
        let first = match self.last_half_mils {
            None => true,
            Some(prev) => {
                // The four-digit display wraps (ten's complement below zero:
                // 0.0000 − 0.0005 reads 9.9995), so distance is modular.
                let d = prev.abs_diff(hm);
                let step = d.min(DISPLAY_HALF_MILS - d);
                if step > self.cfg.max_jump_half_mils {
                    return Err(Fault::XGlitchStorm);
                }
                if step != 1 {
                    self.anomaly(now)?;
                }
                false
            }
        };
        self.last_half_mils = Some(hm);
        let x = half_mils_to_x(hm);
        if hm >= self.cfg.null_from_half_mils {
            self.in_null = true;
            return Ok(XEvent::Update(XUpdate {
                half_mils: hm,
                x,
                update: ALL,
                null: true,
            }));
        }
        let whole_mil = word.0 & XLatchWord::HALF_MIL == 0;
        let mut update = C02;
        if whole_mil {
            update |= C01;
            if thousandths == 0 {
                update |= C00 | C03;
            }
        }
        if self.cfg.refresh_all_on_entry && (first || self.in_null) {
            update = ALL;
        }
        self.in_null = false;
        Ok(XEvent::Update(XUpdate {
            half_mils: hm,
            x,
            update,
            null: false,
        }))
    }
}

/// Builds a latch word from a position (half-mils) the way the 1983 latch
/// presents it: four BCD digits, the half-mil flag, the mil-zero flag.
/// Positions of 10 in and more wrap like the display's digits.
pub fn latch_word(half_mils: u32) -> XLatchWord {
    let mils = (half_mils / 2) % 10_000;
    let d = [mils / 1000, (mils / 100) % 10, (mils / 10) % 10, mils % 10];
    let mut w = (d[0] << 12) | (d[1] << 8) | (d[2] << 4) | d[3];
    if half_mils % 2 == 1 {
        w |= XLatchWord::HALF_MIL;
    }
    if d[3] == 0 {
        w |= XLatchWord::MIL_ZERO;
    }
    XLatchWord(w)
}

/// Modern X: a count (interferometer or glass scale) to X.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CountConfig {
    /// Counts per inch of X; negative if the count falls as X grows.
    pub counts_per_inch: i32,
    /// Count at X = 0 (the spindle axis).
    pub zero_count: u32,
    /// Largest believable change between two loop ticks, counts.
    pub max_step_counts: u32,
}

/// Count-based X with its reciprocal precomputed.
#[derive(Clone, Copy, Debug)]
pub struct CountX {
    cfg: CountConfig,
    /// X bits per count, Q`shift`.
    mult: i64,
    shift: u32,
    last: Option<u32>,
}

impl CountX {
    /// `None` if counts_per_inch is 0.
    pub fn new(cfg: CountConfig) -> Option<Self> {
        if cfg.counts_per_inch == 0 {
            return None;
        }
        let cpi = i64::from(cfg.counts_per_inch);
        // Largest shift with |mult| < 2^31, so count·mult fits an i64.
        let mut shift = 38u32;
        while shift > 0 && ((1i64 << (24 + shift)) / cpi.abs()) >= (1 << 31) {
            shift -= 1;
        }
        let mult = ((1i64 << (24 + shift)) + cpi.abs() / 2) / cpi.abs() * cpi.signum();
        Some(Self {
            cfg,
            mult,
            shift,
            last: None,
        })
    }

    /// X at a count (wrapping difference from the zero count), saturating.
    #[inline]
    pub fn x(&self, count: u32) -> XInches {
        let d = i64::from(count.wrapping_sub(self.cfg.zero_count) as i32);
        let bits = (d * self.mult + (1 << self.shift >> 1)) >> self.shift;
        XInches(I8F24::from_bits(
            bits.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
        ))
    }

    /// X at this loop tick's count; a jump beyond `max_step_counts` since
    /// the last tick is [`Fault::XGlitchStorm`].
    pub fn on_tick(&mut self, count: u32) -> Result<XInches, Fault> {
        if let Some(prev) = self.last {
            if (count.wrapping_sub(prev) as i32).unsigned_abs() > self.cfg.max_step_counts {
                self.last = Some(count);
                return Err(Fault::XGlitchStorm);
            }
        }
        self.last = Some(count);
        Ok(self.x(count))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    use super::*;

    fn cfg() -> LegacyConfig {
        LegacyConfig::new(XInches::from_f64(7.2), 1_000_000)
    }

    /// The nibble-arithmetic decode against digit-by-digit decoding, for
    /// every 16-bit pattern and both half-mil states.
    #[test]
    fn decode_matches_digit_by_digit_for_every_word() {
        for w in 0u32..=0xFFFF {
            let digits = [w >> 12, (w >> 8) & 0xF, (w >> 4) & 0xF, w & 0xF];
            let naive = digits
                .iter()
                .try_fold(0u32, |m, &d| (d <= 9).then_some(m * 10 + d));
            for half in [0, XLatchWord::HALF_MIL] {
                let want = naive.map(|m| m * 2 + u32::from(half != 0));
                assert_eq!(decode(XLatchWord(w | half)), want, "{w:#x}");
            }
        }
        assert_eq!(decode(XLatchWord(1 << 18)), None);
    }

    #[test]
    fn decode_and_word_round_trip() {
        for hm in [0u32, 1, 2, 19, 20, 199, 200, 14399, 14400, 19999] {
            assert_eq!(decode(latch_word(hm)), Some(hm));
        }
        // 3.2415 in = 6483 half-mils.
        assert_eq!(
            decode(XLatchWord(0x3141 | XLatchWord::HALF_MIL)),
            Some(6283)
        );
        assert_eq!(
            half_mils_to_x(6483).to_f64(),
            XInches::from_f64(3.2415).to_f64()
        );
        assert_eq!(cfg().null_from_half_mils, 14400);
    }

    #[test]
    fn non_bcd_is_a_fault_not_a_number() {
        let mut x = LegacyX::new(cfg());
        for bad in [0x000A, 0x00B0, 0x0C00, 0xF000, 0x1234 | (1 << 20)] {
            assert_eq!(x.on_interrupt(XLatchWord(bad), 0), Err(Fault::XBadBcd));
        }
    }

    #[test]
    fn schedule_of_the_8080() {
        let mut x = LegacyX::new(LegacyConfig {
            refresh_all_on_entry: false,
            ..cfg()
        });
        let mut t = 0;
        let mut ev = |hm: u32| {
            t += 10_000;
            match x.on_interrupt(latch_word(hm), t).unwrap() {
                XEvent::Update(u) => u.update,
                XEvent::Ignored => 0xFF,
            }
        };
        // 1.2340 in: whole mil, mil digit 4 → C02, C01.
        assert_eq!(ev(2468), C02 | C01);
        assert_eq!(ev(2469), C02); // 1.2345
        assert_eq!(ev(2470), C02 | C01); // 1.2350
                                         // 1.2400: thousandths 0 → all four.
        for hm in 2471..2480 {
            ev(hm);
        }
        assert_eq!(ev(2480), ALL);
        assert_eq!(ev(2481), C02); // 1.2405: half-mil, C00/C03 wait
    }

    #[test]
    fn repeated_state_is_ignored_and_a_storm_faults() {
        let mut x = LegacyX::new(cfg());
        assert!(matches!(
            x.on_interrupt(latch_word(100), 0),
            Ok(XEvent::Update(_))
        ));
        // Slow dither (one repeat per ms) is harmless for ever.
        for k in 1..100u32 {
            assert_eq!(
                x.on_interrupt(latch_word(100), k * 1000),
                Ok(XEvent::Ignored)
            );
        }
        // A burst of 16 within 2 ms is a storm.
        let mut r = Ok(XEvent::Ignored);
        for k in 0..16u32 {
            r = x.on_interrupt(latch_word(100), 200_000 + k * 100);
        }
        assert_eq!(r, Err(Fault::XGlitchStorm));
    }

    /// A storm is `storm_count` anomalies within the window, whatever the
    /// count: at 4, three repeats 10 ms apart are not one, four within
    /// 1.5 ms (of the 2 ms window at 1 MHz) are, at the fourth.
    #[test]
    fn a_storm_is_its_count_of_anomalies_within_the_window_at_any_count() {
        let mut c = cfg();
        c.storm_count = 4;
        let mut x = LegacyX::new(c);
        assert!(matches!(
            x.on_interrupt(latch_word(100), 0),
            Ok(XEvent::Update(_))
        ));
        for t in [10_000, 20_000, 30_000, 100_000, 100_500, 101_000] {
            assert_eq!(x.on_interrupt(latch_word(100), t), Ok(XEvent::Ignored));
        }
        assert_eq!(
            x.on_interrupt(latch_word(100), 101_500),
            Err(Fault::XGlitchStorm)
        );
    }

    /// The window is open at its end: 16 anomalies spanning exactly the
    /// 2 000 ticks are not a storm, spanning 1 999 they are.
    #[test]
    fn sixteen_anomalies_spanning_the_whole_window_are_not_a_storm() {
        for (last, storm) in [(102_000, false), (101_999, true)] {
            let mut x = LegacyX::new(cfg());
            assert!(matches!(
                x.on_interrupt(latch_word(100), 0),
                Ok(XEvent::Update(_))
            ));
            for _ in 0..15 {
                assert_eq!(
                    x.on_interrupt(latch_word(100), 100_000),
                    Ok(XEvent::Ignored)
                );
            }
            let r = x.on_interrupt(latch_word(100), last);
            assert_eq!(r == Err(Fault::XGlitchStorm), storm, "{last}: {r:?}");
        }
    }

    /// Crossing the spindle axis: the counter borrows through zero and the
    /// display reads 9.9995 in, a one-step move that lands in the null zone
    /// (as with the 8080), not a glitch.
    #[test]
    fn crossing_zero_is_a_step_into_the_null_zone() {
        let mut x = LegacyX::new(cfg());
        x.on_interrupt(latch_word(1), 0).unwrap();
        x.on_interrupt(latch_word(0), 1000).unwrap();
        let XEvent::Update(u) = x.on_interrupt(latch_word(19_999), 2000).unwrap() else {
            panic!()
        };
        assert!(u.null);
        let XEvent::Update(u) = x.on_interrupt(latch_word(0), 3000).unwrap() else {
            panic!()
        };
        assert!(!u.null && u.update == ALL, "back on the table: refresh all");
    }

    #[test]
    fn implausible_jump_faults() {
        let mut x = LegacyX::new(cfg());
        x.on_interrupt(latch_word(100), 0).unwrap();
        assert_eq!(
            x.on_interrupt(latch_word(121), 1000),
            Err(Fault::XGlitchStorm)
        );
    }

    #[test]
    fn null_zone_and_resync_on_leaving_it() {
        let mut x = LegacyX::new(cfg());
        let XEvent::Update(u) = x.on_interrupt(latch_word(14401), 0).unwrap() else {
            panic!()
        };
        assert!(u.null && u.update == ALL);
        let XEvent::Update(u) = x.on_interrupt(latch_word(14400), 10).unwrap() else {
            panic!()
        };
        assert!(u.null, "7.2000 in is null, as the 8080's `CPI 72H`");
        let XEvent::Update(u) = x.on_interrupt(latch_word(14399), 20).unwrap() else {
            panic!()
        };
        assert!(
            !u.null && u.update == ALL,
            "leaving the null zone refreshes all"
        );
    }

    #[test]
    fn count_x_scales_and_flags_jumps() {
        // 1 µin counts, reversed, zero at 1_000_000.
        let mut c = CountX::new(CountConfig {
            counts_per_inch: -1_000_000,
            zero_count: 1_000_000,
            max_step_counts: 50_000,
        })
        .unwrap();
        let x = c.on_tick(1_000_000u32.wrapping_sub(3_241_593)).unwrap();
        assert!((x.to_f64() - 3.241593).abs() < 1e-7, "{x:?}");
        assert_eq!(
            c.on_tick(1_000_000u32.wrapping_sub(3_000_000)),
            Err(Fault::XGlitchStorm)
        );
        // Wrap-around of the counter is a small step.
        let mut w = CountX::new(CountConfig {
            counts_per_inch: 10_000,
            zero_count: u32::MAX - 5,
            max_step_counts: 100,
        })
        .unwrap();
        assert!((w.on_tick(u32::MAX).unwrap().to_f64() - 0.0005).abs() < 1e-7);
        assert!((w.on_tick(4).unwrap().to_f64() - 0.001).abs() < 1e-7);
        assert!(CountX::new(CountConfig {
            counts_per_inch: 0,
            zero_count: 0,
            max_step_counts: 1
        })
        .is_none());
    }

    mod prop {
        use super::*;
        use proptest::prelude::*;

        proptest! {
            /// The half-mil to X conversion is exact to half an LSB of
            /// `I8F24` and strictly increasing over the whole display.
            #[test]
            fn half_mils_to_x_is_nearest_and_increasing(hm in 0u32..DISPLAY_HALF_MILS) {
                let x = half_mils_to_x(hm).to_bits();
                let exact = f64::from(hm) * 0.0005 * 16_777_216.0;
                prop_assert!((f64::from(x) - exact).abs() <= 0.5, "{}: {} vs {}", hm, x, exact);
                prop_assert!(half_mils_to_x(hm + 1).to_bits() > x);
            }

            /// A slide dithering by single half-mils, with repeated latches
            /// (fast reversals: the same state again) spaced slower than a
            /// storm, never faults: every repeat is debounced, every move
            /// is accepted at the position the digits say (a decimal reading
            /// of the word, not `decode`), and C02 is in every update.
            #[test]
            fn dither_with_repeats_is_debounced_not_a_fault(
                start in 300u32..14_000,
                moves in proptest::collection::vec((-1i32..=1, 1u32..4), 1..300),
            ) {
                let mut x = LegacyX::new(cfg());
                let mut hm = start;
                let mut now = 0u32;
                x.on_interrupt(latch_word(hm), now).unwrap();
                for (step, repeats) in moves {
                    if step == 0 {
                        continue;
                    }
                    hm = hm.saturating_add_signed(step);
                    // 1 ms apart: far slower than 16 anomalies in 2 ms.
                    now += 1000;
                    let w = latch_word(hm);
                    let digits = [w.0 >> 12 & 0xF, w.0 >> 8 & 0xF, w.0 >> 4 & 0xF, w.0 & 0xF];
                    let mils = digits.iter().fold(0, |m, d| m * 10 + d);
                    let XEvent::Update(u) = x.on_interrupt(w, now).unwrap() else {
                        panic!("a move to {hm} was ignored");
                    };
                    prop_assert_eq!(u.half_mils, mils * 2 + (w.0 >> 16 & 1));
                    prop_assert!(u.update & C02 != 0);
                    for _ in 1..repeats {
                        now += 1000;
                        prop_assert_eq!(x.on_interrupt(w, now), Ok(XEvent::Ignored));
                    }
                }
            }
        }
    }
}
