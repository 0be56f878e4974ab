//! `zslide` against `host-sim serve`: the simulated machine behind the
//! firmware's link, in real time, driven through the tool's own command
//! lines as a user types them.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use host_sim::serve::Setup;
use zslide::link::proto::LoopPhase;
use zslide_host::cli::run_line;
use zslide_host::client::Link;
use zslide_host::words::CODES_PER_UIN;

mod machine;
use machine::Machine;

fn wait_phase(link: &mut Link, want: LoopPhase) -> zslide::link::proto::Status {
    let start = Instant::now();
    loop {
        let s = link.client().unwrap().status().unwrap();
        if s.state.phase == want {
            return s;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "not {want:?} within 60 s: {}",
            zslide_host::words::status_text(&s)
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A capture CSV row as numbers; x_in (empty while the firmware has no X
/// reading yet) as NaN.
fn row(line: &str) -> Vec<f64> {
    line.split(',')
        .map(|v| {
            if v.is_empty() {
                f64::NAN
            } else {
                v.parse().unwrap()
            }
        })
        .collect()
}

#[test]
fn status_arm_and_capture_on_the_simulated_machine() {
    let m = Machine::start(
        "serve-e2e",
        Setup::new(host_sim::scenario::load("legacy-hw").unwrap()),
    );
    let mut link = Link::new(&m.addr, Duration::from_secs(10));
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/zslide-host-test");

    let out = run_line(&mut link, "link status").unwrap();
    assert!(
        out.starts_with("loop: disarmed (amplifier off), 20000 Hz"),
        "{out}"
    );
    assert!(out.contains("table: "), "{out}");

    // Every parameter's value in its column: the limits start at one place.
    let shown = run_line(&mut link, "params show").unwrap();
    let cols: Vec<usize> = shown.lines().filter_map(|l| l.find(" limits ")).collect();
    assert_eq!(cols.len(), zslide::params::PARAMS.len(), "{shown}");
    assert!(cols.iter().all(|&c| c == cols[0]), "{shown}");

    // A change is refused while armed, accepted while disarmed.
    run_line(&mut link, "params set following_error_ms 3").unwrap();
    assert!(run_line(&mut link, "params get following_error_ms")
        .unwrap()
        .contains("following_error_ms = 3 ms"));
    let armed = run_line(&mut link, "link arm").unwrap();
    assert!(armed.contains("loop armed"), "{armed}");
    let s = wait_phase(&mut link, LoopPhase::Engaged);
    assert!(s.state.amplifier_enabled);
    let e = run_line(&mut link, "params set following_error_ms 2").unwrap_err();
    assert!(e.contains("only while the loop is disarmed"), "{e}");

    // An immediate capture: every tick recorded, the CSV in µin.
    let csv = dir.join("serve-immediate.csv");
    let said = run_line(
        &mut link,
        &format!(
            "capture --samples 200 --trigger immediate --csv {}",
            csv.display()
        ),
    )
    .unwrap();
    assert!(
        said.contains("captured 200 samples (0 before the trigger"),
        "{said}"
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<Vec<f64>> = text.lines().skip(1).map(row).collect();
    assert_eq!(rows.len(), 200);
    // Consecutive ticks, 50 µs apart; error = command − position.
    for w in rows.windows(2) {
        assert_eq!(w[1][1] - w[0][1], 1.0);
        assert!((w[1][0] - w[0][0] - 50e-6).abs() < 1e-9);
    }
    for r in &rows {
        assert!((r[4] - (r[2] - r[3])).abs() < 2.0 / CODES_PER_UIN, "{r:?}");
    }

    // A following-error trigger at a level the engaged loop crosses: the
    // largest error of the immediate capture, halved.
    let largest = rows.iter().map(|r| r[4].abs()).fold(0.0, f64::max);
    let level = (largest / 2.0).max(0.05);
    let csv2 = dir.join("serve-ferr.csv");
    let said = run_line(
        &mut link,
        &format!(
            "capture --samples 100 --pre 40 --trigger ferr:{level:.3} --csv {} --wait-s 30",
            csv2.display()
        ),
    )
    .unwrap();
    assert!(said.contains("µin"), "the trigger in µin: {said}");
    let rows2: Vec<Vec<f64>> = std::fs::read_to_string(&csv2)
        .unwrap()
        .lines()
        .skip(1)
        .map(row)
        .collect();
    let at = rows2.iter().position(|r| r[0] == 0.0).unwrap();
    assert!(rows2[at][4].abs() >= level - 0.02, "{:?}", rows2[at]);
    assert!(rows2[at - 1][4].abs() < level + 0.02, "{:?}", rows2[at - 1]);

    run_line(&mut link, "link disarm").unwrap();
    wait_phase(&mut link, LoopPhase::Disarmed);
    let faults = run_line(&mut link, "link faults").unwrap();
    assert!(faults.starts_with("fault log: "), "{faults}");
}
