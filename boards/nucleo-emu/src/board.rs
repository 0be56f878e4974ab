//! The NUCLEO-H743ZI2 as the firmware sees it: every register access
//! named by the PAC's register map (`build.rs`) and given to the model
//! of its peripheral; the wiring of `docs/BOARD.md` between the models
//! (chip selects, CNV, captures, the X latch, the amplifier); the events
//! of emulated time (the loop timer, the spindle, the X feed, the
//! watchdog) and the interrupt lines into the NVIC.

use crate::adc::Adc;
use crate::clocks::{Pwr, Rcc};
use crate::converters::{Ad4020, Ad5686, Ad5791};
use crate::flash::{Flash, BANK2_BASE, BANK2_SIZE};
use crate::gpio::{PinMode, Port};
use crate::scs::Scs;
use crate::spi::Spi;
use crate::system::{Dbgmcu, Exti, Iwdg, Syscfg};
use crate::timers::Tim;
use crate::world::World;
use crate::Violation;

mod regs {
    include!(concat!(env!("OUT_DIR"), "/regs.rs"));
}

pub const PPB: u32 = 0xE000_0000;

/// IRQ numbers (RM0433 table 137) of the lines the board drives.
pub const IRQ_EXTI2: usize = 8;
pub const IRQ_TIM2: usize = 28;
pub const IRQ_TIM3: usize = 29;
/// How long an interrupt line may be high with its IRQ disabled before
/// the run stops (boot enables them microseconds after their sources).
const UNSERVED_PS: u64 = 1_000_000_000;

/// Pins of `docs/BOARD.md` (port index, pin).
const PA: usize = 0;
const PB: usize = 1;
const PC: usize = 2;
const PD: usize = 3;
const PE: usize = 4;
const PF: usize = 5;
const PG: usize = 6;
const AMP_ENABLE: (usize, u8) = (PG, 4);
const AMP_FAULT: (usize, u8) = (PG, 9);
const AMP_DAC_SYNC: (usize, u8) = (PD, 14);
const QUAD_DAC_SYNC: (usize, u8) = (PA, 4);
const QUAD_DAC_LDAC: (usize, u8) = (PG, 5);
const ARM_BUTTON: (usize, u8) = (PC, 13);
const GAUGE_CNV: (usize, u8, u8) = (PC, 6, 2);
const INDEX_TIME: (usize, u8, u8) = (PA, 0, 1);
const INDEX_COUNT: (usize, u8, u8) = (PB, 8, 2);
const ENC_A: (usize, u8, u8) = (PD, 12, 2);
const ENC_B: (usize, u8, u8) = (PD, 13, 2);
const ENC_A_TIME: (usize, u8, u8) = (PB, 10, 1);
const ENC_B_TIME: (usize, u8, u8) = (PB, 11, 1);
/// SPI pins (SCK, MISO, MOSI) and their alternate function.
const SPI1_PINS: [(usize, u8, u8); 3] = [(PA, 5, 5), (PA, 6, 5), (PB, 5, 5)];
const SPI3_PINS: [(usize, u8, u8); 3] = [(PC, 10, 6), (PC, 11, 6), (PC, 12, 6)];
const SPI4_PINS: [(usize, u8, u8); 3] = [(PE, 12, 5), (PE, 13, 5), (PE, 14, 5)];

/// Statistics the report gives.
#[derive(Default)]
pub struct Stats {
    pub slices: u64,
    pub loop_ticks: u64,
    pub max_tick_latency_ps: u64,
    pub tim3_pended_at: Option<u64>,
    pub index_pulses: u64,
    pub dac_volts_max: f64,
}

pub struct Board {
    /// Emulated time, ps, and the time one instruction takes.
    pub t: u64,
    pub cycle_ps: u64,
    pub instructions: u64,
    /// The CPU runs until this time, then the events are processed.
    pub until: u64,
    pub sleeping: bool,
    /// The address of a WFI that ended the last block counted.
    pub wfi_ran: Option<u32>,
    pub violation: Option<String>,
    pub rcc: Rcc,
    pwr: Pwr,
    pub flash: Flash,
    pub gpio: [Port; 11],
    pub tim2: Tim,
    pub tim3: Tim,
    pub tim4: Tim,
    pub tim5: Tim,
    spi1: Spi,
    spi3: Spi,
    spi4: Spi,
    pub exti: Exti,
    syscfg: Syscfg,
    pub iwdg: Iwdg,
    dbgmcu: Dbgmcu,
    pub scs: Scs,
    pub dac: Ad5791,
    pub quad: Ad5686,
    pub adc: Ad4020,
    /// ADC1 (the centring image's tachometers).
    pub adc1: Adc,
    pub world: World,
    /// Exceptions active (numbers), innermost last.
    pub active: Vec<u32>,
    /// TIM3 kernel ticks processed (exclusive), and the spindle's.
    tim3_seen: u64,
    index_seen: u64,
    x_level_until: u64,
    /// Since when each board interrupt line has been high with its IRQ
    /// disabled in the NVIC.
    line_high_since: [Option<u64>; 3],
    enc_captured: [Option<u64>; 2],
    /// Registers the image touched: address -> (name, accesses).
    pub touched: std::collections::BTreeMap<u32, (String, u64)>,
    pub gauge_break_at: Option<u64>,
    pub stats: Stats,
}

fn lookup(addr: u32) -> Option<(&'static str, &'static str, u32)> {
    let i = regs::REGS.partition_point(|r| r.0 <= addr);
    let &(a, p, n) = regs::REGS.get(i.checked_sub(1)?)?;
    (addr - a < 4).then(|| (p, n.split('|').next().unwrap_or(n), a))
}

/// The register's name, for messages.
pub fn name_of(addr: u32) -> String {
    match lookup(addr) {
        Some((p, n, _)) => format!("{p}.{}", n.to_uppercase()),
        None if (PPB..PPB + 0x10_0000).contains(&addr) => format!("PPB+{:#x}", addr - PPB),
        None => "no register of the H743".into(),
    }
}

impl Board {
    pub fn new(bank2: Vec<u8>, vtor: u32) -> Self {
        let mut gpio: [Port; 11] = Default::default();
        for (i, p) in gpio.iter_mut().enumerate() {
            *p = Port::reset(i);
        }
        Self {
            t: 0,
            cycle_ps: 1_000_000_000_000 / crate::clocks::HSI_HZ,
            instructions: 0,
            until: 0,
            sleeping: false,
            wfi_ran: None,
            violation: None,
            rcc: Rcc::new(false),
            pwr: Pwr::new(),
            flash: Flash::new(bank2),
            gpio,
            tim2: Tim::new("TIM2", true),
            tim3: Tim::new("TIM3", false),
            tim4: Tim::new("TIM4", false),
            tim5: Tim::new("TIM5", true),
            spi1: Spi::new("SPI1"),
            spi3: Spi::new("SPI3"),
            spi4: Spi::new("SPI4"),
            exti: Exti::default(),
            syscfg: Syscfg::default(),
            iwdg: Iwdg::new(),
            dbgmcu: Dbgmcu::default(),
            scs: Scs::new(vtor),
            dac: Ad5791::new(),
            quad: Ad5686::new(),
            adc: Ad4020::new(),
            adc1: Adc::new(),
            world: World::new(),
            active: Vec::new(),
            tim3_seen: 0,
            index_seen: 0,
            x_level_until: 0,
            line_high_since: [None; 3],
            enc_captured: [None; 2],
            touched: Default::default(),
            gauge_break_at: None,
            stats: Stats::default(),
        }
    }

    fn timer_ps(&self) -> u64 {
        1_000_000_000_000 / self.rcc.apb1_timer_hz().max(1)
    }
    /// APB1 timer kernel ticks at `t`.
    fn ticks_at(&self, t: u64) -> u64 {
        t / self.timer_ps()
    }
    fn spindle_count(t: u64) -> u32 {
        World::spindle(t).0 as u32
    }

    /// Stops the run with a violation (the first one is kept).
    pub fn stop(&mut self, v: Violation, addr: u32, write: Option<u32>) {
        if self.violation.is_some() {
            return;
        }
        let what = match write {
            Some(v) => format!("write {v:#010x} to"),
            None => "read of".into(),
        };
        let msg = match v {
            Violation::Unmodelled => format!(
                "unmodelled register access: {what} {} at {addr:#010x}",
                name_of(addr)
            ),
            Violation::Rule(r) => format!(
                "RM0433/datasheet rule broken: {r} ({what} {} at {addr:#010x})",
                name_of(addr)
            ),
        };
        self.violation = Some(msg);
        self.until = self.t;
    }

    fn note(&mut self, addr: u32) {
        let e = self
            .touched
            .entry(addr)
            .or_insert_with(|| (name_of(addr), 0));
        e.1 += 1;
    }

    pub fn read(&mut self, addr: u32, size: usize) -> u32 {
        match self.try_read(addr, size) {
            Ok(v) => v,
            Err(v) => {
                self.stop(v, addr, None);
                0
            }
        }
    }

    pub fn write(&mut self, addr: u32, size: usize, v: u32) {
        if let Err(e) = self.try_write(addr, size, v) {
            self.stop(e, addr, Some(v));
        }
        // A write may change an interrupt line: the CPU stops so the
        // NVIC sees it before the next instruction.
        self.until = self.t;
    }

    fn try_read(&mut self, addr: u32, size: usize) -> Result<u32, Violation> {
        self.note(addr);
        let t = self.t;
        if (PPB..PPB + 0x10_0000).contains(&addr) {
            return self.scs.read(addr - PPB, size);
        }
        if (BANK2_BASE..BANK2_BASE + BANK2_SIZE as u32).contains(&addr) {
            return self.flash.read_cells(addr, size, t);
        }
        let (periph, reg, base) = lookup(addr).ok_or(Violation::Unmodelled)?;
        if !self.rcc.clocked(periph) {
            return Err(Violation::rule(format!(
                "{periph} read with its bus clock off (RCC enable bit clear: reads 0)"
            )));
        }
        let shift = 8 * (addr - base);
        let ticks = self.ticks_at(t);
        let spindle = Self::spindle_count(t);
        let v = match periph {
            "RCC" => self.rcc.read(reg),
            "PWR" => self.pwr.read(reg),
            "FLASH" => self.flash.read(reg, t),
            p if p.starts_with("GPIO") => {
                self.inputs();
                self.gpio[usize::from(p.as_bytes()[4] - b'A')].read(reg)
            }
            "TIM2" => {
                self.spindle_captures(t);
                self.tim2.read(reg, ticks, spindle)
            }
            "TIM3" => self.tim3.read(reg, ticks, spindle),
            "TIM4" => self.tim4.read(reg, ticks, spindle),
            "TIM5" => self.tim5.read(reg, ticks, spindle),
            "SPI1" => self.spi1.read(reg, t)?,
            "SPI3" => self.spi3.read(reg, t)?,
            "SPI4" => self.spi4.read(reg, t)?,
            "EXTI" => self.exti.read(reg),
            "ADC1" => self.adc1.read(reg, t),
            "ADC12_COMMON" => self.adc1.read_common(reg),
            "SYSCFG" => self.syscfg.read(reg),
            "IWDG" => self.iwdg.read(reg, t),
            "DBGMCU" => self.dbgmcu.read(reg),
            _ => None,
        };
        v.map(|v| v >> shift).ok_or(Violation::Unmodelled)
    }

    fn try_write(&mut self, addr: u32, size: usize, v: u32) -> Result<(), Violation> {
        self.note(addr);
        let t = self.t;
        if (PPB..PPB + 0x10_0000).contains(&addr) {
            return self.scs.write(addr - PPB, size, v);
        }
        if (BANK2_BASE..BANK2_BASE + BANK2_SIZE as u32).contains(&addr) {
            return self.flash.write_cells(addr, size, v, t);
        }
        let (periph, reg, _) = lookup(addr).ok_or(Violation::Unmodelled)?;
        if !self.rcc.clocked(periph) {
            return Err(Violation::rule(format!(
                "{periph} written with its bus clock off (RCC enable bit clear: the write is lost)"
            )));
        }
        let ticks = self.ticks_at(t);
        let spindle = Self::spindle_count(t);
        match periph {
            "RCC" => {
                let switched = self
                    .rcc
                    .write(reg, v, self.flash.acr, self.pwr.vos1_ready())?;
                if switched {
                    self.cycle_ps = 1_000_000_000_000 / self.rcc.sys_hz().max(1);
                }
            }
            "PWR" => self.pwr.write(reg, v)?,
            "FLASH" => self.flash.write(reg, v, t)?,
            p if p.starts_with("GPIO") => {
                let i = usize::from(p.as_bytes()[4] - b'A');
                let before = self.gpio[i].clone();
                self.gpio[i].write(reg, v)?;
                self.pins_changed(i, &before)?;
            }
            "TIM2" => {
                self.spindle_captures(t);
                self.tim2.write(reg, v, ticks, spindle)?
            }
            "TIM3" => {
                let was = self.tim3.enabled();
                self.tim3.write(reg, v, ticks, spindle)?;
                if !was && self.tim3.enabled() {
                    self.tim3_seen = ticks + 1;
                    // PWM mode 1 with the count below CCR1: OC1REF, and
                    // CNV with it, rises as the counter starts.
                    self.cnv_rises(t);
                }
            }
            "TIM4" => self.tim4.write(reg, v, ticks, spindle)?,
            "TIM5" => self.tim5.write(reg, v, ticks, spindle)?,
            "SPI1" | "SPI3" | "SPI4" => self.spi_write(periph, reg, v)?,
            "EXTI" => self.exti.write(reg, v)?,
            "ADC1" => self.adc1.write(reg, v, t)?,
            "ADC12_COMMON" => self.adc1.write_common(reg, v)?,
            "SYSCFG" => self.syscfg.write(reg, v)?,
            "IWDG" => self.iwdg.write(reg, v, t)?,
            "DBGMCU" => self.dbgmcu.write(reg, v)?,
            _ => return Err(Violation::Unmodelled),
        }
        Ok(())
    }

    fn af_ok(&self, (port, pin, af): (usize, u8, u8)) -> bool {
        self.gpio[port].mode(pin) == PinMode::Alternate(af)
    }

    fn spi_write(&mut self, periph: &str, reg: &str, v: u32) -> Result<(), Violation> {
        let t = self.t;
        let (spi, pins, kernel) = match periph {
            "SPI1" => (&mut self.spi1, SPI1_PINS, self.rcc.pll1_q_hz()),
            "SPI3" => (&mut self.spi3, SPI3_PINS, self.rcc.pll1_q_hz()),
            _ => (&mut self.spi4, SPI4_PINS, self.rcc.pclk2_hz()),
        };
        let Some(frame) = spi.write(reg, v, t)? else {
            return Ok(());
        };
        let f = spi.format(kernel);
        for p in pins {
            if !self.af_ok(p) {
                return Err(Violation::rule(format!(
                    "{periph}: pin P{}{} is not alternate function {} (the converter never sees the frame)",
                    (b'A' + p.0 as u8) as char,
                    p.1,
                    p.2
                )));
            }
        }
        let reply = match periph {
            "SPI1" => self.dac.clock(f, frame)?,
            "SPI3" => self.quad.clock(f, frame)?,
            _ => self.adc.clock(f, t)?,
        };
        let frame_ps = u64::from(f.bits) * 1_000_000_000_000 / f.sck_hz.max(1);
        let spi = match periph {
            "SPI1" => &mut self.spi1,
            "SPI3" => &mut self.spi3,
            _ => &mut self.spi4,
        };
        spi.received(reply, t, frame_ps);
        Ok(())
    }

    /// Output pins that drive something: chip selects, LDAC, the
    /// amplifier's enable.
    fn pins_changed(&mut self, port: usize, before: &Port) -> Result<(), Violation> {
        let now = &self.gpio[port];
        let changed = |(p, n): (usize, u8)| p == port && before.driven(n) != now.driven(n);
        let level = |(p, n): (usize, u8)| self.gpio[p].driven(n);
        if changed(AMP_DAC_SYNC) {
            if let Some(l) = level(AMP_DAC_SYNC) {
                let v_before = self.dac.volts();
                self.dac.sync(!l)?;
                if self.dac.volts() != v_before {
                    let en = self.amp_enabled();
                    self.world.advance(self.t, self.dac.volts(), en);
                    self.stats.dac_volts_max = self.stats.dac_volts_max.max(self.dac.volts().abs());
                }
            }
        }
        if changed(QUAD_DAC_SYNC) {
            if let Some(l) = level(QUAD_DAC_SYNC) {
                self.quad.sync(!l)?;
            }
        }
        if changed(QUAD_DAC_LDAC) && level(QUAD_DAC_LDAC) == Some(false) {
            self.quad.ldac();
        }
        if changed(AMP_ENABLE) {
            let en = self.amp_enabled();
            self.world.advance(self.t, self.dac.volts(), en);
        }
        Ok(())
    }

    pub fn amp_enabled(&self) -> bool {
        self.gpio[AMP_ENABLE.0].driven(AMP_ENABLE.1) == Some(true)
    }

    /// The world's levels on the input pins.
    fn inputs(&mut self) {
        let t = self.t;
        let set = |p: &mut Port, n: u8, on: bool| {
            if on {
                p.ext |= 1 << n;
            } else {
                p.ext &= !(1 << n);
            }
        };
        let button = self.world.button_at(t);
        set(&mut self.gpio[ARM_BUTTON.0], ARM_BUTTON.1, button);
        let fault = self.world.amp_fault();
        set(&mut self.gpio[AMP_FAULT.0], AMP_FAULT.1, fault);
        if t >= self.x_level_until {
            set(&mut self.gpio[PG], 2, false);
        }
    }

    /// TIM2's encoder-edge captures (CH3 = A, CH4 = B, both edges) up to
    /// now: the newest edge of each line, its flag set while unread.
    fn spindle_captures(&mut self, t: u64) {
        for (line, ch, pin, enc) in [
            (0usize, 2usize, ENC_A_TIME, ENC_A),
            (1, 3, ENC_B_TIME, ENC_B),
        ] {
            if !(self.af_ok(pin) && self.af_ok(enc)) {
                continue;
            }
            if let Some((c, at)) = World::last_edge(t, line == 1) {
                if self.enc_captured[line] != Some(c) {
                    self.enc_captured[line] = Some(c);
                    let value = self.tim2.cnt_at(self.ticks_at(at), 0);
                    self.tim2.capture(ch, value);
                }
            }
        }
    }

    /// The next instant something happens on its own (ps).
    pub fn next_event(&self) -> u64 {
        let mut next = self.t + 50_000_000; // at least every 50 µs
        if self.tim3.enabled() {
            let tp = self.timer_ps();
            for v in [0, self.tim3.ccr[0], self.tim3.ccr[1]] {
                if let Some(k) = self.tim3.tick_of(v, self.tim3_seen) {
                    next = next.min(k * tp);
                }
            }
        }
        next = next.min(World::next_index(self.index_seen).1);
        next = next.min(self.world.next_x().0);
        if let Some(e) = self.iwdg.expires_at() {
            next = next.min(e);
        }
        for &(a, b) in &self.world.button {
            for e in [a, b] {
                if e > self.t {
                    next = next.min(e);
                }
            }
        }
        if let Some(b) = self.gauge_break_at {
            if b > self.t {
                next = next.min(b);
            }
        }
        next.max(self.t + 1)
    }

    /// Everything due by now, in time order; then the interrupt lines.
    pub fn events(&mut self) {
        let t = self.t;
        // The loop timer: update (CNV rises), CC1 (CNV falls), CC2 (the
        // loop interrupt).
        while self.tim3.enabled() {
            let tp = self.timer_ps();
            let now = self.ticks_at(t);
            let mut due = None;
            for (i, v) in [0, self.tim3.ccr[0], self.tim3.ccr[1]]
                .into_iter()
                .enumerate()
            {
                if let Some(k) = self.tim3.tick_of(v, self.tim3_seen) {
                    if k <= now && due.is_none_or(|(dk, _)| k < dk) {
                        due = Some((k, i));
                    }
                }
            }
            let Some((k, which)) = due else { break };
            self.tim3_seen = k + 1;
            let at = k * tp;
            match which {
                0 => {
                    self.tim3.update(k);
                    self.tim3.sr |= crate::timers::SR_UIF;
                    // PWM mode 1 on CH1 (OC1M = 110), output enabled, PC6
                    // on AF2: CNV rises at the update.
                    self.cnv_rises(at);
                }
                1 => {
                    self.tim3.sr |= 1 << 1;
                    self.adc.cnv_high = false;
                }
                _ => {
                    self.tim3.sr |= 1 << 2;
                    if self.tim3.dier & (1 << 2) != 0 && self.stats.tim3_pended_at.is_none() {
                        self.stats.tim3_pended_at = Some(at);
                    }
                }
            }
        }
        // The spindle index: its time on TIM2 CH1, the count on TIM4 CH3.
        loop {
            let (ci, at) = World::next_index(self.index_seen);
            if at > t {
                break;
            }
            self.index_seen = at;
            self.stats.index_pulses += 1;
            if self.af_ok(INDEX_TIME) {
                let v = self.tim2.cnt_at(self.ticks_at(at), 0);
                self.tim2.capture(0, v);
            }
            if self.af_ok(INDEX_COUNT) && self.af_ok(ENC_A) && self.af_ok(ENC_B) {
                let v = self.tim4.cnt_at(0, ci as u32);
                self.tim4.capture(2, v);
            }
        }
        // The legacy X feed: the word on PF0..15, the flags on PG0/PG1,
        // then the half-mil strobe's rising edge on PG2.
        loop {
            let (at, word) = self.world.next_x();
            if at > t {
                break;
            }
            self.world.took_x();
            self.gpio[PF].ext = word & 0xFFFF;
            let g = &mut self.gpio[PG];
            g.ext = (g.ext & !0b111) | ((word >> 16) & 0b11) | 0b100;
            self.x_level_until = at + 10_000_000;
            if self.syscfg.port_of(2) == PG as u32 && self.gpio[PG].mode(2) == PinMode::Input {
                self.exti.edge(2, true);
            }
        }
        if let Some(b) = self.gauge_break_at {
            self.adc.broken = t >= b;
        }
        if let Some(e) = self.iwdg.expires_at() {
            if e <= t && self.violation.is_none() {
                self.violation = Some(format!(
                    "watchdog reset at {:.3} ms: IWDG1 not reloaded for {} counts",
                    e as f64 / 1e9,
                    self.iwdg.rlr + 1
                ));
            }
        }
        self.inputs();
        self.lines();
    }

    /// TIM3 CH1 in PWM mode 1 (OC1M = 110), its output enabled and on
    /// PC6 (AF2): CNV rises at `at` and the AD4020 converts the plant.
    fn cnv_rises(&mut self, at: u64) {
        let pwm = (self.tim3.ccmr[0] >> 4) & 0b111 == 0b110 && self.tim3.channel_on(0);
        if pwm && self.af_ok(GAUGE_CNV) && self.tim3.ccr[0] > 0 {
            let en = self.amp_enabled();
            self.world.advance(at, self.dac.volts(), en);
            let (code, ov) = self.world.convert();
            self.adc.convert(at, code, ov);
        }
    }

    /// Level-sensitive interrupt lines into the NVIC: a line high sets its
    /// IRQ pending unless it is pending or active already (ARMv7-M B3.4).
    pub fn lines(&mut self) {
        let t = self.t;
        for (i, (irq, name, level)) in [
            (IRQ_TIM3, "TIM3", self.tim3.irq_level()),
            (IRQ_TIM2, "TIM2", self.tim2.irq_level()),
            (IRQ_EXTI2, "EXTI2", self.exti.irq_level(2)),
        ]
        .into_iter()
        .enumerate()
        {
            // A request the NVIC never takes: the handler's interrupt is
            // not the one enabled (a wrong IRQ number in the image).
            if level && !self.scs.enabled[irq] {
                let since = *self.line_high_since[i].get_or_insert(t);
                if t - since > UNSERVED_PS && self.violation.is_none() {
                    self.violation = Some(format!(
                        "{name} has requested IRQ {irq} for {} ms and the NVIC never enabled it (ISER): its handler never runs",
                        UNSERVED_PS / 1_000_000_000
                    ));
                }
            } else {
                self.line_high_since[i] = None;
            }
        }
        for (irq, level) in [
            (IRQ_TIM3, self.tim3.irq_level()),
            (IRQ_TIM2, self.tim2.irq_level()),
            (IRQ_EXTI2, self.exti.irq_level(2)),
        ] {
            let active = self.active.contains(&(16 + irq as u32));
            if level && !active {
                self.scs.pending[irq] = true;
            }
        }
    }
}
