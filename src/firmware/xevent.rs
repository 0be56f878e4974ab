//! The X / index handlers (one priority level below the loop tick):
//! legacy half-mil X events decoded, debounced and scheduled, the
//! coefficients at the new X published for the loop tick (and, in the
//! legacy coefficient-output mode, written to the quad DAC); in the modern
//! X mode the X count, taken periodically at this priority, re-interpolated
//! and published the same way; index pulses published as they come.

use crate::command::CommandGen;
use crate::firmware::config::{FirmwareConfig, XMode};
use crate::handoff::coeffs::NULL_META;
use crate::handoff::Shared;
use crate::hw::{BusError, CoefficientDac, XLatchWord};
use crate::safety::{Device, Fault};
use crate::units::XInches;
use crate::xpos::columns::{fast_and_terms, fast_columns, general_columns, IntervalCache};
use crate::xpos::legacy_output::LegacyOutput;
use crate::xpos::{CountX, LegacyConfig, LegacyX, XEvent};

/// A quad DAC that is not there (the coefficient-output mode is off).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoCoefficientDac;

impl CoefficientDac for NoCoefficientDac {
    fn output(&mut self, _codes: &[u16; 4], _update: u8) -> Result<(), BusError> {
        Ok(())
    }
}

/// State of the X and index handlers (one priority level below the tick).
// In declaration order, the slope table last: every other field stays
// within the M4's 12-bit load offset of the state's address.
#[derive(Clone, Debug)]
#[repr(C)]
pub struct EventState {
    pub(crate) gen: Option<CommandGen<'static>>,
    pub(crate) legacy: Option<LegacyX>,
    /// Modern X: the count's scale and glitch check, and the last count
    /// published (an unchanged count publishes nothing).
    pub(crate) count: Option<CountX>,
    pub(crate) last_count: Option<u32>,
    pub(crate) coefficient_output: bool,
    pub(crate) out: LegacyOutput,
    /// Tables within the slope path's range ([`fast_and_terms`]: every
    /// real one) take it; others the command path's general one.
    pub(crate) fast: bool,
    pub(crate) terms: u8,
    pub(crate) coeff_gen: u32,
    pub(crate) cache: IntervalCache,
}

impl EventState {
    /// The X handlers' state; `count` is the modern X mode's scale (built
    /// and checked by the caller from [`XMode::Count`]).
    pub(crate) fn new(
        gen: Option<CommandGen<'static>>,
        cfg: &FirmwareConfig,
        count: Option<CountX>,
    ) -> Self {
        let legacy = match (cfg.x, gen) {
            (XMode::Legacy { clock_hz }, Some(g)) => {
                Some(LegacyX::new(LegacyConfig::new(g.x_null(), clock_hz)))
            }
            (XMode::Legacy { clock_hz }, None) => {
                // No table: every position is "null zone".
                Some(LegacyX::new(LegacyConfig::new(XInches::ZERO, clock_hz)))
            }
            _ => None,
        };
        let (fast, terms) = fast_and_terms(gen.as_ref());
        Self {
            gen,
            legacy,
            count,
            last_count: None,
            coefficient_output: cfg.coefficient_output,
            out: LegacyOutput::new(),
            cache: IntervalCache::new(gen.as_ref()),
            fast,
            terms,
            coeff_gen: 0,
        }
    }

    /// The legacy half-mil interrupt: `word` latched at the edge, `now` the
    /// clock then. Decode, debounce, schedule ([`LegacyX`]); an accepted
    /// event publishes the coefficients at the new X for the loop tick and,
    /// in the coefficient-output mode, writes the scheduled C0j to `quad`
    /// and strobes it. Faults go to the loop tick through `sh`.
    ///
    /// Never inlined, so `cargo xtask isr-cost` can find and count it.
    #[inline(never)]
    pub fn x_event(
        &mut self,
        sh: &Shared,
        word: XLatchWord,
        now: u32,
        quad: &mut impl CoefficientDac,
    ) -> Result<XEvent, Fault> {
        let Some(lx) = self.legacy.as_mut() else {
            return Ok(XEvent::Ignored);
        };
        let u = match lx.on_interrupt(word, now) {
            Ok(XEvent::Update(u)) => u,
            Ok(XEvent::Ignored) => {
                sh.count_x_ignored();
                return Ok(XEvent::Ignored);
            }
            Err(f) => {
                sh.raise(f);
                return Err(f);
            }
        };
        sh.count_x_accepted();
        if let Err(f) = self.publish(sh, u.x, u.null) {
            sh.raise(f);
            return Err(f);
        }
        if self.coefficient_output {
            if let Some(g) = self.gen.as_ref() {
                let frame = self.out.frame(g, &u)?;
                if quad.output(&frame.codes, frame.update).is_err() {
                    let f = Fault::Bus(Device::CoefficientDac);
                    sh.raise(f);
                    return Err(f);
                }
            }
        }
        Ok(XEvent::Update(u))
    }

    /// Modern X mode: the X count, taken by the board periodically at this
    /// handler's priority (about once per loop tick). When it moved, the
    /// coefficients at its X are published for the loop tick exactly as a
    /// legacy X event publishes them (one mechanism for both modes, and the
    /// re-interpolation stays out of the loop tick). A jump beyond the
    /// configured step is [`Fault::XGlitchStorm`], below the table
    /// [`Fault::XOutsideTable`], both raised for the loop tick; in the null
    /// zone the command is null.
    ///
    /// Never inlined, so `cargo xtask isr-cost` can find and count it.
    #[inline(never)]
    pub fn x_count_event(&mut self, sh: &Shared, count: u32) -> Result<(), Fault> {
        let Some(cx) = self.count.as_mut() else {
            return Ok(());
        };
        if self.last_count == Some(count) {
            return Ok(());
        }
        self.last_count = Some(count);
        let published = match cx.on_tick(count) {
            Ok(x) => self.publish(sh, x, false),
            Err(f) => Err(f),
        };
        if let Err(f) = published {
            sh.raise(f);
        }
        published
    }

    /// Computes every column at `x` into the free slot and publishes it.
    #[inline(always)]
    pub(crate) fn publish(&mut self, sh: &Shared, x: XInches, null: bool) -> Result<(), Fault> {
        let g_next = self.coeff_gen.wrapping_add(1);
        let terms = usize::from(self.terms);
        sh.coefficients().publish(g_next, x, |values| {
            let live = match self.gen.as_ref() {
                Some(g) if !null => {
                    if self.fast {
                        fast_columns(g, &mut self.cache, terms, values, x)?
                    } else {
                        general_columns(g, terms, values, x)?
                    }
                }
                _ => false,
            };
            Ok(if live {
                u32::from(self.terms)
            } else {
                NULL_META
            })
        })?;
        self.coeff_gen = g_next;
        Ok(())
    }
}

impl EventState {
    /// The once-per-revolution index: the encoder count the hardware latched
    /// at the edge (ignored with a tachometer) and the edge's timestamp.
    /// Published for the loop tick, which applies it to the estimator. See
    /// [`Shared::index_event`] (this handler's part holds no index state).
    #[inline(never)]
    pub fn index_event(&mut self, sh: &Shared, edge_ticks: u32, count_at_index: u32) {
        sh.index_event(edge_ticks, count_at_index);
    }
}
