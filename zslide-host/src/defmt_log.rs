//! A firmware's defmt log decoded in-process (feature `defmt-log`, part of
//! `probe`): the frames of RTT up channel 0, or of a raw log file, turned
//! into lines with the format strings of the firmware's ELF, as
//! `defmt-print -e ELF` prints them.

use std::io::Write;
use std::path::{Path, PathBuf};

use defmt_decoder::{DecodeError, StreamDecoder, Table};

use crate::Result;

/// The firmware image whose format strings decode a board's log when
/// `ZSLIDE_ELF` does not name one: the release build of the workspace it
/// runs in.
pub const DEFAULT_ELF: &str = "target/thumbv7em-none-eabihf/release/zslide-fw";

/// The ELF `ZSLIDE_ELF` names, else [`DEFAULT_ELF`] when it exists.
pub fn elf_from_env() -> Option<PathBuf> {
    match std::env::var_os("ZSLIDE_ELF") {
        Some(p) => Some(PathBuf::from(p)),
        None => Some(PathBuf::from(DEFAULT_ELF)).filter(|p| p.exists()),
    }
}

/// A stream decoder over one ELF's table.
pub struct DefmtLog {
    decoder: Box<dyn StreamDecoder + Send + Sync + 'static>,
    /// Whether the encoding can find the next frame after a bad one
    /// (rzcobs can; raw cannot, and the rest of the stream is lost).
    recovers: bool,
    stopped: bool,
    pub frames: u64,
    pub malformed: u64,
}

impl DefmtLog {
    pub fn from_elf(path: &Path) -> Result<Self> {
        let elf =
            std::fs::read(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
        let table = Table::parse(&elf)
            .map_err(|e| format!("{}: its defmt table: {e}", path.display()))?
            .ok_or_else(|| {
                format!(
                    "{}: no defmt table (not a firmware built with defmt)",
                    path.display()
                )
            })?;
        let recovers = table.encoding().can_recover();
        // The decoder borrows its table for as long as the log runs: the
        // life of the tool.
        let table: &'static Table = Box::leak(Box::new(table));
        Ok(Self {
            decoder: table.new_stream_decoder(),
            recovers,
            stopped: false,
            frames: 0,
            malformed: 0,
        })
    }

    /// Takes `bytes` of the stream and writes every frame they complete,
    /// one line each, `prefix` first.
    pub fn feed(&mut self, bytes: &[u8], prefix: &str, out: &mut dyn Write) -> std::io::Result<()> {
        if self.stopped {
            return Ok(());
        }
        self.decoder.received(bytes);
        loop {
            match self.decoder.decode() {
                Ok(frame) => {
                    self.frames += 1;
                    writeln!(out, "{prefix}{}", frame.display(false))?;
                }
                Err(DecodeError::UnexpectedEof) => return Ok(()),
                Err(DecodeError::Malformed) => {
                    self.malformed += 1;
                    if self.recovers {
                        writeln!(out, "{prefix}(a malformed defmt frame skipped)")?;
                    } else {
                        writeln!(
                            out,
                            "{prefix}(a malformed defmt frame: this encoding cannot find the next \
                             one, the log stops here; is the ELF the one on the board?)"
                        )?;
                        self.stopped = true;
                        return Ok(());
                    }
                }
            }
        }
    }
}

/// `zslide log`: a raw defmt log (a file, or stdin) decoded to stdout.
pub fn decode_file(elf: &Path, input: Option<&Path>) -> Result<String> {
    use std::io::Read;
    let mut log = DefmtLog::from_elf(elf)?;
    let mut src: Box<dyn Read> = match input {
        Some(p) => Box::new(
            std::fs::File::open(p).map_err(|e| format!("{}: cannot open: {e}", p.display()))?,
        ),
        None => Box::new(std::io::stdin()),
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let mut buf = [0u8; 4096];
    loop {
        let n = src
            .read(&mut buf)
            .map_err(|e| format!("reading the log: {e}"))?;
        if n == 0 {
            break;
        }
        log.feed(&buf[..n], "", &mut out)
            .map_err(|e| format!("writing: {e}"))?;
    }
    Ok(format!(
        "{} frames decoded, {} malformed",
        log.frames, log.malformed
    ))
}
