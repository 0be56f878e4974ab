//! The fault campaign (`host-sim faults`): one fault at a time injected
//! into a simulated cut on the real firmware (`cut::build_stretch`: the
//! finishing pass on `fwrig`, the digital loop armed, settled and
//! learning), and what it leaves: detection, the firmware's reaction and
//! reason, the tool's largest departure into the part, the safe state and
//! how long it took. The bound and its derivation: docs/SAFETY.md
//! ("Fault campaign").
//!
//! Injections reuse the simulator's own mechanisms: the chips' bus-fault
//! injector, the gauge's injection input, the amplifier's trip, the
//! spindle and X-slide models, the cutter's force, the host link's
//! transport ([`crate::fwrig::link`]); the watchdog and the panic handler are
//! board models ([`board`]).

pub mod board;
pub mod link;
pub mod matrix;

use crate::chips::BusFault;
use crate::cut::{build_stretch, CutSpec, Stretch};
use crate::fwrig::{src, Controller, Cpu};
use crate::sched::{prio, Nanos, OneShots};
use anyhow::{bail, Context};
use std::cell::{Cell, RefCell};
use std::rc::Rc;
use zslide::codes::GAUGE_CODES_PER_INCH as CODES_PER_IN;
use zslide::hw::XLatchWord;
use zslide::safety::{Device, Fault, Reaction};
use zslide::servo::Phase;

const MS: Nanos = 1_000_000;
/// The engagement row's re-arm after its disarm: the ramp to null (at
/// most 0.004 in at the slew limits, ~30 ms) and the amplifier off.
const REARM_NS: Nanos = 100 * MS;

/// Radius of the cut where faults are injected, in (tool-centre X).
pub const X_INJECT_IN: f64 = 5.0;
/// The largest injection radius, in: the default table's contour ends at
/// 7.2 in (its null zone beyond); the matrix's outermost radius is 7 in.
pub const X_MAX_IN: f64 = 7.2;
/// Revolutions of cut before the injection (sign check, engagement,
/// settling, learning and the stock memory: the cut's own pre-roll).
pub const PREROLL_REVS: f64 = 60.0;
/// Observation kept before the injection (the trace's start), ns.
pub const BEFORE_NS: Nanos = 20 * MS;
/// How long the safe state must hold, to the end of the run, to count.
pub const HOLD_NS: Nanos = 100 * MS;
/// "Holding at null": the slide within this of Z = 0, in: the depth of
/// cut. Null is not clear of the stock everywhere (at X = 5 in the
/// surface rises to within 100 µin of Z = 0, the stock 300 µin above it),
/// so the loop holds null against the tool's rubbing; the hold is judged
/// against the depth it could leave, not against the gauge noise.
pub const NULL_HOLD_IN: f64 = 300e-6;

/// One fault of the campaign (the list).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Case {
    CorruptTable,
    XOutsideTable,
    XGlitchStorm,
    XBadBcd,
    IndexMissing,
    IndexExtra,
    SpindleSpeed,
    GaugeSaturation,
    AdcBusError,
    DacBusError,
    FollowingError,
    FollowingErrorFast,
    CurrentLimit,
    AmplifierTrip,
    ReversedGauge,
    StalledLoop,
    Panic,
    MalformedHostFrame,
    EdgeForceX2,
    EdgeForceX4,
    GaugeFrozen,
    XCountStopped,
    EngageRunning,
}

impl Case {
    pub const ALL: [Case; 18] = [
        Case::CorruptTable,
        Case::XOutsideTable,
        Case::XGlitchStorm,
        Case::XBadBcd,
        Case::IndexMissing,
        Case::IndexExtra,
        Case::SpindleSpeed,
        Case::GaugeSaturation,
        Case::AdcBusError,
        Case::DacBusError,
        Case::FollowingError,
        Case::FollowingErrorFast,
        Case::CurrentLimit,
        Case::AmplifierTrip,
        Case::ReversedGauge,
        Case::StalledLoop,
        Case::Panic,
        Case::MalformedHostFrame,
    ];

    /// The process rows (contour monitoring, issue 30): the cut itself
    /// changes under the loop, or its X or gauge stops following it. Apart
    /// from [`Case::ALL`], whose rows are each a fault the firmware must
    /// latch: a doubled edge force the loop rides out within the depth of
    /// cut needs no fault (`host-sim/tests/faults_process.rs`).
    pub const PROCESS: [Case; 5] = [
        Case::EdgeForceX2,
        Case::EdgeForceX4,
        Case::GaugeFrozen,
        Case::XCountStopped,
        Case::EngageRunning,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Case::CorruptTable => "corrupt-table",
            Case::XOutsideTable => "x-outside-table",
            Case::XGlitchStorm => "x-glitch-storm",
            Case::XBadBcd => "x-bad-bcd",
            Case::IndexMissing => "index-missing",
            Case::IndexExtra => "index-extra",
            Case::SpindleSpeed => "spindle-speed",
            Case::GaugeSaturation => "gauge-saturation",
            Case::AdcBusError => "adc-bus-error",
            Case::DacBusError => "dac-bus-error",
            Case::FollowingError => "following-error",
            Case::FollowingErrorFast => "following-error-fast",
            Case::CurrentLimit => "current-limit",
            Case::AmplifierTrip => "amplifier-trip",
            Case::ReversedGauge => "reversed-gauge",
            Case::StalledLoop => "stalled-loop",
            Case::Panic => "panic",
            Case::MalformedHostFrame => "malformed-host-frame",
            Case::EdgeForceX2 => "edge-force-x2",
            Case::EdgeForceX4 => "edge-force-x4",
            Case::GaugeFrozen => "gauge-frozen",
            Case::XCountStopped => "x-count-stopped",
            Case::EngageRunning => "engage-running",
        }
    }

    /// What is injected, in words.
    pub fn injection(self) -> &'static str {
        match self {
            Case::CorruptTable => "one byte of the coefficient table image flipped before boot (CRC); arm requested",
            Case::XOutsideTable => "the X feed carries the tool centre past the axis (X < 0, below the table's first node; interferometer count X)",
            Case::XGlitchStorm => "20 half-mil interrupts 50 us apart on an unchanged latch (a noisy interrupt line)",
            Case::XBadBcd => "one half-mil interrupt whose latch holds thousandths nibble 0xC",
            Case::IndexMissing => "the index pulse is lost from now on (index_loss_prob = 1)",
            Case::IndexExtra => "noise on the index line (20 spurious pulses per revolution)",
            Case::SpindleSpeed => "the spindle drive fails: the spindle coasts down at its 100 rpm/s",
            Case::GaugeSaturation => "the gauge output driven to its +10 V rail (0.02 in injected into its input)",
            Case::AdcBusError => "gauge ADC bus stuck low on every frame from now on",
            Case::DacBusError => "every amplifier-DAC transaction fails from now on (SPI error)",
            Case::FollowingError => "a hard inclusion under the tool: the force pushing it out of the cut rises to 20 lbf in 5 ms (above the 17.4 lbf of the loop's 6 A) and dies away over 40 ms",
            Case::FollowingErrorFast => "the amplifier's output stage fails to 4 A while a hard spot pushes the tool out of the cut (16 lbf for 30 ms)",
            Case::CurrentLimit => "a chip wedged under the tool: 18 lbf pushing the tool out for 40 ms (above the 6 A the loop allows)",
            Case::AmplifierTrip => "the amplifier trips on its own (its fault line goes high)",
            Case::ReversedGauge => "gauge wired reversed, the firmware not told; arm requested at boot",
            Case::StalledLoop => "the loop-tick interrupt stops running (the board's IWDG is fed by it)",
            Case::Panic => "the firmware panics (board panic handler)",
            Case::MalformedHostFrame => "a flood of 235 malformed host-link frames (garbage, truncated, corrupt, unknown command, other version, undecodable, oversize) and 10 empty ones, 4 valid read-only requests among them, as fast as the RTT buffer takes them",
            Case::EdgeForceX2 => "the edge force k_e doubles mid-cut (a worn edge, a ploughing chip): the process spring on the slide doubles",
            Case::EdgeForceX4 => "the edge force k_e quadruples mid-cut (another material)",
            Case::GaugeFrozen => "the gauge ADC's result freezes at its last, in-range code (a stuck converter)",
            Case::XCountStopped => "the X count stops (a dead X encoder or half-mil line) while the X slide feeds on",
            Case::EngageRunning => "the loop disarmed mid-cut (ramp to null, amplifier off) and armed again 100 ms later, the spindle turning and X feeding: sign check and engagement onto the running cut",
        }
    }

    /// Whether the injection must latch a fault (a malformed host frame
    /// must not: it is refused and counted, the cut goes on; nor may an
    /// engagement onto the running cut).
    pub fn expects_fault(self) -> bool {
        !matches!(self, Case::MalformedHostFrame | Case::EngageRunning) && !self.may_ride_out()
    }

    /// A change of the cut the loop may ride out within the depth of cut
    /// with no fault (else it must latch one of [`Self::expects`]).
    pub fn may_ride_out(self) -> bool {
        matches!(self, Case::EdgeForceX2 | Case::EdgeForceX4)
    }

    /// Whether `f` is the fault this injection must latch.
    pub fn expects(self, f: Fault) -> bool {
        use zslide::table::TableError;
        match self {
            Case::CorruptTable => matches!(f, Fault::Table(TableError::PayloadCrc { .. })),
            Case::XOutsideTable => f == Fault::XOutsideTable,
            Case::XGlitchStorm => f == Fault::XGlitchStorm,
            Case::XBadBcd => f == Fault::XBadBcd,
            Case::IndexMissing => f == Fault::IndexMissing,
            Case::IndexExtra => f == Fault::IndexExtra,
            Case::SpindleSpeed => f == Fault::SpindleSpeed,
            // The gauge's rail is the ADC's full scale: the OV flag.
            Case::GaugeSaturation => f == Fault::GaugeRange,
            Case::AdcBusError => f == Fault::Bus(Device::GaugeAdc),
            Case::DacBusError => f == Fault::Bus(Device::AmplifierDac),
            // The push stays under the following-error limit; its rebound
            // into the stock is the depth guard's (or the ring the
            // oscillation monitor's).
            Case::FollowingError => matches!(
                f,
                Fault::FollowingError | Fault::DepthGuard | Fault::Oscillation
            ),
            // A slide lost at ~4 in/s crosses the 0.006 in between the
            // following-error limit (0.004 in) and the gauge's range
            // (0.010 in) in ~1.5 ms, inside the monitor's 2 ms persistence:
            // the more severe GaugeRange then holds the latch.
            Case::FollowingErrorFast => matches!(f, Fault::FollowingError | Fault::GaugeRange),
            Case::CurrentLimit => f == Fault::CurrentLimit,
            Case::AmplifierTrip => f == Fault::AmplifierTrip,
            Case::ReversedGauge => f == Fault::SignCheck,
            Case::StalledLoop => f == Fault::Watchdog,
            Case::Panic => f == Fault::Panic,
            Case::MalformedHostFrame => false,
            // The loop rings against the doubled spring (or the tool is
            // pulled into the stock first): either monitor, both retract.
            Case::EdgeForceX2 | Case::EdgeForceX4 => {
                matches!(f, Fault::Oscillation | Fault::DepthGuard)
            }
            Case::GaugeFrozen => f == Fault::GaugeFrozen,
            Case::XCountStopped => f == Fault::XStalled,
            Case::EngageRunning => false,
        }
    }

    /// Injected at boot (or at arm) rather than during the cut.
    pub fn at_boot(self) -> bool {
        matches!(self, Case::CorruptTable | Case::ReversedGauge)
    }

    /// Why the case cannot be injected on this machine (`None`: it can).
    pub fn not_applicable(self, spec: &CutSpec) -> Option<&'static str> {
        use crate::machine::XInterface;
        match (self, &spec.scenario.machine.x) {
            (Case::XBadBcd, XInterface::Quadrature(_)) => Some(
                "needs the legacy BCD X interface (a latched digit); this machine's X is a count",
            ),
            // The storm is interrupts on the legacy half-mil line; a count
            // read every tick has no such line (a count that jumps is
            // `XGlitchStorm` there too, not what this case injects).
            (Case::XGlitchStorm, XInterface::Quadrature(_)) => Some(
                "the storm is interrupts on the legacy half-mil X line; this machine's X is a count read every loop tick",
            ),
            _ => None,
        }
    }

    /// Modelled on the board, not in the core.
    pub fn board_model(self) -> bool {
        matches!(self, Case::StalledLoop | Case::Panic)
    }

    /// Simulated time after the injection, ns: the detection's own time
    /// scale plus the hold.
    fn observe_ns(self) -> Nanos {
        match self {
            // 300 → 100 rpm at 100 rpm/s.
            Case::SpindleSpeed => 2_500 * MS,
            // One revolution (200 ms) plus its tolerance.
            Case::IndexMissing => 600 * MS,
            // x_stall_revs (20) revolutions at 300 rpm: 4 s, and the hold.
            Case::XCountStopped => 4_600 * MS,
            // Ten revolutions: a ring the doubled spring starts has grown
            // (or died) well within them.
            Case::EdgeForceX2 | Case::EdgeForceX4 => 2_000 * MS,
            // The re-arm (100 ms), the sign check and the engagement, the
            // settling revolutions of contour monitoring
            // (`servo::monitor::SETTLE_REVS`) and eight revolutions judged.
            Case::EngageRunning => 2_500 * MS,
            _ => 400 * MS,
        }
    }
}

/// One row of the campaign.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Row {
    pub fault: &'static str,
    pub injection: &'static str,
    pub detected: Option<bool>,
    /// The fault the firmware latched (Debug form).
    pub latched: Option<String>,
    pub reaction: Option<String>,
    /// The tool's largest departure into the part (below the exact command)
    /// after the injection, µin (0 when it never went below).
    pub max_excursion_uin: Option<f64>,
    /// The same over the revolution before the injection (the cut's own
    /// following error at this radius and speed, same seeds), µin.
    pub excursion_before_uin: Option<f64>,
    /// The same run without the injection, over the same time (the
    /// malformed-frame row: the flood must leave the cut as it was), µin.
    pub excursion_undisturbed_uin: Option<f64>,
    pub safe_state: Option<bool>,
    pub reason: String,
    pub time_to_safe_ms: Option<f64>,
    /// Injection instant, s of simulated time.
    pub injected_at_s: Option<f64>,
    /// The host link's account of the flood (malformed-frame row).
    pub link: Option<link::LinkOutcome>,
}

/// One sample per loop-tick instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub t_ns: Nanos,
    /// Tool (true) minus the exact command, in; negative = into the part.
    pub err_in: f64,
    /// Slide carriage position, in.
    pub z_in: f64,
    /// The firmware's command, in.
    pub command_in: f64,
    /// What the loop followed: the command plus the learned correction, in.
    pub reference_in: f64,
    /// Amplifier input (the DAC's analog output), V.
    pub dac_v: f64,
    /// Coil current, A (the motor's force is 2.9 lbf/A of it, toward
    /// +Z for a positive current).
    pub current_a: f64,
    /// The cutting force on the tool (+Z: out of the part), lbf.
    pub force_lbf: f64,
    /// Slide carriage velocity, in/s.
    pub velocity_in_s: f64,
    pub fault: bool,
    /// The latched fault's reaction is to drop the amplifier enable (a
    /// row can latch a ramp-to-null fault first and a disabling one later,
    /// which replaces it).
    pub fault_disables: bool,
    /// The enable line as the amplifier sees it at the tick's instant
    /// (before the tick's own write, which lands `dac_latency_ns` later).
    pub amp_enabled: bool,
    /// The enable line as this tick's handler left it.
    pub enable_written: bool,
}

/// A row and its trace (from `BEFORE_NS` before the injection).
#[derive(Clone, Debug)]
pub struct Outcome {
    pub row: Row,
    /// The fault latched (by the firmware, or the board model).
    pub latched: Option<Fault>,
    pub trace: Vec<Sample>,
    /// The learned correction over the revolution before the injection
    /// (none at boot, where nothing was cut before).
    pub correction_before: Option<CorrectionSpan>,
}

/// The learned correction (the reference less the command, in) over a
/// revolution: the table at this X, every angle once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CorrectionSpan {
    pub least_in: f64,
    pub greatest_in: f64,
    /// Its largest change from one loop tick to the next, in.
    pub largest_step_in: f64,
}

impl CorrectionSpan {
    fn take(&mut self, c_in: f64, last_in: Option<f64>) {
        self.least_in = self.least_in.min(c_in);
        self.greatest_in = self.greatest_in.max(c_in);
        if let Some(l) = last_in {
            self.largest_step_in = self.largest_step_in.max((c_in - l).abs());
        }
    }
}

/// The cut every fault is injected into: chapter 5's pass on the scenario,
/// the digital loop.
pub fn spec(scenario: crate::scenario::Scenario) -> anyhow::Result<CutSpec> {
    spec_at(scenario, None)
}

/// [`spec`] at another spindle speed (`None`: the scenario's).
pub fn spec_at(scenario: crate::scenario::Scenario, rpm: Option<f64>) -> anyhow::Result<CutSpec> {
    let mut spec = CutSpec::chapter5(scenario, Controller::Digital, rpm, None, false)?;
    spec.preroll_revs = PREROLL_REVS;
    Ok(spec)
}

/// When and where a fault is injected into the cut: `after_turns`
/// revolutions after the pre-roll (0: the campaign's instant,
/// `PREROLL_REVS` revolutions in), with the tool centre at `x_in` (the
/// X feed is started so that it is there whatever the instant). The
/// spindle angle at the injection is the fraction of a turn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inject {
    pub after_turns: f64,
    pub x_in: f64,
}

impl Default for Inject {
    /// The campaign's instant and radius.
    fn default() -> Self {
        Self {
            after_turns: 0.0,
            x_in: X_INJECT_IN,
        }
    }
}

/// What one simulated run left.
struct Run {
    /// The tool's largest departure into the part over the revolution
    /// before the injection, in (0: never below).
    before_rev_in: f64,
    /// The learned correction over that revolution.
    correction_before: CorrectionSpan,
    latched: Option<Fault>,
    trace: Vec<Sample>,
    t_inj: Nanos,
    t_end: Nanos,
    /// The host link (malformed-frame row).
    link: Option<Rc<RefCell<crate::fwrig::HostLink>>>,
    phase: Phase,
}

/// A force on the tool (+Z, out of the cut) through the cutter, piecewise
/// linear through `(ms after t0, lbf)` and stepped every 250 µs (the
/// cutter applies a force at loop ticks).
fn force_profile(
    burst: &mut OneShots<crate::fwrig::FirmwareWorld>,
    cutter: &Rc<RefCell<crate::cut::run::Cutter>>,
    t0: Nanos,
    points: &[(f64, f64)],
) {
    const STEP: Nanos = 250_000;
    let end_ms = points.last().map_or(0.0, |p| p.0);
    let steps = (end_ms * 1e6 / STEP as f64).round() as u64;
    for k in 0..=steps {
        let t_ms = k as f64 * STEP as f64 * 1e-6;
        let lbf = points
            .windows(2)
            .find(|w| t_ms >= w[0].0 && t_ms <= w[1].0)
            .map_or(0.0, |w| {
                w[0].1 + (w[1].1 - w[0].1) * (t_ms - w[0].0) / (w[1].0 - w[0].0)
            });
        let c = cutter.clone();
        burst.at(t0 + k * STEP, move |_, _| {
            c.borrow_mut().extra_force_lbf = lbf
        });
    }
}

/// Simulates `case` injected `at` (the malformed-frame row: `flood` is
/// what the host writes at the injection, `None` the undisturbed run with
/// the link idle).
fn simulate(
    spec: &CutSpec,
    case: Case,
    seed_index: u64,
    at: Inject,
    flood: Option<Vec<u8>>,
) -> anyhow::Result<Run> {
    let f = spec.feed_per_rev_in;
    let rev_s = 60.0 / spec.rpm;
    let t_inj: Nanos = if case.at_boot() {
        if at.after_turns != 0.0 {
            bail!(
                "{}: injected at boot or at arm, it has no instant in the cut ({} revolutions after the pre-roll asked)",
                case.name(),
                at.after_turns
            );
        }
        0
    } else {
        if !(at.after_turns >= 0.0 && at.after_turns.is_finite()) {
            bail!(
                "{}: the injection instant must be a finite number of revolutions ≥ 0 after the pre-roll ({} asked)",
                case.name(),
                at.after_turns
            );
        }
        ((PREROLL_REVS + at.after_turns) * rev_s * 1e9).round() as Nanos
    };
    if !(at.x_in > 0.0 && at.x_in <= X_MAX_IN) {
        bail!(
            "{}: the injection radius must lie in the contoured part, 0 < X ≤ {X_MAX_IN} in ({} in asked)",
            case.name(),
            at.x_in
        );
    }
    let feed_in_per_s = f / rev_s;
    // The tool centre reaches X_INJECT_IN (or, for the X fault, the first
    // half-mil below the table's first node) at the injection instant.
    let x_at_inj = if case == Case::XOutsideTable {
        0.2e-6
    } else {
        at.x_in
    };
    let x_start = x_at_inj + feed_in_per_s * t_inj as f64 * 1e-9;
    let st = Stretch {
        x_start_in: x_start,
        x_end_in: x_at_inj - 1.0,
        windows: vec![(x_at_inj - 0.01, x_start)],
        zone: vec![],
        index: seed_index,
        // The campaign's stretch engages onto the running cut.
        entry: crate::cut::run::Entry::InStock,
    };
    let mut spec = spec.clone();
    if case == Case::XOutsideTable {
        // The default table covers X = 0..7.2 in and the null zone lies
        // beyond it, so only a count below zero is outside it: the
        // interferometer count crossing the axis (the 1983 BCD counter
        // has no sign and would wrap, a jump: a glitch storm).
        use crate::machine::XInterface;
        if let XInterface::LegacyBcd(c) = &spec.scenario.machine.x {
            spec.scenario.machine.x = XInterface::Quadrature(c.clone());
        }
    }
    let table: &'static [u8] = if case == Case::CorruptTable {
        let mut t = zslide::DEFAULT_TABLE.to_vec();
        // A byte in the middle of the coefficients: only the CRC sees it.
        let k = t.len() / 2;
        t[k] ^= 0x10;
        Box::leak(t.into_boxed_slice())
    } else {
        zslide::DEFAULT_TABLE
    };
    let mut rig = build_stretch(&spec, &st, 0.0, table)?;
    let reset_at = Rc::new(Cell::new(None));
    rig.s.add(board::Iwdg::new(reset_at.clone()));
    let host_link = if case == Case::MalformedHostFrame {
        // From boot, as on the board.
        Some(crate::fwrig::link::attach(
            &mut rig.w,
            &mut rig.s,
            spec.scenario.loop_hz,
            spec.scenario.servo_design,
            zslide::params::ParamSource::BuiltIn,
        )?)
    } else {
        None
    };

    // One sample per loop-tick instant from BEFORE_NS before the injection.
    let samples: Rc<RefCell<Vec<Sample>>> = Rc::new(RefCell::new(Vec::new()));
    let before_rev = Rc::new(Cell::new(0.0f64));
    let correction_before = Rc::new(Cell::new((
        CorrectionSpan {
            least_in: f64::INFINITY,
            greatest_in: f64::NEG_INFINITY,
            largest_step_in: 0.0,
        },
        None,
    )));
    {
        let samples = samples.clone();
        let before_rev = before_rev.clone();
        let correction_before = correction_before.clone();
        let cutter = rig.cutter.clone();
        let t0 = t_inj.saturating_sub(BEFORE_NS);
        let t_rev = t_inj.saturating_sub((rev_s * 1e9).round() as Nanos);
        rig.s.on_event = Some(Box::new(move |t, k, w| {
            if k != src::LOOP_TICK || t < t_rev.min(t0) {
                return;
            }
            if t >= t_rev && t < t_inj {
                before_rev.set(before_rev.get().max(-cutter.borrow().last_error_in));
                let sv = w.fw.servo();
                let c_in = f64::from(sv.reference_q8() - (w.fw.command_code() << 8))
                    / 256.0
                    / CODES_PER_IN;
                let (mut span, last) = correction_before.get();
                span.take(c_in, last);
                correction_before.set((span, Some(c_in)));
            }
            if t < t0 {
                return;
            }
            let sv = w.fw.servo();
            samples.borrow_mut().push(Sample {
                t_ns: t,
                err_in: cutter.borrow().last_error_in,
                z_in: w.rig.slide.position_in(),
                command_in: f64::from(w.fw.command_code()) / CODES_PER_IN,
                reference_in: f64::from(sv.reference_q8()) / 256.0 / CODES_PER_IN,
                dac_v: w.rig.v_in,
                current_a: w.rig.slide.current_a(),
                force_lbf: w.rig.f_ext,
                velocity_in_s: w.rig.slide.velocity_in_s(),
                fault: w.fw.fault().is_some(),
                fault_disables: w
                    .fw
                    .fault()
                    .is_some_and(|f| f.reaction() == zslide::safety::Reaction::DisableAmplifier),
                amp_enabled: w.rig.amp.enabled(),
                enable_written: w.rig.enable.state.borrow().enable,
            });
        }));
    }

    let (w, s) = (&mut rig.w, &mut rig.s);
    s.run_until(w, t_inj);
    if !case.at_boot() {
        if let Some(f) = w.fw.fault() {
            bail!(
                "{}: the cut faulted before the injection ({f:?}: {})",
                case.name(),
                f.reason()
            );
        }
        let phase = w.fw.servo().phase();
        let revs = w.fw.learning().revolutions();
        if phase != Phase::Engaged || revs == 0 {
            bail!(
                "{}: the loop is not engaged and learning at the injection (phase {phase:?}, {revs} learned revolutions)",
                case.name()
            );
        }
    }
    if case == Case::ReversedGauge {
        // Rewired after the firmware was configured: it is not told.
        w.rig.gauge.params.reversed = true;
    }
    let spindle = w.machine.as_ref().map(|m| m.spindle.clone());
    let mut burst: OneShots<crate::fwrig::FirmwareWorld> = OneShots::new("injected", prio::X_EVENT);
    match case {
        Case::CorruptTable | Case::ReversedGauge | Case::XOutsideTable => {}
        Case::XGlitchStorm => {
            for k in 0..20 {
                burst.at(t_inj + k * 50_000, |_, w| w.x_event(false));
            }
        }
        Case::XBadBcd => {
            let latch = w
                .x_latch()
                .context("x-bad-bcd needs the legacy BCD X interface")?;
            let w0 = latch.0.get();
            // Flags toggled so the debounce lets it through; then the BCD
            // check sees the nibble.
            latch
                .0
                .set(XLatchWord((w0.0 ^ XLatchWord::HALF_MIL) & !0xF | 0xC));
            burst.at(t_inj, |_, w| w.x_event(false));
        }
        Case::IndexMissing => {
            if let Some(sp) = &spindle {
                sp.borrow_mut().model_mut().config_mut().index_loss_prob = 1.0;
            }
        }
        Case::IndexExtra => {
            if let Some(sp) = &spindle {
                sp.borrow_mut().model_mut().config_mut().index_noise_per_rev = 20.0;
            }
        }
        Case::SpindleSpeed => {
            if let Some(sp) = &spindle {
                sp.borrow_mut().model_mut().set_rpm(0.0);
            }
        }
        Case::GaugeSaturation => w.rig.gauge_injection_in = 0.02,
        Case::AdcBusError => {
            w.rig
                .adc
                .state
                .borrow_mut()
                .faults
                .random(1, 1.0, BusFault::StuckLow);
        }
        Case::DacBusError => {
            w.rig
                .dac
                .state
                .borrow_mut()
                .faults
                .random(1, 1.0, BusFault::Error);
        }
        // Beyond the loop's force (6 A × 2.9 lbf/A) for about 20 ms: the
        // slide is pushed out of the cut past the following-error limit
        // within ~8 ms, short of the gauge's range, and the push is gone
        // before the current limit has been held for its 20 ms.
        Case::FollowingError => force_profile(
            &mut burst,
            &rig.cutter,
            t_inj,
            &[(0.0, 0.0), (5.0, 20.0), (45.0, 0.0)],
        ),
        Case::FollowingErrorFast | Case::CurrentLimit => {
            let (lbf, dur) = if case == Case::FollowingErrorFast {
                // An output stage that can give only 4 A: the loop's own
                // 6 A estimate limit never engages, the slide is lost.
                w.rig.amp.params.current_limit_a = 4.0;
                w.rig.amp.params.trip_after_s = 10.0;
                (16.0, 30 * MS)
            } else {
                (18.0, 40 * MS)
            };
            let c = rig.cutter.clone();
            c.borrow_mut().extra_force_lbf = lbf;
            burst.at(t_inj + dur, move |_, _| {
                c.borrow_mut().extra_force_lbf = 0.0
            });
        }
        Case::AmplifierTrip => w.rig.amp.trip_now(),
        Case::StalledLoop => w.cpu = Cpu::LoopStalled,
        Case::Panic => board::panic(w),
        Case::EdgeForceX2 | Case::EdgeForceX4 => {
            let k = if case == Case::EdgeForceX2 { 2.0 } else { 4.0 };
            let c = rig.cutter.clone();
            burst.at(t_inj, move |_, _| {
                c.borrow_mut().engagement_mut().scale_edge_force(k)
            });
        }
        Case::GaugeFrozen => w.rig.gauge_frozen = true,
        Case::XCountStopped => {
            burst.at(t_inj, |_, w| w.hold_x());
        }
        Case::EngageRunning => {
            use zslide::firmware::Request;
            burst.at(t_inj, |_, w| w.request(Request::Disarm));
            burst.at(t_inj + REARM_NS, |_, w| w.request(Request::Arm));
        }
        Case::MalformedHostFrame => {
            if let (Some(bytes), Some(l)) = (flood, host_link.clone()) {
                burst.at(t_inj, move |_, _| l.borrow_mut().send(&bytes));
            }
        }
    }
    let (w, s) = (&mut rig.w, &mut rig.s);
    s.add(burst);
    let t_end = t_inj + case.observe_ns();
    s.run_until(w, t_end);

    // What the firmware (or the board model) latched.
    let latched = match case {
        Case::StalledLoop => reset_at.get().map(|_| Fault::Watchdog),
        // Seen, not assumed: the board model's handler must have halted
        // the core and the amplifier must see its enable low (the QEMU
        // image's real handler: `cargo xtask qemu`, fault paths).
        Case::Panic => (w.cpu == Cpu::Halted && !w.rig.amp.enabled()).then_some(Fault::Panic),
        _ => w.fw.fault(),
    };
    let trace = std::mem::take(&mut *samples.borrow_mut());
    Ok(Run {
        before_rev_in: before_rev.get(),
        correction_before: correction_before.get().0,
        latched,
        trace,
        t_inj,
        t_end,
        link: host_link,
        phase: w.fw.servo().phase(),
    })
}

/// The tool's largest departure into the part over `v`, µin.
fn into_part(v: &[&Sample]) -> f64 {
    v.iter().map(|x| -x.err_in).fold(0.0f64, f64::max).max(0.0) * 1e6
}

/// Runs one case at the campaign's instant; `seed_index` 0 is the
/// scenario's own seeds, others mix into every random stream (as the cut's
/// stretches do).
pub fn run_case(spec: &CutSpec, case: Case, seed_index: u64) -> anyhow::Result<Outcome> {
    run_case_at(spec, case, seed_index, Inject::default())
}

/// Runs one case injected `at`.
pub fn run_case_at(
    spec: &CutSpec,
    case: Case,
    seed_index: u64,
    at: Inject,
) -> anyhow::Result<Outcome> {
    if let Some(why) = case.not_applicable(spec) {
        return Ok(not_applicable(spec, case, why));
    }
    if case == Case::MalformedHostFrame {
        return run_link_case(spec, seed_index, at);
    }
    let Run {
        before_rev_in,
        correction_before,
        latched,
        trace,
        t_inj,
        t_end,
        phase,
        ..
    } = simulate(spec, case, seed_index, at, None)?;
    if latched.is_none() && (case.may_ride_out() || case == Case::EngageRunning) {
        return Ok(ridden_out(spec, case, before_rev_in, trace, t_inj, phase));
    }
    let reaction = latched.map(Fault::reaction);
    let retract_in = spec.scenario.servo_design.retract_z_in;
    let after: Vec<&Sample> = trace.iter().filter(|x| x.t_ns >= t_inj).collect();
    let safe = |x: &Sample| match reaction {
        Some(Reaction::RampToNull) => {
            x.amp_enabled && x.command_in == 0.0 && x.z_in.abs() <= NULL_HOLD_IN
        }
        Some(Reaction::DisableAmplifier) => !x.amp_enabled,
        // Out of the stock at the retract, the loop closed.
        Some(Reaction::Retract) => {
            x.amp_enabled
                && (x.command_in - retract_in).abs() * CODES_PER_IN <= 1.0
                && x.err_in > 0.0
        }
        None => false,
    };
    // The first sample from which the safe state holds to the end.
    let first_safe = after
        .iter()
        .rposition(|x| !safe(x))
        .map_or(0, |k| k + 1)
        .min(after.len());
    let safe_from = after.get(first_safe).map(|x| x.t_ns);
    let stays = safe_from.is_some_and(|t| t_end - t >= HOLD_NS);
    let reason = match latched {
        Some(f) if case.board_model() => {
            format!("{} [board model in host-sim, not in the core]", f.reason())
        }
        Some(f) => f.reason().to_string(),
        None => "not detected".to_string(),
    };
    Ok(Outcome {
        row: Row {
            fault: case.name(),
            injection: case.injection(),
            detected: Some(latched.is_some()),
            latched: latched.map(|f| format!("{f:?}")),
            reaction: reaction.map(|r| format!("{r:?}")),
            max_excursion_uin: Some(into_part(&after)),
            excursion_before_uin: (!case.at_boot()).then_some(before_rev_in.max(0.0) * 1e6),
            excursion_undisturbed_uin: None,
            safe_state: Some(stays),
            reason,
            time_to_safe_ms: safe_from
                .filter(|_| stays)
                .map(|t| (t - t_inj) as f64 * 1e-6),
            injected_at_s: Some(t_inj as f64 * 1e-9),
            link: None,
        },
        latched,
        trace,
        correction_before: (!case.at_boot()).then_some(correction_before),
    })
}

/// The row of a change of the cut that latched nothing: nothing was to
/// detect (`detected` none); safe when the loop is engaged at the end and
/// the tool never went deeper than the depth of cut.
fn ridden_out(
    spec: &CutSpec,
    case: Case,
    before_rev_in: f64,
    trace: Vec<Sample>,
    t_inj: Nanos,
    phase: Phase,
) -> Outcome {
    let after: Vec<&Sample> = trace.iter().filter(|x| x.t_ns >= t_inj).collect();
    let into = into_part(&after);
    let depth_uin = spec.depth_in * 1e6;
    let safe = phase == Phase::Engaged && into < depth_uin;
    Outcome {
        row: Row {
            fault: case.name(),
            injection: case.injection(),
            detected: None,
            latched: None,
            reaction: None,
            max_excursion_uin: Some(into),
            excursion_before_uin: Some(before_rev_in.max(0.0) * 1e6),
            excursion_undisturbed_uin: None,
            safe_state: Some(safe),
            reason: format!(
                "no fault latched: the loop {} the cut ({phase:?} at the end), the tool at most {into:.1} µin into the part against the {depth_uin:.0} µin depth of cut",
                if phase == Phase::Engaged { "rode out" } else { "did not ride out" }
            ),
            time_to_safe_ms: None,
            injected_at_s: Some(t_inj as f64 * 1e-9),
            link: None,
        },
        latched: None,
        trace,
        // Nothing ramped to null: no ramp's depth to bound.
        correction_before: None,
    }
}

/// The row of a case this machine cannot have: nothing injected, nothing
/// judged, the reason said.
fn not_applicable(spec: &CutSpec, case: Case, why: &str) -> Outcome {
    Outcome {
        row: Row {
            fault: case.name(),
            injection: case.injection(),
            detected: None,
            latched: None,
            reaction: None,
            max_excursion_uin: None,
            excursion_before_uin: None,
            excursion_undisturbed_uin: None,
            safe_state: None,
            reason: format!("not applicable on {}: {why}", spec.scenario.file.name),
            time_to_safe_ms: None,
            injected_at_s: None,
            link: None,
        },
        latched: None,
        trace: Vec::new(),
        correction_before: None,
    }
}

/// The malformed-frame row: the cut with the flood, and the same cut
/// (same seeds, the link attached and idle) without it. Detected: the
/// station refused and counted every malformed frame; safe: nothing of
/// the machine changed (no fault, the loop engaged, the tool's path
/// sample for sample the undisturbed run's) and the valid requests in the
/// flood were answered.
fn run_link_case(spec: &CutSpec, seed_index: u64, at: Inject) -> anyhow::Result<Outcome> {
    let case = Case::MalformedHostFrame;
    let fl = link::flood(seed_index);
    let run = simulate(spec, case, seed_index, at, Some(fl.bytes.clone()))?;
    let quiet = simulate(spec, case, seed_index, at, None)?;
    let l = run.link.as_ref().context("the link was attached")?;
    let judged = link::judge(&fl, &l.borrow());
    let after = |t: &[Sample]| -> f64 {
        let v: Vec<&Sample> = t.iter().filter(|x| x.t_ns >= run.t_inj).collect();
        into_part(&v)
    };
    let untouched = run.trace == quiet.trace;
    let unaffected = run.latched.is_none()
        && run.phase == Phase::Engaged
        && run.trace.last().is_some_and(|x| x.amp_enabled && !x.fault)
        && untouched;
    let c = &judged.counters;
    let reason = format!(
        "{}{} of {} malformed frames refused and counted (bad COBS {}, short/undecodable {}, bad CRC {}, other version {}, unknown command {}, oversize {}), {} empty counted; {} of {} valid requests answered, the status in mid-flood: {}, fault {}; {}",
        judged
            .first_refusal
            .as_deref()
            .map_or(String::new(), |r| format!("\"{r}\", … ")),
        judged.refused,
        judged.malformed_sent,
        c.bad_cobs,
        c.malformed,
        c.bad_crc,
        c.bad_version,
        c.unknown_command,
        c.oversize,
        c.empty,
        c.ok,
        judged.valid_sent,
        judged.status_phase.as_deref().unwrap_or("not answered"),
        judged.status_fault.as_deref().unwrap_or("-"),
        if untouched {
            format!(
                "the cut went on, sample for sample as without the flood (into the part {:.1} µin, without the flood {:.1})",
                after(&run.trace),
                after(&quiet.trace)
            )
        } else {
            "the cut's trace differs from the run without the flood".to_string()
        }
    );
    Ok(Outcome {
        row: Row {
            fault: case.name(),
            injection: case.injection(),
            detected: Some(judged.refused == judged.malformed_sent),
            latched: run.latched.map(|f| format!("{f:?}")),
            reaction: Some("Refusal::Frame".into()),
            max_excursion_uin: Some(after(&run.trace)),
            excursion_before_uin: Some(run.before_rev_in.max(0.0) * 1e6),
            excursion_undisturbed_uin: Some(after(&quiet.trace)),
            safe_state: Some(unaffected && judged.all_served()),
            reason,
            // The machine never left its state.
            time_to_safe_ms: (unaffected && judged.all_served()).then_some(0.0),
            injected_at_s: Some(run.t_inj as f64 * 1e-9),
            link: Some(judged),
        },
        latched: run.latched,
        trace: run.trace,
        correction_before: Some(run.correction_before),
    })
}

/// Runs `cases` at the campaign's instant.
pub fn campaign(spec: &CutSpec, cases: &[Case], seed_index: u64) -> anyhow::Result<Vec<Outcome>> {
    campaign_at(spec, cases, seed_index, Inject::default())
}

/// Runs `cases`, each injected `at`.
pub fn campaign_at(
    spec: &CutSpec,
    cases: &[Case],
    seed_index: u64,
    at: Inject,
) -> anyhow::Result<Vec<Outcome>> {
    let runs: Vec<(Case, Inject)> = cases.iter().map(|&c| (c, at)).collect();
    run_all(spec, &runs, seed_index)
}

/// Runs `case` injected at `phases` instants evenly spread over one
/// revolution after the pre-roll (phase k at k/`phases` of a turn): the
/// spindle angle, and with it the part's command and the cutting force, at
/// the injection.
pub fn sweep(
    spec: &CutSpec,
    case: Case,
    phases: usize,
    seed_index: u64,
) -> anyhow::Result<Vec<Outcome>> {
    sweep_at(spec, case, phases, seed_index, X_INJECT_IN)
}

/// [`sweep`] with the tool centre at `x_in`.
pub fn sweep_at(
    spec: &CutSpec,
    case: Case,
    phases: usize,
    seed_index: u64,
    x_in: f64,
) -> anyhow::Result<Vec<Outcome>> {
    if phases == 0 {
        bail!("a sweep needs at least one phase");
    }
    let runs: Vec<(Case, Inject)> = (0..phases)
        .map(|k| {
            let after_turns = k as f64 / phases as f64;
            (case, Inject { after_turns, x_in })
        })
        .collect();
    run_all(spec, &runs, seed_index)
}

/// Runs each (case, instant) in parallel, each on its own thread's
/// simulation.
fn run_all(
    spec: &CutSpec,
    runs: &[(Case, Inject)],
    seed_index: u64,
) -> anyhow::Result<Vec<Outcome>> {
    use rayon::prelude::*;
    runs.par_iter()
        .map(|&(c, at)| {
            run_case_at(spec, c, seed_index, at).with_context(|| {
                format!(
                    "fault {} injected {} revolutions after the pre-roll",
                    c.name(),
                    at.after_turns
                )
            })
        })
        .collect()
}
