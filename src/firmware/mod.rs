//! The firmware application behind the three interrupt entry points the
//! boards call. Both boards (`src/main.rs` on the NUCLEO-H743ZI2 and
//! `boards/qemu`) and `host-sim` drive the same code. This module is the
//! bundle for single-threaded users and the public face of the parts,
//! which live by concept along the data path:
//!
//! ```text
//! X event (legacy half-mil) ── xevent: xpos::LegacyX → xpos::columns ─┐ publish (handoff::Shared)
//! X count (modern, periodic) ─ xevent: xpos::CountX → xpos::columns ──┤ publish (when it moved)
//! index event ─────────────── xevent: (count, edge) ──────────────────┤ publish
//! loop tick (looptick): gauge ─┐                                      │
//!   spindle sample ─┴ spindle estimator → φ, Δφ ; takes X / index ────┘
//!   setpoint: Z, ∂Z/∂φ·Δφ, ∂²Z/∂φ²·Δφ² + ∂Z/∂φ·Δ²φ (gauge codes)
//!   → servo (observer, notches, feedforward, learning, limits, arming)
//!   → amplifier DAC
//! ```
//!
//! `config` holds what a firmware is built from and the table load with
//! its sign check; `codes` the converter scales; `handoff` the lock-free
//! hand-off between priorities and the operator's requests.
//!
//! # Safety
//!
//! Nothing here can panic or allocate. A table the parser refuses, or one
//! whose command is positive somewhere (sign check at load), leaves the
//! firmware faulted with [`Fault::Table`] and the command null. The
//! amplifier is never enabled until an arm request ([`Request::Arm`]); the
//! servo then runs its sign check, engages with the command where the
//! slide is (bumpless), and the command approaches its goal within the
//! slew limits. Before the first
//! index (angle unknown) and before the first X (position unknown) the table
//! command is null. Faults latch ([`Firmware::fault`]); a fault whose
//! reaction is [`Reaction::DisableAmplifier`] clamps the DAC to ground
//! (retried every tick until the DAC accepts it), stops all DAC writes and
//! drops [`Firmware::amplifier_enable`]; a [`Reaction::RampToNull`] fault
//! keeps the loop closed and ramps the command to zero at the slew limit.
//! Only a more severe fault replaces a latched one; [`Request::ClearFault`]
//! clears it when the loop is disarmed and the cause is gone.

pub mod config;
pub mod excite;
pub mod learning;
pub mod looptick;
pub mod xevent;

pub use crate::codes::{gauge_code_from_z, CODE_MAX, CODE_MIN};
pub use crate::firmware::config::{
    load_table, load_table_region, ConfigError, FirmwareConfig, SpindleMode, XMode,
};
pub use crate::firmware::learning::LearnState;
pub use crate::firmware::looptick::{LoopState, SpindleReading, TickInput};
pub use crate::firmware::xevent::{EventState, NoCoefficientDac};
pub use crate::handoff::{Request, Shared};

use crate::command::CommandGen;
use crate::firmware::looptick::Estimator;
use crate::hw::{AmplifierDac, CoefficientDac, GaugeAdc, XLatchWord};
use crate::safety::Fault;
use crate::servo::{Servo, ServoConfig};
use crate::spindle::{EncoderAngle, TachAngle};
use crate::table::{TableError, TableIdentity};
use crate::units::ZInches;
use crate::xpos::{CountX, XEvent};

/// The whole firmware: the loop tick's part, the X/index handlers' part and
/// the data they share (see the module docs). Single-threaded users call
/// its entry points; boards split it with [`Firmware::into_parts`].
pub struct Firmware {
    lp: LoopState,
    ev: EventState,
    learn: LearnState,
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
            ev: EventState::new(None, &fc, None),
            learn: LearnState::new(&cfg, None, false),
            shared: Shared::new(),
        }
    }

    /// The integrated firmware from a table image. A table the parser
    /// refuses or that fails the sign check ([`load_table`]) gives a
    /// firmware latched in [`Fault::Table`] with a null command (never a
    /// panic); a configuration the estimators refuse is a [`ConfigError`].
    pub fn with_table(table: &'static [u8], cfg: FirmwareConfig) -> Result<Self, ConfigError> {
        Self::with_loaded(load_table(table), cfg)
    }

    /// [`Self::with_table`] for the table region of a board's flash
    /// ([`load_table_region`]): an erased region is
    /// `Fault::Table(TableError::Missing)`, never a built-in table.
    pub fn with_table_region(
        region: &'static [u8],
        cfg: FirmwareConfig,
    ) -> Result<Self, ConfigError> {
        Self::with_loaded(load_table_region(region), cfg)
    }

    fn with_loaded(
        loaded: Result<CommandGen<'static>, crate::table::TableError>,
        cfg: FirmwareConfig,
    ) -> Result<Self, ConfigError> {
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
        let count = match cfg.x {
            XMode::Count(c) => Some(CountX::new(c).ok_or(ConfigError::Count)?),
            XMode::None | XMode::Legacy { .. } => None,
        };
        lp.x_published = cfg.x != XMode::None;
        if let Err(e) = loaded {
            lp.trip(Fault::Table(e));
        }
        Ok(Self {
            ev: EventState::new(gen, &cfg, count),
            learn: LearnState::new(&cfg.loop_cfg, gen, cfg.x != XMode::None),
            lp,
            shared: Shared::new(),
        })
    }

    /// The part's interruptions (`crate::table::interrupt`'s checked
    /// block) for the hole edges' anticipation (`crate::servo::edges`): a
    /// block the parser refuses is refused here in its words and changes
    /// nothing; an empty block is a whole face (the firmware then runs as
    /// without one, bit for bit). Before the first tick.
    pub fn set_interruptions(
        &mut self,
        block: &[u8],
    ) -> Result<(), crate::table::interrupt::InterruptError> {
        let holes = crate::table::interrupt::Interruptions::parse(block)?;
        self.learn.set_interruptions(holes);
        Ok(())
    }

    /// [`Self::set_interruptions`] for a board's interruption region
    /// (`Interruptions::parse_region`): an erased region holds no block
    /// (`Ok(None)`: the firmware runs as without one); else the block's
    /// hole count, or its refusal in words (nothing changed).
    pub fn set_interruptions_region(
        &mut self,
        region: &[u8],
    ) -> Result<Option<usize>, crate::table::interrupt::InterruptError> {
        let Some(holes) = crate::table::interrupt::Interruptions::parse_region(region)? else {
            return Ok(None);
        };
        let n = holes.holes().len();
        self.learn.set_interruptions(holes);
        Ok(Some(n))
    }

    /// The hole edges' anticipation (its learned step).
    pub fn edges(&self) -> &crate::servo::edges::Edges {
        self.learn.ahead().edges()
    }

    /// The handlers' parts, for boards that give each interrupt its own and
    /// share a `static` [`Shared`] (this bundle's own is dropped: nothing has
    /// been published into it that the parts would need, as long as no entry
    /// point ran before the split).
    pub fn into_parts(self) -> (LoopState, EventState, LearnState) {
        (self.lp, self.ev, self.learn)
    }

    /// See [`LoopState::loop_tick`]. In the modern X mode the tick's X
    /// count then goes to [`EventState::x_count_event`], as a board's
    /// lower-priority X count handler takes it after the tick: the
    /// coefficients at that X serve the next tick.
    pub fn loop_tick(
        &mut self,
        input: &TickInput,
        gauge: &mut impl GaugeAdc,
        dac: &mut impl AmplifierDac,
    ) {
        self.lp.loop_tick(&self.shared, input, gauge, dac);
        // Then what the boards run below the tick, in their priority
        // order: the X count (a fault it finds is raised in `Shared` for
        // the next tick), then the learning handler: the command ahead of
        // the next tick at the count's X, the learning on this tick's
        // sample.
        let _ = self.ev.x_count_event(&self.shared, input.x_count);
        self.learn.run(&self.shared);
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
    /// The loop tick's part, for what the boards run after each tick with
    /// it (the host link's `TickTap::after_tick`).
    pub fn loop_state_mut(&mut self) -> &mut LoopState {
        &mut self.lp
    }
    /// Contour monitoring's state (`servo::monitor`).
    pub fn monitor(&self) -> &crate::servo::monitor::Monitor {
        self.learn.monitor()
    }
    /// The learning (why it is frozen, revolutions learned); the table is
    /// [`Shared::learned`].
    pub fn learning(&self) -> &crate::servo::Learner {
        self.learn.learner()
    }
    /// The command generator of the loaded table (`None`: no table or refused).
    pub fn command_gen(&self) -> Option<&CommandGen<'static>> {
        self.lp.gen.as_ref()
    }
    /// The loaded table's identity, or why there is none (the refusal the
    /// load latched; no table at all is `Missing`): for the boot log and
    /// the host link's status.
    pub fn table_identity(&self) -> Result<TableIdentity, TableError> {
        match (self.command_gen(), self.fault()) {
            (Some(g), _) => Ok(g.interpolator().table().identity()),
            (None, Some(Fault::Table(e))) => Err(e),
            (None, _) => Err(TableError::Missing),
        }
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
mod preemption_tests;

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests;
