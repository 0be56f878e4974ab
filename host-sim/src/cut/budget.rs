//! `cut --budget`: the error budget of the part. The pass is run with no
//! source beyond the loop (the loop's own part), then with each source of
//! the scenario's `[errors]` alone, then with all of them; every run has
//! the same seeds, so a source's contribution is its grid minus the
//! loop's, point by point. The measurement is two rows of its own: the
//! face tilt (the CMM's levelling on the part's face, `cmm`: it is in the
//! reading, not in the part, so its row is what it adds to the reading of
//! the loop's part) and the CMM's reading of the loop's part minus the
//! part.
//!
//! Per row: the contribution's band (min..max over the 252 points, µin)
//! and its RMS; the root-sum-square of the rows against the contribution
//! of all together; and the tolerance on each source the goal needs: the
//! level at which the source alone takes an equal root-sum-square share
//! of what the loop leaves of the goal, `(G − max|loop|)/√N`, scaling its
//! level linearly from the peak of its contribution (first order: the
//! sources are linear in their level except wear through the force, which
//! is small at a finishing depth).

use super::cmm::{self, CmmLevels};
use super::errors::{ErrorLevels, Selection, Source};
use super::part::CmmGrid;
use super::{run_pass, CutSpec, Extras};

/// One row of the budget.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    pub source: String,
    /// The level the scenario states.
    pub level: String,
    pub band_min_uin: f64,
    pub band_max_uin: f64,
    pub rms_uin: f64,
    /// Largest |contribution|, µin.
    pub peak_uin: f64,
    /// The level the goal allows for this source (same unit as `level`),
    /// as a fraction of the stated level (`None`: the loop alone exceeds
    /// the goal, nothing is left to share).
    pub tolerance_factor: Option<f64>,
}

/// The whole budget.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Budget {
    pub scenario: String,
    pub controller: String,
    pub rpm: f64,
    pub holes: String,
    /// Goal, ± µin (brief §6).
    pub goal_uin: Option<f64>,
    /// The loop's own part: band and RMS of the grid.
    pub loop_band_uin: (f64, f64),
    pub loop_rms_uin: f64,
    pub rows: Vec<Row>,
    /// All sources together (the measurement and the face tilt, its
    /// levelling, excluded): contribution band and RMS, and the
    /// root-sum-square of the rows' RMS.
    pub all_band_uin: (f64, f64),
    pub all_rms_uin: f64,
    pub rss_rms_uin: f64,
    /// The part with every source and the CMM: band, µin.
    pub total_band_uin: (f64, f64),
}

fn values(g: &CmmGrid) -> Vec<Option<f64>> {
    g.err_uin.iter().flatten().copied().collect()
}

/// Contribution of `g` over `base`: (min, max, rms, peak), µin.
fn contribution(g: &CmmGrid, base: &CmmGrid) -> (f64, f64, f64, f64) {
    let d: Vec<f64> = values(g)
        .iter()
        .zip(values(base))
        .filter_map(|(a, b)| Some(a.as_ref()? - b?))
        .collect();
    stats(&d)
}

fn stats(d: &[f64]) -> (f64, f64, f64, f64) {
    if d.is_empty() {
        return (0.0, 0.0, 0.0, 0.0);
    }
    let lo = d.iter().copied().fold(f64::MAX, f64::min);
    let hi = d.iter().copied().fold(f64::MIN, f64::max);
    let rms = (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt();
    (lo, hi, rms, lo.abs().max(hi.abs()))
}

/// The goal of a scenario (brief §6), ± µin.
pub fn goal_uin(scenario: &str) -> Option<f64> {
    match scenario {
        "legacy-hw" => Some(30.0),
        "modern-hw" => Some(5.0),
        _ => None,
    }
}

/// Runs the budget of `spec` (its controller, scenario, speed, holes);
/// `progress(source name)` before each run.
pub fn run(spec: &CutSpec, progress: &dyn Fn(&str)) -> anyhow::Result<Budget> {
    let levels = spec.error_levels.clone();
    let pass = |l: Option<ErrorLevels>| -> anyhow::Result<CmmGrid> {
        let mut s = spec.clone();
        s.measure = cmm::Measure::Exact;
        match l {
            None => s.errors = Selection::None,
            Some(l) => {
                s.errors = Selection::All;
                s.error_levels = l;
            }
        }
        Ok(run_pass(&s, |_| Extras::default(), &|_| {})?.grid)
    };
    progress("the loop alone");
    let base = pass(None)?;
    let base_v: Vec<f64> = values(&base).into_iter().flatten().collect();
    let (blo, bhi, brms, bpeak) = stats(&base_v);
    let goal = goal_uin(&spec.scenario.file.name);
    let sources: Vec<Source> = Source::ALL
        .iter()
        .copied()
        .filter(|s| s.present(&levels) && s.applies(spec.controller))
        .collect();
    // The CMM is one more row in the share.
    let n_rows = (sources.len() + 1) as f64;
    let share = goal.map(|g| (g - bpeak) / n_rows.sqrt());
    let tol = |peak: f64| match share {
        Some(s) if s > 0.0 && peak > 0.0 => Some(s / peak),
        Some(_) => None,
        None => None,
    };
    let mut rows = Vec::new();
    let (surf, _) = spec.surface()?;
    let gain = surf.contact_gain();
    let seed = spec.scenario.rig.seed;
    for s in &sources {
        progress(s.name());
        let g = match s {
            // The levelling is in the reading: the part is the loop's.
            Source::FaceTilt => {
                let face = cmm::FaceLevelling::of(&levels);
                cmm::read(&base, &surf, gain, &CmmLevels::face_only(face), seed)
            }
            _ => pass(Some(s.alone(&levels)))?,
        };
        let (lo, hi, rms, peak) = contribution(&g, &base);
        rows.push(Row {
            source: s.name().to_string(),
            level: s.level(&levels),
            band_min_uin: lo,
            band_max_uin: hi,
            rms_uin: rms,
            peak_uin: peak,
            tolerance_factor: tol(peak),
        });
    }
    let lv = CmmLevels::renault();
    let read = cmm::read(&base, &surf, gain, &lv, seed);
    let (lo, hi, rms, peak) = contribution(&read, &base);
    rows.push(Row {
        source: "measurement (CMM)".to_string(),
        level: format!(
            "{:.2} µin steps, {} µin 1σ, tilt {} µin/in, datum {}°",
            lv.resolution_in * 1e6,
            lv.repeatability_in * 1e6,
            lv.tilt_in_per_in * 1e6,
            lv.angle_datum_deg
        ),
        band_min_uin: lo,
        band_max_uin: hi,
        rms_uin: rms,
        peak_uin: peak,
        tolerance_factor: tol(peak),
    });
    progress("all sources");
    let all = pass(Some(levels.clone()))?;
    let (alo, ahi, arms, _) = contribution(&all, &base);
    let rss = rows
        .iter()
        .map(|r| r.rms_uin * r.rms_uin)
        .sum::<f64>()
        .sqrt();
    let total = cmm::read(
        &all,
        &surf,
        gain,
        &lv.levelled_on(cmm::FaceLevelling::of(&levels)),
        seed,
    );
    let tv: Vec<f64> = values(&total).into_iter().flatten().collect();
    let (tlo, thi, _, _) = stats(&tv);
    Ok(Budget {
        scenario: spec.scenario.file.name.clone(),
        controller: spec.controller.name().to_string(),
        rpm: spec.rpm,
        holes: spec.holes.name().to_string(),
        goal_uin: goal,
        loop_band_uin: (blo, bhi),
        loop_rms_uin: brms,
        rows,
        all_band_uin: (alo, ahi),
        all_rms_uin: arms,
        rss_rms_uin: rss,
        total_band_uin: (tlo, thi),
    })
}

/// The budget as a table (µin).
pub fn table(b: &Budget) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let goal = b
        .goal_uin
        .map_or("none".to_string(), |g| format!("±{g} µin"));
    let _ = writeln!(
        o,
        "error budget: {} / {} / {} rpm / holes {}; goal {goal}",
        b.scenario, b.controller, b.rpm, b.holes
    );
    let _ = writeln!(
        o,
        "{:<26} {:>18} {:>9} {:>9}  {:<44} tolerance for the goal",
        "source", "band, µin", "RMS µin", "peak µin", "level"
    );
    let _ = writeln!(
        o,
        "{:<26} {:>18} {:>9.1} {:>9.1}  {:<44} -",
        "the loop (its own part)",
        format!("{:.1} .. {:.1}", b.loop_band_uin.0, b.loop_band_uin.1),
        b.loop_rms_uin,
        b.loop_band_uin.0.abs().max(b.loop_band_uin.1.abs()),
        "-"
    );
    for r in &b.rows {
        let t = match r.tolerance_factor {
            Some(f) => format!("× {f:.3} of the level"),
            None => "none left (the loop exceeds the goal)".to_string(),
        };
        let _ = writeln!(
            o,
            "{:<26} {:>18} {:>9.1} {:>9.1}  {:<44} {t}",
            r.source,
            format!("{:.1} .. {:.1}", r.band_min_uin, r.band_max_uin),
            r.rms_uin,
            r.peak_uin,
            r.level
        );
    }
    let _ = writeln!(
        o,
        "{:<26} {:>18} {:>9.1}            (root-sum-square of the rows' RMS: {:.1})",
        "all sources together",
        format!("{:.1} .. {:.1}", b.all_band_uin.0, b.all_band_uin.1),
        b.all_rms_uin,
        b.rss_rms_uin
    );
    let _ = writeln!(
        o,
        "{:<26} {:>18}",
        "the part, all + CMM",
        format!("{:.1} .. {:.1}", b.total_band_uin.0, b.total_band_uin.1)
    );
    o
}
