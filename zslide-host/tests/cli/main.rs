//! `zslide`'s command line: strict parsing, the capture's units, and the
//! first-day mistakes refused with a way out.

use clap::error::ErrorKind;
use clap::{CommandFactory, Parser};
use std::time::Duration;
use zslide::link::proto::{CaptureInfo, CaptureState, Sample, Trigger};
use zslide_host::capture::parse_trigger;
use zslide_host::cli::{run_line, Cli};
use zslide_host::client::Link;

/// `identify`'s Bode plots read back (one test binary: a link each).
mod bode_plot;

fn parse(args: &[&str]) -> Result<Cli, ErrorKind> {
    Cli::try_parse_from(std::iter::once("zslide").chain(args.iter().copied())).map_err(|e| e.kind())
}

#[test]
fn every_command_refuses_unknown_flags_and_has_help() {
    Cli::command().debug_assert();
    for cmd in [
        &["table", "build", "--config", "p.toml", "--out", "p.zsct"][..],
        &["table", "check", "t.zsct"],
        &["table", "flash", "t.zsct", "--dry-run"],
        &["table", "holes", "--config", "legacy-hw", "--out", "p.zsib"],
        &["params", "show"],
        &["params", "get", "damping"],
        &["params", "set", "bandwidth_hz", "40"],
        &["params", "set", "damping", "-1"],
        &["params", "load", "p.zspb"],
        &["params", "check", "p.zspb"],
        &["params", "block", "--set", "damping=1", "--out", "p.zspb"],
        &["params", "flash", "p.zspb", "--probe", "0483:374e"],
        &["link", "status"],
        &["--connect", "unix:/tmp/s", "link", "faults"],
        &["link", "arm"],
        &["link", "disarm"],
        &["link", "clear"],
        &[
            "capture",
            "--samples",
            "10",
            "--trigger",
            "fault",
            "--csv",
            "c.csv",
        ],
        &["trace2vcd", "run.log", "--out", "run.vcd"],
    ] {
        assert!(parse(cmd).is_ok(), "{cmd:?}");
        let mut bogus = cmd.to_vec();
        bogus.push("--bogus");
        assert_eq!(
            parse(&bogus).err(),
            Some(ErrorKind::UnknownArgument),
            "{bogus:?}"
        );
        let mut help = cmd.to_vec();
        help.push("--help");
        assert_eq!(parse(&help).err(), Some(ErrorKind::DisplayHelp), "{help:?}");
    }
}

#[test]
fn mistyped_values_are_refused() {
    let capture = |samples: &'static str, trigger: &'static str| {
        parse(&[
            "capture",
            "--samples",
            samples,
            "--trigger",
            trigger,
            "--csv",
            "c",
        ])
        .err()
    };
    assert_eq!(capture("0", "fault"), Some(ErrorKind::ValueValidation));
    assert_eq!(capture("9", "often"), Some(ErrorKind::ValueValidation));
    assert_eq!(
        parse(&["params", "set", "damping", "much"]).err(),
        Some(ErrorKind::ValueValidation)
    );
    assert_eq!(
        parse(&["link", "reboot"]).err(),
        Some(ErrorKind::InvalidSubcommand)
    );
    assert_eq!(
        parse(&["table", "flash"]).err(),
        Some(ErrorKind::MissingRequiredArgument)
    );
    assert_eq!(
        parse(&["params", "block", "--out", "p"]).err(),
        Some(ErrorKind::MissingRequiredArgument)
    );
}

#[test]
fn triggers_parse_and_refuse_nonsense() {
    assert_eq!(parse_trigger("immediate"), Ok(Trigger::Immediate));
    assert_eq!(parse_trigger("fault"), Ok(Trigger::Fault));
    // 10 µin = 524.288 gauge codes.
    assert_eq!(
        parse_trigger("ferr:10"),
        Ok(Trigger::FollowingError { level: 524 })
    );
    for bad in ["ferr:", "ferr:-1", "ferr:x", "sometimes", "ferr:20000"] {
        assert!(parse_trigger(bad).is_err(), "{bad}");
    }
}

/// CSV values are the codes in the documented units: 52.4288 codes per
/// µin, 10 V per 2¹⁹ codes, 2³² per turn, 2²⁴ per inch; time from the
/// trigger at the loop rate.
#[test]
fn capture_csv_converts_codes_to_units() {
    let info = CaptureInfo {
        state: CaptureState::Done,
        trigger: Trigger::Immediate,
        samples: 2,
        pre: 1,
        recorded: 2,
        before_trigger: 1,
        trigger_tick: 101,
        capacity: 1024,
    };
    let s = Sample {
        command: 524_288,
        position: 0,
        error: 524_288,
        output: -262_144,
        phi: 1 << 30,
        x_bits: 3 << 23,
    };
    let csv = zslide_host::capture::csv(&info, &[s, s], 20_000);
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(
        rows[1],
        "-0.000050,100,10000.0000,0.0000,10000.0000,-5.000000,90.0000,1.5000000"
    );
    assert!(rows[2].starts_with("0.000000,101,"));
    // A tick before the first X reading: X left empty, not 0 in.
    let unknown = Sample {
        x_bits: zslide::link::proto::X_UNKNOWN,
        ..s
    };
    let csv = zslide_host::capture::csv(&info, &[s, unknown], 20_000);
    assert!(csv.lines().nth(2).unwrap().ends_with(",90.0000,"), "{csv}");

    // The scope's snapshot: every panel on the screen, the DAC's with it.
    let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../target/zslide-host-test/scope-snapshot");
    std::fs::create_dir_all(&dir).unwrap();
    use zslide_host::scope::Signal;
    let signals = [
        Signal::Command,
        Signal::Position,
        Signal::Error,
        Signal::Dac,
    ];
    zslide_host::scope::snapshot_plot(&dir.join("scope-1"), &signals, &info, &[s, s], 20_000)
        .unwrap();
    let svg = std::fs::read_to_string(dir.join("scope-1.svg")).unwrap();
    for title in [
        "command, µin",
        "position, µin",
        "following error, µin",
        "DAC, V",
    ] {
        assert!(svg.contains(title), "no {title} panel");
    }
    assert!(dir.join("scope-1.png").exists());
}

/// `--pre` with an immediate trigger used to come back quietly shorter
/// (800 of 1000 samples): it is refused before the machine is asked.
#[test]
fn pre_trigger_ticks_with_an_immediate_trigger_are_refused() {
    // No machine at this address: the refusal must come first.
    let mut link = Link::new("unix:/nonexistent/zslide.sock", Duration::from_millis(100));
    let e = run_line(
        &mut link,
        "capture --samples 1000 --pre 200 --trigger immediate --csv /dev/null",
    )
    .unwrap_err();
    assert!(
        e.contains("--pre 200 with --trigger immediate")
            && e.contains("would hold 800 samples, not 1000"),
        "{e}"
    );
}

/// Nothing listening: the refusal says how to start a link.
#[test]
fn a_refused_connection_says_how_to_start_a_link() {
    // A port nothing listens on: bind one, then free it.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mut link = Link::new(&format!("tcp:127.0.0.1:{port}"), Duration::from_millis(100));
    let e = run_line(&mut link, "link status").unwrap_err();
    assert!(
        e.contains(&format!("connecting to tcp:127.0.0.1:{port}")),
        "{e}"
    );
    assert!(
        e.contains("host-sim serve") && e.contains("cargo xtask qemu-link"),
        "{e}"
    );
    assert!(e.contains("--connect"), "{e}");
}

/// An output path that cannot be written is refused naming it, before
/// the machine is asked for a capture.
#[test]
fn an_unwritable_capture_file_is_refused_first() {
    let mut link = Link::new("unix:/nonexistent/zslide.sock", Duration::from_millis(100));
    let e = run_line(
        &mut link,
        "capture --samples 10 --trigger fault --csv /nonexistent/dir/c.csv",
    )
    .unwrap_err();
    assert!(
        e.contains("--csv /nonexistent/dir/c.csv: directory /nonexistent/dir does not exist"),
        "{e}"
    );
}
