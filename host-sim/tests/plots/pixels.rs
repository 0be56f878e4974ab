//! A PNG plot checked against what it plots: every pixel drawn in a
//! curve's colour lies on the curve, as the SVG of the same plot draws it
//! (the SVG's polylines are the data mapped to pixels; a viewer strokes
//! them). Dense noisy data, as a capture is, once made the PNG draw spikes
//! beyond the data and through the axis labels.

use host_sim::plot::{write_images, Series};
use std::path::PathBuf;

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../target/plot-pixels")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The segments of the SVG's polylines stroked in `colour` ("#RRGGBB").
fn svg_segments(svg: &str, colour: &str) -> Vec<[(f64, f64); 2]> {
    let mut segs = Vec::new();
    for el in svg.split("<polyline").skip(1) {
        let el = &el[..el.find("/>").unwrap()];
        if !el.contains(&format!("stroke=\"{colour}\"")) {
            continue;
        }
        let pts = el.split("points=\"").nth(1).unwrap();
        let pts: Vec<(f64, f64)> = pts[..pts.find('"').unwrap()]
            .split_whitespace()
            .map(|p| {
                let (x, y) = p.split_once(',').unwrap();
                (x.parse().unwrap(), y.parse().unwrap())
            })
            .collect();
        segs.extend(pts.windows(2).map(|w| [w[0], w[1]]));
    }
    segs
}

/// The pixels of the PNG in exactly `rgb`.
fn png_pixels(path: &std::path::Path, rgb: [u8; 3]) -> Vec<(u32, u32)> {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    let ch = info.color_type.samples();
    let mut out = Vec::new();
    for y in 0..info.height {
        for x in 0..info.width {
            let i = (y * info.width + x) as usize * ch;
            if buf[i..i + 3] == rgb {
                out.push((x, y));
            }
        }
    }
    out
}

#[test]
fn a_noisy_capture_png_draws_nothing_off_its_curve() {
    let dir = scratch("noisy");
    // 1024 ticks of ±36 µin noise (a fixed LCG: the data, not the code,
    // decides the picture).
    let mut state = 12345u64;
    let points: Vec<(f64, f64)> = (0..1024)
        .map(|i| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            (i as f64 * 0.05, 72.0 * u - 36.0)
        })
        .collect();
    write_images(
        &dir,
        "idle",
        "capture",
        "time from the trigger (ms)",
        "µin",
        &[Series {
            label: "error".into(),
            points,
        }],
    )
    .unwrap();
    let svg = std::fs::read_to_string(dir.join("idle.svg")).unwrap();
    // The curve's colour: the first polyline of stroke width 2.
    let first = svg
        .split("<polyline")
        .skip(1)
        .find(|e| e.contains("stroke-width=\"2\""))
        .unwrap();
    let colour = &first[first.find("stroke=\"").unwrap() + 8..][..7];
    let rgb = [1, 3, 5].map(|k| u8::from_str_radix(&colour[k..k + 2], 16).unwrap());
    let segs = svg_segments(&svg, colour);
    assert!(segs.len() >= 1023, "{} segments", segs.len());
    let px = png_pixels(&dir.join("idle.png"), rgb);
    assert!(px.len() > 2000, "{} curve pixels", px.len());
    // Within the stroke (width 2) and a pixel of rounding of a segment
    // crossing that column.
    let tol = 2.5;
    let off: Vec<&(u32, u32)> = px
        .iter()
        .filter(|&&(x, y)| {
            let (x, y) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
            !segs.iter().any(|[a, b]| {
                let (x0, x1) = (a.0.min(b.0), a.0.max(b.0));
                let (y0, y1) = (a.1.min(b.1), a.1.max(b.1));
                x >= x0 - tol && x <= x1 + tol && y >= y0 - tol && y <= y1 + tol
            })
        })
        .collect();
    let worst = off
        .iter()
        .map(|&&(x, y)| {
            let y = f64::from(y);
            segs.iter()
                .filter(|[a, b]| {
                    (f64::from(x) - a.0.min(b.0)) > -tol && (f64::from(x) - a.0.max(b.0)) < tol
                })
                .map(|[a, b]| (a.1.min(b.1) - y).max(y - a.1.max(b.1)))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max);
    assert!(
        off.is_empty(),
        "{} of {} curve pixels of the PNG lie off the SVG's curve, up to {worst:.0} px (first {:?})",
        off.len(),
        px.len(),
        &off[..off.len().min(5)]
    );
}
