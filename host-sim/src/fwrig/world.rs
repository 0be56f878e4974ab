//! The world: the rig and the firmware with the core's drivers on the
//! simulated chips, its handlers run on the board's timing, and the one way
//! to plug into the loop tick ([`TickHook`]).

use super::attached::{AngleState, Machine, MachineStats, XState};
use crate::chips::{SimAd4020, SimAd5686, SimAd5791, SimAmpEnablePin, SimClock, SimLdacPin};
use crate::machine::hw::{
    SimSpindleEncoder, SimTachometer, SimXLatch, SimXQuadrature, SpindleLink, XHalfMilLink,
};
use crate::machine::spindle::SpindleConfig;
use crate::machine::{MachineConfig, SpindleSensor, XInterface};
use crate::plant::{Rig, RigConfig};
use crate::sched::{Nanos, World};
use embedded_hal::digital::OutputPin;
use std::cell::RefCell;
use std::rc::Rc;
use zslide::drivers::ad4020::Ad4020;
use zslide::drivers::ad5686::Ad5686;
use zslide::drivers::ad5791::Ad5791;
use zslide::firmware::{
    Firmware, FirmwareConfig, LoopState, Request, SpindleMode, SpindleReading, TickInput, XMode,
};
use zslide::hw::{Clock, Encoder, Tachometer, XLatch};
use zslide::safety::{Device, Fault};
use zslide::servo::ServoConfig;
use zslide::spindle::{EncoderAngle, EncoderConfig, TachAngle, TachConfig};
use zslide::units::SpindleAngle;
use zslide::xpos::{CountConfig, CountX, XEvent};
use zslide_replay::record::{Recorder, Tap, TapPin};
use zslide_replay::wire::{Dev, Event, XResult};

/// What plugs into the loop tick (the world's [`FirmwareWorld::hooks`], run
/// in their order): the machine's physics (the cutting force of `cut`, the
/// soak's drift) and the host link's tap ([`super::link`]).
pub trait TickHook {
    /// At every loop tick with a machine attached, after the plant has
    /// reached the tick's instant and before the firmware's `loop_tick`
    /// runs, whatever the MCU does: what the machine's physics reads from
    /// the truth and applies to the rig.
    fn before_tick(&mut self, _rig: &mut Rig, _machine: &Machine, _fw: &Firmware) {}
    /// Last in the loop-tick handler, when it runs (as on the boards: fault
    /// changes, snapshots and the capture for the host link).
    fn after_tick(&mut self, _lp: &mut LoopState) {}
}

/// A hook shared with whoever reads it after the run: the world owns one
/// handle, the driver keeps the other.
impl<H: TickHook> TickHook for Rc<RefCell<H>> {
    #[inline]
    fn before_tick(&mut self, rig: &mut Rig, machine: &Machine, fw: &Firmware) {
        self.borrow_mut().before_tick(rig, machine, fw);
    }
    #[inline]
    fn after_tick(&mut self, lp: &mut LoopState) {
        self.borrow_mut().after_tick(lp);
    }
}

/// Rig + the firmware with the core's drivers on the simulated chips.
pub struct FirmwareWorld {
    pub rig: Rig,
    pub fw: Firmware,
    /// The converters through the core drivers, behind taps that log
    /// every frame when a replay is being recorded (`recorder`).
    pub adc: Ad4020<Tap<SimAd4020>>,
    pub dac: Ad5791<Tap<SimAd5791>>,
    pub enable: SimAmpEnablePin,
    pub clock: SimClock,
    /// The coefficient DAC through the core driver (legacy output mode).
    pub quad: Ad5686<Tap<SimAd5686>, TapPin<SimLdacPin>>,
    /// Records every handler call with its inputs and outputs for the
    /// bit-exact replay on the target (`zslide_replay`, `crate::replay`).
    pub recorder: Option<Recorder>,
    pub machine: Option<Machine>,
    /// What runs at each loop tick besides the firmware: the machine's
    /// physics, the host link's tap (none: no cutting, no link).
    pub hooks: Vec<Box<dyn TickHook>>,
    init_fault: Option<Fault>,
    /// The 1983 loop when it drives the amplifier ([`super::controller::Controller::LegacyAnalog`]).
    pub analog: Option<crate::analog1983::AnalogDrive>,
    /// What the MCU is doing: a board-level state the core has no notion
    /// of (a stalled loop-tick interrupt, a halted core), set by the fault
    /// campaign's board models (`faults::board`).
    pub cpu: Cpu,
    /// The X count as the board sees it, held at this value while the X
    /// slide feeds on (a fault campaign's dead X encoder or half-mil
    /// line: no X interrupt reaches the firmware); `None` normally.
    pub x_held: Option<u32>,
}

/// The MCU's execution state, as far as the handlers are concerned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cpu {
    /// Every interrupt runs.
    Running,
    /// The loop-tick interrupt no longer runs (a handler that never
    /// returns at its priority, or its timer stopped); the DAC holds its
    /// last code and the enable line its last level, as on the board.
    LoopStalled,
    /// Nothing runs (panic handler spinning, core in reset).
    Halted,
}

impl World for FirmwareWorld {
    #[inline]
    fn advance_to(&mut self, t: Nanos) {
        match self.analog.as_mut() {
            None => self.rig.advance_to(t),
            Some(a) => {
                // Its reference: the firmware's command (or the 1983
                // generator's), V = mil.
                let v = match &a.command_v {
                    Some(c) => c.get(),
                    None => {
                        let code = self.fw.table_code().saturating_add(self.fw.target_code());
                        f64::from(code) * 10.0 / 524_288.0
                    }
                };
                a.reference_v = a.reference_sign * v;
                a.advance(&mut self.rig, t);
            }
        }
    }
    #[inline]
    fn set_time(&mut self, t: Nanos) {
        self.rig.time.set(t);
    }
}

impl FirmwareWorld {
    /// Rig and firmware; the DAC initialised through the core driver (zero
    /// code, control register, read-back). A failed init latches
    /// `Fault::Bus(AmplifierDac)`, as the board does.
    pub fn new(cfg: RigConfig, loop_cfg: ServoConfig) -> Self {
        Self::build(Rig::new(cfg), loop_cfg, None)
    }

    /// [`Self::new`], every handler call recorded from the boot on.
    pub fn new_recording(cfg: RigConfig, loop_cfg: ServoConfig, rec: Recorder) -> Self {
        Self::build(Rig::new(cfg), loop_cfg, Some(rec))
    }

    /// [`Self::new`] with `fault` injected into the DAC's first four frames
    /// (the whole init sequence).
    pub fn new_with_dac_faults(
        cfg: RigConfig,
        loop_cfg: ServoConfig,
        fault: crate::chips::BusFault,
    ) -> Self {
        let rig = Rig::new(cfg);
        rig.dac.state.borrow_mut().faults.inject(fault, 4);
        Self::build(rig, loop_cfg, None)
    }

    fn build(rig: Rig, loop_cfg: ServoConfig, recorder: Option<Recorder>) -> Self {
        let dev = rig.devices();
        let r = recorder.clone();
        let mut dac = Ad5791::new(Tap::new(dev.amp_dac, Dev::AmpDac, r.clone()));
        let mut fw = Firmware::new(loop_cfg);
        if let Some(r) = &r {
            r.begin(Event::Boot);
        }
        let mut init_fault = None;
        if dac.init().is_err() {
            init_fault = Some(Fault::Bus(Device::AmplifierDac));
        }
        let tapped = || {
            (
                Tap::new(dev.quad_dac.clone(), Dev::QuadDac, r.clone()),
                TapPin::new(dev.ldac.clone(), r.clone()),
            )
        };
        let (spi, pin) = tapped();
        let quad = match Ad5686::new(spi, pin) {
            Ok(q) => q,
            Err(_) => {
                init_fault = Some(Fault::Bus(Device::CoefficientDac));
                let (spi, pin) = tapped();
                // The pin write is infallible on the simulated pin; the
                // error path is kept for the type.
                Ad5686::new(spi, pin).unwrap_or_else(|_| unreachable!())
            }
        };
        if let Some(f) = init_fault {
            fw.trip(f);
        }
        if let Some(r) = &r {
            r.end(None, fw.amplifier_enable(), fw.fault());
        }
        Self {
            rig,
            fw,
            adc: Ad4020::new(Tap::new(dev.gauge_adc, Dev::GaugeAdc, r)),
            dac,
            enable: dev.amp_enable,
            clock: dev.clock,
            quad,
            machine: None,
            hooks: Vec::new(),
            init_fault,
            analog: None,
            cpu: Cpu::Running,
            x_held: None,
            recorder,
        }
    }

    /// Adds the X slide and spindle, and replaces the bench firmware by the
    /// integrated one (default table, the machine's X and spindle modes,
    /// same loop configuration). Their clocks are the rig's clock.
    pub fn attach_machine(&mut self, m: &MachineConfig) {
        self.attach_machine_with_table(m, zslide::DEFAULT_TABLE);
    }

    /// [`Self::attach_machine`] with another coefficient table (a part of
    /// the user's, or the sinusoid `track` commands).
    pub fn attach_machine_with_table(&mut self, m: &MachineConfig, table: &'static [u8]) {
        let ticks_per_s = self.rig.clock_hz;
        let tps = u32::try_from(ticks_per_s).unwrap_or(u32::MAX);
        let time = self.rig.time.clone();
        let spindle_cfg = SpindleConfig {
            ticks_per_s: ticks_per_s as f64,
            ..m.spindle.clone()
        };
        let cpr = spindle_cfg.encoder_cpr;
        let index_angle =
            SpindleAngle((spindle_cfg.index_phase_turns.rem_euclid(1.0) * 4_294_967_296.0) as u32);
        let link = Rc::new(RefCell::new(SpindleLink::new(
            spindle_cfg,
            m.spindle_step_ns,
            m.window_ns,
        )));
        let count_cfg = CountConfig {
            counts_per_inch: 1_000_000,
            zero_count: 0,
            // 100 in/min at 20 kHz is 83 counts per tick.
            max_step_counts: 1000,
        };
        let x = match &m.x {
            XInterface::LegacyBcd(c) => {
                let l = XHalfMilLink::new(c.clone(), m.x_step_ns, m.window_ns);
                let latch = l.latch.clone();
                XState::Legacy {
                    link: Rc::new(RefCell::new(l)),
                    latch,
                }
            }
            XInterface::Quadrature(c) => XState::Count {
                enc: Box::new(SimXQuadrature::new(
                    c.clone(),
                    m.x_step_ns,
                    time.clone(),
                    ticks_per_s,
                )),
                decoder: CountX::new(count_cfg).expect("counts_per_inch is not zero"),
            },
        };
        let (angle, spindle_mode) = match m.sensor {
            SpindleSensor::EncoderIndex => {
                let c = EncoderConfig {
                    counts_per_rev: cpr,
                    ticks_per_s: tps,
                    min_rpm: m.min_rpm,
                    max_rpm: m.max_rpm,
                    index_tolerance_counts: 2,
                    index_angle,
                    edge_stamps: m.encoder_edges,
                };
                (
                    AngleState::Encoder {
                        dev: SimSpindleEncoder {
                            link: link.clone(),
                            time: time.clone(),
                            edges: m.encoder_edges,
                            last: None,
                        },
                        est: EncoderAngle::new(c).expect("valid encoder configuration"),
                    },
                    SpindleMode::Encoder(c),
                )
            }
            SpindleSensor::TachIndex => {
                let c = TachConfig {
                    ticks_per_s: tps,
                    mv_at_300_rpm: 5000,
                    min_rpm: m.min_rpm,
                    max_rpm: m.max_rpm,
                    index_tolerance_permille: 20,
                    index_angle,
                };
                (
                    AngleState::Tach {
                        dev: SimTachometer {
                            link: link.clone(),
                            time,
                        },
                        est: TachAngle::new(c).expect("valid tachometer configuration"),
                    },
                    SpindleMode::Tach(c),
                )
            }
        };
        let fc = FirmwareConfig {
            loop_cfg: *self.fw.config(),
            spindle: spindle_mode,
            x: match &x {
                XState::Legacy { .. } => XMode::Legacy { clock_hz: tps },
                XState::Count { .. } => XMode::Count(count_cfg),
            },
            coefficient_output: m.coefficient_output,
            gauge_reversed: self.rig.gauge.params.reversed,
        };
        let mut fw = Firmware::with_table(table, fc)
            .expect("the estimators accepted this configuration above");
        if let Some(f) = self.init_fault {
            fw.trip(f);
        }
        if let Some(r) = &self.recorder {
            r.set_setup(table, &fc);
        }
        self.fw = fw;
        self.machine = Some(Machine {
            x,
            angle,
            spindle: link,
            stats: MachineStats::default(),
            monitor: true,
        });
    }

    /// The part's interruption block to the firmware
    /// (`Firmware::set_interruptions`, before the first tick), recorded
    /// with the run when one is being recorded: refused in the firmware's
    /// words, and then nothing changes.
    pub fn set_interruptions(
        &mut self,
        block: &[u8],
    ) -> Result<(), zslide::table::interrupt::InterruptError> {
        self.fw.set_interruptions(block)?;
        if let Some(r) = &self.recorder {
            r.set_interruptions(block);
        }
        Ok(())
    }

    /// The loop-tick interrupt, on the board's timing (`RigConfig`): the
    /// loop-timer event is now; the gauge is sampled `adc_sample_ns` later
    /// (CNV, hardware); the handler reads the clock, the spindle encoder or
    /// tachometer and the X count `handler_entry_ns` after the event, runs
    /// the firmware's loop tick through the drivers (its DAC frame ends
    /// `dac_latency_ns` after the event), then sets the enable line.
    #[inline]
    pub fn tick(&mut self) {
        // The machine's physics runs whatever the MCU does.
        if let Some(m) = self.machine.as_ref() {
            for h in &mut self.hooks {
                h.before_tick(&mut self.rig, m, &self.fw);
            }
        }
        if self.cpu != Cpu::Running {
            return;
        }
        let t_event = self.rig.time.get();
        if self.rig.adc_sample_ns > 0 {
            // No input change falls inside: the last DAC frame ended a
            // period earlier at most (`loop.dac_latency_ns` ≤ period).
            World::advance_to(self, t_event + self.rig.adc_sample_ns);
        }
        match self.analog.as_ref().and_then(|a| a.gauge_volts(&self.rig)) {
            // The 1983 loop's exact steps carry the gauge's noise.
            Some(v) => self.rig.adc.state.borrow_mut().convert(v),
            None => self.rig.cnv(),
        }
        // The handler runs at its read instant (the DAC frame is timed
        // from there, `Rig::new`).
        self.rig.time.set(t_event + self.rig.handler_entry_ns);
        let mut input = TickInput::NONE;
        // The amplifier's fault line, as the board reads it.
        input.amplifier_fault = self.rig.amp.tripped();
        if let Some(m) = self.machine.as_mut() {
            input.now = self.clock.now_ticks();
            // The monitor estimator sees exactly the firmware's readings.
            let monitor = m.monitor;
            let est = match &mut m.angle {
                AngleState::Encoder { dev, est } => {
                    let s = dev.sample();
                    input.spindle = SpindleReading::Encoder(s);
                    monitor.then(|| (est.tick(s.count, s.edge_ticks, input.now), est.referenced()))
                }
                AngleState::Tach { dev, est } => {
                    let mv = dev.millivolts();
                    input.spindle = SpindleReading::Tach(mv);
                    monitor.then(|| (est.tick(mv, input.now), est.referenced()))
                }
            };
            if let Some((e, referenced)) = est {
                m.stats.angle = e.angle;
                m.stats.referenced = referenced;
            }
            if let XState::Count { enc, decoder } = &mut m.x {
                input.x_count = self.x_held.unwrap_or_else(|| enc.sample().count);
                m.stats.x = Some(decoder.x(input.x_count));
            }
        }
        if let Some(r) = &self.recorder {
            r.begin_tick(&input);
        }
        self.fw.loop_tick(&input, &mut self.adc, &mut self.dac);
        if let Some(r) = &self.recorder {
            r.end(None, self.fw.amplifier_enable(), self.fw.fault());
        }
        if let Some(m) = self.machine.as_mut() {
            let sh = self.fw.shared();
            m.stats.x_accepted = u64::from(sh.x_accepted());
            m.stats.x_ignored = u64::from(sh.x_ignored());
        }
        // With the 1983 loop driving, the firmware does not own the enable.
        let on = self.fw.amplifier_enable() || self.analog.is_some();
        if on != self.rig.enable.state.borrow().enable {
            // The pin is written after the handler's DAC frame.
            self.rig.time.set(t_event + self.rig.dac_latency_ns);
            let _ = if on {
                self.enable.set_high()
            } else {
                self.enable.set_low()
            };
        }
        // Last in the handler, as on the boards: fault changes, snapshots
        // and the capture for the host link.
        for h in &mut self.hooks {
            h.after_tick(self.fw.loop_state_mut());
        }
        self.rig.time.set(t_event);
    }

    /// Stops the X count where it is now (`x_held`): the count the
    /// firmware reads every tick stays, and no half-mil interrupt reaches
    /// it, while the X slide feeds on.
    pub fn hold_x(&mut self) {
        let count = match self.machine.as_mut().map(|m| &mut m.x) {
            Some(XState::Count { enc, .. }) => enc.sample().count,
            _ => 0,
        };
        self.x_held = Some(count);
    }

    /// The half-mil interrupt: the latch was loaded at the edge; the
    /// firmware's `x_event` reads it through `hw::XLatch`.
    pub fn x_event(&mut self, stale: bool) {
        if self.cpu == Cpu::Halted {
            return;
        }
        if self.x_held.is_some() {
            return;
        }
        let now = self.clock.now_ticks();
        let Some(m) = self.machine.as_mut() else {
            return;
        };
        let XState::Legacy { latch, .. } = &mut m.x else {
            return;
        };
        m.stats.x_events += 1;
        m.stats.x_stale += u64::from(stale);
        let word = latch.read();
        if let Some(r) = &self.recorder {
            r.begin(Event::X {
                word: word.0,
                now,
                result: XResult::Ignored,
            });
        }
        let result = match self.fw.x_event(word, now, &mut self.quad) {
            Ok(XEvent::Ignored) => XResult::Ignored,
            Ok(XEvent::Update(u)) => {
                m.stats.x = Some(u.x);
                XResult::Update
            }
            Err(f) => {
                m.stats.x_faults += 1;
                m.stats.last_fault = Some(f);
                XResult::Fault
            }
        };
        if let Some(r) = &self.recorder {
            r.end(Some(result), self.fw.amplifier_enable(), self.fw.fault());
        }
        let sh = self.fw.shared();
        m.stats.x_accepted = u64::from(sh.x_accepted());
        m.stats.x_ignored = u64::from(sh.x_ignored());
    }

    /// The index interrupt: the count the encoder timer latched at the edge
    /// and the edge's captured timestamp.
    pub fn index_event(&mut self, count: u32, edge_ticks: u32) {
        if self.cpu == Cpu::Halted {
            return;
        }
        let Some(m) = self.machine.as_mut() else {
            return;
        };
        m.stats.index_events += 1;
        if let Some(r) = &self.recorder {
            r.begin(Event::Index { edge_ticks, count });
        }
        self.fw.index_event(edge_ticks, count);
        if let Some(r) = &self.recorder {
            r.end(None, self.fw.amplifier_enable(), self.fw.fault());
        }
        if !m.monitor {
            return;
        }
        let r = match &mut m.angle {
            AngleState::Encoder { est, .. } => est.on_index(count, edge_ticks),
            AngleState::Tach { est, .. } => est.on_index(edge_ticks),
        };
        if let Err(f) = r {
            m.stats.index_faults += 1;
            m.stats.last_fault = Some(f);
        }
    }

    /// The legacy X interface's BCD latch (what the half-mil handler
    /// reads); `None` without a legacy-X machine.
    pub fn x_latch(&self) -> Option<SimXLatch> {
        match self.machine.as_ref().map(|m| &m.x) {
            Some(XState::Legacy { latch, .. }) => Some(latch.clone()),
            _ => None,
        }
    }

    /// Whether the attached machine's spindle angle comes from an encoder
    /// (else a tachometer, or no machine).
    pub fn spindle_is_encoder(&self) -> bool {
        matches!(
            self.machine.as_ref().map(|m| &m.angle),
            Some(AngleState::Encoder { .. })
        )
    }

    /// True X now (feed profile, without vibration and jitter), in; NaN
    /// without a machine.
    pub fn x_true_in(&self) -> f64 {
        let t_s = self.rig.time.get() as f64 * 1e-9;
        self.machine.as_ref().map_or(f64::NAN, |m| m.x_true_in(t_s))
    }

    /// Hands the amplifier to the 1983 analog loop from now on, stepped
    /// exactly while it is linear ([`crate::analog1983::AnalogDrive`]).
    pub fn use_legacy_analog(&mut self) {
        self.use_legacy_analog_with(true);
    }

    /// [`Self::use_legacy_analog`]; `exact = false`: the 5 µs
    /// co-simulation from the start (the reference the exact steps are
    /// tested against).
    pub fn use_legacy_analog_with(&mut self, exact: bool) {
        self.analog = Some(crate::analog1983::AnalogDrive::position_loop(
            &self.rig,
            exact,
            self.rig.seed ^ 0x1983_A7A1,
        ));
        let _ = self.enable.set_high();
    }

    /// Posts an operator request (arm, disarm, clear) for the next tick.
    pub fn request(&mut self, r: Request) {
        if let Some(rec) = &self.recorder {
            rec.request(r);
        }
        self.fw.request(r);
    }

    pub fn stats(&self) -> Option<&MachineStats> {
        self.machine.as_ref().map(|m| &m.stats)
    }
}
