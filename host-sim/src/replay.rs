//! The runs recorded for the bit-exact replay on the emulated Cortex-M4F
//! (`zslide_replay`; `cargo xtask qemu` plays them in `boards/qemu`'s
//! `zslide-qemu-replay`): the whole machine of a scenario with the firmware
//! armed, every handler call logged frame by frame (`fwrig`'s taps).
//!
//! Together they cover both X interfaces (legacy BCD half-mil events with
//! the coefficient DACs written at each event, and the modern count read by
//! the X handler), both spindle sensors (tachometer and encoder), and
//! faults: a stuck gauge bus that latches `Bus(GaugeAdc)` and clamps the
//! DAC, then the operator's clear, disarm, clear and re-arm: the clear
//! releases the AD5791's clamp (zero code, control register, read-back)
//! and the re-arm's sign check and engagement run again. The loop is the
//! default design at the scenario's rate (a recording carries the rate,
//! and the target computes the same design).

use crate::chips::BusFault;
use crate::fwrig::{add_machine_sources, FirmwareWorld, WorldTick};
use crate::machine::xslide::{FeedSegment, XSlideConfig};
use crate::machine::{SpindleSensor, XInterface};
use crate::sched::{prio, Nanos, OneShots, Scheduler};
use anyhow::{bail, Context};
use zslide::firmware::Request;
use zslide::servo::ServoConfig;
use zslide_replay::record::Recorder;

/// One recorded run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Case {
    pub name: &'static str,
    pub scenario: &'static str,
    pub x: XKind,
    pub sensor: SpindleSensor,
    /// Legacy coefficient output (C00..C03 on the quad DAC, 4-term table).
    pub coefficient_output: bool,
    pub fault: bool,
    /// The part's interruption block given to the firmware
    /// ([`HOLES_AT_X`]), recorded with the run.
    pub holes: bool,
    pub duration_ns: Nanos,
}

/// The part of the runs that carry an interruption block: eight holes of
/// 0.5 in on a 3.0 in circle, where the runs cut (X from 3 in): the nose's
/// whole contact chord crosses every hole, so the edges' anticipation
/// learns its step at the crossings and feeds it to the tick.
pub fn holes_at_x() -> crate::plant::cutting::BoltHoles {
    crate::plant::cutting::BoltHoles {
        count: 8,
        circle_radius_in: 3.0,
        diameter_in: 0.5,
        phase_deg: 10.0,
        filled: false,
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum XKind {
    LegacyBcd,
    Count,
}

/// The runs `cargo xtask qemu` replays.
pub const CASES: [Case; 4] = [
    Case {
        name: "legacy-x-tach-coefficient-dacs",
        scenario: "legacy-hw",
        x: XKind::LegacyBcd,
        sensor: SpindleSensor::TachIndex,
        coefficient_output: true,
        fault: false,
        holes: false,
        duration_ns: 300_000_000,
    },
    Case {
        name: "modern-x-encoder",
        scenario: "modern-hw",
        x: XKind::Count,
        sensor: SpindleSensor::EncoderIndex,
        coefficient_output: false,
        fault: false,
        holes: false,
        duration_ns: 300_000_000,
    },
    Case {
        name: "legacy-x-encoder-gauge-bus-fault",
        scenario: "legacy-hw",
        x: XKind::LegacyBcd,
        sensor: SpindleSensor::EncoderIndex,
        coefficient_output: false,
        fault: true,
        holes: false,
        duration_ns: 300_000_000,
    },
    Case {
        name: "legacy-x-encoder-interruptions",
        scenario: "legacy-hw",
        x: XKind::LegacyBcd,
        sensor: SpindleSensor::EncoderIndex,
        coefficient_output: false,
        fault: false,
        holes: true,
        duration_ns: 300_000_000,
    },
];

/// What a recorded run did (for the report and the tests).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Recorded {
    pub name: &'static str,
    pub bytes: Vec<u8>,
    pub calls: usize,
    pub x_accepted: u64,
    pub index_events: u64,
    pub final_fault: Option<zslide::safety::Fault>,
    pub engaged: bool,
    /// Hole crossings the edges' anticipation learned its step at.
    pub edge_crossings: u32,
}

/// Records `case`.
pub fn record(case: &Case) -> anyhow::Result<Recorded> {
    let sc = crate::scenario::load(case.scenario)
        .with_context(|| format!("scenario {}", case.scenario))?;
    let mut machine = sc.machine.clone();
    // X from 3 in at 2 in/min: a half-mil event every 15 ms, the command
    // well inside the table (not in its null zone).
    let x = XSlideConfig {
        x0_in: 3.0,
        feed: vec![FeedSegment {
            t_start_s: 0.0,
            feed_in_per_min: 2.0,
        }],
        ..match &machine.x {
            XInterface::LegacyBcd(c) | XInterface::Quadrature(c) => c.clone(),
        }
    };
    machine.x = match case.x {
        XKind::LegacyBcd => XInterface::LegacyBcd(x),
        XKind::Count => XInterface::Quadrature(x),
    };
    machine.sensor = case.sensor;
    machine.coefficient_output = case.coefficient_output;
    let table = if case.coefficient_output {
        zslide::LEGACY4_TABLE
    } else {
        zslide::DEFAULT_TABLE
    };
    let loop_cfg = ServoConfig::at_rate(sc.loop_hz)
        .map_err(|e| anyhow::anyhow!("default loop at {} Hz: {e:?}", sc.loop_hz))?;

    let rec = Recorder::new(case.name);
    let mut w = FirmwareWorld::new_recording(sc.rig.clone(), loop_cfg, rec.clone());
    let mut s = Scheduler::new();
    s.add(WorldTick::loop_tick(1_000_000_000 / u64::from(sc.loop_hz)));
    w.attach_machine_with_table(&machine, table);
    if case.holes {
        let block = crate::cut::interruptions::block_of(&holes_at_x())?;
        w.set_interruptions(&block)
            .map_err(|e| anyhow::anyhow!("the firmware refused the interruption block: {e}"))?;
    }
    add_machine_sources(&w, &mut s);
    w.request(Request::Arm);
    if case.fault {
        let mut script = OneShots::new("faults", prio::PLANT_INPUT);
        // The gauge bus stuck high for five frames: Bus(GaugeAdc).
        script.at(120_000_000, |_, w: &mut FirmwareWorld| {
            w.rig
                .adc
                .state
                .borrow_mut()
                .faults
                .inject(BusFault::StuckHigh, 5);
        });
        // The operator clears, disarms, clears and arms again.
        script.at(150_000_000, |_, w: &mut FirmwareWorld| {
            w.request(Request::ClearFault)
        });
        script.at(160_000_000, |_, w: &mut FirmwareWorld| {
            w.request(Request::Disarm)
        });
        script.at(170_000_000, |_, w: &mut FirmwareWorld| {
            w.request(Request::ClearFault)
        });
        script.at(180_000_000, |_, w: &mut FirmwareWorld| {
            w.request(Request::Arm)
        });
        s.add(script);
    }
    s.run_until(&mut w, case.duration_ns);
    let bytes = rec.finish().map_err(anyhow::Error::msg)?;
    let stats = w.stats().cloned().unwrap_or_default();
    Ok(Recorded {
        name: case.name,
        bytes,
        calls: rec.calls(),
        x_accepted: stats.x_accepted,
        index_events: stats.index_events,
        final_fault: w.fw.fault(),
        engaged: w.fw.amplifier_enable(),
        edge_crossings: w.fw.edges().crossings_learned(),
    })
}

/// Every case, in one container (what the target's flash holds).
pub fn record_all() -> anyhow::Result<(Vec<u8>, Vec<Recorded>)> {
    record_cases(&CASES)
}

/// `cases`, in one container.
pub fn record_cases(cases: &[Case]) -> anyhow::Result<(Vec<u8>, Vec<Recorded>)> {
    let runs: Vec<Recorded> = cases.iter().map(record).collect::<anyhow::Result<_>>()?;
    let bytes: Vec<Vec<u8>> = runs.iter().map(|r| r.bytes.clone()).collect();
    let container = zslide_replay::container::build(&bytes);
    if container.len() > MAX_BYTES {
        bail!(
            "the recording is {} bytes, more than the {MAX_BYTES} the replay image reserves",
            container.len()
        );
    }
    Ok((container, runs))
}

/// The flash region `boards/qemu/memory.x` reserves for a recording.
pub const MAX_BYTES: usize = 1 << 20;
