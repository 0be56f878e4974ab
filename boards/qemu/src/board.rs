//! The parts of the mps2-an386 the images use: the device interrupt vector
//! table, two CMSDK APB timers, the dual timer and the watchdog (QEMU
//! `hw/arm/mps2.c`, `hw/timer/cmsdk-apb-timer.c`,
//! `hw/timer/cmsdk-apb-dualtimer.c`, `hw/watchdog/cmsdk-apb-watchdog.c`;
//! ARM DDI0479C §4.4, §4.5, §4.6).
//!
//! | block | base | IRQ | use |
//! |---|---|---|---|
//! | CMSDK APB timer 0 | `0x4000_0000` | 8 | loop tick |
//! | CMSDK APB timer 1 | `0x4000_1000` | 9 | machine events (X, index), lower priority |
//! | CMSDK dual timer | `0x4000_2000` | 10 | `zslide-qemu-watchdog`: index events (timer 1), a free-running clock (timer 2) |
//! | CMSDK APB watchdog | `0x4000_8000` | NMI | `zslide-qemu-watchdog`: the watchdog |
//! | FPGAIO LED0 | `0x4002_8000` | - | bit 0: the amplifier-enable output (the NUCLEO's PG4) |
//!
//! All count PCLK = 25 MHz (`SYSCLK_FRQ`) down; the timers raise their
//! interrupt when they reach 0.

use cortex_m::interrupt::InterruptNumber;

/// PCLK of the APB timers, Hz.
pub const PCLK_HZ: u32 = 25_000_000;

/// Device interrupts, numbered as the NVIC sees them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(clippy::upper_case_acronyms, dead_code)] // the full IRQ map, used or not
#[repr(u16)]
pub enum Interrupt {
    TIMER0 = 8,
    TIMER1 = 9,
    DUALTIMER = 10,
}
// `#[interrupt]` checks handler names against `interrupt::NAME`, as it does
// against a PAC's enum.
pub use cortex_m_rt::interrupt;
pub use Interrupt as interrupt;

// SAFETY: the discriminants are the mps2-an386 IRQ numbers listed above,
// all below the 32 lines the vector table provides.
unsafe impl InterruptNumber for Interrupt {
    fn number(self) -> u16 {
        self as u16
    }
}

/// One entry of the device vector table: a handler or a reserved word.
pub union Vector {
    handler: unsafe extern "C" fn(),
    reserved: usize,
}

extern "C" {
    fn TIMER0();
    fn TIMER1();
    fn DUALTIMER();
}

/// The device part of the vector table (IRQ 0..31). `device.x` binds every
/// handler named here to `DefaultHandler` unless the image defines it.
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
pub static __INTERRUPTS: [Vector; 32] = {
    const R: Vector = Vector { reserved: 0 };
    let mut v = [R; 32];
    v[8] = Vector { handler: TIMER0 };
    v[9] = Vector { handler: TIMER1 };
    v[10] = Vector { handler: DUALTIMER };
    v
};

/// A CMSDK APB timer's register block.
#[derive(Clone, Copy)]
pub struct CmsdkTimer {
    base: usize,
}

const CTRL: usize = 0x00;
const RELOAD: usize = 0x08;
const INTCLEAR: usize = 0x0C;
const CTRL_ENABLE: u32 = 1 << 0;
const CTRL_IRQ_ENABLE: u32 = 1 << 3;

pub const TIMER0_LOOP: CmsdkTimer = CmsdkTimer { base: 0x4000_0000 };
pub const TIMER1_EVENTS: CmsdkTimer = CmsdkTimer { base: 0x4000_1000 };

/// Writes a word register of one of the blocks in the table above.
fn reg_write(addr: usize, value: u32) {
    // SAFETY: every caller passes a block base of the table above plus one
    // of that block's word register offsets: a volatile word write there
    // has no effect on memory Rust owns.
    unsafe { core::ptr::write_volatile(addr as *mut u32, value) }
}

/// Reads a word register (one without read side effects) of one of the
/// blocks in the table above.
fn reg_read(addr: usize) -> u32 {
    // SAFETY: as for `reg_write`; the registers read (a timer's VALUE)
    // change nothing when read.
    unsafe { core::ptr::read_volatile(addr as *const u32) }
}

impl CmsdkTimer {
    fn write(self, offset: usize, value: u32) {
        reg_write(self.base + offset, value);
    }

    /// Starts a periodic interrupt every `period` PCLK cycles (≥ 2).
    pub fn start_periodic(self, period: u32) {
        let reload = period.max(2) - 1;
        self.write(CTRL, 0);
        self.write(RELOAD, reload);
        self.write(INTCLEAR, 1);
        self.write(CTRL, CTRL_ENABLE | CTRL_IRQ_ENABLE);
    }

    pub fn stop(self) {
        self.write(CTRL, 0);
        self.write(INTCLEAR, 1);
    }

    pub fn clear_interrupt(self) {
        self.write(INTCLEAR, 1);
    }
}

/// The CMSDK dual timer: timer 1 periodic with its interrupt (IRQ 10),
/// timer 2 free-running as a 25 MHz clock.
pub mod dualtimer {
    const BASE: usize = 0x4000_2000;
    const TIMER2: usize = 0x20;
    const LOAD: usize = 0x00;
    const VALUE: usize = 0x04;
    const CONTROL: usize = 0x08;
    const INTCLR: usize = 0x0C;
    const EN: u32 = 1 << 7;
    const PERIODIC: u32 = 1 << 6;
    const INT_EN: u32 = 1 << 5;
    const SIZE_32: u32 = 1 << 1;

    fn write(offset: usize, value: u32) {
        super::reg_write(BASE + offset, value);
    }
    fn read(offset: usize) -> u32 {
        super::reg_read(BASE + offset)
    }

    /// Timer 1: an interrupt every `period` PCLK cycles (≥ 2).
    pub fn start_periodic(period: u32) {
        write(CONTROL, 0);
        write(LOAD, period.max(2) - 1);
        write(INTCLR, 1);
        write(CONTROL, EN | PERIODIC | INT_EN | SIZE_32);
    }
    pub fn stop() {
        write(CONTROL, 0);
        write(INTCLR, 1);
    }
    pub fn clear_interrupt() {
        write(INTCLR, 1);
    }
    /// Timer 2 counts down from 2³² − 1, free-running, no interrupt.
    pub fn start_clock() {
        write(TIMER2 + CONTROL, 0);
        write(TIMER2 + LOAD, u32::MAX);
        write(TIMER2 + CONTROL, EN | SIZE_32);
    }
    /// PCLK cycles since [`start_clock`] (wraps after 172 s).
    pub fn clock() -> u32 {
        u32::MAX - read(TIMER2 + VALUE)
    }
}

/// The CMSDK APB watchdog: counts WDOGCLK (PCLK, 25 MHz) down from its
/// load value; at 0 it raises its interrupt, wired to the NMI on this
/// board, and reloads (a second expiry with the interrupt still raised
/// would reset the chip when RESEN is set; not used). A write to INTCLR
/// clears the interrupt and reloads the count: the feed.
pub mod watchdog {
    const BASE: usize = 0x4000_8000;
    const LOAD: usize = 0x000;
    const CONTROL: usize = 0x008;
    const INTCLR: usize = 0x00C;
    const LOCK: usize = 0xC00;
    const UNLOCK_KEY: u32 = 0x1ACC_E551;
    const INT_EN: u32 = 1 << 0;

    fn write(offset: usize, value: u32) {
        super::reg_write(BASE + offset, value);
    }

    /// Starts it with a timeout of `counts` PCLK cycles, interrupt (NMI)
    /// enabled, registers locked again.
    pub fn start(counts: u32) {
        write(LOCK, UNLOCK_KEY);
        write(LOAD, counts);
        write(CONTROL, INT_EN);
        write(LOCK, 0);
    }
    /// Reloads the count and clears a raised interrupt.
    pub fn feed() {
        write(LOCK, UNLOCK_KEY);
        write(INTCLR, 1);
        write(LOCK, 0);
    }
    pub fn stop() {
        write(LOCK, UNLOCK_KEY);
        write(CONTROL, 0);
        write(INTCLR, 1);
        write(LOCK, 0);
    }
}

/// The amplifier-enable output: bit 0 of the FPGAIO's LED0 register
/// (QEMU `hw/misc/mps2-fpgaio.c`: a register that reads back what was
/// written), the emulated board's stand-in for the NUCLEO's PG4. The loop
/// tick drives it, the plant's amplifier follows it, and the fault paths
/// (HardFault, panic) drop it before anything else.
pub mod enable {
    const LED0: usize = 0x4002_8000;

    pub fn set(high: bool) {
        super::reg_write(LED0, u32::from(high));
    }
    /// What the output holds (read back from the device).
    pub fn is_high() -> bool {
        super::reg_read(LED0) & 1 != 0
    }
}
