//! The firmware application: the command path and the loop, behind the three
//! interrupt entry points the boards call. Both boards (`src/main.rs` on the
//! NUCLEO-H743ZI2 and `boards/qemu`) and `host-sim` drive the same code.
//!
//! # Data path
//!
//! ```text
//! X event (legacy half-mil) ── xpos::LegacyX ── coefficients at X ──┐ publish (Shared)
//! index event ─────────────────────────────── (count, edge) ────────┤ publish (Shared)
//! loop tick: gauge ─┐                                                │
//!   spindle sample ─┴ spindle estimator → φ, Δφ ; picks up X / index ┘
//!   modern X count → xpos::CountX → coefficients_into (when the count moved)
//!   evaluate_phi → Z, ∂Z/∂φ → command (gauge codes) + ∂Z/∂φ·Δφ feedforward
//!   → loop → amplifier DAC
//! ```
//!
//! # Priorities and the hand-off
//!
//! The loop tick runs at the highest priority; the X and index events run
//! below it (one level, so they never preempt each other) and are preempted
//! by it. The state is split by owner: [`LoopState`] belongs to the
//! loop-tick handler, [`EventState`] to the X/index handlers, and the only
//! data they share is [`Shared`]: atomics, no locks, no masking.
//!
//! * Coefficients (X event → loop tick): a double buffer of atomic words and
//!   a generation counter. The X handler writes the whole coefficient set
//!   into the slot of generation + 1 (modulo 2) — first that slot's own
//!   sequence word, a release fence, then the data — and publishes it with
//!   one `Release` store of the generation. The loop tick compares the
//!   generation (one load per tick) and copies the slot only when it
//!   changed; after an acquire fence it keeps the copy only if the slot's
//!   sequence word still equals the generation (the seqlock rule), else it
//!   takes the next one. On a single core where the tick preempts the X
//!   handler, the slot being written is never the published one and the
//!   tick runs to completion before the handler resumes, so the check never
//!   fails there; it makes the scheme correct under real concurrency too (a
//!   host test with two threads finds torn sets without it). A lock
//!   (critical section) would instead delay the loop tick by a whole X
//!   event; RTIC ceilings would tie the core to one framework; this costs a
//!   few instructions per tick.
//! * Index (index event → loop tick, [`Shared::index_event`]): the same
//!   two-slot scheme for the `(count at index, edge time)` pair; the loop tick applies it to the
//!   estimator at its next tick (≤ one loop period later: the phase is taken
//!   from the hardware-latched count and edge time, so the delay costs no
//!   accuracy). More than one index within one loop period is
//!   [`Fault::IndexExtra`].
//! * Faults found by the X handler (X outside the table, glitch storm, bad
//!   BCD, coefficient-DAC bus error) are set as bits of one atomic word; the
//!   loop tick latches them at its next tick and reacts.
//!
//! [`Firmware`] bundles the three for single-threaded users (host tests,
//! `host-sim`): its methods call the parts with its own [`Shared`]. The
//! boards take the parts apart ([`Firmware::into_parts`]) and give each
//! handler its own, with a `static` [`Shared`].
//!
//! # The loop (a placeholder until the servo issue)
//!
//! A fixed-point PID position loop on the gauge code with velocity
//! feedforward:
//!
//! ```text
//! g[n]  = target + Z(X, φ[n]) in gauge codes   (0 while a fault is latched)
//! c[n]  = c[n-1] moved toward g[n] by at most `slew_per_tick`
//! e[n]  = c[n] - y[n]                               (gauge codes)
//! v[n]  = ∂Z/∂φ·(φ[n] − φ[n−1]) if c[n] = g[n], else c[n] − c[n−1]
//! I[n]  = clamp(I[n-1] + ki·e[n], ±output_limit)
//! u[n]  = clamp(kp·e[n] + I[n] - kd·(y[n] - y[n-1]) + kv·v[n],
//!               ±output_limit)                      (DAC codes)
//! kv    = kff + kd while following the table, kff while slewing
//! ```
//!
//! The derivative acts on the measurement, not the error, so command steps
//! do not kick the output. Gains are `I8F24`; products are formed in `i64`
//! and the sum is rounded to the nearest DAC code, then saturated. Gauge and
//! DAC codes share a scale (2¹⁹ = 10 V), so `kp` is in volts per gauge volt.
//! `v` is in gauge codes per tick, Q16: the analytic slope times the
//! measured angle step, so the feedforward has neither the noise nor the
//! half-tick lag of a differenced command.
//!
//! # Safety
//!
//! Nothing here can panic or allocate. A table the parser refuses, or one
//! whose command is positive somewhere (sign check at load), leaves the
//! firmware faulted with [`Fault::Table`] and the command null. The first
//! gauge read at engagement sets the command to where the slide is
//! (bumpless), and the command then ramps to its goal. Before the first
//! index (angle unknown) and before the first X (position unknown) the table
//! command is null. Faults latch ([`Firmware::fault`]); a fault whose
//! reaction is [`Reaction::DisableAmplifier`] clamps the DAC to ground
//! (retried every tick until the DAC accepts it), stops all DAC writes and
//! drops [`Firmware::amplifier_enable`]; a [`Reaction::RampToNull`] fault
//! keeps the loop closed and ramps the command to zero at the slew limit.
//! Only a more severe fault replaces a latched one; nothing clears a latch
//! but a new [`Firmware`].

use core::sync::atomic::{fence, AtomicI32, AtomicU32, Ordering};

use crate::command::{Coefficients, CommandGen, LegacyOutput, COEFF_LIMIT};
use crate::hw::{AmplifierDac, BusError, CoefficientDac, EncoderSample, GaugeAdc, XLatchWord};
use crate::safety::{Device, Fault, Reaction};
use crate::servo::{Freeze, Phase, Reference, Servo, ServoConfig, ServoInput};
use crate::spindle::{EncoderAngle, EncoderConfig, TachAngle, TachConfig};
use crate::table::{CoeffTable, TableError, MAX_TERMS};
use crate::units::{SpindleAngle, XInches, ZInches};
use crate::xpos::{CountConfig, CountX, LegacyConfig, LegacyX, XEvent};

/// Largest 20-bit two's complement code (gauge ADC and amplifier DAC).
pub const CODE_MAX: i32 = (1 << 19) - 1;
/// Smallest 20-bit two's complement code.
pub const CODE_MIN: i32 = -(1 << 19);

/// The gauge code that reads `z` (gauge 1 V/mil, ±10 V = ±0.010 in over
/// ±2¹⁹ codes), rounded to nearest and clamped to the converter range.
///
/// `code = z · 2¹⁹ / 0.010 in = z_bits · 2¹⁹ / (0.010 · 2³⁰) = z_bits · 25 / 512`,
/// exact in integers.
pub const fn gauge_code_from_z(z: ZInches) -> i32 {
    let scaled = z.to_bits() as i64 * 25;
    let code = (scaled + 256) >> 9;
    if code > CODE_MAX as i64 {
        CODE_MAX
    } else if code < CODE_MIN as i64 {
        CODE_MIN
    } else {
        code as i32
    }
}

const COLS: usize = MAX_TERMS as usize;

/// Where the spindle angle comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpindleMode {
    /// No spindle: the angle is 0 and the table command stays null (bench
    /// use: the loop follows [`Firmware::set_target_code`] only).
    None,
    /// Encoder + index ([`EncoderAngle`]).
    Encoder(EncoderConfig),
    /// Tachometer + index, the 1983 scheme ([`TachAngle`]).
    Tach(TachConfig),
}

/// Where X comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum XMode {
    /// No X source: the table command stays null.
    None,
    /// The legacy half-mil interrupt ([`Firmware::x_event`]); `clock_hz` is
    /// the rate of the `now` timestamps (storm window). The null zone is the
    /// table's.
    Legacy { clock_hz: u32 },
    /// A count read every loop tick ([`TickInput::x_count`]).
    Count(CountConfig),
}

/// Everything a [`Firmware`] is built from besides its table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FirmwareConfig {
    pub loop_cfg: ServoConfig,
    pub spindle: SpindleMode,
    pub x: XMode,
    /// Legacy coefficient-output mode: each accepted X event also writes
    /// C00..C03 to the quad DAC and strobes it (Table 3-1 scaling).
    pub coefficient_output: bool,
    /// The gauge reads −Z (the 1983 gauge after it was moved): its codes are
    /// negated before the loop.
    pub gauge_reversed: bool,
}

/// A configuration that cannot run (a programming error, not a machine
/// fault: the board refuses to start).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ConfigError {
    /// [`EncoderAngle::new`] or [`TachAngle::new`] refused the configuration.
    Spindle,
    /// [`CountX::new`] refused the configuration.
    Count,
}

/// One spindle reading, as the hw traits deliver it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpindleReading {
    /// No reading (no spindle configured).
    None,
    /// [`crate::hw::Encoder::sample`] of the spindle encoder.
    Encoder(EncoderSample),
    /// [`crate::hw::Tachometer::millivolts`].
    Tach(i32),
}

/// What the loop tick samples besides the gauge, read by the board from its
/// hw-trait implementations at the tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TickInput {
    /// [`crate::hw::Clock::now_ticks`] at the sampling instant.
    pub now: u32,
    pub spindle: SpindleReading,
    /// Modern X mode: the X encoder's count ([`crate::hw::Encoder`]).
    pub x_count: u32,
    /// The power amplifier's fault line (high: it tripped).
    pub amplifier_fault: bool,
}

impl TickInput {
    /// No spindle, no X: the bench's input.
    pub const NONE: Self = Self {
        now: 0,
        spindle: SpindleReading::None,
        x_count: 0,
        amplifier_fault: false,
    };
}

/// A quad DAC that is not there (the coefficient-output mode is off).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoCoefficientDac;

impl CoefficientDac for NoCoefficientDac {
    fn output(&mut self, _codes: &[u16; 4], _update: u8) -> Result<(), BusError> {
        Ok(())
    }
}

// ---------------------------------------------------------------------------
// The shared part: atomics only.

/// One published coefficient set.
struct CoeffSlot {
    value: [AtomicI32; COLS],
    delta: [AtomicI32; COLS],
    x: AtomicI32,
    /// Live columns, or [`NULL_META`] for the null command.
    meta: AtomicU32,
    /// Generation being written into / held by this slot; stored before the
    /// data, so a reader that finds it unchanged after copying has a
    /// complete set (the seqlock rule).
    seq: AtomicU32,
}

const NULL_META: u32 = 1 << 31;

impl CoeffSlot {
    const fn new() -> Self {
        Self {
            value: [const { AtomicI32::new(0) }; COLS],
            delta: [const { AtomicI32::new(0) }; COLS],
            x: AtomicI32::new(0),
            meta: AtomicU32::new(NULL_META),
            seq: AtomicU32::new(0),
        }
    }
}

/// Fault bits of the X handler ([`Shared::x_faults`]).
const XF_OUTSIDE: u32 = 1 << 0;
const XF_STORM: u32 = 1 << 1;
const XF_BCD: u32 = 1 << 2;
const XF_QUAD_BUS: u32 = 1 << 3;

fn x_fault_bit(f: Fault) -> u32 {
    match f {
        Fault::XOutsideTable => XF_OUTSIDE,
        Fault::XBadBcd => XF_BCD,
        Fault::Bus(Device::CoefficientDac) => XF_QUAD_BUS,
        // Every other fault the X path can meet is a storm of some kind.
        _ => XF_STORM,
    }
}

const X_FAULTS: [(u32, Fault); 4] = [
    (XF_OUTSIDE, Fault::XOutsideTable),
    (XF_STORM, Fault::XGlitchStorm),
    (XF_BCD, Fault::XBadBcd),
    (XF_QUAD_BUS, Fault::Bus(Device::CoefficientDac)),
];

/// The data that crosses priorities (see the module docs): written by the
/// X/index handlers, read by the loop tick. `const`-constructible, so a
/// board can keep it in a `static`.
pub struct Shared {
    coeff_gen: AtomicU32,
    coeff: [CoeffSlot; 2],
    index_seq: AtomicU32,
    /// `[count at index, edge ticks, sequence]` per slot.
    index: [[AtomicU32; 3]; 2],
    x_faults: AtomicU32,
    x_accepted: AtomicU32,
    x_ignored: AtomicU32,
    /// Operator requests ([`Request`] bits), taken by the next loop tick.
    requests: AtomicU32,
}

/// What the operator (a switch, the host link, host-sim) asks of the loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Request {
    /// Sign check, then bumpless engagement on the table command.
    Arm,
    /// Ramp to null, then disable the amplifier.
    Disarm,
    /// Clear the latched fault (refused while its cause is present or the
    /// loop is armed).
    ClearFault,
}

impl Request {
    const fn bit(self) -> u32 {
        match self {
            Request::Arm => 1,
            Request::Disarm => 2,
            Request::ClearFault => 4,
        }
    }
}

impl Shared {
    pub const fn new() -> Self {
        Self {
            coeff_gen: AtomicU32::new(0),
            coeff: [CoeffSlot::new(), CoeffSlot::new()],
            index_seq: AtomicU32::new(0),
            index: [
                [AtomicU32::new(0), AtomicU32::new(0), AtomicU32::new(0)],
                [AtomicU32::new(0), AtomicU32::new(0), AtomicU32::new(0)],
            ],
            x_faults: AtomicU32::new(0),
            x_accepted: AtomicU32::new(0),
            x_ignored: AtomicU32::new(0),
            requests: AtomicU32::new(0),
        }
    }
    /// Posts an operator request for the next loop tick (any priority,
    /// lock-free).
    pub fn request(&self, r: Request) {
        self.requests.fetch_or(r.bit(), Ordering::Release);
    }
    /// Legacy X events accepted (an update published) so far.
    pub fn x_accepted(&self) -> u32 {
        self.x_accepted.load(Ordering::Relaxed)
    }
    /// Legacy X events debounced (same half-mil state) so far.
    pub fn x_ignored(&self) -> u32 {
        self.x_ignored.load(Ordering::Relaxed)
    }
    /// Index events received so far.
    pub fn index_events(&self) -> u32 {
        self.index_seq.load(Ordering::Relaxed)
    }
    /// Coefficient sets published so far.
    pub fn coefficient_generation(&self) -> u32 {
        self.coeff_gen.load(Ordering::Relaxed)
    }
    /// The once-per-revolution index, published for the loop tick: the
    /// encoder count at the edge (ignored with a tachometer) and the edge's
    /// timestamp. Needs no handler state, so an index interrupt can call it
    /// on a `static` [`Shared`] directly. One writer (one priority level).
    #[inline(always)]
    pub fn index_event(&self, edge_ticks: u32, count_at_index: u32) {
        let s = self.index_seq.load(Ordering::Relaxed).wrapping_add(1);
        let slot = &self.index[(s & 1) as usize];
        slot[2].store(s, Ordering::Relaxed);
        fence(Ordering::Release);
        slot[0].store(count_at_index, Ordering::Relaxed);
        slot[1].store(edge_ticks, Ordering::Relaxed);
        self.index_seq.store(s, Ordering::Release);
    }
    fn raise(&self, f: Fault) {
        self.x_faults.fetch_or(x_fault_bit(f), Ordering::Relaxed);
    }
}

impl Default for Shared {
    fn default() -> Self {
        Self::new()
    }
}

// ---------------------------------------------------------------------------
// Table load.

/// Largest positive command the load check lets pass: 1 µin (Q30). The
/// series is truncated and quantised, so the command's maximum over φ sits
/// a fraction of a µin around 0; a table for a wrong sign convention or a
/// different surface is off by thousands of µin.
const SIGN_TOLERANCE_Q30: i32 = 1074;
/// Angles per node of the load check (every 22.5°, both eq 2-11 maxima
/// bracketed).
const SIGN_ANGLES: u32 = 16;

/// Parses `bytes` and checks the command's sign at every node inside the
/// table's command range and 16 angles: Z ≤ 0 (within 1 µin,
/// the truncation and quantisation slack). Runs once, at construction.
pub fn load_table(bytes: &'static [u8]) -> Result<CommandGen<'static>, TableError> {
    let table = CoeffTable::parse(bytes)?;
    let gen = CommandGen::new(table);
    for n in 0..table.node_count() {
        let x = table.node_x(n);
        if x > gen.x_null() {
            break;
        }
        let c = gen.coefficients(x).map_err(|_| TableError::SignCheck)?;
        for k in 0..SIGN_ANGLES {
            let phi = SpindleAngle(k.wrapping_mul(u32::MAX / SIGN_ANGLES + 1));
            if gen.evaluate_phi(&c, phi).z.to_bits() > SIGN_TOLERANCE_Q30 {
                return Err(TableError::SignCheck);
            }
        }
    }
    Ok(gen)
}

// ---------------------------------------------------------------------------
// The X / index handlers' part.

/// Per-interval cache of the X handler: the two node rows of the grid
/// interval X is in, fetched once per interval, so each event costs one
/// multiply-add per column and no division.
#[derive(Clone, Debug)]
struct IntervalCache {
    interval: Option<u32>,
    lo: [i32; COLS],
    /// `hi − lo` of the raw (Q30) node values.
    d: [i32; COLS],
    /// X of the interval's nodes, `I8F24` bits (`x_lo ≤ X < x_hi`).
    x_lo: i32,
    x_hi: i32,
    /// Node 0 and the grid step, `I8F24` bits.
    x0: i32,
    dx: i32,
}

/// State of the X and index handlers (one priority level below the tick).
#[derive(Clone, Debug)]
pub struct EventState {
    gen: Option<CommandGen<'static>>,
    legacy: Option<LegacyX>,
    coefficient_output: bool,
    out: LegacyOutput,
    cache: IntervalCache,
    /// Q30 tables with every |coefficient| ≤ COEFF_LIMIT/2 (all real ones:
    /// no clamp in `coefficients_into`, node changes fit an i32) take the
    /// cached path; others the command path's general one.
    fast: bool,
    terms: u8,
    /// The interval whose changes each slot's `delta` holds.
    slot_interval: [Option<u32>; 2],
    coeff_gen: u32,
}

impl EventState {
    fn new(gen: Option<CommandGen<'static>>, cfg: &FirmwareConfig) -> Self {
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
            coefficient_output: cfg.coefficient_output,
            out: LegacyOutput::new(),
            cache: IntervalCache::new(gen.as_ref()),
            fast,
            terms,
            slot_interval: [None; 2],
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
                // One writer: a load and a store, no read-modify-write loop.
                let n = sh.x_ignored.load(Ordering::Relaxed);
                sh.x_ignored.store(n.wrapping_add(1), Ordering::Relaxed);
                return Ok(XEvent::Ignored);
            }
            Err(f) => {
                sh.raise(f);
                return Err(f);
            }
        };
        let n = sh.x_accepted.load(Ordering::Relaxed);
        sh.x_accepted.store(n.wrapping_add(1), Ordering::Relaxed);
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

    /// Computes every column at `x` into the free slot and publishes it.
    #[inline(always)]
    fn publish(&mut self, sh: &Shared, x: XInches, null: bool) -> Result<(), Fault> {
        let g_next = self.coeff_gen.wrapping_add(1);
        let which = (g_next & 1) as usize;
        let slot = &sh.coeff[which];
        slot.seq.store(g_next, Ordering::Relaxed);
        fence(Ordering::Release);
        slot.x.store(x.to_bits(), Ordering::Relaxed);
        let terms = usize::from(self.terms);
        let (cache, held) = (&mut self.cache, &mut self.slot_interval);
        let live = match self.gen.as_ref() {
            Some(g) if !null => {
                if self.fast {
                    fast_columns(g, cache, held, terms, slot, which, x)?
                } else {
                    general_columns(g, held, terms, slot, which, x)?
                }
            }
            _ => false,
        };
        let meta = if live {
            u32::from(self.terms)
        } else {
            NULL_META
        };
        slot.meta.store(meta, Ordering::Relaxed);
        self.coeff_gen = g_next;
        sh.coeff_gen.store(g_next, Ordering::Release);
        Ok(())
    }
}

/// The columns at `x` through the command path itself (tables the cached
/// path does not cover).
fn general_columns(
    g: &CommandGen<'static>,
    held: &mut [Option<u32>; 2],
    terms: usize,
    slot: &CoeffSlot,
    which: usize,
    x: XInches,
) -> Result<bool, Fault> {
    let mut c = Coefficients::NULL;
    g.coefficients_into(x, &mut c)?;
    if c.null {
        return Ok(false);
    }
    let dst = slot.value.iter().zip(slot.delta.iter());
    let src = c.value.iter().zip(c.delta.iter());
    for ((v, dv), (a, b)) in dst.zip(src).take(terms) {
        v.store(*a, Ordering::Relaxed);
        dv.store(*b, Ordering::Relaxed);
    }
    if let Some(s) = held.get_mut(which) {
        *s = None;
    }
    Ok(true)
}

/// Whether `gen`'s table takes the cached path: Q30 with every
/// |coefficient| ≤ COEFF_LIMIT/2 (all real ones: no clamp in
/// `coefficients_into`, node changes fit an i32) and a grid in X bits; and
/// its live column count.
fn fast_and_terms(gen: Option<&CommandGen<'static>>) -> (bool, u8) {
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
enum Seek {
    /// Beyond the table's command range: the null command.
    Null,
    /// On the last node: the command path's own way.
    General,
    /// Inside the cached interval, Q31 position in it.
    In(i32),
}

impl IntervalCache {
    fn new(gen: Option<&CommandGen<'static>>) -> Self {
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

    /// The coefficients at `x` into `c`, bit for bit what
    /// [`CommandGen::coefficients_into`] gives (the modern X mode's
    /// re-interpolation in the loop tick: one multiply-add per column while
    /// X stays in the interval, one flash row more at a crossing).
    #[inline(always)]
    fn coefficients_into(
        &mut self,
        g: &CommandGen<'static>,
        n: usize,
        x: XInches,
        c: &mut Coefficients,
    ) -> Result<(), Fault> {
        let f = match self.seek(g, n, x)? {
            Seek::In(f) => f,
            Seek::Null | Seek::General => return g.coefficients_into(x, c),
        };
        let src = self.lo.iter().zip(self.d.iter());
        let dst = c.value.iter_mut().zip(c.delta.iter_mut());
        for ((v, dv), (lo, d)) in dst.zip(src).take(n) {
            *v = Self::lerp(*lo, *d, f);
            *dv = *d;
        }
        c.set_live(n as u8, x);
        Ok(())
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
    fn seek(&mut self, g: &CommandGen<'static>, n: usize, x: XInches) -> Result<Seek, Fault> {
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
    fn lerp(lo: i32, d: i32, f: i32) -> i32 {
        let step = (i64::from(d << 1) * i64::from(f) + (1 << 31)) >> 32;
        lo.wrapping_add(step as i32)
    }
}

/// The columns at `x` through the interval cache ([`IntervalCache::seek`]),
/// bit for bit what [`CommandGen::coefficients_into`] gives: per column one
/// 32×32 → 64 multiply-add; the interval changes written to a slot only
/// when that slot does not hold them yet.
#[inline(always)]
fn fast_columns(
    g: &CommandGen<'static>,
    c: &mut IntervalCache,
    held: &mut [Option<u32>; 2],
    n: usize,
    slot: &CoeffSlot,
    which: usize,
    x: XInches,
) -> Result<bool, Fault> {
    let f = match c.seek(g, n, x)? {
        Seek::Null => return Ok(false),
        Seek::General => return general_columns(g, held, n, slot, which, x),
        Seek::In(f) => f,
    };
    let cols = c.lo.iter().zip(c.d.iter());
    for ((lo, d), v) in cols.zip(slot.value.iter()).take(n) {
        v.store(IntervalCache::lerp(*lo, *d, f), Ordering::Relaxed);
    }
    if let Some(s) = held.get_mut(which) {
        if *s != c.interval {
            for (d, dv) in c.d.iter().zip(slot.delta.iter()).take(n) {
                dv.store(*d, Ordering::Relaxed);
            }
            *s = c.interval;
        }
    }
    Ok(true)
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

// ---------------------------------------------------------------------------
// The loop tick's part.

#[derive(Clone, Debug)]
enum Estimator {
    None,
    Encoder(EncoderAngle),
    Tach(TachAngle),
}

#[derive(Clone, Debug)]
// The large variant is the only one a modern-X firmware uses (no heap to
// box it in; the enum lives once, in the loop-tick state). Keeping the
// cache here measured cheaper on the M4 than a separate field, and so did
// copying the slopes every time over testing whether they changed.
#[allow(clippy::large_enum_variant)]
enum LoopX {
    /// Coefficients arrive from the X handler.
    Published,
    /// Modern X: re-interpolated in the tick, through the interval cache
    /// when the table takes the fast path (`Some`).
    Count(CountX, Option<IntervalCache>),
    None,
}

/// Gauge codes per tick (Q16) from ∂Z/∂φ (Q30 in/rad) × Δφ (binary angle):
/// `v = p · 2π · 25 · 2²¹ / 2⁶² · 2¹⁶ = p · K / 2²⁵`, K = 50π, here Q16.
const FF_K_Q16: i64 = 10_294_371;
/// 100π² in Q8: codes/tick² from ∂²Z/∂φ² (Q30 in/rad²) × Δφ² (binary angle):
/// `a = d2 · Δφ² · (2π/2³²)² · 25·2²¹ / 2³⁰`, here as `d2·Δφ²·100π²/2⁷³`.
const FF_K2_Q8: i64 = 252_662;

/// State of the loop-tick handler (highest priority).
#[derive(Clone, Debug)]
pub struct LoopState {
    gen: Option<CommandGen<'static>>,
    spindle: Estimator,
    x: LoopX,
    gauge_reversed: bool,
    coeffs: Coefficients,
    coeff_seen: u32,
    index_seen: u32,
    x_faults_seen: u32,
    last_x_count: Option<u32>,
    last_phi: Option<SpindleAngle>,
    /// X of the last coefficient set (learning freezes when it jumps).
    last_coeff_x: Option<XInches>,
    /// Offset added to the table command, gauge codes.
    target: i32,
    /// The offset on the last tick.
    last_target: i32,
    /// Table command of the last tick, gauge codes.
    table_code: i32,
    /// Velocity input of the last tick (∂Z/∂φ·Δφ), codes/tick Q16.
    ff_q16: i64,
    /// Acceleration input of the last tick, codes/tick², Q16.
    accel_q16: i64,
    servo: Servo,
    /// Gauge code of the last good sample (+Z).
    position: i32,
    /// Whether the last gauge sample was bad (range, rail, bus).
    gauge_bad: bool,
    ticks: u32,
    output: i32,
    fault: Option<Fault>,
    /// The last clear request was refused (the cause was still present).
    clear_refused: Option<Fault>,
    dac_clamped: bool,
    /// The DAC holds code 0 (disarmed).
    dac_zeroed: bool,
}

/// |ΔX| between two coefficient sets beyond which the learned table no
/// longer belongs to the radius: 0.01 in (the feed moves 100 µin per
/// revolution; a jump this size is a restart elsewhere or a bad count).
const X_JUMP_BITS: i32 = (0.01 * (1u64 << 24) as f64) as i32;

impl LoopState {
    fn new(cfg: ServoConfig) -> Self {
        Self {
            gen: None,
            spindle: Estimator::None,
            x: LoopX::None,
            gauge_reversed: false,
            coeffs: Coefficients::NULL,
            coeff_seen: 0,
            index_seen: 0,
            x_faults_seen: 0,
            last_x_count: None,
            last_phi: None,
            last_coeff_x: None,
            target: 0,
            last_target: 0,
            table_code: 0,
            ff_q16: 0,
            accel_q16: 0,
            servo: Servo::new(cfg),
            position: 0,
            gauge_bad: false,
            ticks: 0,
            output: 0,
            fault: None,
            clear_refused: None,
            dac_clamped: false,
            dac_zeroed: false,
        }
    }

    /// Latches `fault` unless a fault with an equally or more severe reaction
    /// is already latched (the first cause stays readable).
    pub fn trip(&mut self, fault: Fault) {
        match self.fault {
            Some(f) if f.reaction() >= fault.reaction() => {}
            _ => self.fault = Some(fault),
        }
    }

    /// Sets an offset added to the table command (with no table: where the
    /// slide should go); the command ramps there at the slew limit. Clamped
    /// to the gauge range.
    pub fn set_target_code(&mut self, code: i32) {
        self.target = code.clamp(CODE_MIN, CODE_MAX);
    }

    /// Picks up what the X / index handlers published.
    #[inline(always)]
    fn take_published(&mut self, sh: &Shared) {
        let xf = sh.x_faults.load(Ordering::Relaxed);
        if xf != self.x_faults_seen {
            let new = xf & !self.x_faults_seen;
            self.x_faults_seen = xf;
            for (bit, f) in X_FAULTS {
                if new & bit != 0 {
                    self.trip(f);
                }
            }
        }
        let s = sh.index_seq.load(Ordering::Acquire);
        if s != self.index_seen {
            let missed = s.wrapping_sub(self.index_seen) > 1;
            let slot = &sh.index[(s & 1) as usize];
            let count = slot[0].load(Ordering::Relaxed);
            let edge = slot[1].load(Ordering::Relaxed);
            fence(Ordering::Acquire);
            if slot[2].load(Ordering::Relaxed) != s {
                // Overwritten while read (a writer that can preempt the
                // tick): the pulses came faster than the loop rate.
                self.index_seen = s;
                self.trip(Fault::IndexExtra);
                return;
            }
            self.index_seen = s;
            if missed {
                // Two index pulses within one loop period: noise.
                self.trip(Fault::IndexExtra);
            }
            let r = match &mut self.spindle {
                Estimator::Encoder(e) => e.on_index(count, edge),
                Estimator::Tach(t) => t.on_index(edge),
                Estimator::None => Ok(()),
            };
            if let Err(f) = r {
                self.trip(f);
            }
        }
        if matches!(self.x, LoopX::Published) {
            let g = sh.coeff_gen.load(Ordering::Acquire);
            if g != self.coeff_seen {
                let slot = &sh.coeff[(g & 1) as usize];
                let meta = slot.meta.load(Ordering::Relaxed);
                let x = XInches::from_bits(slot.x.load(Ordering::Relaxed));
                if meta & NULL_META != 0 {
                    self.coeffs.set_null(x);
                } else {
                    let n = (meta as usize).min(COLS);
                    let src = slot.value.iter().zip(slot.delta.iter());
                    let dst = self
                        .coeffs
                        .value
                        .iter_mut()
                        .zip(self.coeffs.delta.iter_mut());
                    for ((v, d), (sv, sd)) in dst.zip(src).take(n) {
                        *v = sv.load(Ordering::Relaxed);
                        *d = sd.load(Ordering::Relaxed);
                    }
                    self.coeffs.set_live(n as u8, x);
                }
                self.note_x(x);
                fence(Ordering::Acquire);
                // Overwritten while copying (only possible if the writer can
                // preempt the tick): drop it, take the next one.
                if slot.seq.load(Ordering::Relaxed) == g {
                    self.coeff_seen = g;
                } else {
                    self.coeffs.set_null(x);
                }
            }
        }
    }

    /// The loop-tick interrupt: gauge and spindle sample in, one DAC code out.
    ///
    /// Never inlined, so that `cargo xtask isr-cost` finds it in the image
    /// and counts its instructions apart from the board's glue.
    #[inline(never)]
    pub fn loop_tick(
        &mut self,
        sh: &Shared,
        input: &TickInput,
        gauge: &mut impl GaugeAdc,
        dac: &mut impl AmplifierDac,
    ) {
        self.ticks = self.ticks.wrapping_add(1);
        self.take_published(sh);
        // The gauge is read even with the amplifier off: a clear request
        // needs to see whether a gauge fault's cause is gone.
        let read = gauge.read();
        let gauge_fault = match read {
            Err(_) => Some(Fault::Bus(Device::GaugeAdc)),
            Ok(s) if s.overrange => Some(Fault::GaugeRange),
            // A reading on a rail without OV: the gauge's own output is
            // pinned, so the loop cannot see where the slide is beyond it.
            Ok(s) if s.code <= CODE_MIN || s.code >= CODE_MAX => Some(Fault::GaugeSaturated),
            Ok(_) => None,
        };
        self.gauge_bad = gauge_fault.is_some();
        self.take_requests(sh, input.amplifier_fault);
        let sample = match (read, gauge_fault) {
            (Ok(s), None) => s,
            (_, f) => {
                self.trip(f.unwrap_or(Fault::Bus(Device::GaugeAdc)));
                self.hold_safe(dac);
                return;
            }
        };
        if self.amplifier_must_be_off() {
            self.hold_safe(dac);
            return;
        }
        let code = if self.gauge_reversed {
            sample.code.saturating_neg()
        } else {
            sample.code
        };
        let y = code.clamp(CODE_MIN, CODE_MAX);
        self.position = y;

        // Spindle angle.
        let est = match (&mut self.spindle, input.spindle) {
            (Estimator::Encoder(e), SpindleReading::Encoder(s)) => {
                let est = e.tick(s.count, s.edge_ticks, input.now);
                e.referenced().then_some(est)
            }
            (Estimator::Tach(t), SpindleReading::Tach(mv)) => {
                let est = t.tick(mv, input.now);
                t.referenced().then_some(est)
            }
            _ => None,
        };
        let phi = match est {
            Some(e) => {
                if let Some(f) = e.fault {
                    self.trip(f);
                }
                Some(e.angle)
            }
            None => None,
        };

        // Modern X: re-interpolate when the count moved.
        if let LoopX::Count(cx, cache) = &mut self.x {
            if self.last_x_count != Some(input.x_count) {
                self.last_x_count = Some(input.x_count);
                let moved = cx.on_tick(input.x_count);
                let r = match (moved, self.gen.as_ref(), cache) {
                    (Ok(x), Some(g), Some(c)) => {
                        let n = usize::from(g.interpolator().table().header().terms);
                        c.coefficients_into(g, n.min(COLS), x, &mut self.coeffs)
                    }
                    (Ok(x), Some(g), None) => g.coefficients_into(x, &mut self.coeffs),
                    (Err(f), _, _) => Err(f),
                    (Ok(_), None, _) => Ok(()),
                };
                if let Err(f) = r {
                    self.trip(f);
                }
                if let Ok(x) = moved {
                    self.note_x(x);
                }
            }
        }

        // The command and its slope.
        let (table_code, slope, accel) = match (self.gen.as_ref(), phi) {
            (Some(g), Some(phi)) if self.fault.is_none() => {
                let c = g.evaluate_phi(&self.coeffs, phi);
                let dphi = match self.last_phi {
                    Some(p) => phi.0.wrapping_sub(p.0) as i32,
                    None => 0,
                };
                // Bounds that make every product below plain 64-bit
                // arithmetic (no saturating multiplies on the M4): |Δφ| ≤
                // 2²⁶ (1/64 turn per tick, 18 750 rpm at 20 kHz), |∂Z/∂φ| ≤
                // 2²⁷ (1/8 in/rad), |∂²Z/∂φ²| ≤ 2²⁸: far beyond any real cut.
                let dphi64 = i64::from(dphi.clamp(-(1 << 26), 1 << 26));
                let d1 = i64::from(c.dz_dphi.to_bits().clamp(-(1 << 27), 1 << 27));
                let d2 = i64::from(c.d2z_dphi2.to_bits().clamp(-(1 << 28), 1 << 28));
                // |p >> 16| ≤ 2³⁷, times K < 2²⁴.
                let v = (((d1 * dphi64) >> 16) * FF_K_Q16) >> 25;
                // ∂²Z/∂φ²·Δφ² in codes/tick², Q16: d2·Δφ²·100π²/2⁵⁷, in two
                // steps (≤ 2³⁰ and ≤ 2³² before the constant).
                let t = (((d2 * dphi64) >> 24) * dphi64) >> 24;
                let a = ((t * FF_K2_Q8) >> 17).clamp(-(1 << 24), 1 << 24);
                (gauge_code_from_z(c.z), v, a)
            }
            _ => (0, 0, 0),
        };
        let dphi = match (self.last_phi, phi) {
            (Some(p), Some(q)) => q.0.wrapping_sub(p.0) as i32,
            _ => 0,
        };
        self.last_phi = phi;
        self.table_code = table_code;
        self.ff_q16 = slope;
        self.accel_q16 = accel;
        let faulted = self.fault.is_some();
        let reference = if faulted {
            // RampToNull: the loop stays closed and ramps to null.
            Reference::default()
        } else {
            // The target offset's own rate (a user signal, clean) joins the
            // table's analytic rate in the velocity feedforward when it is a
            // motion (a step is approached by the servo's slew profile).
            let step = i64::from(self.target) - i64::from(self.last_target);
            let slew_codes = self.servo.config().slew_q16 >> 16;
            let target_step = if step.abs() <= slew_codes { step } else { 0 };
            Reference {
                code: self
                    .target
                    .saturating_add(table_code)
                    .clamp(CODE_MIN, CODE_MAX),
                velocity_q16: slope + (target_step << 16),
                accel_q16: accel,
            }
        };
        self.last_target = self.target;
        let out = self.servo.update(&ServoInput {
            gauge_code: y,
            reference,
            angle: phi.map(|p| (p, dphi)),
            freeze: if faulted {
                Some(Freeze::Fault)
            } else if self.coeffs.null || self.gen.is_none() {
                Some(Freeze::Null)
            } else {
                None
            },
            amplifier_tripped: input.amplifier_fault,
        });
        if let Some(f) = out.fault {
            self.trip(f);
            if self.amplifier_must_be_off() {
                self.hold_safe(dac);
                return;
            }
        }
        if !out.enable {
            // Disarmed: DAC at zero volts (written once), enable low.
            if !self.dac_zeroed {
                match dac.write(0) {
                    Ok(()) => self.dac_zeroed = true,
                    Err(_) => {
                        self.trip(Fault::Bus(Device::AmplifierDac));
                        self.hold_safe(dac);
                    }
                }
            }
            self.output = 0;
            return;
        }
        self.dac_zeroed = false;
        match dac.write(out.dac_code) {
            Ok(()) => self.output = out.dac_code,
            Err(_) => {
                self.trip(Fault::Bus(Device::AmplifierDac));
                self.hold_safe(dac);
            }
        }
    }

    /// Remembers the X of a new coefficient set; a jump freezes learning
    /// for a second (the table belongs to another radius).
    #[inline(always)]
    fn note_x(&mut self, x: XInches) {
        if let Some(p) = self.last_coeff_x {
            let d = x.0.to_bits().wrapping_sub(p.0.to_bits());
            if !(-X_JUMP_BITS..=X_JUMP_BITS).contains(&d) {
                let hold = self.servo.config().rate_hz;
                self.servo.freeze_learning(Freeze::XJump, hold);
            }
        }
        self.last_coeff_x = Some(x);
    }

    /// Operator requests posted in [`Shared`].
    #[inline(always)]
    fn take_requests(&mut self, sh: &Shared, amplifier_fault: bool) {
        if sh.requests.load(Ordering::Relaxed) == 0 {
            return;
        }
        let r = sh.requests.swap(0, Ordering::Acquire);
        if r & Request::Disarm.bit() != 0 {
            self.servo.disarm();
        }
        if r & Request::ClearFault.bit() != 0 {
            self.clear_fault(amplifier_fault);
        }
        // Arming with a ramp-to-null fault latched is allowed: the loop then
        // holds the slide at null (a refused table, a lost X).
        if r & Request::Arm.bit() != 0
            && r & Request::Disarm.bit() == 0
            && !self.amplifier_must_be_off()
        {
            self.servo.arm();
        }
    }

    /// Clears the latched fault when the loop is disarmed and the cause is
    /// no longer seen; otherwise records the refusal.
    fn clear_fault(&mut self, amplifier_fault: bool) {
        let Some(f) = self.fault else {
            return;
        };
        let present = self.servo.phase() != Phase::Disarmed
            || match f {
                Fault::GaugeRange | Fault::GaugeSaturated | Fault::Bus(Device::GaugeAdc) => {
                    self.gauge_bad
                }
                Fault::AmplifierTrip => amplifier_fault,
                // A refused table stays refused: only a new table clears it.
                Fault::Table(_) => true,
                _ => false,
            };
        if present {
            self.clear_refused = Some(f);
        } else {
            self.fault = None;
            self.clear_refused = None;
            self.dac_clamped = false;
        }
    }

    fn amplifier_must_be_off(&self) -> bool {
        matches!(self.fault, Some(f) if f.reaction() == Reaction::DisableAmplifier)
    }

    fn hold_safe(&mut self, dac: &mut impl AmplifierDac) {
        self.output = 0;
        self.servo.stop();
        self.dac_zeroed = false;
        if !self.dac_clamped && dac.clamp_to_ground().is_ok() {
            self.dac_clamped = true;
        }
    }

    /// Whether the board may drive the amplifier-enable line high: the loop
    /// is armed (never on its own: only after [`Request::Arm`]) and no
    /// fault demands it off.
    pub fn amplifier_enable(&self) -> bool {
        self.servo.phase() != Phase::Disarmed && !self.amplifier_must_be_off()
    }
    /// The servo (engagement phase, estimate, learning, configuration).
    pub fn servo(&self) -> &Servo {
        &self.servo
    }
    /// The fault a clear request could not clear (its cause was present or
    /// the loop armed), until the next successful clear.
    pub fn clear_refused(&self) -> Option<Fault> {
        self.clear_refused
    }
    /// Loop ticks run so far (wrapping), faulted ticks included.
    pub fn ticks(&self) -> u32 {
        self.ticks
    }
    /// The latched fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }
    /// The command the loop followed on the last tick, gauge codes.
    pub fn command_code(&self) -> i32 {
        self.servo.command_code()
    }
    /// The table's Z command of the last tick, gauge codes (0 when null).
    pub fn table_code(&self) -> i32 {
        self.table_code
    }
    /// The offset (no table: the target) the command ramps to, gauge codes.
    pub fn target_code(&self) -> i32 {
        self.target
    }
    /// The gauge code of the last good sample (Z sense).
    pub fn position_code(&self) -> i32 {
        self.position
    }
    /// The DAC code written on the last tick (0 when held safe).
    pub fn output_code(&self) -> i32 {
        self.output
    }
    /// Velocity feedforward input of the last tick, gauge codes per tick, Q16.
    pub fn feedforward_q16(&self) -> i64 {
        self.ff_q16
    }
    /// Acceleration feedforward input of the last tick (∂²Z/∂φ²·Δφ²),
    /// gauge codes per tick², Q16.
    pub fn accel_q16(&self) -> i64 {
        self.accel_q16
    }
    /// Whether the DAC has acknowledged its clamp to ground.
    pub fn dac_clamped(&self) -> bool {
        self.dac_clamped
    }
    /// The coefficients the loop tick evaluates.
    pub fn coefficients(&self) -> &Coefficients {
        &self.coeffs
    }
    pub fn config(&self) -> &ServoConfig {
        self.servo.config()
    }
}

// ---------------------------------------------------------------------------
// The bundle.

/// The whole firmware: the loop tick's part, the X/index handlers' part and
/// the data they share (see the module docs). Single-threaded users call
/// its entry points; boards split it with [`Firmware::into_parts`].
pub struct Firmware {
    lp: LoopState,
    ev: EventState,
    shared: Shared,
}

impl Firmware {
    /// A loop without a table (holds [`Firmware::set_target_code`]): the bench.
    pub fn new(cfg: ServoConfig) -> Self {
        let fc = FirmwareConfig {
            loop_cfg: cfg,
            spindle: SpindleMode::None,
            x: XMode::None,
            coefficient_output: false,
            gauge_reversed: false,
        };
        Self {
            lp: LoopState::new(cfg),
            ev: EventState::new(None, &fc),
            shared: Shared::new(),
        }
    }

    /// The integrated firmware from a table image. A table the parser
    /// refuses or that fails the sign check ([`load_table`]) gives a
    /// firmware latched in [`Fault::Table`] with a null command (never a
    /// panic); a configuration the estimators refuse is a [`ConfigError`].
    pub fn with_table(table: &'static [u8], cfg: FirmwareConfig) -> Result<Self, ConfigError> {
        let loaded = load_table(table);
        let gen = loaded.ok();
        let mut lp = LoopState::new(cfg.loop_cfg);
        lp.gen = gen;
        lp.gauge_reversed = cfg.gauge_reversed;
        lp.spindle = match cfg.spindle {
            SpindleMode::None => Estimator::None,
            SpindleMode::Encoder(c) => {
                Estimator::Encoder(EncoderAngle::new(c).ok_or(ConfigError::Spindle)?)
            }
            SpindleMode::Tach(c) => Estimator::Tach(TachAngle::new(c).ok_or(ConfigError::Spindle)?),
        };
        lp.x = match cfg.x {
            XMode::None => LoopX::None,
            XMode::Legacy { .. } => LoopX::Published,
            XMode::Count(c) => {
                let cx = CountX::new(c).ok_or(ConfigError::Count)?;
                let fast = fast_and_terms(gen.as_ref()).0;
                LoopX::Count(cx, fast.then(|| IntervalCache::new(gen.as_ref())))
            }
        };
        if let Err(e) = loaded {
            lp.trip(Fault::Table(e));
        }
        Ok(Self {
            ev: EventState::new(gen, &cfg),
            lp,
            shared: Shared::new(),
        })
    }

    /// The handlers' parts, for boards that give each interrupt its own and
    /// share a `static` [`Shared`] (this bundle's own is dropped: nothing has
    /// been published into it that the parts would need, as long as no entry
    /// point ran before the split).
    pub fn into_parts(self) -> (LoopState, EventState) {
        (self.lp, self.ev)
    }

    /// See [`LoopState::loop_tick`].
    pub fn loop_tick(
        &mut self,
        input: &TickInput,
        gauge: &mut impl GaugeAdc,
        dac: &mut impl AmplifierDac,
    ) {
        self.lp.loop_tick(&self.shared, input, gauge, dac);
    }
    /// See [`EventState::x_event`].
    pub fn x_event(
        &mut self,
        word: XLatchWord,
        now: u32,
        quad: &mut impl CoefficientDac,
    ) -> Result<XEvent, Fault> {
        self.ev.x_event(&self.shared, word, now, quad)
    }
    /// See [`EventState::index_event`].
    pub fn index_event(&mut self, edge_ticks: u32, count_at_index: u32) {
        self.ev
            .index_event(&self.shared, edge_ticks, count_at_index);
    }

    pub fn shared(&self) -> &Shared {
        &self.shared
    }
    pub fn loop_state(&self) -> &LoopState {
        &self.lp
    }
    /// The command generator of the loaded table (`None`: no table or refused).
    pub fn command_gen(&self) -> Option<&CommandGen<'static>> {
        self.lp.gen.as_ref()
    }
    pub fn trip(&mut self, fault: Fault) {
        self.lp.trip(fault);
    }
    pub fn set_target_code(&mut self, code: i32) {
        self.lp.set_target_code(code);
    }
    /// [`Self::set_target_code`] for a Z position (gauge sign: +volts = +Z).
    pub fn set_target(&mut self, z: ZInches) {
        self.lp.set_target_code(gauge_code_from_z(z));
    }
    pub fn amplifier_enable(&self) -> bool {
        self.lp.amplifier_enable()
    }
    pub fn ticks(&self) -> u32 {
        self.lp.ticks()
    }
    pub fn fault(&self) -> Option<Fault> {
        self.lp.fault()
    }
    pub fn command_code(&self) -> i32 {
        self.lp.command_code()
    }
    pub fn table_code(&self) -> i32 {
        self.lp.table_code()
    }
    pub fn target_code(&self) -> i32 {
        self.lp.target_code()
    }
    pub fn position_code(&self) -> i32 {
        self.lp.position_code()
    }
    pub fn output_code(&self) -> i32 {
        self.lp.output_code()
    }
    pub fn dac_clamped(&self) -> bool {
        self.lp.dac_clamped()
    }
    pub fn config(&self) -> &ServoConfig {
        self.lp.config()
    }
    /// Posts an operator request (see [`Request`]).
    pub fn request(&mut self, r: Request) {
        self.shared.request(r);
    }
    pub fn servo(&self) -> &Servo {
        self.lp.servo()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;

    use super::*;
    use crate::hw::{BusError, GaugeSample};
    use std::vec::Vec;

    /// A gauge whose next reading the test sets.
    struct Gauge(Result<GaugeSample, BusError>);
    impl Gauge {
        fn at(code: i32) -> Self {
            Self(Ok(GaugeSample {
                code,
                overrange: false,
            }))
        }
        fn set(&mut self, code: i32) {
            self.0 = Ok(GaugeSample {
                code,
                overrange: false,
            });
        }
    }
    impl GaugeAdc for Gauge {
        fn read(&mut self) -> Result<GaugeSample, BusError> {
            self.0
        }
    }

    #[derive(Default)]
    struct Dac {
        writes: Vec<i32>,
        clamps: u32,
        fail_writes: bool,
        fail_clamps: u32,
    }
    impl AmplifierDac for Dac {
        fn write(&mut self, code: i32) -> Result<(), BusError> {
            if self.fail_writes {
                return Err(BusError);
            }
            self.writes.push(code);
            Ok(())
        }
        fn clamp_to_ground(&mut self) -> Result<(), BusError> {
            self.clamps += 1;
            if self.fail_clamps > 0 {
                self.fail_clamps -= 1;
                return Err(BusError);
            }
            Ok(())
        }
    }

    #[test]
    fn gauge_scale_is_one_volt_per_mil_over_20_bits() {
        // Brief: code = round(V · 2¹⁹ / 10 V), 1 V per mil.
        assert_eq!(gauge_code_from_z(ZInches::from_f64(0.005)), 1 << 18);
        assert_eq!(gauge_code_from_z(ZInches::from_f64(-0.010)), CODE_MIN);
        assert_eq!(gauge_code_from_z(ZInches::from_f64(0.010)), CODE_MAX);
        assert_eq!(gauge_code_from_z(ZInches::from_f64(0.5)), CODE_MAX);
        // 1 µin = 52.4288 codes.
        assert_eq!(gauge_code_from_z(ZInches::from_f64(1e-6)), 52);
        assert_eq!(gauge_code_from_z(ZInches::from_f64(-1e-6)), -52);
    }

    #[test]
    fn gauge_bus_error_latches_and_clamps_dac() {
        let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        g.0 = Err(BusError);
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::Bus(Device::GaugeAdc)));
        assert!(!fw.amplifier_enable());
        assert_eq!(d.clamps, 1);
        // The gauge recovers; the latch holds and the DAC stays untouched.
        g.set(5);
        for _ in 0..5 {
            fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        }
        assert_eq!(d.writes.len(), 1);
        assert_eq!(d.clamps, 1);
        assert_eq!(fw.fault(), Some(Fault::Bus(Device::GaugeAdc)));
        assert_eq!(fw.ticks(), 7);
    }

    #[test]
    fn dac_bus_error_latches_and_retries_clamp_until_accepted() {
        let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        d.fail_writes = true;
        d.fail_clamps = 2;
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::Bus(Device::AmplifierDac)));
        assert!(!fw.dac_clamped());
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert!(fw.dac_clamped());
        assert_eq!(d.clamps, 3);
    }

    #[test]
    fn gauge_pinned_at_either_rail_is_saturated_and_disables_amplifier() {
        // The AD4020's extreme codes, ±10 V (±0.010 in), without OV.
        for code in [(1 << 19) - 1, -(1 << 19)] {
            let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
            let mut g = Gauge(Ok(GaugeSample {
                code,
                overrange: false,
            }));
            let mut d = Dac::default();
            fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
            assert_eq!(fw.fault(), Some(Fault::GaugeSaturated));
            assert!(d.writes.is_empty());
            assert_eq!(d.clamps, 1);
            assert!(!fw.amplifier_enable());
        }
        // One code inside the rail is a reading like any other.
        let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
        let mut g = Gauge(Ok(GaugeSample {
            code: (1 << 19) - 2,
            overrange: false,
        }));
        let mut d = Dac::default();
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert_eq!(fw.fault(), None);
    }

    #[test]
    fn overrange_gauge_disables_amplifier() {
        let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
        let mut g = Gauge(Ok(GaugeSample {
            code: CODE_MAX,
            overrange: true,
        }));
        let mut d = Dac::default();
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::GaugeRange));
        assert!(d.writes.is_empty());
        assert_eq!(d.clamps, 1);
    }

    /// The default loop without the commissioning sign check (the test
    /// gauges here do not move when the DAC does).
    fn no_check_cfg() -> ServoConfig {
        let mut d = crate::servo::ServoDesign::brief(20_000);
        d.sign_check_v = 0.0;
        d.config().unwrap()
    }

    fn armed_without_sign_check() -> Firmware {
        let mut fw = Firmware::new(no_check_cfg());
        fw.request(Request::Arm);
        fw
    }

    #[test]
    fn ramp_to_null_fault_keeps_loop_closed_and_nulls_command() {
        let mut fw = armed_without_sign_check();
        let (mut g, mut d) = (Gauge::at(1000), Dac::default());
        fw.set_target_code(1000);
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert_eq!(fw.command_code(), 1000);
        fw.trip(Fault::FollowingError);
        // Toward null at ≤ 2.6 codes/tick² (20 in/s²), never past it: a
        // 1000-code move takes 2·√(1000/2.6) ≈ 39 ticks.
        let mut prev = fw.command_code();
        let mut n = 0;
        while fw.command_code() != 0 {
            fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
            let c = fw.command_code();
            assert!(c <= prev && c >= 0, "{prev} -> {c}");
            prev = c;
            n += 1;
            assert!(n < 60, "too slow");
        }
        assert!(n > 30, "{n} ticks: the acceleration limit is not in force");
        assert!(fw.amplifier_enable());
        // A more severe fault replaces it; a milder one does not.
        fw.trip(Fault::Watchdog);
        fw.trip(Fault::XGlitchStorm);
        assert_eq!(fw.fault(), Some(Fault::Watchdog));
    }

    #[test]
    fn amplifier_stays_off_until_armed_and_engages_bumpless() {
        let mut fw = Firmware::new(ServoConfig::at_rate(20_000).unwrap());
        let (mut g, mut d) = (Gauge::at(-40_000), Dac::default());
        for _ in 0..1000 {
            fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        }
        assert!(!fw.amplifier_enable());
        assert!(d.writes.iter().all(|&c| c == 0));
        let mut fw = armed_without_sign_check();
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert!(fw.amplifier_enable());
        // The command starts where the slide is and sets off toward the
        // target (0) at the slew acceleration (20 in/s²: 2.6 codes/tick²).
        let c = fw.command_code();
        assert!((-40_000..=-39_997).contains(&c), "{c}");
    }

    #[test]
    fn a_fault_is_cleared_only_when_its_cause_is_gone_and_needs_a_new_arm() {
        let mut fw = armed_without_sign_check();
        let mut d = Dac::default();
        let mut g = Gauge(Ok(GaugeSample {
            code: 1000,
            overrange: true,
        }));
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::GaugeRange));
        fw.request(Request::ClearFault);
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::GaugeRange));
        assert_eq!(fw.loop_state().clear_refused(), Some(Fault::GaugeRange));
        g.set(1000);
        fw.request(Request::ClearFault);
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert_eq!(fw.fault(), None);
        assert!(!fw.amplifier_enable(), "clearing must not re-arm");
        fw.request(Request::Arm);
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert!(fw.amplifier_enable());
    }

    // -------------------------------------------------------------------
    // The integrated command path.

    use crate::command::LegacyFrame;
    use crate::table::TableHeader;
    use crate::xpos::{half_mils_to_x, latch_word, XUpdate};
    use crate::{DEFAULT_TABLE, LEGACY4_TABLE};
    use std::boxed::Box;

    /// Clock of the tests: 1 MHz; loop 20 kHz = 50 clock ticks.
    const CLOCK_HZ: u32 = 1_000_000;
    const TICK: u32 = 50;
    /// 4000 counts per rev at 300 rpm: exactly one count per loop tick.
    const CPR: u32 = 4000;

    fn leak(v: Vec<u8>) -> &'static [u8] {
        Box::leak(v.into_boxed_slice())
    }

    fn enc_cfg() -> EncoderConfig {
        EncoderConfig {
            counts_per_rev: CPR,
            ticks_per_s: CLOCK_HZ,
            min_rpm: 30,
            max_rpm: 3000,
            index_tolerance_counts: 4,
            index_angle: SpindleAngle(0),
        }
    }

    fn fw_cfg(x: XMode, coefficient_output: bool) -> FirmwareConfig {
        FirmwareConfig {
            loop_cfg: no_check_cfg(),
            spindle: SpindleMode::Encoder(enc_cfg()),
            x,
            coefficient_output,
            gauge_reversed: false,
        }
    }

    fn legacy(table: &'static [u8], output: bool) -> Firmware {
        Firmware::with_table(table, fw_cfg(XMode::Legacy { clock_hz: CLOCK_HZ }, output)).unwrap()
    }

    /// Encoder reading `n` counts after the start, its edge at this tick.
    fn enc(n: u32) -> TickInput {
        TickInput {
            now: n * TICK,
            spindle: SpindleReading::Encoder(EncoderSample {
                count: n,
                edge_ticks: n * TICK,
            }),
            x_count: 0,
            amplifier_fault: false,
        }
    }

    /// φ of count `n` after an index at count 0: n·2³²/CPR, rounded down.
    fn phi_of(n: u32) -> SpindleAngle {
        let q = (u64::from(n % CPR) << 32) / u64::from(CPR);
        SpindleAngle(q as u32)
    }

    /// A recording quad DAC.
    #[derive(Default)]
    struct Quad {
        frames: Vec<LegacyFrame>,
        fail: bool,
    }
    impl CoefficientDac for Quad {
        fn output(&mut self, codes: &[u16; 4], update: u8) -> Result<(), BusError> {
            if self.fail {
                return Err(BusError);
            }
            self.frames.push(LegacyFrame {
                codes: *codes,
                update,
            });
            Ok(())
        }
    }

    /// The default table with its header and payload rewritten.
    fn reencode(f: impl Fn(&mut TableHeader, &mut Vec<i32>)) -> &'static [u8] {
        let t = CoeffTable::parse(DEFAULT_TABLE).unwrap();
        let mut h = *t.header();
        let mut payload: Vec<i32> = (0..t.node_count())
            .flat_map(|n| (0..t.terms()).map(move |c| (n, c)))
            .map(|(n, c)| t.coeff_raw(n, c))
            .collect();
        f(&mut h, &mut payload);
        let mut out = std::vec![0u8; h.image_len()];
        h.encode(&payload, &mut out).unwrap();
        leak(out)
    }

    #[test]
    fn refused_table_faults_with_the_parsers_reason_and_nulls() {
        let mut images: Vec<&'static [u8]> = std::vec![&[], &DEFAULT_TABLE[..63]];
        for at in [0usize, 9, 17, 70, 3000, DEFAULT_TABLE.len() - 1] {
            let mut v = DEFAULT_TABLE.to_vec();
            v[at] ^= 0x5A;
            images.push(leak(v));
        }
        for img in images {
            let expected = CoeffTable::parse(img).unwrap_err();
            let mut fw = legacy(img, true);
            assert_eq!(fw.fault(), Some(Fault::Table(expected)));
            assert!(fw.command_gen().is_none());
            // The entry points still run; armed, the command ramps to null
            // with the loop closed (RampToNull), from wherever the slide is.
            let (mut g, mut d) = (Gauge::at(3000), Dac::default());
            fw.request(Request::Arm);
            fw.index_event(0, 0);
            let mut quad = Quad::default();
            for hm in 100..110 {
                let _ = fw.x_event(latch_word(hm), hm * 1000, &mut quad);
            }
            for n in 0..100 {
                fw.loop_tick(&enc(n), &mut g, &mut d);
            }
            assert_eq!(fw.command_code(), 0);
            assert!(fw.amplifier_enable());
            assert!(quad.frames.is_empty());
        }
    }

    #[test]
    fn sign_check_refuses_a_positive_command() {
        assert!(load_table(DEFAULT_TABLE).is_ok());
        assert!(load_table(LEGACY4_TABLE).is_ok());
        // The default table with every coefficient negated: a valid image
        // whose command is ≥ 0 (the wrong sign convention).
        let neg = reencode(|_, p| p.iter_mut().for_each(|v| *v = -*v));
        assert!(CoeffTable::parse(neg).is_ok());
        assert_eq!(load_table(neg).err(), Some(TableError::SignCheck));
        let fw = legacy(neg, false);
        assert_eq!(fw.fault(), Some(Fault::Table(TableError::SignCheck)));
        // A constant +2 µin offset in C00 (Z = 0 at X = 0 becomes +2 µin).
        let off = reencode(|h, p| {
            let t = usize::from(h.terms);
            p.iter_mut().step_by(t).for_each(|v| *v += 2148);
        });
        assert_eq!(load_table(off).err(), Some(TableError::SignCheck));
    }

    /// Every accepted X event hands the loop exactly the coefficients the
    /// command path computes at that X (interval cache, no division:
    /// bit-identical to `CommandGen::coefficients`), walking the whole table
    /// up into the null zone and back.
    #[test]
    fn x_event_publishes_the_command_paths_coefficients() {
        let mut fw = legacy(DEFAULT_TABLE, false);
        let gen = *fw.command_gen().unwrap();
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        let mut quad = NoCoefficientDac;
        let walk = (0..14_600u32).chain((14_000..14_599).rev());
        let mut now = 0u32;
        let mut accepted = 0;
        for hm in walk {
            now += 1000;
            let r = fw.x_event(latch_word(hm), now, &mut quad).unwrap();
            let XEvent::Update(u) = r else {
                panic!("event at {hm} ignored");
            };
            accepted += 1;
            assert_eq!(u.x, half_mils_to_x(hm));
            fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
            let got = fw.loop_state().coefficients();
            // The legacy null zone is the 8080's (X ≥ 7.2 in, xpos).
            assert_eq!(u.null, hm >= 14_400);
            assert_eq!(got.null, u.null, "hm {hm}");
            assert_eq!(got.x(), u.x);
            if !u.null {
                let want = gen.coefficients(u.x).unwrap();
                let n = usize::from(want.terms());
                assert_eq!(got.terms(), want.terms());
                assert_eq!(got.value[..n], want.value[..n], "hm {hm}");
                assert_eq!(got.delta[..n], want.delta[..n], "hm {hm}");
            }
        }
        assert_eq!(fw.shared().x_accepted(), accepted);
        assert_eq!(fw.shared().coefficient_generation(), accepted);
        assert_eq!(fw.fault(), None);
    }

    /// The loop tick's command is the command path's Z at the X of the last
    /// X event and the angle of the encoder count (closed form n·2³²/CPR
    /// after the index), and its feedforward is ∂Z/∂φ·Δφ (checked against a
    /// central difference of the command path's own Z).
    #[test]
    fn loop_tick_commands_z_at_the_encoder_angle_with_feedforward() {
        let mut fw = legacy(DEFAULT_TABLE, false);
        let gen = *fw.command_gen().unwrap();
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        let mut quad = NoCoefficientDac;
        let hm = 6_283; // 3.1415 in
        fw.x_event(latch_word(hm), 10, &mut quad).unwrap();
        // Before the index the angle is unknown: null command.
        fw.loop_tick(&enc(0), &mut g, &mut d);
        assert_eq!(fw.table_code(), 0);
        fw.index_event(0, 0);
        let x = half_mils_to_x(hm);
        let codes = |phi: SpindleAngle| f64::from(gen.z(x, phi).unwrap().to_bits()) * 25.0 / 512.0;
        let mut worst_ff = 0f64;
        let mut largest_ff = 0f64;
        let (mut worst_acc, mut largest_acc) = (0f64, 0f64);
        let mut deepest = 0;
        for n in 1..=CPR + 10 {
            if n == CPR {
                fw.index_event(n * TICK, n);
            }
            fw.loop_tick(&enc(n), &mut g, &mut d);
            let phi = phi_of(n);
            let want = gauge_code_from_z(gen.z(x, phi).unwrap());
            assert!((fw.table_code() - want).abs() <= 1, "n {n}");
            deepest = deepest.min(fw.table_code());
            // The perfect slide: at the command.
            g.set(fw.command_code());
            if n >= 3 {
                let step = phi_of(1).0;
                let central = (codes(SpindleAngle(phi.0.wrapping_add(step)))
                    - codes(SpindleAngle(phi.0.wrapping_sub(step))))
                    / 2.0;
                let ff = fw.loop_state().feedforward_q16() as f64 / 65536.0;
                worst_ff = worst_ff.max((ff - central).abs());
                largest_ff = largest_ff.max(ff.abs());
                // Over ±10 steps, scaled back: the Q30 quantisation of Z
                // (0.05 code) would swamp a one-step second difference.
                let h = step.wrapping_mul(10);
                let second = (codes(SpindleAngle(phi.0.wrapping_add(h))) - 2.0 * codes(phi)
                    + codes(SpindleAngle(phi.0.wrapping_sub(h))))
                    / 100.0;
                let acc = fw.loop_state().accel_q16() as f64 / 65536.0;
                worst_acc = worst_acc.max((acc - second).abs());
                largest_acc = largest_acc.max(acc.abs());
            }
        }
        // Slopes up to ~150 codes/tick; the central difference's own error
        // at Δφ = 2π/4000 (third derivative · Δφ²/6) is ≈ 0.1 code.
        assert!(largest_ff > 50.0, "slope {largest_ff}");
        assert!(worst_ff < 0.5, "feedforward off by {worst_ff} codes/tick");
        // ∂²Z/∂φ²·Δφ² (~0.25 codes/tick² at most) against the second
        // difference, to 1 %.
        assert!(largest_acc > 0.1, "acceleration {largest_acc}");
        assert!(
            worst_acc < 0.01,
            "acceleration off by {worst_acc} codes/tick² (largest {largest_acc})"
        );
        assert_eq!(fw.fault(), None);
        // A real command at 3.14 in: tens of µin deep (1 µin = 52 codes).
        assert!(deepest < -5000, "deepest {deepest}");
    }

    #[test]
    fn modern_x_reinterpolates_when_the_count_moves() {
        let cc = CountConfig {
            counts_per_inch: 100_000,
            zero_count: 0,
            max_step_counts: 1000,
        };
        let mut fw = Firmware::with_table(DEFAULT_TABLE, fw_cfg(XMode::Count(cc), false)).unwrap();
        let gen = *fw.command_gen().unwrap();
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        fw.index_event(0, 0);
        for n in 0..2000u32 {
            let count = 200_000 + n * 37; // from 2.0 in, 370 µin per tick
            let mut input = enc(n);
            input.x_count = count;
            fw.loop_tick(&input, &mut g, &mut d);
            g.set(fw.command_code());
            let c = fw.loop_state().coefficients();
            let exact = f64::from(count) / 100_000.0 * f64::from(1u32 << 24);
            assert!((f64::from(c.x().to_bits()) - exact).abs() <= 1.0);
            let want = gen.coefficients(c.x()).unwrap();
            assert_eq!(c.value[..5], want.value[..5]);
            if n > 0 {
                let want = gauge_code_from_z(gen.z(c.x(), phi_of(n)).unwrap());
                assert!((fw.table_code() - want).abs() <= 1, "n {n}");
            }
        }
        assert_eq!(fw.fault(), None);
        // A jump beyond max_step_counts: glitch, ramp to null.
        let mut input = enc(2000);
        input.x_count = 10;
        fw.loop_tick(&input, &mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::XGlitchStorm));
    }

    /// The modern X mode's cached re-interpolation equals the command path
    /// bit for bit over the whole table: walking up and down through every
    /// interval (crossings to both neighbours), jumps of several intervals,
    /// every node exactly, the last node and the null zone.
    #[test]
    fn modern_x_cache_matches_the_command_path_over_the_table() {
        let cc = CountConfig {
            counts_per_inch: 1 << 24, // one count per X LSB: nodes exactly
            zero_count: 0,
            max_step_counts: u32::MAX,
        };
        let mut fw = Firmware::with_table(DEFAULT_TABLE, fw_cfg(XMode::Count(cc), false)).unwrap();
        let gen = *fw.command_gen().unwrap();
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        let t = gen.interpolator().table();
        let last = t.node_x(t.node_count() - 1).to_bits();
        let dx = t.node_x(1).to_bits() - t.node_x(0).to_bits();
        // Steps that are not a divisor of the grid, so every phase occurs.
        let up = (0..=last + dx).step_by(40_009);
        let down = (0..=last + dx).rev().step_by(33_331);
        let jumps = (0..400i64).map(|k| ((k * 7_919_993) % i64::from(last + dx)) as i32);
        let nodes = (0..t.node_count()).map(|n| t.node_x(n).to_bits());
        let mut checked = 0;
        for bits in up.chain(down).chain(jumps).chain(nodes) {
            let mut input = TickInput::NONE;
            input.x_count = bits as u32;
            fw.loop_tick(&input, &mut g, &mut d);
            let got = fw.loop_state().coefficients();
            assert_eq!(got.x().to_bits(), bits);
            let want = gen.coefficients(got.x()).unwrap();
            assert_eq!(got.null, want.null, "x bits {bits}");
            if !want.null {
                let n = usize::from(want.terms());
                assert_eq!(got.terms(), want.terms());
                assert_eq!(got.value[..n], want.value[..n], "x bits {bits}");
                assert_eq!(got.delta[..n], want.delta[..n], "x bits {bits}");
                checked += 1;
            }
        }
        assert!(checked > 1000);
        assert_eq!(fw.fault(), None);
    }

    #[test]
    fn debounce_ignores_repeats_without_publishing() {
        let mut fw = legacy(DEFAULT_TABLE, false);
        let mut quad = NoCoefficientDac;
        fw.x_event(latch_word(2000), 0, &mut quad).unwrap();
        fw.x_event(latch_word(2001), 5_000, &mut quad).unwrap();
        for k in 0..3 {
            // The same half-mil state again (a reversal across a boundary).
            let r = fw.x_event(latch_word(2001), 10_000 + k * 5_000, &mut quad);
            assert_eq!(r, Ok(XEvent::Ignored));
        }
        assert_eq!(fw.shared().x_accepted(), 2);
        assert_eq!(fw.shared().x_ignored(), 3);
        assert_eq!(fw.shared().coefficient_generation(), 2);
        assert_eq!(fw.fault(), None);
    }

    /// Runs `ticks` loop ticks on a perfect slide from tick `from`.
    fn run(fw: &mut Firmware, g: &mut Gauge, d: &mut Dac, from: u32, ticks: u32) {
        for n in from..from + ticks {
            fw.loop_tick(&enc(n), g, d);
            g.set(fw.command_code());
        }
    }

    /// Engaged at X = 3.1415 in after an index, tracking.
    fn cutting() -> (Firmware, Gauge, Dac) {
        let mut fw = legacy(DEFAULT_TABLE, false);
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        fw.x_event(latch_word(6_283), 0, &mut NoCoefficientDac)
            .unwrap();
        fw.index_event(0, 0);
        fw.request(Request::Arm);
        run(&mut fw, &mut g, &mut d, 0, 100);
        assert_eq!(fw.fault(), None);
        assert!(fw.command_code() < -1000);
        (fw, g, d)
    }

    fn assert_ramps_to_null(fw: &mut Firmware, g: &mut Gauge, d: &mut Dac, from: u32, f: Fault) {
        assert_eq!(f.reaction(), Reaction::RampToNull);
        let slew = (fw.config().slew_q16 >> 16) as i32 + 1;
        let mut prev = fw.command_code();
        for n in from..from + 800 {
            fw.loop_tick(&enc(n), g, d);
            g.set(fw.command_code());
            let c = fw.command_code();
            // Never faster than the slew rate (it decelerates out of the
            // table's motion first, then ramps to null and stops there).
            assert!((c - prev).abs() <= slew, "{prev} -> {c}");
            prev = c;
        }
        assert_eq!(fw.fault(), Some(f));
        assert_eq!(fw.command_code(), 0);
        assert!(fw.amplifier_enable(), "the loop stays closed");
    }

    #[test]
    fn x_glitch_storm_ramps_to_null() {
        let (mut fw, mut g, mut d) = cutting();
        let r = fw.x_event(latch_word(6_283 + 41), 100_000, &mut NoCoefficientDac);
        assert_eq!(r, Err(Fault::XGlitchStorm));
        assert_ramps_to_null(&mut fw, &mut g, &mut d, 100, Fault::XGlitchStorm);
    }

    #[test]
    fn bad_bcd_ramps_to_null() {
        let (mut fw, mut g, mut d) = cutting();
        let r = fw.x_event(XLatchWord(0x31A2), 100_000, &mut NoCoefficientDac);
        assert_eq!(r, Err(Fault::XBadBcd));
        assert_ramps_to_null(&mut fw, &mut g, &mut d, 100, Fault::XBadBcd);
    }

    #[test]
    fn x_below_the_table_ramps_to_null() {
        // The default grid moved to start at 1 in (null zone at 8.2 in).
        let img = reencode(|h, _| {
            h.x0_raw = 1 << 24;
            h.x_null_raw += 1 << 24;
        });
        let mut fw = legacy(img, false);
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        fw.x_event(latch_word(2_100), 0, &mut NoCoefficientDac)
            .unwrap();
        fw.index_event(0, 0);
        fw.request(Request::Arm);
        run(&mut fw, &mut g, &mut d, 0, 100);
        assert_eq!(fw.fault(), None);
        let mut now = 0;
        let mut last = None;
        for hm in (1_990..2_100).rev() {
            now += 1000;
            if let Err(f) = fw.x_event(latch_word(hm), now, &mut NoCoefficientDac) {
                last = Some((hm, f));
                break;
            }
        }
        // 1.0 in = 2000 half-mils is the first node; 1999 is below it.
        assert_eq!(last, Some((1_999, Fault::XOutsideTable)));
        assert_ramps_to_null(&mut fw, &mut g, &mut d, 100, Fault::XOutsideTable);
    }

    #[test]
    fn two_index_pulses_in_one_loop_period_are_extra() {
        let (mut fw, mut g, mut d) = cutting();
        fw.index_event(4_000 * TICK, 4_000);
        fw.index_event(4_000 * TICK + 3, 4_000);
        assert_ramps_to_null(&mut fw, &mut g, &mut d, 100, Fault::IndexExtra);
    }

    #[test]
    fn early_index_is_extra_and_missing_index_is_missing() {
        let (mut fw, mut g, mut d) = cutting();
        // Half a turn after the last one.
        fw.index_event(2_000 * TICK, 2_000);
        assert_ramps_to_null(&mut fw, &mut g, &mut d, 100, Fault::IndexExtra);

        let (mut fw, mut g, mut d) = cutting();
        // No index for more than a turn and the tolerance.
        run(&mut fw, &mut g, &mut d, 100, CPR);
        assert_eq!(fw.fault(), Some(Fault::IndexMissing));
        assert_ramps_to_null(&mut fw, &mut g, &mut d, 100 + CPR, Fault::IndexMissing);
    }

    #[test]
    fn stalled_spindle_is_a_speed_fault() {
        let (mut fw, mut g, mut d) = cutting();
        // The count stops at 100 while time goes on.
        for n in 100..600 {
            let mut input = enc(100);
            input.now = n * TICK;
            fw.loop_tick(&input, &mut g, &mut d);
            g.set(fw.command_code());
        }
        assert_eq!(fw.fault(), Some(Fault::SpindleSpeed));
        assert_eq!(fw.command_code(), 0);
        assert!(fw.amplifier_enable());
    }

    /// Coefficient-output mode: every accepted event writes exactly the
    /// frame of the command path's reference (`CommandGen::legacy_frame`)
    /// with one strobe; a bus error disables the amplifier.
    #[test]
    fn coefficient_output_writes_the_legacy_frames() {
        let mut fw = legacy(LEGACY4_TABLE, true);
        let gen = *fw.command_gen().unwrap();
        let mut quad = Quad::default();
        let mut now = 0;
        let mut updates: Vec<XUpdate> = Vec::new();
        for hm in (13_900..14_500).chain((14_350..14_499).rev()) {
            now += 1000;
            if let XEvent::Update(u) = fw.x_event(latch_word(hm), now, &mut quad).unwrap() {
                updates.push(u);
            }
        }
        assert_eq!(updates.len(), 749);
        assert_eq!(quad.frames.len(), updates.len());
        for (f, u) in quad.frames.iter().zip(&updates) {
            assert_eq!(*f, gen.legacy_frame(u).unwrap(), "{u:?}");
        }
        let (mut g, mut d) = (Gauge::at(0), Dac::default());
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        quad.fail = true;
        let r = fw.x_event(latch_word(14_349), now + 1000, &mut quad);
        assert_eq!(r, Err(Fault::Bus(Device::CoefficientDac)));
        fw.loop_tick(&TickInput::NONE, &mut g, &mut d);
        assert_eq!(fw.fault(), Some(Fault::Bus(Device::CoefficientDac)));
        assert!(!fw.amplifier_enable());
        assert!(fw.dac_clamped());
    }

    /// The hand-off under real concurrency (host threads, stronger than the
    /// board's preemption): every coefficient set the loop tick takes is one
    /// complete published set, never a mix of two X positions.
    #[test]
    fn hand_off_never_tears_under_concurrency() {
        use std::sync::atomic::AtomicBool;
        let fw = legacy(DEFAULT_TABLE, false);
        let gen = *fw.command_gen().unwrap();
        let (mut lp, mut ev) = fw.into_parts();
        let shared = Shared::new();
        let stop = AtomicBool::new(false);
        /// Stops the writer however the reader leaves (a failed assert too).
        struct Stop<'a>(&'a AtomicBool);
        impl Drop for Stop<'_> {
            fn drop(&mut self) {
                self.0.store(true, Ordering::Relaxed);
            }
        }
        std::thread::scope(|s| {
            s.spawn(|| {
                let mut now = 0u32;
                'run: loop {
                    for hm in (1..14_000).chain((1..13_999).rev()) {
                        if stop.load(Ordering::Relaxed) {
                            break 'run;
                        }
                        now = now.wrapping_add(1000);
                        let _ = ev.x_event(&shared, latch_word(hm), now, &mut NoCoefficientDac);
                    }
                }
            });
            let _stop = Stop(&stop);
            let (mut g, mut d) = (Gauge::at(0), Dac::default());
            let mut checked = 0u32;
            let mut seen = 0u32;
            while checked < 20_000 {
                lp.loop_tick(&shared, &TickInput::NONE, &mut g, &mut d);
                let c = lp.coefficients();
                if !c.null && shared.coefficient_generation() != seen {
                    seen = shared.coefficient_generation();
                    let want = gen.coefficients(c.x()).unwrap();
                    assert_eq!(c.value[..5], want.value[..5], "torn at {:?}", c.x());
                    checked += 1;
                }
                d.writes.clear();
            }
        });
        assert_eq!(lp.fault(), None);
    }
}
