//! `cargo xtask qemu [--bless] [--vcd FILE]`: the QEMU image run and its
//! log snapshot (`qemu.rs`), then the replay, watchdog and fault-path
//! checks, and with `--vcd` the traced run.

use std::path::Path;

use crate::images::build_qemu;
use crate::qemu::run_qemu;
use crate::tools::require_for_qemu_log;
use crate::{faultpath, replay, snapshot, trace, watchdog, Result};

pub fn run(bless: bool, vcd: Option<&Path>) -> Result<u8> {
    require_for_qemu_log()?;
    build_qemu()?;
    let (code, lines) = run_qemu()?;
    eprintln!("QEMU image exited with status {code}");
    if code == 0 {
        snapshot::check(&lines, bless)?;
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
