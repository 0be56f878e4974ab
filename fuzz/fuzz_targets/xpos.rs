//! The legacy X interface (`zslide::xpos`): BCD decoder, debounce, schedule
//! and glitch watch, fed arbitrary latch words at arbitrary times; and the
//! count-based X on arbitrary counts.
//!
//! Input: 8 configuration bytes, then 7-byte events
//! `[word: u32 LE (low 18 bits kept unless bit 7 of the flag byte is set),
//! dt: u16 LE ticks, kind]`. Everything is checked against a model written
//! from the 8080 listing's rules (module documentation of `xpos`), not from
//! the code: a decimal reading of the digits, the debounce on the flag bits,
//! the anomaly window, the schedule of C00..C03.
#![no_main]

use libfuzzer_sys::fuzz_target;
use zslide::hw::XLatchWord;
use zslide::safety::Fault;
use zslide::xpos::{
    decode, half_mils_to_x, latch_word, CountConfig, CountX, LegacyConfig, LegacyX, XEvent, ALL,
    C00, C01, C02, C03, DISPLAY_HALF_MILS,
};

/// Digit-by-digit decimal reading of a latch word: half-mils, or `None`.
fn model_decode(w: u32) -> Option<u32> {
    if w >> 18 != 0 {
        return None;
    }
    let mut mils = 0;
    for shift in [12, 8, 4, 0] {
        let d = (w >> shift) & 0xF;
        if d > 9 {
            return None;
        }
        mils = mils * 10 + d;
    }
    Some(mils * 2 + (w >> 16 & 1))
}

/// The anomaly window: storm when `n` anomalies fall within `window` ticks.
struct Storm {
    times: Vec<u32>,
    n: usize,
    window: u32,
}

impl Storm {
    fn hit(&mut self, now: u32) -> bool {
        self.times.push(now);
        let len = self.times.len();
        len >= self.n && now.wrapping_sub(self.times[len - self.n]) < self.window
    }
}

fn legacy(cfg_bytes: &[u8], events: &[u8]) {
    let cfg = LegacyConfig {
        null_from_half_mils: u32::from(u16::from_le_bytes([cfg_bytes[0], cfg_bytes[1]])),
        storm_count: cfg_bytes[2] % 40,
        storm_window_ticks: u32::from(u16::from_le_bytes([cfg_bytes[3], cfg_bytes[4]])) * 4,
        max_jump_half_mils: u32::from(cfg_bytes[5] % 32),
        refresh_all_on_entry: cfg_bytes[6] & 1 == 1,
    };
    let mut x = LegacyX::new(cfg);
    let mut storm = Storm {
        times: Vec::new(),
        n: usize::from(cfg.storm_count).clamp(1, 32),
        window: cfg.storm_window_ticks,
    };
    let mut last_flags: Option<u32> = None;
    let mut last_hm: Option<u32> = None;
    let mut in_null = false;
    let mut now = 0u32;
    for ev in events.chunks_exact(7) {
        let raw = u32::from_le_bytes([ev[0], ev[1], ev[2], ev[3]]);
        let word = if ev[6] & 0x80 != 0 {
            raw
        } else {
            raw & 0x3_FFFF
        };
        now = now.wrapping_add(u32::from(u16::from_le_bytes([ev[4], ev[5]])));
        // The decoder against the decimal model, and the latch-word builder
        // inverting it for every legal position.
        let dec = decode(XLatchWord(word));
        assert_eq!(dec, model_decode(word), "decode({word:#x})");
        if let Some(hm) = dec {
            assert!(hm < DISPLAY_HALF_MILS);
            assert_eq!(decode(latch_word(hm)), Some(hm));
            let xi = half_mils_to_x(hm).to_f64();
            assert!((xi - f64::from(hm) * 0.0005).abs() <= 0.5 / 16_777_216.0 + 1e-15);
        }
        let flags = word & (XLatchWord::HALF_MIL | XLatchWord::MIL_ZERO);
        let got = x.on_interrupt(XLatchWord(word), now);
        if last_flags == Some(flags) {
            // Debounced: the same half-mil state again is an anomaly only.
            let want = if storm.hit(now) {
                Err(Fault::XGlitchStorm)
            } else {
                Ok(XEvent::Ignored)
            };
            assert_eq!(got, want, "repeat of flags {flags:#x}");
            continue;
        }
        let Some(hm) = dec else {
            assert_eq!(got, Err(Fault::XBadBcd), "non-BCD {word:#x}");
            continue;
        };
        last_flags = Some(flags);
        let thousandths = word & 0xF;
        if (word & XLatchWord::MIL_ZERO != 0) != (thousandths == 0) && storm.hit(now) {
            assert_eq!(
                got,
                Err(Fault::XGlitchStorm),
                "mil-zero flag contradicts digit"
            );
            continue;
        }
        if let Some(prev) = last_hm {
            let d = prev.abs_diff(hm);
            let step = d.min(DISPLAY_HALF_MILS - d);
            if step > cfg.max_jump_half_mils {
                assert_eq!(got, Err(Fault::XGlitchStorm), "jump {prev} -> {hm}");
                continue;
            }
            if step != 1 && storm.hit(now) {
                assert_eq!(got, Err(Fault::XGlitchStorm), "step {prev} -> {hm}");
                continue;
            }
        }
        let Ok(XEvent::Update(u)) = got else {
            panic!("{word:#x} at {now}: expected an update, got {got:?}");
        };
        assert_eq!(u.half_mils, hm);
        assert_eq!(u.x, half_mils_to_x(hm));
        let null = hm >= cfg.null_from_half_mils;
        assert_eq!(u.null, null);
        let resync = cfg.refresh_all_on_entry && (last_hm.is_none() || in_null);
        let want_update = if null || resync {
            ALL
        } else if hm % 2 == 1 {
            C02
        } else if (hm / 2) % 10 == 0 {
            C02 | C01 | C00 | C03
        } else {
            C02 | C01
        };
        assert_eq!(u.update, want_update, "schedule at {hm} half-mils");
        in_null = null;
        last_hm = Some(hm);
        assert_eq!(x.half_mils(), Some(hm));
    }
}

fn count(cfg_bytes: &[u8], events: &[u8]) {
    let cfg = CountConfig {
        counts_per_inch: i32::from_le_bytes([
            cfg_bytes[0],
            cfg_bytes[1],
            cfg_bytes[2],
            cfg_bytes[3],
        ]),
        zero_count: u32::from_le_bytes([cfg_bytes[4], cfg_bytes[5], cfg_bytes[6], 0]),
        max_step_counts: u32::from(cfg_bytes[7]) << 8,
    };
    let Some(mut c) = CountX::new(cfg) else {
        assert_eq!(cfg.counts_per_inch, 0);
        return;
    };
    let mut last: Option<u32> = None;
    for ev in events.chunks_exact(4) {
        let n = u32::from_le_bytes([ev[0], ev[1], ev[2], ev[3]]);
        let got = c.on_tick(n);
        let jump =
            last.is_some_and(|p| (n.wrapping_sub(p) as i32).unsigned_abs() > cfg.max_step_counts);
        last = Some(n);
        if jump {
            assert_eq!(got, Err(Fault::XGlitchStorm));
            continue;
        }
        let x = got.expect("a small step is accepted");
        // Exact X, saturated to the format: relative error of the reciprocal
        // below 2^-30, plus half an LSB of rounding.
        let d = f64::from(n.wrapping_sub(cfg.zero_count) as i32);
        let exact = (d / f64::from(cfg.counts_per_inch)).clamp(-128.0, 128.0 - 1.0 / 16_777_216.0);
        let tol = exact.abs() * 2f64.powi(-29) + 1.0 / 16_777_216.0;
        assert!(
            (x.to_f64() - exact).abs() <= tol,
            "count {n}: {} vs {exact}",
            x.to_f64()
        );
        assert_eq!(x, c.x(n));
    }
}

fuzz_target!(|data: &[u8]| {
    if data.len() < 9 {
        return;
    }
    let (cfg, events) = data[1..].split_at(8);
    if data[0] & 1 == 0 {
        legacy(cfg, events);
    } else {
        count(cfg, events);
    }
});
