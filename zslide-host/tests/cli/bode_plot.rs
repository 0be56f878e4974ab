//! `zslide identify`'s Bode plots read back from their SVG: the measured
//! points drawn as points at their frequencies on a logarithmic axis, the
//! low-coherence ones marked apart (in the panel and in the coherence
//! panel under it); the phase unwrapped.

use std::path::PathBuf;

use nalgebra::Complex;
use zslide_host::identify::{bins, known_from_scenario, unwrap_deg, write_plots, Measured};

/// (cx, cy, r, fill, stroke) of every circle.
fn circles(svg: &str) -> Vec<(f64, f64, f64, String, String)> {
    let attr = |el: &str, name: &str| -> String {
        let at = el.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
        el[at..at + el[at..].find('"').unwrap()].to_string()
    };
    svg.split("<circle")
        .skip(1)
        .map(|el| {
            let el = &el[..el.find("/>").unwrap()];
            (
                attr(el, "cx").parse().unwrap(),
                attr(el, "cy").parse().unwrap(),
                attr(el, "r").parse().unwrap(),
                attr(el, "fill"),
                attr(el, "stroke"),
            )
        })
        .collect()
}

#[test]
fn measured_points_are_drawn_at_their_frequencies_with_low_coherence_marked() {
    let (known, plant) = known_from_scenario("legacy-hw").unwrap();
    let ks = bins(known.loop_hz, &plant);
    let n = ks.len();
    let ms: Vec<Measured> = ks
        .iter()
        .enumerate()
        .map(|(i, &k)| {
            let f_hz = k as f64 * known.loop_hz / 1024.0;
            Measured {
                f_hz,
                h: known.response(&plant, f_hz) * Complex::new(1.0, 0.02),
                // The top frequency as the issue's 2930 Hz point: 0.018.
                coherence: if i == n - 1 { 0.018 } else { 0.99 },
                rel_sigma: 0.01,
                amplitude_v: 1.0,
            }
        })
        .collect();
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/zslide-host-test/bode");
    std::fs::create_dir_all(&dir).unwrap();
    let stem = dir.join("id");
    write_plots(&stem, &ms, &known, &plant).unwrap();
    for part in ["mag", "phase"] {
        let svg = std::fs::read_to_string(dir.join(format!("id-{part}.svg"))).unwrap();
        assert!(svg.contains("frequency (Hz)"), "{part}");
        assert!(!svg.contains("log10"), "{part}");
        let c = circles(&svg);
        let good: Vec<_> = c.iter().filter(|c| c.3 != "none").collect();
        let low: Vec<_> = c.iter().filter(|c| c.3 == "none").collect();
        // Each point in its panel and in the coherence panel, one legend
        // mark for each kind.
        assert_eq!(good.len(), 2 * (n - 1) + 1, "{part}: filled points");
        assert_eq!(low.len(), 2 + 1, "{part}: marked points");
        assert!(
            low.iter().all(|c| c.4 != good[0].3),
            "{part}: marked in another colour"
        );
        // The panel's points (the upper ones at each x: the coherence
        // panel is below) on a log axis: x = a + b·log10 f to a pixel.
        let mut xs: Vec<f64> = good.iter().map(|c| c.0).collect();
        xs.sort_by(f64::total_cmp);
        xs.dedup_by(|a, b| (*a - *b).abs() < 0.01);
        let xs: Vec<f64> = xs
            .into_iter()
            .filter(|&x| good.iter().filter(|c| (c.0 - x).abs() < 0.01).count() == 2)
            .collect();
        assert_eq!(xs.len(), n - 1, "{part}: {xs:?}");
        let lf: Vec<f64> = ms[..n - 1].iter().map(|m| m.f_hz.log10()).collect();
        let b = (xs[n - 2] - xs[0]) / (lf[n - 2] - lf[0]);
        for (x, l) in xs.iter().zip(&lf) {
            let want = xs[0] + b * (l - lf[0]);
            assert!(
                (x - want).abs() < 1.0,
                "{part}: point at {x} px, log axis puts it at {want}"
            );
        }
    }
}

#[test]
fn phases_unwrap_to_steps_under_half_a_turn() {
    assert_eq!(
        unwrap_deg([170.0, -170.0, -150.0, 170.0, 10.0]),
        vec![170.0, 190.0, 210.0, 170.0, 10.0]
    );
    assert_eq!(unwrap_deg([-158.0, 180.0]), vec![-158.0, -180.0]);
}
