//! `host-sim trace2vcd`: a board's decoded defmt log (QEMU or the NUCLEO,
//! built with trace events) → a VCD with the simulator's signal names
//! (`vcd::target`). `cargo xtask trace2vcd` and `cargo xtask qemu --vcd`
//! call it.

use anyhow::{Context, Result};
use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    /// The decoded log (`defmt-print` output); `-` for stdin.
    pub log: PathBuf,
    /// The VCD to write.
    #[arg(long, short)]
    pub out: PathBuf,
}

pub fn run(a: Args) -> Result<()> {
    let (partial, file) = crate::outpath::Partial::create(&a.out)?;
    let out = BufWriter::new(file);
    let summary = if a.log.as_os_str() == "-" {
        crate::vcd::target::convert(std::io::stdin().lock(), out)
    } else {
        let f = File::open(&a.log).with_context(|| format!("cannot open {}", a.log.display()))?;
        crate::vcd::target::convert(BufReader::new(f), out)
    }
    .with_context(|| format!("trace {}", a.log.display()))?;
    partial.commit()?;
    let names = ["loop tick", "X event", "index"];
    eprintln!(
        "{}: {} events over {:.6} s (clock {} Hz)",
        a.out.display(),
        summary.events,
        summary.span_s,
        summary.clock_hz
    );
    for (k, name) in names.iter().enumerate() {
        if summary.runs[k] > 0 {
            eprintln!(
                "  {name}: {} runs, longest {:.2} µs entry to exit",
                summary.runs[k], summary.longest_us[k]
            );
        }
    }
    Ok(())
}
