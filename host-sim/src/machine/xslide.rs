//! The X slide as the firmware sees it: a feed profile, the interferometer's
//! 1 µin up/down count, and the 1983 BCD counter chain with its half-mil
//! interrupt logic and latch (chapter 3, Figure 3-9).
//!
//! # What is modelled
//! * **Position** `x(t)`: piecewise-constant feed segments (in/min, either
//!   sign), plus the slide's vibration (a sinusoid, amplitude in µin) and a
//!   seeded random jitter: near a digit boundary these make the counter run
//!   back and forth.
//! * **Counter chain**: the interferometer's 1 µin pulses drive a chain of
//!   BCD up/down counters (display `d.dddddd`). The count is kept as an
//!   integer number of µin; the model steps it one count at a time, so
//!   every intermediate state is visited, as in the hardware.
//! * **Half-mil interrupt**: the decoder on the ten-thousandths digit fires
//!   when that digit *becomes* 0 or 5, from either side (4→5, 6→5, 9→0,
//!   1→0). The latch takes the units, tenths, hundredths and thousandths
//!   digits and the two flags ([`zslide::hw::XLatchWord`]).
//! * **False interrupts**: a fast reversal across a 4|5, 5|6, 9|0 or 0|1
//!   boundary re-enters the same state and fires again with the same flags
//!   (what the 8080's debounce was for).
//! * **Ripple-latch glitch**: on an up-count 9→0 of the ten-thousandths
//!   digit the carry into the thousandths digit (and beyond) is still
//!   rippling when the latch strobes; with probability `ripple_prob` the
//!   latch holds the higher digits from *before* the carry (e.g. 1.2340
//!   latched for 1.2350), flags included.
//!
//! Randomness is a seeded ChaCha8 stream: a run is reproducible from its seed.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use zslide::hw::XLatchWord;

/// µin per inch: the interferometer's count.
pub const COUNTS_PER_INCH: f64 = 1.0e6;

/// One feed segment: from `t_start_s` on, X moves at `feed_in_per_min`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeedSegment {
    pub t_start_s: f64,
    pub feed_in_per_min: f64,
}

/// Configuration of the X-slide model.
#[derive(Clone, Debug, PartialEq)]
pub struct XSlideConfig {
    /// X at t = 0, inches.
    pub x0_in: f64,
    /// Feed segments, in time order (the first should start at 0).
    pub feed: Vec<FeedSegment>,
    /// Vibration amplitude, µin, and frequency, Hz.
    pub vibration_uin: f64,
    pub vibration_hz: f64,
    /// Uniform random jitter added to each sample, ± µin.
    pub jitter_uin: f64,
    /// Probability that the latch catches a carry mid-ripple.
    pub ripple_prob: f64,
    pub seed: u64,
}

impl Default for XSlideConfig {
    fn default() -> Self {
        Self {
            x0_in: 0.0,
            feed: vec![FeedSegment {
                t_start_s: 0.0,
                feed_in_per_min: 0.2,
            }],
            vibration_uin: 0.0,
            vibration_hz: 120.0,
            jitter_uin: 0.0,
            ripple_prob: 0.0,
            seed: 1,
        }
    }
}

/// One half-mil interrupt: when, what was latched, and the truth.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct XInterrupt {
    pub t_ns: u64,
    pub word: XLatchWord,
    /// The interferometer count (µin) that caused it.
    pub count: i64,
    /// The latch caught the higher digits before the carry.
    pub stale: bool,
}

/// Digits of the BCD chain for a count (µin), the display's ten's
/// complement for negative counts (the chain just borrows through zero).
fn digits(count: i64) -> [u32; 9] {
    let modulus = 1_000_000_000i64;
    let mut v = count.rem_euclid(modulus) as u64;
    let mut d = [0u32; 9];
    for slot in d.iter_mut() {
        *slot = (v % 10) as u32;
        v /= 10;
    }
    d // d[0] = µin, d[2] = ten-thousandths, d[3] = thousandths, …
}

/// The latch word for a chain state.
pub fn latch_of(count: i64) -> XLatchWord {
    let d = digits(count);
    let mut w = (d[6] << 12) | (d[5] << 8) | (d[4] << 4) | d[3];
    if d[2] == 5 {
        w |= XLatchWord::HALF_MIL;
    }
    if d[3] == 0 {
        w |= XLatchWord::MIL_ZERO;
    }
    XLatchWord(w)
}

/// The X slide with its counter chain.
pub struct XSlide {
    cfg: XSlideConfig,
    rng: ChaCha8Rng,
    count: i64,
    t_ns: u64,
    /// The vibration's sin(2π f t), by rotation between samples.
    vib: crate::fastmath::Phasor,
}

impl XSlide {
    pub fn new(cfg: XSlideConfig) -> Self {
        let rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let count = (cfg.x0_in * COUNTS_PER_INCH).round() as i64;
        let vib = crate::fastmath::Phasor::new(std::f64::consts::TAU * cfg.vibration_hz);
        Self {
            cfg,
            rng,
            count,
            t_ns: 0,
            vib,
        }
    }

    /// Nominal X (feed only, no vibration), inches.
    pub fn nominal_x(&self, t_s: f64) -> f64 {
        let mut x = self.cfg.x0_in;
        for (i, seg) in self.cfg.feed.iter().enumerate() {
            if t_s <= seg.t_start_s {
                break;
            }
            let end = self
                .cfg
                .feed
                .get(i + 1)
                .map_or(t_s, |n| n.t_start_s.min(t_s));
            x += seg.feed_in_per_min / 60.0 * (end - seg.t_start_s);
        }
        x
    }

    /// The interferometer count now (µin), e.g. for the modern X mode.
    pub fn count(&self) -> i64 {
        self.count
    }

    pub fn time_ns(&self) -> u64 {
        self.t_ns
    }

    /// Advances to `t_ns`, sampling the position every `step_ns`, stepping
    /// the chain one count at a time, and appends the interrupts fired.
    pub fn advance(&mut self, t_ns: u64, step_ns: u64, out: &mut Vec<XInterrupt>) {
        let step = step_ns.max(1);
        while self.t_ns < t_ns {
            let t_next = (self.t_ns + step).min(t_ns);
            let ts = t_next as f64 * 1e-9;
            let vib = if self.cfg.vibration_uin != 0.0 {
                self.cfg.vibration_uin * self.vib.sin_at(t_next)
            } else {
                0.0
            };
            let jit = if self.cfg.jitter_uin > 0.0 {
                self.rng
                    .random_range(-self.cfg.jitter_uin..=self.cfg.jitter_uin)
            } else {
                0.0
            };
            let target =
                crate::fastmath::round_i64(self.nominal_x(ts) * COUNTS_PER_INCH + vib + jit);
            let n = (target - self.count).unsigned_abs().max(1);
            let mut k = 0u64;
            while self.count != target {
                k += 1;
                let up = target > self.count;
                let before = digits(self.count)[2];
                self.count += if up { 1 } else { -1 };
                let after = digits(self.count)[2];
                if after != before && (after == 0 || after == 5) {
                    // Count edges spread evenly over the sample interval.
                    let t_edge = self.t_ns + (t_next - self.t_ns) * k / n;
                    let carry = up && after == 0;
                    let stale = carry && self.rng.random_bool(self.cfg.ripple_prob.clamp(0.0, 1.0));
                    let word = if stale {
                        // Higher digits before the carry, decoder line "0".
                        let w = latch_of(self.count - 1).0 & !XLatchWord::HALF_MIL;
                        let w = if w & 0xF == 0 {
                            w | XLatchWord::MIL_ZERO
                        } else {
                            w & !XLatchWord::MIL_ZERO
                        };
                        XLatchWord(w)
                    } else {
                        latch_of(self.count)
                    };
                    out.push(XInterrupt {
                        t_ns: t_edge,
                        word,
                        count: self.count,
                        stale,
                    });
                }
            }
            self.t_ns = t_next;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use zslide::xpos::decode;

    #[test]
    fn clean_sweep_fires_once_per_half_mil_with_exact_digits() {
        // 1.0 in → 1.01 in at 1 in/min: 20 half-mils, 20 interrupts.
        let mut s = XSlide::new(XSlideConfig {
            x0_in: 1.0,
            feed: vec![FeedSegment {
                t_start_s: 0.0,
                feed_in_per_min: 1.0,
            }],
            ..XSlideConfig::default()
        });
        let mut ev = Vec::new();
        s.advance(600_000_000, 20_000, &mut ev);
        assert_eq!(ev.len(), 20);
        for (i, e) in ev.iter().enumerate() {
            assert_eq!(decode(e.word), Some(2001 + i as u32));
            assert_eq!(e.count, 1_000_500 + 500 * i as i64);
        }
        assert_eq!(
            latch_of(-1).0 & 0xFFFF,
            0x9999,
            "ten's complement below zero"
        );
    }

    #[test]
    fn dither_across_a_boundary_repeats_the_same_state() {
        // Parked 2 µin below 1.0005 with 5 µin of vibration: the digit goes
        // 4→5 at every vibration peak, 5→4 without interrupt in between.
        let mut s = XSlide::new(XSlideConfig {
            x0_in: 1.000_498,
            feed: vec![FeedSegment {
                t_start_s: 0.0,
                feed_in_per_min: 0.0,
            }],
            vibration_uin: 5.0,
            vibration_hz: 100.0,
            ..XSlideConfig::default()
        });
        let mut ev = Vec::new();
        s.advance(100_000_000, 10_000, &mut ev);
        assert_eq!(ev.len(), 10, "one false interrupt per vibration cycle");
        assert!(ev.iter().all(|e| e.word == ev[0].word));
    }
}
