//! Line plots as SVG and PNG with the CSV behind them, for every command
//! that writes plots (`cut`, `center`, `response`).
//!
//! Text needs a TrueType font for its metrics (both backends) and glyphs
//! (PNG): DejaVu Sans, embedded by the `dejavu` crate, so a plot never
//! depends on what fonts a machine has.

use crate::outpath::{replace, replace_with};
use anyhow::Context;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

/// Registers the embedded font as `sans-serif`, once per process. Call
/// before drawing any text.
pub fn register_font() {
    use std::sync::Once;
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TrueType font (the crate's own asset): a
        // refusal here is a build defect, not a run-time condition.
        if plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
            .is_err()
        {
            eprintln!(
                "warning: the embedded DejaVu Sans font was refused; plot text may be missing"
            );
        }
    });
}

/// A curve as one path per segment between neighbouring points. The
/// bitmap backend fills a path wider than a pixel as one polygon whose
/// corners are the offset lines' intersections (`plotters_backend::
/// rasterizer::polygonize`): on the inside of a sharp turn (dense noisy
/// data: a capture) that intersection lies far from the curve, and the
/// PNG shows spikes beyond the data that the SVG, stroked by the viewer,
/// does not (plotters issue #549). A two-point path has no corner.
pub fn segments<'a, S: Into<ShapeStyle> + Copy + 'a>(
    points: &'a [(f64, f64)],
    style: S,
) -> impl Iterator<Item = PathElement<(f64, f64)>> + 'a {
    let one = if points.len() == 1 {
        Some(vec![points[0]; 2])
    } else {
        None
    };
    points
        .windows(2)
        .map(|w| w.to_vec())
        .chain(one)
        .map(move |p| PathElement::new(p, style))
}

/// One curve: label and (x, y) points (NaN y = gap).
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let all = series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|p| p.1.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in all {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, -1.0, 1.0);
    }
    let pad = ((y1 - y0) * 0.08).max(1e-3);
    // Room above the data for the legend (upper right), so that it never
    // hides a curve.
    let legend_room = (y1 - y0).max(1e-3) * 0.07 * series.len() as f64;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad + legend_room))
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let (xspan, yspan) = (x1 - x0, y1 - y0 + 2.0 * pad + legend_room);
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&|v| tick_label(*v, xspan))
        .y_label_formatter(&|v| tick_label(*v, yspan))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    for (k, s) in series.iter().enumerate() {
        let color = Palette99::pick(k).to_rgba();
        // Split at gaps (points not measured).
        let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
        for &p in &s.points {
            if p.1.is_finite() {
                runs.last_mut().expect("one run").push(p);
            } else if !runs.last().expect("one run").is_empty() {
                runs.push(Vec::new());
            }
        }
        let mut first = true;
        for run in runs.into_iter().filter(|r| !r.is_empty()) {
            let a = chart
                .draw_series(segments(&run, color.stroke_width(2)))
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            if first {
                a.label(s.label.clone()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                });
                first = false;
            }
        }
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    root.present().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    Ok(())
}

/// Writes `<dir>/<name>.svg`, `.png` and `.csv` (columns `x_label`, then
/// one per series).
pub fn write_plot(
    dir: &Path,
    name: &str,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> anyhow::Result<()> {
    write_images(dir, name, title, x_label, y_label, series)?;
    write_csv(dir, name, x_label, series)
}

/// Writes `<dir>/<name>.svg` and `<dir>/<name>.png` of `size` pixels,
/// each drawn by its own backend's `svg` / `png` and written whole or not
/// at all (`crate::outpath`): every plot of the tools goes through here.
pub fn write_svg_png(
    dir: &Path,
    name: &str,
    size: (u32, u32),
    svg: impl FnOnce(DrawingArea<SVGBackend, Shift>) -> anyhow::Result<()>,
    png: impl FnOnce(DrawingArea<BitMapBackend, Shift>) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    register_font();
    let path = dir.join(format!("{name}.svg"));
    replace_with(&path, |tmp| {
        svg(SVGBackend::new(tmp, size).into_drawing_area())
    })
    .with_context(|| format!("writing {}", path.display()))?;
    let path = dir.join(format!("{name}.png"));
    replace_with(&path, |tmp| {
        png(BitMapBackend::new(tmp, size).into_drawing_area())
    })
    .with_context(|| format!("writing {}", path.display()))
}

/// Writes `<dir>/<name>.svg` and `.png` only (the caller writes its own
/// data file: `zslide capture`).
pub fn write_images(
    dir: &Path,
    name: &str,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
) -> anyhow::Result<()> {
    write_svg_png(
        dir,
        name,
        (900, 560),
        |a| draw(a, title, x_label, y_label, series),
        |a| draw(a, title, x_label, y_label, series),
    )
}

/// A column name from a label: `φ, deg` → `phi_deg`, `error, µin` →
/// `error_uin` (ASCII, one `_` between words).
fn csv_name(s: &str) -> String {
    let ascii = s.replace('φ', "phi").replace('µ', "u").replace('−', "-");
    let mut out = String::new();
    for c in ascii.chars() {
        if c.is_ascii_alphanumeric() || c == '.' {
            out.push(c);
        } else if !out.ends_with('_') {
            out.push('_');
        }
    }
    out.trim_matches('_').to_string()
}

/// The CSV behind a plot: series sharing the x column when their x agree,
/// else one `x,y` pair of columns per series.
pub(crate) fn write_csv(
    dir: &Path,
    name: &str,
    x_label: &str,
    series: &[Series],
) -> anyhow::Result<()> {
    use std::fmt::Write as _;
    let path = dir.join(format!("{name}.csv"));
    let shared = series.windows(2).all(|w| {
        w[0].points
            .iter()
            .map(|p| p.0)
            .eq(w[1].points.iter().map(|p| p.0))
    });
    let mut out = String::new();
    let fmt = |v: f64| {
        if v.is_finite() {
            format!("{v}")
        } else {
            String::new()
        }
    };
    if shared {
        out.push_str(&csv_name(x_label));
        for s in series {
            write!(out, ",{}", csv_name(&s.label))?;
        }
        out.push('\n');
        let n = series.first().map_or(0, |s| s.points.len());
        for k in 0..n {
            out.push_str(&fmt(series[0].points[k].0));
            for s in series {
                write!(out, ",{}", fmt(s.points[k].1))?;
            }
            out.push('\n');
        }
    } else {
        let n = series.iter().map(|s| s.points.len()).max().unwrap_or(0);
        let head: Vec<String> = series
            .iter()
            .map(|s| {
                format!(
                    "{}_{},{}",
                    csv_name(&s.label),
                    csv_name(x_label),
                    csv_name(&s.label)
                )
            })
            .collect();
        out.push_str(&head.join(","));
        out.push('\n');
        for k in 0..n {
            let row: Vec<String> = series
                .iter()
                .map(|s| match s.points.get(k) {
                    Some(&(x, y)) => format!("{},{}", fmt(x), fmt(y)),
                    None => ",".to_string(),
                })
                .collect();
            out.push_str(&row.join(","));
            out.push('\n');
        }
    }
    replace(&path, out)
}

/// Tick labels with the digits the span needs, no binary noise.
pub fn tick_label(v: f64, span: f64) -> String {
    let digits = if span >= 50.0 {
        0
    } else if span >= 5.0 {
        1
    } else if span >= 0.5 {
        2
    } else {
        (-(span.log10().floor()) as usize + 2).min(9)
    };
    let s = format!("{v:.digits$}");
    if s.starts_with('-') && s.trim_start_matches(['-', '0', '.']).is_empty() {
        s[1..].to_string()
    } else {
        s
    }
}

/// One measured frequency of a Bode plot.
#[derive(Clone, Copy, Debug)]
pub struct BodePoint {
    pub f_hz: f64,
    pub value: f64,
    /// The measurement's coherence (0..1).
    pub coherence: f64,
}

/// A Bode plot's panel (magnitude or phase) over the measurement's
/// coherence, on one logarithmic frequency axis in Hz: the measured
/// points drawn as points (filled: coherence at least `coherence_min`;
/// hollow and red below it, where the point says more about the noise
/// than the plant), the fitted model as a line. `<dir>/<name>.svg` and
/// `.png`.
pub fn write_bode(
    dir: &Path,
    name: &str,
    title: &str,
    y_label: &str,
    measured: &[BodePoint],
    model: &[(f64, f64)],
    coherence_min: f64,
) -> anyhow::Result<()> {
    write_svg_png(
        dir,
        name,
        (900, 640),
        |a| draw_bode(a, title, y_label, measured, model, coherence_min),
        |a| draw_bode(a, title, y_label, measured, model, coherence_min),
    )
}

/// Red: a measured point of low coherence.
pub const LOW_COHERENCE: RGBColor = RGBColor(214, 39, 40);
/// Blue: a measured point; the model's line is black.
pub const MEASURED: RGBColor = RGBColor(31, 119, 180);

fn draw_bode<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    title: &str,
    y_label: &str,
    measured: &[BodePoint],
    model: &[(f64, f64)],
    coherence_min: f64,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |e| anyhow::anyhow!("{e:?}");
    root.fill(&WHITE).map_err(e)?;
    let fs = measured
        .iter()
        .map(|m| m.f_hz)
        .chain(model.iter().map(|p| p.0));
    let (f0, f1) = fs.fold((f64::MAX, f64::MIN), |(a, b), f| (a.min(f), b.max(f)));
    anyhow::ensure!(
        f0 > 0.0 && f1 > f0,
        "a Bode plot needs frequencies above 0 Hz"
    );
    let ys = measured
        .iter()
        .map(|m| m.value)
        .chain(model.iter().map(|p| p.1))
        .filter(|y| y.is_finite());
    let (y0, y1) = ys.fold((f64::MAX, f64::MIN), |(a, b), y| (a.min(y), b.max(y)));
    let pad = ((y1 - y0) * 0.08).max(1.0);
    let root = root.titled(title, ("sans-serif", 20)).map_err(e)?;
    let (top, bottom) = root.split_vertically(root.dim_in_pixel().1 * 7 / 10);
    let hz = |v: &f64| format!("{v:.0}");
    let mut ch = ChartBuilder::on(&top)
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(70)
        .build_cartesian_2d((f0 * 0.9..f1 * 1.1).log_scale(), (y0 - pad)..(y1 + pad))
        .map_err(e)?;
    ch.configure_mesh()
        .x_desc("frequency (Hz)")
        .y_desc(y_label)
        .x_label_formatter(&hz)
        .y_label_formatter(&|v| tick_label(*v, y1 - y0 + 2.0 * pad))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(e)?;
    ch.draw_series(segments(model, BLACK.stroke_width(2)))
        .map_err(e)?
        .label("fit (model)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(2)));
    let good = measured.iter().filter(|m| m.coherence >= coherence_min);
    ch.draw_series(good.map(|m| Circle::new((m.f_hz, m.value), 4, MEASURED.filled())))
        .map_err(e)?
        .label("measured")
        .legend(|(x, y)| Circle::new((x + 9, y), 4, MEASURED.filled()));
    let low = measured.iter().filter(|m| m.coherence < coherence_min);
    ch.draw_series(low.map(|m| Circle::new((m.f_hz, m.value), 5, LOW_COHERENCE.stroke_width(2))))
        .map_err(e)?
        .label(format!("measured, coherence < {coherence_min}"))
        .legend(|(x, y)| Circle::new((x + 9, y), 5, LOW_COHERENCE.stroke_width(2)));
    ch.configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    let mut co = ChartBuilder::on(&bottom)
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(70)
        .build_cartesian_2d((f0 * 0.9..f1 * 1.1).log_scale(), 0.0..1.05)
        .map_err(e)?;
    co.configure_mesh()
        .x_desc("frequency (Hz)")
        .y_desc("coherence")
        .x_label_formatter(&hz)
        .y_labels(3)
        .y_label_formatter(&|v| format!("{v:.1}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()
        .map_err(e)?;
    co.draw_series(DashedLineSeries::new(
        [(f0 * 0.9, coherence_min), (f1 * 1.1, coherence_min)],
        6,
        4,
        LOW_COHERENCE.into(),
    ))
    .map_err(e)?;
    co.draw_series(measured.iter().map(|m| {
        let c = if m.coherence >= coherence_min {
            MEASURED.filled()
        } else {
            LOW_COHERENCE.stroke_width(2)
        };
        Circle::new((m.f_hz, m.coherence.clamp(0.0, 1.05)), 4, c)
    }))
    .map_err(e)?;
    root.present().map_err(e)?;
    Ok(())
}
