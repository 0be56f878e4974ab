//! Line plots as SVG and PNG with the CSV behind them, for every command
//! that writes plots (`cut`, `center`, `response`).
//!
//! Text needs a TrueType font for its metrics (both backends) and glyphs
//! (PNG): DejaVu Sans, embedded by the `dejavu` crate, so a plot never
//! depends on what fonts a machine has.

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
                .draw_series(LineSeries::new(run, color.stroke_width(2)))
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
    register_font();
    let svg = dir.join(format!("{name}.svg"));
    draw(
        SVGBackend::new(&svg, (900, 560)).into_drawing_area(),
        title,
        x_label,
        y_label,
        series,
    )
    .with_context(|| format!("writing {}", svg.display()))?;
    let png = dir.join(format!("{name}.png"));
    draw(
        BitMapBackend::new(&png, (900, 560)).into_drawing_area(),
        title,
        x_label,
        y_label,
        series,
    )
    .with_context(|| format!("writing {}", png.display()))?;
    Ok(())
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
    std::fs::write(&path, out).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
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
