//! `cut`: the finishing pass of chapter 5 (Figure 5-3) on the simulated
//! machine, and the part it leaves, measured like Table 5-2.
//!
//! * [`engage`]: the tool's engagement with the stock and the cutting force
//!   on the slide, every loop tick;
//! * [`nominal`]: the exact command at the true X and φ, exact and per tick;
//! * [`run`]: one stretch of the pass through the real firmware
//!   (`fwrig`), recording the tool-centre path at the CMM angles;
//! * [`part`]: the surface as the envelope of the tool nose, the CMM grid,
//!   the finish;
//! * [`plot`]: the plots, their CSV and the VCD of `--out`.
//!
//! A pass is planned as stretches ([`plan`]): by default one band per CMM
//! radius (the revolutions whose nose arcs form the surface there, after a
//! pre-roll that brings the firmware, the slide and the stock memory to
//! the state they have at that radius in a whole pass), run in parallel;
//! `--full` one stretch from the outer edge to the axis. Every stretch is
//! seeded from the scenario seed and its index: a run is reproducible.
//!
//! Conventions and the model: docs/CUT.md.

pub mod budget;
pub mod cmm;
pub mod command1983;
pub mod engage;
pub mod errors;
pub mod frame;
pub mod errmap;
pub mod gridcut;
pub mod holezone;
pub mod interruptions;
pub mod zoneplot;
pub mod nominal;
pub mod part;
pub mod partcut;
pub mod plot;
pub mod rectgrid;
pub mod ringing;
pub mod run;
pub mod sensitivity;
pub mod sign;
pub mod test_cut;

use crate::cut::part::{CmmGrid, PassLog, CMM_X_IN};
use crate::cut::run::{Cutter, StretchLog};
use crate::fwrig::machine_with_table;
use crate::machine::XInterface;
use crate::scenario::Scenario;
use crate::surface::Surface;
use anyhow::{bail, Context};
use rayon::prelude::*;
use std::cell::RefCell;
use std::rc::Rc;
use std::time::Instant;

pub use crate::fwrig::Controller;

/// Bolt holes of the part face.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Holes {
    /// Open countersunk holes: interrupted cut (the first part).
    Open,
    /// Filled with cast material (the second part).
    Filled,
}

impl Holes {
    /// As the flag spells it.
    pub fn name(self) -> &'static str {
        match self {
            Holes::Open => "open",
            Holes::Filled => "filled",
        }
    }
}

/// Everything a pass needs.
#[derive(Clone, Debug)]
pub struct CutSpec {
    pub scenario: Scenario,
    pub controller: Controller,
    /// Spindle speed, rpm.
    pub rpm: f64,
    pub holes: Holes,
    /// Depth of cut, in (chapter 5: 0.0003).
    pub depth_in: f64,
    /// Feed per revolution, in (positive; the pass feeds toward the axis).
    pub feed_per_rev_in: f64,
    /// Half width of a band (tool-centre X recorded around each CMM radius), in.
    pub band_half_in: f64,
    /// Revolutions simulated before a band's recording starts.
    pub preroll_revs: f64,
    pub full: bool,
    /// Where the full pass starts (tool-centre X, in).
    pub x_start_in: f64,
    /// Offset added to the firmware's Z command (its target), in:
    /// positive lifts the tool off the part and leaves stock.
    pub z_offset_in: f64,
    /// A part of one's own (`cut --part`); `None`: the default table's.
    pub part: Option<std::sync::Arc<partcut::PartCut>>,
    /// Which error sources beyond the loop are applied, and their levels
    /// (`errors`; the scenario's `[errors]`).
    pub errors: errors::Selection,
    pub error_levels: errors::ErrorLevels,
    /// The command generator's sign (`sign`).
    pub command_sign: sign::CommandSign,
    /// How the grid is measured (`cmm`), and how many CMM readings of
    /// the part are averaged (`cmm::read_averaged`; 1: one reading).
    pub measure: cmm::Measure,
    pub cmm_readings: u32,
    /// A rectangular grid instead of the polar one (`cut --part --grid`).
    pub grid: Option<std::sync::Arc<rectgrid::RectGrid>>,
    /// Also measure the hole zone (`holezone`: bands across the bolt
    /// circle's ring, a dense grid around it).
    pub hole_zone: bool,
    /// The default part cut with this table instead of the default one
    /// (`cut --table` without `--part`).
    pub table_image: Option<&'static [u8]>,
    /// The digital firmware anticipates the edges of the open holes of its
    /// interruption block (`zslide::servo::edges`); `false`: it gets the
    /// block (contour monitoring stands down over the holes) with
    /// `edge_feedforward` 0.
    pub anticipate: bool,
    /// Added to every hole's angle in the block the firmware gets (not to
    /// the part the tool cuts), degrees: a part program that has the holes
    /// wrong.
    pub block_angle_error_deg: f64,
    /// A compensated table's axial slide program against the nominal's
    /// (`crate::part::axial::AxialProgram`): added to the tool's height.
    pub axial: Option<std::sync::Arc<crate::part::axial::AxialProgram>>,
}

impl CutSpec {
    /// The pass of chapter 5 on `scenario`: its spindle speed unless
    /// `rpm` is given, its feed read as a feed per revolution at its own
    /// speed (−0.03 in/min at 300 rpm = 100 µin/rev), its holes unless
    /// `holes` is given, its depth of cut (`[servo] depth_of_cut_uin`).
    pub fn chapter5(
        scenario: Scenario,
        controller: Controller,
        rpm: Option<f64>,
        holes: Option<Holes>,
        full: bool,
    ) -> anyhow::Result<Self> {
        let f = &scenario.file;
        if f.x.feed_in_per_min >= 0.0 {
            bail!(
                "scenario {}: x.feed_in_per_min = {} — the finishing pass feeds toward the axis, it must be negative",
                f.name,
                f.x.feed_in_per_min
            );
        }
        let feed_per_rev_in = -f.x.feed_in_per_min / f.spindle.rpm;
        let rpm = rpm.unwrap_or(f.spindle.rpm);
        let (lo, hi) = (f64::from(f.spindle.min_rpm), f64::from(f.spindle.max_rpm));
        if !(rpm.is_finite() && rpm >= lo && rpm <= hi) {
            bail!(
                "--rpm {rpm}: outside the speed band the firmware of scenario {} accepts ({lo}..{hi} rpm, spindle.min_rpm/max_rpm)",
                f.name
            );
        }
        let holes = holes.unwrap_or(if scenario.cutting.bolt_holes.filled {
            Holes::Filled
        } else {
            Holes::Open
        });
        check_part_side(scenario.cutting.part_side)
            .with_context(|| format!("scenario {}", f.name))?;
        // The holes as the firmware's interruption block would carry them:
        // a set it would refuse is refused before the pass.
        interruptions::block_of(&scenario.cutting.bolt_holes)
            .with_context(|| format!("scenario {}", f.name))?;
        let error_levels = scenario.file.errors.clone();
        let depth_in = scenario.servo_design.depth_of_cut_uin / 1e6;
        Ok(Self {
            x_start_in: f.x.x0_in,
            scenario,
            controller,
            rpm,
            holes,
            depth_in,
            feed_per_rev_in,
            band_half_in: 0.01,
            preroll_revs: 60.0,
            full,
            z_offset_in: 0.0,
            part: None,
            // The 1983 loop cuts on the shop's machine as chapter 5 had
            // it; the digital loop's figures are its own contribution,
            // with the sources in the budget (docs/CUT.md).
            errors: match controller {
                Controller::LegacyAnalog => errors::Selection::All,
                Controller::Digital => errors::Selection::None,
            },
            error_levels,
            command_sign: sign::CommandSign::Normal,
            measure: cmm::Measure::Exact,
            cmm_readings: 1,
            grid: None,
            hole_zone: false,
            table_image: None,
            axial: None,
            anticipate: true,
            block_angle_error_deg: 0.0,
        })
    }

    /// Cuts `depth_in` deep, and tells the firmware so: its
    /// `depth_of_cut_uin` set as a parameter set over the link is
    /// (checked, the design refusing in its words).
    pub fn set_depth_in(&mut self, depth_in: f64) -> anyhow::Result<()> {
        let p = zslide::params::by_name("depth_of_cut_uin")
            .ok_or_else(|| anyhow::anyhow!("the firmware has no depth_of_cut_uin parameter"))?;
        let (design, cfg) = zslide::params::set(&self.scenario.servo_design, p.id, depth_in * 1e6)
            .map_err(|e| anyhow::anyhow!("--depth-in {depth_in}: {e}"))?;
        self.scenario.servo_design = design;
        self.scenario.servo = cfg;
        self.depth_in = depth_in;
        Ok(())
    }

    /// The hole zone's grid when this cut measures it: the scenario's
    /// bolt holes (filled as `holes` says) on the part the pass cuts.
    pub fn zone_grid(&self) -> anyhow::Result<Option<holezone::ZoneGrid>> {
        if !self.hole_zone || self.grid.is_some() {
            return Ok(None);
        }
        let gain = self.contact_gain()?;
        let holes = crate::plant::cutting::BoltHoles {
            filled: self.holes == Holes::Filled,
            ..self.scenario.cutting.bolt_holes.clone()
        };
        Ok(holezone::ZoneGrid::new(
            &holes,
            gain,
            self.x_start_in * gain,
        ))
    }

    /// Makes this cut pass `pass` of the same part on the same machine
    /// (a compensation cut: `pass` = the table's compensation steps): every
    /// noise stream (plant, X, spindle, the spindle's asynchronous error
    /// motion, the CMM) drawn afresh, while the deterministic sources (tool
    /// wear along the pass, the drifts' schedule, gauge scale and
    /// nonlinearity, X zero) repeat. Pass 0 is the scenario's own seeds.
    pub fn set_pass(&mut self, pass: u64) {
        if pass > 0 {
            self.scenario = seeded(&self.scenario, PASS_STREAMS + pass);
        }
    }

    /// The table image the firmware runs.
    pub fn table(&self) -> &'static [u8] {
        match (&self.part, self.table_image) {
            (Some(p), _) => p.table,
            (None, Some(t)) => t,
            (None, None) => zslide::DEFAULT_TABLE,
        }
    }

    /// The CMM that measures this cut (`--measure cmm`): chapter 5's,
    /// levelled on the part's face when the error sources are applied.
    pub fn cmm_levels(&self) -> cmm::CmmLevels {
        let face = match self.errors {
            errors::Selection::All => cmm::FaceLevelling::of(&self.error_levels),
            errors::Selection::None => cmm::FaceLevelling::default(),
        };
        cmm::CmmLevels::renault().levelled_on(face)
    }

    /// Radii the CMM measures (tool centre for a part, surface else), in.
    pub fn cmm_x(&self) -> Vec<f64> {
        self.part
            .as_ref()
            .map_or(CMM_X_IN.to_vec(), |p| p.cmm_x.clone())
    }

    /// Surface radius over tool-centre radius of a contact (FOREX4's
    /// constant gain for the default part; 1 for a part, whose CMM radii
    /// are tool-centre radii: `partcut`).
    pub fn contact_gain(&self) -> anyhow::Result<f64> {
        match &self.part {
            Some(_) => Ok(1.0),
            None => Ok(self.surface()?.0.contact_gain()),
        }
    }

    /// The levels this cut applies.
    pub fn applied_levels(&self) -> Option<errors::ErrorLevels> {
        match self.errors {
            errors::Selection::None => None,
            errors::Selection::All => Some(self.error_levels.clone()),
        }
    }

    /// Feed, in/min (negative: toward the axis).
    pub fn feed_in_per_min(&self) -> f64 {
        -self.feed_per_rev_in * self.rpm
    }

    /// The part's nominal surface: the geometry of the firmware's table.
    pub fn surface(&self) -> anyhow::Result<(Surface, f64)> {
        let t = zslide::table::CoeffTable::parse(zslide::DEFAULT_TABLE)
            .map_err(|e| anyhow::anyhow!("default table refused: {e}"))?;
        let mut s = Surface::from_table_geometry(&t.header().geometry)
            .map_err(|e| anyhow::anyhow!("table geometry: {e}"))?;
        let r_t = self.scenario.cutting.tool_radius_in;
        if (r_t - s.tool_radius()).abs() > 1e-12 {
            bail!(
                "cutting.tool_radius_in = {r_t} but the firmware's table compensates for a {} in nose",
                s.tool_radius()
            );
        }
        s = s
            .with_tool_radius(r_t)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        Ok((s, t.x_null().to_f64()))
    }
}

/// The material of the concave paraboloid lies on the −Y_t side of the
/// surface (`Y(X)` of eq 2-14 rises with X: the face looks toward +Y_t),
/// so the stock pushes the tool toward +Z: `part_side` must be −1.
pub fn check_part_side(part_side: f64) -> anyhow::Result<()> {
    if part_side != -1.0 {
        bail!(
            "cutting.part_side = {part_side}: the part's material lies on the -Z side of the tool \
             (the concave face looks toward +Y_t, eq 2-14), so the stock pushes the slide toward \
             +Z: set part_side = -1"
        );
    }
    Ok(())
}

/// One stretch of the pass.
#[derive(Clone, Debug, PartialEq)]
pub struct Stretch {
    /// Tool-centre X where the simulation starts and ends, in.
    pub x_start_in: f64,
    pub x_end_in: f64,
    /// Recording windows (tool-centre X), in.
    pub windows: Vec<(f64, f64)>,
    /// Recording windows of the hole zone (tool-centre X), in.
    pub zone: Vec<(f64, f64)>,
    /// Stream index of its seeds.
    pub index: u64,
    /// How its tool meets the stock.
    pub entry: run::Entry,
}

/// Seed streams of the hole zone's stretches start here (the CMM bands
/// keep theirs, 1..).
pub const ZONE_SEED_BASE: u64 = 1000;

impl Stretch {
    pub fn seconds(&self, spec: &CutSpec) -> f64 {
        (self.x_start_in - self.x_end_in) / (spec.feed_per_rev_in * spec.rpm / 60.0)
    }
}

/// Seed stream of the rim's stretch.
pub const RIM_SEED: u64 = 999;

/// Revolutions the pass starts with the nose's leading point clear of the
/// stock: the legacy X chain's first half-mil event and the firmware's
/// table engaging happen in air, as a machinist starts a facing pass.
pub const RIM_CLEAR_REVS: f64 = 5.0;

/// Revolutions the rim's stretch runs after the chord is whole.
pub const RIM_AFTER_REVS: f64 = 30.0;

/// Tool-centre X of the stock's rim: the pass starts `RIM_CLEAR_REVS`
/// revolutions before the leading point of the nose (`sqrt(2 r_t d)`
/// ahead of the centre) meets it.
pub fn rim_in(spec: &CutSpec) -> f64 {
    let front = (2.0 * spec.scenario.cutting.tool_radius_in * spec.depth_in).sqrt();
    spec.x_start_in - front - RIM_CLEAR_REVS * spec.feed_per_rev_in
}

/// The stretch from the pass's start to the chord whole under the stock
/// and `RIM_AFTER_REVS` more: the rim engagement.
pub fn rim_stretch(spec: &CutSpec) -> Stretch {
    let f = spec.feed_per_rev_in;
    let chord = (2.0 * spec.scenario.cutting.tool_radius_in * spec.depth_in).sqrt() + f;
    let rim = rim_in(spec);
    Stretch {
        x_start_in: spec.x_start_in,
        x_end_in: (rim - chord - RIM_AFTER_REVS * f).max(0.0),
        windows: vec![],
        zone: vec![],
        index: RIM_SEED,
        entry: run::Entry::Rim(rim),
    }
}

/// The stretches of the pass: one band per CMM radius (the hole zone's
/// bands, then the rim's engagement after them), or the whole pass.
pub fn plan(spec: &CutSpec, contact_gain: f64) -> Vec<Stretch> {
    let f = spec.feed_per_rev_in;
    // The zone's grid needs the part's own gain; a plan asked with another
    // (a test's) has none.
    let zone = spec
        .zone_grid()
        .ok()
        .flatten()
        .map_or(Vec::new(), |g| g.windows(spec.band_half_in));
    let windows: Vec<(f64, f64)> = match &spec.grid {
        Some(g) => gridcut::windows(g, spec.band_half_in),
        None => spec
            .cmm_x()
            .iter()
            .map(|&x| {
                let xc = x / contact_gain;
                (xc - spec.band_half_in, xc + spec.band_half_in)
            })
            .collect(),
    };
    if spec.full {
        return vec![Stretch {
            x_start_in: spec.x_start_in,
            x_end_in: 0.0,
            windows,
            zone,
            index: 0,
            entry: run::Entry::Rim(rim_in(spec)),
        }];
    }
    let bands = windows
        .into_iter()
        .enumerate()
        .map(|(k, (lo, hi))| Stretch {
            x_start_in: hi + spec.preroll_revs * f,
            x_end_in: lo - 2.0 * f,
            windows: vec![(lo, hi)],
            zone: vec![],
            index: k as u64 + 1,
            entry: run::Entry::AfterPreroll,
        });
    let zone = zone.into_iter().enumerate().map(|(k, (lo, hi))| Stretch {
        x_start_in: hi + spec.preroll_revs * f,
        x_end_in: lo - 2.0 * f,
        windows: vec![],
        zone: vec![(lo, hi)],
        index: ZONE_SEED_BASE + k as u64,
        entry: run::Entry::AfterPreroll,
    });
    bands
        .chain(zone)
        .chain(std::iter::once(rim_stretch(spec)))
        .collect()
}

/// What a stretch returns.
#[derive(Debug, Default)]
pub struct StretchResult {
    pub log: StretchLog,
    pub simulated_s: f64,
    pub wall_s: f64,
    pub faults: Vec<String>,
    /// The hole edges' learned step (`zslide::servo::edges`) after every
    /// half second of machine time: (seconds from the stretch's start,
    /// DAC codes Q8).
    pub edge_steps_q8: Vec<(f64, i32)>,
}

/// Extra outputs of one stretch.
#[derive(Clone, Debug, Default)]
pub struct Extras {
    /// Write a VCD of `(from, to)` seconds after the recording starts.
    pub vcd: Option<(std::path::PathBuf, f64, f64)>,
    /// Keep a tick-by-tick trace of this many seconds of the recording.
    pub trace_s: f64,
}

/// Seed streams of later passes start here (stretches use 1..=8).
const PASS_STREAMS: u64 = 1 << 32;

/// Seeds of stretch `index` (0 = the scenario's own).
fn seeded(sc: &Scenario, index: u64) -> Scenario {
    let mut sc = sc.clone();
    if index == 0 {
        return sc;
    }
    let mix = index.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    sc.rig.seed ^= mix;
    match &mut sc.machine.x {
        XInterface::LegacyBcd(c) | XInterface::Quadrature(c) => c.seed ^= mix,
    }
    sc.machine.spindle.seed ^= mix;
    sc
}

/// A stretch ready to run: the world with the cutter hooked in and the
/// controller attached, its scheduler, and the cutter's other handle.
pub struct StretchRig {
    pub w: crate::fwrig::FirmwareWorld,
    pub s: crate::sched::Scheduler<crate::fwrig::FirmwareWorld>,
    pub cutter: Rc<RefCell<Cutter>>,
    /// When the first recording window starts, s.
    pub rec_start_s: f64,
    /// The stretch's length, s.
    pub total_s: f64,
}

/// Builds stretch `st` of `spec` with the coefficient table image `table`
/// (the firmware's default for a cut), keeping a tick-by-tick trace of
/// `trace_s` seconds of the recording.
pub fn build_stretch(
    spec: &CutSpec,
    st: &Stretch,
    trace_s: f64,
    table: &'static [u8],
) -> anyhow::Result<StretchRig> {
    let sc = seeded(&spec.scenario, st.index);
    let mut machine = sc.machine.clone();
    let feed = spec.feed_in_per_min();
    // The stretch is planned on the part; the X the machine reads is off
    // by the X-zero error (`errors`), so a band keeps its pre-roll on the
    // part whatever the error.
    let x_zero = spec.applied_levels().map_or(0.0, |l| l.x_zero_error_in);
    match &mut machine.x {
        XInterface::LegacyBcd(c) | XInterface::Quadrature(c) => {
            c.x0_in = st.x_start_in + x_zero;
            c.feed = vec![crate::machine::xslide::FeedSegment {
                t_start_s: 0.0,
                feed_in_per_min: feed,
            }];
        }
    }
    machine.spindle.rpm0 = spec.rpm;
    let generator = command1983_levels(spec, &machine)?;
    if generator.is_some() {
        // The 8080's coefficient output: C00..C03 to the quad DAC.
        machine.coefficient_output = true;
    }
    let mut cutting = sc.cutting.clone();
    cutting.bolt_holes.filled = spec.holes == Holes::Filled;
    // The engagement works in the command's angle; the holes are placed
    // in the part's (`frame`).
    cutting.bolt_holes.phase_deg = frame::command_deg_of_part(cutting.bolt_holes.phase_deg);
    let nominal: nominal::Command = match &spec.part {
        Some(p) => {
            let rt = cutting.tool_radius_in;
            if (rt - p.part.tool.nose_radius).abs() > 1e-12 {
                bail!(
                    "cutting.tool_radius_in = {rt} but part {} is tabled for a {} in nose (tool.nose_radius_in)",
                    p.name,
                    p.part.tool.nose_radius
                );
            }
            partcut::PartNominal::new(p.clone()).into()
        }
        None => {
            let (surf, x_null) = spec.surface()?;
            nominal::Nominal::new(surf, x_null).into()
        }
    };
    let eng = engage::Engagement::new(&cutting, spec.depth_in, spec.feed_per_rev_in);
    let total_s = st.seconds(spec);
    let v = feed / 60.0;
    let rec_start_s = st
        .windows
        .iter()
        .chain(&st.zone)
        .map(|&(_, hi)| (hi - st.x_start_in) / v)
        .fold(f64::INFINITY, f64::min)
        .max(0.0);
    let cutter = Rc::new(RefCell::new(Cutter::new(
        eng,
        nominal,
        machine.spindle.index_phase_turns,
        st.windows.clone(),
        (rec_start_s, rec_start_s + trace_s),
        // The slide starts at null, the firmware unreferenced: the stock
        // memory starts after a third of the pre-roll (at least 5 revs).
        (rec_start_s / 3.0).max(5.0 * 60.0 / spec.rpm),
        st.entry,
    )));
    {
        let mut c = cutter.borrow_mut();
        c.nominal_sign = spec.command_sign.factor();
        c.axial = spec.axial.clone();
        c.log.grid = spec.grid.as_deref().map(gridcut::AngleLog::of_grid);
        if !st.zone.is_empty() {
            if let Some(g) = spec.zone_grid()? {
                c.log.zone = Some(holezone::ZoneLog::new(
                    &g,
                    cutting.tool_radius_in,
                    spec.feed_per_rev_in,
                    st.zone.clone(),
                ));
            }
        }
        // The default part's axial path and contact radius (a part of
        // one's own, `--part`, keeps X as the radius and no axial term).
        let surf_for_errors = match &spec.part {
            None => Some(spec.surface()?.0),
            Some(_) => None,
        };
        c.errors = spec.applied_levels().map(|l| {
            let st = errors::ErrorState::new(
                l,
                spec.x_start_in,
                st.x_start_in,
                spec.feed_per_rev_in,
                spec.rpm,
                sc.rig.seed,
            );
            match surf_for_errors {
                Some(surf) => st.with_part(surf),
                None => st,
            }
        });
        let m = &sc.file.motor;
        c.drive = (
            m.kf_lbf_per_a,
            sc.file.amplifier.gain,
            m.r_ohm,
            m.l_over_r_ms * 1e-3,
        );
    }
    // The digital firmware gets the mistake as a table (and refuses it).
    let table = match (spec.command_sign, spec.controller) {
        (sign::CommandSign::Reversed, Controller::Digital) => sign::negated_default_table()?,
        _ => table,
    };
    // The part program's depth of cut (`--depth-in`): the depth guard's.
    let mut design = sc.servo_design;
    design.depth_of_cut_uin = spec.depth_in * 1e6;
    // `--anticipate off`: the block still tells contour monitoring where
    // the holes are; only the edges' feedforward is off.
    if !spec.anticipate {
        design.edge_feedforward = 0;
    }
    let servo = design
        .config()
        .map_err(|e| anyhow::anyhow!("servo.{}", design.refusal(e)))?;
    let (mut w, mut s) = machine_with_table(sc.rig.clone(), &machine, sc.loop_hz, servo, table);
    if spec.controller == Controller::Digital {
        // The part program's interruption block, through the firmware's
        // own parser (filled holes: an empty block).
        let mut holes = cutting.bolt_holes.clone();
        holes.phase_deg += spec.block_angle_error_deg;
        let block = interruptions::block_of(&holes)?;
        w.set_interruptions(&block)
            .map_err(|e| anyhow::anyhow!("the firmware refused the interruption block: {e}"))?;
    }
    spec.controller.attach(&mut w, &mut s);
    if let Some(a) = w.analog.as_mut() {
        a.reference_sign = spec.command_sign.factor();
        if let Some(l) = spec.applied_levels().filter(|l| l.cmd_lag_us > 0.0) {
            a.reference_lag = Some(crate::analog1983::lag::FirstOrderLag::new(
                l.cmd_lag_us * 1e-6,
            ));
        }
        if let Some(lv) = generator {
            let out = Rc::new(std::cell::Cell::new(0.0));
            a.command_v = Some(out.clone());
            cutter.borrow_mut().command1983 = Some(command1983::AnalogCommand::new(lv, out));
        }
    }
    w.fw.set_target_code((spec.z_offset_in * zslide::codes::GAUGE_CODES_PER_INCH).round() as i32);
    w.hooks.push(Box::new(cutter.clone()));
    Ok(StretchRig {
        w,
        s,
        cutter,
        rec_start_s,
        total_s,
    })
}

/// The 1983 command generator's levels when this cut uses it: the 1983
/// loop with the scenario's `gen_*` levels applied. It needs the legacy X
/// events (its coefficients come from the quad DAC they write) and the
/// index at φ = 0 (its integrators reset to sine 0 there).
fn command1983_levels(
    spec: &CutSpec,
    machine: &crate::machine::MachineConfig,
) -> anyhow::Result<Option<crate::analog1983::generator::GeneratorLevels>> {
    let Some(lv) = spec.applied_levels().and_then(|l| command1983::levels(&l)) else {
        return Ok(None);
    };
    if spec.controller != Controller::LegacyAnalog {
        return Ok(None);
    }
    if !matches!(machine.x, XInterface::LegacyBcd(_)) {
        bail!(
            "scenario {}: errors.gen_calibrated_rpm = {} asks for the 1983 command generator, which takes \
             its coefficients from the legacy X events' quad DAC; this machine's X interface is not legacy BCD",
            spec.scenario.file.name,
            lv.calibrated_rpm
        );
    }
    if machine.spindle.index_phase_turns != 0.0 {
        bail!(
            "scenario {}: spindle.index_phase_deg = {} but the 1983 command generator resets its sine to 0 at the index",
            spec.scenario.file.name,
            machine.spindle.index_phase_turns * 360.0
        );
    }
    Ok(Some(lv))
}

/// Simulates one stretch; `progress(simulated_s)` after every chunk.
pub fn run_stretch(
    spec: &CutSpec,
    st: &Stretch,
    extras: &Extras,
    progress: &(dyn Fn(f64) + Sync),
) -> anyhow::Result<StretchResult> {
    let wall0 = Instant::now();
    let StretchRig {
        mut w,
        mut s,
        cutter,
        rec_start_s,
        total_s,
    } = build_stretch(spec, st, extras.trace_s, spec.table())?;
    // Nothing but the VCD reads the monitor copy of the angle estimator.
    if extras.vcd.is_none() {
        if let Some(m) = w.machine.as_mut() {
            m.monitor = false;
        }
    }
    let trace = match &extras.vcd {
        Some((path, from, to)) => {
            let (partial, file) = crate::outpath::Partial::create(path)?;
            let t0 = ((rec_start_s + from) * 1e9) as u64;
            let t1 = ((rec_start_s + to) * 1e9) as u64;
            let tr = crate::vcd::machine::attach(&mut s, std::io::BufWriter::new(file), t0, t1)?;
            Some((partial, tr))
        }
        None => None,
    };
    let t_end = (total_s * 1e9) as u64;
    let chunk = 500_000_000u64;
    let mut t = 0;
    let mut edge_steps_q8 = Vec::new();
    while t < t_end {
        t = (t + chunk).min(t_end);
        s.run_until(&mut w, t);
        edge_steps_q8.push((t as f64 * 1e-9, w.fw.edges().amplitude_q8()));
        progress(chunk.min(t_end) as f64 * 1e-9);
    }
    if let Some((partial, tr)) = trace {
        crate::vcd::machine::detach(&mut s, tr)?;
        partial.commit()?;
    }
    let mut faults = Vec::new();
    if let Some(f) = w.fw.fault() {
        faults.push(format!("{f:?}"));
    }
    if let Some(f) = w.stats().and_then(|m| m.last_fault) {
        let s = format!("{f:?}");
        if !faults.contains(&s) {
            faults.push(s);
        }
    }
    if w.rig.amp.tripped() {
        faults.push("AmplifierTrip".to_string());
    }
    w.hooks.clear();
    let log = match Rc::try_unwrap(cutter) {
        Ok(c) => c.into_inner().log,
        Err(_) => bail!("cutter still shared after the run"),
    };
    Ok(StretchResult {
        log,
        simulated_s: total_s,
        wall_s: wall0.elapsed().as_secs_f64(),
        faults,
        edge_steps_q8,
    })
}

/// The measured pass.
#[derive(Debug)]
pub struct CutOutcome {
    pub grid: CmmGrid,
    pub passes: PassLog,
    pub following_error_rms_uin: f64,
    pub following_error_peak_uin: f64,
    /// The tool's lowest point against the finished surface while it cut,
    /// over every tick of every stretch (engagements included), µin
    /// (negative: below it; `run::StretchLog::deepest_in`).
    pub deepest_uin: f64,
    /// The same over the rim's engagement alone (`run::Entry::Rim`), µin.
    pub rim_deepest_uin: f64,
    /// Mean cutting force while recording, lbf.
    pub mean_force_lbf: f64,
    /// Largest |coil current| while recording, A.
    pub current_peak_a: f64,
    /// Tick-by-tick (t s, following error µin, force lbf) of the trace
    /// stretch.
    pub trace: Vec<(f64, f64, f64)>,
    /// The same per stretch, in plan order (band k: CMM radius k; empty
    /// where that stretch kept none).
    pub traces: Vec<Vec<(f64, f64, f64)>>,
    pub simulated_s: f64,
    pub wall_s: f64,
    /// Σ of the stretches' own wall times (one core's work).
    pub cpu_s: f64,
    pub faults: Vec<String>,
    pub stretches: usize,
    /// The rectangular grid's measurement (`--grid`; the polar `grid` is
    /// then unmeasured: no stretch is at its radii).
    pub rect: Option<gridcut::RectMeasured>,
    /// The hole zone (`CutSpec::hole_zone`; `None` where the part has no
    /// holes).
    pub zone: Option<holezone::ZoneMeasured>,
    /// With `--measure cmm`: the true surface on the same grid (what the
    /// CMM read is of), µin.
    pub exact: Option<CmmGrid>,
}

/// Runs the plan (stretches in parallel), measures the part.
/// `progress(simulated_s)` is called from the worker threads.
pub fn run_pass(
    spec: &CutSpec,
    extras_for: impl Fn(&Stretch) -> Extras + Sync,
    progress: &(dyn Fn(f64) + Sync),
) -> anyhow::Result<CutOutcome> {
    if spec.grid.is_some() && spec.part.is_none() {
        bail!(
            "a rectangular grid (--grid) measures a part of one's own (--part): the default part is measured on chapter 5's polar grid"
        );
    }
    let gain = spec.contact_gain()?;
    let stretches = plan(spec, gain);
    let wall0 = Instant::now();
    let results: Vec<anyhow::Result<StretchResult>> = stretches
        .par_iter()
        .map(|st| run_stretch(spec, st, &extras_for(st), progress))
        .collect();
    let wall_s = wall0.elapsed().as_secs_f64();
    let mut passes = PassLog::new();
    let mut grid_log = spec.grid.as_deref().map(gridcut::AngleLog::of_grid);
    let mut zone_log: Option<holezone::ZoneLog> = None;
    let (mut sum_sq, mut n, mut peak, mut force) = (0.0, 0u64, 0.0f64, 0.0);
    let mut current_peak_a = 0.0f64;
    let (mut simulated_s, mut cpu_s) = (0.0, 0.0);
    let mut deepest = f64::INFINITY;
    let mut rim_deepest = f64::INFINITY;
    let mut faults = Vec::new();
    let mut trace = Vec::new();
    let mut traces = Vec::new();
    for (r, st) in results.into_iter().zip(&stretches) {
        let mut r = r?;
        if matches!(st.entry, run::Entry::Rim(_)) {
            rim_deepest = rim_deepest.min(r.log.deepest_in);
        }
        traces.push(std::mem::take(&mut r.log.trace));
        passes.merge(r.log.passes);
        if let (Some(a), Some(b)) = (grid_log.as_mut(), r.log.grid.take()) {
            a.merge(b);
        }
        if let Some(b) = r.log.zone.take() {
            match zone_log.as_mut() {
                Some(a) => a.merge(&b),
                None => zone_log = Some(b),
            }
        }
        sum_sq += r.log.fe_sum_sq;
        n += r.log.fe_n;
        peak = peak.max(r.log.fe_peak);
        deepest = deepest.min(r.log.deepest_in);
        current_peak_a = current_peak_a.max(r.log.current_peak_a);
        force += r.log.force_sum;
        simulated_s += r.simulated_s;
        cpu_s += r.wall_s;
        if trace.is_empty() {
            trace.clone_from(traces.last().expect("pushed above"));
        }
        for f in r.faults {
            if !faults.contains(&f) {
                faults.push(f);
            }
        }
    }
    let holes = engage::HoleRing::new(&crate::plant::cutting::BoltHoles {
        filled: spec.holes == Holes::Filled,
        ..spec.scenario.cutting.bolt_holes.clone()
    });
    let grid = CmmGrid::measure_at(
        &passes,
        &spec.cmm_x(),
        gain,
        spec.scenario.cutting.tool_radius_in,
        spec.feed_per_rev_in,
        |x, phi_deg| holes.over_hole(x, phi_deg / 360.0),
    );
    let rect = spec.grid.as_deref().zip(grid_log.as_ref()).map(|(g, log)| {
        gridcut::RectMeasured::measure(
            g,
            log,
            spec.scenario.cutting.tool_radius_in,
            spec.feed_per_rev_in,
            |x, phi_deg| holes.over_hole(x, phi_deg / 360.0),
        )
    });
    let exact = (spec.measure == cmm::Measure::Cmm).then(|| grid.clone());
    let grid = match spec.measure {
        cmm::Measure::Exact => grid,
        cmm::Measure::Cmm => {
            // The CMM model's residuals follow the default part's slope
            // on chapter 5's radii; a part of one's own has neither.
            if spec.part.is_some() {
                anyhow::bail!(
                    "--measure cmm models chapter 5's CMM on the default part; a part of one's own (--part) is measured exact"
                );
            }
            let (surf, _) = spec.surface()?;
            cmm::read_averaged(
                &grid,
                &surf,
                gain,
                &spec.cmm_levels(),
                spec.scenario.rig.seed,
                spec.cmm_readings,
            )
        }
    };
    let nf = n.max(1) as f64;
    Ok(CutOutcome {
        grid,
        passes,
        following_error_rms_uin: (sum_sq / nf).sqrt() * 1e6,
        following_error_peak_uin: peak * 1e6,
        deepest_uin: deepest * 1e6,
        rim_deepest_uin: rim_deepest * 1e6,
        mean_force_lbf: force / nf,
        current_peak_a,
        trace,
        traces,
        simulated_s,
        wall_s,
        cpu_s,
        faults,
        stretches: stretches.len(),
        rect,
        zone: spec
            .zone_grid()?
            .zip(zone_log)
            .map(|(g, log)| holezone::ZoneMeasured::measure(&g, &log)),
        exact,
    })
}
