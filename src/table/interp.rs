//! Coefficients at X: linear interpolation of every table column between the
//! two grid nodes around X, in fixed point, continuous across nodes.
//!
//! # Why continuity matters
//! The 1983 system cut grooves 0.1 in apart (one per grid interval) until the
//! interpolation at the interval end points was changed. Here the value at X
//! is `c_i + (c_{i+1} − c_i)·f` with `f ∈ [0, 1)` the position inside the
//! interval, so approaching node `i+1` from below gives `c_{i+1}` to within
//! one LSB of the intermediate format (2⁻³¹ of the difference), and node
//! `i+1` itself gives exactly `c_{i+1}`: no step at any node. The property
//! tests check this for every node of random tables.
//!
//! # Fixed-point path (identical on host and target: integers only)
//! * X is `I8F24`. The grid lives in "grid units" of 2^−F in, F = max(24,
//!   table X fraction bits), so node positions are exact.
//! * The grid coordinate `u = (X − x0)/ΔX` in Q32 comes from a multiply by a
//!   reciprocal computed once when the table is loaded:
//!   `u = (t · ⌈2^(32+k)/ΔX⌉) >> k`, `t = X − x0`, with `k` as large as keeps
//!   `t · inv` inside 64 bits over the whole table. Its error is below
//!   `t / 2^k + 1` Q32 units, i.e. under 10⁻⁷ of an interval for any table
//!   the format allows; it moves the interpolation point, never the node
//!   values. No division on the hot path.
//! * The value is formed with `f` in Q31 in an `i64` (`c_i·2³¹ + Δ·f`, exact,
//!   cannot overflow: |Δ| < 2³², f < 2³¹) and rounded once to Q30 inches,
//!   the format of [`crate::units::ZInches`].

use crate::table::CoeffTable;
use crate::units::XInches;

/// Where X falls on the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Locus {
    /// Lower node of the interval (the last node itself when X is on it).
    pub node: u32,
    /// Position inside the interval, Q32: `[0, 1)`.
    pub frac: u32,
}

/// X relative to the table's grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Located {
    /// X is below the first node.
    Below,
    /// X is on the grid (first node ≤ X ≤ last node).
    In(Locus),
    /// X is beyond the last node.
    Above,
}

/// Constants of [`Interpolator::locate_fast`].
#[derive(Clone, Copy, Debug)]
struct Fast {
    /// Node 0, `I8F24` bits.
    x0: i32,
    /// ΔX, `I8F24` bits.
    dx: u32,
    /// ⌊2^(32+s)/ΔX⌋ < 2^32.
    r: u32,
    s: u32,
}

/// Linear interpolation of a [`CoeffTable`], with the grid reciprocal
/// precomputed. Cheap to copy; borrows the table in place.
#[derive(Clone, Copy, Debug)]
pub struct Interpolator<'a> {
    table: CoeffTable<'a>,
    /// Shift from `I8F24` bits to grid units (F − 24).
    x_up: u32,
    /// Node 0 in grid units.
    x0: i64,
    /// (nodes − 1)·ΔX in grid units.
    t_max: u64,
    /// ΔX in grid units.
    dx: u64,
    /// ⌈2^(32+k)/ΔX⌉.
    inv: u64,
    k: u32,
    /// 2^16 / ΔX (ΔX in inches), for slopes; ≤ 2^31.
    per_inch_q16: i64,
    /// Table coefficient fraction bits.
    fc: u32,
    fast: Option<Fast>,
    /// Largest |coefficient| in the table, Q30 (saturating): lets callers
    /// skip per-value clamps when the whole table is small.
    max_abs_q30: i64,
}

impl<'a> Interpolator<'a> {
    /// Precomputes the grid constants. Called once per table load (it divides).
    pub fn new(table: CoeffTable<'a>) -> Self {
        let h = *table.header();
        let fx = u32::from(h.x_frac_bits);
        let f = fx.max(24);
        let x_up = f - 24;
        let x0 = i64::from(h.x0_raw) << (f - fx);
        // ΔX > 0 is checked by the parser; max(1) keeps this total anyway.
        let dx = (i64::from(h.dx_raw) << (f - fx)).max(1) as u64;
        let t_max = dx * u64::from(h.node_count - 1);
        let mut k = 31;
        let mut inv;
        loop {
            inv = ((1u128 << (32 + k)) / u128::from(dx) + 1) as u64;
            let fits = u128::from(t_max) * u128::from(inv) < (1u128 << 64);
            if fits || k == 0 {
                break;
            }
            k -= 1;
        }
        let per_inch_q16 = ((1u128 << (f + 16)) / u128::from(dx)).min(1 << 31) as i64;
        let fast = if x_up == 0 && dx < (1 << 31) && t_max < (1 << 32) {
            i32::try_from(x0).ok().map(|x0| {
                let mut s = 31;
                while s > 0 && (1u64 << (32 + s)) / dx >= (1 << 32) {
                    s -= 1;
                }
                Fast {
                    x0,
                    dx: dx as u32,
                    r: ((1u64 << (32 + s)) / dx) as u32,
                    s,
                }
            })
        } else {
            None
        };
        let shift = u32::from(h.coeff_frac_bits);
        let mut max_abs_q30 = 0i64;
        for n in 0..h.node_count {
            for c in table.node_row(n).chunks_exact(4) {
                let v = i64::from(i32::from_le_bytes(<[u8; 4]>::try_from(c).unwrap_or([0; 4])));
                // |v| · 2^(30 − fc), saturating.
                let q = if shift <= 30 {
                    v.abs() << (30 - shift)
                } else {
                    v.abs() >> (shift - 30)
                };
                max_abs_q30 = max_abs_q30.max(q);
            }
        }
        Self {
            table,
            max_abs_q30,
            x_up,
            x0,
            t_max,
            dx,
            inv,
            k,
            per_inch_q16,
            fc: u32::from(h.coeff_frac_bits),
            fast,
        }
    }

    pub fn table(&self) -> &CoeffTable<'a> {
        &self.table
    }

    /// Largest |coefficient| of the table, Q30 inches (found at load).
    pub fn max_abs_q30(&self) -> i64 {
        self.max_abs_q30
    }

    /// Finds the interval that holds X.
    #[inline]
    pub fn locate(&self, x: XInches) -> Located {
        match self.fast {
            Some(fp) => self.locate_fast(fp, x),
            None => self.locate_general(x),
        }
    }

    /// 32-bit path for tables whose grid is in X's own format or coarser
    /// (every table the generator makes): one 32×32 multiply for the node,
    /// an exact remainder, and the same fraction as the general path, so
    /// both give identical results (tested).
    #[inline(always)]
    fn locate_fast(&self, fp: Fast, x: XInches) -> Located {
        let t = i64::from(x.to_bits()) - i64::from(fp.x0);
        if t < 0 {
            return Located::Below;
        }
        if t as u64 > self.t_max {
            return Located::Above;
        }
        // t_max < 2^32 in this mode. r ≤ 2^(32+s)/ΔX, so the estimate is
        // never too high and (its error being below one) at most one low.
        let t = t as u32;
        let mut node = ((u64::from(t) * u64::from(fp.r)) >> 32) as u32 >> fp.s;
        let mut rem = t - node * fp.dx;
        if rem >= fp.dx {
            node += 1;
            rem -= fp.dx;
        }
        self.finish(node, u64::from(rem))
    }

    fn locate_general(&self, x: XInches) -> Located {
        let t = (i64::from(x.to_bits()) << self.x_up) - self.x0;
        if t < 0 {
            return Located::Below;
        }
        let t = t as u64;
        if t > self.t_max {
            return Located::Above;
        }
        // t ≤ t_max, and t_max·inv < 2^64 by the choice of k. The reciprocal
        // is rounded up, so this node is never too low, at most one too high.
        let u = t.wrapping_mul(self.inv) >> self.k;
        let mut node = (u >> 32) as u32;
        let mut rem = t as i64 - i64::from(node) * self.dx as i64;
        if rem < 0 {
            node = node.saturating_sub(1);
            rem += self.dx as i64;
        }
        self.finish(node, rem.max(0) as u64)
    }

    /// The locus from the exact node and remainder. The remainder is exact,
    /// so X on a node gives frac = 0 and exactly the node's value.
    #[inline(always)]
    fn finish(&self, node: u32, rem: u64) -> Located {
        let last = self.table.node_count() - 1;
        let node = node.min(last);
        let frac = if node >= last {
            0
        } else {
            (rem.wrapping_mul(self.inv) >> self.k).min(u64::from(u32::MAX)) as u32
        };
        Located::In(Locus { node, frac })
    }

    /// The fraction of [`Locus`] for a remainder `rem` (grid units) inside
    /// an interval: exactly what [`Interpolator::locate`] computes from the
    /// same remainder, so a caller that already knows the interval (the
    /// legacy X event: X stays in one interval for ~60 events) can skip the
    /// node search and get identical results.
    #[inline(always)]
    pub(crate) fn frac_of_rem(&self, rem: u64) -> u32 {
        (rem.wrapping_mul(self.inv) >> self.k).min(u64::from(u32::MAX)) as u32
    }

    /// For a grid step of 2ᵐ X bits (a binary grid: 1/32 in is 2¹⁹):
    /// `32 − m`, the shift that gives [`Self::frac_of_rem`] of every
    /// remainder below the step exactly. There `inv = 2^(32+k−m) + 1`, so
    /// `rem·inv >> k = rem·2^(32−m) + ⌊rem/2ᵏ⌋`, and the last term is zero
    /// for rem < 2ᵐ ≤ 2ᵏ (no wrap: rem·inv < 2^(33+k) ≤ 2⁶⁴). `None` for
    /// any other grid.
    pub(crate) fn frac_shift(&self) -> Option<u32> {
        if !self.dx.is_power_of_two() {
            return None;
        }
        let m = self.dx.trailing_zeros();
        let exact = (1..=31).contains(&m)
            && self.k >= m
            && self.k <= 31
            && self.inv == (1u64 << (32 + self.k - m)) + 1;
        exact.then_some(32 - m)
    }

    /// Whether X in `I8F24` is already in grid units (then a remainder in X
    /// bits is a remainder in grid units).
    pub(crate) fn x_in_grid_units(&self) -> bool {
        self.x_up == 0
    }

    /// The interval `(lower node, Q31 position in it)` that serves `at`: the
    /// last node is served by the last interval at its far end (f = 1).
    #[inline(always)]
    pub(crate) fn interval(&self, at: Locus) -> (u32, i64) {
        let n = at.node.min(self.table.node_count().saturating_sub(2));
        let f = if at.node > n {
            1 << 31
        } else {
            i64::from(at.frac >> 1)
        };
        (n, f)
    }

    /// Linear interpolation of one column between its node values, Q30.
    #[inline(always)]
    pub(crate) fn lerp(&self, lo: i64, hi: i64, f: i64) -> i32 {
        if self.fc == 30 {
            // f ≤ 2^31, so the rounded sum lies between lo and hi, both
            // i32: the cast is exact.
            (lo + (((hi - lo) * f + (1 << 30)) >> 31)) as i32
        } else {
            to_q30((lo << 31) + (hi - lo) * f, self.fc + 1)
        }
    }

    /// Column `column` at `at`, Q30 inches, rounded once. A column the table
    /// does not have reads as zero.
    #[inline]
    pub fn value(&self, at: Locus, column: u8) -> i32 {
        let (n, f) = self.interval(at);
        let (lo, hi) = (
            read(self.table.node_row(n), column),
            read(self.table.node_row(n + 1), column),
        );
        self.lerp(lo, hi, f)
    }

    /// Raw value (table units) of one column at one node, zero if absent.
    #[inline]
    pub(crate) fn raw(&self, node: u32, column: u8) -> i64 {
        read(self.table.node_row(node), column)
    }

    /// Several columns at `at` (`columns[i]` into `out[i]`), fetching the
    /// two rows once: the legacy X event's path.
    pub fn select(&self, at: Locus, columns: &[u8], out: &mut [i32]) {
        let (n, f) = self.interval(at);
        let (lo_row, hi_row) = (self.table.node_row(n), self.table.node_row(n + 1));
        for (o, &c) in out.iter_mut().zip(columns) {
            *o = self.lerp(read(lo_row, c), read(hi_row, c), f);
        }
    }

    /// Change of column `column` across the interval that holds `at`
    /// (the last interval at the last node), Q30 inches.
    #[inline]
    pub fn delta(&self, at: Locus, column: u8) -> i32 {
        let (n, _) = self.interval(at);
        let (lo, hi) = (
            read(self.table.node_row(n), column),
            read(self.table.node_row(n + 1), column),
        );
        to_q30((hi - lo) << 31, self.fc + 1)
    }

    /// Every column at `at` in one pass over the two rows (the loop-tick
    /// path): values and interval changes, Q30 inches. Fills as many
    /// columns as the table has and the slices hold.
    pub fn columns(&self, at: Locus, values: &mut [i32], deltas: &mut [i32]) {
        let (n, f) = self.interval(at);
        // Stepped pairwise with `next` (`Iterator::zip` of two
        // `ChunksExact` sizes itself with a division by the run-time chunk
        // size: a panic path).
        let (mut lo_rows, mut hi_rows) = (
            self.table.node_row(n).chunks_exact(4),
            self.table.node_row(n + 1).chunks_exact(4),
        );
        let rows = core::iter::from_fn(move || Some((lo_rows.next()?, hi_rows.next()?)));
        let sh = self.fc + 1;
        let word = |b: &[u8]| i32::from_le_bytes(<[u8; 4]>::try_from(b).unwrap_or([0; 4]));
        if self.fc == 30 {
            // The table is already in Q30 (the default): constant shifts
            // only, identical results to the general path below.
            for ((v, d), (l, h)) in values.iter_mut().zip(deltas.iter_mut()).zip(rows) {
                let (lo, hi) = (i64::from(word(l)), i64::from(word(h)));
                *v = self.lerp(lo, hi, f);
                *d = sat_i32(hi - lo);
            }
            return;
        }
        for ((v, d), (l, h)) in values.iter_mut().zip(deltas.iter_mut()).zip(rows) {
            let (lo, hi) = (i64::from(word(l)), i64::from(word(h)));
            *v = self.lerp(lo, hi, f);
            *d = to_q30((hi - lo) << 31, sh);
        }
    }

    /// Converts a change across one interval (Q30 in) into a slope per inch
    /// of X (Q30 in/in), saturating.
    #[inline]
    pub fn per_inch(&self, delta_q30: i64) -> i64 {
        let d = delta_q30.clamp(-(1 << 32), 1 << 32);
        (d * self.per_inch_q16 + (1 << 15)) >> 16
    }
}

/// Column `column` of a row (little-endian i32), zero if absent.
#[inline(always)]
fn read(row: &[u8], column: u8) -> i64 {
    let at = usize::from(column) * 4;
    row.get(at..at + 4)
        .and_then(|b| <[u8; 4]>::try_from(b).ok())
        .map_or(0, |b| i64::from(i32::from_le_bytes(b)))
}

#[inline(always)]
fn sat_i32(v: i64) -> i32 {
    v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

/// Rounds `v` with `shift` (1..=32) fraction bits more than Q30 to Q30 and
/// saturates to i32.
#[inline]
fn to_q30(v: i64, shift: u32) -> i32 {
    let r = (v + (1i64 << (shift - 1))) >> shift;
    r.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;
    use super::*;
    use crate::table::{Geometry, Representation, TableHeader};
    use std::vec;
    use std::vec::Vec;

    pub fn header(nodes: u32, terms: u8, fc: u8, fx: u8, dx_raw: i32) -> TableHeader {
        TableHeader {
            representation: Representation::SinPower,
            terms,
            coeff_frac_bits: fc,
            x_frac_bits: fx,
            node_count: nodes,
            x0_raw: 0,
            dx_raw,
            x_null_raw: 0,
            geometry: Geometry {
                c_nin: 316_700_000_000,
                s_y_nin: 28_000_000_000,
                tool_radius_nin: 125_000_000,
            },
        }
    }

    fn image(h: &TableHeader, payload: &[i32]) -> Vec<u8> {
        let mut out = vec![0u8; h.image_len()];
        h.encode(payload, &mut out).unwrap();
        out
    }

    /// The binary grid's shift is exactly the reciprocal's fraction for
    /// every remainder in an interval of the default table (1/32 in = 2¹⁹
    /// X bits), and a grid that is not binary has none.
    #[test]
    fn frac_shift_equals_the_reciprocal_for_every_remainder() {
        let it = Interpolator::new(CoeffTable::parse(crate::DEFAULT_TABLE).unwrap());
        let s = it.frac_shift().unwrap();
        assert_eq!(s, 32 - 19);
        for rem in 0..(1u32 << 19) {
            assert_eq!(rem << s, it.frac_of_rem(u64::from(rem)), "{rem}");
        }
        let h = header(5, 1, 30, 24, 3 << 20);
        let img = image(&h, &[0, 1, 2, 3, 4]);
        let odd = Interpolator::new(CoeffTable::parse(&img).unwrap());
        assert_eq!(odd.frac_shift(), None);
    }

    /// Exact value of the piecewise-linear function at X (f64 on exact
    /// rationals is enough here: the numbers are far below 2^53).
    fn reference(h: &TableHeader, payload: &[i32], x: f64, col: usize) -> f64 {
        let scale_x = 2f64.powi(i32::from(h.x_frac_bits));
        let dx = f64::from(h.dx_raw) / scale_x;
        let x0 = f64::from(h.x0_raw) / scale_x;
        let u = (x - x0) / dx;
        let i = (u.floor() as usize).min(h.node_count as usize - 1);
        let f = u - i as f64;
        let t = usize::from(h.terms);
        let c =
            |n: usize| f64::from(payload[n * t + col]) / 2f64.powi(i32::from(h.coeff_frac_bits));
        if i + 1 >= h.node_count as usize {
            c(i)
        } else {
            c(i) + (c(i + 1) - c(i)) * f
        }
    }

    #[test]
    fn matches_the_exact_piecewise_linear_function() {
        // 0.1 in grid with 24 X fraction bits is inexact in binary: the node
        // positions are whatever the raw grid says, and the interpolator
        // must follow them.
        let h = header(81, 2, 30, 24, 1_677_722);
        let payload: Vec<i32> = (0..81 * 2)
            .map(|i| ((i * i * 7919) % 6_000_000) - 3_000_000)
            .collect();
        let img = image(&h, &payload);
        let it = Interpolator::new(CoeffTable::parse(&img).unwrap());
        let mut x = 0.0;
        while x <= 8.0 {
            let xi = XInches::from_f64(x);
            let Located::In(l) = it.locate(xi) else {
                panic!("{x} not in table")
            };
            for col in 0..2u8 {
                let want = reference(&h, &payload, xi.to_f64(), usize::from(col));
                let got = f64::from(it.value(l, col)) / 2f64.powi(30);
                assert!(
                    (got - want).abs() <= 1.01 * 2f64.powi(-30),
                    "x={x} col={col}: {got} vs {want}"
                );
            }
            x += 0.000_731;
        }
        assert_eq!(it.locate(XInches::from_f64(-1e-7)), Located::Below);
        assert_eq!(it.locate(XInches::from_f64(8.001)), Located::Above);
    }

    mod prop {
        use super::*;
        use proptest::prelude::*;

        proptest! {
            /// Approaching any node from below ends within one LSB of the
            /// node's value, and the node itself is exact: no grooves.
            #[test]
            fn continuous_across_every_node(
                vals in proptest::collection::vec(any::<i32>(), 6..40),
                fc in 0u8..=31, fx in 0u8..=31, dx_in in 1e-4f64..0.25,
            ) {
                let nodes = vals.len() as u32;
                // Keep the last node inside both the X format and the table's.
                let room = 2f64.powi(31 - i32::from(fx)).min(127.0) / f64::from(nodes);
                let dx_raw = ((dx_in.min(room) * 2f64.powi(fx.into())) as i32).max(1);
                let h = header(nodes, 1, fc, fx, dx_raw);
                let img = image(&h, &vals);
                let t = CoeffTable::parse(&img).unwrap();
                let it = Interpolator::new(t);
                let q30 = |c: i32| -> i64 {
                    let v = ((i64::from(c) << 31) + (1i64 << fc)) >> (u32::from(fc) + 1);
                    v.clamp(i32::MIN.into(), i32::MAX.into())
                };
                for n in 1..nodes {
                    let xn = t.node_x(n);
                    // Nodes that I8F24 cannot resolve are skipped.
                    if t.node_x(n - 1) >= xn { continue; }
                    let below = XInches::from_bits(xn.to_bits() - 1);
                    let (Located::In(a), Located::In(b)) = (it.locate(below), it.locate(xn)) else {
                        continue;
                    };
                    let va = i64::from(it.value(a, 0));
                    let vb = i64::from(it.value(b, 0));
                    let want = q30(vals[n as usize]);
                    // Node value exact where X is exact in I8F24 (fx ≤ 24).
                    if fx <= 24 { prop_assert_eq!(vb, want); }
                    // One X LSB below the node: moves by at most the slope
                    // over that LSB, plus rounding.
                    let lo = q30(vals[n as usize - 1]);
                    let steps = (1u64 << 24) as f64 / (xn.to_bits() - t.node_x(n - 1).to_bits()) as f64;
                    let bound = ((want - lo).abs() as f64 * steps).ceil() as i64 + 2;
                    prop_assert!((va - vb).abs() <= bound, "node {n}: {va} vs {vb} (bound {bound})");
                }
            }

            /// The 32-bit locate and the general one agree everywhere.
            #[test]
            fn fast_and_general_locate_agree(
                nodes in 2u32..300, fx in 0u8..=24, dx_in in 1e-4f64..0.5,
                x0_in in -2.0f64..2.0, xbits in any::<i32>(),
            ) {
                let room = (100.0 / f64::from(nodes)).min(dx_in);
                let dx_raw = ((room * 2f64.powi(fx.into())) as i32).max(1);
                let mut h = header(nodes, 1, 30, fx, dx_raw);
                h.x0_raw = (x0_in * 2f64.powi(fx.into())) as i32;
                h.x_null_raw = h.x0_raw;
                let vals: Vec<i32> = (0..nodes as i32).collect();
                let img = image(&h, &vals);
                let Ok(t) = CoeffTable::parse(&img) else { return Ok(()); };
                let it = Interpolator::new(t);
                prop_assert!(it.fast.is_some());
                for x in [xbits, xbits / 64, t.node_x(nodes / 2).to_bits(), t.node_x(nodes - 1).to_bits()] {
                    let x = XInches::from_bits(x);
                    prop_assert_eq!(it.locate(x), it.locate_general(x));
                }
            }

            /// The one-pass row reader (with its Q30 fast path) and the
            /// per-column reader agree bit for bit.
            #[test]
            fn columns_equal_value_and_delta(
                vals in proptest::collection::vec(any::<i32>(), 12..60),
                fc in prop_oneof![Just(30u8), 0u8..=31],
                xbits in 0i32..(40 << 24),
            ) {
                let nodes = vals.len() as u32 / 3;
                let vals = &vals[..nodes as usize * 3];
                let h = header(nodes, 3, fc, 24, 1 << 22);
                let img = image(&h, vals);
                let it = Interpolator::new(CoeffTable::parse(&img).unwrap());
                if let Located::In(l) = it.locate(XInches::from_bits(xbits)) {
                    let (mut v, mut d) = ([0i32; 3], [0i32; 3]);
                    it.columns(l, &mut v, &mut d);
                    for c in 0..3u8 {
                        prop_assert_eq!(v[usize::from(c)], it.value(l, c));
                        prop_assert_eq!(d[usize::from(c)], it.delta(l, c));
                    }
                }
            }

            /// Any X, any table the format allows: never panics, and the
            /// value lies between the two node values (no overflow wrap).
            #[test]
            fn bounded_between_nodes_everywhere(
                vals in proptest::collection::vec(any::<i32>(), 2..30),
                fc in 0u8..=31, fx in 0u8..=31, dx_in in 1e-5f64..4.0,
                xbits in any::<i32>(),
            ) {
                let nodes = vals.len() as u32;
                let dx_raw = ((dx_in * 2f64.powi(fx.into())) as i32).max(1);
                let h = header(nodes, 1, fc, fx, dx_raw);
                let img = image(&h, &vals);
                let Ok(t) = CoeffTable::parse(&img) else { return Ok(()); };
                let it = Interpolator::new(t);
                if let Located::In(l) = it.locate(XInches::from_bits(xbits)) {
                    let v = i64::from(it.value(l, 0));
                    let q = |c: i32| (((i64::from(c) << 31) + (1i64 << fc)) >> (u32::from(fc) + 1)).clamp(i32::MIN.into(), i32::MAX.into());
                    let a = q(vals[l.node as usize]);
                    let b = q(*vals.get(l.node as usize + 1).unwrap_or(&vals[l.node as usize]));
                    prop_assert!(v >= a.min(b) - 1 && v <= a.max(b) + 1);
                    let _ = it.per_inch(i64::from(it.delta(l, 0)));
                }
            }
        }
    }
}
