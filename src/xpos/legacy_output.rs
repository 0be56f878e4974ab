//! The legacy coefficient output (C00..C03 for the 1983 analog
//! electronics): what one accepted legacy X event sends to the quad
//! coefficient DAC, from the command generator's table at X.

use super::XUpdate;
use crate::command::{sat_i32, CommandGen};
use crate::safety::Fault;
use crate::table::Representation;

/// What one legacy X event sends to the quad coefficient DAC: the codes of
/// C00..C03 (Table 3-1) and which of them to write before the one strobe.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LegacyFrame {
    pub codes: [u16; 4],
    /// Bit j = channel C0j is written.
    pub update: u8,
}

/// The legacy coefficient output with the 8080's economy: the table values
/// at the two ends of the grid interval are fetched only when X enters
/// another interval (the 8080 recomputed its rates only when the two high
/// digits changed); each X event then costs one multiply-add and one code
/// conversion per scheduled coefficient. Results are bit-identical to
/// [`CommandGen::legacy_frame`] (tested). Use one per [`CommandGen`].
#[derive(Clone, Copy, Debug, Default)]
pub struct LegacyOutput {
    interval: Option<u32>,
    lo: [i64; 4],
    hi: [i64; 4],
}

impl LegacyOutput {
    pub const fn new() -> Self {
        Self {
            interval: None,
            lo: [0; 4],
            hi: [0; 4],
        }
    }

    /// Forgets the cached interval (after a table change).
    pub fn reset(&mut self) {
        self.interval = None;
    }

    /// The quad-DAC frame of one accepted legacy X event.
    pub fn frame(&mut self, gen: &CommandGen, u: &XUpdate) -> Result<LegacyFrame, Fault> {
        let mut codes = [LEGACY_DAC_ZERO; 4];
        let at = if u.null { None } else { gen.locate(u.x)? };
        let Some(at) = at else {
            return Ok(LegacyFrame {
                codes,
                update: 0b1111,
            });
        };
        let it = &gen.interp;
        let (n, f) = it.interval(at);
        let cols = gen.legacy_columns();
        if self.interval != Some(n) {
            for ((lo, hi), c) in self.lo.iter_mut().zip(self.hi.iter_mut()).zip(cols) {
                *lo = it.raw(n, c);
                *hi = it.raw(n + 1, c);
            }
            self.interval = Some(n);
        }
        let m = u.update;
        // Source columns the scheduled coefficients need (harmonic: C00 ←
        // C0, C2; C01 ← S1, S3; C02 ← C2; C03 ← S3, in source order C0, C2,
        // S1, S3).
        let need = match gen.repr {
            Representation::SinPower => m,
            Representation::Harmonic => {
                let mut n = 0;
                if m & 1 != 0 {
                    n |= 0b0011;
                }
                if m & 2 != 0 {
                    n |= 0b1100;
                }
                if m & 4 != 0 {
                    n |= 0b0010;
                }
                if m & 8 != 0 {
                    n |= 0b1000;
                }
                n
            }
        };
        let mut v = [0i64; 4];
        for (j, ((vj, lo), hi)) in v.iter_mut().zip(&self.lo).zip(&self.hi).enumerate() {
            if need & (1 << j) != 0 {
                *vj = i64::from(it.lerp(*lo, *hi, f));
            }
        }
        let [a, b, c, d] = v;
        let out = match gen.repr {
            Representation::SinPower => v,
            Representation::Harmonic => [a + b, c + 3 * d, -2 * b, -4 * d],
        };
        for (j, (code, x)) in codes.iter_mut().zip(out).enumerate() {
            if m & (1 << j) != 0 {
                *code = legacy_dac_code(sat_i32(x));
            }
        }
        Ok(LegacyFrame {
            codes,
            update: m & 0b1111,
        })
    }
}

impl CommandGen<'_> {
    /// The quad-DAC frame of one accepted legacy X event: only the
    /// coefficients in its update set are computed; the null zone writes
    /// zero to all four. Below the table: [`Fault::XOutsideTable`].
    pub fn legacy_frame(&self, u: &XUpdate) -> Result<LegacyFrame, Fault> {
        let mut codes = [LEGACY_DAC_ZERO; 4];
        let at = if u.null { None } else { self.locate(u.x)? };
        let Some(at) = at else {
            return Ok(LegacyFrame {
                codes,
                update: 0b1111,
            });
        };
        if self.repr == Representation::SinPower {
            // Only the scheduled columns: at most half-mils only C02 (the
            // common event) costs one column.
            for (j, code) in codes.iter_mut().enumerate() {
                if u.update & (1 << j) != 0 {
                    *code = legacy_dac_code(self.interp.value(at, j as u8));
                }
            }
        } else {
            let v = self.legacy_coefficients(at);
            for (j, (code, c)) in codes.iter_mut().zip(v).enumerate() {
                if u.update & (1 << j) != 0 {
                    *code = legacy_dac_code(c);
                }
            }
        }
        Ok(LegacyFrame {
            codes,
            update: u.update & 0b1111,
        })
    }
}

/// Table 3-1 scaling of the coefficient DACs: ±10 V ↔ ±0.010 in, 16 bits over
/// 0.020 in (3.2768 LSB/µin), straight binary with 32768 = 0:
/// `code = 32768 + round(C · 65536 / 0.020 in)`, saturated to 0..=65535.
/// `c_q30` is in Q30 inches. Ties round up.
pub fn legacy_dac_code(c_q30: i32) -> u16 {
    // 65536 / 0.020 = 3_276_800 LSB per inch; |c|·3276800 < 2^53.
    let v = i64::from(c_q30) * 3_276_800;
    let code = 32768 + ((v + (1 << 29)) >> 30);
    code.clamp(0, 65535) as u16
}

/// The code of a zero coefficient (0 V).
pub const LEGACY_DAC_ZERO: u16 = 32768;

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;
    use super::*;
    use crate::command::tests::{q30, table};
    use crate::table::CoeffTable;
    use crate::xpos::{half_mils_to_x, XUpdate};
    use std::vec::Vec;

    /// The interval-cached legacy output gives exactly the frames of the
    /// stateless one, across interval changes in both directions.
    #[test]
    fn legacy_output_cache_is_exact() {
        let nodes = 6u32;
        let mut harm = Vec::new();
        let mut pow = Vec::new();
        for n in 0..nodes as i32 {
            harm.extend([
                q30(-1e-5) * n,
                7,
                q30(2e-4) * n,
                q30(-1.3e-3) * n,
                5,
                3,
                q30(4e-6) * n,
            ]);
            pow.extend([
                q30(-1e-5) * n,
                q30(2e-4) * n,
                q30(-1.3e-3) * n,
                q30(4e-6) * n,
            ]);
        }
        for (img, repr) in [
            (table(Representation::Harmonic, 7, &harm, nodes), "harmonic"),
            (table(Representation::SinPower, 4, &pow, nodes), "sin-power"),
        ] {
            let g = CommandGen::new(CoeffTable::parse(&img).unwrap());
            let mut out = LegacyOutput::new();
            let sweep = (0..2000u32).chain((0..2000u32).rev()).step_by(7);
            for (k, hm) in sweep.enumerate() {
                let u = XUpdate {
                    half_mils: hm,
                    x: half_mils_to_x(hm),
                    update: (k % 16) as u8,
                    null: hm > 1990,
                };
                assert_eq!(out.frame(&g, &u), g.legacy_frame(&u), "{repr} at {hm}");
            }
        }
    }

    #[test]
    fn legacy_codes_follow_table_3_1() {
        assert_eq!(legacy_dac_code(0), 32768);
        // +0.010 in is full scale (one LSB past the top code), -0.010 in is code 0.
        assert_eq!(legacy_dac_code(q30(0.010)), 65535);
        assert_eq!(legacy_dac_code(q30(-0.010)), 0);
        // 1 µin = 3.2768 LSB; C02 at X = 7.2 in (Table 2-2) = -0.0048855 in.
        assert_eq!(legacy_dac_code(q30(1e-6)), 32771);
        assert_eq!(legacy_dac_code(q30(-0.0048855)), 32768 - 16009);
    }
}
