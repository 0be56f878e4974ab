//! A command's report: its lines, written to the user's output.

use std::io::Write;

use crate::Result;

/// What `say` returns when the reader of the output went away (`zslide
/// params show | head -3`): not an error of the command.
pub const CLOSED_OUTPUT: &str = "the output was closed";

/// Writes one line of a command's report.
pub fn say_to(out: &mut dyn Write, s: &str) -> Result<()> {
    writeln!(out, "{}", s.trim_end()).map_err(|e| {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            CLOSED_OUTPUT.to_string()
        } else {
            format!("writing the report: {e}")
        }
    })
}
