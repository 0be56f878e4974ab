//! The three converters, decoding the bits on their pins by their
//! datasheets, not by the firmware's drivers:
//!
//! * AD5791 (amplifier DAC): 24-bit frames framed by SYNC; bit 23 R/W̄,
//!   bits 22..20 the register, 19..0 data; data taken on SCLK's falling
//!   edge (CPOL 0 / CPHA 1, or CPOL 1 / CPHA 0); a frame that is not 24
//!   clocks is ignored by the chip (datasheet, "Serial interface"); a read
//!   request's register comes out on SDO in the next frame; SCLK ≤ 35 MHz.
//!   Control register: RBUF 1, OPGND 2, DACTRI 3, BIN/2sC 4, SDODIS 5; power-on
//!   value OPGND | DACTRI (output clamped to ground, tristated).
//! * AD4020 (gauge ADC) in three-wire mode (SDI high): a conversion starts
//!   at CNV's rising edge and takes t_CONV ≤ 320 ns; with CNV low the
//!   result is shifted out MSB first on SDO, data valid on SCK's rising
//!   edge (CPOL 0 / CPHA 0); SCK ≤ 71 MHz. With the status bits enabled,
//!   the frame is 20 result bits (two's complement), then OV, then the
//!   fixed pattern 0b010 (`docs/BOARD.md`).
//! * AD5686 (quad DAC): 24-bit frames framed by SYNC; command bits 23..20,
//!   DAC-select mask 19..16, data 15..0; data taken on SCLK's falling
//!   edge; SCLK ≤ 50 MHz; LDAC low updates the DAC registers.

use crate::spi::Format;
use crate::Violation;

/// A datasheet's SPI clock modes: (CPOL, CPHA) pairs it samples correctly.
fn check(name: &str, f: Format, modes: &[(bool, bool)], max_sck: u64) -> Result<(), Violation> {
    if !modes.contains(&(f.cpol, f.cpha)) {
        return Err(Violation::rule(format!(
            "{name}: SPI clock mode CPOL = {}, CPHA = {} (datasheet: data taken on the {} edge of SCLK)",
            u8::from(f.cpol),
            u8::from(f.cpha),
            if modes.contains(&(false, false)) { "rising" } else { "falling" }
        )));
    }
    if f.bits != 8 && f.bits != 24 && f.bits != 12 {
        return Err(Violation::rule(format!(
            "{name}: data frames of {} bits do not add up to its 24-bit frame",
            f.bits
        )));
    }
    if f.lsb_first {
        return Err(Violation::rule(format!(
            "{name}: LSB first (the chip shifts MSB first)"
        )));
    }
    if f.sck_hz > max_sck {
        return Err(Violation::rule(format!(
            "{name}: SCLK {:.1} MHz above its {:.0} MHz maximum",
            f.sck_hz as f64 / 1e6,
            max_sck as f64 / 1e6
        )));
    }
    Ok(())
}

/// A SYNC-framed 24-bit shift register (AD5791, AD5686).
#[derive(Default)]
struct Framed {
    selected: bool,
    bits: u32,
    shift_in: u64,
    shift_out: u32,
}

impl Framed {
    fn select(&mut self, out: u32) {
        self.selected = true;
        self.bits = 0;
        self.shift_in = 0;
        self.shift_out = out;
    }
    fn clock(&mut self, v: u32, bits: u32) -> u32 {
        self.shift_in = (self.shift_in << bits) | u64::from(v);
        self.bits += bits;
        let out = (self.shift_out >> (24 - bits.min(24))) & ((1 << bits) - 1);
        self.shift_out <<= bits;
        out
    }
}

pub struct Ad5791 {
    frame: Framed,
    pub dac: u32,
    pub ctrl: u32,
    pending_read: Option<u32>,
    pub writes: u64,
    pub aborted: u64,
}

impl Ad5791 {
    pub fn new() -> Self {
        Self {
            frame: Framed::default(),
            dac: 0,
            ctrl: 0b1100,
            pending_read: None,
            writes: 0,
            aborted: 0,
        }
    }
    /// Output volts (10 V reference span: V = 10 V · code / 2¹⁹ in two's
    /// complement): 0 while clamped (OPGND) or tristated (DACTRI).
    pub fn volts(&self) -> f64 {
        if self.ctrl & 0b1100 != 0 {
            return 0.0;
        }
        let code = if self.ctrl & (1 << 4) != 0 {
            self.dac as i32 - (1 << 19) // offset binary
        } else {
            ((self.dac << 12) as i32) >> 12
        };
        10.0 * f64::from(code) / f64::from(1u32 << 19)
    }
    pub fn sync(&mut self, low: bool) -> Result<(), Violation> {
        if low && !self.frame.selected {
            let out = self.pending_read.take().unwrap_or(0);
            self.frame.select(out);
        } else if !low && self.frame.selected {
            self.frame.selected = false;
            if self.frame.bits != 24 {
                self.aborted += 1;
                return Err(Violation::rule(format!(
                    "AD5791: SYNC framed {} SCLK cycles (datasheet: a write is 24; the chip ignores this frame)",
                    self.frame.bits
                )));
            }
            let f = self.frame.shift_in as u32 & 0xFF_FFFF;
            let reg = (f >> 20) & 0b111;
            let data = f & 0xF_FFFF;
            if f & (1 << 23) != 0 {
                let v = match reg {
                    1 => self.dac,
                    2 => self.ctrl,
                    _ => 0,
                };
                if self.ctrl & (1 << 5) == 0 {
                    self.pending_read = Some((1 << 23) | (reg << 20) | v);
                }
            } else {
                match reg {
                    1 => {
                        self.dac = data;
                        self.writes += 1;
                    }
                    2 => self.ctrl = data & 0x3FE,
                    0 | 3 | 4 => {}
                    _ => {}
                }
            }
        }
        Ok(())
    }
    pub fn clock(&mut self, f: Format, v: u32) -> Result<u32, Violation> {
        check("AD5791", f, &[(false, true), (true, false)], 35_000_000)?;
        if !self.frame.selected {
            return Err(Violation::rule(
                "AD5791: SCLK with SYNC high (the frame goes nowhere)",
            ));
        }
        Ok(self.frame.clock(v, f.bits))
    }
}

pub struct Ad5686 {
    frame: Framed,
    pub input: [u16; 4],
    pub output: [u16; 4],
    pub frames: u64,
}

impl Ad5686 {
    pub fn new() -> Self {
        Self {
            frame: Framed::default(),
            input: [0; 4],
            output: [0; 4],
            frames: 0,
        }
    }
    pub fn sync(&mut self, low: bool) -> Result<(), Violation> {
        if low && !self.frame.selected {
            self.frame.select(0);
        } else if !low && self.frame.selected {
            self.frame.selected = false;
            if self.frame.bits != 24 {
                return Err(Violation::rule(format!(
                    "AD5686: SYNC framed {} SCLK cycles (datasheet: 24)",
                    self.frame.bits
                )));
            }
            let f = self.frame.shift_in as u32;
            let cmd = (f >> 20) & 0xF;
            let mask = (f >> 16) & 0xF;
            let data = f as u16;
            self.frames += 1;
            for ch in 0..4 {
                if mask & (1 << ch) != 0 {
                    match cmd {
                        0b0001 => self.input[ch] = data,
                        0b0011 => {
                            self.input[ch] = data;
                            self.output[ch] = data;
                        }
                        0b0010 => self.output[ch] = self.input[ch],
                        _ => {}
                    }
                }
            }
        }
        Ok(())
    }
    /// LDAC low: every input register to its output.
    pub fn ldac(&mut self) {
        self.output = self.input;
    }
    pub fn clock(&mut self, f: Format, v: u32) -> Result<u32, Violation> {
        check("AD5686", f, &[(false, true), (true, false)], 50_000_000)?;
        if !self.frame.selected {
            return Err(Violation::rule("AD5686: SCLK with SYNC high"));
        }
        self.frame.clock(v, f.bits);
        Ok(0)
    }
}

pub struct Ad4020 {
    /// The conversion result shifting out, and bits left in it.
    result: u32,
    left: u32,
    /// When the last conversion started (CNV rising) and whether CNV is high.
    pub cnv_high: bool,
    converted_at: u64,
    /// The SDO line stuck (a broken bus): reads all ones.
    pub broken: bool,
    pub conversions: u64,
    pub reads: u64,
}

/// t_CONV, ps.
const T_CONV_PS: u64 = 320_000;

impl Ad4020 {
    pub fn new() -> Self {
        Self {
            result: 0,
            left: 0,
            cnv_high: false,
            converted_at: 0,
            broken: false,
            conversions: 0,
            reads: 0,
        }
    }
    /// CNV rising at `t`: converts `code` (20-bit two's complement) with
    /// its over-range flag.
    pub fn convert(&mut self, t: u64, code: i32, overrange: bool) {
        self.cnv_high = true;
        self.converted_at = t;
        self.result = ((code as u32 & 0xF_FFFF) << 4) | (u32::from(overrange) << 3) | 0b010;
        self.left = 24;
        self.conversions += 1;
    }
    pub fn clock(&mut self, f: Format, t: u64) -> Result<u32, Violation> {
        check("AD4020", f, &[(false, false), (true, true)], 71_000_000)?;
        if self.cnv_high {
            return Err(Violation::rule(
                "AD4020: SCK while CNV is high (three-wire mode: SDO is high-impedance until CNV falls)",
            ));
        }
        if t < self.converted_at + T_CONV_PS {
            return Err(Violation::rule(
                "AD4020: read before t_CONV (320 ns) after CNV",
            ));
        }
        if self.broken {
            return Ok((1 << f.bits) - 1);
        }
        if self.conversions == 0 {
            return Err(Violation::rule(
                "AD4020 read with no conversion ever started (CNV never rose: TIM3 CH1 PWM on PC6, AF2)",
            ));
        }
        if self.left < f.bits {
            return Err(Violation::rule(format!(
                "AD4020: {} more SCK cycles than the 24-bit result holds (one read per conversion)",
                f.bits - self.left
            )));
        }
        self.left -= f.bits;
        if self.left == 0 {
            self.reads += 1;
        }
        Ok((self.result >> self.left) & ((1 << f.bits) - 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fmt(cpol: bool, cpha: bool, bits: u32, sck_hz: u64) -> Format {
        Format {
            cpol,
            cpha,
            bits,
            lsb_first: false,
            sck_hz,
        }
    }

    /// Clocks a 24-bit frame in three bytes between SYNC edges.
    fn frame(d: &mut Ad5791, f: u32) -> Result<u32, Violation> {
        d.sync(true)?;
        let mut out = 0;
        for k in (0..3).rev() {
            out = (out << 8) | d.clock(fmt(false, true, 8, 25_000_000), (f >> (8 * k)) & 0xFF)?;
        }
        d.sync(false)?;
        Ok(out)
    }

    /// AD5791 datasheet: control register write (0b010, RBUF) releases the
    /// output; code 0x80000 in two's complement is −full scale, −10 V on
    /// the board's ±10 V span; the read-back comes in the next frame.
    #[test]
    fn ad5791_decodes_the_datasheet_frames() {
        let mut d = Ad5791::new();
        assert_eq!(d.volts(), 0.0, "power-on: clamped");
        frame(&mut d, (0b001 << 20) | 0x8_0000).unwrap();
        frame(&mut d, (0b010 << 20) | 0b10).unwrap();
        assert_eq!(d.volts(), -10.0);
        frame(&mut d, (0b001 << 20) | 0x4_0000).unwrap();
        assert_eq!(d.volts(), 5.0);
        frame(&mut d, (1 << 23) | (0b010 << 20)).unwrap();
        let back = frame(&mut d, 0).unwrap();
        assert_eq!(back, (1 << 23) | (0b010 << 20) | 0b10);
    }

    #[test]
    fn ad5791_refuses_a_short_frame_and_the_wrong_clock_mode() {
        let mut d = Ad5791::new();
        d.sync(true).unwrap();
        d.clock(fmt(false, true, 8, 25_000_000), 0x10).unwrap();
        d.clock(fmt(false, true, 8, 25_000_000), 0x00).unwrap();
        assert!(matches!(d.sync(false), Err(Violation::Rule(r)) if r.contains("16 SCLK")));
        d.sync(true).unwrap();
        assert!(
            matches!(d.clock(fmt(false, false, 8, 25_000_000), 0), Err(Violation::Rule(r)) if r.contains("CPHA = 0"))
        );
        assert!(
            matches!(d.clock(fmt(false, true, 8, 50_000_000), 0), Err(Violation::Rule(r)) if r.contains("35 MHz"))
        );
    }

    /// AD4020 with status bits: 20-bit two's complement result, OV, then
    /// 0b010; read in mode 0 after CNV falls and t_CONV has passed.
    #[test]
    fn ad4020_shifts_out_its_conversion_after_cnv() {
        let mut a = Ad4020::new();
        a.convert(0, -52_429, false);
        let f = fmt(false, false, 8, 50_000_000);
        assert!(a.clock(f, 1_000_000).is_err(), "CNV still high");
        a.cnv_high = false;
        assert!(a.clock(f, 100_000).is_err(), "before t_CONV");
        let mut frame = 0;
        for _ in 0..3 {
            frame = (frame << 8) | a.clock(f, 1_000_000).unwrap();
        }
        assert_eq!(frame, (((-52_429i32) as u32 & 0xF_FFFF) << 4) | 0b010);
        assert!(a.clock(f, 1_000_000).is_err(), "a 25th clock");
        assert!(
            matches!(a.clock(fmt(false, true, 8, 50_000_000), 1_000_000), Err(Violation::Rule(r)) if r.contains("CPHA = 1"))
        );
    }
}
