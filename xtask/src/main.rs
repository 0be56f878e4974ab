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
//! * `size`    – flash and RAM use of the three images (builds them first).
//! * `isr-cost [--json] [--variant V] [--profile R [--call N]]` –
//!   instructions per interrupt handler under QEMU.
//! * `no-panic` – builds the three images and proves that no panic path is
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
mod doccmds;
mod docnames;
mod elf;
mod faultpath;
mod figures;
mod fuzz;
mod generated;
mod images;
mod isr_cost;
mod link;
mod mutants;
mod nextest;
mod nopanic;
mod nucleo;
mod powercut;
mod qemu;
mod qemu_cmd;
mod replay;
mod size;
mod snapshot;
mod stack;
mod suite;
mod table_checks;
mod tools;
mod trace;
mod watchdog;

use clap::{Parser, Subcommand};
use std::env;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

// The helpers the command modules share, at the crate's root.
pub use images::{build_qemu_image, build_qemu_image_with};
pub use qemu::{
    default_table_path, qemu_command, qemu_command_with, run_qemu_elf, run_qemu_elf_at,
    run_qemu_elf_echo, run_qemu_elf_with, run_qemu_with, QemuRegions,
};
pub use tools::{output_of, require_for_qemu, run, works};

pub const TARGET: &str = "thumbv7em-none-eabihf";

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
    ///
    /// The last line is `tests: N passed, N failed, N skipped`.
    Test {
        /// Seconds each fuzz target runs (0 skips the fuzz step).
        #[arg(long, default_value_t = fuzz::TEST_SECONDS, value_name = "N")]
        fuzz_seconds: u32,
    },
    /// Build and run the QEMU image; exit status passed through.
    ///
    /// Checks its log against boards/qemu/expected.log, replays host-sim's
    /// recorded runs bit-exact on the emulated Cortex-M4F (and checks that
    /// an altered code is caught), hangs each handler and checks that the
    /// watchdog trips.
    Qemu {
        /// Rewrite boards/qemu/expected.log with this run's log.
        #[arg(long)]
        bless: bool,
        /// Also run the image built with trace events and write the run as
        /// a VCD (the simulator's signal names; its decoded log beside it).
        #[arg(long, value_name = "FILE")]
        vcd: Option<PathBuf>,
    },
    /// Flash and RAM use of the three images (zslide-fw, zslide-centre,
    /// zslide-qemu).
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
    /// docs/*.md and rewrite them (`--check`: list what drifted, exit 1).
    ///
    /// Also rewrites the generated sections (parameters, faults, commands),
    /// checks that the names the docs cite exist, and parses every command
    /// they show with the program's own parser (the `sh quick` blocks also
    /// run). `cargo xtask test` runs `--check --quick`.
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
        Cmd::Test { fuzz_seconds } => suite::run(fuzz_seconds),
        Cmd::Qemu { bless, vcd } => qemu_cmd::run(bless, vcd.as_deref()),
        Cmd::Size => size::run(),
        Cmd::IsrCost(args) => isr_cost::run(&args),
        Cmd::NoPanic => nopanic::run(),
        Cmd::Fuzz(args) => fuzz::run(&args).map(|_| 0),
        Cmd::QemuLink(args) => link::run_session(&args),
        Cmd::LinkTest => link::run_test(),
        Cmd::FlashCut => powercut::run(),
        Cmd::Figures(args) => figures::run(&args),
        Cmd::Cycles => cycles::run(),
        Cmd::Nucleo(args) => nucleo::run(&args),
        Cmd::Mutants(args) => mutants::run(&args),
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
}
