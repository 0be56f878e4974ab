//! The NUCLEO's host link, the table and interruption regions of
//! `memory.x` (the parameter region is the store's, `board::flash`), and
//! the RTT channels (one control block:
//! up channel 0 carries the defmt log, which `probe-rs run` decodes; the
//! link's frames go up on channel 1 and come down on channel 1, the pair
//! OpenOCD's `rtt server start PORT 1` bridges to a TCP port for
//! `zslide`, `docs/BOARD.md`).

use rtt_target::{ChannelMode, DownChannel, UpChannel};
use zslide::link::station::LinkIo;
use zslide::link::tap::{Scope, TapShared};

pub use zslide::link::CAPTURE;

/// The capture ring (zeros: `.bss`).
static SCOPE: Scope<CAPTURE> = Scope::new();

/// The loop tick's and the background's shared link state.
pub static TAP: TapShared<'static, CAPTURE> = TapShared::new(&SCOPE);

extern "C" {
    static __zsct_start: u8;
    static __zsct_size: u8;
    static __zsib_start: u8;
    static __zsib_size: u8;
}

/// The bytes of a `memory.x` region given its start and size symbols.
fn region(start: *const u8, size: *const u8) -> &'static [u8] {
    // SAFETY: `memory.x` defines both symbols: the start is the region's
    // first byte and the *address* of the size symbol is its length (a
    // linker constant, never dereferenced). The region is a flash sector
    // outside every section of the image, readable whether programmed or
    // erased, and the firmware never programs it (it programs only the
    // parameter region, `board::flash`, which has no such view), so a
    // shared `'static` view of it is sound.
    unsafe { core::slice::from_raw_parts(start, size as usize) }
}

/// The coefficient-table region (`ZSCT`, bank 1 sector 7, 0x080E_0000).
pub fn table_region() -> &'static [u8] {
    region(
        core::ptr::addr_of!(__zsct_start),
        core::ptr::addr_of!(__zsct_size),
    )
}

/// The interruption region (`ZSIB`, bank 2 sector 7, 0x081E_0000): the
/// part's interruption block (`zslide::table::interrupt`), or erased. Read
/// at boot only: a parameter save stalls bank 2's reads.
pub fn interruptions_region() -> &'static [u8] {
    region(
        core::ptr::addr_of!(__zsib_start),
        core::ptr::addr_of!(__zsib_size),
    )
}

/// The link's RTT channel pair.
pub struct RttLink {
    up: UpChannel,
    down: DownChannel,
}

impl LinkIo for RttLink {
    fn read(&mut self, buf: &mut [u8]) -> usize {
        self.down.read(buf)
    }
    fn write(&mut self, bytes: &[u8]) -> usize {
        // NoBlockTrim: as much as fits; the station sends the rest later.
        self.up.write(bytes)
    }
}

/// Sets up RTT: defmt on up channel 0, the link on channel pair 1. Call
/// once, first thing at boot (defmt output before it is lost).
pub fn init_rtt() -> RttLink {
    let ch = rtt_target::rtt_init! {
        up: {
            0: {
                size: 1024,
                mode: ChannelMode::NoBlockSkip,
                name: "defmt"
            }
            1: {
                size: 1024,
                mode: ChannelMode::NoBlockTrim,
                name: "zslide-link"
            }
        }
        down: {
            0: {
                size: 16,
                name: "unused"
            }
            1: {
                size: 128,
                name: "zslide-link"
            }
        }
    };
    rtt_target::set_defmt_channel(ch.up.0);
    RttLink {
        up: ch.up.1,
        down: ch.down.1,
    }
}
