//! The parts of the mps2-an386 this image uses: the device interrupt vector
//! table and two CMSDK APB timers (QEMU `hw/arm/mps2.c`, `hw/timer/
//! cmsdk-apb-timer.c`; ARM DDI0479C §4.4).
//!
//! | block | base | IRQ | use |
//! |---|---|---|---|
//! | CMSDK APB timer 0 | `0x4000_0000` | 8 | loop tick |
//! | CMSDK APB timer 1 | `0x4000_1000` | 9 | machine events (X, index), lower priority |
//!
//! Both count PCLK = 25 MHz (`SYSCLK_FRQ`) down from `RELOAD` to 0 and
//! raise their interrupt when they reach 0.

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

impl CmsdkTimer {
    fn write(self, offset: usize, value: u32) {
        // SAFETY: `base` is one of the two timer blocks of the mps2-an386
        // memory map and `offset` one of its word registers: a volatile word
        // write there has no effect on memory Rust owns.
        unsafe { core::ptr::write_volatile((self.base + offset) as *mut u32, value) }
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
