//! The hole zone's plot (`cut --out`): the ring unrolled, the part's angle
//! φ across, the surface radius up, the error in the error map's colour
//! bands (blue: too deep, red: excess stock), open holes grey and every
//! hole's rim drawn. The upper panel is the whole ring; the lower one the
//! ±15° around the hole with the largest error next to it, at the grid's
//! own resolution. With `hole_zone.csv`: every grid point.

use super::errmap::{band_color, band_of, colour_bar, grid_limit};
use super::holezone::{half_width_deg, ZoneGrid, ZoneMeasured, PHI_COUNT};
use anyhow::Context;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::io::Write;
use std::path::Path;

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("{e:?}")
}

/// The hole nearest the largest |error| (degrees of its centre).
fn worst_hole_deg(z: &ZoneMeasured) -> f64 {
    let mut worst = (0.0f64, 0usize);
    for (i, row) in z.err_uin.iter().enumerate() {
        for e in row.iter().flatten() {
            if e.abs() > worst.0 {
                worst = (e.abs(), i);
            }
        }
    }
    let phi = ZoneGrid::phi_deg(worst.1);
    z.grid
        .hole_deg()
        .into_iter()
        .min_by(|a, b| {
            let d = |h: f64| ((phi - h + 180.0).rem_euclid(360.0) - 180.0).abs();
            d(*a).total_cmp(&d(*b))
        })
        .unwrap_or(0.0)
}

fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    z: &ZoneMeasured,
    lim: f64,
    (from, to): (f64, f64),
    title: &str,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    let r = &z.grid.radii;
    let dr = (r[r.len() - 1] - r[0]) / (r.len() - 1) as f64;
    let (y0, y1) = (r[0] - dr / 2.0, r[r.len() - 1] + dr / 2.0);
    let mut ch = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(from..to, y0..y1)
        .map_err(err)?;
    let dphi = 360.0 / PHI_COUNT as f64;
    let grey = RGBColor(170, 170, 170);
    let white = RGBColor(255, 255, 255);
    let mut cells = Vec::new();
    for (i, row) in z.err_uin.iter().enumerate() {
        // Unwrapped into the panel's range.
        let mut p = ZoneGrid::phi_deg(i);
        while p < from - dphi {
            p += 360.0;
        }
        while p > to + dphi {
            p -= 360.0;
        }
        if p < from - dphi || p > to + dphi {
            continue;
        }
        for (j, e) in row.iter().enumerate() {
            let c = match e {
                Some(v) => band_color(band_of(*v, lim)),
                None if z.place[i][j].in_hole => grey,
                None => white,
            };
            cells.push(Rectangle::new(
                [
                    (p - dphi / 2.0, r[j] - dr / 2.0),
                    (p + dphi / 2.0, r[j] + dr / 2.0),
                ],
                c.filled(),
            ));
        }
    }
    ch.draw_series(cells).map_err(err)?;
    ch.configure_mesh()
        .x_desc("φ (part frame), deg; the tool runs toward −φ")
        .y_desc("radius, in")
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.2}"))
        .disable_mesh()
        .label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 14))
        .draw()
        .map_err(err)?;
    // Every hole's rim, both halves, at 200 radii.
    let h = z.grid.holes();
    let rho = h.diameter_in / 2.0;
    for c in z.grid.hole_deg() {
        for shift in [-360.0, 0.0, 360.0] {
            let centre = c + shift;
            if centre + 30.0 < from || centre - 30.0 > to {
                continue;
            }
            for side in [-1.0, 1.0] {
                let pts: Vec<(f64, f64)> = (0..=200)
                    .filter_map(|k| {
                        let rr = h.circle_radius_in - rho + 2.0 * rho * f64::from(k) / 200.0;
                        half_width_deg(h, rr).map(|w| (centre + side * w, rr))
                    })
                    .filter(|&(p, _)| p >= from && p <= to)
                    .collect();
                ch.draw_series(LineSeries::new(pts, BLACK.stroke_width(1)))
                    .map_err(err)?;
            }
        }
    }
    Ok(())
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    z: &ZoneMeasured,
    title: &str,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(err)?;
    let lim = grid_limit(&z.err_uin);
    let root = root.titled(title, ("sans-serif", 18)).map_err(err)?;
    let (w, _) = root.dim_in_pixel();
    let (main, bar) = root.split_horizontally(w - 130);
    let (top, bottom) = main.split_vertically(330);
    panel(&top, z, lim, (0.0, 360.0), "the whole ring")?;
    let c = worst_hole_deg(z);
    panel(
        &bottom,
        z,
        lim,
        (c - 15.0, c + 15.0),
        &format!("around the hole at {c:.1}° (the largest error next to it)"),
    )?;
    colour_bar(&bar, lim, "open hole")?;
    root.present().map_err(err)?;
    Ok(())
}

/// Writes `<dir>/hole_zone.png` and `hole_zone.csv` (every grid point:
/// radius, φ, error or empty, in a hole, distance from the nearest edge,
/// side).
pub fn write(dir: &Path, z: &ZoneMeasured, title: &str) -> anyhow::Result<()> {
    crate::plot::register_font();
    let png = dir.join("hole_zone.png");
    draw(
        BitMapBackend::new(&png, (1500, 720)).into_drawing_area(),
        z,
        title,
    )
    .with_context(|| format!("writing {}", png.display()))?;
    let csv = dir.join("hole_zone.csv");
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(&csv).with_context(|| format!("writing {}", csv.display()))?,
    );
    writeln!(
        f,
        "radius_in,phi_deg,error_uin,in_hole,edge_distance_in,side"
    )?;
    for (i, row) in z.err_uin.iter().enumerate() {
        for (j, e) in row.iter().enumerate() {
            let p = z.place[i][j];
            writeln!(
                f,
                "{:.4},{:.2},{},{},{:.4},{}",
                z.grid.radii[j],
                ZoneGrid::phi_deg(i),
                e.map_or(String::new(), |v| format!("{v:.2}")),
                p.in_hole,
                p.edge_in,
                if p.leading { "leading" } else { "trailing" }
            )?;
        }
    }
    f.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cut::holezone::ZoneLog;
    use crate::plant::cutting::BoltHoles;

    #[test]
    fn the_zone_plot_and_its_csv_cover_every_grid_point() {
        let g = ZoneGrid::new(&BoltHoles::default(), 1.0, 7.25).unwrap();
        let mut log = ZoneLog::new(&g, 0.125, 100e-6, vec![]);
        for i in 0..PHI_COUNT {
            let mut x = g.radii[0] - 0.001;
            while x < g.radii[g.radii.len() - 1] + 0.001 {
                log.add(i, x, 1e-6 * (x - 3.5));
                x += 100e-6;
            }
        }
        let z = ZoneMeasured::measure(&g, &log);
        let dir = std::env::temp_dir().join(format!("zslide-zoneplot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        write(&dir, &z, "test").unwrap();
        let png = std::fs::read(dir.join("hole_zone.png")).unwrap();
        assert!(
            png.starts_with(b"\x89PNG") && png.len() > 10_000,
            "{}",
            png.len()
        );
        let csv = std::fs::read_to_string(dir.join("hole_zone.csv")).unwrap();
        assert_eq!(csv.lines().count(), 1 + PHI_COUNT * g.radii.len());
        assert!(csv.lines().any(|l| l.contains(",true,")), "hole points");
        std::fs::remove_dir_all(&dir).ok();
    }
}
