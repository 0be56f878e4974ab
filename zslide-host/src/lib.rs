//! `zslide`, the machine's host tool: what a user does with a Z-slide
//! machine, on a board (probe or RTT bridge), the QEMU image, or a
//! simulated machine (`host-sim serve`). `xtask` keeps only the project's
//! own automation and drives this crate in its tests.

pub mod capture;
pub mod cli;
pub mod client;
#[cfg(feature = "defmt-log")]
pub mod defmt_log;
pub mod fields;
pub mod fit;
pub mod flash;
pub mod identify;
pub mod interrupt;
pub mod measured;
pub mod predict;
pub mod process;
#[cfg(feature = "probe")]
pub mod probe;
pub mod regions;
pub mod report;
pub mod scope;
pub mod words;

pub type Result<T> = std::result::Result<T, String>;

/// Writes `bytes` as the whole of `path`, or leaves `path` as it was
/// (`host_sim::outpath`, the one way both tools write their files).
pub fn write_file(path: &std::path::Path, bytes: impl AsRef<[u8]>) -> Result<()> {
    host_sim::outpath::replace(path, bytes).map_err(|e| format!("{e:#}"))
}
