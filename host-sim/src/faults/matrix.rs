//! The fault campaign and the stalled-loop sweep over a matrix of
//! machines, radii and spindle speeds (`host-sim faults --matrix`), and the
//! worst excursion into the part each fault reached over it
//! (docs/SAFETY.md, "The campaign on every machine").

use super::{campaign_at, spec_at, sweep_at, Case, Inject, Outcome};
use crate::cut::CutSpec;

/// One point of the matrix.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Point {
    pub scenario: String,
    pub x_in: f64,
    pub rpm: f64,
}

/// The worst a fault did over the matrix.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Worst {
    pub fault: &'static str,
    /// Rows run (the machine had the fault) and rows not applicable.
    pub runs: usize,
    pub not_applicable: usize,
    /// Every run detected, with the expected fault, and ended safe.
    pub all_detected_and_safe: bool,
    pub worst_excursion_uin: f64,
    pub worst_at: Option<Point>,
    /// The longest time to safe, ms, and where.
    pub slowest_safe_ms: f64,
    pub slowest_at: Option<Point>,
}

/// The matrix: every scenario at every radius and speed (`None`: the
/// scenario's own), `phases` stall instants a revolution at each point
/// (0: no sweep), on seed stream `seed`.
pub fn run(
    scenarios: &[&str],
    xs_in: &[f64],
    rpms: &[Option<f64>],
    phases: usize,
    seed: u64,
) -> anyhow::Result<Vec<Worst>> {
    let mut worst: Vec<Worst> = Case::ALL
        .iter()
        .map(|c| Worst {
            fault: c.name(),
            all_detected_and_safe: true,
            ..Worst::default()
        })
        .collect();
    for name in scenarios {
        for rpm in rpms {
            let spec: CutSpec = spec_at(crate::scenario::load(name)?, *rpm)?;
            for &x_in in xs_in {
                let at = Inject {
                    after_turns: 0.0,
                    x_in,
                };
                let point = Point {
                    scenario: name.to_string(),
                    x_in,
                    rpm: spec.rpm,
                };
                let mut rows: Vec<(Case, Outcome)> = Case::ALL
                    .iter()
                    .copied()
                    .zip(campaign_at(&spec, &Case::ALL, seed, at)?)
                    .collect();
                if phases > 0 {
                    for o in sweep_at(&spec, Case::StalledLoop, phases, seed, x_in)? {
                        rows.push((Case::StalledLoop, o));
                    }
                }
                for (case, o) in rows {
                    let w = worst
                        .iter_mut()
                        .find(|w| w.fault == case.name())
                        .expect("every case has its entry");
                    let r = &o.row;
                    if r.detected.is_none() {
                        w.not_applicable += 1;
                        continue;
                    }
                    w.runs += 1;
                    let expected =
                        !case.expects_fault() || o.latched.is_some_and(|f| case.expects(f));
                    w.all_detected_and_safe &=
                        r.detected == Some(true) && r.safe_state == Some(true) && expected;
                    let e = r.max_excursion_uin.unwrap_or(f64::INFINITY);
                    if w.worst_at.is_none() || e > w.worst_excursion_uin {
                        w.worst_excursion_uin = e;
                        w.worst_at = Some(point.clone());
                    }
                    let t = r.time_to_safe_ms.unwrap_or(f64::INFINITY);
                    if w.slowest_at.is_none() || t > w.slowest_safe_ms {
                        w.slowest_safe_ms = t;
                        w.slowest_at = Some(point.clone());
                    }
                }
            }
        }
    }
    Ok(worst)
}
