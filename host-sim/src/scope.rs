//! Stacked panels on one time axis, as a scope or a logic analyser shows
//! them: each panel has its own y axis, scale and unit, two-state signals
//! are drawn as steps between "off" and "on" in a short panel of their own,
//! a marker (the fault's instant) runs through every panel, and the legend
//! sits beside the data, never on it. Used by `faults --out` and
//! `cut --out`; `crate::plot` draws the single-axis plots.

use crate::plot::tick_label;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

pub use crate::plot::Series;

/// What a panel shows.
pub enum Kind {
    /// Values on a linear axis labelled `unit`.
    Analog { unit: String },
    /// A two-state signal (y ≠ 0 is "on").
    Digital,
}

/// One panel: its y-axis title, its curves and its share of the height.
pub struct Panel {
    pub title: String,
    pub kind: Kind,
    pub series: Vec<Series>,
    /// Relative height (an analog panel 3, a digital one 1 reads well).
    pub weight: u32,
    /// A fixed y range (values beyond it are drawn at its edge), and the
    /// note that says so.
    pub y_limits: Option<(f64, f64)>,
    pub note: Option<String>,
}

impl Panel {
    pub fn analog(title: &str, unit: &str, series: Vec<Series>) -> Panel {
        Panel {
            title: title.into(),
            kind: Kind::Analog { unit: unit.into() },
            series,
            weight: 3,
            y_limits: None,
            note: None,
        }
    }

    /// Shows `lo..hi` only, with `note` in the panel's corner (what lies
    /// beyond and why it is not the point of the plot).
    pub fn limited(mut self, lo: f64, hi: f64, note: String) -> Panel {
        self.y_limits = Some((lo, hi));
        self.note = Some(note);
        self
    }

    pub fn digital(title: &str, points: Vec<(f64, bool)>) -> Panel {
        Panel {
            title: title.into(),
            kind: Kind::Digital,
            series: vec![Series {
                label: title.into(),
                points: points
                    .into_iter()
                    .map(|(x, on)| (x, if on { 1.0 } else { 0.0 }))
                    .collect(),
            }],
            weight: 1,
            y_limits: None,
            note: None,
        }
    }
}

/// A vertical line through every panel at `x`, named in the top panel.
pub struct Marker {
    pub x: f64,
    pub label: String,
}

/// The figure: a title, a subtitle (wrapped to the width), the shared x
/// axis' label and the panels top to bottom.
pub struct Figure<'a> {
    pub title: &'a str,
    pub subtitle: &'a str,
    pub x_label: &'a str,
    pub panels: &'a [Panel],
    pub markers: &'a [Marker],
}

const WIDTH: u32 = 1100;
const LEGEND_W: u32 = 300;
const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
];

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("{e:?}")
}

/// Splits `text` into lines of at most `width` characters at spaces.
pub fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split_whitespace() {
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > width {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

fn height(fig: &Figure) -> u32 {
    let units: u32 = fig.panels.iter().map(|p| p.weight).sum();
    header_h(fig) + 60 * units + 50
}

fn header_h(fig: &Figure) -> u32 {
    40 + 20 * wrap(fig.subtitle, 120).len() as u32
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, fig: &Figure) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(err)?;
    let (head, body) = root.split_vertically(header_h(fig));
    head.draw_text(
        fig.title,
        &("sans-serif", 24).into_font().color(&BLACK),
        (14, 8),
    )
    .map_err(err)?;
    for (k, line) in wrap(fig.subtitle, 120).iter().enumerate() {
        head.draw_text(
            line,
            &("sans-serif", 15).into_font().color(&RGBColor(60, 60, 60)),
            (14, 38 + 20 * k as i32),
        )
        .map_err(err)?;
    }
    let x_range = fig
        .panels
        .iter()
        .flat_map(|p| p.series.iter().flat_map(|s| s.points.iter().map(|q| q.0)))
        .fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
    let (x0, x1) = if x_range.0 < x_range.1 {
        x_range
    } else {
        (0.0, 1.0)
    };
    let total: u32 = fig.panels.iter().map(|p| p.weight).sum::<u32>().max(1);
    let body_h = body.dim_in_pixel().1.saturating_sub(50);
    let mut breaks = Vec::new();
    let mut acc = 0;
    for p in &fig.panels[..fig.panels.len().saturating_sub(1)] {
        acc += p.weight;
        breaks.push((body_h * acc / total) as i32);
    }
    let areas = body.split_by_breakpoints([] as [i32; 0], breaks);
    let last = fig.panels.len().saturating_sub(1);
    for (k, (panel, area)) in fig.panels.iter().zip(areas).enumerate() {
        let (plot, legend) = area.split_horizontally(WIDTH - LEGEND_W);
        draw_panel(&plot, panel, (x0, x1), fig, k == 0, k == last)?;
        draw_legend(&legend, panel)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

fn y_range(panel: &Panel) -> (f64, f64) {
    if let Kind::Digital = panel.kind {
        return (-0.25, 1.25);
    }
    if let Some(l) = panel.y_limits {
        return l;
    }
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for &(_, y) in panel.series.iter().flat_map(|s| s.points.iter()) {
        if y.is_finite() {
            lo = lo.min(y);
            hi = hi.max(y);
        }
    }
    if lo > hi {
        return (-1.0, 1.0);
    }
    // A flat trace still gets a readable axis around its value.
    let span = (hi - lo).max(1e-9 + 1e-6 * lo.abs().max(hi.abs()));
    let pad = span * 0.08;
    (lo - pad, hi + pad)
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    (x0, x1): (f64, f64),
    fig: &Figure,
    top: bool,
    bottom: bool,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let (y0, y1) = y_range(panel);
    let mut chart = ChartBuilder::on(area)
        .margin_left(8)
        .margin_right(8)
        .margin_top(6)
        .x_label_area_size(if bottom { 44 } else { 18 })
        .y_label_area_size(100)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    // A digital panel is too short for a rotated title: its name is
    // written beside it, where the legends are.
    let y_desc = match &panel.kind {
        Kind::Analog { unit } => format!("{}, {unit}", panel.title),
        Kind::Digital => String::new(),
    };
    let span = y1 - y0;
    let xspan = x1 - x0;
    let digital = matches!(panel.kind, Kind::Digital);
    let y_fmt = |v: &f64| {
        if digital {
            match *v {
                v if (v - 1.0).abs() < 1e-9 => "on".to_string(),
                v if v.abs() < 1e-9 => "off".to_string(),
                _ => String::new(),
            }
        } else {
            tick_label(*v, span)
        }
    };
    let x_fmt = |v: &f64| {
        if bottom {
            tick_label(*v, xspan)
        } else {
            String::new()
        }
    };
    let mut mesh = chart.configure_mesh();
    mesh.y_desc(y_desc)
        .y_label_formatter(&y_fmt)
        .x_label_formatter(&x_fmt)
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .light_line_style(RGBColor(235, 235, 235));
    if digital {
        mesh.y_labels(3);
    } else {
        mesh.y_labels(5);
    }
    if bottom {
        mesh.x_desc(fig.x_label);
    }
    mesh.draw().map_err(err)?;
    for m in fig.markers {
        chart
            .draw_series(DashedLineSeries::new(
                vec![(m.x, y0), (m.x, y1)],
                6,
                4,
                RGBColor(200, 0, 0).stroke_width(2),
            ))
            .map_err(err)?;
        if top {
            let (px, _) = chart.backend_coord(&(m.x, y1));
            area.draw_text(
                &m.label,
                &("sans-serif", 14).into_font().color(&RGBColor(200, 0, 0)),
                (px + 6 - area.get_base_pixel().0, 8),
            )
            .map_err(err)?;
        }
    }
    if let Some(note) = &panel.note {
        // Top right, clear of the marker's label at the top left.
        let (px, py) = chart.backend_coord(&(x1, y1));
        let base = area.get_base_pixel();
        let font = ("sans-serif", 13).into_font().color(&RGBColor(90, 90, 90));
        let (w, _) = area.estimate_text_size(note, &font).map_err(err)?;
        area.draw_text(note, &font, (px - base.0 - w as i32 - 6, py - base.1 + 4))
            .map_err(err)?;
    }
    for (k, s) in panel.series.iter().enumerate() {
        let color = COLORS[k % COLORS.len()];
        let points: Vec<(f64, f64)> = if digital {
            // Steps: hold each state until the next sample.
            let mut v = Vec::with_capacity(s.points.len() * 2);
            for w in s.points.windows(2) {
                v.push(w[0]);
                v.push((w[1].0, w[0].1));
            }
            v.extend(s.points.last());
            v
        } else {
            // Clamped to a limited range: drawn along its edge.
            s.points
                .iter()
                .map(|&(x, y)| (x, if y.is_finite() { y.clamp(y0, y1) } else { y }))
                .collect()
        };
        // The first series is drawn widest, so that a second one lying on
        // it (the slide on its command) leaves it visible at the edges.
        let width = if k == 0 && panel.series.len() > 1 {
            4
        } else {
            2
        };
        for run in points.split(|p| !p.1.is_finite()).filter(|r| !r.is_empty()) {
            chart
                .draw_series(crate::plot::segments(run, color.stroke_width(width)))
                .map_err(err)?;
        }
    }
    Ok(())
}

fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    if matches!(panel.kind, Kind::Digital) {
        let (_, h) = area.dim_in_pixel();
        area.draw_text(
            &panel.title,
            &("sans-serif", 14).into_font().color(&BLACK),
            (8, h as i32 / 2 - 14),
        )
        .map_err(err)?;
        return Ok(());
    }
    let mut y = 12;
    for (k, s) in panel.series.iter().enumerate() {
        let color = COLORS[k % COLORS.len()];
        area.draw(&PathElement::new(
            vec![(4, y + 8), (26, y + 8)],
            color.stroke_width(3),
        ))
        .map_err(err)?;
        for line in wrap(&s.label, 34) {
            area.draw_text(
                &line,
                &("sans-serif", 13).into_font().color(&BLACK),
                (32, y),
            )
            .map_err(err)?;
            y += 16;
        }
        y += 6;
    }
    Ok(())
}

/// Writes `<dir>/<name>.svg`, `.png` and the CSV behind them (every
/// panel's series, labelled with their units).
pub fn write(dir: &Path, name: &str, fig: &Figure) -> anyhow::Result<()> {
    write_images(dir, name, fig)?;
    let all: Vec<Series> = fig
        .panels
        .iter()
        .flat_map(|p| {
            p.series.iter().map(move |s| Series {
                label: match &p.kind {
                    Kind::Analog { unit } if !s.label.contains(unit.as_str()) => {
                        format!("{} {unit}", s.label)
                    }
                    _ => s.label.clone(),
                },
                points: s.points.clone(),
            })
        })
        .collect();
    crate::plot::write_csv(dir, name, fig.x_label, &all)
}

/// Writes `<dir>/<name>.svg` and `.png` only (the caller writes its own
/// data file: `zslide scope`'s snapshot).
pub fn write_images(dir: &Path, name: &str, fig: &Figure) -> anyhow::Result<()> {
    crate::plot::write_svg_png(
        dir,
        name,
        (WIDTH, height(fig)),
        |a| draw(a, fig),
        |a| draw(a, fig),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrapping_keeps_every_word_and_the_width() {
        let t =
            "stalled loop: the loop tick stops for 5 ms while the amplifier holds its last output";
        let lines = wrap(t, 30);
        assert!(lines.iter().all(|l| l.chars().count() <= 30), "{lines:?}");
        assert_eq!(lines.join(" "), t);
    }

    #[test]
    fn tick_labels_have_the_digits_of_the_span_and_no_negative_zero() {
        assert_eq!(tick_label(7.199999988079071, 7.0), "7.2");
        assert_eq!(tick_label(-0.0001, 10.0), "0.0");
        assert_eq!(tick_label(0.99999999, 1e-4), "1.000000");
        assert_eq!(tick_label(81234.4, 3000.0), "81234");
    }
}
