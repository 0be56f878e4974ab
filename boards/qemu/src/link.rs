//! What the emulated board adds for the host link and the flash regions:
//! the table and parameter regions of `memory.x`, the CMSDK UART0 that
//! carries the link's frames (QEMU's first `-serial`), and the choice of
//! run: the checked run (`scenario::TICKS` ticks, default) or a link session that runs
//! until QEMU is stopped (semihosting command line `link`, as
//! `cargo xtask test` starts it for the end-to-end link test).
//!
//! | block | base | use |
//! |---|---|---|
//! | CMSDK APB UART0 | `0x4000_4000` | link frames (`-serial`), polled by the background |

use cortex_m_semihosting::nr;
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
    static __zspb_start: u8;
    static __zspb_size: u8;
    static __zsib_start: u8;
    static __zsib_size: u8;
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

/// The interruption region (`ZSIB`, 0x0038_1000, 4 KiB): the part's
/// interruption block (`zslide::table::interrupt`), or zeros.
pub fn interruptions_region() -> &'static [u8] {
    region(
        core::ptr::addr_of!(__zsib_start),
        core::ptr::addr_of!(__zsib_size),
    )
}

/// Whether QEMU was started with the semihosting argument `link` (a link
/// session instead of the checked run).
pub fn session_requested() -> bool {
    argument(b"link")
}

/// Whether the semihosting command line holds the word `word`.
pub fn argument(word: &[u8]) -> bool {
    let mut buf = [0u8; CMDLINE];
    let found = words(&mut buf).any(|w| w == word);
    found
}

/// The number `N` of the command line's word `key=N` (`key` with its `=`),
/// if it is there and a number.
pub fn value(key: &[u8]) -> Option<u32> {
    let mut buf = [0u8; CMDLINE];
    let n = words(&mut buf)
        .find_map(|w| w.strip_prefix(key))
        .filter(|d| !d.is_empty() && d.len() <= 9)
        .and_then(|d| {
            d.iter().try_fold(0u32, |n, &c| {
                c.is_ascii_digit().then(|| n * 10 + u32::from(c - b'0'))
            })
        });
    n
}

/// The longest command line read (the power-cut runs' is the longest).
const CMDLINE: usize = 128;

/// The semihosting command line's words (none if it cannot be read).
fn words(buf: &mut [u8; CMDLINE]) -> impl Iterator<Item = &[u8]> {
    // SYS_GET_CMDLINE: a two-word block (buffer, length), the length
    // replaced by the command line's.
    let mut block = [buf.as_mut_ptr() as usize, buf.len() - 1];
    // SAFETY: the semihosting call writes at most `block[1]` bytes into
    // `buf` and updates `block[1]`, through the pointers it is given (taken
    // from `&mut` borrows); both live until the call returns.
    let r = unsafe { cortex_m_semihosting::syscall1(nr::GET_CMDLINE, block.as_mut_ptr() as usize) };
    let len = if r == 0 { block[1].min(buf.len()) } else { 0 };
    buf[..len].split(|&b| b == b' ').filter(|w| !w.is_empty())
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

/// A scripted host inside the checked run: it hands the station one
/// request frame at a time and collects the reply, so that the run arms a
/// capture at boot (the loop tick records 1024 samples while it is being
/// checked, and `cargo xtask isr-cost` counts the recording) and reads
/// samples back at the end.
pub struct Script {
    tx: [u8; zslide::link::proto::MAX_REQUEST],
    tx_len: usize,
    tx_at: usize,
    rx: heapless::Vec<u8, { zslide::link::proto::MAX_FRAME }>,
    seq: u16,
}

impl Script {
    pub const fn new() -> Self {
        Self {
            tx: [0; zslide::link::proto::MAX_REQUEST],
            tx_len: 0,
            tx_at: 0,
            rx: heapless::Vec::new(),
            seq: 0,
        }
    }

    /// Queues `req` for the station.
    pub fn send(&mut self, req: &zslide::link::proto::Request) {
        self.seq = self.seq.wrapping_add(1);
        let mut out = [0u8; zslide::link::proto::MAX_REQUEST];
        let n = zslide::link::proto::encode(self.seq, req, &mut out).map_or(0, <[u8]>::len);
        self.tx[..n].copy_from_slice(&out[..n]);
        self.tx_len = n;
        self.tx_at = 0;
        self.rx.clear();
    }

    /// The reply to the last request, once complete.
    pub fn reply(&mut self) -> Option<zslide::link::proto::Reply> {
        if self.rx.last() != Some(&0) {
            return None;
        }
        let n = self.rx.len() - 1;
        let r = zslide::link::proto::decode(&mut self.rx[..n], u32::MAX).ok();
        self.rx.clear();
        r.filter(|(seq, _)| *seq == self.seq).map(|(_, r)| r)
    }
}

impl LinkIo for Script {
    // Checked access only: `Station::poll` calls these, and `cargo xtask
    // no-panic` holds it (and so them) to the handlers' rule.
    fn read(&mut self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        for b in buf.iter_mut() {
            match self.tx.get(self.tx_at).filter(|_| self.tx_at < self.tx_len) {
                Some(&v) => *b = v,
                None => break,
            }
            self.tx_at += 1;
            n += 1;
        }
        n
    }
    fn write(&mut self, bytes: &[u8]) -> usize {
        let mut n = 0;
        for &b in bytes {
            if self.rx.push(b).is_err() {
                break;
            }
            n += 1;
        }
        n
    }
}
