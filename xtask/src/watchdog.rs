//! The watchdog step of `cargo xtask qemu` (and `test`): the image
//! `zslide-qemu-watchdog` hangs each firmware handler in turn (X, index,
//! loop tick) and stops the loop tick, and the CMSDK watchdog, fed by the
//! background through `zslide::watchdog::FeedGate`, must expire within its
//! 5 ms every time; with the feed moved into the loop tick (the control)
//! a hung X handler must go uncaught.

use std::path::PathBuf;

use crate::{run_qemu_elf, step, target_dir, QemuRegions, Result, TARGET};

pub fn watchdog_elf() -> PathBuf {
    target_dir()
        .join(TARGET)
        .join("release/zslide-qemu-watchdog")
}

/// Runs the image; returns the summary line.
pub fn check() -> Result<String> {
    step("QEMU watchdog: zslide-qemu-watchdog (a hang of each handler)");
    // The image builds its firmware from the built-in table.
    let regions = QemuRegions {
        table: None,
        params: None,
    };
    let (code, lines) = run_qemu_elf(&watchdog_elf(), &regions, &[])?;
    let caught = lines
        .iter()
        .filter(|l| l.contains("watchdog expired"))
        .count();
    if code != 0 || caught != 4 || !lines.iter().any(|l| l.ends_with("PASS")) {
        return Err(format!(
            "the watchdog check failed (exit status {code}, {caught} of 4 stops caught)"
        ));
    }
    Ok("a hung X, index and loop-tick handler and a stopped loop tick each trip it within 5 ms; fed from the loop tick a hung X handler is missed".into())
}
