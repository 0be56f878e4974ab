//! Ctrl-C (SIGINT) and SIGTERM sent to the `zslide` binary while it drives
//! `host-sim serve`: the command stops, sends the safe stop, and exits with
//! 128 + the signal; the machine is left as the loop alone drives it (no
//! excitation, no capture waiting for its trigger) by the time the tool
//! has exited, so the first status after it, one link round-trip, sees
//! the DAC back to the loop's own output. The files the command would have
//! written keep what they held.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use host_sim::serve::Setup;
use zslide::link::proto::{CaptureState, LoopPhase, Request, Trigger};
use zslide_host::cli::run_line;
use zslide_host::client::Link;
use zslide_host::words::V_PER_CODE;

mod machine;
use machine::Machine;

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../target/zslide-host-test")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn zslide(addr: &str, args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_zslide"))
        .arg("--connect")
        .arg(addr)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Reads the child's report until a line containing `what`.
fn wait_for_line(child: &mut Child, what: &str) -> Vec<String> {
    let out = child.stdout.as_mut().unwrap();
    let mut seen = Vec::new();
    for line in BufReader::new(out).lines() {
        let line = line.unwrap();
        let done = line.contains(what);
        seen.push(line);
        if done {
            return seen;
        }
    }
    panic!("the child ended before printing {what:?}: {seen:?}");
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
}

fn wait_engaged(link: &mut Link) {
    let start = Instant::now();
    while link.client().unwrap().status().unwrap().state.phase != LoopPhase::Engaged {
        assert!(start.elapsed() < Duration::from_secs(30), "not engaged");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The exit code and stderr of a child that was signalled, and how long
/// it took to exit.
fn finish(mut child: Child, since: Instant) -> (Option<i32>, String, Duration) {
    let status = child.wait().unwrap();
    let took = since.elapsed();
    let mut err = String::new();
    std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err).unwrap();
    (status.code(), err, took)
}

#[test]
fn ctrl_c_during_identify_stops_the_excitation_and_keeps_the_old_files() {
    let m = Machine::start(
        "interrupt-identify",
        Setup::new(host_sim::scenario::load("legacy-hw").unwrap()),
    );
    let dir = scratch("interrupt-identify");
    let stem = dir.join("idkeep");
    std::fs::write(stem.with_extension("csv"), "the user's csv\n").unwrap();
    std::fs::write(stem.with_extension("plant"), "amp_gain = 1\n").unwrap();
    {
        let mut link = Link::new(&m.addr, Duration::from_secs(10));
        run_line(&mut link, "link arm").unwrap();
        wait_engaged(&mut link);
    }
    let mut child = zslide(
        &m.addr,
        &["identify", "--out", stem.to_str().unwrap(), "--no-plot"],
    );
    // The first frequency measured: the second one's sine starts at once
    // and runs for a second and more of real time.
    wait_for_line(&mut child, " Hz ");
    std::thread::sleep(Duration::from_millis(150));
    let t = Instant::now();
    signal(&child, "-INT");
    let (code, err, took) = finish(child, t);
    assert_eq!(code, Some(130), "{err}");
    assert!(err.contains("excitation stopped"), "{err}");
    assert!(err.contains("stopped by SIGINT"), "{err}");
    eprintln!(
        "identify: SIGINT to exit {:.0} ms",
        took.as_secs_f64() * 1e3
    );

    let mut link = Link::new(&m.addr, Duration::from_secs(10));
    let c = link.client().unwrap();
    let s = c.status().unwrap();
    assert!(!s.state.exciting, "still exciting after the tool exited");
    assert_eq!(s.state.phase, LoopPhase::Engaged);
    // The DAC is the loop's own output: at null, a few mV, where the sine
    // was volts.
    let out = run_line(
        &mut link,
        &format!(
            "capture --samples 1024 --trigger immediate --csv {}",
            dir.join("after.csv").display()
        ),
    )
    .unwrap();
    assert!(out.contains("captured 1024"), "{out}");
    let peak_v = std::fs::read_to_string(dir.join("after.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(5).unwrap().parse::<f64>().unwrap().abs())
        .fold(0.0, f64::max);
    assert!(
        peak_v < 0.05,
        "DAC peaks at {peak_v} V after the interrupt (one code is {V_PER_CODE} V)"
    );
    assert_eq!(
        std::fs::read_to_string(stem.with_extension("csv")).unwrap(),
        "the user's csv\n"
    );
    assert_eq!(
        std::fs::read_to_string(stem.with_extension("plant")).unwrap(),
        "amp_gain = 1\n"
    );
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        3,
        "a partial file left behind"
    );
}

#[test]
fn sigterm_during_a_following_error_capture_releases_it_and_keeps_the_old_csv() {
    let m = Machine::start(
        "interrupt-capture",
        Setup::new(host_sim::scenario::load("legacy-hw").unwrap()),
    );
    let dir = scratch("interrupt-capture");
    let csv = dir.join("keep2.csv");
    std::fs::write(&csv, "the user's capture\n").unwrap();
    let mut child = zslide(
        &m.addr,
        &[
            "capture",
            "--samples",
            "200",
            "--pre",
            "50",
            "--trigger",
            "ferr:5000",
            "--csv",
            csv.to_str().unwrap(),
        ],
    );
    wait_for_line(&mut child, "capture armed");
    let t = Instant::now();
    signal(&child, "-TERM");
    let (code, err, took) = finish(child, t);
    assert_eq!(code, Some(143), "{err}");
    assert!(err.contains("armed capture released"), "{err}");
    eprintln!(
        "capture: SIGTERM to exit {:.0} ms",
        took.as_secs_f64() * 1e3
    );
    let mut link = Link::new(&m.addr, Duration::from_secs(10));
    let c = link.client().unwrap();
    let st = c.status().unwrap().capture.state;
    assert!(
        !matches!(st, CaptureState::Armed | CaptureState::Triggered),
        "capture {st:?} after the tool exited"
    );
    // A capture of one's own is armed as usual afterwards.
    let r = c
        .call(&Request::CaptureStart {
            samples: 10,
            pre: 0,
            trigger: Trigger::Immediate,
        })
        .unwrap();
    assert!(matches!(r, zslide::link::proto::Reply::Capture(_)), "{r:?}");
    assert_eq!(
        std::fs::read_to_string(&csv).unwrap(),
        "the user's capture\n"
    );
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        1,
        "a partial file left behind"
    );
}
