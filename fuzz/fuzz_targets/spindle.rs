//! The spindle-angle estimators (`zslide::spindle`) on arbitrary
//! configurations and reading sequences: no panic (overflow checks are on
//! in fuzz builds), no fault outside the ones each call documents, and the
//! angle is still the documented function of the readings:
//! * encoder: within one count of `index_angle + (count − reference)·turn/CPR`,
//!   the reference following the documented index rules;
//! * tachometer: rate = millivolts · 5 turns/s per `mv_at_300_rpm` · gain,
//!   gain kept in [1/4, 4], re-phasing at an index bounded by rate × the
//!   time between the edge and the last tick.
//!
//! Input: a mode byte (bit 0: tachometer; bit 1: encoder edges stamped at
//! the read, `EdgeStamps::AtRead`), 24 configuration bytes, then 9-byte events
//! `[kind, a: u32 LE, b: u32 LE]`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use zslide::safety::Fault;
use zslide::spindle::{EncoderAngle, EncoderConfig, TachAngle, TachConfig, TACH_MIN_MV_TICKS};
use zslide::units::SpindleAngle;

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Circular distance of two binary angles.
fn dist(a: SpindleAngle, b: u32) -> u32 {
    let d = a.0.wrapping_sub(b);
    d.min(d.wrapping_neg())
}

/// Ticks a revolution takes at `rpm` (the band's definition; a revolution
/// at `min_rpm` must fit the 32-bit clock).
fn period(ticks_per_s: u32, rpm: u32) -> u64 {
    u64::from(ticks_per_s) * 60 / u64::from(rpm)
}

fn encoder(c: &[u8], events: &[u8], at_read: bool) {
    let cfg = EncoderConfig {
        counts_per_rev: u32_at(c, 0),
        ticks_per_s: u32_at(c, 4),
        min_rpm: u32_at(c, 8),
        max_rpm: u32_at(c, 12),
        index_tolerance_counts: u32_at(c, 16),
        index_angle: SpindleAngle(u32_at(c, 20)),
        edge_stamps: if at_read {
            zslide::spindle::EdgeStamps::AtRead
        } else {
            zslide::spindle::EdgeStamps::Captured
        },
    };
    let valid = cfg.counts_per_rev >= 4
        && cfg.ticks_per_s > 0
        && cfg.min_rpm > 0
        && cfg.max_rpm >= cfg.min_rpm
        && period(cfg.ticks_per_s, cfg.min_rpm) <= u64::from(u32::MAX);
    let Some(mut e) = EncoderAngle::new(cfg) else {
        assert!(!valid, "refused a valid configuration {cfg:?}");
        return;
    };
    assert!(valid, "accepted an invalid configuration {cfg:?}");
    let cpr = i64::from(cfg.counts_per_rev);
    let tol = i64::from(cfg.index_tolerance_counts);
    let mut reference: Option<u32> = None;
    let mut prev_index_edge: Option<u32> = None;
    let (mut count, mut now) = (0u32, 0u32);
    let mut last_edge: Option<u32> = None;
    let mut last_count = 0u32;
    for ev in events.chunks_exact(9) {
        let (a, b) = (u32_at(ev, 1), u32_at(ev, 5));
        let edge;
        if ev[0] & 2 == 0 {
            // A plausible step: a few counts, the edge a little before now.
            count = count.wrapping_add(a as i8 as i32 as u32);
            now = now.wrapping_add(b & 0xFFFF);
            edge = now.wrapping_sub((b >> 16) & 0xFF);
        } else {
            count = a;
            now = b;
            edge = u32_at(ev, 3);
        }
        if ev[0] & 1 == 0 {
            let est = e.tick(count, edge, now);
            if last_edge.is_none() || count != last_count {
                last_edge = Some(edge);
                last_count = count;
            }
            let Some(r) = reference else {
                assert_eq!(est.angle, cfg.index_angle, "angle before the first index");
                assert_eq!(est.fault, None);
                continue;
            };
            let mut fault = None;
            if i64::from(count.wrapping_sub(r) as i32) > cpr + tol {
                fault = Some(Fault::IndexMissing);
                reference = Some(r.wrapping_add(cfg.counts_per_rev));
            }
            // An edge stamped after the read has just happened (the
            // estimator's rule): no time since it.
            let since = match now.wrapping_sub(last_edge.unwrap_or(edge)) {
                d if (d as i32) < 0 => 0,
                d => u64::from(d),
            };
            let count_period = period(cfg.ticks_per_s, cfg.min_rpm) / u64::from(cfg.counts_per_rev);
            match est.fault {
                // At-read stamps also hold the 20 ms baseline's rate to the
                // band's floor (`spindle::encoder`), which can trip between
                // edges: this model does not keep the baseline, so it checks
                // the time since the edge only for captured edges.
                Some(Fault::SpindleSpeed) => {
                    assert!(at_read || since > count_period, "stall after {since} ticks")
                }
                f => {
                    assert_eq!(f, fault);
                    assert!(
                        since <= 4 * count_period.max(1),
                        "no stall after {since} ticks"
                    );
                }
            }
            let r = reference.unwrap_or(r);
            let delta = i128::from(count.wrapping_sub(r) as i32);
            let want = ((delta << 32) / i128::from(cpr)) as i64 as u32;
            let want = want.wrapping_add(cfg.index_angle.0);
            // One count of extrapolation, plus rounding: the Q32 per-count
            // constant (< ½ LSB over any count distance), the estimator's and
            // this model's truncations (1 LSB each).
            let one_count = (1u64 << 32) / cfg.counts_per_rev as u64 + 4;
            assert!(
                u64::from(dist(est.angle, want)) <= one_count,
                "angle {:?} vs {want} (count {count}, reference {r})",
                est.angle
            );
        } else {
            let got = e.on_index(count, edge);
            let Some(r) = reference else {
                assert_eq!(got, Ok(()));
                reference = Some(count);
                prev_index_edge = Some(edge);
                continue;
            };
            let d = i64::from(count.wrapping_sub(r) as i32);
            if d < cpr - tol {
                assert_eq!(got, Err(Fault::IndexExtra), "index after {d} counts");
                continue;
            }
            reference = Some(count);
            let prev = prev_index_edge.replace(edge);
            if d > cpr + tol {
                assert_eq!(got, Err(Fault::IndexMissing), "index after {d} counts");
                continue;
            }
            let p = prev.map(|p| u64::from(edge.wrapping_sub(p)));
            let out_of_band = p.is_some_and(|p| {
                p < period(cfg.ticks_per_s, cfg.max_rpm) || p > period(cfg.ticks_per_s, cfg.min_rpm)
            });
            assert_eq!(
                got,
                if out_of_band {
                    Err(Fault::SpindleSpeed)
                } else {
                    Ok(())
                }
            );
        }
        let _ = e.rate_q16();
    }
}

fn tach(c: &[u8], events: &[u8]) {
    let cfg = TachConfig {
        ticks_per_s: u32_at(c, 0),
        mv_at_300_rpm: u32_at(c, 4),
        min_rpm: u32_at(c, 8),
        max_rpm: u32_at(c, 12),
        index_tolerance_permille: u32_at(c, 16),
        index_angle: SpindleAngle(u32_at(c, 20)),
    };
    let valid = cfg.ticks_per_s > 0
        && cfg.mv_at_300_rpm > 0
        && cfg.min_rpm > 0
        && cfg.max_rpm >= cfg.min_rpm
        && period(cfg.ticks_per_s, cfg.min_rpm) <= u64::from(u32::MAX)
        && cfg.index_tolerance_permille <= 250
        && u64::from(cfg.mv_at_300_rpm) * u64::from(cfg.ticks_per_s) >= TACH_MIN_MV_TICKS;
    let Some(mut t) = TachAngle::new(cfg) else {
        assert!(!valid, "refused a valid configuration {cfg:?}");
        return;
    };
    assert!(valid, "accepted an invalid configuration {cfg:?}");
    let mut now = 0u32;
    let mut last_tick: Option<u32> = None;
    for ev in events.chunks_exact(9) {
        let (a, b) = (u32_at(ev, 1), u32_at(ev, 5));
        if ev[0] & 1 == 0 {
            let mv = if ev[0] & 2 == 0 {
                i32::from(a as i16)
            } else {
                a as i32
            };
            now = if ev[0] & 4 == 0 {
                now.wrapping_add(b & 0xFFFF)
            } else {
                b
            };
            let est = t.tick(mv, now);
            last_tick = Some(now);
            assert!(matches!(
                est.fault,
                None | Some(Fault::IndexMissing) | Some(Fault::SpindleSpeed)
            ));
            // The documented scale: 5 turns/s at mv_at_300_rpm, times the gain.
            let mv = f64::from(mv.clamp(-(1 << 16), 1 << 16));
            let gain = t.gain_q30() as f64 / f64::from(1u32 << 30);
            assert!((0.25..=4.0).contains(&gain), "gain {gain}");
            let want = mv * 5.0 / (f64::from(cfg.mv_at_300_rpm) * f64::from(cfg.ticks_per_s))
                * 2f64.powi(48)
                * gain;
            let got = t.rate_q48() as f64;
            // Two truncated products (k to one LSB of Q16, times the Q30
            // gain, truncated; times the reading, truncated): at most
            // |mv|·(gain + 1)/2^16 + 1 LSB (`spindle::tests::tach_rate_is_
            // within_its_rounding_bound…`), plus the f64 reference's own
            // rounding.
            let bound = mv.abs() * (gain + 1.0) / 65_536.0 + 1.0 + want.abs() * 1e-12;
            assert!(
                (got - want).abs() <= bound,
                "rate {got} Q48 turns/tick, want {want} ({mv} mV)"
            );
            if mv * 600.0 < f64::from(cfg.mv_at_300_rpm) * f64::from(cfg.min_rpm) - 600.0 {
                // One fault per tick: a missing index found on the same
                // tick takes precedence (same reaction, ramp to null).
                assert!(
                    matches!(
                        est.fault,
                        Some(Fault::SpindleSpeed) | Some(Fault::IndexMissing)
                    ),
                    "{mv} mV is below the band, fault {:?}",
                    est.fault
                );
            }
            assert_eq!(est.angle, t.angle());
        } else {
            let edge = if ev[0] & 2 == 0 {
                now.wrapping_sub(a & 0xFFFF)
            } else {
                a
            };
            let got = t.on_index(edge);
            assert!(matches!(
                got,
                Ok(())
                    | Err(Fault::IndexExtra)
                    | Err(Fault::IndexMissing)
                    | Err(Fault::SpindleSpeed)
            ));
            if got != Err(Fault::IndexExtra) {
                // Re-phased to the edge: off the index angle by at most the
                // rate times the edge's distance from the last tick.
                let back = last_tick.map_or(0, |lt| i64::from(edge.wrapping_sub(lt) as i32));
                let bound = (t.rate_q48().unsigned_abs() as f64 * back.unsigned_abs() as f64)
                    / 65536.0
                    + 2.0;
                assert!(
                    f64::from(dist(t.angle(), cfg.index_angle.0)) <= bound,
                    "angle {:?} after the index, bound {bound}",
                    t.angle()
                );
            }
        }
    }
}

fuzz_target!(|data: &[u8]| {
    if data.len() < 25 {
        return;
    }
    let (cfg, events) = data[1..].split_at(24);
    if data[0] & 1 == 0 {
        encoder(cfg, events, data[0] & 2 != 0);
    } else {
        tach(cfg, events);
    }
});
