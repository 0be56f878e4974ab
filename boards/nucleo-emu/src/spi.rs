//! The SPI block of the STM32H7 (RM0433 §50) as a master: configuration
//! (CFG1/CFG2 only while SPE = 0), a transfer of TSIZE data frames started
//! by CSTART, TXP/RXP/EOT, and each frame shifted to the attached converter
//! at the SCK rate the kernel clock and MBR give, in the clock mode CFG2
//! sets, so the converter can refuse what its datasheet does not accept.

use crate::Violation;

/// The wire format of one data frame as the converter sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Format {
    pub cpol: bool,
    pub cpha: bool,
    pub bits: u32,
    pub lsb_first: bool,
    pub sck_hz: u64,
}

pub struct Spi {
    pub name: &'static str,
    pub cr1: u32,
    pub cr2: u32,
    pub cfg1: u32,
    pub cfg2: u32,
    pub ier: u32,
    /// Frames moved in the current transfer.
    sent: u32,
    /// Received frames and when each is complete (ps).
    rx: std::collections::VecDeque<(u32, u64)>,
    /// When the shift register is free for the next frame (ps).
    busy_until: u64,
    eot: bool,
    ovr: bool,
    pub frames: u64,
}

const CR1_SPE: u32 = 1 << 0;
const CR1_CSTART: u32 = 1 << 9;
const SR_RXP: u32 = 1 << 0;
const SR_TXP: u32 = 1 << 1;
const SR_EOT: u32 = 1 << 3;
const SR_TXTF: u32 = 1 << 4;
const SR_OVR: u32 = 1 << 6;
const SR_TXC: u32 = 1 << 12;
/// RX FIFO depth in data frames (SPI1..3: 16 bytes; SPI4..6: 8).
const FIFO: usize = 8;

impl Spi {
    pub fn new(name: &'static str) -> Self {
        Self {
            name,
            cr1: 0,
            cr2: 0,
            cfg1: 0x0007_0007,
            cfg2: 0,
            ier: 0,
            sent: 0,
            rx: Default::default(),
            busy_until: 0,
            eot: false,
            ovr: false,
            frames: 0,
        }
    }
    fn enabled(&self) -> bool {
        self.cr1 & CR1_SPE != 0
    }
    fn started(&self) -> bool {
        self.enabled() && self.cr1 & CR1_CSTART != 0
    }
    fn tsize(&self) -> u32 {
        self.cr2 & 0xFFFF
    }

    pub fn format(&self, kernel_hz: u64) -> Format {
        let mbr = (self.cfg1 >> 28) & 0b111;
        Format {
            cpol: self.cfg2 & (1 << 25) != 0,
            cpha: self.cfg2 & (1 << 24) != 0,
            bits: (self.cfg1 & 0x1F) + 1,
            lsb_first: self.cfg2 & (1 << 23) != 0,
            sck_hz: kernel_hz >> (mbr + 1),
        }
    }

    pub fn read_sr(&self, t: u64) -> u32 {
        let mut sr = 0;
        if self.rx.front().is_some_and(|&(_, at)| at <= t) {
            sr |= SR_RXP;
        }
        if self.started() && self.sent < self.tsize() && t >= self.busy_until {
            sr |= SR_TXP;
        }
        if self.started() && self.sent >= self.tsize() {
            sr |= SR_TXTF;
        }
        if self.eot && t >= self.busy_until {
            sr |= SR_EOT | SR_TXC;
        } else if !self.started() {
            sr |= SR_TXC;
        }
        if self.ovr {
            sr |= SR_OVR;
        }
        sr
    }

    pub fn read(&mut self, reg: &str, t: u64) -> Result<Option<u32>, Violation> {
        Ok(Some(match reg {
            "cr1" => self.cr1,
            "cr2" => self.cr2,
            "cfg1" => self.cfg1,
            "cfg2" => self.cfg2,
            "ier" => self.ier,
            "sr" => self.read_sr(t),
            "rxdr8" => match self.rx.front() {
                Some(&(v, at)) if at <= t => {
                    self.rx.pop_front();
                    v
                }
                _ => {
                    return Err(Violation::rule(format!(
                    "{}_RXDR read with RXP = 0 (no received frame: the read returns stale data)",
                    self.name
                )))
                }
            },
            _ => return Ok(None),
        }))
    }

    /// A write; `Some(frame)` when it puts a data frame on the wire (the
    /// caller exchanges it with the converter and hands the reply to
    /// [`Spi::received`]).
    pub fn write(&mut self, reg: &str, v: u32, t: u64) -> Result<Option<u32>, Violation> {
        let locked = |what: &str| {
            Violation::rule(format!(
                "{}_{what} written while SPE = 1 (RM0433 §50.4.8: configuration only with the SPI disabled)",
                self.name
            ))
        };
        match reg {
            "cr1" => {
                if self.enabled() && v & CR1_SPE == 0 {
                    // Disabling ends the transfer and flushes the FIFOs.
                    self.rx.clear();
                    self.sent = 0;
                    self.eot = false;
                }
                if v & CR1_CSTART != 0 && v & CR1_SPE == 0 && !self.enabled() {
                    return Err(Violation::rule(format!(
                        "{}_CR1: CSTART with SPE = 0 (RM0433 §50.4.9: a transfer starts only with the SPI enabled)",
                        self.name
                    )));
                }
                if !self.enabled() && v & CR1_SPE != 0 {
                    self.sent = 0;
                    self.eot = false;
                    self.busy_until = t;
                }
                self.cr1 = v;
            }
            "cr2" => {
                if self.enabled() {
                    return Err(locked("CR2 (TSIZE)"));
                }
                self.cr2 = v;
            }
            "cfg1" => {
                if self.enabled() {
                    return Err(locked("CFG1"));
                }
                self.cfg1 = v;
            }
            "cfg2" => {
                if self.enabled() {
                    return Err(locked("CFG2"));
                }
                if v & (1 << 22) == 0 {
                    return Err(Violation::rule(format!(
                        "{}_CFG2: not master (the board's converters are slaves)",
                        self.name
                    )));
                }
                self.cfg2 = v;
            }
            "ier" => self.ier = v,
            "ifcr" => {
                if v & SR_EOT != 0 {
                    self.eot = false;
                }
                if v & SR_OVR != 0 {
                    self.ovr = false;
                }
            }
            "txdr8" => {
                if !self.started() {
                    return Err(Violation::rule(format!(
                        "{}_TXDR written with no transfer started (SPE and CSTART): the frame never leaves",
                        self.name
                    )));
                }
                if self.sent >= self.tsize() {
                    return Err(Violation::rule(format!(
                        "{}_TXDR: more data than TSIZE = {}",
                        self.name,
                        self.tsize()
                    )));
                }
                if t < self.busy_until {
                    return Err(Violation::rule(format!(
                        "{}_TXDR written with TXP = 0",
                        self.name
                    )));
                }
                return Ok(Some(v & 0xFF));
            }
            _ => return Err(Violation::Unmodelled),
        }
        Ok(None)
    }

    /// The frame sent at `t` took `frame_ps` on the wire; its reply is
    /// readable when it ends.
    pub fn received(&mut self, reply: u32, t: u64, frame_ps: u64) {
        let done = t.max(self.busy_until) + frame_ps;
        self.busy_until = done;
        self.sent += 1;
        self.frames += 1;
        if self.rx.len() >= FIFO {
            self.ovr = true;
        } else {
            self.rx.push_back((reply, done));
        }
        if self.sent >= self.tsize() {
            self.eot = true;
        }
    }
}
