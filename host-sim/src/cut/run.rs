//! One stretch of the pass on the simulated machine: the real firmware
//! (`fwrig::machine_demo`: `loop_tick`, `x_event`, `index_event` through
//! the core drivers) with the cutting physics of [`super::engage`] applied
//! at every loop tick, and the tool-centre path recorded where the CMM
//! measures.

use super::engage::Engagement;
use super::errors::ErrorState;
use super::frame;
use super::nominal::Command;
use super::part::{Pass, PassLog, CMM_PHI_COUNT};
use crate::fwrig::{Machine, TickHook};
use crate::plant::Rig;
use zslide::firmware::Firmware;

/// Cutting force that counts as full spindle load (a 0.010 in roughing cut
/// at the outer edge, 3–4 A on the slide: 10 lbf at 7.25 in).
const FULL_LOAD_LBF_IN: f64 = 10.0 * 7.25;

/// How a stretch's tool meets the stock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Entry {
    /// The pass's own start: the tool feeds in from outside the stock,
    /// whose rim lies at this tool-centre X, in (the nose's chord grows
    /// over it: `engage`). The only engagement a facing pass has.
    Rim(f64),
    /// A band inside the part: the pre-roll runs with the tool clear of
    /// the stock while the firmware arms, references X and follows the
    /// table, as a continuous pass does before its rim; at the settle time
    /// (and the firmware following its table) the whole chord is in the
    /// stock at once, the stock being what the previous pass left from
    /// there on. The chord's force comes in over `ENTRY_RAMP_REVS`
    /// revolutions: a band stands for the middle of a continuous pass,
    /// whose chord grew in over the rim's 87 (`Rim`), and a whole-chord
    /// step is a tool crash, not a band (contour monitoring latches it).
    AfterPreroll,
    /// The tool in the stock from the first tick, the loop engaging onto
    /// the running cut (a fault campaign's stretch).
    InStock,
}

/// Revolutions over which a band's chord force comes in after its
/// pre-roll (`Entry::AfterPreroll`): nine times as fast as the real rim's
/// growth (the chord over the feed, 8660 / 100 µin), so the band's
/// recording, 40 revolutions later, sees the learning settled on the
/// whole chord.
pub const ENTRY_RAMP_REVS: f64 = 10.0;

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
    /// The passes at a rectangular grid's angles (`cut --grid`).
    pub grid: Option<super::gridcut::AngleLog>,
    /// The hole zone's envelope (`holezone`), on its stretches.
    pub zone: Option<super::holezone::ZoneLog>,
    /// Largest |coil current| while recording (the grid's or the zone's
    /// windows), A.
    pub current_peak_a: f64,
    /// The tool's lowest point against the finished surface while it cuts
    /// (any tick with a cutting force, the engagement and the preroll
    /// included: not only the recording windows), in; +∞ if it never cut.
    pub deepest_in: f64,
}

/// The cutting physics and recorder, run by `FirmwareWorld::tick`.
pub struct Cutter {
    eng: Engagement,
    nominal: Command,
    index_phase_turns: f64,
    /// Recording windows of tool-centre X, in (lo, hi).
    windows: Vec<(f64, f64)>,
    /// Tick-by-tick trace window (time, s).
    trace_window: (f64, f64),
    /// Time at which the start-up transient is over and the stock memory
    /// starts afresh, s (∞ once done).
    settle_s: f64,
    entry: Entry,
    /// The spindle's turns when a band's chord met the stock
    /// (`Entry::AfterPreroll`; `None` before, or another entry).
    entered_turns: Option<f64>,
    prev: Option<(f64, f64, f64)>,
    rev: i64,
    rev_force_sum: f64,
    rev_force_n: u32,
    prev_turns: Option<f64>,
    pub log: StretchLog,
    /// A force added to the cutting force from now on, lbf (+Z: a hard
    /// spot or a wedged chip pushing the tool out; a fault campaign's
    /// injection; 0 in a plain cut).
    pub extra_force_lbf: f64,
    /// At the last tick: the tool (slide carriage, true) minus the nominal
    /// command at the true X and φ, in; negative = into the part.
    pub last_error_in: f64,
    /// The error sources beyond the loop (`errors`), and the sign of the
    /// nominal the part is cut and measured against (−1: the 1983 command
    /// generator's reversed sign, measured against the reversed nominal).
    pub errors: Option<ErrorState>,
    pub nominal_sign: f64,
    /// The slide's electrical constants for the amplifier hum's force:
    /// (Kf lbf/A, K_A V/V, R Ω, L/R s).
    pub drive: (f64, f64, f64, f64),
    /// The 1983 command generator, when it makes the 1983 loop's command.
    pub command1983: Option<super::command1983::AnalogCommand>,
    /// A compensated table's axial slide program against the nominal's.
    pub axial: Option<std::sync::Arc<crate::part::axial::AxialProgram>>,
}

impl Cutter {
    /// The tool's engagement with the stock (its cutting constants).
    pub fn engagement_mut(&mut self) -> &mut Engagement {
        &mut self.eng
    }

    pub fn new(
        eng: Engagement,
        nominal: impl Into<Command>,
        index_phase_turns: f64,
        windows: Vec<(f64, f64)>,
        trace_window: (f64, f64),
        settle_s: f64,
        entry: Entry,
    ) -> Self {
        let mut eng = eng;
        let settle_s = match entry {
            Entry::Rim(rim) => {
                eng.set_rim(rim);
                f64::INFINITY
            }
            Entry::AfterPreroll => {
                eng.set_rim(f64::NEG_INFINITY);
                settle_s
            }
            Entry::InStock => settle_s,
        };
        Self {
            settle_s,
            entry,
            entered_turns: None,
            eng,
            nominal: nominal.into(),
            index_phase_turns,
            windows,
            trace_window,
            prev: None,
            rev: i64::MIN,
            rev_force_sum: 0.0,
            rev_force_n: 0,
            prev_turns: None,
            log: StretchLog {
                passes: PassLog::new(),
                deepest_in: f64::INFINITY,
                ..StretchLog::default()
            },
            extra_force_lbf: 0.0,
            last_error_in: 0.0,
            errors: None,
            nominal_sign: 1.0,
            drive: (0.0, 0.0, 1.0, 0.0),
            command1983: None,
            axial: None,
        }
    }

    fn recording(&self, x: f64) -> bool {
        self.windows.iter().any(|&(lo, hi)| x >= lo && x <= hi)
    }
}

impl TickHook for Cutter {
    fn before_tick(&mut self, rig: &mut Rig, m: &Machine, fw: &Firmware) {
        let t = rig.t_ns;
        let t_s = t as f64 * 1e-9;
        let x_read = m.x_true_in(t_s);
        let turns = m.spindle.borrow_mut().turns_at(t) + self.index_phase_turns;
        // The command's angle (increasing with time) and the part's under
        // the tool (`frame`: the part turns the other way round).
        let phi = crate::fastmath::frac(turns);
        let phi_p = frame::part_turns(phi);
        // The tool rides on the slide carriage (not on the coil frame the
        // gauge also sees).
        let z_slide = rig.slide.position_in();
        if let Some(g) = self.command1983.as_mut() {
            let q = rig.quad.state.borrow();
            let c_v = [q.volts(0), q.volts(1), q.volts(2), q.volts(3)];
            drop(q);
            let engaged = fw.table_code() != 0;
            g.tick(
                t_s,
                turns - self.index_phase_turns,
                c_v,
                engaged,
                fw.target_code(),
            );
        }
        let d_turns = self.prev_turns.map_or(0.0, |p| turns - p);
        self.prev_turns = Some(turns);
        let (x, z, hum) = match self.errors.as_mut() {
            None => (x_read, z_slide, 0.0),
            Some(er) => {
                let x = er.x_part(x_read);
                if er.gauge_active() {
                    rig.gauge_injection_in = er.gauge_error_in(rig.slide.gauge_position_in(), x);
                }
                let (kf, ka, r, tau) = self.drive;
                let hum = er.hum_force_lbf(t_s, kf, ka, r, tau);
                (x, z_slide + er.tool_offset_in(t_s, x, phi_p, d_turns), hum)
            }
        };
        // The axial slide on a compensated program carries the tool by
        // its ΔY(X) against the nominal's.
        let z = z + self.axial.as_ref().map_or(0.0, |a| a.at(x));
        let nom = self.nominal_sign * self.nominal.fast(x, phi);
        let e = z - nom;
        // A band enters the stock once the digital firmware (when it
        // drives the slide) follows its table: its command before that is
        // not the part's.
        let following = !fw.amplifier_enable() || fw.table_code() != 0;
        if t_s >= self.settle_s && (self.entry != Entry::AfterPreroll || following) {
            self.eng.reset_memory();
            if self.entry == Entry::AfterPreroll {
                self.eng.set_rim(f64::INFINITY);
                self.entered_turns = Some(turns);
            }
            self.settle_s = f64::INFINITY;
        }
        self.last_error_in = e;
        let mut c = self.eng.step(x, phi, e);
        if let Some(er) = self.errors.as_ref() {
            c.force_lbf *= er.force_speed_factor(x);
        }
        if let Some(t0) = self.entered_turns {
            c.force_lbf *= ((turns - t0) / ENTRY_RAMP_REVS).clamp(0.0, 1.0);
        }
        if c.force_lbf != 0.0 {
            self.log.deepest_in = self.log.deepest_in.min(e);
        }
        // The chip's broadband force acts on the tool and on the part; the
        // part's overhang mode takes the whole force at the tool's radius.
        let noise = match self.errors.as_mut() {
            None => 0.0,
            Some(er) => {
                let n = er.force_noise_lbf();
                er.drive_part(t_s, x, c.force_lbf + n + self.extra_force_lbf);
                n
            }
        };
        rig.set_force_lbf(c.force_lbf + noise + self.extra_force_lbf + hum);

        // Spindle load, once per revolution (the speed sags over seconds).
        let rev = crate::fastmath::floor_i64(turns);
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
            let fe = z_slide - nom;
            self.log.current_peak_a = self.log.current_peak_a.max(rig.slide.current_a().abs());
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
                let k0 = crate::fastmath::floor_i64(turns0 * n);
                let k1 = crate::fastmath::floor_i64(turns * n);
                for k in (k0 + 1)..=k1 {
                    let tc = k as f64 / n;
                    let w = (tc - turns0) / (turns - turns0);
                    let xc = x0 + (x - x0) * w;
                    let zc = z0 + (z - z0) * w;
                    // The part's angle of this command angle: its CMM row.
                    let i = frame::part_index(k, CMM_PHI_COUNT);
                    let ec = zc - self.nominal_sign * self.nominal.exact(xc, i as f64 / n);
                    self.log.passes.by_phi[i].push(Pass { x_in: xc, e_in: ec });
                }
                if let Some(g) = self.log.grid.as_mut() {
                    let (nominal, sign) = (&self.nominal, self.nominal_sign);
                    g.record((turns0, x0, z0), (turns, x, z), |x, p| {
                        sign * nominal.exact(x, p)
                    });
                }
            }
            self.prev = Some((turns, x, z));
        } else {
            self.prev = None;
        }
        if let Some(zl) = self.log.zone.as_mut() {
            if zl.recording(x) {
                self.log.current_peak_a = self.log.current_peak_a.max(rig.slide.current_a().abs());
                if let Some((turns0, x0, z0)) = zl.prev {
                    let n = super::holezone::PHI_COUNT as f64;
                    for (k, i) in super::holezone::ZoneLog::crossings(turns0, turns) {
                        let w = (k as f64 / n - turns0) / (turns - turns0);
                        let xc = x0 + (x - x0) * w;
                        let zc = z0 + (z - z0) * w;
                        let ec = zc - self.nominal_sign * self.nominal.exact(xc, i as f64 / n);
                        zl.add(i, xc, ec);
                    }
                }
                zl.prev = Some((turns, x, z));
            } else {
                zl.prev = None;
            }
        }
    }
}
