//! The NUCLEO through the probe-rs library (feature `probe`): attach to
//! the chip, the link on RTT channel pair 1 (`src/board/link.rs`), the
//! defmt log of up channel 0 passed to stderr alongside, and flashing the
//! table and parameter regions.
//!
//! Channel 0 carries defmt frames, which only the firmware's ELF can
//! decode: with an ELF (`ZSLIDE_ELF`, else the workspace's release build
//! of zslide-fw) each frame is printed to stderr as it comes, `fw: ` first
//! (`crate::defmt_log`); without one they are counted. `ZSLIDE_DEFMT_LOG`
//! also keeps the raw bytes in a file (`zslide log --elf ELF FILE`
//! decodes it later).

use std::io::{Read, Write};
use std::path::Path;

use probe_rs::flashing::{download_file, BinLoader, BinOptions};
use probe_rs::probe::list::Lister;
use probe_rs::probe::DebugProbeSelector;
use probe_rs::rtt::Rtt;
use probe_rs::{Permissions, Session};

use crate::regions::NUCLEO_CHIP;
use crate::Result;

/// RTT channel of the link (both directions) and of the defmt log (up).
pub const LINK_CHANNEL: usize = 1;
pub const DEFMT_CHANNEL: usize = 0;

fn session(selector: Option<&str>) -> Result<Session> {
    let lister = Lister::new();
    let probe = match selector.filter(|s| !s.is_empty()) {
        Some(sel) => {
            let sel: DebugProbeSelector = sel
                .parse()
                .map_err(|e| format!("probe selector {sel:?}: {e}"))?;
            lister
                .open(sel)
                .map_err(|e| format!("opening probe: {e}"))?
        }
        None => {
            let all = lister.list_all();
            let first = all
                .first()
                .ok_or("no debug probe found (is the NUCLEO's ST-LINK connected?)")?;
            if all.len() > 1 {
                return Err(format!(
                    "{} probes connected: choose one with probe:VID:PID[:SERIAL]",
                    all.len()
                ));
            }
            first.open().map_err(|e| format!("opening probe: {e}"))?
        }
    };
    probe
        .attach(NUCLEO_CHIP, Permissions::default())
        .map_err(|e| format!("attaching to {NUCLEO_CHIP}: {e}"))
}

/// The link on RTT channel pair 1 as a byte stream.
pub struct RttLink {
    session: Session,
    rtt: Rtt,
    defmt: Option<std::fs::File>,
    decoded: Option<crate::defmt_log::DefmtLog>,
    pub defmt_bytes: u64,
}

// The session is used from one thread at a time (the `Client`).
unsafe impl Send for RttLink {}

impl RttLink {
    pub fn attach(selector: &str) -> Result<Self> {
        let mut session = session(Some(selector))?;
        let rtt = {
            let mut core = session.core(0).map_err(|e| e.to_string())?;
            Rtt::attach(&mut core).map_err(|e| format!("RTT control block: {e}"))?
        };
        let defmt = match std::env::var_os("ZSLIDE_DEFMT_LOG") {
            Some(p) => Some(
                std::fs::File::create(&p)
                    .map_err(|e| format!("{}: {e}", Path::new(&p).display()))?,
            ),
            None => None,
        };
        let decoded = match crate::defmt_log::elf_from_env() {
            Some(elf) => Some(crate::defmt_log::DefmtLog::from_elf(&elf)?),
            None => {
                eprintln!(
                    "the board's defmt log is not decoded: no firmware ELF (set ZSLIDE_ELF, or \
                     build {})",
                    crate::defmt_log::DEFAULT_ELF
                );
                None
            }
        };
        Ok(Self {
            session,
            rtt,
            defmt,
            decoded,
            defmt_bytes: 0,
        })
    }
}

fn io(e: impl std::fmt::Display) -> std::io::Error {
    std::io::Error::other(e.to_string())
}

impl Read for RttLink {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let mut core = self.session.core(0).map_err(io)?;
        // The log first, so that it never backs up behind the link.
        if let Some(up) = self.rtt.up_channel(DEFMT_CHANNEL) {
            let mut log = [0u8; 1024];
            let n = up.read(&mut core, &mut log).map_err(io)?;
            self.defmt_bytes += n as u64;
            if let Some(f) = self.defmt.as_mut() {
                f.write_all(&log[..n])?;
            }
            if let Some(d) = self.decoded.as_mut() {
                d.feed(&log[..n], "fw: ", &mut std::io::stderr())?;
            }
        }
        let up = self
            .rtt
            .up_channel(LINK_CHANNEL)
            .ok_or_else(|| io("the firmware has no RTT up channel 1 (zslide-link)"))?;
        let n = up.read(&mut core, buf).map_err(io)?;
        if n == 0 {
            std::thread::sleep(std::time::Duration::from_millis(1));
            return Err(std::io::ErrorKind::WouldBlock.into());
        }
        Ok(n)
    }
}

impl Write for RttLink {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let mut core = self.session.core(0).map_err(io)?;
        let down = self
            .rtt
            .down_channel(LINK_CHANNEL)
            .ok_or_else(|| io("the firmware has no RTT down channel 1 (zslide-link)"))?;
        down.write(&mut core, buf).map_err(io)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Writes `file` at `addr` of the NUCLEO's flash (the region's sector is
/// erased and programmed by probe-rs's flash algorithm).
pub fn flash(file: &Path, addr: u32, selector: Option<&str>) -> Result<()> {
    let mut s = session(selector)?;
    download_file(
        &mut s,
        file,
        BinLoader(BinOptions {
            base_address: Some(u64::from(addr)),
            skip: 0,
        }),
    )
    .map_err(|e| format!("writing {} at {addr:#010x}: {e}", file.display()))?;
    eprintln!("written; reset the board (the firmware reads the region at boot)");
    Ok(())
}
