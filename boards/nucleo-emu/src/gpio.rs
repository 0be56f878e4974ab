//! GPIO ports A..G (RM0433 §11.4): mode, type, speed, pull, alternate
//! function, output data (ODR through BSRR) and the input lines the world
//! drives. A pin reads its output level when it is an output, the world's
//! level when it is an input, and its pull (or 0) when nothing drives it.

use crate::Violation;

#[derive(Clone, Default)]
pub struct Port {
    pub moder: u32,
    pub otyper: u32,
    pub ospeedr: u32,
    pub pupdr: u32,
    pub odr: u32,
    pub afr: [u32; 2],
    /// Levels the world drives on the pins (inputs).
    pub ext: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PinMode {
    Input,
    Output,
    Alternate(u8),
    Analog,
}

impl Port {
    /// Reset state (RM0433 §11.4.1): every pin analog, except the debug
    /// pins of ports A and B.
    pub fn reset(port: usize) -> Self {
        let moder = match port {
            0 => 0xABFF_FFFF,
            1 => 0xFFFF_FEBF,
            _ => 0xFFFF_FFFF,
        };
        Self {
            moder,
            ..Default::default()
        }
    }

    pub fn mode(&self, n: u8) -> PinMode {
        match (self.moder >> (2 * n)) & 0b11 {
            0b00 => PinMode::Input,
            0b01 => PinMode::Output,
            0b10 => {
                PinMode::Alternate(((self.afr[usize::from(n / 8)] >> (4 * (n % 8))) & 0xF) as u8)
            }
            _ => PinMode::Analog,
        }
    }

    pub fn idr(&self) -> u32 {
        let mut v = 0;
        for n in 0..16u8 {
            let level = match self.mode(n) {
                PinMode::Output => self.odr >> n & 1,
                PinMode::Input | PinMode::Alternate(_) => self.ext >> n & 1,
                PinMode::Analog => 0,
            };
            v |= level << n;
        }
        v
    }

    /// The level an output pin drives (None: not an output).
    pub fn driven(&self, n: u8) -> Option<bool> {
        (self.mode(n) == PinMode::Output).then_some(self.odr >> n & 1 != 0)
    }

    pub fn read(&self, reg: &str) -> Option<u32> {
        Some(match reg {
            "moder" => self.moder,
            "otyper" => self.otyper,
            "ospeedr" => self.ospeedr,
            "pupdr" => self.pupdr,
            "idr" => self.idr(),
            "odr" => self.odr,
            "afrl" => self.afr[0],
            "afrh" => self.afr[1],
            _ => return None,
        })
    }

    pub fn write(&mut self, reg: &str, v: u32) -> Result<(), Violation> {
        match reg {
            "moder" => self.moder = v,
            "otyper" => self.otyper = v & 0xFFFF,
            "ospeedr" => self.ospeedr = v,
            "pupdr" => self.pupdr = v,
            "odr" => self.odr = v & 0xFFFF,
            "bsrr" => {
                // Set wins when both bits of a pin are written (RM0433 §11.4.7).
                self.odr = (self.odr & !(v >> 16)) | (v & 0xFFFF);
            }
            "afrl" => self.afr[0] = v,
            "afrh" => self.afr[1] = v,
            "idr" => return Err(Violation::rule("GPIO IDR is read-only")),
            _ => return Err(Violation::Unmodelled),
        }
        Ok(())
    }
}
