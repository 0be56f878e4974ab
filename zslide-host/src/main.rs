//! `zslide`: see `zslide --help`.

use clap::Parser;
use std::process::ExitCode;
use std::time::Duration;
use zslide_host::cli::{execute, Cli};
use zslide_host::client::Link;
use zslide_host::interrupt;
use zslide_host::report::CLOSED_OUTPUT;

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(e) = interrupt::install() {
        eprintln!("zslide: warning: Ctrl-C cannot be caught ({e}); it ends zslide at once");
    }
    let mut link = Link::new(&cli.connect, Duration::from_millis(cli.timeout_ms));
    let r = execute(&cli.cmd, &mut link, &mut std::io::stdout());
    let sig = interrupt::received();
    let code = match (&r, sig) {
        (_, Some(sig)) => {
            eprintln!("zslide: {}", interrupt::refusal(sig));
            ExitCode::from(interrupt::exit_code(sig))
        }
        (Ok(()), None) => return ExitCode::SUCCESS,
        (Err(e), None) if e == CLOSED_OUTPUT => return ExitCode::SUCCESS,
        (Err(e), None) => {
            eprintln!("zslide: error: {e}");
            ExitCode::from(1)
        }
    };
    // A command stopped part-way, by an error or a signal, leaves the
    // machine as the loop alone drives it.
    match link.make_safe() {
        Some(Ok(did)) if !did.is_empty() => {
            eprintln!("zslide: left the machine safe: {}", did.join(", "))
        }
        Some(Err(e)) => eprintln!("zslide: error: leaving the machine safe: {e}"),
        _ => {}
    }
    code
}
