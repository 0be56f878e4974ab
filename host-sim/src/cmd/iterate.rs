//! `host-sim compensate-iterate [--passes N] [--gain G] [--keep-tilt]
//! [--dir D] [--json] [-- CUT OPTIONS]`: measure → compensate → cut, N
//! times, on one machine (docs/PARTS.md "Compensating a measured part").
//!
//! Pass 0 cuts the default part with its nominal table; each further pass
//! cuts with the table `compensate` made from the pass before (`--from`
//! the table that pass was cut with), so the wear, drifts, gauge and X
//! zero repeat and the noise is new (`cut --table`). Every pass is
//! measured by the CMM model (`--measure cmm`) and its true surface kept
//! beside it; the hole zone is not measured (compensation does not read
//! it). The same files as the three-command walk-through: `passK.json`,
//! `passK.zsct` and its record, in `--dir` (default: a temporary directory,
//! removed).
//!
//! Per pass: the true band and the CMM's, and the true surface split into
//! its part even about φ = 90° (unchanged by φ → 180° − φ: what a series
//! in sin φ, the 1983 command generator's `C00 + C01 s + C02 s² + C03 s³`,
//! can carry) and the odd rest, which the 1983 generator cannot carry;
//! and the fit the next table was made from.

use crate::cmd::compensate::{self, save};
use crate::cmd::cut;
use crate::cut::part::CmmGrid;
use anyhow::{anyhow, bail, Context};
use clap::Parser;
use std::path::{Path, PathBuf};

/// Most passes one run makes.
pub const MAX_PASSES: usize = 6;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Compensated passes after the first cut.
    #[arg(long, default_value_t = 2)]
    pub passes: usize,
    /// Share of each fitted error taken off, 0 < G <= 1 (`compensate --gain`).
    #[arg(long, default_value_t = 1.0)]
    pub gain: f64,
    /// Take the fitted tilt off too (`compensate --keep-tilt`).
    #[arg(long)]
    pub keep_tilt: bool,
    /// Keep every pass's cut JSON, table and record here (created; must
    /// be empty or absent).
    #[arg(long)]
    pub dir: Option<PathBuf>,
    /// Print JSON: every pass (each pass is also printed to stderr as one
    /// JSON line as it finishes).
    #[arg(long)]
    pub json: bool,
    /// `cut`'s options for every pass, after `--` (e.g. `-- --scenario
    /// modern-hw --errors all --holes filled`); `--table`, `--part`,
    /// `--grid`, `--out`, `--json`, `--budget`, `--force-sensitivity` and
    /// `--measure` are the iteration's own and refused.
    #[arg(last = true, allow_hyphen_values = true)]
    pub cut: Vec<String>,
}

#[derive(Parser)]
#[command(name = "cut")]
struct CutCli {
    #[command(flatten)]
    args: cut::Args,
}

/// A grid's values split by φ → 180° − φ, µin.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Parity {
    /// Peak and RMS of the even part `(e(φ) + e(180° − φ)) / 2`.
    pub even_peak_uin: f64,
    pub even_rms_uin: f64,
    /// Peak and RMS of the odd part `(e(φ) − e(180° − φ)) / 2`.
    pub odd_peak_uin: f64,
    pub odd_rms_uin: f64,
}

/// Splits chapter 5's grid (rows every 10° from 0°, so row i meets row
/// 18 − i mod 36) into its parts even and odd about φ = 90°; points
/// whose mirror is unmeasured are left out.
pub fn parity(g: &CmmGrid) -> Parity {
    let rows = g.err_uin.len();
    let (mut ev, mut od) = (vec![], vec![]);
    for (i, row) in g.err_uin.iter().enumerate() {
        let m = (rows + rows / 2 - i) % rows;
        for (j, e) in row.iter().enumerate() {
            if let (Some(a), Some(b)) = (e, g.err_uin[m][j]) {
                ev.push((a + b) / 2.0);
                od.push((a - b) / 2.0);
            }
        }
    }
    let peak = |v: &[f64]| v.iter().fold(0.0f64, |a, e| a.max(e.abs()));
    let rms = |v: &[f64]| (v.iter().map(|e| e * e).sum::<f64>() / v.len().max(1) as f64).sqrt();
    Parity {
        even_peak_uin: peak(&ev),
        even_rms_uin: rms(&ev),
        odd_peak_uin: peak(&od),
        odd_rms_uin: rms(&od),
    }
}

/// The fit a pass's measurement gave the next table.
#[derive(Clone, Debug, serde::Serialize)]
pub struct NextFit {
    pub order: u32,
    pub terms: usize,
    pub noise_estimate_uin: f64,
    pub noise_share: f64,
    pub tilt_edge_uin: f64,
    pub tilt_compensated: bool,
}

/// One pass.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Pass {
    pub pass: usize,
    /// The table cut (none: the default part's nominal table).
    pub table: Option<String>,
    /// The true contour band on the CMM grid, µin.
    pub true_min_uin: f64,
    pub true_max_uin: f64,
    /// What the CMM read, µin.
    pub cmm_min_uin: f64,
    pub cmm_max_uin: f64,
    /// The scenario's contour goal, ±µin, and whether the true band is in it.
    pub goal_uin: Option<f64>,
    pub true_within_goal: Option<bool>,
    /// The true surface's parts even and odd about φ = 90°.
    pub parity: Parity,
    /// The fit made from this pass's measurement (none after the last).
    pub next_fit: Option<NextFit>,
}

#[derive(serde::Serialize)]
pub struct Report {
    pub scenario: String,
    pub controller: crate::cut::Controller,
    pub errors: crate::cut::errors::Selection,
    pub gain: f64,
    pub keep_tilt: bool,
    pub cut_options: Vec<String>,
    pub passes: Vec<Pass>,
}

fn cut_args(a: &Args) -> anyhow::Result<cut::Args> {
    const OWN: [&str; 8] = [
        "--table",
        "--part",
        "--grid",
        "--out",
        "--json",
        "--budget",
        "--force-sensitivity",
        "--measure",
    ];
    if let Some(o) = a.cut.iter().find(|o| {
        OWN.iter()
            .any(|w| o.as_str() == *w || o.starts_with(&format!("{w}=")))
    }) {
        bail!("cut option {o}: the iteration sets it itself (measure cmm, each pass's table)");
    }
    let mut c = CutCli::try_parse_from(std::iter::once("cut".to_string()).chain(a.cut.clone()))
        .map_err(|e| anyhow!("the cut options after --: {e}"))?
        .args;
    c.measure = crate::cut::cmm::Measure::Cmm;
    c.hole_zone = cut::OnOff::Off;
    Ok(c)
}

fn dir_of(a: &Args) -> anyhow::Result<(PathBuf, bool)> {
    match &a.dir {
        Some(d) => {
            if d.exists() {
                anyhow::ensure!(
                    d.is_dir() && std::fs::read_dir(d)?.next().is_none(),
                    "--dir {}: must be an empty directory or absent",
                    d.display()
                );
            }
            std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
            Ok((d.clone(), false))
        }
        None => {
            let d = std::env::temp_dir().join(format!(
                "host-sim-compensate-iterate-{}-{}",
                std::process::id(),
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map_or(0, |d| d.as_nanos())
            ));
            std::fs::create_dir_all(&d).with_context(|| format!("creating {}", d.display()))?;
            Ok((d, true))
        }
    }
}

fn iterate(a: &Args, dir: &Path) -> anyhow::Result<Report> {
    let mut c = cut_args(a)?;
    let mut passes = Vec::new();
    let mut table: Option<PathBuf> = None;
    let mut errors = None;
    for k in 0..=a.passes {
        c.table = table.clone();
        let (s, o) = cut::cut_once(&c)?;
        errors = Some(s.errors);
        let measured = dir.join(format!("pass{k}.json"));
        std::fs::write(&measured, serde_json::to_string_pretty(&s)?)
            .with_context(|| format!("writing {}", measured.display()))?;
        let exact = o
            .exact
            .as_ref()
            .ok_or_else(|| anyhow!("pass {k}: the cut kept no true surface"))?;
        let (t_lo, t_hi) = exact
            .band()
            .ok_or_else(|| anyhow!("pass {k}: no point measured"))?;
        let next_fit = if k < a.passes {
            let out = dir.join(format!("pass{}.zsct", k + 1));
            let ca = compensate::Args {
                measured: measured.clone(),
                out: out.clone(),
                from: table.clone(),
                gain: a.gain,
                part: None,
                bound_uin: None,
                noise_uin: None,
                keep_tilt: a.keep_tilt,
                scenario: c.scenario.clone(),
                json: false,
            };
            let (image, record, r) =
                compensate::make(&ca).with_context(|| format!("compensating pass {k}"))?;
            save(&out, &image, &record)?;
            table = Some(out);
            Some(NextFit {
                order: r.fit.order,
                terms: r.fit.coefficients_uin.len(),
                noise_estimate_uin: r.fit.noise_estimate_uin,
                noise_share: r.fit.noise_share,
                tilt_edge_uin: r.tilt_edge_uin,
                tilt_compensated: r.tilt_compensated,
            })
        } else {
            None
        };
        let p = Pass {
            pass: k,
            table: c.table.as_ref().map(|t| t.display().to_string()),
            true_min_uin: t_lo,
            true_max_uin: t_hi,
            cmm_min_uin: s.contour_error_min_uin.unwrap_or(f64::NAN),
            cmm_max_uin: s.contour_error_max_uin.unwrap_or(f64::NAN),
            goal_uin: s.contour_goal_uin,
            true_within_goal: s.contour_goal_uin.map(|g| t_lo >= -g && t_hi <= g),
            parity: parity(exact),
            next_fit,
        };
        eprintln!("{}", serde_json::to_string(&p)?);
        passes.push(p);
    }
    let s = c.scenario.load()?;
    Ok(Report {
        scenario: s.file.name.clone(),
        controller: c.controller,
        errors: errors.ok_or_else(|| anyhow!("no pass cut"))?,
        gain: a.gain,
        keep_tilt: a.keep_tilt,
        cut_options: a.cut.clone(),
        passes,
    })
}

pub fn run(a: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        (1..=MAX_PASSES).contains(&a.passes),
        "--passes {}: must be 1..={MAX_PASSES}",
        a.passes
    );
    let (dir, temporary) = dir_of(&a)?;
    let r = iterate(&a, &dir);
    if temporary {
        let _ = std::fs::remove_dir_all(&dir);
    }
    let r = r?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
        return Ok(());
    }
    println!(
        "{} / {} / errors {:?} / gain {}{}",
        r.scenario,
        r.controller.name(),
        r.errors,
        r.gain,
        if r.keep_tilt {
            " / tilt compensated"
        } else {
            ""
        }
    );
    println!(
        "pass  true band, µin       CMM band, µin        even / odd about 90°, peak µin   next fit"
    );
    for p in &r.passes {
        println!(
            "{:>4}  {:>8.1} .. {:>7.1}  {:>8.1} .. {:>7.1}  {:>8.1} / {:>7.1}              {}",
            p.pass,
            p.true_min_uin,
            p.true_max_uin,
            p.cmm_min_uin,
            p.cmm_max_uin,
            p.parity.even_peak_uin,
            p.parity.odd_peak_uin,
            p.next_fit.as_ref().map_or(String::new(), |f| format!(
                "order {} ({} terms), σ̂ {:.1} µin, tilt {:.1} µin{}",
                f.order,
                f.terms,
                f.noise_estimate_uin,
                f.tilt_edge_uin,
                if f.tilt_compensated { "" } else { " left" }
            ))
        );
    }
    if let Some(d) = &a.dir {
        println!("files in {}", d.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(cut: &[&str]) -> Args {
        Args {
            passes: 2,
            gain: 1.0,
            keep_tilt: false,
            dir: None,
            json: true,
            cut: cut.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// `7 + 100 sin φ` is even about 90° (a series in sin φ), `30 cos φ`
    /// odd: the split gives peaks 107 and 30, one unmeasured point
    /// taking its mirror out with it.
    #[test]
    fn parity_splits_sin_phi_from_cos_phi_about_90_degrees() {
        let mut g = CmmGrid {
            err_uin: (0..36)
                .map(|i| {
                    let p = (10.0 * f64::from(i)).to_radians();
                    vec![Some(7.0 + 100.0 * p.sin() + 30.0 * p.cos()); 2]
                })
                .collect(),
            in_hole: vec![vec![false; 2]; 36],
            finish_by_x_uin: vec![None; 2],
        };
        g.err_uin[9][1] = None;
        let p = parity(&g);
        assert!((p.even_peak_uin - 107.0).abs() < 1e-9, "{p:?}");
        assert!((p.odd_peak_uin - 30.0).abs() < 1e-9, "{p:?}");
        // RMS of 30 cos φ over whole turns: 30/√2.
        assert!((p.odd_rms_uin - 30.0 / 2f64.sqrt()).abs() < 0.5, "{p:?}");
    }

    #[test]
    fn the_iterations_own_cut_options_are_refused() {
        for o in [
            "--table=t.zsct",
            "--part",
            "--grid",
            "--out",
            "--json",
            "--budget",
            "--force-sensitivity",
            "--measure",
        ] {
            let e = cut_args(&args(&[o, "x"])).unwrap_err().to_string();
            assert!(e.contains("the iteration sets it itself"), "{o}: {e}");
        }
        let e = cut_args(&args(&["--no-such-option"]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("the cut options after --"), "{e}");
        let c = cut_args(&args(&["--scenario", "modern-hw", "--errors", "all"])).unwrap();
        assert_eq!(c.measure, crate::cut::cmm::Measure::Cmm);
        assert_eq!(c.hole_zone, cut::OnOff::Off);
        assert_eq!(c.scenario.scenario, "modern-hw");
    }
}
