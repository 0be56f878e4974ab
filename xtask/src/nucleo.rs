//! `cargo xtask nucleo [--json] [--ms N]`: the release `zslide-fw` ELF,
//! the file `cargo run --release --bin zslide-fw` flashes, run unmodified
//! on the emulated NUCLEO-H743ZI2 (`boards/nucleo-emu`, docs/BOARD.md
//! "Emulated NUCLEO"), driven through its RTT link by the `zslide` tool's
//! own client and command lines:
//!
//! 1. boot with `tables/default.zsct` in the table region and an erased
//!    bank 2: the table identity and the built-in parameters over the link;
//! 2. `link arm`, the spindle referenced and X events in, engaged: a
//!    capture of the loop's own command and position gives the tracking;
//! 3. the gauge's SDO stuck high (the emulator's `break-gauge`): the loop
//!    latches `Bus(GaugeAdc)` and disables the amplifier;
//! 4. disarm, `params set hum_notch_q 10`, `params save` into the bank-2
//!    flash model; the client closes and the emulator ends;
//! 5. a power cycle: the same bank 2, a new boot: the saved block in force;
//! 6. a corrupt table (one byte of the default's coefficients flipped):
//!    refused, `Fault::Table` latched, the slide held at null;
//! 7. `zslide-centre` boots and runs its 10 kHz tick for 50 ms.
//!
//! Every run stops on a register access no model implements or on an
//! access RM0433 or a converter's datasheet forbids, naming it.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::{Duration, Instant};

use zslide::link::proto::{CaptureState, LoopPhase, Reply, Request, Trigger};
use zslide::params::ParamSource;
use zslide::safety::{Device, Fault};
use zslide_host::client::{unexpected, Client, Link};

use crate::link::{cli, wait_for, Checks};
use crate::Result;

/// How long the emulated board may take to reach a state (its link is
/// slower than QEMU's: the emulator runs the H7's clock on one host core).
const EMU_WAIT: Duration = Duration::from_secs(60);

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print one JSON object (the run's figures) on stdout.
    #[arg(long)]
    json: bool,
    /// Machine time the first boot may take at most, ms (it ends when the
    /// checks are done: 160-170 ms).
    #[arg(long, default_value_t = TEST_MS, value_name = "N")]
    ms: u64,
}

/// One gauge code in µin (2¹⁹ codes = 0.010 in).
const UIN_PER_CODE: f64 = 0.010e6 / 524_288.0;
/// The QEMU image's tracking line in its blessed log (the log CI checks
/// the QEMU run against: `cargo xtask qemu`).
const QEMU_TRACKING: &str = "tracking: max |command - position| = ";
/// How far the emulated NUCLEO's tracking may be from the QEMU image's on
/// the same script: both run the one core, plant and table; what differs
/// is the board (200 MHz captured spindle edges against QEMU's 25 MHz
/// synthetic clock), the sampling window and the gauge noise's instants.
pub const TRACKING_TOLERANCE_UIN: f64 = 5.0;

/// The first boot's machine-time limit in `cargo xtask test`: a bound,
/// not the length (a run ends when the link client closes; the first boot
/// takes 160-170 ms): the emulator runs on while the client waits on the
/// wall clock, so the bound leaves room for a slow machine.
pub const TEST_MS: u64 = 3_000;
/// The later boots' bound (they end at the client's close, after ~30 ms).
const SHORT_BOOT_MS: u64 = 2_000;

fn emu_dir() -> PathBuf {
    crate::root().join("boards/nucleo-emu")
}
fn emu_bin() -> PathBuf {
    crate::target_dir().join("nucleo-emu/release/nucleo-emu")
}
fn work_dir() -> PathBuf {
    crate::target_dir().join("nucleo")
}

/// Debian's libunicorn (2.0.1, with pkg-config's file): the emulator's
/// crate links it and compiles no C.
pub fn require_unicorn() -> Result<()> {
    let found = || crate::tools::works("pkg-config", &["--exists", "unicorn"]);
    if found() {
        return Ok(());
    }
    crate::tools::apt_tool("pkg-config", "pkg-config", "pkg-config")?;
    if !found() {
        let root = crate::tools::output("id", &["-u"]).is_some_and(|s| s.trim() == "0");
        if !root {
            return Err("libunicorn: run `sudo apt-get install -y libunicorn-dev`".into());
        }
        crate::step("installing libunicorn-dev (apt-get)");
        crate::tools::run(
            Command::new("apt-get")
                .args(["install", "-y", "--no-install-recommends", "libunicorn-dev"])
                .env("DEBIAN_FRONTEND", "noninteractive"),
            "apt-get install libunicorn-dev",
        )?;
    }
    if found() {
        Ok(())
    } else {
        Err("libunicorn-dev installed but pkg-config does not find unicorn".into())
    }
}

pub fn build_emulator() -> Result<()> {
    crate::step("emulated NUCLEO: cargo build --release (boards/nucleo-emu)");
    crate::tools::run(
        crate::cargo().current_dir(emu_dir()).args([
            "build",
            "--release",
            "--target-dir",
            &crate::target_dir().join("nucleo-emu").to_string_lossy(),
        ]),
        "nucleo-emu build",
    )
}

/// The emulator's own tests (its converters against their datasheets'
/// frames); the number that passed.
pub fn model_tests() -> Result<u64> {
    crate::step("emulated NUCLEO: its models' tests (cargo test, boards/nucleo-emu)");
    let out = crate::cargo()
        .current_dir(emu_dir())
        .args([
            "test",
            "--release",
            "--target-dir",
            &crate::target_dir().join("nucleo-emu").to_string_lossy(),
        ])
        .output()
        .map_err(|e| format!("cargo test (nucleo-emu): {e}"))?;
    let text = String::from_utf8_lossy(&out.stdout);
    let (mut passed, mut failed) = (0, 0);
    for (p, f, _) in text.lines().filter_map(crate::nextest::parse_test_result) {
        passed += p;
        failed += f;
    }
    if !out.status.success() || failed > 0 {
        return Err(format!("nucleo-emu's tests failed:\n{text}"));
    }
    Ok(passed)
}

/// A running emulator with its link socket.
struct Emu {
    child: Child,
    stdin: ChildStdin,
    socket: PathBuf,
}

impl Emu {
    fn start(table: &Path, bank2: &Path, ms: u64, name: &str) -> Result<Self> {
        let dir = work_dir();
        let socket = dir.join(format!("{name}.sock"));
        let _ = fs::remove_file(&socket);
        let mut child = Command::new(emu_bin())
            .arg("--elf")
            .arg(crate::board_elf())
            .arg("--table")
            .arg(table)
            .arg("--bank2")
            .arg(bank2)
            .args(["--ms", &ms.to_string()])
            .arg("--socket")
            .arg(&socket)
            .arg("--end-on-close")
            .arg("--log")
            .arg(dir.join(format!("{name}.defmt")))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .map_err(|e| format!("cannot start {}: {e}", emu_bin().display()))?;
        let stdin = child.stdin.take().ok_or("emulator stdin")?;
        let start = Instant::now();
        while !socket.exists() {
            if start.elapsed() > Duration::from_secs(20) {
                return Err(format!("the emulator did not open {}", socket.display()));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        Ok(Self {
            child,
            stdin,
            socket,
        })
    }

    fn connect(&self) -> Result<Link> {
        Ok(Link::from_client(Client::connect(
            &format!("unix:{}", self.socket.display()),
            Duration::from_secs(60),
        )?))
    }

    fn command(&mut self, c: &str) -> Result<()> {
        writeln!(self.stdin, "{c}").map_err(|e| format!("emulator stdin: {e}"))
    }

    /// Why the emulator ended, for an error the client met: its report's
    /// stop (it exits by itself on a violation), or a kill after 5 s.
    fn explain(mut self, e: String) -> String {
        drop(self.stdin);
        let start = Instant::now();
        while matches!(self.child.try_wait(), Ok(None)) && start.elapsed() < Duration::from_secs(5)
        {
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let out = self
            .child
            .wait_with_output()
            .map(|o| o.stdout)
            .unwrap_or_default();
        let report: serde_json::Value = serde_json::from_slice(&out).unwrap_or_default();
        match report["stop"].as_str() {
            Some(stop) => format!("{e}\n  the emulated NUCLEO stopped: {stop}"),
            None => e,
        }
    }

    /// The run's report, once the client has closed.
    fn finish(self, link: Link) -> Result<serde_json::Value> {
        drop(link);
        drop(self.stdin);
        let out = self.child.wait_with_output().map_err(|e| e.to_string())?;
        let text = String::from_utf8_lossy(&out.stdout);
        let report: serde_json::Value = serde_json::from_str(text.trim())
            .map_err(|e| format!("emulator report: {e}: {text}"))?;
        if let Some(stop) = report["stop"].as_str() {
            return Err(format!("the emulated NUCLEO stopped: {stop}"));
        }
        Ok(report)
    }
}

/// One boot: `f` drives it over the link; then the emulator's report, or
/// the client's error with the emulator's stop reason.
fn session<T>(
    mut emu: Emu,
    f: impl FnOnce(&mut Emu) -> Result<(Link, T)>,
) -> Result<(serde_json::Value, T)> {
    match f(&mut emu) {
        Ok((c, t)) => Ok((emu.finish(c)?, t)),
        Err(e) => Err(emu.explain(e)),
    }
}

/// The QEMU image's tracking on the same script, µin, from its log.
pub fn qemu_tracking_uin() -> Result<f64> {
    let log =
        fs::read_to_string(crate::qemu_dir().join("expected.log")).map_err(|e| e.to_string())?;
    let line = log
        .lines()
        .find_map(|l| l.split(QEMU_TRACKING).nth(1))
        .ok_or("boards/qemu/expected.log: no tracking line")?;
    let codes: f64 = line
        .split_whitespace()
        .next()
        .and_then(|c| c.parse().ok())
        .ok_or("boards/qemu/expected.log: tracking codes")?;
    Ok(codes * UIN_PER_CODE)
}

/// The first boot's defmt log (RTT up channel 0, as the probe read it),
/// decoded when defmt-print is there (`cargo xtask test` installs it).
fn boot_log() -> Option<String> {
    let raw = fs::read(work_dir().join("boot1.defmt")).ok()?;
    let mut p = Command::new("defmt-print")
        .arg("-e")
        .arg(crate::board_elf())
        .args(["--log-format", "{t} {L} {s}", "stdin"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .ok()?;
    p.stdin.take()?.write_all(&raw).ok()?;
    let out = p.wait_with_output().ok()?;
    Some(String::from_utf8_lossy(&out.stdout).into_owned())
}

fn sha256(path: &Path) -> Result<String> {
    use sha2::Digest;
    let bytes = fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(format!("{:x}", sha2::Sha256::digest(&bytes)))
}

/// The whole check; its report (the names first).
pub fn check(ms: u64) -> Result<serde_json::Value> {
    let dir = work_dir();
    fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let table = crate::default_table_path();
    let bank2 = dir.join("bank2.bin");
    let _ = fs::remove_file(&bank2);
    let want = zslide::table::CoeffTable::parse(&fs::read(&table).map_err(|e| e.to_string())?)
        .map_err(|e| e.to_string())?
        .identity();
    let mut checks = Checks::new("emulated NUCLEO");

    crate::step("emulated NUCLEO: boot, arm, track, a gauge bus fault, a save");
    let (first, (booted, armed, tracking_max_uin, capture_ticks, faults_latched)) =
        session(Emu::start(&table, &bank2, ms, "boot1")?, |emu| {
            let mut c = emu.connect()?;
            let s = wait_for(&mut c, "the loop ticking", EMU_WAIT, |s| {
                s.state.ticks > 100
            })?;
            let booted = s.table == Ok(want)
                && matches!(s.params, ParamSource::BuiltIn)
                && s.state.fault.is_none();
            checks.ok(
                booted,
                &format!(
                    "boot: table {:?}, params {:?}, fault {:?}",
                    s.table, s.params, s.state.fault
                ),
            )?;
            cli(&mut c, "link status")?;
            wait_for(&mut c, "the spindle referenced and X in", EMU_WAIT, |s| {
                s.state.phi.is_some() && s.state.x_bits.is_some()
            })?;
            let armed_text = cli(&mut c, "link arm")?;
            let s = wait_for(&mut c, "engaged", EMU_WAIT, |s| {
                s.state.phase == LoopPhase::Engaged
            })?;
            let armed = s.state.amplifier_enabled && armed_text.contains("armed");
            checks.ok(armed, "arm")?;
            // Let the loop settle (the arm's transient), then capture what it tracks.
            let from = s.state.ticks;
            wait_for(&mut c, "1000 ticks engaged", EMU_WAIT, |s| {
                s.state.ticks.wrapping_sub(from) >= 1_000
            })?;
            match c.client()?.call(&Request::CaptureStart {
                samples: 1_000,
                pre: 0,
                trigger: Trigger::Immediate,
            })? {
                Reply::Capture(_) => {}
                r => return Err(unexpected(&r)),
            }
            let info = {
                let start = Instant::now();
                loop {
                    let i = c.client()?.capture_info()?;
                    if i.state == CaptureState::Done || start.elapsed() > Duration::from_secs(60) {
                        break i;
                    }
                    std::thread::sleep(Duration::from_millis(20));
                }
            };
            checks.ok(info.state == CaptureState::Done, "capture")?;
            let samples = c.client()?.capture_read(info.recorded)?;
            let tracking_codes = samples
                .iter()
                .map(|s| s.error.unsigned_abs())
                .max()
                .unwrap_or(u32::MAX);
            let tracking_max_uin = f64::from(tracking_codes) * UIN_PER_CODE;
            let moving = samples.iter().map(|s| s.command).max().unwrap_or(0)
                - samples.iter().map(|s| s.command).min().unwrap_or(0);
            checks.ok(
                moving > 0,
                "the command did not move over the capture (nothing tracked)",
            )?;

            // One fault: the gauge's data line stuck high.
            emu.command("break-gauge")?;
            let s = wait_for(&mut c, "the gauge bus fault", EMU_WAIT, |s| {
                s.state.fault.is_some()
            })?;
            let latched =
                s.state.fault == Some(Fault::Bus(Device::GaugeAdc)) && !s.state.amplifier_enabled;
            checks.ok(
                latched,
                &format!(
                    "gauge bus fault: latched {:?}, amplifier {}",
                    s.state.fault, s.state.amplifier_enabled
                ),
            )?;
            let faults_latched = u32::from(latched);

            // A parameter saved to the bank-2 flash model.
            cli(&mut c, "link disarm")?;
            wait_for(&mut c, "disarmed", EMU_WAIT, |s| {
                s.state.phase == LoopPhase::Disarmed
            })?;
            cli(&mut c, "params set hum_notch_q 10")?;
            let saved = cli(&mut c, "params save")?;
            checks.ok(saved.contains("saved"), &format!("params save: {saved}"))?;
            Ok((
                c,
                (
                    booted,
                    armed,
                    tracking_max_uin,
                    samples.len(),
                    faults_latched,
                ),
            ))
        })?;
    checks.ok(
        first["flash_erases"].as_u64().unwrap_or(0) + first["flash_programs"].as_u64().unwrap_or(0)
            > 0,
        "the save never reached the bank-2 flash",
    )?;

    crate::step("emulated NUCLEO: power cycle (the same bank 2)");
    let (second, ()) = session(Emu::start(&table, &bank2, SHORT_BOOT_MS, "boot2")?, |emu| {
        let mut c = emu.connect()?;
        let s = wait_for(&mut c, "the loop ticking", EMU_WAIT, |s| {
            s.state.ticks > 100
        })?;
        checks.ok(
            matches!(s.params, ParamSource::Block { .. }),
            &format!(
                "after the power cycle the parameters are {:?}, not the saved block",
                s.params
            ),
        )?;
        let q = cli(&mut c, "params get hum_notch_q")?;
        checks.ok(
            q.contains("hum_notch_q = 10 "),
            &format!("saved value not in force: {q}"),
        )?;
        Ok((c, ()))
    })?;

    crate::step("emulated NUCLEO: a corrupt table is refused");
    let mut bad = fs::read(&table).map_err(|e| e.to_string())?;
    let last = bad.len() - 1;
    bad[last] ^= 0x01;
    let bad_table = dir.join("corrupt.zsct");
    fs::write(&bad_table, &bad).map_err(|e| e.to_string())?;
    let corrupt = Emu::start(
        &bad_table,
        &dir.join("bank2-erased.bin"),
        SHORT_BOOT_MS,
        "corrupt",
    )?;
    let (third, ()) = session(corrupt, |emu| {
        let mut c = emu.connect()?;
        let s = wait_for(&mut c, "the loop ticking", EMU_WAIT, |s| {
            s.state.ticks > 100
        })?;
        checks.ok(
            s.table.is_err() && matches!(s.state.fault, Some(Fault::Table(_))),
            &format!("corrupt table: {:?}, fault {:?}", s.table, s.state.fault),
        )?;
        Ok((c, ()))
    })?;
    let _ = fs::remove_file(dir.join("bank2-erased.bin"));

    if let Some(log) = boot_log() {
        eprintln!("emulated NUCLEO, first boot's defmt log (RTT channel 0):");
        for l in log.lines() {
            eprintln!("  {l}");
        }
    }
    crate::step("emulated NUCLEO: zslide-centre boots and ticks (50 ms)");
    let out = Command::new(emu_bin())
        .arg("--elf")
        .arg(crate::centre_elf())
        .args(["--ms", "50"])
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("cannot start {}: {e}", emu_bin().display()))?;
    let centre: serde_json::Value = serde_json::from_slice(&out.stdout)
        .map_err(|e| format!("emulator report (zslide-centre): {e}"))?;
    // Its tick is 10 kHz (`src/centre.rs`): 500 in 50 ms less the boot.
    let ticks = centre["loop_ticks"].as_u64().unwrap_or(0);
    checks.ok(
        centre["stop"].is_null() && ticks >= 450,
        &format!(
            "zslide-centre: stop {}, {ticks} ticks in 50 ms",
            centre["stop"]
        ),
    )?;
    let qemu = qemu_tracking_uin()?;
    let elf = crate::board_elf();
    let ms_total: f64 = [&first, &second, &third]
        .iter()
        .map(|r| r["machine_ms"].as_f64().unwrap_or(0.0))
        .sum();
    let unmodelled: u64 = [&first, &second, &third, &centre]
        .iter()
        .map(|r| r["unmodelled_accesses"].as_u64().unwrap_or(0))
        .sum();
    Ok(serde_json::json!({
        "elf": elf.display().to_string(),
        "elf_sha256": sha256(&elf)?,
        "booted": booted,
        "armed": armed,
        "tracking_max_uin": tracking_max_uin,
        "unmodelled_accesses": unmodelled,
        "faults_injected": 1,
        "faults_latched": faults_latched,
        "link_checks_passed": checks.passed,
        "qemu_tracking_max_uin": qemu,
        "tracking_tolerance_uin": TRACKING_TOLERANCE_UIN,
        "machine_ms": ms_total,
        "capture_ticks": capture_ticks,
        "boot1": first,
        "power_cycle": second,
        "corrupt_table": third,
        "centre": centre,
    }))
}

pub fn run(args: &Args) -> Result<u8> {
    crate::tools::require(&[crate::tools::Tool::Target, crate::tools::Tool::FlipLink])?;
    require_unicorn()?;
    crate::images::build_board()?;
    build_emulator()?;
    let r = check(args.ms)?;
    let pass = report(&r);
    if args.json {
        let mut brief = r.clone();
        for k in ["boot1", "power_cycle", "corrupt_table", "centre"] {
            if let Some(o) = brief.as_object_mut() {
                o.remove(k);
            }
        }
        println!("{brief}");
    }
    Ok(if pass { 0 } else { 1 })
}

/// Prints the summary; whether the tracking is within the tolerance of
/// the QEMU image's.
pub fn report(r: &serde_json::Value) -> bool {
    let t = r["tracking_max_uin"].as_f64().unwrap_or(f64::MAX);
    let q = r["qemu_tracking_max_uin"].as_f64().unwrap_or(0.0);
    let ok = (t - q).abs() <= TRACKING_TOLERANCE_UIN;
    eprintln!(
        "emulated NUCLEO: {} ({:.0} ms of machine time): booted {}, armed {}, tracking max {:.2} µin (QEMU image {:.2} µin, tolerance ±{TRACKING_TOLERANCE_UIN} µin: {}), unmodelled accesses {}, faults {}/{} latched, {} link checks passed",
        r["elf"].as_str().unwrap_or(""),
        r["machine_ms"].as_f64().unwrap_or(0.0),
        r["booted"],
        r["armed"],
        t,
        q,
        if ok { "within" } else { "OUTSIDE" },
        r["unmodelled_accesses"],
        r["faults_latched"],
        r["faults_injected"],
        r["link_checks_passed"],
    );
    ok
}
