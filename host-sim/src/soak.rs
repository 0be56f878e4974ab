//! `soak`: hours of machine time on the real firmware with the disturbances
//! a shop floor adds, summarised per simulated hour.
//!
//! The machine is the scenario's (`fwrig`, the digital loop armed at the
//! start), with on top of the scenario's own noise:
//!
//! * **X counter glitches**: the latch catches a carry mid-ripple with
//!   probability `glitch_prob` per interrupt (legacy BCD X), and the slide
//!   vibrates across digit edges (the scenario's vibration);
//! * **index jitter**: each true index edge moved by a uniform random time
//!   of `index_jitter_us` RMS (the tachometer machine's photodiode index;
//!   an encoder's index is gated by its counts and has none);
//! * **spindle speed noise**: a new random speed offset every revolution,
//!   `speed_noise_rpm` RMS, on top of the sag and ripple;
//! * **cutting-force noise**: the mean thrust of a finishing cut plus a
//!   first-order Gauss-Markov force of `force_noise_lbf` RMS and
//!   `force_noise_hz` bandwidth.
//!
//! The X slide traverses the part back and forth between `x_lo_in` and
//! `x_hi_in` at the scenario's feed, so every radius, both directions of X
//! and the reversals are covered. No stock is modelled (the force is
//! noise, not an engagement): the soak is about the firmware's long-run
//! health, the cut's accuracy is `cut`'s.
//!
//! Per hour: faults (a healthy soak has none: any is a false fault), the
//! following error (true tool position minus the exact command at the true
//! X and φ), the firmware's spindle phase against the truth (mean: drift;
//! largest), and the learned table's size at the hour's end (it must not
//! grow).

use crate::cut::nominal::Nominal;
use crate::fwrig::{machine_with, Controller, Machine, TickHook};
use crate::machine::xslide::FeedSegment;
use crate::machine::XInterface;
use crate::plant::Rig;
use crate::scenario::Scenario;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::cell::RefCell;
use std::rc::Rc;
use zslide::firmware::Firmware;

/// What to soak and how hard.
#[derive(Clone, Debug)]
pub struct SoakSpec {
    pub scenario: Scenario,
    pub hours: f64,
    pub x_lo_in: f64,
    pub x_hi_in: f64,
    pub glitch_prob: f64,
    pub index_jitter_us: f64,
    pub speed_noise_rpm: f64,
    pub force_mean_lbf: f64,
    pub force_noise_lbf: f64,
    pub force_noise_hz: f64,
}

impl SoakSpec {
    /// The default stresses on `scenario` for `hours`.
    pub fn new(scenario: Scenario, hours: f64) -> Self {
        let force_mean_lbf = scenario.cutting.thrust_lbf(0.0003, 100e-6);
        Self {
            scenario,
            hours,
            x_lo_in: 1.0,
            x_hi_in: 7.0,
            glitch_prob: 0.05,
            index_jitter_us: 20.0,
            speed_noise_rpm: 2.0,
            force_mean_lbf,
            force_noise_lbf: 0.1,
            force_noise_hz: 50.0,
        }
    }

    fn check(&self) -> anyhow::Result<()> {
        let f = &self.scenario.file;
        anyhow::ensure!(
            self.hours > 0.0 && self.hours <= 1000.0,
            "--hours {}: must be in (0, 1000]",
            self.hours
        );
        anyhow::ensure!(
            0.0 < self.x_lo_in && self.x_lo_in < self.x_hi_in && self.x_hi_in <= 7.2,
            "X range {}..{} in: must lie inside the contoured 0..7.2 in",
            self.x_lo_in,
            self.x_hi_in
        );
        anyhow::ensure!(
            f.x.feed_in_per_min != 0.0,
            "scenario {}: x.feed_in_per_min = 0, the soak needs the X slide moving",
            f.name
        );
        anyhow::ensure!(
            (0.0..=0.5).contains(&self.glitch_prob),
            "--glitch-prob {}: must be in [0, 0.5]",
            self.glitch_prob
        );
        anyhow::ensure!(
            (0.0..=1000.0).contains(&self.index_jitter_us),
            "--index-jitter-us {}: must be in [0, 1000]",
            self.index_jitter_us
        );
        anyhow::ensure!(
            self.speed_noise_rpm >= 0.0 && self.speed_noise_rpm <= f.spindle.rpm / 10.0,
            "--speed-noise-rpm {}: must be in [0, rpm/10]",
            self.speed_noise_rpm
        );
        anyhow::ensure!(
            self.force_noise_lbf >= 0.0 && self.force_noise_lbf <= 5.0,
            "--force-noise-lbf {}: must be in [0, 5]",
            self.force_noise_lbf
        );
        anyhow::ensure!(
            self.force_noise_hz > 0.0 && self.force_noise_hz <= 2000.0,
            "--force-noise-hz {}: must be in (0, 2000]",
            self.force_noise_hz
        );
        Ok(())
    }
}

/// One simulated hour.
#[derive(Clone, Debug, Default, Serialize)]
pub struct HourSummary {
    pub hour: u32,
    /// Faults raised this hour, with the time they were raised (s).
    pub faults: Vec<String>,
    pub following_error_rms_uin: f64,
    pub following_error_peak_uin: f64,
    /// Firmware spindle angle minus the true angle: mean (drift) and the
    /// largest, degrees.
    pub phase_error_mean_deg: f64,
    pub phase_error_max_deg: f64,
    /// Learned correction table at the hour's end: largest entry, µin.
    pub learned_peak_uin: f64,
    pub x_events: u64,
    pub x_glitched_latches: u64,
    pub index_events: u64,
    pub rpm_min: f64,
    pub rpm_max: f64,
    pub x_min_in: f64,
    pub x_max_in: f64,
}

#[derive(Default)]
struct Acc {
    fe_sq: f64,
    fe_n: u64,
    fe_peak: f64,
    ph_sum: f64,
    ph_n: u64,
    ph_max: f64,
    rpm_min: f64,
    rpm_max: f64,
    x_min: f64,
    x_max: f64,
}

impl Acc {
    fn new() -> Self {
        Self {
            rpm_min: f64::INFINITY,
            rpm_max: f64::NEG_INFINITY,
            x_min: f64::INFINITY,
            x_max: f64::NEG_INFINITY,
            ..Self::default()
        }
    }
}

/// The per-tick physics (force noise) and recorder.
struct SoakHook {
    nominal: Nominal,
    index_phase_turns: f64,
    rng: ChaCha8Rng,
    force_mean: f64,
    force_sigma: f64,
    /// Gauss-Markov pole per tick.
    alpha: f64,
    noise: f64,
    /// Recording starts here (the loop armed and learned), ns.
    settle_ns: u64,
    /// True spindle angle at the previous tick, turns (the firmware's
    /// angle read at a tick belongs to that tick).
    prev_true_turns: Option<f64>,
    acc: Acc,
}

impl TickHook for SoakHook {
    fn before_tick(&mut self, rig: &mut Rig, m: &Machine, _fw: &Firmware) {
        // Unit Gaussian by Box-Muller; one per tick keeps the stream simple.
        let (u1, u2): (f64, f64) = (self.rng.random(), self.rng.random());
        let g = (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        self.noise =
            self.alpha * self.noise + (1.0 - self.alpha * self.alpha).sqrt() * self.force_sigma * g;
        rig.set_force_lbf(self.force_mean + self.noise);

        let t = rig.t_ns;
        let t_s = t as f64 * 1e-9;
        let x = m.x_true_in(t_s);
        let (turns, rpm) = {
            let mut sp = m.spindle.borrow_mut();
            (sp.turns_at(t) + self.index_phase_turns, sp.rpm_at(t))
        };
        if t >= self.settle_ns {
            let e = rig.slide.position_in() - self.nominal.fast(x, turns.rem_euclid(1.0));
            let a = &mut self.acc;
            a.fe_sq += e * e;
            a.fe_n += 1;
            a.fe_peak = a.fe_peak.max(e.abs());
            a.rpm_min = a.rpm_min.min(rpm);
            a.rpm_max = a.rpm_max.max(rpm);
            a.x_min = a.x_min.min(x);
            a.x_max = a.x_max.max(x);
            if let (Some(prev), true) = (self.prev_true_turns, m.stats.referenced) {
                let fw = f64::from(m.stats.angle.0) / 4_294_967_296.0;
                let d = (fw - prev).rem_euclid(1.0);
                let d = if d > 0.5 { d - 1.0 } else { d } * 360.0;
                a.ph_sum += d;
                a.ph_n += 1;
                a.ph_max = a.ph_max.max(d.abs());
            }
        }
        self.prev_true_turns = Some(turns);
    }
}

/// X going back and forth between the limits, starting at the top going
/// in, at |feed|: the segments cover `total_s`.
fn traverse(x_lo: f64, x_hi: f64, feed_abs: f64, total_s: f64) -> Vec<FeedSegment> {
    let leg_s = (x_hi - x_lo) / feed_abs * 60.0;
    let mut v = Vec::new();
    let mut t = 0.0;
    let mut sign = -1.0;
    while t < total_s + leg_s {
        v.push(FeedSegment {
            t_start_s: t,
            feed_in_per_min: sign * feed_abs,
        });
        t += leg_s;
        sign = -sign;
    }
    v
}

/// Runs the soak; `progress(simulated_s)` after every simulated minute.
pub fn run(spec: &SoakSpec, progress: &dyn Fn(f64)) -> anyhow::Result<Vec<HourSummary>> {
    spec.check()?;
    let sc = &spec.scenario;
    let total_s = spec.hours * 3600.0;
    let mut machine = sc.machine.clone();
    let feed_abs = sc.file.x.feed_in_per_min.abs();
    match &mut machine.x {
        XInterface::LegacyBcd(c) | XInterface::Quadrature(c) => {
            c.x0_in = spec.x_hi_in;
            c.feed = traverse(spec.x_lo_in, spec.x_hi_in, feed_abs, total_s);
            c.ripple_prob = spec.glitch_prob;
        }
    }
    // The photodiode index of the tachometer machine has timing jitter; an
    // encoder's index is gated by its own counts (none).
    if machine.sensor == crate::machine::SpindleSensor::TachIndex {
        machine.spindle.index_jitter_us = spec.index_jitter_us;
    }
    machine.spindle.speed_noise_rpm = spec.speed_noise_rpm;
    let t = zslide::table::CoeffTable::parse(zslide::DEFAULT_TABLE)
        .map_err(|e| anyhow::anyhow!("default table refused: {e}"))?;
    let surf = crate::surface::Surface::from_table_geometry(&t.header().geometry)
        .map_err(|e| anyhow::anyhow!("table geometry: {e}"))?;
    let dt = 1.0 / f64::from(sc.loop_hz);
    let hook = Rc::new(RefCell::new(SoakHook {
        nominal: Nominal::new(surf, t.x_null().to_f64()),
        index_phase_turns: machine.spindle.index_phase_turns,
        rng: ChaCha8Rng::seed_from_u64(sc.rig.seed ^ 0x534f_414b),
        force_mean: spec.force_mean_lbf,
        force_sigma: spec.force_noise_lbf,
        alpha: (-std::f64::consts::TAU * spec.force_noise_hz * dt).exp(),
        noise: 0.0,
        // Engagement, then the learning's first 40 revolutions.
        settle_ns: (40.0 * 60.0 / sc.file.spindle.rpm * 1e9) as u64,
        prev_true_turns: None,
        acc: Acc::new(),
    }));
    let (mut w, mut s) = machine_with(sc.rig.clone(), &machine, sc.loop_hz, sc.servo);
    Controller::Digital.attach(&mut w, &mut s);
    w.hooks.push(Box::new(hook.clone()));

    let hour_ns = 3_600_000_000_000u64;
    let end_ns = (total_s * 1e9) as u64;
    let mut out = Vec::new();
    let mut seen_fault = None;
    let mut last = (0u64, 0u64, 0u64);
    let mut t = 0u64;
    let mut hour = 0u32;
    while t < end_ns {
        let hour_end = ((u64::from(hour) + 1) * hour_ns).min(end_ns);
        let mut faults = Vec::new();
        while t < hour_end {
            t = (t + 60_000_000_000).min(hour_end);
            s.run_until(&mut w, t);
            let now = w.fw.fault().or(w.stats().and_then(|m| m.last_fault));
            if now != seen_fault {
                if let Some(f) = now {
                    faults.push(format!("{:.1} s: {f:?}: {}", t as f64 * 1e-9, f.reason()));
                }
                seen_fault = now;
            }
            progress(t as f64 * 1e-9);
        }
        let st = w.stats().cloned().unwrap_or_default();
        let a = std::mem::replace(&mut hook.borrow_mut().acc, Acc::new());
        let fe_n = a.fe_n.max(1) as f64;
        out.push(HourSummary {
            hour: hour + 1,
            faults,
            following_error_rms_uin: (a.fe_sq / fe_n).sqrt() * 1e6,
            following_error_peak_uin: a.fe_peak * 1e6,
            phase_error_mean_deg: a.ph_sum / a.ph_n.max(1) as f64,
            phase_error_max_deg: a.ph_max,
            learned_peak_uin: f64::from(w.fw.shared().learned().peak_code()) * 0.010e6
                / f64::from(1u32 << 19),
            x_events: st.x_events - last.0,
            x_glitched_latches: st.x_stale - last.1,
            index_events: st.index_events - last.2,
            rpm_min: a.rpm_min,
            rpm_max: a.rpm_max,
            x_min_in: a.x_min,
            x_max_in: a.x_max,
        });
        last = (st.x_events, st.x_stale, st.index_events);
        hour += 1;
    }
    w.hooks.clear();
    Ok(out)
}
