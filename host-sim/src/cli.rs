//! The command line of `host-sim` (its `main` is `src/main.rs`), here so
//! that tools can read it: `cargo xtask figures` checks the commands and
//! options the docs cite against [`command`].
use crate::cmd;
use clap::{CommandFactory, Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "host-sim",
    version,
    about = "Z-slide machine simulator and coefficient tools"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Coefficient tables: Table 2-2 (sin-power form) or a Fourier expansion at one X.
    Coeffs(cmd::coeffs::Args),
    /// Accuracy of the firmware command path against the exact surface.
    Accuracy(cmd::accuracy::Args),
    /// The smallest harmonic table meeting a part file's bound, and its error split.
    PartTable(cmd::parttable::Args),
    /// A table compensating a measured part's error (nominal − gain × fitted error).
    Compensate(cmd::compensate::Args),
    /// Measure, compensate, cut again, N times on one machine: the bands after each pass.
    CompensateIterate(cmd::iterate::Args),
    /// Feasibility of a part on the machine before cutting (exit 1 with the reasons if not).
    Plan(cmd::plan::Args),
    /// Z command from the firmware's fixed-point path for `x_in,phi_deg` lines on stdin.
    Zcmd(cmd::zcmd::Args),
    /// Appendix C block diagrams (CSMP studies C-1 .. C-6) simulated.
    Csmp(cmd::csmp::Args),
    /// Closed-loop tracking of a spindle-synchronous sinusoid.
    Track(cmd::track::Args),
    /// Frequency response of a loop of the simulated machine (signal analyser).
    Response(cmd::response::Args),
    /// The simulated finishing cut and its CMM measurement.
    Cut(cmd::cut::Args),
    /// Automatic centring (Y-1594).
    Center(cmd::center::Args),
    /// Fault injection campaign.
    Faults(cmd::faults::Args),
    /// Hours of machine time with shop-floor disturbances, a summary per hour.
    Soak(cmd::soak::Args),
    /// Cost of one plant step and of one simulated second at the loop rate.
    Bench(cmd::bench::Args),
    /// A board's decoded defmt trace log as a VCD with the simulator's signal names.
    Trace2vcd(cmd::trace2vcd::Args),
    /// The simulated machine behind the firmware's link, in real time, for
    /// `zslide --connect ADDR ...`.
    Serve(cmd::serve::Args),
    /// Record the runs the target replays bit-exact (`cargo xtask qemu`).
    ReplayRecord(cmd::replay::Args),
}

/// The parser, as `main` uses it.
pub fn command() -> clap::Command {
    with_negative_numbers(Cli::command())
}

/// Every option that takes a value accepts a leading minus, so that
/// `cut --rpm -5` reaches the command's own range check ("--rpm -5: must
/// be ...") instead of clap's "unexpected argument '-5'". One rule for all
/// commands, so a new numeric option cannot miss it.
fn with_negative_numbers(cmd: clap::Command) -> clap::Command {
    cmd.mut_subcommands(|sub| {
        sub.mut_args(|a| {
            if a.get_action().takes_values() {
                a.allow_negative_numbers(true)
            } else {
                a
            }
        })
    })
}

/// Runs one parsed command.
pub fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Coeffs(a) => cmd::coeffs::run(a),
        Command::Compensate(a) => cmd::compensate::run(a),
        Command::CompensateIterate(a) => cmd::iterate::run(a),
        Command::Accuracy(a) => cmd::accuracy::run(a),
        Command::Zcmd(a) => cmd::zcmd::run(a),
        Command::PartTable(a) => cmd::parttable::run(a),
        Command::Plan(a) => cmd::plan::run(a),
        Command::Csmp(a) => cmd::csmp::run(a),
        Command::Track(a) => cmd::track::run(a),
        Command::Response(a) => cmd::response::run(a),
        Command::Cut(a) => cmd::cut::run(a),
        Command::Center(a) => cmd::center::run(a),
        Command::Faults(a) => cmd::faults::run(a),
        Command::Soak(a) => cmd::soak::run(a),
        Command::Bench(a) => cmd::bench::run(a),
        Command::Trace2vcd(a) => cmd::trace2vcd::run(a),
        Command::Serve(a) => cmd::serve::run(a),
        Command::ReplayRecord(a) => cmd::replay::run(a),
    }
}
