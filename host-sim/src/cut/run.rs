//! One stretch of the pass on the simulated machine: the real firmware
//! (`fwrig::machine_demo`: `loop_tick`, `x_event`, `index_event` through
//! the core drivers) with the cutting physics of [`super::engage`] applied
//! at every loop tick, and the tool-centre path recorded where the CMM
//! measures.

use super::engage::Engagement;
use super::part::{Pass, PassLog, CMM_PHI_COUNT};
use crate::coeffgen::{eval_sin_power, harmonics};
use crate::fwrig::{Machine, TickHook};
use crate::plant::Rig;
use crate::surface::Surface;
use std::cell::RefCell;
use std::f64::consts::TAU;
use std::rc::Rc;
use zslide::firmware::Firmware;

/// Gauge codes per inch (2¹⁹ codes = 0.010 in).
pub const CODES_PER_IN: f64 = (1u32 << 19) as f64 / 0.010;

/// Sin-power terms of the per-tick nominal (harmonics 0..8: below 1e-4 µin
/// truncation at 7.2 in, like the default table's five).
const NOMINAL_TERMS: usize = 9;
/// X travel after which the per-tick nominal is re-expanded, in. It only
/// sets the depth of cut of the force law (the CMM uses the exact Z):
/// |∂Z/∂X| < 0.002 makes it < 0.1 µin of a 300 µin depth. (At 5 µin the
/// re-expansion was 15 % of a simulated second under callgrind.)
const NOMINAL_REFRESH_IN: f64 = 50e-6;

/// Cutting force that counts as full spindle load (a 0.010 in roughing cut
/// at the outer edge, 3–4 A on the slide: 10 lbf at 7.25 in).
const FULL_LOAD_LBF_IN: f64 = 10.0 * 7.25;

/// What one stretch records.
#[derive(Clone, Debug, Default)]
pub struct StretchLog {
    pub passes: PassLog,
    /// Following error (the slide's true position minus the exact command
    /// at the true X and φ), over the
    /// recording windows: Σe², n, max |e|, in.
    pub fe_sum_sq: f64,
    pub fe_n: u64,
    pub fe_peak: f64,
    /// (t s, following error µin, force lbf) of every tick of the trace
    /// window.
    pub trace: Vec<(f64, f64, f64)>,
    /// Mean cutting force while recording, lbf.
    pub force_sum: f64,
}

/// The cutting physics and recorder, run by `FirmwareWorld::tick`.
pub struct Cutter {
    eng: Engagement,
    surf: Surface,
    x_null: f64,
    index_phase_turns: f64,
    /// Recording windows of tool-centre X, in (lo, hi).
    windows: Vec<(f64, f64)>,
    /// Tick-by-tick trace window (time, s).
    trace_window: (f64, f64),
    /// Time at which the start-up transient is over and the stock memory
    /// starts afresh, s (NaN once done).
    settle_s: f64,
    nominal: Vec<f64>,
    nominal_x: f64,
    prev: Option<(f64, f64, f64)>,
    rev: i64,
    rev_force_sum: f64,
    rev_force_n: u32,
    pub log: StretchLog,
    /// A force added to the cutting force from now on, lbf (+Z: a hard
    /// spot or a wedged chip pushing the tool out; a fault campaign's
    /// injection; 0 in a plain cut).
    pub extra_force_lbf: f64,
    /// At the last tick: the tool (slide carriage, true) minus the nominal
    /// command at the true X and φ, in; negative = into the part.
    pub last_error_in: f64,
}

impl Cutter {
    pub fn new(
        eng: Engagement,
        surf: Surface,
        x_null: f64,
        index_phase_turns: f64,
        windows: Vec<(f64, f64)>,
        trace_window: (f64, f64),
        settle_s: f64,
    ) -> Self {
        Self {
            settle_s,
            eng,
            surf,
            x_null,
            index_phase_turns,
            windows,
            trace_window,
            nominal: vec![0.0; NOMINAL_TERMS],
            nominal_x: f64::NAN,
            prev: None,
            rev: i64::MIN,
            rev_force_sum: 0.0,
            rev_force_n: 0,
            log: StretchLog {
                passes: PassLog::new(),
                ..StretchLog::default()
            },
            extra_force_lbf: 0.0,
            last_error_in: 0.0,
        }
    }

    /// Exact Z command at tool-centre `x` and angle φ (turns): the part's
    /// nominal; zero on the face beyond the table's null zone.
    fn exact_z(&self, x: f64, phi_turns: f64) -> f64 {
        if x >= self.x_null || x < 0.0 {
            return 0.0;
        }
        self.surf.z(x, phi_turns * TAU).unwrap_or(0.0)
    }

    fn nominal_now(&mut self, x: f64, phi_turns: f64) -> f64 {
        if x >= self.x_null || x < 0.0 {
            return 0.0;
        }
        if (x - self.nominal_x).abs() >= NOMINAL_REFRESH_IN || self.nominal_x.is_nan() {
            match self.surf.section(x) {
                Ok(sec) => {
                    self.nominal = harmonics(&sec, NOMINAL_TERMS - 1).sin_power(NOMINAL_TERMS)
                }
                Err(_) => self.nominal.iter_mut().for_each(|c| *c = 0.0),
            }
            self.nominal_x = x;
        }
        eval_sin_power(&self.nominal, (phi_turns * TAU).sin())
    }

    fn recording(&self, x: f64) -> bool {
        self.windows.iter().any(|&(lo, hi)| x >= lo && x <= hi)
    }
}

impl TickHook for Cutter {
    fn before_tick(&mut self, rig: &mut Rig, m: &Machine, _fw: &Firmware) {
        let t = rig.t_ns;
        let t_s = t as f64 * 1e-9;
        let x = m.x_true_in(t_s);
        let turns = m.spindle.borrow_mut().turns_at(t) + self.index_phase_turns;
        let phi = turns.rem_euclid(1.0);
        // The tool rides on the slide carriage (not on the coil frame the
        // gauge also sees).
        let z = rig.slide.position_in();
        let e = z - self.nominal_now(x, phi);
        if t_s >= self.settle_s {
            self.eng.reset_memory();
            self.settle_s = f64::INFINITY;
        }
        self.last_error_in = e;
        let c = self.eng.step(x, phi, e);
        rig.set_force_lbf(c.force_lbf + self.extra_force_lbf);

        // Spindle load, once per revolution (the speed sags over seconds).
        let rev = turns.floor() as i64;
        self.rev_force_sum += c.force_lbf.abs();
        self.rev_force_n += 1;
        if rev != self.rev {
            if self.rev_force_n > 0 {
                let mean = self.rev_force_sum / f64::from(self.rev_force_n);
                m.spindle
                    .borrow_mut()
                    .model_mut()
                    .set_load((mean * x / FULL_LOAD_LBF_IN).min(1.0));
            }
            self.rev = rev;
            self.rev_force_sum = 0.0;
            self.rev_force_n = 0;
        }

        if self.recording(x) {
            // The tool against the exact surface command at the true X and
            // φ (as `track`): what the part sees, whatever the controller.
            let fe = e;
            self.log.fe_sum_sq += fe * fe;
            self.log.fe_n += 1;
            self.log.fe_peak = self.log.fe_peak.max(fe.abs());
            self.log.force_sum += c.force_lbf;
            if t_s >= self.trace_window.0 && t_s < self.trace_window.1 {
                self.log.trace.push((t_s, fe * 1e6, c.force_lbf));
            }
            // CMM angles crossed since the last tick: the tool centre there,
            // interpolated between the two ticks.
            if let Some((turns0, x0, z0)) = self.prev {
                let n = CMM_PHI_COUNT as f64;
                let k0 = (turns0 * n).floor() as i64;
                let k1 = (turns * n).floor() as i64;
                for k in (k0 + 1)..=k1 {
                    let tc = k as f64 / n;
                    let w = (tc - turns0) / (turns - turns0);
                    let xc = x0 + (x - x0) * w;
                    let zc = z0 + (z - z0) * w;
                    let i = k.rem_euclid(CMM_PHI_COUNT as i64) as usize;
                    let ec = zc - self.exact_z(xc, i as f64 / n);
                    self.log.passes.by_phi[i].push(Pass { x_in: xc, e_in: ec });
                }
            }
            self.prev = Some((turns, x, z));
        } else {
            self.prev = None;
        }
    }
}

/// A shareable cutter: the world owns one handle, the driver reads the
/// log through the other.
pub struct SharedCutter(pub Rc<RefCell<Cutter>>);

impl TickHook for SharedCutter {
    fn before_tick(&mut self, rig: &mut Rig, m: &Machine, fw: &Firmware) {
        self.0.borrow_mut().before_tick(rig, m, fw);
    }
}
