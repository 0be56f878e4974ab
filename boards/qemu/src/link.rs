//! What the emulated board adds for the host link and the flash regions:
//! the table and parameter regions of `memory.x`, the CMSDK UART0 that
//! carries the link's frames (QEMU's first `-serial`), and the choice of
//! run: the checked 4000-tick run (default) or a link session that runs
//! until QEMU is stopped (semihosting command line `link`, as
//! `cargo xtask test` starts it for the end-to-end link test).
//!
//! | block | base | use |
//! |---|---|---|
//! | CMSDK APB UART0 | `0x4000_4000` | link frames (`-serial`), polled by the background |

use cortex_m_semihosting::nr;
use zslide::link::station::LinkIo;
use zslide::link::tap::{Scope, TapShared};

/// Capture ring: 1024 loop ticks (51 ms at 20 kHz), 24 KiB of RAM.
pub const CAPTURE: usize = 1024;

/// The capture ring (zeros: `.bss`).
static SCOPE: Scope<CAPTURE> = Scope::new();

/// The loop tick's and the background's shared link state.
pub static TAP: TapShared<'static, CAPTURE> = TapShared::new(&SCOPE);

extern "C" {
    static __zsct_start: u8;
    static __zsct_size: u8;
    static __zspb_start: u8;
    static __zspb_size: u8;
}

/// The bytes of a `memory.x` region given its start and size symbols.
fn region(start: *const u8, size: *const u8) -> &'static [u8] {
    // SAFETY: `memory.x` defines both symbols: the start is the region's
    // first byte and the *address* of the size symbol is its length (a
    // linker constant, never dereferenced). The region lies in the 4 MiB
    // SSRAM1 that QEMU maps at 0x0, outside every section of the image, and
    // nothing writes it while the program runs (only QEMU's loader, before
    // reset), so a shared `'static` view of it is sound.
    unsafe { core::slice::from_raw_parts(start, size as usize) }
}

/// The coefficient-table region (`ZSCT`, 0x0030_0000, 512 KiB).
pub fn table_region() -> &'static [u8] {
    region(
        core::ptr::addr_of!(__zsct_start),
        core::ptr::addr_of!(__zsct_size),
    )
}

/// The servo-parameter region (`ZSPB`, 0x0038_0000, 4 KiB).
pub fn params_region() -> &'static [u8] {
    region(
        core::ptr::addr_of!(__zspb_start),
        core::ptr::addr_of!(__zspb_size),
    )
}

/// Whether QEMU was started with the semihosting argument `link` (a link
/// session instead of the checked run).
pub fn session_requested() -> bool {
    let mut buf = [0u8; 64];
    // SYS_GET_CMDLINE: a two-word block (buffer, length), the length
    // replaced by the command line's.
    let mut block = [buf.as_mut_ptr() as usize, buf.len() - 1];
    // SAFETY: the semihosting call writes at most `block[1]` bytes into
    // `buf` and updates `block[1]`; both live until the call returns.
    let r = unsafe { cortex_m_semihosting::syscall(nr::GET_CMDLINE, &mut block) };
    if r != 0 {
        return false;
    }
    let len = block[1].min(buf.len());
    buf[..len].split(|&b| b == b' ').any(|w| w == b"link")
}

/// CMSDK APB UART0 (ARM DDI0479C §4.3; QEMU `hw/char/cmsdk-apb-uart.c`):
/// one byte each way, polled. QEMU holds further input back while the
/// receive register is full, so nothing is lost however slowly the
/// background reads.
pub struct Uart0;

const UART0: usize = 0x4000_4000;
const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const BAUDDIV: usize = 0x10;
const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;

fn rd(offset: usize) -> u32 {
    // SAFETY: a word register of the UART0 block of the mps2-an386 memory
    // map; a volatile read there touches no memory Rust owns.
    unsafe { core::ptr::read_volatile((UART0 + offset) as *const u32) }
}
fn wr(offset: usize, v: u32) {
    // SAFETY: as `rd`.
    unsafe { core::ptr::write_volatile((UART0 + offset) as *mut u32, v) }
}

impl Uart0 {
    /// Enables transmit and receive (the divider is QEMU's minimum; QEMU
    /// moves bytes at the socket's pace whatever it is).
    pub fn new() -> Self {
        wr(BAUDDIV, 16);
        wr(CTRL, CTRL_TX_EN | CTRL_RX_EN);
        Self
    }
}

impl LinkIo for Uart0 {
    fn read(&mut self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        for b in buf.iter_mut() {
            if rd(STATE) & STATE_RX_FULL == 0 {
                break;
            }
            *b = rd(DATA) as u8;
            n += 1;
        }
        n
    }

    fn write(&mut self, bytes: &[u8]) -> usize {
        let mut n = 0;
        for &b in bytes {
            if rd(STATE) & STATE_TX_FULL != 0 {
                break;
            }
            wr(DATA, u32::from(b));
            n += 1;
        }
        n
    }
}
