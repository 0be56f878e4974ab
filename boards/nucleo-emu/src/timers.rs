//! General-purpose timers TIM2..TIM5 (RM0433 §39): up-counting with
//! prescaler and auto-reload (both loaded at the update event), compare
//! flags, input captures, and TIM4's encoder mode 3, all as functions of
//! emulated time, so a counter read is the count at that instant.

use crate::Violation;

pub const SR_UIF: u32 = 1 << 0;

pub struct Tim {
    pub name: &'static str,
    pub width32: bool,
    pub cr1: u32,
    pub cr2: u32,
    pub smcr: u32,
    pub dier: u32,
    pub sr: u32,
    pub ccmr: [u32; 2],
    pub ccer: u32,
    pub psc: u32,
    psc_active: u32,
    pub arr: u32,
    arr_active: u32,
    pub ccr: [u32; 4],
    /// Counter value `cnt_base` at kernel tick `base_ticks` (counting
    /// since then when CEN is set).
    cnt_base: u32,
    base_ticks: u64,
    /// Encoder mode: the count is the world's, plus this offset.
    enc_offset: u32,
}

impl Tim {
    pub fn new(name: &'static str, width32: bool) -> Self {
        let arr = if width32 { u32::MAX } else { 0xFFFF };
        Self {
            name,
            width32,
            cr1: 0,
            cr2: 0,
            smcr: 0,
            dier: 0,
            sr: 0,
            ccmr: [0; 2],
            ccer: 0,
            psc: 0,
            psc_active: 0,
            arr,
            arr_active: arr,
            ccr: [0; 4],
            cnt_base: 0,
            base_ticks: 0,
            enc_offset: 0,
        }
    }

    pub fn enabled(&self) -> bool {
        self.cr1 & 1 != 0
    }
    pub fn encoder_mode(&self) -> bool {
        self.smcr & 0b111 == 0b011
    }
    fn period(&self) -> u64 {
        u64::from(self.arr_active) + 1
    }
    fn mask(&self) -> u32 {
        if self.width32 {
            u32::MAX
        } else {
            0xFFFF
        }
    }

    /// The counter at kernel tick `ticks` (`spindle`: the world's encoder
    /// count then, for the encoder mode).
    pub fn cnt_at(&self, ticks: u64, spindle: u32) -> u32 {
        if self.encoder_mode() {
            if !self.enabled() {
                return self.cnt_base;
            }
            let c = u64::from(spindle.wrapping_add(self.enc_offset)) % self.period();
            return c as u32;
        }
        if !self.enabled() {
            return self.cnt_base;
        }
        let counts = ticks.saturating_sub(self.base_ticks) / (u64::from(self.psc_active) + 1);
        ((u64::from(self.cnt_base) + counts) % self.period()) as u32
    }

    /// The first kernel tick ≥ `from` at which the counter is `value`
    /// (it gets there by counting), if it runs.
    pub fn tick_of(&self, value: u32, from: u64) -> Option<u64> {
        if !self.enabled() || self.encoder_mode() || u64::from(value) >= self.period() {
            return None;
        }
        let div = u64::from(self.psc_active) + 1;
        let from = from.max(self.base_ticks);
        let counts = (from - self.base_ticks).div_ceil(div);
        let now = (u64::from(self.cnt_base) + counts) % self.period();
        let ahead = (u64::from(value) + self.period() - now) % self.period();
        Some(self.base_ticks + (counts + ahead) * div)
    }

    /// An update event at tick `ticks` (overflow or UG): the preloaded
    /// prescaler and (with ARPE) period take effect, the count restarts.
    pub fn update(&mut self, ticks: u64) {
        self.psc_active = self.psc;
        self.arr_active = self.arr;
        self.cnt_base = 0;
        self.base_ticks = ticks;
    }

    pub fn read(&mut self, reg: &str, ticks: u64, spindle: u32) -> Option<u32> {
        Some(match reg {
            "cr1" => self.cr1,
            "cr2" => self.cr2,
            "smcr" => self.smcr,
            "dier" => self.dier,
            "sr" => self.sr,
            "ccmr1_input" => self.ccmr[0],
            "ccmr2_input" => self.ccmr[1],
            "ccer" => self.ccer,
            "cnt" => self.cnt_at(ticks, spindle),
            "psc" => self.psc,
            "arr" => self.arr,
            "ccr1" => self.read_ccr(0),
            "ccr2" => self.read_ccr(1),
            "ccr3" => self.read_ccr(2),
            "ccr4" => self.read_ccr(3),
            _ => return None,
        })
    }

    /// Reading a capture register clears its flag (RM0433 §39.4.15).
    fn read_ccr(&mut self, ch: usize) -> u32 {
        if self.is_input(ch) {
            self.sr &= !(1 << (ch + 1));
        }
        self.ccr[ch]
    }

    /// Channel `ch` (0-based) configured as an input (CCxS ≠ 00).
    pub fn is_input(&self, ch: usize) -> bool {
        (self.ccmr[ch / 2] >> (8 * (ch % 2))) & 0b11 != 0
    }
    pub fn channel_on(&self, ch: usize) -> bool {
        self.ccer & (1 << (4 * ch)) != 0
    }

    /// A capture on channel `ch` of counter value `value`: the register
    /// and its flag (only when the channel is an enabled input).
    pub fn capture(&mut self, ch: usize, value: u32) -> bool {
        if !(self.is_input(ch) && self.channel_on(ch)) {
            return false;
        }
        self.ccr[ch] = value;
        self.sr |= 1 << (ch + 1);
        true
    }

    /// The interrupt line: a flag set whose DIER enable is set.
    pub fn irq_level(&self) -> bool {
        self.sr & self.dier & 0x1F != 0
    }

    pub fn write(&mut self, reg: &str, v: u32, ticks: u64, spindle: u32) -> Result<(), Violation> {
        match reg {
            "cr1" => {
                let was = self.enabled();
                if !was && v & 1 != 0 {
                    // Counting starts from the count held.
                    self.base_ticks = ticks;
                } else if was && v & 1 == 0 {
                    self.cnt_base = self.cnt_at(ticks, spindle);
                }
                self.cr1 = v & 0x3FF;
            }
            "cr2" => self.cr2 = v,
            "smcr" => {
                if self.enabled() {
                    return Err(Violation::rule(format!(
                        "{}_SMCR written while the counter runs (slave mode must be set with CEN = 0)",
                        self.name
                    )));
                }
                self.smcr = v;
            }
            "dier" => self.dier = v,
            // rc_w0: a 0 clears, a 1 leaves the flag.
            "sr" => self.sr &= v,
            "egr" => {
                if v & 1 != 0 {
                    self.update(ticks);
                    if self.cr1 & (1 << 2) == 0 {
                        self.sr |= SR_UIF; // URS = 0: UG sets UIF
                    }
                }
            }
            "ccmr1_input" => self.write_ccmr(0, v)?,
            "ccmr2_input" => self.write_ccmr(1, v)?,
            "ccer" => self.ccer = v,
            "cnt" => {
                if self.encoder_mode() {
                    self.enc_offset = v.wrapping_sub(spindle);
                } else {
                    self.cnt_base = v & self.mask();
                    self.base_ticks = ticks;
                }
            }
            "psc" => self.psc = v & 0xFFFF,
            "arr" => {
                self.arr = v & self.mask();
                // Without ARPE the new period applies at once.
                if self.cr1 & (1 << 7) == 0 {
                    let now = self.cnt_at(ticks, spindle);
                    self.arr_active = self.arr;
                    self.cnt_base = now;
                    self.base_ticks = ticks;
                }
            }
            "ccr1" => self.ccr[0] = v & self.mask(),
            "ccr2" => self.ccr[1] = v & self.mask(),
            "ccr3" => self.ccr[2] = v & self.mask(),
            "ccr4" => self.ccr[3] = v & self.mask(),
            _ => return Err(Violation::Unmodelled),
        }
        Ok(())
    }

    /// RM0433 §39.4.7: CCxS is writable only while the channel is off.
    fn write_ccmr(&mut self, i: usize, v: u32) -> Result<(), Violation> {
        for half in 0..2 {
            let ch = 2 * i + half;
            let old = (self.ccmr[i] >> (8 * half)) & 0b11;
            let new = (v >> (8 * half)) & 0b11;
            if old != new && self.channel_on(ch) {
                return Err(Violation::rule(format!(
                    "{}_CCMR{}: CC{}S changed while CC{}E = 1 (RM0433: writable only when the channel is off)",
                    self.name,
                    i + 1,
                    ch + 1,
                    ch + 1
                )));
            }
        }
        self.ccmr[i] = v;
        Ok(())
    }
}
