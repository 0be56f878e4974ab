//! Bad input as a new user types it (issue 25): each gets the command's own
//! message naming the option, value or path, a non-zero exit status, and
//! no work done first.

use std::io::Read;
use std::process::{Command, Output, Stdio};

fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

#[test]
fn negative_values_reach_the_range_check_instead_of_clap() {
    for (args, named) in [
        (&["cut", "--rpm", "-5"][..], "-5"),
        (&["cut", "--depth-in", "-0.001"][..], "--depth-in -0.001"),
        (&["soak", "--hours", "-1"][..], "-1"),
        (&["track", "--freq", "-10"][..], "-10"),
    ] {
        let o = host_sim(args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
        assert!(!e.contains("unexpected argument"), "{args:?}: {e}");
        assert!(e.contains(named), "{args:?}: {e}");
    }
}

#[test]
fn a_cut_deeper_than_the_gauge_or_the_amplifier_or_the_firmware_allows_is_refused_with_the_reason()
{
    for (args, said) in [
        (
            &["--depth-in", "0.011"][..],
            &["--depth-in 0.011", "gauge"][..],
        ),
        // k_e × 10 at 0.010 in: 2e5·0.01·1e-4 + 1500·(√(2·0.125·0.01) +
        // 50e-6) = 75.3 lbf, 26.0 A at 2.9 lbf/A, beyond legacy-hw's 8 A.
        (
            &["--depth-in", "0.01", "--ke-scale", "10"],
            &["75.3 lbf", "26.0 A", "8 A limit"],
        ),
        // k_e × 2.7: 0.2 + 405·0.050050 = 20.5 lbf, 7.1 A: within the
        // amplifier's 8 A, beyond the firmware's 6 A (current_limit_a),
        // which would fault the pass after 20 ms.
        (
            &["--depth-in", "0.01", "--ke-scale", "2.7"],
            &["20.5 lbf", "7.1 A", "firmware's current limit 6 A"],
        ),
    ] {
        let o = host_sim(&[&["cut"][..], args].concat());
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
        assert!(said.iter().all(|w| e.contains(w)), "{args:?}: {e}");
    }
}

#[test]
fn a_refused_centring_exits_non_zero_and_says_why() {
    let o = host_sim(&["center", "--offset-x", "0.6"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("centring refused") && e.contains("CentringOutOfRange"),
        "{e}"
    );
}

#[test]
fn output_paths_are_checked_before_the_work_and_named() {
    let t = std::time::Instant::now();
    let o = host_sim(&[
        "response",
        "--loop",
        "digital",
        "--svg",
        "/nonexistent-zslide-dir/l.svg",
    ]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.contains("--svg /nonexistent-zslide-dir/l.svg")
            && e.contains("/nonexistent-zslide-dir does not exist"),
        "{e}"
    );
    // The 200-point digital sweep takes minutes; the refusal comes first.
    assert!(t.elapsed().as_secs() < 20, "{:?}", t.elapsed());

    let file = std::env::temp_dir().join(format!("zslide-badout-{}", std::process::id()));
    std::fs::write(&file, b"x").unwrap();
    let o = host_sim(&["faults", "--out", file.to_str().unwrap()]);
    let e = stderr(&o);
    std::fs::remove_file(&file).ok();
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("is a file"), "{e}");
    assert!(e.contains(file.to_str().unwrap()), "{e}");

    let o = host_sim(&[
        "bench",
        "--vcd",
        "/proc/zslide-no/x.vcd",
        "--seconds",
        "0.01",
    ]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("--vcd /proc/zslide-no/x.vcd"), "{e}");
}

#[test]
fn a_table_configuration_range_error_names_its_file() {
    let cfg = std::env::temp_dir().join(format!("zslide-badcfg-{}.toml", std::process::id()));
    std::fs::write(&cfg, "[grid]\nstep_in = -0.1\n").unwrap();
    let o = host_sim(&["coeffs", "--config", cfg.to_str().unwrap()]);
    let e = stderr(&o);
    std::fs::remove_file(&cfg).ok();
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains(cfg.to_str().unwrap()), "{e}");
}

/// `host-sim coeffs | head -1`: the reader goes away after one line; the
/// tool ends without a "Broken pipe" error or a panic.
#[test]
fn a_reader_that_stops_early_is_not_an_error() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("coeffs")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Closed before the tool writes (as `head` does once it has its line;
    // closing first makes the closed pipe certain, not a race).
    drop(child.stdout.take());
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    let status = child.wait().unwrap();
    assert!(
        !err.contains("Broken pipe") && !err.contains("panicked"),
        "{status:?}: {err}"
    );
    assert_ne!(status.code(), Some(1), "{err}");
}
