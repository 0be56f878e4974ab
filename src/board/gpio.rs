//! GPIO pins by port and number, on the register layout every STM32H7 port
//! shares (RM0433 §11.4). The PAC gives ports A, B and C-K different Rust
//! types; one small raw accessor keeps the pin map a single table of
//! constants (`super::pins`) and lets the panic handler reach the
//! amplifier-enable pin without owning anything.

use core::convert::Infallible;
use core::ptr::{read_volatile, write_volatile};

/// GPIO ports: their register blocks are 0x400 apart from GPIOA.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Port {
    A = 0,
    B,
    C,
    D,
    E,
    F,
    G,
}

const GPIOA_BASE: usize = 0x5802_0000;
const MODER: usize = 0x00;
const OTYPER: usize = 0x04;
const OSPEEDR: usize = 0x08;
const PUPDR: usize = 0x0C;
const IDR: usize = 0x10;
const BSRR: usize = 0x18;
const AFRL: usize = 0x20;

/// A pin of a port; `n` < 16 (all constants in `super::pins` are).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pin {
    pub port: Port,
    pub n: u8,
}

/// Pin configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Input with the given pull (0 none, 1 up, 2 down).
    Input(u8),
    /// Push-pull output, initial level.
    Output(bool),
    /// Alternate function number, push-pull, very high speed.
    Alternate(u8),
    /// Analog (ADC input): no pull, digital input off.
    Analog,
}

impl Port {
    const fn base(self) -> usize {
        GPIOA_BASE + 0x400 * self as usize
    }
    /// Reads the port's 16 input lines at once.
    pub fn read(self) -> u16 {
        // SAFETY: IDR of a GPIO port of the STM32H743 memory map; reading it
        // has no side effects.
        unsafe { read_volatile((self.base() + IDR) as *const u32) as u16 }
    }
}

impl Pin {
    pub const fn new(port: Port, n: u8) -> Self {
        Self { port, n: n & 15 }
    }

    fn reg(self, offset: usize) -> *mut u32 {
        (self.port.base() + offset) as *mut u32
    }

    /// Read-modify-write of a `width`-bit field of this pin.
    ///
    /// Callers configure pins from `main` before the interrupts that use
    /// them are unmasked, so the read-modify-write cannot race.
    fn set_field(self, offset: usize, width: u32, index: u32, value: u32) {
        let shift = index * width;
        let mask = ((1u32 << width) - 1) << shift;
        // SAFETY: `offset` is a configuration register of a GPIO port of the
        // STM32H743 memory map; only this pin's field changes.
        unsafe {
            let r = self.reg(offset);
            write_volatile(r, (read_volatile(r) & !mask) | ((value << shift) & mask));
        }
    }

    /// Configures the pin. The port's clock must be on (`clocks::enable_gpio`).
    pub fn configure(self, mode: Mode) {
        let n = u32::from(self.n);
        match mode {
            Mode::Input(pull) => {
                self.set_field(PUPDR, 2, n, u32::from(pull));
                self.set_field(MODER, 2, n, 0b00);
            }
            Mode::Output(high) => {
                // Level first, so the pin never glitches to the other one.
                self.set(high);
                self.set_field(OTYPER, 1, n, 0);
                self.set_field(OSPEEDR, 2, n, 0b01);
                self.set_field(MODER, 2, n, 0b01);
            }
            Mode::Alternate(af) => {
                let (reg, index) = if n < 8 { (AFRL, n) } else { (AFRL + 4, n - 8) };
                self.set_field(reg, 4, index, u32::from(af));
                self.set_field(OTYPER, 1, n, 0);
                self.set_field(OSPEEDR, 2, n, 0b11);
                self.set_field(MODER, 2, n, 0b10);
            }
            Mode::Analog => {
                self.set_field(PUPDR, 2, n, 0);
                self.set_field(MODER, 2, n, 0b11);
            }
        }
    }

    /// Drives an output pin. Atomic (BSRR), so safe from any priority.
    pub fn set(self, high: bool) {
        let bit = if high {
            1u32 << self.n
        } else {
            1u32 << (self.n + 16)
        };
        // SAFETY: BSRR of a GPIO port: a write-only set/reset register whose
        // write touches only the pins whose bits are set.
        unsafe { write_volatile(self.reg(BSRR), bit) }
    }

    pub fn is_high(self) -> bool {
        self.port.read() & (1 << self.n) != 0
    }
}

/// An output pin as embedded-hal 1.0 sees it (chip selects, LDAC, enables).
#[derive(Clone, Copy, Debug)]
pub struct Output(pub Pin);

impl embedded_hal::digital::ErrorType for Output {
    type Error = Infallible;
}

impl embedded_hal::digital::OutputPin for Output {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.0.set(false);
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.0.set(true);
        Ok(())
    }
}
