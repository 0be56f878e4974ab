//! The finishing cut of chapter 5, simulated by bands around each radius the
//! CMM measures, and the part "measured" on the CMM grid.
//!
//! **The pass.** The X slide feeds toward the axis at the feed per
//! revolution (100 µin/rev, brief §2) with the spindle at the scenario's
//! speed (or `--rpm`). Each band starts `settle + learn + measure/2`
//! revolutions outside a CMM radius X_m, arms the loop, lets it settle and
//! learn (the state the firmware would really have there, having cut the
//! part's outer zone), then records the passes over X_m. The firmware is the
//! real one (`fwrig`: loop tick, X and index events, the drivers on the
//! simulated chips) with the default coefficient table of the dissertation's
//! part; `legacy-analog` hands the amplifier to the 1983 loop.
//!
//! **The force.** The thrust of `plant::cutting` from the instantaneous
//! engagement: depth d = d₀ + part_side·(z − z_ideal) (d₀ = 0.0003 in; a
//! tool that lags into the part cuts deeper), the feed per revolution, and
//! the bolt holes (open: no stock over them; filled: cut like the part),
//! set on the slide at every loop tick.
//!
//! **The part.** A pass p of the tool centre at radius X_c = X_m + δ_p with
//! error e_p = z − z_ideal(X_c, φ) (z_ideal: the exact tool-centre path of
//! `surface`, FOREX4 compensation) leaves the surface at
//! z_ideal + e_p + part_side·(r − √(r² − δ_p²)) ≈ … + part_side·δ_p²/2r
//! (the nose's envelope); the part keeps the pass that cut deepest. Excess
//! stock (chapter 5's sign: positive = material left) at (X_m, φ) is
//! therefore `−part_side · max_p(part_side·e_p − δ_p²/2r)`. Grid points that
//! fall in an open hole have no surface: reported as absent.
//!
//! **Finish.** The RMS, over the measured passes, of the error after its
//! per-angle mean is removed (the slide's high-frequency motion), combined
//! with the RMS of the feed marks' scallop, f²/(8r) peak to valley (RMS
//! = f²/(8r) · 2/(3√5)).

use crate::fwrig::{Controller, WorldTick};
use crate::scenario::Scenario;
use crate::surface::Surface;
use rayon::prelude::*;
use serde::Serialize;
use zslide::firmware::Request;

/// CMM grid of chapter 5.
pub const CMM_X_IN: [f64; 7] = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
pub const CMM_PHI_STEPS: usize = 36;

/// Holes in the part face.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Holes {
    /// First part: open countersinks (an interrupted cut).
    Open,
    /// Second part: filled.
    Filled,
}

#[derive(Clone, Debug)]
pub struct CutSpec {
    pub controller: Controller,
    pub rpm: f64,
    pub holes: Holes,
    pub feed_per_rev_in: f64,
    pub depth_in: f64,
    pub settle_revs: u32,
    pub learn_revs: u32,
    pub measure_revs: u32,
}

impl CutSpec {
    pub fn new(sc: &Scenario, controller: Controller, rpm: Option<f64>, holes: Holes) -> Self {
        Self {
            controller,
            rpm: rpm.unwrap_or(sc.file.spindle.rpm),
            holes,
            feed_per_rev_in: 100e-6,
            depth_in: 300e-6,
            settle_revs: 10,
            learn_revs: 40,
            measure_revs: 20,
        }
    }
}

/// One band's result.
#[derive(Clone, Debug)]
pub struct Band {
    pub x_in: f64,
    /// Excess stock per CMM angle, in (None: over an open hole).
    pub excess_in: Vec<Option<f64>>,
    pub following_sq: f64,
    pub following_n: f64,
    pub following_peak: f64,
    pub finish_hf_rms_in: f64,
    pub faults: Vec<String>,
    pub simulated_s: f64,
    /// Error at X_m against φ (deg), for plots.
    pub trace: Vec<(f64, f64)>,
}

/// The cut's report (brief §5).
#[derive(Clone, Debug, Serialize)]
pub struct CutReport {
    pub contour_error_min_uin: f64,
    pub contour_error_max_uin: f64,
    pub following_error_rms_uin: f64,
    pub following_error_peak_uin: f64,
    pub finish_rms_uin: f64,
    pub finish_rms_by_radius_uin: Vec<f64>,
    pub simulated_s: f64,
    pub wall_s: f64,
    pub faults: Vec<String>,
    pub cmm_grid_uin: Vec<Vec<Option<f64>>>,
    pub phi_deg: Vec<f64>,
    pub x_in: Vec<f64>,
    pub rpm: f64,
    pub holes: Holes,
    pub controller: String,
    pub scenario: String,
}

fn band(sc: &Scenario, spec: &CutSpec, x_m: f64) -> Band {
    let f = spec.feed_per_rev_in;
    let revs_before = spec.settle_revs + spec.learn_revs + spec.measure_revs / 2;
    let mut machine = sc.machine.clone();
    machine.spindle.rpm0 = spec.rpm;
    let feed_in_per_min = -f * spec.rpm;
    let x0 = x_m + f * f64::from(revs_before);
    match &mut machine.x {
        crate::fwrig::XInterface::LegacyBcd(c) | crate::fwrig::XInterface::Quadrature(c) => {
            c.x0_in = x0;
            c.feed = vec![crate::machine::xslide::FeedSegment {
                t_start_s: 0.0,
                feed_in_per_min,
            }];
        }
    }
    let mut cutting = sc.cutting.clone();
    cutting.bolt_holes.filled = spec.holes == Holes::Filled;
    let surface = Surface::dissertation();
    let (mut w, mut s) = crate::fwrig::firmware_with(sc.rig.clone(), sc.loop_hz, sc.servo);
    w.attach_machine(&machine);
    crate::fwrig::add_machine_sources(&w, &mut s);
    match spec.controller {
        Controller::Digital => w.request(Request::Arm),
        Controller::LegacyAnalog => {
            w.use_legacy_analog();
            s.add(WorldTick::analog_substep(5_000));
        }
    }
    let tick_ns = 1_000_000_000 / u64::from(sc.loop_hz);
    let rev_s = 60.0 / spec.rpm;
    let t_cut = f64::from(spec.settle_revs) * rev_s;
    let t_meas = f64::from(spec.settle_revs + spec.learn_revs) * rev_s;
    let t_end = f64::from(revs_before + spec.measure_revs / 2) * rev_s;
    let index_phase = machine.spindle.index_phase_turns;
    let part_side = cutting.part_side;
    let r = cutting.tool_radius_in;
    let n_phi = CMM_PHI_STEPS;
    let mut best: Vec<Option<f64>> = vec![None; n_phi];
    let mut bins = vec![(0.0f64, 0.0f64, 0.0f64); n_phi]; // (Σe, Σe², n) per angle bin
    let (mut fsq, mut fn_, mut fpk) = (0.0, 0.0, 0.0f64);
    let mut last_turns: Option<f64> = None;
    let mut trace = Vec::new();
    let mut t = 0u64;
    let end_ns = (t_end * 1e9) as u64;
    while t < end_ns {
        t += tick_ns;
        s.run_until(&mut w, t);
        let ts = t as f64 * 1e-9;
        let turns = {
            let m = w.machine.as_ref().expect("machine attached");
            let tr = m.spindle.borrow_mut().turns_at(t);
            tr + index_phase
        };
        let phi = std::f64::consts::TAU * turns.rem_euclid(1.0);
        let x_c = w.x_true_in();
        let z_ideal = surface.z(x_c, phi).unwrap_or(0.0);
        let z = w.rig.slide.position_in();
        let e = z - z_ideal;
        // The cut: from the end of the settling on.
        let force = if ts >= t_cut {
            let d = (spec.depth_in + part_side * e).max(0.0);
            cutting.force_on_slide_lbf(x_c, phi, d, f)
        } else {
            0.0
        };
        w.rig.set_force_lbf(force);
        if ts >= t_meas {
            fsq += e * e;
            fn_ += 1.0;
            fpk = fpk.max(e.abs());
            let bin = ((turns.rem_euclid(1.0)) * n_phi as f64) as usize % n_phi;
            let b = &mut bins[bin];
            b.0 += e;
            b.1 += e * e;
            b.2 += 1.0;
            // CMM angles crossed this tick.
            if let Some(lt) = last_turns {
                let (a0, a1) = (lt * n_phi as f64, turns * n_phi as f64);
                let mut k = a0.floor() as i64 + 1;
                while (k as f64) <= a1 {
                    let j = k.rem_euclid(n_phi as i64) as usize;
                    let delta = x_c - x_m;
                    if delta.abs() <= 10.0 * f {
                        let cut = part_side * e - delta * delta / (2.0 * r);
                        best[j] = Some(best[j].map_or(cut, |b: f64| b.max(cut)));
                    }
                    if delta.abs() <= f / 2.0 {
                        trace.push((360.0 * j as f64 / n_phi as f64, -part_side * e));
                    }
                    k += 1;
                }
            }
        }
        last_turns = Some(turns);
        if w.fw.fault().is_some() {
            break;
        }
    }
    let excess_in = (0..n_phi)
        .map(|j| {
            let phi = std::f64::consts::TAU * j as f64 / n_phi as f64;
            if cutting.bolt_holes.over_hole(x_m, phi) {
                None
            } else {
                best[j].map(|b| -part_side * b)
            }
        })
        .collect();
    let (mut hf, mut hn) = (0.0, 0.0);
    for b in &bins {
        if b.2 > 1.0 {
            hf += b.1 - b.0 * b.0 / b.2;
            hn += b.2;
        }
    }
    Band {
        x_in: x_m,
        excess_in,
        following_sq: fsq,
        following_n: fn_,
        following_peak: fpk,
        finish_hf_rms_in: if hn > 0.0 { (hf / hn).sqrt() } else { 0.0 },
        faults: w
            .fw
            .fault()
            .map(|f| vec![format!("X {x_m} in: {f:?}: {}", f.reason())])
            .unwrap_or_default(),
        simulated_s: t as f64 * 1e-9,
        trace,
    }
}

/// RMS of the feed marks' scallop: f²/(8r) peak to valley, a parabola.
pub fn cusp_rms_in(feed_in: f64, tool_radius_in: f64) -> f64 {
    feed_in * feed_in / (8.0 * tool_radius_in) * 2.0 / (3.0 * 5f64.sqrt())
}

/// Runs the bands (in parallel) and assembles the report.
pub fn run(
    sc: &Scenario,
    spec: &CutSpec,
    progress: Option<&indicatif::ProgressBar>,
) -> (CutReport, Vec<Band>) {
    let t0 = std::time::Instant::now();
    let bands: Vec<Band> = CMM_X_IN
        .par_iter()
        .map(|&x| {
            let b = band(sc, spec, x);
            if let Some(p) = progress {
                p.inc(1);
            }
            b
        })
        .collect();
    let wall_s = t0.elapsed().as_secs_f64();
    let n_phi = CMM_PHI_STEPS;
    let grid: Vec<Vec<Option<f64>>> = (0..n_phi)
        .map(|j| {
            bands
                .iter()
                .map(|b| b.excess_in[j].map(|v| v * 1e6))
                .collect()
        })
        .collect();
    let vals: Vec<f64> = grid.iter().flatten().flatten().copied().collect();
    let (fsq, fnn): (f64, f64) = bands.iter().fold((0.0, 0.0), |a, b| {
        (a.0 + b.following_sq, a.1 + b.following_n)
    });
    let cusp = cusp_rms_in(spec.feed_per_rev_in, sc.cutting.tool_radius_in);
    let finish_by: Vec<f64> = bands
        .iter()
        .map(|b| (b.finish_hf_rms_in.powi(2) + cusp * cusp).sqrt() * 1e6)
        .collect();
    let report = CutReport {
        contour_error_min_uin: vals.iter().copied().fold(f64::INFINITY, f64::min),
        contour_error_max_uin: vals.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        following_error_rms_uin: (fsq / fnn.max(1.0)).sqrt() * 1e6,
        following_error_peak_uin: bands.iter().map(|b| b.following_peak).fold(0.0, f64::max) * 1e6,
        finish_rms_uin: (finish_by.iter().map(|v| v * v).sum::<f64>() / finish_by.len() as f64)
            .sqrt(),
        finish_rms_by_radius_uin: finish_by,
        simulated_s: bands.iter().map(|b| b.simulated_s).sum(),
        wall_s,
        faults: bands.iter().flat_map(|b| b.faults.clone()).collect(),
        cmm_grid_uin: grid,
        phi_deg: (0..n_phi)
            .map(|j| 360.0 * j as f64 / n_phi as f64)
            .collect(),
        x_in: CMM_X_IN.to_vec(),
        rpm: spec.rpm,
        holes: spec.holes,
        controller: match spec.controller {
            Controller::Digital => "digital",
            Controller::LegacyAnalog => "legacy-analog",
        }
        .into(),
        scenario: sc.file.name.clone(),
    };
    (report, bands)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scallop left by a still slide: the lower envelope of circles of
    /// radius r every f, sampled finely, has peak to valley f²/(8r) and the
    /// RMS `cusp_rms_in` gives (to the parabola's approximation).
    #[test]
    fn feed_mark_rms_matches_the_envelope_of_the_nose() {
        let (f, r) = (100e-6, 0.125);
        let n = 2000;
        let ys: Vec<f64> = (0..n)
            .map(|i| {
                let x = f * (i as f64 / n as f64 - 0.5);
                // nearest passes at −f/2.. +f/2 around the sample
                [-1.0, 0.0, 1.0]
                    .iter()
                    .map(|k| {
                        let d = x - k * f + f / 2.0 - f / 2.0;
                        r - (r * r - d * d).sqrt()
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        let mean = ys.iter().sum::<f64>() / n as f64;
        let rms = (ys.iter().map(|y| (y - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        let pv = ys.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - ys.iter().cloned().fold(f64::INFINITY, f64::min);
        assert!((pv / (f * f / (8.0 * r)) - 1.0).abs() < 1e-3, "{pv}");
        assert!(
            (rms / cusp_rms_in(f, r) - 1.0).abs() < 1e-2,
            "{rms} vs {}",
            cusp_rms_in(f, r)
        );
    }
}
