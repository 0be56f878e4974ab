//! `host-sim replay-record`: records the runs the target replays bit-exact
//! (`crate::replay::CASES`) into one file for the replay image's flash, and
//! optionally a copy with one recorded DAC code altered, which the replay
//! must refuse (the self-check of `cargo xtask qemu`).

use crate::replay::{record_cases, Case, CASES};
use crate::sched::Nanos;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where to write the recording.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Also write the recording with one amplifier-DAC code of the first
    /// run altered (its least significant bit flipped) here.
    #[arg(long, value_name = "FILE")]
    pub altered_out: Option<PathBuf>,
    /// Which of the first run's loop-tick DAC frames to alter (from 0).
    #[arg(
        long,
        value_name = "N",
        default_value_t = 3000,
        requires = "altered_out"
    )]
    pub alter_nth: usize,
    /// Record each run for this many milliseconds instead of its own
    /// length (300 ms): a short recording, such as the fuzz seeds
    /// (`docs/RELIABILITY.md`). `cargo xtask qemu` checks the full runs.
    #[arg(long, value_name = "MS", value_parser = clap::value_parser!(u32).range(1..))]
    pub ms: Option<u32>,
}

#[derive(serde::Serialize)]
struct RunSummary {
    name: &'static str,
    bytes: usize,
    handler_calls: usize,
    x_accepted: u64,
    index_events: u64,
    engaged_at_end: bool,
    fault_at_end: Option<String>,
    /// Hole crossings the edges' anticipation learned at (runs with an
    /// interruption block).
    edge_crossings: u32,
}

#[derive(serde::Serialize)]
struct Summary {
    file: PathBuf,
    bytes: usize,
    runs: Vec<RunSummary>,
    /// The altered code: run, loop tick (from 1), the frame recorded and
    /// the one written instead.
    altered: Option<Altered>,
}

#[derive(serde::Serialize)]
struct Altered {
    file: PathBuf,
    run: &'static str,
    tick: u32,
    original: String,
    altered: String,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let cases = CASES.map(|c| match a.ms {
        Some(ms) => Case {
            duration_ns: Nanos::from(ms) * 1_000_000,
            ..c
        },
        None => c,
    });
    let (container, runs) = record_cases(&cases)?;
    crate::outpath::replace(&a.out, &container)?;
    let mut altered = None;
    if let Some(path) = &a.altered_out {
        let first: &'static [u8] = Box::leak(runs[0].bytes.clone().into_boxed_slice());
        let (changed, alt) =
            zslide_replay::record::alter(first, a.alter_nth).map_err(anyhow::Error::msg)?;
        let mut all: Vec<Vec<u8>> = runs.iter().map(|r| r.bytes.clone()).collect();
        all[0] = changed;
        crate::outpath::replace(path, zslide_replay::container::build(&all))?;
        altered = Some(Altered {
            file: path.clone(),
            run: runs[0].name,
            tick: alt.tick,
            original: format!("{:#08x}", alt.original),
            altered: format!("{:#08x}", alt.altered),
        });
    }
    let summary = Summary {
        file: a.out.clone(),
        bytes: container.len(),
        runs: runs
            .iter()
            .map(|r| RunSummary {
                name: r.name,
                bytes: r.bytes.len(),
                handler_calls: r.calls,
                x_accepted: r.x_accepted,
                index_events: r.index_events,
                engaged_at_end: r.engaged,
                fault_at_end: r.final_fault.map(|f| format!("{f:?}")),
                edge_crossings: r.edge_crossings,
            })
            .collect(),
        altered,
    };
    println!("{}", serde_json::to_string_pretty(&summary)?);
    Ok(())
}
