//! The CMM error map as a filled contour view: φ across, X up, the error
//! in colour bands (blue: the tool went too deep, red: excess stock), the
//! points the probe could not touch (inside an open bolt hole) in grey, and
//! the CMM's grid points as dots. Seven overlapping curves against φ hid
//! which radius did what; this shows the whole face at once, as Figures
//! 5-6 and 5-8 are read.
//!
//! Between the CMM points (10° by 1 in) the error is interpolated
//! bilinearly, φ wrapping from 350° to 360° = 0°; a cell whose nearest CMM
//! point is in a hole is grey.

use super::part::{cmm_phi_deg, CmmGrid};
use crate::plot::Series;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Colour bands either side of zero.
const BANDS: usize = 6;

/// The band edge: the largest |error| rounded up to 1, 2 or 5 × 10ⁿ µin.
pub fn nice_limit(max_abs: f64) -> f64 {
    if max_abs.is_nan() || max_abs <= 0.0 || max_abs.is_infinite() {
        return 1.0;
    }
    let e = 10f64.powf(max_abs.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * e)
        .find(|&v| v >= max_abs)
        .unwrap_or(10.0 * e)
}

/// The colour scale's limit for a grid of errors (µin; `None`: not
/// measured): [`nice_limit`] of its largest magnitude.
pub fn grid_limit(err_uin: &[Vec<Option<f64>>]) -> f64 {
    nice_limit(
        err_uin
            .iter()
            .flatten()
            .flatten()
            .fold(0.0f64, |m, v| m.max(v.abs())),
    )
}

/// Diverging colour of band `k` of `2·BANDS` (0 = deepest blue).
pub fn band_color(k: usize) -> RGBColor {
    let n = BANDS as f64;
    let t = (k as f64 + 0.5) / n - 1.0; // −1 .. 1
    let a = t.abs().min(1.0);
    let (r, g, b) = if t < 0.0 {
        (1.0 - 0.85 * a, 1.0 - 0.6 * a, 1.0)
    } else {
        (1.0, 1.0 - 0.75 * a, 1.0 - 0.85 * a)
    };
    RGBColor((r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8)
}

pub fn band_of(v: f64, lim: f64) -> usize {
    let k = ((v / lim + 1.0) * BANDS as f64).floor();
    k.clamp(0.0, (2 * BANDS - 1) as f64) as usize
}

/// The error at (φ, X) between the CMM points (radii `xs`, ascending: the
/// grid's columns); `None` where the nearest point is
/// unmeasured.
pub fn interpolate(grid: &CmmGrid, xs: &[f64], phi_deg: f64, x_in: f64) -> Option<f64> {
    let rows = grid.err_uin.len();
    let cols = xs.len();
    if rows == 0 || cols < 2 {
        return None;
    }
    let step = 360.0 / rows as f64;
    let u = phi_deg.rem_euclid(360.0) / step;
    let i0 = (u.floor() as usize) % rows;
    let i1 = (i0 + 1) % rows;
    let fu = u - u.floor();
    // The bracketing radii (any spacing).
    let x = x_in.clamp(xs[0], xs[cols - 1]);
    let j0 = (0..cols - 1).rfind(|&j| xs[j] <= x).unwrap_or(0);
    let j1 = j0 + 1;
    let fv = (x - xs[j0]) / (xs[j1] - xs[j0]);
    let nearest = (
        if fu < 0.5 { i0 } else { i1 },
        if fv < 0.5 { j0 } else { j1 },
    );
    grid.err_uin[nearest.0][nearest.1]?;
    let corners = [
        (i0, j0, (1.0 - fu) * (1.0 - fv)),
        (i1, j0, fu * (1.0 - fv)),
        (i0, j1, (1.0 - fu) * fv),
        (i1, j1, fu * fv),
    ];
    let (mut sum, mut w) = (0.0, 0.0);
    for (i, j, wt) in corners {
        if let Some(e) = grid.err_uin[i][j] {
            sum += e * wt;
            w += wt;
        }
    }
    (w > 0.0).then(|| sum / w)
}

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("{e:?}")
}

/// The colour bar beside a map: the bands with their edges (±`lim`), the
/// sense of the sign, and grey labelled `grey_label`.
pub fn colour_bar<DB: DrawingBackend>(
    bar: &DrawingArea<DB, Shift>,
    lim: f64,
    grey_label: &str,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let (_, h) = bar.dim_in_pixel();
    let (top, bottom) = (50i32, h as i32 - 70);
    let step = (bottom - top) / (2 * BANDS) as i32;
    let font = ("sans-serif", 13).into_font().color(&BLACK);
    bar.draw_text("error, µin", &font, (6, top - 30))
        .map_err(err)?;
    for k in 0..2 * BANDS {
        let y1 = bottom - step * k as i32;
        bar.draw(&Rectangle::new(
            [(10, y1 - step), (40, y1)],
            band_color(k).filled(),
        ))
        .map_err(err)?;
        let edge = -lim + 2.0 * lim * k as f64 / (2 * BANDS) as f64;
        bar.draw_text(&crate::plot::tick_label(edge, lim), &font, (46, y1 - 7))
            .map_err(err)?;
    }
    bar.draw_text(
        &crate::plot::tick_label(lim, lim),
        &font,
        (46, bottom - step * (2 * BANDS) as i32 - 7),
    )
    .map_err(err)?;
    bar.draw(&Rectangle::new(
        [(10, bottom + 16), (40, bottom + 32)],
        RGBColor(170, 170, 170).filled(),
    ))
    .map_err(err)?;
    bar.draw_text(grey_label, &font, (46, bottom + 18))
        .map_err(err)?;
    bar.draw_text("+ excess stock", &font, (6, top - 14))
        .map_err(err)?;
    bar.draw_text("− too deep", &font, (6, bottom + 40))
        .map_err(err)?;
    Ok(())
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    grid: &CmmGrid,
    xs: &[f64],
    title: &str,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(err)?;
    let lim = grid_limit(&grid.err_uin);
    let (main, bar) = root.split_horizontally(820);
    let mut ch = ChartBuilder::on(&main)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..360.0, xs[0]..xs[xs.len() - 1])
        .map_err(err)?;
    let dphi = 2.0;
    let nphi = (360.0 / dphi) as usize;
    let dx = (xs[xs.len() - 1] - xs[0]) / 120.0;
    let nx = 120;
    let grey = RGBColor(170, 170, 170);
    let mut cells = Vec::with_capacity(nphi * nx);
    for a in 0..nphi {
        for b in 0..nx {
            let (p0, x0) = (a as f64 * dphi, xs[0] + b as f64 * dx);
            let c = match interpolate(grid, xs, p0 + dphi / 2.0, x0 + dx / 2.0) {
                Some(v) => band_color(band_of(v, lim)),
                None => grey,
            };
            cells.push(Rectangle::new([(p0, x0), (p0 + dphi, x0 + dx)], c.filled()));
        }
    }
    ch.draw_series(cells).map_err(err)?;
    ch.configure_mesh()
        .x_desc("φ, deg")
        .y_desc("X (radius), in")
        .x_labels(13)
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_labels(7)
        .y_label_formatter(&|v| crate::plot::tick_label(*v, xs[xs.len() - 1] - xs[0]))
        .disable_mesh()
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(err)?;
    let pts: Vec<(f64, f64)> = cmm_phi_deg()
        .into_iter()
        .flat_map(|p| xs.iter().map(move |&x| (p, x)))
        .collect();
    ch.draw_series(pts.into_iter().map(|p| Circle::new(p, 1, BLACK.filled())))
        .map_err(err)?;
    colour_bar(&bar, lim, "in a hole")?;
    root.present().map_err(err)?;
    Ok(())
}

/// Writes `<dir>/error_map.svg`, `.png` and `.csv` (φ rows, one column per
/// radius of `xs`, empty where unmeasured).
pub fn write(dir: &Path, grid: &CmmGrid, xs: &[f64], title: &str) -> anyhow::Result<()> {
    anyhow::ensure!(
        xs.len() >= 2 && grid.err_uin.iter().all(|r| r.len() == xs.len()),
        "error map: {} CMM radii for a grid of {} columns",
        xs.len(),
        grid.err_uin.first().map_or(0, Vec::len)
    );
    crate::plot::write_svg_png(
        dir,
        "error_map",
        (980, 560),
        |a| draw(a, grid, xs, title),
        |a| draw(a, grid, xs, title),
    )?;
    let series: Vec<Series> = xs
        .iter()
        .enumerate()
        .map(|(j, x)| Series {
            label: format!("X = {x} in"),
            points: super::plot::column(grid, j),
        })
        .collect();
    crate::plot::write_csv(dir, "error_map", "phi_deg", &series)
}

#[cfg(test)]
mod tests {
    use super::*;

    const XS: [f64; 7] = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];

    fn grid(f: impl Fn(f64, f64) -> Option<f64>) -> CmmGrid {
        let err_uin: Vec<Vec<Option<f64>>> = cmm_phi_deg()
            .into_iter()
            .map(|p| XS.iter().map(|&x| f(p, x)).collect())
            .collect();
        CmmGrid {
            in_hole: err_uin
                .iter()
                .map(|r| r.iter().map(Option::is_none).collect())
                .collect(),
            err_uin,
            finish_by_x_uin: vec![None; XS.len()],
        }
    }

    #[test]
    fn interpolation_is_exact_for_a_plane_in_x_and_wraps_in_phi() {
        let g = grid(|p, x| Some(10.0 * x + if p == 0.0 { 100.0 } else { 0.0 }));
        let v = interpolate(&g, &XS, 20.0, 3.25).unwrap();
        assert!((v - 32.5).abs() < 1e-9, "{v}");
        // Halfway from 350° to 360° (= 0°, +100): +50.
        let v = interpolate(&g, &XS, 355.0, 2.0).unwrap();
        assert!((v - 70.0).abs() < 1e-9, "{v}");
    }

    #[test]
    fn a_cell_next_to_a_hole_point_is_unmeasured() {
        let g = grid(|p, x| {
            if p == 40.0 && x == 3.0 {
                None
            } else {
                Some(1.0)
            }
        });
        assert_eq!(interpolate(&g, &XS, 41.0, 3.1), None);
        assert_eq!(interpolate(&g, &XS, 30.0, 3.0), Some(1.0));
    }

    #[test]
    fn band_limits_round_up_to_one_two_five() {
        assert_eq!(nice_limit(82.3), 100.0);
        assert_eq!(nice_limit(8.0), 10.0);
        assert_eq!(nice_limit(1.3), 2.0);
        assert_eq!(nice_limit(450.0), 500.0);
    }

    #[test]
    fn the_radius_axis_ticks_of_a_part_within_two_inches_are_distinct() {
        // A part's radii, 0 .. 1.5 in: whole-inch labels read "0 0 1 1 1 1 0".
        let xs = [0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5];
        let g = grid(|_, x| Some(-0.1 - 0.4 * x));
        let dir = std::env::temp_dir().join(format!("errmap-ticks-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        write(&dir, &g, &xs, "part").unwrap();
        let svg = std::fs::read_to_string(dir.join("error_map.svg")).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        // The Y axis' tick labels: text elements right-aligned at the axis.
        let labels: Vec<&str> = svg
            .split("<text")
            .skip(1)
            .filter(|t| t.contains("text-anchor=\"end\""))
            .filter_map(|t| t.split('>').nth(1)?.split('<').next())
            .collect();
        assert!(labels.len() >= 4, "{labels:?}");
        let mut sorted = labels.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(
            sorted.len(),
            labels.len(),
            "repeated Y tick labels: {labels:?}"
        );
        assert!(labels.iter().any(|l| l.contains('.')), "{labels:?}");
    }
}
