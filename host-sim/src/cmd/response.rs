//! `host-sim response`: the signal analyser. Measures the frequency response
//! of a chosen loop of the simulated machine by swept sine (see
//! `analyser`) and writes Bode data as CSV (`f_hz,mag_db,phase_deg`) and an
//! SVG Bode plot with the published transfer function overlaid.

use crate::analog1983::{self, PositionLoop1983, VelocityLoop1983};
use crate::analyser::{log_freqs, BodePoint, SweptSine};
use crate::plant::linear::LinearSystem;
use crate::plant::ZSlideParams;
use nalgebra::Complex;
use std::io::Write;
use std::path::{Path, PathBuf};

/// A published reference transfer function: `(Ko, ω) → H(jω)`.
pub type RefTf = fn(f64, f64) -> Complex<f64>;

/// Excitation method.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    Sine,
    Noise,
}

/// Which loop to measure.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Loop {
    /// Amplifier input (V) → gauge (V), no feedback (Model 15 plant,
    /// amplifier gain 10, 3150 Hz mode).
    Plant,
    /// The emulated 1983 analog velocity loop, R1 → gauge (V/V); compare eq 4-44.
    Velocity1983,
    /// The 1983 closed position loop with the eq 4-45 compensator, R2 →
    /// gauge; compare eq 4-47 (no mode) and eq 4-49 (measured).
    Position1983,
    /// The firmware's digital loop (`zslide::servo`, the scenario's
    /// `[servo]` design) on the scenario's plant, measured through the
    /// simulated chips in the time domain: a sinusoid injected into the
    /// gauge's reading gives the sensitivity S (what the gauge reads) and
    /// the complementary sensitivity T (minus the slide's true motion); the
    /// loop gain L = T/S gives the margins.
    Digital,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Loop to measure.
    #[arg(long = "loop", value_enum, default_value = "velocity1983")]
    pub which: Loop,
    /// Lowest frequency, Hz.
    #[arg(long, default_value_t = 1.0)]
    pub f_min: f64,
    /// Highest frequency, Hz.
    #[arg(long, default_value_t = 6400.0)]
    pub f_max: f64,
    /// Number of log-spaced frequencies.
    #[arg(long, default_value_t = 200)]
    pub points: usize,
    /// Position-loop gain Ko of eq 4-45 (Kv = 8088 Ko).
    #[arg(long, default_value_t = 0.5934)]
    pub ko: f64,
    /// Rigid slide (no 3150 Hz mode).
    #[arg(long)]
    pub rigid: bool,
    /// Excitation amplitude, V (default: 0.001 V for the open plant, whose
    /// free integrator would take the gauge out of range, 0.01 V else).
    #[arg(long)]
    pub amplitude: Option<f64>,
    /// Excitation: swept sine, or seeded noise with H1 averaging (the HP
    /// 5420's usual mode). The firmware loop is always swept.
    #[arg(long, value_enum, default_value = "sine")]
    pub method: Method,
    /// CSV output (default: stdout).
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// SVG Bode plot.
    #[arg(long)]
    pub svg: Option<PathBuf>,
    /// Print a JSON summary (agreement with the published equation, mode
    /// peak; for the digital loop the margins) instead of the CSV on stdout.
    #[arg(long)]
    pub json: bool,
    /// The process stiffness on the slide, lbf/in (digital loop only): the
    /// engaged part as a spring, `F = −k·(z − z₀)` on the slide carriage,
    /// updated at every loop tick as the cut's force is (0 = in air; the
    /// force model's value at the scenario's depth of cut and feed:
    /// `cut::stiffness`, ≈ 2200 lbf/in at the nominal k_e).
    #[arg(long, default_value_t = 0.0)]
    pub process_stiffness: f64,
    /// Instead of one sweep: the margins over the process stiffness, from
    /// in air to k_e × 5 of the scenario's force model (`cut::stiffness`),
    /// with the learning's convergence factor at each (JSON rows; `--svg`
    /// plots them against the stiffness, `--csv` writes the rows).
    #[arg(long)]
    pub stiffness_sweep: bool,
    /// Scenario (the digital loop's plant and `[servo]` design).
    #[command(flatten)]
    pub scenario: crate::scenario::ScenarioArg,
}

/// The system to excite (input 0 → output 0) and the published reference.
pub fn setup(which: Loop, ko: f64, rigid: bool) -> (LinearSystem, Option<RefTf>, &'static str) {
    let mut p = ZSlideParams::model15();
    if rigid {
        p = p.rigid();
    }
    match which {
        Loop::Plant => (analog1983::plant_open(&p, 10.0), None, "plant"),
        Loop::Velocity1983 => {
            let c = VelocityLoop1983::default().controller();
            (
                analog1983::close_loop(&p, 10.0, &c),
                Some(|_, w| analog1983::eq4_44(w)),
                "eq 4-44",
            )
        }
        // Not a linear system: measured by `measure_digital`.
        Loop::Digital => (analog1983::plant_open(&p, 10.0), None, "digital"),
        Loop::Position1983 => {
            let c = PositionLoop1983 {
                ko,
                ..Default::default()
            }
            .controller();
            (
                analog1983::close_loop(&p, 10.0, &c),
                Some(analog1983::eq4_47),
                "eq 4-47",
            )
        }
    }
}

/// Summary of a measurement.
#[derive(serde::Serialize, Debug)]
pub struct Summary {
    pub r#loop: String,
    pub points: usize,
    pub reference: Option<String>,
    /// Largest |Δ magnitude| (dB) and |Δ phase| (deg) from the reference
    /// up to 1 kHz.
    pub max_mag_dev_db_to_1khz: Option<f64>,
    pub max_phase_dev_deg_to_1khz: Option<f64>,
    /// Largest magnitude above the reference between 2.5 and 4 kHz (dB)
    /// and where: the structural mode.
    pub mode_peak_over_ref_db: Option<f64>,
    pub mode_peak_hz: Option<f64>,
}

pub fn summarize(
    pts: &[BodePoint],
    reference: Option<RefTf>,
    ko: f64,
    name: &str,
    which: Loop,
) -> Summary {
    let mut s = Summary {
        r#loop: format!("{which:?}"),
        points: pts.len(),
        reference: reference.map(|_| name.to_string()),
        max_mag_dev_db_to_1khz: None,
        max_phase_dev_deg_to_1khz: None,
        mode_peak_over_ref_db: None,
        mode_peak_hz: None,
    };
    if let Some(r) = reference {
        let (mut dm, mut dp) = (0.0f64, 0.0f64);
        let (mut peak, mut peak_f) = (f64::NEG_INFINITY, 0.0);
        for p in pts {
            let h = r(ko, std::f64::consts::TAU * p.f_hz);
            let ratio = p.h / h;
            let mag = 20.0 * ratio.norm().log10();
            if p.f_hz <= 1000.0 {
                dm = dm.max(mag.abs());
                dp = dp.max(ratio.arg().to_degrees().abs());
            }
            if (2500.0..=4000.0).contains(&p.f_hz) && mag > peak {
                peak = mag;
                peak_f = p.f_hz;
            }
        }
        s.max_mag_dev_db_to_1khz = Some(dm);
        s.max_phase_dev_deg_to_1khz = Some(dp);
        if peak.is_finite() {
            s.mode_peak_over_ref_db = Some(peak);
            s.mode_peak_hz = Some(peak_f);
        }
    }
    s
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.f_min > 0.0 && args.f_max > args.f_min,
        "need 0 < f-min < f-max"
    );
    anyhow::ensure!(args.points >= 2, "need at least 2 points");
    if let Some(p) = &args.csv {
        crate::outpath::check_file("--csv", p)?;
    }
    if let Some(p) = &args.svg {
        crate::outpath::check_file("--svg", p)?;
    }
    let (sys, reference, name) = setup(args.which, args.ko, args.rigid);
    let amplitude = args.amplitude.unwrap_or(if args.which == Loop::Plant {
        0.001
    } else {
        0.01
    });
    anyhow::ensure!(
        amplitude > 0.0 && amplitude.is_finite(),
        "need a positive amplitude"
    );
    let an = SweptSine {
        amplitude,
        settle_s: if args.which == Loop::Position1983 {
            3.0
        } else {
            0.05
        },
        ..Default::default()
    };
    let freqs = log_freqs(args.f_min, args.f_max, args.points);
    anyhow::ensure!(
        args.process_stiffness.is_finite() && args.process_stiffness >= 0.0,
        "--process-stiffness {}: need a finite stiffness >= 0 lbf/in",
        args.process_stiffness
    );
    anyhow::ensure!(
        args.which == Loop::Digital || (args.process_stiffness == 0.0 && !args.stiffness_sweep),
        "--process-stiffness and --stiffness-sweep apply to --loop digital only"
    );
    if args.which == Loop::Digital {
        return run_digital(&args, &freqs);
    }
    let pts = if args.method == Method::Noise {
        crate::analyser::NoiseExcitation {
            amplitude,
            ..Default::default()
        }
        .sweep(&sys, 0, 0, &freqs)
    } else {
        an.sweep(&sys, 0, 0, &freqs)
    };
    let mut csv = String::from("f_hz,mag_db,phase_deg\n");
    for p in &pts {
        csv.push_str(&format!(
            "{:.6},{:.6},{:.4}\n",
            p.f_hz,
            p.mag_db(),
            p.phase_deg()
        ));
    }
    if let Some(path) = &args.csv {
        crate::outpath::replace(path, &csv)?;
    }
    if let Some(path) = &args.svg {
        crate::outpath::replace_with(path, |tmp| {
            plot_bode(
                tmp,
                &pts,
                reference.map(|r| (name, r)),
                args.ko,
                &format!("{:?}", args.which),
            )
        })?;
    }
    let peak_v = pts
        .iter()
        .map(|p| p.peak_out)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    if peak_v > 10.0 {
        eprintln!("warning: gauge output reached {peak_v:.2} V, beyond its ±10 V range; lower --amplitude");
    }
    if args.json {
        let s = summarize(&pts, reference, args.ko, name, args.which);
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else if args.csv.is_none() {
        std::io::stdout().write_all(csv.as_bytes())?;
    }
    Ok(())
}

fn plot_bode(
    path: &Path,
    pts: &[BodePoint],
    reference: Option<(&str, RefTf)>,
    ko: f64,
    title: &str,
) -> anyhow::Result<()> {
    use plotters::prelude::*;
    crate::plot::register_font();
    let root = SVGBackend::new(path, (900, 700)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(350);
    let f0 = pts.first().map_or(1.0, |p| p.f_hz);
    let f1 = pts.last().map_or(10.0, |p| p.f_hz);
    let mags: Vec<f64> = pts.iter().map(|p| p.mag_db()).collect();
    let lo = mags.iter().cloned().fold(f64::INFINITY, f64::min).floor() - 5.0;
    let hi = mags
        .iter()
        .cloned()
        .fold(f64::NEG_INFINITY, f64::max)
        .ceil()
        + 5.0;
    let refpts: Vec<(f64, Complex<f64>)> = reference.map_or(Vec::new(), |(_, r)| {
        pts.iter()
            .map(|p| (p.f_hz, r(ko, std::f64::consts::TAU * p.f_hz)))
            .collect()
    });
    {
        let mut ch = ChartBuilder::on(&top)
            .caption(format!("{title}: magnitude (dB)"), ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d((f0..f1).log_scale(), lo..hi)?;
        ch.configure_mesh().x_desc("f (Hz)").draw()?;
        ch.draw_series(LineSeries::new(
            pts.iter().map(|p| (p.f_hz, p.mag_db())),
            &BLUE,
        ))?
        .label("simulated")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
        if let Some((name, _)) = reference {
            ch.draw_series(LineSeries::new(
                refpts.iter().map(|(f, h)| (*f, 20.0 * h.norm().log10())),
                &RED,
            ))?
            .label(name)
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
        }
        ch.configure_series_labels().border_style(BLACK).draw()?;
    }
    {
        // Unwrapped, so a mode's phase excursion reads as one excursion.
        let ph = unwrap_deg(pts.iter().map(|p| p.phase_deg()));
        let ph_ref = unwrap_deg(refpts.iter().map(|(_, h)| h.arg().to_degrees()));
        let all = ph.iter().chain(&ph_ref);
        let lo = all.clone().cloned().fold(f64::INFINITY, f64::min);
        let hi = all.cloned().fold(f64::NEG_INFINITY, f64::max);
        let lo = (lo / 45.0).floor() * 45.0 - 10.0;
        let hi = (hi / 45.0).ceil() * 45.0 + 10.0;
        let mut ch = ChartBuilder::on(&bottom)
            .caption("phase (deg, unwrapped)", ("sans-serif", 18))
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d((f0..f1).log_scale(), lo..hi)?;
        ch.configure_mesh().x_desc("f (Hz)").draw()?;
        ch.draw_series(LineSeries::new(
            pts.iter().zip(&ph).map(|(p, a)| (p.f_hz, *a)),
            &BLUE,
        ))?;
        if reference.is_some() {
            ch.draw_series(LineSeries::new(
                refpts.iter().zip(&ph_ref).map(|((f, _), a)| (*f, *a)),
                &RED,
            ))?;
        }
    }
    root.present()?;
    Ok(())
}

/// Removes the ±360° jumps of a phase sequence, starting in (−180, 180].
pub fn unwrap_deg(phases: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for p in phases {
        let v = match out.last() {
            Some(&prev) => p + 360.0 * ((prev - p) / 360.0).round(),
            None => p,
        };
        out.push(v);
    }
    out
}

/// S and T of the digital loop at one frequency.
#[derive(Clone, Copy, Debug)]
pub struct LoopPoint {
    pub f_hz: f64,
    /// Sensitivity: gauge reading / injection.
    pub s: Complex<f64>,
    /// Complementary sensitivity: −slide motion / injection.
    pub t: Complex<f64>,
}

impl LoopPoint {
    /// The loop gain L = T / S.
    pub fn l(&self) -> Complex<f64> {
        self.t / self.s
    }
}

/// Swept-sine point of the digital loop on `sc`'s plant (noiseless gauge,
/// no spindle: the learning does not run): `amplitude_in` injected into the
/// gauge's reading, S and T fitted after settling.
pub fn measure_digital(
    sc: &crate::scenario::Scenario,
    f_hz: f64,
    amplitude_in: f64,
    rigid: bool,
) -> LoopPoint {
    measure_digital_on(sc, f_hz, amplitude_in, rigid, 0.0)
}

/// [`measure_digital`] with the tool engaged in a part of stiffness
/// `stiffness_lbf_per_in`: from the injection's start the slide carriage
/// carries `F = −k·(z − z₀)` (z₀ where it stood then), set before every
/// loop tick as the cut sets its force (`cut::run`), so the spring is
/// sampled as the board's cut samples it.
pub fn measure_digital_on(
    sc: &crate::scenario::Scenario,
    f_hz: f64,
    amplitude_in: f64,
    rigid: bool,
    stiffness_lbf_per_in: f64,
) -> LoopPoint {
    use crate::fwrig::{firmware_with, FirmwareWorld};
    use crate::plant::GaugeParams;
    use crate::sched::Periodic;
    let mut cfg = sc.rig.clone();
    cfg.gauge = GaugeParams::noiseless();
    if rigid {
        cfg.slide = cfg.slide.rigid();
    }
    // The noiseless gauge reads the loop's linear response; a real
    // gauge's noise is what the frozen-gauge check relies on, so it is
    // held off for this bench measurement (never for a cut).
    let mut servo = sc.servo;
    servo.monitor.gauge_frozen_ticks = u32::MAX;
    let (mut w, mut s) = firmware_with(cfg, sc.loop_hz, servo);
    w.fw.request(zslide::firmware::Request::Arm);
    let period = 1_000_000_000 / u64::from(sc.loop_hz.max(1));
    let wr = std::f64::consts::TAU * f_hz;
    let t0 = 200_000_000u64;
    s.run_until(&mut w, t0);
    let z0 = w.rig.slide.position_in();
    // The injection (and the spring's force) is set just before each
    // conversion (higher priority than the tick at the same instant).
    s.add(Periodic::new(
        "injection",
        255,
        t0 + period,
        period,
        move |t, w: &mut FirmwareWorld| {
            let tt = (t - t0) as f64 * 1e-9;
            w.rig.gauge_injection_in = amplitude_in * (wr * tt).sin();
            if stiffness_lbf_per_in != 0.0 {
                let z = w.rig.slide.position_in();
                w.rig.set_force_lbf(-stiffness_lbf_per_in * (z - z0));
            }
        },
    ));
    let settle = (0.3f64).max(10.0 / f_hz);
    let measure = (0.1f64).max(10.0 / f_hz);
    let t_settle = t0 + (settle * 1e9) as u64;
    s.run_until(&mut w, t_settle);
    type Rec = std::rc::Rc<std::cell::RefCell<(Vec<(f64, f64)>, Vec<(f64, f64)>)>>;
    let rec: Rec = Default::default();
    let r2 = rec.clone();
    s.on_event = Some(Box::new(move |t, k, w: &FirmwareWorld| {
        if k == 0 {
            let tt = (t - t0) as f64 * 1e-9;
            let mut r = r2.borrow_mut();
            r.0.push((
                tt,
                w.rig.slide.gauge_position_in() + w.rig.gauge_injection_in,
            ));
            r.1.push((tt, -w.rig.slide.gauge_position_in()));
        }
    }));
    s.run_until(&mut w, t_settle + (measure * 1e9) as u64);
    assert!(
        w.fw.fault().is_none(),
        "the response measurement at {f_hz} Hz latched {:?}: its points would not be the loop's",
        w.fw.fault()
    );
    let r = rec.borrow();
    LoopPoint {
        f_hz,
        s: crate::analyser::fit_sine(&r.0, wr) / amplitude_in,
        t: crate::analyser::fit_sine(&r.1, wr) / amplitude_in,
    }
}

/// Gain and phase margins from the loop gain over a sweep.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Margins {
    /// Where |L| crosses 1 (the first time from below), Hz, and 180° + ∠L there.
    pub crossover_hz: Option<f64>,
    pub phase_margin_deg: Option<f64>,
    /// Where ∠L crosses −180° above the crossover with the largest |L|
    /// (the smallest margin of those crossings), Hz, and −20·log|L|
    /// there, dB.
    pub phase_crossover_hz: Option<f64>,
    pub gain_margin_db: Option<f64>,
    /// The largest |S| (the inverse of the distance to −1), dB.
    pub peak_sensitivity_db: f64,
}

/// Margins read off the sweep, each crossing linearly interpolated between
/// its two sweep points: the result moves with the sweep's resolution. The
/// command uses [`margins_refined`].
pub fn margins(pts: &[LoopPoint]) -> Margins {
    margins_with(pts, None)
}

/// Margins whose crossings are found by bisection in log f between the two
/// sweep points that bracket them, measuring the loop at each midpoint until
/// the bracket is narrower than 0.01 %: the crossover and margins no longer
/// depend on how many points the plot has (the sweep only has to bracket each
/// crossing once).
pub fn margins_refined(pts: &[LoopPoint], measure: &dyn Fn(f64) -> LoopPoint) -> Margins {
    margins_with(pts, Some(measure))
}

/// `b`'s phase of L, degrees, unwrapped next to `a`'s (`pha`).
fn phase_next_to(pha: f64, a: &LoopPoint, b: &LoopPoint) -> f64 {
    let d = b.l().arg().to_degrees() - a.l().arg().to_degrees();
    pha + d - 360.0 * (d / 360.0).round()
}

/// Narrows the bracket `(a, pha)`..`(b, phb)` of a crossing of `side` (true
/// on a's side) by bisection in log f.
fn bisect(
    measure: &dyn Fn(f64) -> LoopPoint,
    mut a: (LoopPoint, f64),
    mut b: (LoopPoint, f64),
    side: &dyn Fn(&LoopPoint, f64) -> bool,
) -> ((LoopPoint, f64), (LoopPoint, f64)) {
    for _ in 0..24 {
        if b.0.f_hz / a.0.f_hz < 1.0001 {
            break;
        }
        let m = measure((a.0.f_hz * b.0.f_hz).sqrt());
        let phm = phase_next_to(a.1, &a.0, &m);
        if side(&m, phm) {
            a = (m, phm);
        } else {
            b = (m, phm);
        }
    }
    (a, b)
}

fn margins_with(pts: &[LoopPoint], refine: Option<&dyn Fn(f64) -> LoopPoint>) -> Margins {
    let mut m = Margins {
        crossover_hz: None,
        phase_margin_deg: None,
        phase_crossover_hz: None,
        gain_margin_db: None,
        peak_sensitivity_db: pts
            .iter()
            .map(|p| 20.0 * p.s.norm().log10())
            .fold(f64::NEG_INFINITY, f64::max),
    };
    let ph = unwrap_deg(pts.iter().map(|p| p.l().arg().to_degrees()));
    for i in 1..pts.len() {
        let (a, b) = ((pts[i - 1], ph[i - 1]), (pts[i], ph[i]));
        let (ma, mb) = (a.0.l().norm().log10(), b.0.l().norm().log10());
        if m.crossover_hz.is_none() && ma >= 0.0 && mb < 0.0 {
            let above_one = |p: &LoopPoint, _: f64| p.l().norm() >= 1.0;
            let (a, b) = match refine {
                Some(f) => bisect(f, a, b, &above_one),
                None => (a, b),
            };
            let (ma, mb) = (a.0.l().norm().log10(), b.0.l().norm().log10());
            let f = ma / (ma - mb);
            m.crossover_hz = Some(a.0.f_hz * (b.0.f_hz / a.0.f_hz).powf(f));
            m.phase_margin_deg = Some(180.0 + a.1 + f * (b.1 - a.1));
        }
        // The gain margin is read above the crossover: below it the loop
        // (integral action in the observer, a type-3 loop at low
        // frequency) passes −180° with |L| ≫ 1, which is conditional
        // stability, not a margin.
        // Every crossing of the negative real axis above it is a
        // candidate (the Nyquist plot's, read on L itself rather than on
        // an unwrapped phase): a notch whose poles are turned (the hum
        // canceller) takes L through nearly nothing at its own zero, which
        // an unwrapped phase counts as a turn of 360°, and below the
        // crossing that sets the margin.
        let above = m.crossover_hz.is_some_and(|fc| a.0.f_hz >= fc);
        let (la, lb) = (a.0.l(), b.0.l());
        if above && (la.im > 0.0) != (lb.im > 0.0) && la.re + lb.re < 0.0 {
            let positive = la.im > 0.0;
            let same_side = move |p: &LoopPoint, _: f64| (p.l().im > 0.0) == positive;
            let (a, b) = match refine {
                Some(f) => bisect(f, a, b, &same_side),
                None => (a, b),
            };
            let (la, lb) = (a.0.l(), b.0.l());
            let f = la.im / (la.im - lb.im);
            let l = la + (lb - la) * f;
            if l.re < 0.0 {
                let gm = -20.0 * l.norm().log10();
                if m.gain_margin_db.is_none_or(|g| gm < g) {
                    m.phase_crossover_hz = Some(a.0.f_hz * (b.0.f_hz / a.0.f_hz).powf(f));
                    m.gain_margin_db = Some(gm);
                }
            }
        }
    }
    if let Some(measure) = refine {
        m.peak_sensitivity_db = refine_peak_s(pts, measure);
    }
    m
}

/// The largest |S|, dB: the sweep's largest point, then a golden-section
/// search in log f between its two neighbours (the peak of a sweep point
/// alone moves with the resolution).
fn refine_peak_s(pts: &[LoopPoint], measure: &dyn Fn(f64) -> LoopPoint) -> f64 {
    let db = |p: &LoopPoint| 20.0 * p.s.norm().log10();
    let Some(k) = (0..pts.len()).max_by(|&a, &b| db(&pts[a]).total_cmp(&db(&pts[b]))) else {
        return f64::NEG_INFINITY;
    };
    let best = db(&pts[k]);
    let (mut a, mut b) = (
        pts[k.saturating_sub(1)].f_hz.ln(),
        pts[(k + 1).min(pts.len() - 1)].f_hz.ln(),
    );
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let at = |x: f64| db(&measure(x.exp()));
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (at(c), at(d));
    for _ in 0..30 {
        if (b - a).abs() < 1e-4 {
            break;
        }
        if fc > fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = at(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = at(d);
        }
    }
    best.max(fc).max(fd)
}

/// The digital loop on `sc` swept over `freqs` (`amplitude_in` injected
/// into the gauge's reading), and its margins refined by bisection: what
/// `response --loop digital` reports, and what `zslide tune` predicts for
/// the design it writes.
pub fn sweep_digital(
    sc: &crate::scenario::Scenario,
    freqs: &[f64],
    amplitude_in: f64,
    rigid: bool,
) -> (Vec<LoopPoint>, Margins) {
    sweep_digital_on(sc, freqs, amplitude_in, rigid, 0.0)
}

/// [`sweep_digital`] with the tool engaged in a part of stiffness
/// `stiffness_lbf_per_in` ([`measure_digital_on`]).
pub fn sweep_digital_on(
    sc: &crate::scenario::Scenario,
    freqs: &[f64],
    amplitude_in: f64,
    rigid: bool,
    stiffness_lbf_per_in: f64,
) -> (Vec<LoopPoint>, Margins) {
    let at = |f: f64| measure_digital_on(sc, f, amplitude_in, rigid, stiffness_lbf_per_in);
    let pts: Vec<LoopPoint> = freqs.iter().map(|&f| at(f)).collect();
    let m = margins_refined(&pts, &at);
    (pts, m)
}

/// The injection `response --loop digital` uses unless told: 20 µin, well
/// inside the gauge's range and above its quantisation.
pub const DIGITAL_AMPLITUDE_IN: f64 = 20e-6;

/// One row of `response --loop digital --stiffness-sweep`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StiffnessRow {
    /// The force model's k_e scale (0: in air).
    pub ke_factor: f64,
    pub stiffness_lbf_per_in: f64,
    /// Measured through the firmware on the rig (`sweep_digital_on`).
    pub margins: Margins,
    /// The sampled-data model's largest |S| (`loopmodel`), dB.
    pub model_peak_sensitivity_db: f64,
    /// The learning's largest revolution-to-revolution factor over the
    /// spindle harmonics at the scenario's speed (< 1: it converges), and
    /// where, Hz (`loopmodel::LoopModel::learning_factor`).
    pub learning_factor: f64,
    pub learning_factor_hz: f64,
}

/// The k_e scales of the stiffness sweep: in air to k_e × 5.
pub const STIFFNESS_SWEEP_KE: [f64; 8] = [0.0, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0];

/// The margins over the process stiffness of chapter 5's cut on `sc`.
pub fn stiffness_sweep(
    sc: &crate::scenario::Scenario,
    freqs: &[f64],
    amplitude_in: f64,
) -> anyhow::Result<Vec<StiffnessRow>> {
    let spec = crate::cut::CutSpec::chapter5(
        sc.clone(),
        crate::cut::Controller::Digital,
        None,
        None,
        false,
    )?;
    let latency = sc.rig.dac_latency_ns as f64 * 1e-9;
    let rpm = sc.file.spindle.rpm;
    let mut rows = Vec::new();
    for f in STIFFNESS_SWEEP_KE {
        let mut c = sc.cutting.clone();
        c.k_e_lbf_per_in *= f;
        let k = if f == 0.0 {
            0.0
        } else {
            crate::cut::sensitivity::stiffness_lbf_per_in(&c, spec.depth_in, spec.feed_per_rev_in)
        };
        let (_, margins) = sweep_digital_on(sc, freqs, amplitude_in, false, k);
        let m = crate::loopmodel::LoopModel::new(
            &sc.servo_design,
            sc.file.motor.l_over_r_ms * 1e-3,
            latency,
            k,
        );
        let (g, gf) = m.learning_factor(rpm);
        rows.push(StiffnessRow {
            ke_factor: f,
            stiffness_lbf_per_in: k,
            margins,
            model_peak_sensitivity_db: m.peak_sensitivity_db(1.0, 5000.0, 2000).0,
            learning_factor: g,
            learning_factor_hz: gf,
        });
    }
    Ok(rows)
}

fn run_stiffness_sweep(
    args: &Args,
    sc: &crate::scenario::Scenario,
    freqs: &[f64],
    amp: f64,
) -> anyhow::Result<()> {
    let rows = stiffness_sweep(sc, freqs, amp)?;
    let mut csv = String::from(
        "ke_factor,stiffness_lbf_per_in,crossover_hz,phase_margin_deg,gain_margin_db,peak_sensitivity_db,model_peak_sensitivity_db,learning_factor,learning_factor_hz\n",
    );
    let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.3}"));
    for r in &rows {
        csv.push_str(&format!(
            "{},{:.1},{},{},{},{:.3},{:.3},{:.4},{:.1}\n",
            r.ke_factor,
            r.stiffness_lbf_per_in,
            o(r.margins.crossover_hz),
            o(r.margins.phase_margin_deg),
            o(r.margins.gain_margin_db),
            r.margins.peak_sensitivity_db,
            r.model_peak_sensitivity_db,
            r.learning_factor,
            r.learning_factor_hz
        ));
    }
    if let Some(path) = &args.csv {
        crate::outpath::replace(path, &csv)?;
    }
    if let Some(path) = &args.svg {
        crate::outpath::replace_with(path, |tmp| plot_stiffness(tmp, &rows, &sc.file.name))?;
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "loop": "digital",
                "scenario": sc.file.name,
                "rows": rows,
            }))?
        );
    } else if args.csv.is_none() {
        std::io::stdout().write_all(csv.as_bytes())?;
    }
    Ok(())
}

fn plot_stiffness(path: &Path, rows: &[StiffnessRow], scenario: &str) -> anyhow::Result<()> {
    use plotters::prelude::*;
    crate::plot::register_font();
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(300);
    let k1 = rows.last().map_or(1.0, |r| r.stiffness_lbf_per_in).max(1.0);
    {
        let mut ch = ChartBuilder::on(&top)
            .caption(
                format!("digital loop on {scenario}: peak |S| (dB) against the process stiffness"),
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..k1, 0.0..12.0)?;
        ch.configure_mesh().x_desc("stiffness (lbf/in)").draw()?;
        ch.draw_series(LineSeries::new(
            rows.iter()
                .map(|r| (r.stiffness_lbf_per_in, r.margins.peak_sensitivity_db)),
            &BLUE,
        ))?
        .label("measured (firmware on the rig)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
        ch.draw_series(LineSeries::new(
            rows.iter()
                .map(|r| (r.stiffness_lbf_per_in, r.model_peak_sensitivity_db)),
            &RED,
        ))?
        .label("sampled-data model")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
        ch.configure_series_labels().border_style(BLACK).draw()?;
    }
    {
        let mut ch = ChartBuilder::on(&bottom)
            .caption(
                "learning: largest factor per revolution (< 1 converges)",
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..k1, 0.5..1.1)?;
        ch.configure_mesh().x_desc("stiffness (lbf/in)").draw()?;
        ch.draw_series(LineSeries::new(
            rows.iter()
                .map(|r| (r.stiffness_lbf_per_in, r.learning_factor)),
            &BLUE,
        ))?;
        ch.draw_series(LineSeries::new([(0.0, 1.0), (k1, 1.0)], &BLACK))?;
    }
    root.present()?;
    Ok(())
}

fn run_digital(args: &Args, freqs: &[f64]) -> anyhow::Result<()> {
    let sc = args.scenario.load()?;
    if args.stiffness_sweep {
        let amp = args.amplitude.map_or(DIGITAL_AMPLITUDE_IN, |v| v * 0.001);
        return run_stiffness_sweep(args, &sc, freqs, amp);
    }
    let amp = args.amplitude.map_or(DIGITAL_AMPLITUDE_IN, |v| v * 0.001);
    let k = args.process_stiffness;
    let (pts, m) = sweep_digital_on(&sc, freqs, amp, args.rigid, k);
    let mut csv =
        String::from("f_hz,s_mag_db,s_phase_deg,t_mag_db,t_phase_deg,l_mag_db,l_phase_deg\n");
    for p in &pts {
        let db = |h: Complex<f64>| 20.0 * h.norm().log10();
        csv.push_str(&format!(
            "{:.6},{:.4},{:.3},{:.4},{:.3},{:.4},{:.3}\n",
            p.f_hz,
            db(p.s),
            p.s.arg().to_degrees(),
            db(p.t),
            p.t.arg().to_degrees(),
            db(p.l()),
            p.l().arg().to_degrees()
        ));
    }
    if let Some(path) = &args.csv {
        crate::outpath::replace(path, &csv)?;
    }
    if let Some(path) = &args.svg {
        crate::outpath::replace_with(path, |tmp| plot_sensitivities(tmp, &pts, &sc.file.name))?;
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "loop": "digital",
                "scenario": sc.file.name,
                "process_stiffness_lbf_per_in": k,
                "points": pts.len(),
                "margins": m,
            }))?
        );
    } else {
        if args.csv.is_none() {
            std::io::stdout().write_all(csv.as_bytes())?;
        }
        eprintln!(
            "digital loop on {}: crossover {} Hz, phase margin {} deg, gain margin {} dB (at {} Hz), peak |S| {:.1} dB",
            sc.file.name,
            fmt_opt(m.crossover_hz, 1),
            fmt_opt(m.phase_margin_deg, 1),
            fmt_opt(m.gain_margin_db, 1),
            fmt_opt(m.phase_crossover_hz, 0),
            m.peak_sensitivity_db
        );
    }
    Ok(())
}

/// A margin or crossing with `digits` decimals, or that the sweep had none.
pub fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("none in the sweep".into(), |x| format!("{x:.digits$}"))
}

fn plot_sensitivities(path: &Path, pts: &[LoopPoint], scenario: &str) -> anyhow::Result<()> {
    use plotters::prelude::*;
    crate::plot::register_font();
    let root = SVGBackend::new(path, (900, 450)).into_drawing_area();
    root.fill(&WHITE)?;
    let f0 = pts.first().map_or(1.0, |p| p.f_hz);
    let f1 = pts.last().map_or(10.0, |p| p.f_hz);
    let db = |h: Complex<f64>| 20.0 * h.norm().log10();
    let all: Vec<f64> = pts.iter().flat_map(|p| [db(p.s), db(p.t)]).collect();
    let lo = all
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min)
        .max(-80.0)
        .floor()
        - 5.0;
    let hi = all.iter().cloned().fold(f64::NEG_INFINITY, f64::max).ceil() + 5.0;
    let mut ch = ChartBuilder::on(&root)
        .caption(
            format!(
                "digital loop on {scenario}: sensitivity S and complementary sensitivity T (dB)"
            ),
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d((f0..f1).log_scale(), lo..hi)?;
    ch.configure_mesh().x_desc("f (Hz)").draw()?;
    ch.draw_series(LineSeries::new(
        pts.iter().map(|p| (p.f_hz, db(p.s))),
        &BLUE,
    ))?
    .label("S")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    ch.draw_series(LineSeries::new(pts.iter().map(|p| (p.f_hz, db(p.t))), &RED))?
        .label("T")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
    ch.configure_series_labels().border_style(BLACK).draw()?;
    root.present()?;
    Ok(())
}
