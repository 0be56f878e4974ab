//! Every command that writes plots writes them on any machine: the font is
//! embedded (a machine without fonts once made every PNG, and with the
//! font-metrics backend every SVG with text, fail), PNGs are real PNGs and
//! each plot has its CSV.

use std::path::Path;
use std::process::Command;

/// The PNGs' pixels against their data (one test binary: a link each).
mod pixels;

fn host_sim(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "host-sim {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn assert_png(p: &Path) {
    let b = std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    assert!(
        b.starts_with(b"\x89PNG\r\n\x1a\n") && b.len() > 2000,
        "{}",
        p.display()
    );
}

fn assert_svg_with_text(p: &Path) {
    let s = std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    assert!(s.contains("<svg") && s.contains("<text"), "{}", p.display());
}

#[test]
fn cut_writes_both_controllers_plots_as_png_svg_and_csv_and_a_vcd() {
    let dir = std::env::temp_dir().join(format!("zslide-plots-cut-{}", std::process::id()));
    let d = dir.to_str().unwrap();
    host_sim(&[
        "cut",
        "--band-in",
        "0.0005",
        "--preroll-revs",
        "15",
        // The zone's plot has its own test (`cut::zoneplot`); its band
        // runs would add a hundred stretches here.
        "--hole-zone",
        "off",
        "--out",
        d,
    ]);
    for name in ["error_map", "error_x7", "following_error"] {
        assert_png(&dir.join(format!("{name}.png")));
        assert_svg_with_text(&dir.join(format!("{name}.svg")));
        assert!(dir.join(format!("{name}.csv")).exists(), "{name}.csv");
    }
    let x7 = std::fs::read_to_string(dir.join("error_x7.csv")).unwrap();
    let head = x7.lines().next().unwrap();
    assert!(
        head.contains("digital") && head.contains("legacy_analog"),
        "{head}"
    );
    // Axis labels in words with units, not column names; the holes as
    // the option says them; φ over the whole turn (350° closes at 360°).
    let map = std::fs::read_to_string(dir.join("error_map.svg")).unwrap();
    assert!(
        map.contains("φ, deg") && map.contains("holes open"),
        "error_map.svg"
    );
    assert!(!map.contains("holes Open"), "error_map.svg");
    let last = x7.lines().last().unwrap();
    assert!(last.starts_with("360,"), "{last}");
    let fe = std::fs::read_to_string(dir.join("following_error.svg")).unwrap();
    assert!(
        fe.contains("following error, µin") && fe.contains("cutting force, lbf"),
        "following_error.svg"
    );
    let vcd = std::fs::read_to_string(dir.join("window.vcd")).unwrap();
    assert!(vcd.contains("$enddefinitions") && vcd.contains("loop_tick"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn center_writes_labelled_png_and_svg_plots() {
    let dir = std::env::temp_dir().join(format!("zslide-plots-center-{}", std::process::id()));
    host_sim(&[
        "center",
        "--offset-x",
        "0.25",
        "--method",
        "lsq",
        "--out",
        dir.to_str().unwrap(),
    ]);
    for name in ["center_residual", "center_slides"] {
        assert_png(&dir.join(format!("{name}.png")));
        assert_svg_with_text(&dir.join(format!("{name}.svg")));
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn response_writes_a_bode_svg() {
    let dir = std::env::temp_dir().join(format!("zslide-plots-resp-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let svg = dir.join("v.svg");
    host_sim(&[
        "response",
        "--loop",
        "velocity1983",
        "--points",
        "8",
        "--svg",
        svg.to_str().unwrap(),
    ]);
    assert_svg_with_text(&svg);
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 25: the digital loop's plot never registered the font, so every
/// `response --loop digital --svg` failed ("FontUnavailable") and left an
/// empty file.
#[test]
fn digital_response_writes_an_svg_with_text() {
    let dir = std::env::temp_dir().join(format!("zslide-plots-digital-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let svg = dir.join("loop.svg");
    host_sim(&[
        "response",
        "--loop",
        "digital",
        "--points",
        "2",
        "--f-min",
        "50",
        "--f-max",
        "200",
        "--svg",
        svg.to_str().unwrap(),
    ]);
    assert_svg_with_text(&svg);
    std::fs::remove_dir_all(&dir).ok();
}

/// A fault's plot is stacked panels, one quantity and unit each, with the
/// fault's instant marked and its full name as the title.
#[test]
fn fault_plots_are_stacked_panels_with_units_and_the_instant_marked() {
    let dir = std::env::temp_dir().join(format!("zslide-plots-fault-{}", std::process::id()));
    host_sim(&[
        "faults",
        "--fault",
        "x-glitch-storm",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let p = dir.join("fault_x-glitch-storm.svg");
    assert_svg_with_text(&p);
    assert_png(&dir.join("fault_x-glitch-storm.png"));
    let s = std::fs::read_to_string(&p).unwrap();
    for want in [
        "fault: x-glitch-storm",
        "fault injected",
        "tool − exact command, µin",
        "position, µin",
        "DAC output, V",
        "fault latched",
        "amplifier enabled",
        "time after the injection, ms",
    ] {
        assert!(s.contains(want), "{want:?} missing from {}", p.display());
    }
    std::fs::remove_dir_all(&dir).ok();
}
