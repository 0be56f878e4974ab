//! `zslide`: see `zslide --help`.

use clap::Parser;
use std::process::ExitCode;
use std::time::Duration;
use zslide_host::cli::{execute, Cli};
use zslide_host::client::Link;
use zslide_host::report::CLOSED_OUTPUT;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let mut link = Link::new(&cli.connect, Duration::from_millis(cli.timeout_ms));
    match execute(&cli.cmd, &mut link, &mut std::io::stdout()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e == CLOSED_OUTPUT => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("zslide: error: {e}");
            ExitCode::from(1)
        }
    }
}
