//! `cargo xtask trace2vcd LOG --out FILE`: a board's decoded defmt log with
//! trace events → VCD, by `host-sim trace2vcd` (the one decoder and the one
//! set of signal names: `zslide::trace`, `host-sim/src/vcd/target.rs`).
//! Built in the dev profile, which `cargo test --workspace` has already
//! built, so it costs no extra compile in `cargo xtask test`.

use crate::{cargo, root, Result};
use std::path::Path;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The decoded log (`defmt-print` output); `-` for stdin.
    pub log: std::path::PathBuf,
    /// The VCD to write.
    #[arg(long, short, value_name = "FILE")]
    pub out: std::path::PathBuf,
}

pub fn run(a: &Args) -> Result<u8> {
    convert(&a.log, &a.out)?;
    Ok(0)
}

/// Runs the converter; its message (events, span, handler times) goes to
/// stderr; an unreadable or corrupt trace is an error.
pub fn convert(log: &Path, vcd: &Path) -> Result<()> {
    let abs = |p: &Path| {
        if p.as_os_str() == "-" || p.is_absolute() {
            p.to_path_buf()
        } else {
            std::env::current_dir()
                .map(|d| d.join(p))
                .unwrap_or_else(|_| p.to_path_buf())
        }
    };
    let status = cargo()
        .current_dir(root())
        .args(["run", "--quiet", "-p", "host-sim", "--", "trace2vcd"])
        .arg(abs(log))
        .arg("--out")
        .arg(abs(vcd))
        .status()
        .map_err(|e| format!("cannot start cargo run -p host-sim: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("host-sim trace2vcd failed ({status})"))
    }
}
