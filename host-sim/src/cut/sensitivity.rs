//! `cut --force-sensitivity`: the part's contour band with the cutting
//! force model's two constants scaled, one at a time. k_t (thrust per unit
//! chip area) and k_e (the edge's rubbing force per unit contact length)
//! rest on one datum (brief §2: the force measured at one depth and feed),
//! so each is swept over × 0.25 .. × 4 with the other at its value; every
//! run has the same seeds as the nominal one. k_e sets the engaged part's
//! stiffness (`stiffness_lbf_per_in`), the loop's uncertain plant parameter
//! (docs/TUNING.md, "The process spring").

use super::{run_pass, CutSpec, Extras};

/// The factors swept.
pub const FACTORS: [f64; 7] = [0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0];

/// The engaged part's stiffness against the tool, lbf/in: the slope of the
/// force model's steady thrust at depth of cut `depth_in` and feed `feed_in`
/// (`CuttingParams::thrust_lbf`), `k_t·f + k_e·√(r_t / (2d))`: 2185 lbf/in
/// at chapter 5's 0.0003 in and 100 µin/rev with the nominal constants. The
/// slope the loop meets as a spring (docs/TUNING.md).
pub fn stiffness_lbf_per_in(
    c: &crate::plant::cutting::CuttingParams,
    depth_in: f64,
    feed_in: f64,
) -> f64 {
    c.k_t_psi * feed_in + c.k_e_lbf_per_in * (c.tool_radius_in / (2.0 * depth_in)).sqrt()
}

/// One run of the sweep.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    /// `k_t` or `k_e`.
    pub constant: &'static str,
    pub factor: f64,
    /// The constant's value in the run (psi or lbf/in).
    pub value: f64,
    pub band_min_uin: f64,
    pub band_max_uin: f64,
    pub following_error_rms_uin: f64,
    /// The tool's lowest point against the finished surface while it cut,
    /// engagements included (`CutOutcome::deepest_uin`), µin: deeper than
    /// −depth of cut is scrap whatever the band.
    pub deepest_uin: f64,
    /// The same over the rim's engagement alone
    /// (`CutOutcome::rim_deepest_uin`), µin.
    pub rim_deepest_uin: f64,
    pub mean_force_lbf: f64,
    /// The engaged part's stiffness at this scale (`stiffness_lbf_per_in`).
    pub stiffness_lbf_per_in: f64,
    pub faults: Vec<String>,
}

/// Runs the sweep on `spec` (its controller, scenario, speed, holes,
/// error sources); `progress(label)` before each run.
pub fn run(spec: &CutSpec, progress: &dyn Fn(&str)) -> anyhow::Result<Vec<Row>> {
    let c = &spec.scenario.cutting;
    let (kt, ke) = (c.k_t_psi, c.k_e_lbf_per_in);
    let mut rows = Vec::new();
    for constant in ["k_t", "k_e"] {
        for f in FACTORS {
            progress(&format!("{constant} × {f}"));
            let mut s = spec.clone();
            let value = if constant == "k_t" {
                s.scenario.cutting.k_t_psi = kt * f;
                kt * f
            } else {
                s.scenario.cutting.k_e_lbf_per_in = ke * f;
                ke * f
            };
            let o = run_pass(&s, |_| Extras::default(), &|_| {})?;
            let (lo, hi) = o
                .grid
                .band()
                .ok_or_else(|| anyhow::anyhow!("{constant} × {f}: the grid has no value"))?;
            rows.push(Row {
                constant,
                factor: f,
                value,
                band_min_uin: lo,
                band_max_uin: hi,
                following_error_rms_uin: o.following_error_rms_uin,
                deepest_uin: o.deepest_uin,
                rim_deepest_uin: o.rim_deepest_uin,
                mean_force_lbf: o.mean_force_lbf,
                stiffness_lbf_per_in: stiffness_lbf_per_in(
                    &s.scenario.cutting,
                    s.depth_in,
                    s.feed_per_rev_in,
                ),
                faults: o.faults,
            });
        }
    }
    Ok(rows)
}

/// The sweep as a table (µin).
pub fn table(spec: &CutSpec, rows: &[Row]) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "force-model sensitivity: {} / {} / {} rpm / holes {} / errors {:?}",
        spec.scenario.file.name,
        spec.controller.name(),
        spec.rpm,
        spec.holes.name(),
        spec.errors
    );
    let _ = writeln!(
        o,
        "{:<10} {:>12} {:>10} {:>20} {:>10} {:>12} {:>12} {:>10}  faults",
        "constant",
        "value",
        "lbf/in",
        "contour band, µin",
        "p-v µin",
        "FE RMS µin",
        "deepest µin",
        "rim µin"
    );
    for r in rows {
        let _ = writeln!(
            o,
            "{:<10} {:>12} {:>10.0} {:>20} {:>10.1} {:>12.1} {:>12.1} {:>10.1}  {}",
            format!("{} × {}", r.constant, r.factor),
            format!("{:.1}", r.value),
            r.stiffness_lbf_per_in,
            format!("{:.1} .. {:.1}", r.band_min_uin, r.band_max_uin),
            r.band_max_uin - r.band_min_uin,
            r.following_error_rms_uin,
            r.deepest_uin,
            r.rim_deepest_uin,
            if r.faults.is_empty() {
                "none".to_string()
            } else {
                r.faults.join(", ")
            }
        );
    }
    o
}
