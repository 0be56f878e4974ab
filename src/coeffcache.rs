//! Coefficients at X through a per-interval cache: the two node rows of
//! the grid interval X is in, fetched once per interval, so an X event
//! (legacy half-mil or modern X count) costs one multiply-add per column
//! and no division; bit-identical to `CommandGen::coefficients_into`.

use crate::command::{Coefficients, CommandGen, COEFF_LIMIT};
use crate::config::COLS;
use crate::handoff::CoeffSlot;
use crate::safety::Fault;
use crate::table::MAX_TERMS;
use crate::units::XInches;
use core::sync::atomic::Ordering;

/// Per-interval cache of the X handler: the two node rows of the grid
/// interval X is in, fetched once per interval, so each event costs one
/// multiply-add per column and no division.
#[derive(Clone, Debug)]
pub(crate) struct IntervalCache {
    pub(crate) interval: Option<u32>,
    pub(crate) lo: [i32; COLS],
    /// `hi − lo` of the raw (Q30) node values.
    pub(crate) d: [i32; COLS],
    /// X of the interval's nodes, `I8F24` bits (`x_lo ≤ X < x_hi`).
    pub(crate) x_lo: i32,
    pub(crate) x_hi: i32,
    /// Node 0 and the grid step, `I8F24` bits.
    pub(crate) x0: i32,
    pub(crate) dx: i32,
}

/// The columns at `x` through the command path itself (tables the cached
/// path does not cover).
pub(crate) fn general_columns(
    g: &CommandGen<'static>,
    terms: usize,
    slot: &CoeffSlot,
    x: XInches,
) -> Result<bool, Fault> {
    let mut c = Coefficients::NULL;
    g.coefficients_into(x, &mut c)?;
    if c.null {
        return Ok(false);
    }
    for (v, a) in slot.value.iter().zip(c.value.iter()).take(terms) {
        v.store(*a, Ordering::Relaxed);
    }
    Ok(true)
}

/// Whether `gen`'s table takes the cached path: Q30 with every
/// |coefficient| ≤ COEFF_LIMIT/2 (all real ones: no clamp in
/// `coefficients_into`, node changes fit an i32) and a grid in X bits; and
/// its live column count.
pub(crate) fn fast_and_terms(gen: Option<&CommandGen<'static>>) -> (bool, u8) {
    match gen {
        Some(g) => {
            let h = g.interpolator().table().header();
            (
                h.coeff_frac_bits == 30
                    && g.interpolator().max_abs_q30() <= i64::from(COEFF_LIMIT / 2)
                    && g.interpolator().x_in_grid_units(),
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
    /// Inside the cached interval, Q31 position in it.
    In(i32),
}

impl IntervalCache {
    pub(crate) fn new(gen: Option<&CommandGen<'static>>) -> Self {
        Self {
            interval: None,
            lo: [0; COLS],
            d: [0; COLS],
            x_lo: 0,
            x_hi: 0,
            x0: gen.map_or(0, |g| g.interpolator().table().node_x(0).to_bits()),
            dx: gen.map_or(0, |g| {
                let t = g.interpolator().table();
                t.node_x(1).to_bits().wrapping_sub(t.node_x(0).to_bits())
            }),
        }
    }

    /// Moves the cache to the interval holding `x` (for Q30 tables within
    /// ±2²⁶, every real one) and gives the position in it, bit for bit what
    /// [`crate::interp::Interpolator::locate`] gives:
    ///
    /// * the cached interval while X stays in it (X moves by half-mils,
    ///   ~60 events per 1/32 in), its neighbour when X crosses a node, a
    ///   search only after a jump; the fraction from the remainder exactly
    ///   as `locate` forms it;
    /// * at a crossing to a neighbour only the one new node row is read
    ///   from flash: the shared node's values are the cached `lo` or
    ///   `lo + d`, exactly (the change was formed from them);
    /// * no division anywhere.
    #[inline(always)]
    pub(crate) fn seek(
        &mut self,
        g: &CommandGen<'static>,
        n: usize,
        x: XInches,
    ) -> Result<Seek, Fault> {
        if x > g.x_null() {
            return Ok(Seek::Null);
        }
        let it = g.interpolator();
        let t = it.table();
        let bits = x.to_bits();
        let inside = self.interval.is_some() && bits >= self.x_lo && bits < self.x_hi;
        if !inside {
            let dx = self.dx;
            let word = |b: &[u8]| i32::from_le_bytes(<[u8; 4]>::try_from(b).unwrap_or([0; 4]));
            let node = match self.interval {
                Some(k) if bits >= self.x_hi && bits - self.x_hi < dx && k + 2 < t.node_count() => {
                    // Up: the old high node is the new low one.
                    // Rows are stepped with `next`, never zipped: a zip of
                    // `ChunksExact` sizes itself with a division by the
                    // run-time chunk size, a `panic_const_div_by_zero` path
                    // in the handler (`cargo xtask no-panic` finds it).
                    let mut hi = t.node_row(k + 2).chunks_exact(4);
                    for (lo, d) in self.lo.iter_mut().zip(self.d.iter_mut()).take(n) {
                        let Some(b) = hi.next() else { break };
                        // |values| ≤ 2²⁶ (checked at load): sums and
                        // changes fit an i32.
                        *lo = lo.wrapping_add(*d);
                        *d = word(b).wrapping_sub(*lo);
                    }
                    k + 1
                }
                Some(k) if bits < self.x_lo && self.x_lo - bits <= dx && k > 0 => {
                    // Down: the old low node is the new high one.
                    let mut lo_row = t.node_row(k - 1).chunks_exact(4);
                    for (lo, d) in self.lo.iter_mut().zip(self.d.iter_mut()).take(n) {
                        let Some(a) = lo_row.next() else { break };
                        let v = word(a);
                        *d = lo.wrapping_sub(v);
                        *lo = v;
                    }
                    k - 1
                }
                _ => {
                    let node = match g.locate(x)? {
                        None => return Ok(Seek::Null),
                        Some(at) if at.node + 1 < t.node_count() => at.node,
                        Some(_) => return Ok(Seek::General),
                    };
                    let mut lo_row = t.node_row(node).chunks_exact(4);
                    let mut hi_row = t.node_row(node + 1).chunks_exact(4);
                    for (lo, d) in self.lo.iter_mut().zip(self.d.iter_mut()) {
                        let (Some(a), Some(b)) = (lo_row.next(), hi_row.next()) else {
                            break;
                        };
                        *lo = word(a);
                        *d = word(b).wrapping_sub(*lo);
                    }
                    node
                }
            };
            self.interval = Some(node);
            // The grid is exact in X bits (fast path): x0 + node·ΔX, no
            // overflow (the parser checked the last node fits).
            self.x_lo = self.x0.wrapping_add((node as i32).wrapping_mul(self.dx));
            self.x_hi = self.x_lo.wrapping_add(self.dx);
        }
        let rem = u64::from(bits.wrapping_sub(self.x_lo) as u32);
        // Interpolator::interval: Q31 position = the Q32 fraction >> 1.
        Ok(Seek::In((it.frac_of_rem(rem) >> 1) as i32))
    }

    /// Column `lo + d·f` of the cached interval at Q31 position `f`:
    /// `Interpolator::lerp` for Q30 tables, (d·f + 2³⁰) >> 31, as
    /// (2d·f + 2³¹) >> 32: the same integer (|2d| ≤ 2²⁸ fits an i32), and
    /// one SMMULR on the M4.
    #[inline(always)]
    pub(crate) fn lerp(lo: i32, d: i32, f: i32) -> i32 {
        let step = (i64::from(d << 1) * i64::from(f) + (1 << 31)) >> 32;
        lo.wrapping_add(step as i32)
    }
}

/// The columns at `x` through the interval cache ([`IntervalCache::seek`]),
/// bit for bit what [`CommandGen::coefficients_into`] gives: per column one
/// 32×32 → 64 multiply-add.
#[inline(always)]
pub(crate) fn fast_columns(
    g: &CommandGen<'static>,
    c: &mut IntervalCache,
    n: usize,
    slot: &CoeffSlot,
    x: XInches,
) -> Result<bool, Fault> {
    let f = match c.seek(g, n, x)? {
        Seek::Null => return Ok(false),
        Seek::General => return general_columns(g, n, slot, x),
        Seek::In(f) => f,
    };
    let cols = c.lo.iter().zip(c.d.iter());
    for ((lo, d), v) in cols.zip(slot.value.iter()).take(n) {
        v.store(IntervalCache::lerp(*lo, *d, f), Ordering::Relaxed);
    }
    Ok(true)
}
