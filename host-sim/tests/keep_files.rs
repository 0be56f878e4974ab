//! A refused or interrupted command leaves the user's files as they were:
//! each command of `host-sim` that writes files, refused after its output
//! was named, against existing files; and one stopped by Ctrl-C while it
//! writes. No hidden partial file is left either.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn scratch(name: &str) -> PathBuf {
    let d = root().join("target/keep-files").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn host_sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .current_dir(root())
        .output()
        .unwrap()
}

/// `host-sim args` with `files` (name, text) standing in `dir`: refused
/// with `why` in its words, every file as it was and nothing else
/// in `dir`.
fn refused_keeps(dir: &Path, files: &[(&str, &str)], args: &[&str], why: &str) {
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).unwrap();
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let out = host_sim(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "host-sim {args:?}: {err}");
    assert!(err.contains(why), "host-sim {args:?}: {err}");
    for (name, text) in files {
        assert_eq!(
            std::fs::read_to_string(dir.join(name)).unwrap(),
            *text,
            "host-sim {args:?} changed {name}"
        );
    }
    let left: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), files.len(), "host-sim {args:?} left {left:?}");
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn a_table_refused_keeps_the_old_table() {
    let dir = scratch("tables");
    let t = dir.join("keep.zsct");
    refused_keeps(
        &dir,
        &[("keep.zsct", "old table")],
        &[
            "coeffs",
            "--config",
            "tables/toric-lens.toml",
            "--out",
            s(&t),
        ],
        "is a part file (docs/PARTS.md)",
    );
    // A bound the firmware's allowance alone uses up.
    let part = std::fs::read_to_string(root().join("tables/toric-lens.toml"))
        .unwrap()
        .replace("bound_uin = 0.1", "bound_uin = 0.005");
    let other = scratch("tables-part");
    let p = other.join("tight.toml");
    std::fs::write(&p, part).unwrap();
    refused_keeps(
        &dir,
        &[("keep.zsct", "old table")],
        &["part-table", s(&p), "--out", s(&t)],
        "firmware_allowance_uin = 0.01: must be in",
    );
}

#[test]
fn a_trace_refused_or_interrupted_keeps_the_old_vcd() {
    let dir = scratch("trace");
    let vcd = dir.join("keep.vcd");
    refused_keeps(
        &dir,
        &[("keep.vcd", "old vcd")],
        &["trace2vcd", s(&dir.join("missing.log")), "--out", s(&vcd)],
        "cannot open",
    );
    // Reading a log from stdin, Ctrl-C before it ends.
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["trace2vcd", "-", "--out", s(&vcd)])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // stdin stays open until the tool has exited: closed earlier, its EOF
    // could end the read (exit 1) before the signal thread exits 130.
    let mut stdin = child.stdin.take().unwrap();
    stdin.write_all(b"0.000001 ").unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let ok = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let status = child.wait().unwrap();
    drop(stdin);
    let out = std::process::Output {
        status,
        stdout: Vec::new(),
        stderr: {
            let mut e = Vec::new();
            std::io::Read::read_to_end(&mut child.stderr.take().unwrap(), &mut e).unwrap();
            e
        },
    };
    assert_eq!(
        out.status.code(),
        Some(130),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(std::fs::read_to_string(&vcd).unwrap(), "old vcd");
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        1,
        "a partial file left"
    );
}

#[test]
fn refused_runs_keep_the_old_plots_and_data() {
    let dir = scratch("runs");
    let missing = dir.join("no-such-part.toml");
    let keep = [
        ("error_map.png", "old png"),
        ("error_map.csv", "old csv"),
        ("predicted_error_map.png", "old png"),
    ];
    refused_keeps(
        &dir,
        &keep,
        &["cut", "--part", s(&missing), "--out", s(&dir)],
        "no-such-part.toml",
    );
    refused_keeps(
        &dir,
        &keep,
        &["plan", s(&missing), "--out", s(&dir)],
        "no-such-part.toml",
    );
    refused_keeps(
        &dir,
        &[("r.csv", "old csv"), ("r.svg", "old svg")],
        &[
            "response",
            "--loop",
            "digital",
            "--csv",
            s(&dir.join("r.csv")),
            "--svg",
            s(&dir.join("r.svg")),
            "--scenario",
            "no-such-scenario",
        ],
        "no-such-scenario",
    );
    refused_keeps(
        &dir,
        &[("fault_x-glitch-storm.png", "old png")],
        &["faults", "--out", s(&dir), "--fault", "no-such-fault"],
        "no-such-fault",
    );
}

#[test]
fn serve_refuses_a_bad_speed_before_its_banner_and_writes_no_flash_file() {
    let dir = scratch("serve");
    let flash = dir.join("flash.bin");
    refused_keeps(
        &dir,
        &[],
        &[
            "serve",
            "--params-flash",
            s(&flash),
            "--speed",
            "-2",
            "--listen",
            "tcp:127.0.0.1:1",
        ],
        "--speed -2: must be in (0, 100]",
    );
    let out = host_sim(&["serve", "--speed", "-2", "--listen", "tcp:127.0.0.1:1"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !err.contains("in another shell"),
        "the banner came first: {err}"
    );
}
