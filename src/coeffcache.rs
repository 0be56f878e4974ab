//! Coefficients at X through a per-interval cache: the two node rows of
//! the grid interval X is in, fetched when X enters it, so an X event
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
    /// A binary grid's fraction as a shift of the remainder
    /// ([`crate::interp::Interpolator::frac_shift`]).
    pub(crate) frac_shift: Option<u32>,
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
            frac_shift: gen.and_then(|g| g.interpolator().frac_shift()),
        }
    }

    /// Moves the cache to the interval holding `x` (for Q30 tables within
    /// ±2²⁶, every real one) and gives the position in it, bit for bit what
    /// [`crate::interp::Interpolator::locate`] gives:
    ///
    /// * the cached interval while X stays in it (X moves by half-mils,
    ///   ~60 events per 1/32 in); otherwise the interval is found again
    ///   (on a binary grid, 2ᵐ X bits, its node is the offset shifted by m:
    ///   exactly `locate`'s node, with no search) and both of its node rows
    ///   are read from flash, so a crossing costs what the first event does;
    /// * the fraction from the remainder exactly as `locate` forms it (a
    ///   shift on a binary grid);
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
            let offset = i64::from(bits) - i64::from(self.x0);
            let node = match self.frac_shift {
                // Binary grid: ⌊offset / 2ᵐ⌋ (m = 32 − shift), inside the
                // table's intervals. Anything else (below the table, its
                // last node, beyond it) goes through `locate`.
                Some(s) if offset >= 0 && (offset >> (32 - s)) + 1 < i64::from(t.node_count()) => {
                    (offset >> (32 - s)) as u32
                }
                _ => match g.locate(x)? {
                    None => return Ok(Seek::Null),
                    Some(at) if at.node + 1 < t.node_count() => at.node,
                    Some(_) => return Ok(Seek::General),
                },
            };
            // The rows as words of a compile-time size (`as_chunks`: no
            // division by a run-time chunk size, which `chunks_exact` would
            // bring into the handler as a panic path).
            let (lo_row, _) = t.node_row(node).as_chunks::<4>();
            let (hi_row, _) = t.node_row(node + 1).as_chunks::<4>();
            let cache = self.lo.iter_mut().zip(self.d.iter_mut());
            for ((lo, d), (a, b)) in cache.zip(lo_row.iter().zip(hi_row)).take(n) {
                // |values| ≤ 2²⁶ (checked at load): changes fit an i32.
                *lo = i32::from_le_bytes(*a);
                *d = i32::from_le_bytes(*b).wrapping_sub(*lo);
            }
            self.interval = Some(node);
            // The grid is exact in X bits (fast path): x0 + node·ΔX, no
            // overflow (the parser checked the last node fits).
            self.x_lo = self.x0.wrapping_add((node as i32).wrapping_mul(self.dx));
            self.x_hi = self.x_lo.wrapping_add(self.dx);
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
