//! `zslide identify` and `zslide tune`: the slide's frequency response
//! measured through the firmware's link, the plant model fitted to it
//! (`crate::fit`), and the loop's model parameters set from the fit.
//!
//! The measurement is a stepped sine. For each frequency the firmware adds
//! a sine to its DAC output from a loop tick the host states
//! (`Request::ExciteAt`: only while engaged at null, amplitude bounded by
//! the firmware), and captures whole windows of consecutive loop ticks
//! from ticks the host states (`Trigger::AtTick`: the DAC code u that
//! reached the amplifier and the gauge code y), the first once the loop
//! has settled. Which ticks are measured is the plan's, not the link's
//! timing: a request the firmware takes too late is refused as late, and
//! the next window (or a sine further ahead) is asked for. Each
//! frequency is a whole number of periods in the window (a bin of its
//! DFT), so one DFT bin of u and of y gives the response y/u with no
//! leakage from the sine itself. Repeated windows give the coherence and
//! the noise: the spread of the per-window responses.
//!
//! The sine is a disturbance of the closed loop, added after the servo;
//! y/u is the plant whatever the loop adds to u. Its amplitude at each
//! frequency aims the open plant's response at `--target-uin` of the data
//! sheet's model (the closed loop moves less below its bandwidth), capped
//! by the firmware's bound.

use std::io::Write;
use std::path::{Path, PathBuf};

use nalgebra::Complex;
use zslide::firmware::excite::ExciteError;
use zslide::link::proto::{
    CaptureState, FrameError, LoopPhase, Refusal, Reply, Request, Sample, Trigger,
};
use zslide::params;
use zslide::servo::design::DAC_CODES_PER_V;
use zslide::servo::ServoDesign;

use crate::client::{get, set, unexpected, Client, Link};
use crate::fields::read_fields;
use crate::fit::{self, Known, Plant, Point};
pub use crate::measured::Measured;
use crate::process::{self, Process};
use crate::report::say_to;
use crate::Result;

#[derive(clap::Args, Debug, Clone)]
pub struct IdentifyArgs {
    /// The data sheet's model (motor Kf, Kb, R, L; air film B; the mass,
    /// amplifier gain and mode to start from): a scenario name or file.
    #[arg(long, default_value = "legacy-hw")]
    pub scenario: String,
    /// Output stem: STEM.csv (the Bode data), STEM.plant (the fit, for
    /// `zslide tune`), STEM-mag.png / STEM-phase.png (+ .svg).
    #[arg(long, value_name = "STEM", default_value = "identify")]
    pub out: PathBuf,
    /// Slide motion aimed at, µin (amplitude of the model's response).
    #[arg(long, value_name = "UIN", default_value_t = 400.0)]
    pub target_uin: f64,
    /// Capture windows averaged per frequency below the mode band.
    #[arg(long, value_name = "N", default_value_t = 2)]
    pub repeats: u32,
    /// ... and in the mode band (where the response is a few µin).
    #[arg(long, value_name = "N", default_value_t = 6)]
    pub mode_repeats: u32,
    /// Settling time at each frequency before the first window, ms.
    #[arg(long, value_name = "MS", default_value_t = 60.0)]
    pub settle_ms: f64,
    /// No plot images (the CSV and the fit only).
    #[arg(long)]
    pub no_plot: bool,
    /// Measure the process instead, during a light test cut at null: the
    /// slide's response with the part engaged against the in-air fit
    /// AIR.plant (an earlier `identify`'s), the part's stiffness and
    /// damping from their difference. Writes STEM.csv and STEM.process
    /// (for `zslide tune --process`).
    #[arg(long, value_name = "AIR.plant", requires = "cut_depth")]
    pub in_cut: Option<PathBuf>,
    /// The test cut's depth of cut, µin: the excitation moves the tool by
    /// well under it (the in-air model's response aimed at an eighth).
    #[arg(long, value_name = "UIN", requires = "in_cut")]
    pub cut_depth: Option<f64>,
    /// Capture windows averaged per frequency in the cut (its motion is
    /// a few µin against the gauge's noise and the chip's force noise).
    #[arg(long, value_name = "N", default_value_t = 16)]
    pub cut_repeats: u32,
}

#[derive(clap::Args, Debug, Clone)]
pub struct TuneArgs {
    /// The fit `zslide identify` wrote (STEM.plant).
    pub plant: PathBuf,
    /// The data sheet `identify` was given (motor, gauge, board timing):
    /// with the fit, the plant the prediction runs on.
    #[arg(long, default_value = "legacy-hw")]
    pub scenario: String,
    /// The process `zslide identify --in-cut` measured (STEM.process):
    /// the design is also refused when its predicted margins at that
    /// stiffness, or at its two-sigma bounds, fall below the minimums.
    #[arg(long, value_name = "STEM.process")]
    pub process: Option<PathBuf>,
    /// Only print what would be set.
    #[arg(long)]
    pub dry_run: bool,
}

/// Excitations started at one frequency before `identify` gives up on a
/// link too slow to fit its windows in one.
const MAX_STARTS: u32 = 4;

/// How far ahead of the machine's tick count (as the status read it) the
/// sine's start tick is set, seconds, doubled at each new start: the
/// request's way to the loop tick (a few link polls) and back.
const START_LEAD_S: f64 = 0.02;

/// Capture window: the firmware's ring.
const WINDOW: usize = zslide::link::CAPTURE;

/// The DFT bin `k` of `x` over the window (amplitude-scaled).
fn bin(x: impl Iterator<Item = f64>, k: usize) -> Complex<f64> {
    let n = WINDOW as f64;
    let mut s = Complex::new(0.0, 0.0);
    for (i, v) in x.enumerate() {
        let a = -std::f64::consts::TAU * (k * i) as f64 / n;
        s += Complex::new(a.cos(), a.sin()) * v;
    }
    s * (2.0 / n)
}

/// The data sheet's model (the fit's fixed part and its start).
pub fn known_from_scenario(name: &str) -> Result<(Known, Plant)> {
    let sc = host_sim::scenario::load(name).map_err(|e| format!("--scenario {name}: {e:#}"))?;
    let slide = sc.rig.slide.clone();
    let mode = slide
        .mode
        .ok_or_else(|| format!("--scenario {name}: no [mode] to start the fit from"))?;
    let known = Known {
        slide: slide.clone(),
        gauge_v_per_in: sc.servo_design.slide.gauge_v_per_in,
        loop_hz: f64::from(sc.loop_hz),
    };
    let start = Plant {
        amp_gain: sc.rig.amplifier.gain,
        mass_lbf_s2_per_in: slide.mass_lbf_s2_per_in,
        mode_pole_hz: mode.pole_hz,
        mode_zero_hz: mode.zero_hz,
        mode_zeta: mode.zeta,
        delay_s: sc.rig.dac_latency_ns as f64 * 1e-9,
    };
    Ok((known, start))
}

/// The frequency bins measured: log-spaced below the mode band (skipping
/// the bins next to the 120 Hz hum), every second bin across it, and a few
/// above it up to the excitation's bound (a quarter of the loop rate:
/// 4.98 kHz at 20 kHz). The lowest is the window's first bin (19.5 Hz at
/// 20 kHz): the firmware's capture ring holds 1024 ticks.
pub fn bins(loop_hz: f64, start: &Plant) -> Vec<usize> {
    let df = loop_hz / WINDOW as f64;
    let hum = (120.0 / df).round() as usize;
    let lo = ((0.85 * start.mode_zero_hz) / df).floor() as usize;
    let hi = ((1.15 * start.mode_pole_hz) / df).ceil() as usize;
    let mut ks: Vec<usize> = [1, 2, 3, 4, 5, 8, 11, 16, 22, 32, 45, 64, 90]
        .into_iter()
        .filter(|&k: &usize| k.abs_diff(hum) > 1 && k < lo)
        .collect();
    ks.extend((lo..=hi).step_by(2).filter(|&k| k < WINDOW / 4));
    let top = WINDOW / 4 - 1;
    ks.extend(
        [hi + (top - hi) / 3, hi + 2 * (top - hi) / 3, top]
            .into_iter()
            .filter(|&k| k > hi + 1 && k <= top),
    );
    ks.dedup();
    ks
}

/// The in-cut measurement's bins: the window's first ten (19.5 .. 195 Hz
/// at 20 kHz), without the hum's: where the part's spring is a large
/// share of the slide's impedance (above, the mass hides it).
pub fn cut_bins(loop_hz: f64) -> Vec<usize> {
    let df = loop_hz / WINDOW as f64;
    let hum = (120.0 / df).round() as usize;
    (1..=10usize).filter(|k| k.abs_diff(hum) > 1).collect()
}

/// One frequency of a measurement: the bin, the sine's amplitude (DAC
/// codes) and the windows averaged.
#[derive(Clone, Copy, Debug)]
pub struct Plan {
    pub k: usize,
    pub amplitude: u32,
    pub repeats: u32,
}

/// The in-air plan: each bin's amplitude aims the model's response at
/// `target_uin`, capped by the firmware's bound.
fn plan(
    ks: &[usize],
    loop_hz: f64,
    known: &Known,
    p: &Plant,
    target_uin: f64,
    repeats: impl Fn(f64) -> u32,
) -> Vec<Plan> {
    let codes_per_uin = known.gauge_v_per_in * DAC_CODES_PER_V * 1e-6;
    ks.iter()
        .map(|&k| {
            let f_hz = k as f64 * loop_hz / WINDOW as f64;
            let h_nom = known.response(p, f_hz).norm();
            let max = zslide::firmware::excite::max_amplitude_codes(f_hz);
            Plan {
                k,
                amplitude: ((target_uin * codes_per_uin / h_nom) as u32).clamp(1, max),
                repeats: repeats(f_hz).max(2),
            }
        })
        .collect()
}

/// Stops the sine.
fn stop_excitation(c: &mut Client) -> Result<()> {
    match c.call(&Request::Excite {
        step: 0,
        amplitude: 0,
        ticks: 0,
    })? {
        Reply::Exciting { .. } => Ok(()),
        r => Err(unexpected(&r)),
    }
}

/// Starts the sine with its phase 0 on loop tick `at`; `None` when the
/// firmware took the request on or after that tick (a late arm).
fn excite_at(
    c: &mut Client,
    step: u32,
    amplitude: u32,
    ticks: u32,
    at: u32,
) -> Result<Option<u32>> {
    match c.call(&Request::ExciteAt {
        step,
        amplitude,
        ticks,
        at,
    })? {
        Reply::Exciting { tick, .. } if tick == at => Ok(Some(tick)),
        Reply::Refused(Refusal::Excite(ExciteError::StartTick { .. })) => Ok(None),
        Reply::Refused(Refusal::Frame(FrameError::UnknownCommand(_))) => Err(
            "this firmware has no excitation anchored to a loop tick (link command ExciteAt): \
             identify needs it to capture exactly the planned ticks; update the firmware"
                .into(),
        ),
        r => Err(unexpected(&r)),
    }
}

/// One capture window from loop tick `at`: its samples, or `None` when
/// the firmware armed it after that tick (a late arm).
fn window_at(c: &mut Client, at: u32) -> Result<Option<Vec<Sample>>> {
    match c.call(&Request::CaptureStart {
        samples: WINDOW as u16,
        pre: 0,
        trigger: Trigger::AtTick { tick: at },
    })? {
        Reply::Capture(_) => {}
        r => return Err(unexpected(&r)),
    }
    loop {
        let info = c.capture_info()?;
        match info.state {
            CaptureState::Late => return Ok(None),
            CaptureState::Done => {
                if usize::from(info.recorded) != WINDOW || info.trigger_tick != at {
                    return Err(format!(
                        "the capture armed for tick {at} recorded {} samples from tick {}, \
                         not {WINDOW} from {at}",
                        info.recorded, info.trigger_tick
                    ));
                }
                return Ok(Some(c.capture_read(info.recorded)?));
            }
            // No pause of its own: each request's round trip (a link
            // poll on a board, a machine step on a simulated one) paces
            // the polling, and on a machine in lockstep a pause would
            // only cost wall-clock time.
            _ => {}
        }
    }
}

/// Checks that the machine is engaged at null with the model's loop
/// rate; returns the rate.
fn check_machine(c: &mut Client, known: &Known) -> Result<f64> {
    let st = c.status()?;
    if st.state.phase != LoopPhase::Engaged || st.state.fault.is_some() || !st.state.null_command {
        return Err(
            "identify needs the loop armed, engaged and at null (no fault, X outside the table): \
             `zslide link arm` with X outside the table, then `zslide link status`"
                .into(),
        );
    }
    let loop_hz = f64::from(st.loop_hz);
    if (loop_hz - known.loop_hz).abs() > 0.5 {
        return Err(format!(
            "the machine's loop runs at {loop_hz} Hz, the model's at {} Hz",
            known.loop_hz
        ));
    }
    Ok(loop_hz)
}

/// Measures the response at the bins of `plan`.
pub fn measure(
    c: &mut Client,
    plan: &[Plan],
    loop_hz: f64,
    settle_ms: f64,
    out: &mut dyn Write,
) -> Result<Vec<Measured>> {
    let settle = (settle_ms * 1e-3 * loop_hz) as u32;
    let mut res = Vec::new();
    for &Plan {
        k,
        amplitude,
        repeats,
    } in plan
    {
        let f_hz = k as f64 * loop_hz / WINDOW as f64;
        let step = (k as u64 * (1u64 << 32) / WINDOW as u64) as u32;
        // Long enough for the settling and the windows with their reads
        // (a read takes about a window's ticks more on a simulated link).
        let ticks = ((settle + 12 * WINDOW as u32 * repeats) as f64)
            .min(zslide::firmware::excite::EXCITE_MAX_S * loop_hz) as u32;
        // The sine starts on a stated loop tick, `lead` ahead of the
        // status's count, and each window is captured from a stated tick:
        // the settled sine's next whole window, one after another. So the
        // ticks measured are the plan's, whenever the host's requests
        // arrive; a window (or a sine) the firmware took too late is not
        // recorded (it says so), and the next one is asked for (the sine
        // again, further ahead). Each window's DFT bins are turned back by
        // the sine's phase at its first tick: the windows then average
        // coherently, u and y alike, so the noise the loop feeds back from
        // y into u averages out of the ratio instead of biasing it.
        let mut uy: Vec<(Complex<f64>, Complex<f64>)> = Vec::new();
        let mut starts = 0;
        'sine: while uy.len() < repeats as usize {
            starts += 1;
            if starts > MAX_STARTS {
                stop_excitation(c)?;
                return Err(format!(
                    "{f_hz:.1} Hz: {MAX_STARTS} excitations of {ticks} ticks each ended before \
                     {repeats} capture windows were taken in them: the link is too slow against \
                     the machine's loop"
                ));
            }
            let lead = ((START_LEAD_S * loop_hz) as u32) << (starts - 1);
            let now = c.status()?.state.ticks;
            let Some(start) = excite_at(c, step, amplitude, ticks, now.wrapping_add(lead))? else {
                continue;
            };
            let mut since = settle;
            while uy.len() < repeats as usize {
                if u64::from(since) + WINDOW as u64 > u64::from(ticks) {
                    continue 'sine;
                }
                let at = start.wrapping_add(since);
                since += WINDOW as u32;
                let Some(w) = window_at(c, at)? else {
                    continue;
                };
                let turns = ((u64::from(step) * u64::from(at.wrapping_sub(start))) & 0xFFFF_FFFF)
                    as f64
                    / 4_294_967_296.0;
                let back = Complex::from_polar(1.0, -std::f64::consts::TAU * turns);
                let u = bin(w.iter().map(|s| f64::from(s.output)), k);
                let y = bin(w.iter().map(|s| f64::from(s.position)), k);
                uy.push((u * back, y * back));
            }
        }
        stop_excitation(c)?;
        let (mut su, mut sy, mut suy, mut suu, mut syy) = (
            Complex::new(0.0, 0.0),
            Complex::new(0.0, 0.0),
            Complex::new(0.0, 0.0),
            0.0,
            0.0,
        );
        for &(u, y) in &uy {
            su += u;
            sy += y;
            suy += u.conj() * y;
            suu += u.norm_sqr();
            syy += y.norm_sqr();
        }
        let hs: Vec<Complex<f64>> = uy.iter().map(|&(u, y)| y / u).collect();
        let h = sy / su;
        let coherence = suy.norm_sqr() / (suu * syy);
        let n = hs.len() as f64;
        let spread = (hs.iter().map(|x| (x / h - 1.0).norm_sqr()).sum::<f64>() / (n - 1.0)).sqrt();
        // Two windows estimate a spread poorly: never trust one below the
        // coherence's own figure.
        let from_coh = ((1.0 - coherence).max(0.0) / (coherence * n)).sqrt();
        let m = Measured {
            f_hz,
            h,
            coherence,
            rel_sigma: (spread / n.sqrt()).max(from_coh).max(1e-3),
            amplitude_v: f64::from(amplitude) / DAC_CODES_PER_V,
        };
        say_to(
            out,
            &format!(
                "{:7.1} Hz  {:7.2} dB {:7.1} deg  coherence {:.3}  ({:.3} V, {} windows)",
                f_hz,
                20.0 * h.norm().log10(),
                h.arg().to_degrees(),
                coherence,
                m.amplitude_v,
                repeats
            ),
        )?;
        res.push(m);
    }
    Ok(res)
}

/// The fit's file: `name = value` lines.
pub fn plant_text(p: &Plant, scenario: &str) -> String {
    format!(
        "# zslide identify: the plant fitted to the measured response (data sheet: {scenario})\n\
         amp_gain = {}\nmass_lbf_s2_per_in = {}\nmode_pole_hz = {}\nmode_zero_hz = {}\n\
         mode_zeta = {}\ndelay_s = {}\n",
        p.amp_gain, p.mass_lbf_s2_per_in, p.mode_pole_hz, p.mode_zero_hz, p.mode_zeta, p.delay_s
    )
}

/// Reads [`plant_text`]'s file; every field is required, nothing else is
/// accepted.
pub fn read_plant(path: &Path) -> Result<Plant> {
    let mut v = read_fields(path)?;
    let mut take = |k: &str| {
        v.remove(k)
            .ok_or_else(|| format!("{}: no {k}", path.display()))
    };
    let p = Plant {
        amp_gain: take("amp_gain")?,
        mass_lbf_s2_per_in: take("mass_lbf_s2_per_in")?,
        mode_pole_hz: take("mode_pole_hz")?,
        mode_zero_hz: take("mode_zero_hz")?,
        mode_zeta: take("mode_zeta")?,
        delay_s: take("delay_s")?,
    };
    if let Some(k) = v.keys().next() {
        return Err(format!("{}: unknown field {k}", path.display()));
    }
    Ok(p)
}

/// Phases in degrees made continuous: each differs from the one before
/// by less than 180° (the model's curve, dense enough for that to hold).
pub fn unwrap_deg(wrapped: impl IntoIterator<Item = f64>) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for p in wrapped {
        let v = match out.last() {
            Some(&prev) => p + 360.0 * ((prev - p) / 360.0).round(),
            None => p,
        };
        out.push(v);
    }
    out
}

/// `phase` (deg) moved by whole turns to lie within 180° of `near`.
fn turn_to(phase: f64, near: f64) -> f64 {
    phase + 360.0 * ((near - phase) / 360.0).round()
}

/// The measured phases, and the model's at the same frequencies, on the
/// branch of the model's unwrapped curve (continuous, where the measured
/// points are too sparse across the mode to unwrap among themselves).
fn measured_phases(ms: &[Measured], known: &Known, p: &Plant) -> (Vec<f64>, Vec<f64>) {
    let dense = model_curve(known, p, ms.first().map_or(15.0, |m| m.f_hz));
    ms.iter()
        .map(|m| {
            let near = dense
                .iter()
                .min_by(|a, b| (a.0 - m.f_hz).abs().total_cmp(&(b.0 - m.f_hz).abs()))
                .map_or(0.0, |&(_, (_, ph))| ph);
            let model = turn_to(known.response(p, m.f_hz).arg().to_degrees(), near);
            (turn_to(m.h.arg().to_degrees(), model), model)
        })
        .unzip()
}

/// The model's response from `f_lo` to the excitation's top (5 kHz),
/// 400 log-spaced points: (f, (dB, unwrapped deg)).
fn model_curve(known: &Known, p: &Plant, f_lo: f64) -> Vec<(f64, (f64, f64))> {
    let f_lo = f_lo.min(4000.0);
    let fs: Vec<f64> = (0..400)
        .map(|i| f_lo * (5000.0 / f_lo).powf(f64::from(i) / 399.0))
        .collect();
    let hs: Vec<Complex<f64>> = fs.iter().map(|&f| known.response(p, f)).collect();
    let ph = unwrap_deg(hs.iter().map(|h| h.arg().to_degrees()));
    fs.into_iter()
        .zip(hs)
        .zip(ph)
        .map(|((f, h), ph)| (f, (20.0 * h.norm().log10(), ph)))
        .collect()
}

/// Below it a measured point is drawn as suspect (hollow, red): half its
/// power or more is noise.
pub const COHERENCE_MIN: f64 = 0.5;

fn write_csv(path: &Path, ms: &[Measured], known: &Known, p: &Plant) -> Result<()> {
    let (phase, model_phase) = measured_phases(ms, known, p);
    let mut s = String::from(
        "f_hz,mag_db,phase_deg,coherence,rel_sigma,excitation_v,model_mag_db,model_phase_deg\n",
    );
    for (k, m) in ms.iter().enumerate() {
        let h = known.response(p, m.f_hz);
        s += &format!(
            "{:.3},{:.4},{:.3},{:.5},{:.5},{:.4},{:.4},{:.3}\n",
            m.f_hz,
            20.0 * m.h.norm().log10(),
            phase[k],
            m.coherence,
            m.rel_sigma,
            m.amplitude_v,
            20.0 * h.norm().log10(),
            model_phase[k]
        );
    }
    crate::write_file(path, s)
}

/// STEM-mag and STEM-phase (.svg, .png): each over the coherence, on a
/// logarithmic axis in Hz, phases unwrapped.
pub fn write_plots(stem: &Path, ms: &[Measured], known: &Known, p: &Plant) -> Result<()> {
    use host_sim::plot::{write_bode, BodePoint};
    let dir = stem
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = stem
        .file_name()
        .map_or("identify".into(), |n| n.to_string_lossy().into_owned());
    let model = model_curve(known, p, ms.first().map_or(15.0, |m| m.f_hz * 0.9));
    let (phase, _) = measured_phases(ms, known, p);
    let mag: Vec<f64> = ms.iter().map(|m| 20.0 * m.h.norm().log10()).collect();
    for (suffix, label, ys, line) in [
        (
            "mag",
            "gauge/DAC (dB)",
            &mag,
            model
                .iter()
                .map(|&(f, (db, _))| (f, db))
                .collect::<Vec<_>>(),
        ),
        (
            "phase",
            "phase (deg, unwrapped)",
            &phase,
            model.iter().map(|&(f, (_, ph))| (f, ph)).collect(),
        ),
    ] {
        let pts: Vec<BodePoint> = ms
            .iter()
            .zip(ys)
            .map(|(m, &value)| BodePoint {
                f_hz: m.f_hz,
                value,
                coherence: m.coherence,
            })
            .collect();
        write_bode(
            dir,
            &format!("{name}-{suffix}"),
            "zslide identify: measured (points) and fitted (line)",
            label,
            &pts,
            &line,
            COHERENCE_MIN,
        )
        .map_err(|e| format!("{e:#}"))?;
    }
    Ok(())
}

/// What `zslide identify` measured: the plant in air, or the process.
pub enum Identified {
    Air(fit::Fit),
    Process(Process),
}

/// `zslide identify`: measure, fit, write.
pub fn identify(link: &mut Link, a: &IdentifyArgs, out: &mut dyn Write) -> Result<Identified> {
    match &a.in_cut {
        Some(air) => in_cut(link, a, air, out).map(Identified::Process),
        None => in_air(link, a, out).map(Identified::Air),
    }
}

/// The in-cut measurement (`--in-cut`): the response at [`cut_bins`],
/// the process from it against the in-air fit (`crate::process`).
fn in_cut(
    link: &mut Link,
    a: &IdentifyArgs,
    air_path: &Path,
    out: &mut dyn Write,
) -> Result<Process> {
    let (known, _) = known_from_scenario(&a.scenario)?;
    let air = read_plant(air_path)?;
    let depth_uin = a.cut_depth.ok_or("--in-cut needs --cut-depth")?;
    if !(depth_uin.is_finite() && depth_uin > 0.0) {
        return Err(format!(
            "--cut-depth {depth_uin}: need a depth of cut > 0 uin"
        ));
    }
    let stem = a.out.clone();
    let csv = stem.with_extension("csv");
    let file = stem.with_extension("process");
    for p in [&csv, &file] {
        host_sim::outpath::check_file("--out", p).map_err(|e| format!("{e:#}"))?;
    }
    let c = link.client()?;
    let loop_hz = check_machine(c, &known)?;
    // An eighth of the depth in the in-air model: the part's spring only
    // lowers the response below its own frequency and raises it at most
    // by its damping's resonance (×1.7 at legacy-hw's air film and
    // 2200 lbf/in), and the closed loop moves the slide less than the
    // open plant: the tool stays in the stock, where the force model is
    // smooth (its curvature biases the slope by (3/32)(a/d)², 0.4 % at
    // a quarter of the depth).
    let ks = cut_bins(loop_hz);
    let pl = plan(&ks, loop_hz, &known, &air, depth_uin / 8.0, |_| {
        a.cut_repeats
    });
    let ms = measure(c, &pl, loop_hz, a.settle_ms, out)?;
    let pts: Vec<process::PointEstimate> = ms
        .iter()
        .map(|m| process::at_point(&known, &air, m))
        .collect::<Result<_>>()?;
    let p = process::combine(&pts)?;
    let mut text = String::from(
        "f_hz,mag_db,phase_deg,coherence,rel_sigma,excitation_v,air_mag_db,stiffness_lbf_per_in,\
         stiffness_sigma,damping_lbf_s_per_in,damping_sigma\n",
    );
    for (m, e) in ms.iter().zip(&pts) {
        let h0 = known.response(&air, m.f_hz);
        text += &format!(
            "{:.3},{:.4},{:.3},{:.5},{:.5},{:.4},{:.4},{:.1},{:.1},{:.4},{:.4}\n",
            m.f_hz,
            20.0 * m.h.norm().log10(),
            m.h.arg().to_degrees(),
            m.coherence,
            m.rel_sigma,
            m.amplitude_v,
            20.0 * h0.norm().log10(),
            e.k,
            e.cov[(0, 0)].sqrt(),
            e.c,
            e.cov[(1, 1)].sqrt()
        );
    }
    crate::write_file(&csv, text)?;
    crate::write_file(&file, process::process_text(&p, air_path))?;
    for line in [
        format!(
            "process ({} frequencies against {}, chi2 per degree of freedom {:.2}):",
            pts.len(),
            air_path.display(),
            p.chi2
        ),
        format!(
            "  stiffness  {:.0} lbf/in  ± {:.0} (1 sigma)",
            p.stiffness_lbf_per_in, p.stiffness_sigma
        ),
        format!(
            "  damping    {:.3} lbf s/in  ± {:.3} (1 sigma)",
            p.damping_lbf_s_per_in, p.damping_sigma
        ),
        format!("wrote {}, {}", csv.display(), file.display()),
    ] {
        say_to(out, &line)?;
    }
    Ok(p)
}

/// The in-air measurement and fit.
fn in_air(link: &mut Link, a: &IdentifyArgs, out: &mut dyn Write) -> Result<fit::Fit> {
    let (known, start) = known_from_scenario(&a.scenario)?;
    let stem = a.out.clone();
    let csv = stem.with_extension("csv");
    // Every output path is checked before the machine is touched; each
    // file is replaced only when its new contents are whole.
    for p in [&csv, &stem.with_extension("plant")] {
        host_sim::outpath::check_file("--out", p).map_err(|e| format!("{e:#}"))?;
    }
    let c = link.client()?;
    let loop_hz = check_machine(c, &known)?;
    let pl = plan(
        &bins(loop_hz, &start),
        loop_hz,
        &known,
        &start,
        a.target_uin,
        |f_hz| {
            if f_hz >= 0.85 * start.mode_zero_hz {
                a.mode_repeats
            } else {
                a.repeats
            }
        },
    );
    let ms = measure(c, &pl, loop_hz, a.settle_ms, out)?;
    let pts: Vec<Point> = ms
        .iter()
        .map(|m| Point {
            f_hz: m.f_hz,
            h: m.h,
            rel_sigma: m.rel_sigma,
        })
        .collect();
    let f = fit::fit(&known, &pts, &start)?;
    let p = &f.plant;
    write_csv(&csv, &ms, &known, p)?;
    crate::write_file(&stem.with_extension("plant"), plant_text(p, &a.scenario))?;
    if !a.no_plot {
        write_plots(&stem, &ms, &known, p)?;
    }
    let rel = |x: f64, x0: f64| 100.0 * (x / x0 - 1.0);
    let s = &f.rel_sigma;
    for line in [
        format!(
            "fit ({} points, {} iterations, weighted rms residual {:.2}):",
            ms.len(),
            f.iterations,
            f.rms_weighted
        ),
        format!(
            "  amplifier gain  {:.4} V/V          ({:+.1} % of the data sheet, ±{:.2} %)",
            p.amp_gain,
            rel(p.amp_gain, start.amp_gain),
            100.0 * s[0]
        ),
        format!(
            "  moving mass     {:.6} lbf s^2/in ({:+.1} %, ±{:.2} %)",
            p.mass_lbf_s2_per_in,
            rel(p.mass_lbf_s2_per_in, start.mass_lbf_s2_per_in),
            100.0 * s[1]
        ),
        format!(
            "  mode pole       {:.1} Hz          ({:+.1} %, ±{:.2} %), damping {:.4} (±{:.0} %)",
            p.mode_pole_hz,
            rel(p.mode_pole_hz, start.mode_pole_hz),
            100.0 * s[2],
            p.mode_zeta,
            100.0 * s[4]
        ),
        format!(
            "  mode zero       {:.1} Hz          ({:+.1} %, ±{:.2} %)",
            p.mode_zero_hz,
            rel(p.mode_zero_hz, start.mode_zero_hz),
            100.0 * s[3]
        ),
        format!("  DAC delay       {:.2} us", p.delay_s * 1e6),
        format!(
            "wrote {}, {}{}",
            csv.display(),
            stem.with_extension("plant").display(),
            if a.no_plot {
                String::new()
            } else {
                format!(", {0}-mag.png, {0}-phase.png", stem.display())
            }
        ),
    ] {
        say_to(out, &line)?;
    }
    Ok(f)
}

/// The parameters `tune` sets from a fit: the loop's model of the slide
/// (its mass and the amplifier's gain) and the mode notch on the fitted
/// mode.
pub fn tuned(p: &Plant) -> [(&'static str, f64); 3] {
    [
        ("mass_lbf_s2_per_in", p.mass_lbf_s2_per_in),
        ("amp_gain", p.amp_gain),
        ("mode_notch_hz", p.mode_pole_hz),
    ]
}

/// The design the machine runs now, read parameter by parameter.
pub fn design_on(c: &mut Client) -> Result<ServoDesign> {
    let loop_hz = c.status()?.loop_hz;
    let mut d = ServoDesign::brief(loop_hz);
    for p in params::PARAMS.iter() {
        p.set(&mut d, get(c, p.id)?);
    }
    Ok(d)
}

/// `zslide tune`: the loop's model from the fit, designed by the
/// firmware's own design code (checked here first, then by the firmware on
/// each set), set on the machine while disarmed.
pub fn tune(link: &mut Link, a: &TuneArgs, out: &mut dyn Write) -> Result<ServoDesign> {
    let plant = read_plant(&a.plant)?;
    let in_cut = a
        .process
        .as_deref()
        .map(process::read_process)
        .transpose()?;
    let c = link.client()?;
    let mut d = design_on(c)?;
    let before = d;
    for (name, v) in tuned(&plant) {
        let p = params::by_name(name).ok_or_else(|| format!("no parameter {name}"))?;
        if !(p.min..=p.max).contains(&v) {
            return Err(format!(
                "{}: {name} = {v} is outside its limits {} .. {} {}: the fit is not a slide this \
                 firmware can run",
                a.plant.display(),
                p.min,
                p.max,
                p.unit
            ));
        }
        p.set(&mut d, v);
    }
    d.config().map_err(|e| {
        format!(
            "the design from {} is refused: {}",
            a.plant.display(),
            d.refusal(e)
        )
    })?;
    for (name, v) in tuned(&plant) {
        let p = params::by_name(name).ok_or_else(|| format!("no parameter {name}"))?;
        say_to(
            out,
            &format!(
                "{name:<22} {:>12.6} -> {v:>12.6} {}",
                p.get(&before),
                p.unit
            ),
        )?;
    }
    let data_sheet = host_sim::scenario::load(&a.scenario)
        .map_err(|e| format!("--scenario {}: {e:#}", a.scenario))?;
    say_to(
        out,
        &format!(
            "predicted on the fitted plant (data sheet {}; the simulated firmware of \
             `host-sim response --loop digital` and `track`):",
            a.scenario
        ),
    )?;
    let now = crate::predict::predict(&data_sheet, &plant, &before)?;
    let after = crate::predict::predict(&data_sheet, &plant, &d)?;
    for line in crate::predict::table(&now, &after) {
        say_to(out, &line)?;
    }
    crate::predict::check_margins(&after.margins).map_err(|e| {
        format!(
            "the design from {} is refused: {e} (nothing set)",
            a.plant.display()
        )
    })?;
    if let (Some(path), Some(pr)) = (&a.process, in_cut) {
        say_to(
            out,
            &format!(
                "predicted in the cut ({}: {:.0} ± {:.0} lbf/in; the tuned design at it and at \
                 its two-sigma bounds):",
                path.display(),
                pr.stiffness_lbf_per_in,
                pr.stiffness_sigma
            ),
        )?;
        for k in process::stiffnesses_checked(&pr) {
            let m = crate::predict::margins_in_cut(&data_sheet, &plant, &d, k)?;
            say_to(
                out,
                &format!(
                    "  at {k:>6.0} lbf/in: crossover (Hz) {}, phase margin (deg) {}, gain margin (dB) {}",
                    host_sim::cmd::response::fmt_opt(m.crossover_hz, 1),
                    host_sim::cmd::response::fmt_opt(m.phase_margin_deg, 1),
                    host_sim::cmd::response::fmt_opt(m.gain_margin_db, 1)
                ),
            )?;
            crate::predict::check_margins(&m).map_err(|e| {
                format!(
                    "the design from {} is refused in the cut of {}: at {k:.0} lbf/in the {e} \
                     (nothing set)",
                    a.plant.display(),
                    path.display()
                )
            })?;
        }
    }
    if a.dry_run {
        return Ok(d);
    }
    if c.status()?.state.phase != LoopPhase::Disarmed {
        return Err(
            "tune sets parameters, which change only while disarmed: `zslide link disarm` first"
                .into(),
        );
    }
    for (name, v) in tuned(&plant) {
        let p = params::by_name(name).ok_or_else(|| format!("no parameter {name}"))?;
        set(c, p.id, v).map_err(|e| format!("setting {name} = {v}: {e}"))?;
    }
    say_to(
        out,
        "set on the machine (in force now; `zslide params save` or `params flash` to keep them)",
    )?;
    Ok(d)
}
