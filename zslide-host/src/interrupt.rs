//! Ctrl-C (SIGINT) and SIGTERM while a command drives the machine: the
//! signal only notes itself; the link then refuses every further request
//! but the safe stop ([`crate::client::Client::make_safe`]: the excitation
//! off, an armed capture released), which `main` sends before it exits
//! with the signal's code. A second signal while that runs ends the
//! process at once by the signal's default action, so a stuck link never
//! makes Ctrl-C useless.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

use signal_hook::consts::{SIGINT, SIGTERM};

/// The signal received (0: none), and whether any was.
fn slots() -> &'static (Arc<AtomicUsize>, Arc<AtomicBool>) {
    static SLOTS: OnceLock<(Arc<AtomicUsize>, Arc<AtomicBool>)> = OnceLock::new();
    SLOTS.get_or_init(|| {
        (
            Arc::new(AtomicUsize::new(0)),
            Arc::new(AtomicBool::new(false)),
        )
    })
}

/// Installs the handlers: once, at the start of the `zslide` binary (a
/// library user, such as a test, keeps the default actions).
pub fn install() -> std::io::Result<()> {
    let (which, any) = slots();
    for sig in [SIGINT, SIGTERM] {
        // Registered first, so it sees the flag as the previous signal
        // left it: the second signal takes the default action.
        signal_hook::flag::register_conditional_default(sig, any.clone())?;
        signal_hook::flag::register_usize(sig, which.clone(), sig as usize)?;
        signal_hook::flag::register(sig, any.clone())?;
    }
    Ok(())
}

/// The signal that asked the command to stop, if one did.
pub fn received() -> Option<i32> {
    match slots().0.load(Ordering::Relaxed) {
        0 => None,
        s => Some(s as i32),
    }
}

/// Why a request was not sent.
pub fn refusal(sig: i32) -> String {
    let name = match sig {
        SIGINT => "SIGINT (Ctrl-C)",
        SIGTERM => "SIGTERM",
        _ => "a signal",
    };
    format!("stopped by {name}")
}

/// The exit code of a command a signal stopped: 128 + the signal's
/// number, as a shell reports a process the signal ended.
pub fn exit_code(sig: i32) -> u8 {
    (128 + sig).clamp(0, 255) as u8
}
