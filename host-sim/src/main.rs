//! `host-sim`: the simulator's and the coefficient tools' command line
//! (the parser: `host_sim::cli`).
use clap::FromArgMatches;
use host_sim::cli::{self, Cli};

/// Errors go to stderr as one readable chain ("what: because"), exit code 1,
/// with no backtrace even when `RUST_BACKTRACE` is set: a bad input line or
/// a refused geometry is a message for the user, not a crash.
fn main() {
    // A reader that stops early (`host-sim coeffs | head -1`) is not an
    // error: Rust ignores SIGPIPE, so `println!` would panic on the closed
    // pipe; the default action ends the process quietly, as `cat` does.
    #[cfg(unix)]
    restore_sigpipe();
    #[cfg(unix)]
    if let Err(e) = host_sim::outpath::remove_partials_on_signal() {
        eprintln!("warning: Ctrl-C cannot be caught ({e}); it may leave a hidden .partial file");
    }
    let matches = cli::command().get_matches();
    let parsed = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    if let Err(e) = cli::run(parsed.command) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

#[cfg(unix)]
fn restore_sigpipe() {
    // SAFETY: resetting one signal's disposition to its default at start-up,
    // before any thread exists; no handler code runs.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
