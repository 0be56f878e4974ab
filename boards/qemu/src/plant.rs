//! The simulated world of the QEMU image: the project's one plant model
//! (`zslide-plant`: the Model 15 slide and motor with its coil inductance
//! and the 3150 Hz coil-frame mode, the ×10 amplifier with its 8 A limit and
//! trip, the capacitance gauge with the modern gauge's noise and the ADC's
//! quantisation), the same code `host-sim` steps, behind `SpiDevice` models
//! of the converters that speak the chips' frames.
//!
//! The slide steps with the exact zero-order-hold matrices that
//! `build.rs` generated from the same parameters with the same code (the
//! image has no matrix exponential); every step this image takes is one of
//! those or composed of their power-of-two entries, and
//! [`Plant::missing_steps`] proves it at the end of the run.
//!
//! This is the world, not firmware: `f64` (soft float on the M4F,
//! deterministic), stepped in the loop-timer interrupt after the firmware's
//! tick, which `cargo xtask isr-cost` does not count (it measures the
//! firmware's entry points).

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use embedded_hal::spi::{ErrorKind, ErrorType, Operation, SpiDevice};
use zslide_plant::slide::st;
use zslide_plant::{gauge, Amplifier, AmplifierParams, Gauge, GaugeParams, ZSlide, ZSlideParams};

/// The discretisations of the slide model `build.rs` generated:
/// `STEPS: [Step; N]`.
mod steps {
    use zslide_plant::slide::{Mats, Step};
    include!(concat!(env!("OUT_DIR"), "/plant_steps.rs"));
}

/// Time from the loop-tick event to the end of its DAC frame, ns: the
/// NUCLEO's estimate (`scenarios/*.toml`, `loop.dac_latency_ns`), so the
/// loop sees the board's delay here too.
pub const DAC_LATENCY_NS: u64 = 8_500;
/// Seed of the gauge noise.
const SEED: u64 = 1983;

/// The slide, its motor and amplifier, and the gauge.
pub struct Plant {
    slide: ZSlide,
    amp: Amplifier,
    gauge: Gauge,
    /// Plant time, ns.
    t_ns: u64,
    period_ns: u64,
    /// Amplifier input now applied, V.
    v_in: f64,
    /// The gauge's conversion at the last sampling instant, published to
    /// the ADC's SPI model when the plant moves, so that a read costs the
    /// firmware what a real converter read would, not a soft-float
    /// conversion (it would distort `cargo xtask isr-cost`).
    code: i32,
    overrange: bool,
    /// Makes the gauge bus fail, for the fault-reaction check.
    pub gauge_bus_broken: bool,
}

impl Plant {
    /// The slide at rest at `x_in`, amplifier off, modern gauge; the loop
    /// ticks at `tick_hz` (the generated steps are for 20 kHz).
    pub fn new(x_in: f64, tick_hz: u32) -> Self {
        let mut slide = ZSlide::new(ZSlideParams::model15());
        slide.preload(&steps::STEPS);
        slide.x[st::Z] = x_in;
        let mut p = Self {
            slide,
            amp: Amplifier::new(AmplifierParams::default()),
            gauge: Gauge::new(GaugeParams::modern(), SEED),
            t_ns: 0,
            period_ns: 1_000_000_000 / u64::from(tick_hz.max(1)),
            v_in: 0.0,
            code: 0,
            overrange: false,
            gauge_bus_broken: false,
        };
        p.convert();
        p
    }

    /// CNV at the plant's time: the gauge (with its noise) converted.
    fn convert(&mut self) {
        let v = self.gauge.volts(self.t_ns, self.slide.gauge_position_in());
        (self.code, self.overrange) = gauge::adc_convert(v);
        self.publish_gauge();
    }

    /// Advances one loop period after a tick that wrote `dac_volts` and set
    /// the amplifier enable: the old output for the DAC's latency, then the
    /// new one (zero-order hold), then the next sample.
    pub fn step(&mut self, dac_volts: f64, amplifier_enabled: bool) {
        let latency = DAC_LATENCY_NS.min(self.period_ns);
        self.amp.advance(&mut self.slide, latency, self.v_in, 0.0);
        self.v_in = dac_volts;
        self.amp.set_enabled(amplifier_enabled);
        self.amp
            .advance(&mut self.slide, self.period_ns - latency, self.v_in, 0.0);
        self.t_ns += self.period_ns;
        self.convert();
    }

    /// The gauge code the ADC converted at the last sampling instant.
    pub fn gauge_code(&self) -> i32 {
        self.code
    }

    /// Steps the slide could not take (zero when the generated table
    /// covers every step: see the module doc).
    pub fn missing_steps(&self) -> u64 {
        self.slide.missing_steps()
    }
}

/// What the converters see of the world: statics, so the firmware's real
/// drivers (`zslide::drivers::{Ad4020, Ad5791}`) can own their bus objects
/// while the plant (stepped by the same handler) reads and writes them.
static GAUGE_FRAME: AtomicU32 = AtomicU32::new(0);
static GAUGE_BROKEN: AtomicBool = AtomicBool::new(false);
/// AD5791 DAC register (20-bit two's complement) and control register.
static DAC_REG: AtomicU32 = AtomicU32::new(0);
/// Power-on: OPGND and DACTRI set (output clamped and tristated).
static DAC_CTRL: AtomicU32 = AtomicU32::new(0b1100);
static DAC_WRITES: AtomicU32 = AtomicU32::new(0);

impl Plant {
    /// Puts the gauge's current conversion on the ADC's output register.
    pub fn publish_gauge(&self) {
        // AD4020 frame: bits 23..4 result, bit 3 OV, bits 2..0 = 0b010.
        let frame = ((self.code as u32 & 0xF_FFFF) << 4) | (u32::from(self.overrange) << 3) | 0b010;
        GAUGE_FRAME.store(frame, Ordering::Relaxed);
        GAUGE_BROKEN.store(self.gauge_bus_broken, Ordering::Relaxed);
    }
}

#[derive(Debug)]
pub struct BusFault;
impl embedded_hal::spi::Error for BusFault {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

fn frame_of(b: &[u8]) -> u32 {
    b.iter().take(3).fold(0, |f, &x| (f << 8) | u32::from(x))
}
fn put_frame(b: &mut [u8], f: u32) {
    for (i, x) in b.iter_mut().take(3).enumerate() {
        *x = (f >> (16 - 8 * i)) as u8;
    }
}

/// The gauge ADC's SPI device (AD4020 class): every 3-byte read shifts out
/// the last conversion. A broken bus reads all ones (fails the pattern).
pub struct GaugeSpi;
impl ErrorType for GaugeSpi {
    type Error = BusFault;
}
impl SpiDevice for GaugeSpi {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), BusFault> {
        let frame = if GAUGE_BROKEN.load(Ordering::Relaxed) {
            0xFF_FFFF
        } else {
            GAUGE_FRAME.load(Ordering::Relaxed)
        };
        for op in ops {
            match op {
                Operation::Read(b) | Operation::TransferInPlace(b) => put_frame(b, frame),
                Operation::Transfer(r, _) => put_frame(r, frame),
                Operation::Write(_) | Operation::DelayNs(_) => {}
            }
        }
        Ok(())
    }
}

/// The amplifier DAC's SPI device (AD5791 class): write frames set the DAC
/// or control register; a read request returns the register in the next
/// frame.
pub struct DacSpi {
    pending: Option<u32>,
}
impl DacSpi {
    pub const fn new() -> Self {
        Self { pending: None }
    }
}
impl ErrorType for DacSpi {
    type Error = BusFault;
}
impl DacSpi {
    /// One 24-bit frame in, the reply to the previous read request out.
    fn frame(&mut self, f: u32) -> u32 {
        let reply = self.pending.take().unwrap_or(0);
        let reg = (f >> 20) & 0b111;
        if f & (1 << 23) != 0 {
            self.pending = Some(
                match reg {
                    0b001 => DAC_REG.load(Ordering::Relaxed),
                    0b010 => DAC_CTRL.load(Ordering::Relaxed),
                    _ => 0,
                } | (reg << 20),
            );
        } else {
            match reg {
                0b001 => {
                    DAC_REG.store(f & 0xF_FFFF, Ordering::Relaxed);
                    DAC_WRITES.fetch_add(1, Ordering::Relaxed);
                }
                0b010 => DAC_CTRL.store(f & 0x3E, Ordering::Relaxed),
                _ => {}
            }
        }
        reply
    }
}
impl SpiDevice for DacSpi {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), BusFault> {
        for op in ops {
            match op {
                Operation::Write(b) => {
                    self.frame(frame_of(b));
                }
                Operation::TransferInPlace(b) => {
                    let r = self.frame(frame_of(b));
                    put_frame(b, r);
                }
                Operation::Transfer(r, w) => {
                    let x = self.frame(frame_of(w));
                    put_frame(r, x);
                }
                Operation::Read(b) => {
                    let x = self.frame(0);
                    put_frame(b, x);
                }
                Operation::DelayNs(_) => {}
            }
        }
        Ok(())
    }
}

/// The amplifier DAC's output as the plant sees it.
pub struct Dac;

impl Dac {
    /// Output volts: 0 while clamped (OPGND) or tristated (DACTRI).
    pub fn volts() -> f64 {
        if Self::clamped() {
            0.0
        } else {
            let code = ((DAC_REG.load(Ordering::Relaxed) << 12) as i32) >> 12;
            10.0 * f64::from(code) / f64::from(1u32 << 19)
        }
    }
    pub fn clamped() -> bool {
        DAC_CTRL.load(Ordering::Relaxed) & 0b1100 != 0
    }
    pub fn writes() -> u32 {
        DAC_WRITES.load(Ordering::Relaxed)
    }
}
