//! The QEMU command line and runner every QEMU check uses. The log
//! snapshot is `snapshot.rs`, the command itself `qemu_cmd.rs`.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::{qemu_elf, root, step, Result};

const QEMU_TIMEOUT: Duration = Duration::from_secs(120);

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

pub fn wait_timeout(
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
pub fn run_qemu() -> Result<(u8, Vec<String>)> {
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
