//! `cargo xtask qemu-link`, which starts the QEMU image as a link session
//! for `zslide --connect unix:PATH ...`, and the end-to-end link test
//! `cargo xtask test` runs on it.
//!
//! `end_to_end`: a QEMU link session driven through the `zslide` tool's
//! own command lines (`zslide_host::cli::run_line`: status, fault log,
//! arm/disarm, clear, parameters in and out of limits, a fault-triggered
//! capture saved as CSV), plus malformed frames sent raw.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use zslide::link::proto::{
    self, CaptureState, FrameError, LoopPhase, Refusal, Reply, Request, Status, Trigger, MAX_FRAME,
};
use zslide::params;
use zslide_host::capture;
use zslide_host::cli::run_line;
use zslide_host::client::{unexpected, Client, Link};
use zslide_host::words::status_text;

use crate::Result;

// ------------------------------------------------------------- QEMU session

#[derive(clap::Args, Debug)]
pub struct SessionArgs {
    /// The Unix socket QEMU's UART0 listens on.
    #[arg(long, value_name = "PATH", default_value = "target/zslide-link.sock")]
    socket: PathBuf,
    /// The table to load into the table region (default: tables/default.zsct).
    #[arg(long, value_name = "FILE")]
    table: Option<PathBuf>,
    /// A parameter block to load into the parameter region.
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
}

/// A QEMU link session: the image, its UART0 on a Unix socket.
pub struct Session {
    qemu: Child,
    pub socket: PathBuf,
}

impl Drop for Session {
    fn drop(&mut self) {
        let _ = self.qemu.kill();
        let _ = self.qemu.wait();
        let _ = fs::remove_file(&self.socket);
    }
}

/// Starts the (built) QEMU image as a link session; QEMU waits for the
/// first connection before it runs the image.
pub fn start_session(socket: &Path, table: &Path, params: Option<&Path>) -> Result<Session> {
    let _ = fs::remove_file(socket);
    let qemu = crate::qemu_command_with(
        &crate::qemu_elf(),
        &crate::QemuRegions {
            table: Some(table),
            params,
        },
        &format!("unix:{},server=on,wait=on", socket.display()),
        "enable=on,target=native,arg=zslide,arg=link",
    )
    .stdin(Stdio::null())
    .stdout(Stdio::null())
    .spawn()
    .map_err(|e| format!("cannot start qemu-system-arm: {e}"))?;
    let s = Session {
        qemu,
        socket: socket.to_path_buf(),
    };
    let start = Instant::now();
    while !socket.exists() {
        if start.elapsed() > Duration::from_secs(10) {
            return Err(format!("QEMU did not open {}", socket.display()));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(s)
}

pub fn run_session(args: &SessionArgs) -> Result<u8> {
    let table = args.table.clone().unwrap_or_else(crate::default_table_path);
    check_session_files(&table, args.params.as_deref())?;
    crate::require_for_qemu()?;
    crate::build_qemu_image()?;
    let mut s = start_session(&args.socket, &table, args.params.as_deref())?;
    eprintln!(
        "QEMU link session on {} (table {}); in another shell:\n  zslide --connect unix:{} link status\nCtrl-C stops it.",
        args.socket.display(),
        table.display(),
        args.socket.display()
    );
    let status = s.qemu.wait().map_err(|e| e.to_string())?;
    Ok(status.code().unwrap_or(1).clamp(0, 255) as u8)
}

/// The files a session loads, checked as the firmware will check them,
/// before anything starts: QEMU's loader would otherwise wait on its socket
/// and the first `zslide` command would meet "connection reset".
pub fn check_session_files(table: &Path, params: Option<&Path>) -> Result<()> {
    zslide_host::regions::check_table_file(table, &zslide_host::regions::QEMU)?;
    if let Some(p) = params {
        zslide_host::regions::check_params_file(p, &zslide_host::regions::QEMU)?;
    }
    Ok(())
}

// ------------------------------------------------------------- the test

/// How long the QEMU session may take to reach a state.
const LINK_WAIT: Duration = Duration::from_secs(30);

/// One `zslide` command line on the session, its reply echoed (the
/// emulated boards' link checks share it).
pub fn cli(c: &mut Link, line: &str) -> Result<String> {
    let text = run_line(c, line)?;
    for l in text.lines() {
        eprintln!("  zslide {line:<40} | {l}");
    }
    Ok(text)
}

fn expect_refused(c: &mut Link, line: &str, words: &str) -> Result<String> {
    match cli(c, line) {
        Ok(out) => Err(format!("`zslide {line}` was accepted: {out}")),
        Err(e) if e.contains(words) => {
            eprintln!("  zslide {line:<40} | refused: {e}");
            Ok(e)
        }
        Err(e) => Err(format!("`zslide {line}`: refused for another reason: {e}")),
    }
}

/// Polls the status until `f` holds, or fails after `limit` with the last
/// status.
pub fn wait_for(
    c: &mut Link,
    what: &str,
    limit: Duration,
    f: impl Fn(&Status) -> bool,
) -> Result<Status> {
    let start = Instant::now();
    loop {
        let s = c.client()?.status()?;
        if f(&s) {
            return Ok(s);
        }
        if start.elapsed() > limit {
            return Err(format!(
                "{what}: not within {} s; status:\n{}",
                limit.as_secs(),
                status_text(&s)
            ));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The end-to-end link test on the built QEMU image (`cargo xtask test`).
/// Returns the number of checks that passed.
pub fn end_to_end() -> Result<u32> {
    crate::step(
        "host link end to end: QEMU link session over UART0, driven by zslide's command lines",
    );
    let dir = crate::root().join("target/link-e2e");
    fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let table = crate::default_table_path();
    // A parameter block in the parameter region: the hum notch's Q from
    // 20 to 10 (within its limits), read at boot.
    let block = dir.join("params.zspb");
    let q = params::by_name("hum_notch_q").ok_or("hum_notch_q")?;
    let mut bytes = vec![0u8; params::HEADER_LEN + params::ENTRY_LEN];
    let n = params::encode_block(
        &[(q.id, 10.0)],
        &zslide::servo::ServoDesign::brief(zslide_host::regions::LOOP_HZ),
        &mut bytes,
    )
    .map_err(|e| e.to_string())?;
    fs::write(&block, &bytes[..n]).map_err(|e| e.to_string())?;
    let session = start_session(&dir.join("uart0.sock"), &table, Some(&block))?;
    let mut c = Link::from_client(Client::connect(
        &format!("unix:{}", session.socket.display()),
        Duration::from_secs(10),
    )?);
    let mut checks = Checks::new("link end to end");
    let mut check = |ok: bool, what: &str| checks.ok(ok, what);

    // Status: disarmed, the table of the region, the loop running.
    let out = cli(&mut c, "link status")?;
    let s = c.client()?.status()?;
    let file = fs::read(&table).map_err(|e| e.to_string())?;
    let want = zslide::table::CoeffTable::parse(&file)
        .map_err(|e| e.to_string())?
        .identity();
    check(
        s.state.phase == LoopPhase::Disarmed && !s.state.amplifier_enabled,
        "status: not disarmed at boot",
    )?;
    check(
        s.table == Ok(want),
        "status: the table identity is not the file's",
    )?;
    check(
        out.contains(&format!("CRC {:#010x}", want.crc)),
        "status text lacks the table CRC",
    )?;
    check(
        matches!(s.params, params::ParamSource::Block { entries: 1, .. }),
        "status: the parameter block was not read",
    )?;
    check(
        cli(&mut c, "params get hum_notch_q")?.contains("hum_notch_q = 10 "),
        "the parameter block's value is not in force",
    )?;
    wait_for(&mut c, "the spindle referenced", LINK_WAIT, |s| {
        s.state.phi.is_some() && s.state.x_bits.is_some()
    })?;

    // Parameters out of and within their limits.
    expect_refused(
        &mut c,
        "params set following_error_in 0.5",
        "outside its limits 0.000001 .. 0.01 in",
    )?;
    expect_refused(
        &mut c,
        "params set learning_lead_bins 3.5",
        "must be a whole number",
    )?;
    expect_refused(
        &mut c,
        "params set bandwidth_hz 1000",
        "bandwidth_hz: must be > 0 and below rate_hz / 20",
    )?;
    // A following-error limit of 1 µin with no persistence: the first
    // tick that tracks worse than that trips the fault.
    cli(&mut c, "params set following_error_in 0.000001")?;
    cli(&mut c, "params set following_error_ms 0")?;
    let got = cli(&mut c, "params get following_error_in")?;
    check(
        got.contains("following_error_in = 0.000001 in"),
        "get after set",
    )?;

    // A capture armed on the fault, then arm: the fault triggers it.
    let csv = dir.join("fault.csv");
    // The CLI's capture waits for its trigger, and the link carries one
    // request at a time: here the capture is armed first, the loop armed
    // after, and the CLI's own reader and CSV writer take the result.
    match c.client()?.call(&Request::CaptureStart {
        samples: 600,
        pre: 200,
        trigger: Trigger::Fault,
    })? {
        Reply::Capture(i) => check(i.state == CaptureState::Armed, "capture not armed")?,
        r => return Err(unexpected(&r)),
    }
    let armed = cli(&mut c, "link arm")?;
    check(armed.contains("armed"), "arm")?;
    let s = wait_for(&mut c, "the 1 µin following-error fault", LINK_WAIT, |s| {
        s.state.fault.is_some()
    })?;
    check(
        s.state.fault == Some(zslide::safety::Fault::FollowingError),
        &format!(
            "expected the following-error fault, got {:?}",
            s.state.fault
        ),
    )?;
    let info = {
        let start = Instant::now();
        loop {
            let i = c.client()?.capture_info()?;
            if i.state == CaptureState::Done || start.elapsed() > Duration::from_secs(10) {
                break i;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    check(
        info.state == CaptureState::Done,
        "the fault did not trigger the capture",
    )?;
    // The fault may come before the 200-tick window has filled (it trips
    // soon after the arm): the capture holds what there was, and all 400
    // ticks from the trigger on.
    check(
        info.before_trigger <= 200
            && info.before_trigger > 0
            && info.recorded == info.before_trigger + 400,
        &format!("capture window: {info:?}"),
    )?;
    let samples = c.client()?.capture_read(info.recorded)?;
    fs::write(&csv, capture::csv(&info, &samples, s.loop_hz)).map_err(|e| e.to_string())?;
    // The trigger sample is the tick the fault latched: its |error| is over
    // the 1 µin (52 codes) limit; the loop was engaged before it.
    let trig = samples[usize::from(info.before_trigger)];
    check(
        trig.error.unsigned_abs() > 52,
        &format!(
            "trigger sample error {} codes, not over the limit",
            trig.error
        ),
    )?;
    let text = fs::read_to_string(&csv).map_err(|e| e.to_string())?;
    check(
        text.lines().count() == usize::from(info.recorded) + 1
            && text
                .starts_with("t_s,tick,command_uin,position_uin,error_uin,output_v,phi_deg,x_in"),
        "capture CSV",
    )?;

    // The fault log has it, at the capture's trigger tick, in words.
    let log = cli(&mut c, "link faults")?;
    let (_, records) = c.client()?.fault_log()?;
    check(
        records.iter().any(|r| {
            r.fault == zslide::safety::Fault::FollowingError
                && !r.cleared
                && r.tick == info.trigger_tick
        }),
        "fault log: the following-error record at the trigger tick",
    )?;
    check(
        log.contains("LATCHED following error beyond its limit"),
        "fault log words",
    )?;

    // Clear: refused while armed (the fault ramps to null with the loop
    // closed), accepted once disarmed.
    expect_refused(&mut c, "link clear", "clear refused")?;
    expect_refused(
        &mut c,
        "params set following_error_in 0.004",
        "only while the loop is disarmed",
    )?;
    cli(&mut c, "link disarm")?;
    wait_for(&mut c, "disarmed", LINK_WAIT, |s| {
        s.state.phase == LoopPhase::Disarmed
    })?;
    let cleared = cli(&mut c, "link clear")?;
    check(
        cleared.contains("cleared: following error beyond its limit"),
        "clear",
    )?;
    check(
        c.client()?.status()?.state.fault.is_none(),
        "fault still latched after the clear",
    )?;
    let (_, records) = c.client()?.fault_log()?;
    check(
        records.last().is_some_and(|r| r.cleared),
        "the clear is not in the log",
    )?;
    expect_refused(&mut c, "link clear", "no fault is latched")?;

    // Back to the built-in limits; arm; an immediate capture through the
    // CLI, with its plot; then a following-error-level trigger.
    cli(&mut c, "params set following_error_in 0.004")?;
    cli(&mut c, "params set following_error_ms 2")?;
    cli(&mut c, "link arm")?;
    wait_for(&mut c, "engaged", LINK_WAIT, |s| {
        s.state.phase == LoopPhase::Engaged
    })?;
    // The image's parameter store (its flash model): no save while armed.
    expect_refused(
        &mut c,
        "params save",
        "saved only while the loop is disarmed",
    )?;
    let csv2 = dir.join("immediate.csv");
    cli(
        &mut c,
        &format!(
            "capture --samples 400 --trigger immediate --csv {} --plot {}",
            csv2.display(),
            dir.join("immediate").display()
        ),
    )?;
    check(
        fs::read_to_string(&csv2)
            .map_err(|e| e.to_string())?
            .lines()
            .count()
            == 401,
        "immediate capture CSV",
    )?;
    check(
        dir.join("immediate.svg").exists() && dir.join("immediate.png").exists(),
        "capture plot",
    )?;
    let csv3 = dir.join("ferr.csv");
    cli(
        &mut c,
        &format!(
            "capture --samples 100 --pre 50 --trigger ferr:1 --csv {}",
            csv3.display()
        ),
    )?;
    let i3 = c.client()?.capture_info()?;
    let s3 = c.client()?.capture_read(i3.recorded)?;
    let t3 = s3[usize::from(i3.before_trigger)];
    check(
        t3.error.unsigned_abs() >= 52,
        "following-error trigger sample below its level",
    )?;
    check(
        s3[usize::from(i3.before_trigger) - 1].error.unsigned_abs() < 52,
        "the sample before the following-error trigger already over its level",
    )?;
    expect_refused(
        &mut c,
        "capture --samples 2000 --trigger immediate --csv /dev/null",
        // The tool's own range (`zslide::link::CAPTURE`), before the request
        // reaches the firmware, whose refusal the station's tests hold.
        "2000 is not in 1..=1024",
    )?;
    cli(&mut c, "link disarm")?;
    // Disarmed, the save goes through the station into the store.
    wait_for(&mut c, "disarmed", LINK_WAIT, |s| {
        s.state.phase == LoopPhase::Disarmed
    })?;
    let saved = cli(&mut c, "params save")?;
    // Every parameter in force (`zslide::params::PARAMS`).
    let every = format!(
        "saved {} parameters to the machine's parameter store",
        zslide::params::PARAMS.len()
    );
    check(
        saved.contains(&every),
        &format!("params save on the QEMU image: {saved}"),
    )?;

    // Malformed frames, sent raw: each refused by name and counted; the
    // firmware keeps answering.
    let before = c.client()?.status()?.frames;
    let mut good = [0u8; MAX_FRAME];
    let good = proto::encode(9, &Request::Faults { from: 0 }, &mut good)
        .ok_or("encode")?
        .to_vec();
    let raw = host_sim::faults::link::frame;
    let mut bad_crc = good.clone();
    bad_crc[3] ^= 0x08;
    let mut truncated = good[..good.len() - 4].to_vec();
    truncated.push(0);
    let mut oversize = vec![0x42u8; 300];
    oversize.push(0);
    let cases: [(&str, Vec<u8>); 6] = [
        ("garbage", vec![0x13, 0x37, 0xFF, 0x01, 0x00]),
        ("truncated", truncated),
        ("bad CRC", bad_crc),
        ("unknown command", raw(&[proto::VERSION, 9, 77])),
        ("other version", raw(&[9, 9, 0])),
        ("oversize", oversize),
    ];
    for (name, bytes) in cases {
        c.client()?.send_raw(&bytes)?;
        match c.client()?.receive()? {
            (_, Reply::Refused(Refusal::Frame(e))) => {
                eprintln!("  raw {name:<36} | refused: {e}");
                let fits = match name {
                    "unknown command" => e == FrameError::UnknownCommand(77),
                    "other version" => e == FrameError::BadVersion(9),
                    "oversize" => e == FrameError::Oversize,
                    "bad CRC" => matches!(e, FrameError::BadCrc { .. }),
                    _ => true,
                };
                check(fits, &format!("{name}: refused as {e:?}"))?;
            }
            (_, r) => return Err(format!("{name}: answered {r:?}")),
        }
    }
    let after = cli(&mut c, "link status")
        .and_then(|_| c.client()?.status())?
        .frames;
    let refused = |f: proto::FrameCounters| {
        f.oversize + f.bad_cobs + f.bad_crc + f.bad_version + f.unknown_command + f.malformed
    };
    check(
        refused(after) - refused(before) == 6,
        "malformed frames not counted",
    )?;
    drop(session);
    let n = checks.passed;
    eprintln!(
        "host link end to end: {n} checks passed (files in {})",
        dir.display()
    );
    Ok(n)
}

/// A session's checks: the count that passed, or the first that failed,
/// named after the session (`session`).
pub struct Checks {
    pub passed: u32,
    session: &'static str,
}

impl Checks {
    pub fn new(session: &'static str) -> Self {
        Self { passed: 0, session }
    }
    pub fn ok(&mut self, ok: bool, what: &str) -> Result<()> {
        if ok {
            self.passed += 1;
            Ok(())
        } else {
            Err(format!("{}: {what}", self.session))
        }
    }
}

// ------------------------------------------------------- cargo xtask link-test

/// `cargo xtask link-test`: the QEMU table-region runs, the parameter
/// fault path and the host-link end-to-end test of `cargo xtask test`, alone.
pub fn run_test() -> Result<u8> {
    crate::tools::require_for_qemu_log()?;
    crate::images::build_qemu()?;
    let (code, lines) = crate::qemu::run_qemu()?;
    if code != 0 {
        return Err(format!("the QEMU image exited with status {code}"));
    }
    let n = crate::table_checks::qemu_table_checks(&lines)?
        + crate::faultpath::params_check()?
        + end_to_end()?;
    eprintln!("{n} passed, 0 failed");
    Ok(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `qemu-link --table missing.zsct` is refused naming the file, before
    /// QEMU or a build starts.
    #[test]
    fn a_session_refuses_a_missing_or_wrong_file_first() {
        let dir = crate::root().join("target/link-session-test");
        fs::create_dir_all(&dir).unwrap();
        let e = check_session_files(&dir.join("missing.zsct"), None).unwrap_err();
        assert!(e.contains("missing.zsct: cannot read"), "{e}");
        let table = crate::default_table_path();
        assert!(check_session_files(&table, None).is_ok());
        // The table given as the parameter block.
        let e = check_session_files(&table, Some(&table)).unwrap_err();
        assert!(e.contains("this is a coefficient table (ZSCT)"), "{e}");
    }
}
