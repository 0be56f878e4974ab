//! Coefficients at X for the X handler from per-interval slopes computed
//! once, at table load: an X event (legacy half-mil or modern X count)
//! finds its grid interval (the cached one while X stays in it; a shift of
//! the offset on a binary grid otherwise), reads the interval's lower node
//! row from flash and its slopes from RAM, and costs one multiply-add per
//! column, no division and no row fetch at a crossing: every event costs
//! about what an event inside the interval does. Bit-identical to
//! `CommandGen::coefficients_into` (tested over the whole table).
//!
//! RAM: one word per interval and column, [`SLOPES`] words at most (the
//! default table: 256 intervals × 5 columns = 1280). A table that does not
//! fit, or is not Q30 within the fast path's range, or whose grid is not
//! in X bits, takes the command path's general interpolation instead.

use crate::command::{Coefficients, CommandGen, COEFF_LIMIT};
use crate::safety::Fault;
use crate::table::MAX_TERMS;
use crate::units::XInches;
use crate::word::Word;
use core::sync::atomic::Ordering;

/// Capacity of the slope table, words (8 KiB).
pub const SLOPES: usize = 2048;

/// The X handler's interpolation state: the interval X was last in and
/// the slopes of every interval (last: see `EventState`).
#[derive(Clone, Debug)]
#[repr(C)]
pub(crate) struct IntervalCache {
    /// The interval X was last in (its lower node).
    pub(crate) interval: Option<u32>,
    /// X of the interval's nodes, `I8F24` bits (`x_lo ≤ X < x_hi`).
    pub(crate) x_lo: i32,
    pub(crate) x_hi: i32,
    /// Node 0 and the grid step, `I8F24` bits.
    pub(crate) x0: i32,
    pub(crate) dx: i32,
    /// A binary grid's fraction as a shift of the remainder
    /// ([`crate::table::interp::Interpolator::frac_shift`]).
    pub(crate) frac_shift: Option<u32>,
    /// Columns per node row.
    pub(crate) terms: usize,
    /// The interval's lower node row (in the table, in flash) and where
    /// its slopes start, set when X enters the interval.
    pub(crate) row: &'static [[u8; 4]],
    pub(crate) at: usize,
    /// `row[n + 1][c] − row[n][c]` (raw Q30) at `n·terms + c`.
    pub(crate) slopes: [i32; SLOPES],
}

/// The columns at `x` through the command path itself (tables the cached
/// path does not cover).
pub(crate) fn general_columns(
    g: &CommandGen<'static>,
    terms: usize,
    values: &[Word],
    x: XInches,
) -> Result<bool, Fault> {
    let mut c = Coefficients::NULL;
    g.coefficients_into(x, &mut c)?;
    if c.null {
        return Ok(false);
    }
    for (v, a) in values.iter().zip(c.value.iter()).take(terms) {
        v.store(*a as u32, Ordering::Relaxed);
    }
    Ok(true)
}

/// Whether `gen`'s table takes the slope path: Q30 with every
/// |coefficient| ≤ COEFF_LIMIT/2 (all real ones: no clamp in
/// `coefficients_into`, node changes fit an i32), a grid in X bits, and
/// slopes that fit [`SLOPES`]; and its live column count.
pub(crate) fn fast_and_terms(gen: Option<&CommandGen<'static>>) -> (bool, u8) {
    match gen {
        Some(g) => {
            let t = g.interpolator().table();
            let h = t.header();
            let words = (t.node_count() as usize - 1) * usize::from(h.terms);
            (
                h.coeff_frac_bits == 30
                    && g.interpolator().max_abs_q30() <= i64::from(COEFF_LIMIT / 2)
                    && g.interpolator().x_in_grid_units()
                    && words <= SLOPES,
                h.terms.min(MAX_TERMS),
            )
        }
        None => (false, 0),
    }
}

/// Where [`IntervalCache::seek`] found X.
pub(crate) enum Seek {
    /// Beyond the table's command range: the null command.
    Null,
    /// On the last node: the command path's own way.
    General,
    /// In the cached interval, at this Q31 position.
    In(i32),
}

impl IntervalCache {
    /// The slopes of `gen`'s table (left zero when it does not take the
    /// slope path, [`fast_and_terms`]).
    pub(crate) fn new(gen: Option<&CommandGen<'static>>) -> Self {
        let mut c = Self {
            interval: None,
            x_lo: 0,
            x_hi: 0,
            x0: gen.map_or(0, |g| g.interpolator().table().node_x(0).to_bits()),
            dx: gen.map_or(0, |g| {
                let t = g.interpolator().table();
                t.node_x(1).to_bits().wrapping_sub(t.node_x(0).to_bits())
            }),
            frac_shift: gen.and_then(|g| g.interpolator().frac_shift()),
            terms: gen.map_or(0, |g| usize::from(g.interpolator().table().terms())),
            row: &[],
            at: 0,
            slopes: [0; SLOPES],
        };
        if let (Some(g), (true, _)) = (gen, fast_and_terms(gen)) {
            let t = g.interpolator().table();
            let rows = (0..t.node_count()).map(|n| t.node_row(n).as_chunks::<4>().0);
            let pairs = rows.clone().zip(rows.skip(1));
            for (d, (lo, hi)) in c.slopes.chunks_mut(c.terms.max(1)).zip(pairs) {
                for (d, (a, b)) in d.iter_mut().zip(lo.iter().zip(hi)) {
                    // |values| ≤ 2²⁶ (the fast path's bound): fits an i32.
                    *d = i32::from_le_bytes(*b).wrapping_sub(i32::from_le_bytes(*a));
                }
            }
        }
        c
    }

    /// Moves to the interval holding `x` and gives the position in it, bit
    /// for bit what [`crate::table::interp::Interpolator::locate`] gives: the
    /// cached interval while X stays in it (X moves by half-mils, ~60
    /// events per 1/32 in); otherwise the node from the offset (a shift on
    /// a binary grid, exactly `locate`'s node) or, off the grid's interior,
    /// `locate` itself. The fraction from the remainder exactly as `locate`
    /// forms it (a shift on a binary grid). No division anywhere.
    #[inline(always)]
    pub(crate) fn seek(&mut self, g: &CommandGen<'static>, x: XInches) -> Result<Seek, Fault> {
        if x > g.x_null() {
            return Ok(Seek::Null);
        }
        let it = g.interpolator();
        let bits = x.to_bits();
        match self.interval {
            Some(_) if bits >= self.x_lo && bits < self.x_hi => {}
            _ => {
                let count = it.table().node_count();
                // The offset from node 0 as an unsigned word (checked to be
                // the true one below).
                let offset = bits.wrapping_sub(self.x0) as u32;
                let node = match self.frac_shift {
                    // Binary grid, 2ᵐ X bits (m = 32 − shift): ⌊offset/2ᵐ⌋
                    // inside the table's intervals.
                    Some(s) if bits >= self.x0 && (offset >> (32 - s)) + 1 < count => {
                        offset >> (32 - s)
                    }
                    // Anything else: below the table, its last node, beyond.
                    _ => match g.locate(x)? {
                        None => return Ok(Seek::Null),
                        Some(at) if at.node + 1 < count => at.node,
                        Some(_) => return Ok(Seek::General),
                    },
                };
                self.interval = Some(node);
                // The grid is exact in X bits (fast path): x0 + node·ΔX, no
                // overflow (the parser checked the last node fits).
                self.x_lo = self.x0.wrapping_add((node as i32).wrapping_mul(self.dx));
                self.x_hi = self.x_lo.wrapping_add(self.dx);
                self.row = it.table().node_row(node).as_chunks::<4>().0;
                self.at = node as usize * self.terms;
            }
        }
        let rem = bits.wrapping_sub(self.x_lo) as u32;
        let frac = match self.frac_shift {
            // rem < 2ᵐ: the shift loses nothing.
            Some(s) => rem << s,
            None => it.frac_of_rem(u64::from(rem)),
        };
        // Interpolator::interval: Q31 position = the Q32 fraction >> 1.
        Ok(Seek::In((frac >> 1) as i32))
    }

    /// Column `lo + d·f` of an interval at Q31 position `f`:
    /// `Interpolator::lerp` for Q30 tables, (d·f + 2³⁰) >> 31, as
    /// (2d·f + 2³¹) >> 32: the same integer (|2d| ≤ 2²⁸ fits an i32), and
    /// one SMMULR on the M4.
    #[inline(always)]
    pub(crate) fn lerp(lo: i32, d: i32, f: i32) -> i32 {
        let step = (i64::from(d << 1) * i64::from(f) + (1 << 31)) >> 32;
        lo.wrapping_add(step as i32)
    }
}

/// The columns at `x` from the interval's lower row and slopes
/// ([`IntervalCache::seek`]), bit for bit what
/// [`CommandGen::coefficients_into`] gives: per column one 32×32 → 64
/// multiply-add.
#[inline(always)]
pub(crate) fn fast_columns(
    g: &CommandGen<'static>,
    c: &mut IntervalCache,
    n: usize,
    values: &[Word],
    x: XInches,
) -> Result<bool, Fault> {
    let f = match c.seek(g, x)? {
        Seek::Null => return Ok(false),
        Seek::General => return general_columns(g, n, values, x),
        Seek::In(f) => f,
    };
    let row = c.row;
    let slopes = c.slopes.get(c.at..).unwrap_or(&[]);
    // One length for all three: no bounds checks in the loop.
    let m = n.min(row.len()).min(slopes.len()).min(values.len());
    for k in 0..m {
        let v = IntervalCache::lerp(i32::from_le_bytes(row[k]), slopes[k], f);
        values[k].store(v as u32, Ordering::Relaxed);
    }
    Ok(true)
}
