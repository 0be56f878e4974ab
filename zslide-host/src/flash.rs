//! Writing a checked file into the NUCLEO's flash: with the probe-rs
//! library (`--features probe`, `probe.rs`) or its command-line tool.

use std::path::Path;
use std::process::Command;

use crate::regions::NUCLEO_CHIP;
use crate::Result;

/// The `probe-rs` command-line tool's command that writes `file` at
/// `addr` on the NUCLEO (the build without the `probe` feature).
pub fn probe_rs_download(file: &Path, addr: u32, probe: Option<&str>) -> Command {
    let mut cmd = Command::new("probe-rs");
    cmd.args(["download", "--chip", NUCLEO_CHIP]);
    if let Some(p) = probe {
        cmd.args(["--probe", p]);
    }
    cmd.args(["--binary-format", "bin", "--base-address"])
        .arg(format!("{addr:#010x}"))
        .arg(file);
    cmd
}

pub fn show(cmd: &Command) -> String {
    std::iter::once(cmd.get_program())
        .chain(cmd.get_args())
        .map(|a| a.to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join(" ")
}

/// Writes `file` (already checked) at `addr` on the NUCLEO: with the
/// probe-rs library when built with `probe`, else with its command-line
/// tool. `dry_run` prints what would be done.
pub fn download(file: &Path, addr: u32, probe: Option<&str>, dry_run: bool) -> Result<()> {
    #[cfg(feature = "probe")]
    {
        if dry_run {
            println!(
                "probe-rs library: attach {NUCLEO_CHIP}{}, write {} at {addr:#010x}",
                probe.map(|p| format!(" (probe {p})")).unwrap_or_default(),
                file.display()
            );
            return Ok(());
        }
        crate::probe::flash(file, addr, probe)
    }
    #[cfg(not(feature = "probe"))]
    {
        let mut cmd = probe_rs_download(file, addr, probe);
        if dry_run {
            println!("{}", show(&cmd));
            return Ok(());
        }
        eprintln!("==> {}", show(&cmd));
        let status = cmd.status().map_err(|e| {
            format!(
                "cannot start probe-rs ({e}): install it with `cargo install probe-rs-tools \
                 --locked`, or build zslide with the probe-rs library (`--features probe`)"
            )
        })?;
        if status.success() {
            eprintln!("written; reset the board (the firmware reads the region at boot)");
            Ok(())
        } else {
            Err(format!("probe-rs download failed ({status})"))
        }
    }
}
