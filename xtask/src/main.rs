//! Project automation: `cargo xtask <command>` (`--help` on each).
//!
//! * `test`    – everything: host tests, the board firmware, the QEMU image
//!   built, run and its log checked; image sizes; a short fuzz run of every
//!   target; no import cycle between modules (`cycles`). Installs what is
//!   missing when it can (Rust target, flip-link,
//!   defmt-print, QEMU, cargo-fuzz) and otherwise says exactly what is
//!   missing.
//! * `qemu [--bless]` – builds and runs the QEMU image, decodes its defmt
//!   log, compares it (timestamps stripped) with `boards/qemu/expected.log`
//!   (`--bless` rewrites that file); then replays host-sim's recorded runs
//!   bit-exact on the emulated target and checks that an altered code is
//!   caught (`replay.rs`); then hangs each handler and checks that the
//!   watchdog trips (`watchdog.rs`).
//! * `size`    – flash and RAM use of both images (builds them first).
//! * `isr-cost [--json] [--variant V] [--profile R [--call N]]` –
//!   instructions per interrupt handler under QEMU.
//! * `no-panic` – builds both images and proves that no panic path is
//!   reachable from their interrupt handlers (`nopanic.rs`); part of `test`.
//! * `cycles` – no import cycle between the modules of any crate, and the
//!   biggest source file (`cycles.rs`); part of `test`.
//! * `flash-cut` – a power cut at every flash operation of the QEMU
//!   image's parameter saves, across boots (`powercut.rs`); part of `test`.
//! * `fuzz --seconds N [--target T]` – builds and runs the cargo-fuzz
//!   targets of `fuzz/` (`fuzz.rs`).
//! * `nucleo [--json] [--ms N]` – the release zslide-fw ELF on the
//!   emulated NUCLEO-H743ZI2 over its RTT link (`nucleo.rs`); part of `test`.
//!
//! Arguments are parsed strictly (clap): an unknown or mistyped flag is an
//! error with exit status 2, never ignored.

mod cycles;
mod docnames;
mod elf;
mod faultpath;
mod figures;
mod fuzz;
mod isr_cost;
mod link;
mod mutants;
mod nopanic;
mod nucleo;
mod powercut;
mod replay;
mod stack;
mod table_checks;
mod trace;
mod watchdog;

use clap::{Parser, Subcommand};
use std::env;
use std::fs;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

pub const TARGET: &str = "thumbv7em-none-eabihf";
const QEMU_TIMEOUT: Duration = Duration::from_secs(120);

type Result<T> = std::result::Result<T, String>;

#[derive(Parser)]
#[command(
    name = "cargo xtask",
    bin_name = "cargo xtask",
    about = "Build, test, QEMU, ISR-cost and fuzz automation"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Host tests, board firmware, QEMU image run, no-panic check, sizes and
    /// a short fuzz run (installs what it can, names what is missing).
    Test {
        /// Seconds each fuzz target runs (0 skips the fuzz step).
        #[arg(long, default_value_t = fuzz::TEST_SECONDS, value_name = "N")]
        fuzz_seconds: u32,
    },
    /// Build and run the QEMU image; exit status passed through.
    Qemu {
        /// Rewrite boards/qemu/expected.log with this run's log.
        #[arg(long)]
        bless: bool,
        /// Also run the image built with trace events and write the run as
        /// a VCD (the simulator's signal names; its decoded log beside it).
        #[arg(long, value_name = "FILE")]
        vcd: Option<PathBuf>,
    },
    /// Flash and RAM use of both images.
    Size,
    /// Instructions per interrupt handler under QEMU (takes minutes: the
    /// image runs under an instruction trace).
    IsrCost(isr_cost::Args),
    /// Prove no panic path is reachable from the images' interrupt handlers.
    NoPanic,
    /// Build and run the cargo-fuzz targets (nightly toolchain, cargo-fuzz).
    Fuzz(fuzz::Args),
    /// Run the QEMU image as a link session on a Unix socket (for
    /// `zslide --connect unix:PATH ...`).
    QemuLink(link::SessionArgs),
    /// The QEMU table-region runs and the host-link end-to-end test of
    /// `cargo xtask test`, alone.
    LinkTest,
    /// A power cut at every flash operation of the QEMU image's parameter
    /// saves, across boots (part of `test`, alone).
    FlashCut,
    /// Rerun the commands behind the figures marked in README.md and
    /// docs/*.md and rewrite them (`--check`: list what drifted, exit 1);
    /// also checks the names the docs cite exist.
    Figures(figures::Args),
    /// Import cycles between the modules of every crate (part of `test`).
    Cycles,
    /// The release zslide-fw ELF on the emulated NUCLEO-H743ZI2: boot, arm,
    /// track, a gauge bus fault, a save and a power cycle over its RTT link.
    Nucleo(nucleo::Args),
    /// Mutation testing of the core's safety-relevant modules
    /// (cargo-mutants, installed on demand; not part of `test`).
    Mutants(mutants::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.cmd {
        Cmd::Test { fuzz_seconds } => cmd_test(fuzz_seconds),
        Cmd::Qemu { bless, vcd } => cmd_qemu(bless, vcd.as_deref()),
        Cmd::Size => cmd_size(),
        Cmd::IsrCost(args) => isr_cost::run(&args),
        Cmd::NoPanic => cmd_no_panic(),
        Cmd::Fuzz(args) => fuzz::run(&args).map(|_| 0),
        Cmd::QemuLink(args) => link::run_session(&args),
        Cmd::LinkTest => cmd_link_test(),
        Cmd::FlashCut => cmd_flash_cut(),
        Cmd::Figures(args) => figures::run(&args),
        Cmd::Cycles => cycles::run(),
        Cmd::Mutants(args) => mutants::run(&args),
        Cmd::Nucleo(args) => nucleo::run(&args),
    };
    match result {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            eprintln!("xtask: error: {e}");
            ExitCode::from(1)
        }
    }
}

pub fn root() -> PathBuf {
    // xtask/Cargo.toml lives one level below the workspace root.
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

pub fn qemu_dir() -> PathBuf {
    root().join("boards/qemu")
}

/// Both workspaces build into the root's target directory (boards/qemu's
/// config points there), unless CARGO_TARGET_DIR overrides it for both.
pub fn target_dir() -> PathBuf {
    match env::var_os("CARGO_TARGET_DIR") {
        Some(dir) => root().join(dir),
        None => root().join("target"),
    }
}

pub fn board_elf() -> PathBuf {
    target_dir().join(TARGET).join("release/zslide-fw")
}

/// The centring firmware (Feezell 1967) for the same board.
pub fn centre_elf() -> PathBuf {
    target_dir().join(TARGET).join("release/zslide-centre")
}

pub fn qemu_elf() -> PathBuf {
    target_dir().join(TARGET).join("release/zslide-qemu")
}

pub fn cargo() -> Command {
    Command::new(env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

pub fn step(title: &str) {
    eprintln!("\n==> {title}");
}

/// Runs a command to completion; Ok if it exits 0.
fn run(cmd: &mut Command, what: &str) -> Result<()> {
    let status = cmd
        .status()
        .map_err(|e| format!("{what}: cannot start {:?}: {e}", cmd.get_program()))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{what} failed ({status})"))
    }
}

/// Whether `program args` starts and exits 0 (used to probe for tools).
fn works(program: &str, args: &[&str]) -> bool {
    Command::new(program)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .map(|s| s.success())
        .unwrap_or(false)
}

/// Whether an executable named `bin` is on PATH (for tools, like flip-link,
/// that have no harmless "print your version" call).
fn on_path(bin: &str) -> bool {
    env::var_os("PATH")
        .map(|paths| env::split_paths(&paths).any(|dir| dir.join(bin).is_file()))
        .unwrap_or(false)
}

pub fn output_of(program: &str, args: &[&str]) -> Option<String> {
    output(program, args)
}

fn output(program: &str, args: &[&str]) -> Option<String> {
    let out = Command::new(program).args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).into_owned())
}

// ---------------------------------------------------------------- tools

#[derive(Clone, Copy, PartialEq, Eq)]
enum Tool {
    Target,
    FlipLink,
    DefmtPrint,
    Qemu,
    Viewers,
}

/// `bin` from Debian's `package`: there already, or installed with apt-get
/// when running as root; otherwise the exact command to run.
fn apt_tool(bin: &str, package: &str, what: &str) -> Result<()> {
    if on_path(bin) {
        return Ok(());
    }
    let root = output("id", &["-u"])
        .map(|s| s.trim() == "0")
        .unwrap_or(false);
    let apt = works("apt-get", &["--version"]);
    if root && apt {
        step(&format!("installing {package} (apt-get)"));
        let env = [("DEBIAN_FRONTEND", "noninteractive")];
        run(
            Command::new("apt-get").arg("update").envs(env),
            "apt-get update",
        )
        .and_then(|()| {
            run(
                Command::new("apt-get")
                    .args(["install", "-y", "--no-install-recommends", package])
                    .envs(env),
                &format!("apt-get install {package}"),
            )
        })
        .map_err(|e| format!("{bin} ({e})"))?;
        if on_path(bin) {
            Ok(())
        } else {
            Err(format!(
                "{bin} (package {package} installed but {bin} not found)"
            ))
        }
    } else if apt {
        Err(format!(
            "{bin}: run `sudo apt-get update && sudo apt-get install -y {package}` (not root, so \
             xtask does not)"
        ))
    } else {
        Err(format!(
            "{bin} ({what}): no apt-get here; install it with your package manager"
        ))
    }
}

/// Makes sure each tool is there, installing it when possible. Returns the
/// list of what is still missing, each with the exact remedy.
fn ensure(tools: &[Tool]) -> Vec<String> {
    let mut missing = Vec::new();
    for &tool in tools {
        if let Err(e) = ensure_one(tool) {
            missing.push(e);
        }
    }
    missing
}

fn ensure_one(tool: Tool) -> Result<()> {
    match tool {
        Tool::Target => {
            let installed = output("rustup", &["target", "list", "--installed"]);
            match installed {
                Some(list) if list.lines().any(|l| l.trim() == TARGET) => Ok(()),
                Some(_) => {
                    step(&format!("installing the Rust target {TARGET}"));
                    run(
                        Command::new("rustup").args(["target", "add", TARGET]),
                        "rustup target add",
                    )
                    .map_err(|e| {
                        format!("Rust target {TARGET} ({e}); run `rustup target add {TARGET}`")
                    })
                }
                None => Err(format!(
                    "rustup (to add the {TARGET} target); install rustup from https://rustup.rs, \
                     or provide a toolchain with the {TARGET} standard library"
                )),
            }
        }
        Tool::FlipLink => cargo_install("flip-link", &["flip-link", "--locked"]),
        Tool::DefmtPrint => cargo_install(
            "defmt-print",
            // defmt-print 1.x decodes defmt 1.x frames.
            &["defmt-print", "--locked", "--version", "^1"],
        ),
        Tool::Qemu => apt_tool(
            "qemu-system-arm",
            "qemu-system-arm",
            "QEMU ≥ 7 with the mps2-an386 machine",
        ),
        // The VCD viewers' readers the host tests check the VCDs with
        // (`trace::check_both`): GTKWave's converter, libsigrok.
        Tool::Viewers => apt_tool("vcd2fst", "gtkwave", "GTKWave's vcd2fst")
            .and_then(|()| apt_tool("sigrok-cli", "sigrok-cli", "sigrok-cli (libsigrok)")),
    }
}

fn cargo_install(bin: &str, install: &[&str]) -> Result<()> {
    if on_path(bin) {
        return Ok(());
    }
    step(&format!("installing {bin} (cargo install)"));
    let mut cmd = cargo();
    cmd.arg("install").args(install);
    run(&mut cmd, &format!("cargo install {bin}"))
        .map_err(|e| format!("{bin} ({e}); run `cargo install {}`", install.join(" ")))?;
    if on_path(bin) {
        Ok(())
    } else {
        Err(format!(
            "{bin}: installed but not on PATH; add ~/.cargo/bin to PATH"
        ))
    }
}

fn require(tools: &[Tool]) -> Result<()> {
    let missing = ensure(tools);
    if missing.is_empty() {
        return Ok(());
    }
    let mut msg = String::from("missing, and could not be installed:");
    for m in &missing {
        msg.push_str("\n  - ");
        msg.push_str(m);
    }
    Err(msg)
}

// ---------------------------------------------------------------- builds

fn build_board() -> Result<()> {
    step("board firmware: cargo fw (NUCLEO-H743ZI2: zslide-fw, zslide-centre)");
    run(cargo().current_dir(root()).arg("fw"), "cargo fw")
}

pub fn require_for_qemu() -> Result<()> {
    require(&[Tool::Target, Tool::FlipLink, Tool::Qemu])
}

pub fn build_qemu_image() -> Result<()> {
    build_qemu()
}

/// The QEMU image with extra cargo features of `boards/qemu` (e.g.
/// `modern-x`), at the same path as [`build_qemu_image`]'s: build the plain
/// one again before running the log check.
pub fn build_qemu_image_with(features: &str) -> Result<()> {
    step(&format!(
        "QEMU image: cargo build --release --features {features} (boards/qemu)"
    ));
    run(
        cargo()
            .current_dir(qemu_dir())
            .args(["build", "--release", "--features", features]),
        "QEMU image build",
    )
}

fn build_qemu() -> Result<()> {
    step("QEMU image: cargo build --release (boards/qemu, mps2-an386)");
    // From its own directory: that picks up its .cargo/config.toml (target,
    // runner) on top of the root one (linker, rustflags).
    run(
        cargo().current_dir(qemu_dir()).args(["build", "--release"]),
        "QEMU image build",
    )
}

/// The default coefficient table's file (what the QEMU runs load into
/// the table region unless told otherwise).
pub fn default_table_path() -> PathBuf {
    root().join("tables/default.zsct")
}

/// What QEMU's loader writes into the image's flash regions
/// (`boards/qemu/memory.x`).
pub struct QemuRegions<'a> {
    pub table: Option<&'a Path>,
    pub params: Option<&'a Path>,
}

/// The QEMU command line, the same as the runner in boards/qemu/.cargo,
/// with the default table in the table region.
pub fn qemu_command(elf: &Path) -> Command {
    let table = default_table_path();
    qemu_command_with(
        elf,
        &QemuRegions {
            table: Some(&table),
            params: None,
        },
        "null",
        "enable=on,target=native",
    )
}

/// [`qemu_command`] with other region contents, UART0 (`-serial`) and
/// semihosting configuration.
pub fn qemu_command_with(
    elf: &Path,
    regions: &QemuRegions,
    serial: &str,
    semihosting: &str,
) -> Command {
    let mut cmd = Command::new("qemu-system-arm");
    for (file, addr) in [
        (regions.table, zslide_host::regions::QEMU.table_addr),
        (regions.params, zslide_host::regions::QEMU.params_addr),
    ] {
        if let Some(f) = file {
            let mut arg = std::ffi::OsString::from("loader,file=");
            arg.push(f);
            arg.push(format!(",addr={addr:#x},force-raw=on"));
            cmd.arg("-device").arg(arg);
        }
    }
    cmd.args([
        "-machine",
        "mps2-an386",
        "-cpu",
        "cortex-m4",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        serial,
        "-semihosting-config",
        semihosting,
        "-icount",
        "shift=0,sleep=off",
        "-kernel",
    ])
    .arg(elf);
    cmd
}

fn wait_timeout(
    child: &mut Child,
    limit: Duration,
    what: &str,
) -> Result<std::process::ExitStatus> {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().map_err(|e| format!("{what}: {e}"))? {
            return Ok(status);
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!(
                "{what}: no exit within {} s, killed",
                limit.as_secs()
            ));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs the QEMU image with its log decoded; returns (exit code, log lines).
fn run_qemu() -> Result<(u8, Vec<String>)> {
    run_qemu_with(Some(&default_table_path()))
}

/// [`run_qemu`] with `table` (or nothing) in the table region.
pub fn run_qemu_with(table: Option<&Path>) -> Result<(u8, Vec<String>)> {
    step(&format!(
        "QEMU run: qemu-system-arm -machine mps2-an386 | defmt-print; table region: {}",
        table.map_or("empty".into(), |t| t.display().to_string())
    ));
    let regions = QemuRegions {
        table,
        params: None,
    };
    run_qemu_elf(&qemu_elf(), &regions, &[])
}

/// Runs `elf` under QEMU with `regions` loaded and `extra` arguments (the
/// replay image's recording loader, say), its log decoded and shown;
/// returns (exit code, log lines).
pub fn run_qemu_elf(
    elf: &Path,
    regions: &QemuRegions,
    extra: &[&str],
) -> Result<(u8, Vec<String>)> {
    run_qemu_elf_echo(elf, regions, extra, true)
}

/// [`run_qemu_elf`], the log shown on stdout only with `echo` (a traced
/// run's log is tens of thousands of lines).
pub fn run_qemu_elf_echo(
    elf: &Path,
    regions: &QemuRegions,
    extra: &[&str],
    echo: bool,
) -> Result<(u8, Vec<String>)> {
    run_qemu_elf_with(elf, regions, "enable=on,target=native", extra, echo)
}

/// [`run_qemu_elf_echo`] with another semihosting configuration (its
/// command-line arguments select an image's injected faults).
pub fn run_qemu_elf_with(
    elf: &Path,
    regions: &QemuRegions,
    semihosting: &str,
    extra: &[&str],
    echo: bool,
) -> Result<(u8, Vec<String>)> {
    run_qemu_elf_at(elf, regions, semihosting, extra, echo, None)
}

/// [`run_qemu_elf_with`] with QEMU in `dir` (where the image's semihosting
/// file operations land).
pub fn run_qemu_elf_at(
    elf: &Path,
    regions: &QemuRegions,
    semihosting: &str,
    extra: &[&str],
    echo: bool,
    dir: Option<&Path>,
) -> Result<(u8, Vec<String>)> {
    let elf = elf.to_path_buf();
    let mut cmd = qemu_command_with(&elf, regions, "null", semihosting);
    if let Some(d) = dir {
        cmd.current_dir(d);
    }
    let mut qemu = cmd
        .args(extra)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot start qemu-system-arm: {e}"))?;
    let qemu_out = qemu.stdout.take().ok_or("no QEMU stdout")?;
    let mut print = Command::new("defmt-print")
        .args(["-e"])
        .arg(&elf)
        .args(["--log-format", "{t} {L} {s}", "stdin"])
        .stdin(Stdio::from(qemu_out))
        .stdout(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot start defmt-print: {e}"))?;
    let print_out = print.stdout.take().ok_or("no defmt-print stdout")?;
    let reader = std::thread::spawn(move || {
        let mut lines = Vec::new();
        for line in BufReader::new(print_out)
            .lines()
            .map_while(std::result::Result::ok)
        {
            if echo {
                println!("{line}");
            }
            lines.push(line);
        }
        lines
    });
    let status = wait_timeout(&mut qemu, QEMU_TIMEOUT, "qemu-system-arm")?;
    // defmt-print ends when QEMU closes the pipe.
    let print_status = wait_timeout(&mut print, Duration::from_secs(10), "defmt-print")?;
    let lines = reader.join().map_err(|_| "log reader panicked")?;
    if !print_status.success() {
        return Err(format!("defmt-print failed ({print_status})"));
    }
    let code = status.code().map(|c| c.clamp(0, 255) as u8).unwrap_or(1);
    Ok((code, lines))
}

/// A decoded log line without its timestamp (the first field).
fn strip_timestamp(line: &str) -> &str {
    match line.split_once(' ') {
        Some((t, rest)) if t.chars().all(|c| c.is_ascii_digit() || c == '.') => rest,
        _ => line,
    }
}

fn check_snapshot(lines: &[String], bless: bool) -> Result<()> {
    let path = qemu_dir().join("expected.log");
    let got: Vec<&str> = lines.iter().map(|l| strip_timestamp(l)).collect();
    let text = got.join("\n") + "\n";
    if bless {
        fs::write(&path, &text).map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("wrote {}", path.display());
        return Ok(());
    }
    let want = fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    if want == text {
        eprintln!("QEMU log matches {} ({} lines)", path.display(), got.len());
        return Ok(());
    }
    let mut msg = format!("QEMU log differs from {}:", path.display());
    for (i, (w, g)) in want.lines().zip(got.iter()).enumerate() {
        if w != *g {
            msg.push_str(&format!(
                "\n  line {}:\n    expected: {w}\n    got:      {g}",
                i + 1
            ));
        }
    }
    if want.lines().count() != got.len() {
        msg.push_str(&format!(
            "\n  expected {} lines, got {}",
            want.lines().count(),
            got.len()
        ));
    }
    msg.push_str("\n  (if the change is intended: cargo xtask qemu --bless)");
    Err(msg)
}

// ---------------------------------------------------------------- commands

fn cmd_qemu(bless: bool, vcd: Option<&Path>) -> Result<u8> {
    require(&[Tool::Target, Tool::FlipLink, Tool::Qemu, Tool::DefmtPrint])?;
    build_qemu()?;
    let (code, lines) = run_qemu()?;
    eprintln!("QEMU image exited with status {code}");
    if code == 0 {
        check_snapshot(&lines, bless)?;
        let summary = replay::check()?;
        eprintln!("QEMU replay: {summary}");
        let summary = watchdog::check()?;
        eprintln!("QEMU watchdog: {summary}");
        let summary = faultpath::check()?;
        eprintln!("QEMU fault paths: {summary}");
        if let Some(vcd) = vcd {
            let (summary, _) = trace::qemu_vcd(vcd)?;
            eprintln!("QEMU trace: {summary}");
        }
    }
    Ok(code)
}

fn cmd_link_test() -> Result<u8> {
    require(&[Tool::Target, Tool::FlipLink, Tool::Qemu, Tool::DefmtPrint])?;
    build_qemu()?;
    let (code, lines) = run_qemu()?;
    if code != 0 {
        return Err(format!("the QEMU image exited with status {code}"));
    }
    let n =
        table_checks::qemu_table_checks(&lines)? + faultpath::params_check()? + link::end_to_end()?;
    eprintln!("{n} passed, 0 failed");
    Ok(0)
}

fn cmd_flash_cut() -> Result<u8> {
    require(&[Tool::Target, Tool::FlipLink, Tool::Qemu, Tool::DefmtPrint])?;
    build_qemu()?;
    eprintln!("QEMU power cuts: {}", powercut::check()?);
    Ok(0)
}

fn cmd_size() -> Result<u8> {
    require(&[Tool::Target, Tool::FlipLink])?;
    build_board()?;
    build_qemu()?;
    print_sizes()?;
    Ok(0)
}

fn cmd_no_panic() -> Result<u8> {
    require(&[Tool::Target, Tool::FlipLink])?;
    build_board()?;
    build_qemu()?;
    check_no_panic()?;
    Ok(0)
}

/// Every image: no panic path from any interrupt handler (`nopanic.rs`).
fn check_no_panic() -> Result<()> {
    step("no panic path from interrupt handlers (every image)");
    let mut errors = Vec::new();
    for (elf, link) in [
        (board_elf(), true),
        (centre_elf(), false),
        (qemu_elf(), true),
    ] {
        match nopanic::check(&elf, link) {
            Ok(summary) => eprintln!("{summary}"),
            Err(e) => errors.push(e),
        }
    }
    if errors.is_empty() {
        Ok(())
    } else {
        Err(errors.join("\n"))
    }
}

/// LENGTH of region `name` in a linker `memory.x`, bytes (`1792K`, `3M`,
/// or a number): the percentages of `size` are of the region the image is
/// linked into, read from the file that defines it.
fn region_len(memory_x: &std::path::Path, name: &str) -> Result<u64> {
    let text = fs::read_to_string(memory_x).map_err(|e| format!("{}: {e}", memory_x.display()))?;
    let line = text
        .lines()
        .find(|l| l.split(':').next().is_some_and(|n| n.trim() == name))
        .ok_or_else(|| format!("{}: no {name} region", memory_x.display()))?;
    let len = line
        .split("LENGTH")
        .nth(1)
        .and_then(|r| r.split('=').nth(1))
        .map(str::trim)
        .ok_or_else(|| format!("{}: {name} has no LENGTH", memory_x.display()))?;
    let (num, unit) = match len.chars().last() {
        Some('K') => (&len[..len.len() - 1], 1024),
        Some('M') => (&len[..len.len() - 1], 1024 * 1024),
        _ => (len, 1),
    };
    let n: u64 = if let Some(h) = num.strip_prefix("0x") {
        u64::from_str_radix(h, 16).map_err(|e| e.to_string())?
    } else {
        num.parse()
            .map_err(|e| format!("{}: {name} LENGTH {len}: {e}", memory_x.display()))?
    };
    Ok(n * unit)
}

fn print_sizes() -> Result<()> {
    step("image sizes");
    let board = root().join("memory.x");
    let qemu = root().join("boards/qemu/memory.x");
    for (name, path, memory_x) in [
        ("NUCLEO-H743ZI2 (zslide-fw)", board_elf(), &board),
        ("NUCLEO-H743ZI2 (zslide-centre)", centre_elf(), &board),
        ("QEMU mps2-an386 (zslide-qemu)", qemu_elf(), &qemu),
    ] {
        let flash_total = region_len(memory_x, "FLASH")?;
        let ram_total = region_len(memory_x, "RAM")?;
        let s = elf::sizes(&path)?;
        eprintln!(
            "{name}: flash {} B ({:.2} % of the {} KiB FLASH region), static RAM {} B ({:.2} % of {} KiB)  \
             [text+rodata {} B, data {} B, bss+uninit {} B]",
            s.flash(),
            100.0 * s.flash() as f64 / flash_total as f64,
            flash_total / 1024,
            s.ram(),
            100.0 * s.ram() as f64 / ram_total as f64,
            ram_total / 1024,
            s.text,
            s.data,
            s.bss
        );
    }
    Ok(())
}

/// (passed, failed, ignored) of a libtest summary line,
/// "test result: ok. 11 passed; 0 failed; 0 ignored; 0 measured; ...".
fn parse_test_result(line: &str) -> Option<(u64, u64, u64)> {
    let rest = line.strip_prefix("test result: ")?;
    let (mut passed, mut failed, mut ignored) = (0, 0, 0);
    for part in rest.split(';') {
        let mut words = part.split_whitespace().rev();
        let (Some(what), Some(n)) = (words.next(), words.next()) else {
            continue;
        };
        let Ok(n) = n.parse::<u64>() else { continue };
        match what {
            "passed" => passed = n,
            "failed" => failed = n,
            "ignored" => ignored = n,
            _ => {}
        }
    }
    Some((passed, failed, ignored))
}

/// `cargo test --workspace`, its output shown as it comes; returns the
/// summed counts of its "test result:" lines.
/// `cargo test --workspace`.
fn host_tests() -> Result<(u64, u64, u64)> {
    let mut child = cargo()
        .current_dir(root())
        .args(["test", "--workspace"])
        .stdout(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot start cargo test: {e}"))?;
    let out = child.stdout.take().ok_or("no cargo test stdout")?;
    let (mut passed, mut failed, mut ignored) = (0, 0, 0);
    for line in BufReader::new(out)
        .lines()
        .map_while(std::result::Result::ok)
    {
        println!("{line}");
        if let Some((p, f, i)) = parse_test_result(&line) {
            passed += p;
            failed += f;
            ignored += i;
        }
    }
    let status = child.wait().map_err(|e| format!("cargo test: {e}"))?;
    if !status.success() {
        return Err(format!("cargo test --workspace failed ({status})"));
    }
    Ok((passed, failed, ignored))
}

fn cmd_test(fuzz_seconds: u32) -> Result<u8> {
    let started = Instant::now();
    let mut missing = ensure(&[
        Tool::Target,
        Tool::FlipLink,
        Tool::Qemu,
        Tool::DefmtPrint,
        Tool::Viewers,
    ]);
    let viewers = !missing
        .iter()
        .any(|m| m.starts_with("vcd2fst") || m.starts_with("sigrok"));
    let firmware_possible = !missing.iter().any(|m| {
        m.starts_with("Rust target") || m.starts_with("rustup") || m.starts_with("flip-link")
    });
    let qemu_possible = firmware_possible
        && !missing
            .iter()
            .any(|m| m.starts_with("qemu") || m.starts_with("defmt-print"));

    step("import cycles between modules (every crate)");
    let modules = cycles::check_crates(&root(), cycles::CRATES)?;
    modules.print();

    step("host tests: cargo test --workspace");
    let results = host_tests()?;
    // The docs' cheap figures (the full set: `cargo xtask figures --check`)
    // and the names they cite: each figure and the name check count as tests.
    let (figure_count, drift) = figures::figures(true, true)?;
    let names = docnames::check()?;
    for line in drift.iter().chain(&names) {
        eprintln!("{line}");
    }
    let docs_passed = (figure_count - drift.len()) as u64 + u64::from(names.is_empty());
    let docs_failed = drift.len() as u64 + u64::from(!names.is_empty());
    let docs_line = format!(
        "{figure_count} quick figures, {} drifted; cited names: {} not found",
        drift.len(),
        names.len()
    );

    if firmware_possible {
        build_board()?;
        build_qemu()?;
        print_sizes()?;
        check_no_panic()?;
    }
    let mut qemu_code = None;
    let mut replay_line = None;
    let mut watchdog_line = None;
    let mut vcd_line = None;
    let mut board_checks = 0u64;
    if qemu_possible {
        let (code, lines) = run_qemu()?;
        if code != 0 {
            return Err(format!("the QEMU image exited with status {code}"));
        }
        check_snapshot(&lines, false)?;
        qemu_code = Some(code);
        board_checks += u64::from(table_checks::qemu_table_checks(&lines)?);
        board_checks += u64::from(faultpath::params_check()?);
        board_checks += u64::from(link::end_to_end()?);
        eprintln!("QEMU power cuts: {}", powercut::check()?);
        board_checks += 1;
        replay_line = Some(replay::check()?);
        watchdog_line = Some(watchdog::check()?);
        eprintln!("QEMU fault paths: {}", faultpath::check()?);
        board_checks += 2;
        if viewers {
            let vcd = target_dir().join("qemu-trace/run.vcd");
            let (summary, t) = trace::qemu_vcd(&vcd)?;
            eprintln!("QEMU trace: {summary}");
            vcd_line = Some(trace::check_both(&vcd, t.runs[0])?);
            board_checks += 2;
        }
    }

    // The release zslide-fw ELF on the emulated NUCLEO (`nucleo.rs`).
    let mut nucleo_line = None;
    if firmware_possible {
        match nucleo::require_unicorn().and_then(|()| nucleo::build_emulator()) {
            Ok(()) => {
                board_checks += nucleo::model_tests()?;
                let r = nucleo::check(nucleo::TEST_MS)?;
                if !nucleo::report(&r) {
                    return Err(
                        "emulated NUCLEO: tracking outside its tolerance of the QEMU image's"
                            .into(),
                    );
                }
                board_checks += r["link_checks_passed"].as_u64().unwrap_or(0);
                nucleo_line = Some(format!(
                    "booted, armed, tracking {:.2} µin (QEMU {:.2}), {} of {} faults latched, {} checks, {:.0} ms of machine time",
                    r["tracking_max_uin"].as_f64().unwrap_or(0.0),
                    r["qemu_tracking_max_uin"].as_f64().unwrap_or(0.0),
                    r["faults_latched"],
                    r["faults_injected"],
                    r["link_checks_passed"],
                    r["machine_ms"].as_f64().unwrap_or(0.0)
                ));
            }
            Err(e) => missing.push(e),
        }
    }

    // A short fuzz run of every target: a finding fails the run (after the
    // summary), each clean target counts as one passed test.
    let mut fuzz_line = String::from("NOT RUN (--fuzz-seconds 0)");
    let (mut fuzz_passed, mut fuzz_failed) = (0u64, 0u64);
    if fuzz_seconds > 0 {
        let fuzz_missing = fuzz::missing_tools();
        if fuzz_missing.is_empty() {
            match fuzz::run_targets(&fuzz::TARGETS, fuzz_seconds) {
                Ok(runs) => {
                    fuzz_passed = runs.len() as u64;
                    let execs: u64 = runs.iter().map(|(_, s)| s.execs).sum();
                    fuzz_line = format!(
                        "{} targets × {fuzz_seconds} s, {execs} executions, no finding",
                        runs.len()
                    );
                }
                Err(e) => {
                    fuzz_failed = e.lines().skip(1).count().max(1) as u64;
                    fuzz_passed = (fuzz::TARGETS.len() as u64).saturating_sub(fuzz_failed);
                    fuzz_line = format!("FAILED: {e}");
                }
            }
        } else {
            fuzz_line = "NOT RUN (tools missing, below)".into();
            missing.extend(fuzz_missing);
        }
    }

    eprintln!("\n==> summary ({:.0} s)", started.elapsed().as_secs_f64());
    let (passed, failed, ignored) = results;
    eprintln!("host tests: passed ({passed} passed, {failed} failed, {ignored} ignored)");
    eprintln!(
        "board firmware: {}",
        if firmware_possible {
            "built"
        } else {
            "NOT BUILT"
        }
    );
    if firmware_possible {
        eprintln!("panic paths from interrupt handlers: none (every image)");
    }
    eprintln!(
        "QEMU image: {}",
        match qemu_code {
            Some(_) => "ran, exit status 0, log as expected",
            None => "NOT RUN",
        }
    );
    if qemu_code.is_some() {
        eprintln!("QEMU table region and host link end to end: {board_checks} checks passed");
    }
    eprintln!(
        "QEMU replay: {}",
        replay_line.as_deref().unwrap_or("NOT RUN")
    );
    eprintln!(
        "QEMU watchdog: {}",
        watchdog_line.as_deref().unwrap_or("NOT RUN")
    );
    eprintln!(
        "VCD (the traced QEMU run, PASS; a host-sim machine VCD): {}",
        vcd_line.as_deref().unwrap_or("NOT RUN")
    );
    eprintln!(
        "emulated NUCLEO (release zslide-fw): {}",
        nucleo_line.as_deref().unwrap_or("NOT RUN")
    );
    eprintln!("fuzz: {fuzz_line}");
    eprintln!("docs: {docs_line}");
    eprintln!("{}", modules.summary());
    eprintln!("{}", modules.biggest_line());
    // The cycle check is one test of the tally.
    let cycle_failed = u64::from(!modules.cycles.is_empty());
    let code = if fuzz_failed > 0 || cycle_failed > 0 || docs_failed > 0 {
        1
    } else if missing.is_empty() {
        0
    } else {
        eprintln!("incomplete: missing, and could not be installed:");
        for m in &missing {
            eprintln!("  - {m}");
        }
        1
    };
    // The last line is the plain "N passed, N failed" tally CI reads; the
    // last libtest line above is a doc-test run that may count zero.
    eprintln!(
        "tests: {} passed, {} failed, {ignored} skipped",
        passed + fuzz_passed + board_checks + (1 - cycle_failed) + docs_passed,
        failed + fuzz_failed + cycle_failed + docs_failed
    );
    Ok(code)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::error::ErrorKind;
    use clap::CommandFactory;

    fn parse(args: &[&str]) -> std::result::Result<Cli, ErrorKind> {
        Cli::try_parse_from(std::iter::once("cargo xtask").chain(args.iter().copied()))
            .map_err(|e| e.kind())
    }

    #[test]
    fn every_command_refuses_unknown_flags_and_has_help() {
        Cli::command().debug_assert();
        for cmd in [
            &["test"][..],
            &["qemu"],
            &["size"],
            &["isr-cost"],
            &["no-panic"],
            &["fuzz", "--seconds", "1"],
            &["qemu-link"],
            &["qemu-link", "--table", "t.zsct"],
            &["link-test"],
            &["flash-cut"],
            &["nucleo"],
            &["nucleo", "--json", "--ms", "500"],
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
        assert_eq!(parse(&["sise"]).err(), Some(ErrorKind::InvalidSubcommand));
    }

    #[test]
    fn mistyped_values_are_refused() {
        assert_eq!(
            parse(&["fuzz"]).err(),
            Some(ErrorKind::MissingRequiredArgument)
        );
        assert_eq!(
            parse(&["fuzz", "--seconds", "0"]).err(),
            Some(ErrorKind::ValueValidation)
        );
        assert_eq!(
            parse(&["fuzz", "--seconds", "ten"]).err(),
            Some(ErrorKind::ValueValidation)
        );
        assert_eq!(
            parse(&["fuzz", "--seconds", "1", "--target", "tabel_parse"]).err(),
            Some(ErrorKind::InvalidValue)
        );
        assert_eq!(
            parse(&["isr-cost", "--variant", "moden"]).err(),
            Some(ErrorKind::InvalidValue)
        );
        assert_eq!(
            parse(&["isr-cost", "--call", "3"]).err(),
            Some(ErrorKind::MissingRequiredArgument)
        );
        assert!(parse(&[
            "isr-cost",
            "--profile",
            "x_count_event_modern",
            "--call",
            "3"
        ])
        .is_ok());
        assert_eq!(
            parse(&["test", "--fuzz-seconds", "-1"]).err(),
            Some(ErrorKind::UnknownArgument)
        );
        // The user's commands are `zslide`'s (zslide-host), not xtask's.
        for gone in [
            "link",
            "flash-table",
            "flash-params",
            "param-block",
            "trace2vcd",
        ] {
            assert_eq!(
                parse(&[gone]).err(),
                Some(ErrorKind::InvalidSubcommand),
                "{gone}"
            );
        }
    }

    #[test]
    fn test_result_lines_are_summed_by_field() {
        let line = "test result: ok. 19 passed; 2 failed; 3 ignored; 0 measured; 0 filtered out; finished in 0.01s";
        assert_eq!(parse_test_result(line), Some((19, 2, 3)));
        assert_eq!(parse_test_result("running 19 tests"), None);
    }

    #[test]
    fn timestamps_are_stripped_only_when_present() {
        assert_eq!(strip_timestamp("0.200019 INFO  PASS"), "INFO  PASS");
        assert_eq!(strip_timestamp("INFO  tick 1: x"), "INFO  tick 1: x");
    }
}
