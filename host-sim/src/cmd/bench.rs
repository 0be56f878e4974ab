//! `host-sim bench`: cost of the plant and of the simulation loop.
//!
//! * `plant_step_ns`: one exact ZOH step of the Z-slide model (5 states,
//!   cached discretisation) through the amplifier logic;
//! * `sim_second_wall_s`: wall time of one simulated second with a 20 kHz
//!   loop tick run by the scheduler: CNV, a 3-byte ADC read and a 3-byte
//!   DAC write through the core drivers on the simulated SPI chips, a
//!   stand-in proportional position controller, the
//!   plant advanced exactly between ticks, legacy gauge noise;
//! * `firmware_*`: the same with the firmware's `loop_tick`;
//! * `machine_*`: the whole machine of the scenario (`--scenario`): the
//!   integrated firmware (table, X and spindle entry points), the X
//!   interface and the spindle with their interrupts (`fwrig`).
//!
//! Run it in release: `cargo run --release -p host-sim -- bench --json`.

use crate::chips::{SimAd4020, SimAd5791, SimAmpEnablePin};
use crate::plant::{Rig, RigConfig};
use crate::sched::{prio, Periodic, Scheduler, World};
use embedded_hal::digital::OutputPin;
use std::time::Instant;
use zslide::drivers::ad4020::Ad4020;
use zslide::drivers::ad5791::Ad5791;
use zslide::hw::{AmplifierDac, GaugeAdc};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
    /// Simulated seconds for the loop benchmark.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Loop rate, Hz (default: the scenario's `loop.rate_hz`).
    #[arg(long)]
    pub loop_hz: Option<u64>,
    /// Also write a VCD trace of 250 ms of the whole machine on the
    /// scenario (positions, command, error, current, force, ADC and DAC
    /// codes, X and spindle angle true and as the firmware has them, loop
    /// tick / X event / index activity, amplifier enable, fault).
    #[arg(long)]
    pub vcd: Option<std::path::PathBuf>,
    /// Run only the whole-machine simulation (for profiling it, e.g. under
    /// `valgrind --tool=callgrind`), print its wall time and expm count.
    #[arg(long)]
    pub only_machine: bool,
    /// Plant, noise and machine of the firmware and whole-machine runs.
    #[command(flatten)]
    pub scenario: crate::scenario::ScenarioArg,
}

/// A stand-in digital controller on the simulated chips: proportional
/// position feedback in integer arithmetic through the core's converter
/// drivers (`zslide::drivers`). Not the firmware's controller; it exists to
/// exercise and time the simulation path without the firmware.
pub struct DemoLoop {
    pub adc: Ad4020<SimAd4020>,
    pub dac: Ad5791<SimAd5791>,
    pub enable: SimAmpEnablePin,
    /// DAC code per ADC code, Q16 (negative feedback applied in `tick`).
    pub kp_q16: i64,
    /// Per tick: (t ns, ADC code, DAC code); empty unless `record`.
    pub trace: Vec<(u64, i32, i32)>,
    pub record: bool,
    pub bus_errors: u64,
}

impl DemoLoop {
    /// Initialises the DAC (driver init: out of its power-on clamp, read
    /// back) and enables the amplifier.
    pub fn start(&mut self) {
        if self.dac.init().is_err() {
            self.bus_errors += 1;
        }
        let _ = self.enable.set_high();
    }

    pub fn tick(&mut self, now: u64, rig: &mut Rig) {
        rig.cnv();
        let code = match self.adc.read() {
            Ok(s) => s.code,
            Err(_) => {
                self.bus_errors += 1;
                return;
            }
        };
        let u = ((-i64::from(code) * self.kp_q16) >> 16).clamp(-(1 << 19), (1 << 19) - 1) as i32;
        if AmplifierDac::write(&mut self.dac, u).is_err() {
            self.bus_errors += 1;
        }
        if self.record {
            self.trace.push((now, code, u));
        }
    }
}

/// Rig plus stand-in controller.
pub struct DemoWorld {
    pub rig: Rig,
    pub ctl: DemoLoop,
}

impl World for DemoWorld {
    fn advance_to(&mut self, t: u64) {
        self.rig.advance_to(t);
    }
    fn set_time(&mut self, t: u64) {
        self.rig.time.set(t);
    }
}

/// Builds the rig, the stand-in loop and a scheduler with the loop tick.
/// Proportional gain 0.05 V/V (loop crossover ≈ 200 rad/s with the Model
/// 15 plant: stable with ≈ 50° margin).
pub fn demo(cfg: RigConfig, loop_hz: u64, record: bool) -> (DemoWorld, Scheduler<DemoWorld>) {
    let rig = Rig::new(cfg);
    let dev = rig.devices();
    let mut ctl = DemoLoop {
        adc: Ad4020::new(dev.gauge_adc),
        dac: Ad5791::new(dev.amp_dac),
        enable: dev.amp_enable,
        kp_q16: (0.05 * 65536.0) as i64,
        trace: Vec::new(),
        record,
        bus_errors: 0,
    };
    ctl.start();
    let mut s = Scheduler::new();
    let period = 1_000_000_000 / loop_hz;
    s.add(Periodic::new(
        "loop_tick",
        prio::LOOP_TICK,
        period,
        period,
        |t, w: &mut DemoWorld| w.ctl.tick(t, &mut w.rig),
    ));
    (DemoWorld { rig, ctl }, s)
}

#[derive(serde::Serialize, Debug)]
pub struct BenchResult {
    pub plant_step_ns: f64,
    pub rig_step_ns: f64,
    pub loop_hz: u64,
    pub simulated_s: f64,
    pub sim_second_wall_s: f64,
    pub real_time_factor: f64,
    /// The same with the firmware's `loop_tick` instead of the stand-in.
    pub firmware_sim_second_wall_s: f64,
    pub firmware_real_time_factor: f64,
    /// Scenario of the firmware and whole-machine runs.
    pub scenario: String,
    /// The whole machine: firmware loop tick through the core drivers, X
    /// interface (half-mil interrupts or quadrature count) and spindle
    /// (index interrupts, tachometer or encoder) of the scenario.
    pub machine_sim_second_wall_s: f64,
    pub machine_real_time_factor: f64,
    /// Events of the whole-machine run per simulated second, by source.
    pub machine_events_per_s: std::collections::BTreeMap<String, f64>,
    /// Fault latched in the whole-machine run, if any.
    pub machine_fault: Option<String>,
    /// One exact step of the 1983 analog loop closed around the plant
    /// (`AnalogClosedLoop`, 13 states), ns.
    pub analog_closed_loop_step_ns: f64,
    pub expm_computed: u64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let sc = args.scenario.load()?;
    let loop_hz = args.loop_hz.unwrap_or(u64::from(sc.loop_hz));
    anyhow::ensure!(
        args.seconds > 0.0 && loop_hz > 0,
        "need positive seconds and loop rate"
    );
    if let Some(path) = &args.vcd {
        crate::outpath::check_file("--vcd", path)?;
    }
    if args.only_machine {
        let (mut mw, mut ms) =
            crate::fwrig::machine_with(sc.rig.clone(), &sc.machine, loop_hz as u32, sc.servo);
        mw.request(zslide::firmware::Request::Arm);
        let t0 = Instant::now();
        ms.run_until(&mut mw, (args.seconds * 1e9) as u64);
        let wall = t0.elapsed().as_secs_f64();
        println!(
            "{{\"scenario\": \"{}\", \"machine_sim_second_wall_s\": {}, \"machine_real_time_factor\": {}, \"expm_computed\": {}, \"fault\": \"{:?}\"}}",
            sc.file.name,
            wall / args.seconds,
            args.seconds / wall,
            mw.rig.slide.expm_count(),
            mw.fw.fault()
        );
        return Ok(());
    }
    // One plant step.
    let mut slide = crate::plant::ZSlide::new(crate::plant::ZSlideParams::model15());
    let n = 2_000_000u64;
    let t0 = Instant::now();
    for k in 0..n {
        let e = if k & 1024 == 0 { 0.1 } else { -0.1 };
        slide.step(50_000, e, 0.0, false);
    }
    let plant_step_ns = t0.elapsed().as_nanos() as f64 / n as f64;
    std::hint::black_box(slide.x);
    // One rig step (amplifier logic + input-change bookkeeping).
    let mut rig = Rig::new(RigConfig::legacy(1));
    rig.amp.set_enabled(true);
    let t0 = Instant::now();
    for k in 1..=n {
        rig.v_in = if k & 1024 == 0 { 0.01 } else { -0.01 };
        rig.advance_to(k * 50_000);
    }
    let rig_step_ns = t0.elapsed().as_nanos() as f64 / n as f64;
    std::hint::black_box(rig.slide.x);
    // One simulated second at the loop rate.
    let (mut w, mut s) = demo(RigConfig::legacy(7), loop_hz, false);
    let t_end = (args.seconds * 1e9) as u64;
    let t0 = Instant::now();
    s.run_until(&mut w, t_end);
    let wall = t0.elapsed().as_secs_f64();
    let (mut fw, mut s) = firmware_demo(sc.rig.clone(), loop_hz as u32);
    fw.request(zslide::firmware::Request::Arm);
    let t0 = Instant::now();
    s.run_until(&mut fw, t_end);
    let fw_wall = t0.elapsed().as_secs_f64();
    anyhow::ensure!(
        fw.fw.fault().is_none(),
        "firmware faulted in the benchmark: {:?}",
        fw.fw.fault()
    );
    let (mut mw, mut ms) =
        crate::fwrig::machine_with(sc.rig.clone(), &sc.machine, loop_hz as u32, sc.servo);
    mw.request(zslide::firmware::Request::Arm);
    let t0 = Instant::now();
    ms.run_until(&mut mw, t_end);
    let machine_wall = t0.elapsed().as_secs_f64();
    // Interrupts the firmware actually took. The scheduler's per-source
    // counts would also include the X and spindle models' look-ahead
    // wake-ups, which are simulator work, not interrupts.
    let stats = mw
        .machine
        .as_ref()
        .map(|m| m.stats.clone())
        .unwrap_or_default();
    let loop_ticks = (0..ms.fired.len())
        .find(|&k| ms.source_name(k) == "loop_tick")
        .map_or(0, |k| ms.fired[k]);
    let machine_events_per_s = [
        ("loop_tick", loop_ticks),
        ("x_event", stats.x_events),
        ("index", stats.index_events),
    ]
    .into_iter()
    .map(|(name, n)| (name.to_string(), n as f64 / args.seconds))
    .collect();
    let mut cl = crate::analog1983::AnalogClosedLoop::legacy();
    let t0 = Instant::now();
    for k in 0..n / 4 {
        let r = if k & 1024 == 0 { 0.1 } else { -0.1 };
        cl.step(50_000, r, 0.0, 0.0);
    }
    let analog_closed_loop_step_ns = t0.elapsed().as_nanos() as f64 / (n / 4) as f64;
    std::hint::black_box(cl.position_in());
    let r = BenchResult {
        plant_step_ns,
        rig_step_ns,
        loop_hz,
        simulated_s: args.seconds,
        sim_second_wall_s: wall / args.seconds,
        real_time_factor: args.seconds / wall,
        firmware_sim_second_wall_s: fw_wall / args.seconds,
        firmware_real_time_factor: args.seconds / fw_wall,
        scenario: sc.file.name.clone(),
        machine_sim_second_wall_s: machine_wall / args.seconds,
        machine_real_time_factor: args.seconds / machine_wall,
        machine_events_per_s,
        machine_fault: mw.fw.fault().map(|f| format!("{f:?}")),
        analog_closed_loop_step_ns,
        expm_computed: w.rig.slide.expm_count(),
    };
    if let Some(path) = &args.vcd {
        write_vcd(path, loop_hz, &sc)?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        println!("plant step: {:.1} ns; rig step: {:.1} ns; one simulated second at {} Hz: {:.4} s wall ({:.0}x real time), with the firmware loop: {:.4} s ({:.0}x), whole machine ({}): {:.4} s ({:.0}x)", r.plant_step_ns, r.rig_step_ns, r.loop_hz, r.sim_second_wall_s, r.real_time_factor, r.firmware_sim_second_wall_s, r.firmware_real_time_factor, r.scenario, r.machine_sim_second_wall_s, r.machine_real_time_factor);
    }
    Ok(())
}

/// 250 ms of the whole machine as a VCD (the signal set of
/// [`crate::vcd::machine`]): the firmware's loop tick through the core
/// drivers, the scenario's X interface and spindle, engagement from 2 mil
/// off null, a 1.3 lbf cutting-force step at 120 ms (a finishing cut
/// engaging), a 1 mil target step at 150 ms. Returns what the X and spindle
/// handlers saw (the activity bits toggle once per handler run).
pub fn write_vcd(
    path: &std::path::Path,
    loop_hz: u64,
    sc: &crate::scenario::Scenario,
) -> anyhow::Result<crate::fwrig::MachineStats> {
    let (mut w, mut s) =
        crate::fwrig::machine_with(sc.rig.clone(), &sc.machine, loop_hz as u32, sc.servo);
    w.request(zslide::firmware::Request::Arm);
    w.rig.slide.x[crate::plant::zslide::st::Z] = 0.002;
    let mut o = crate::sched::OneShots::new("script", prio::PLANT_INPUT);
    o.at(120_000_000, |_, w: &mut FirmwareWorld| {
        w.rig.set_force_lbf(-1.3)
    });
    o.at(150_000_000, |_, w: &mut FirmwareWorld| {
        w.fw.set_target_code(1 << 16)
    });
    s.add(o);
    let (partial, file) =
        crate::outpath::Partial::create(path).map_err(|e| anyhow::anyhow!("--vcd {e:#}"))?;
    let tr = crate::vcd::machine::attach(&mut s, std::io::BufWriter::new(file), 0, u64::MAX)?;
    s.run_until(&mut w, 250_000_000);
    crate::vcd::machine::detach(&mut s, tr)?;
    partial.commit()?;
    Ok(w.stats().cloned().unwrap_or_default())
}

pub use crate::fwrig::{firmware_demo, FirmwareWorld};
