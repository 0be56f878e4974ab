//! A small model of the Z slide for the QEMU image, with the brief's
//! section 2 numbers: moving mass, viscous air-film friction, the Model 15
//! voice-coil motor behind the ×10 linear amplifier (back-EMF, 8 A limit,
//! coil inductance neglected: L/R = 0.26 ms is 5 ticks), and an amplifier
//! input offset for the integral term to remove. The capacitance gauge reads
//! 1 V/mil into a 20-bit ±10 V ADC.
//!
//! This is the simulated world, not firmware: it uses `f64` (soft float on the
//! M4F, deterministic) and semi-implicit Euler with four sub-steps per tick
//! (12.5 µs against a 3.3 ms mechanical time constant).

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use embedded_hal::spi::{ErrorKind, ErrorType, Operation, SpiDevice};

/// Slide mass, lbf·s²/in (0.194 slug).
const MASS: f64 = 0.194 / 12.0;
/// Air-film viscous friction, lbf·s/in (51.2 lbf·s/ft, eq 4-32).
const FRICTION: f64 = 51.2 / 12.0;
/// Motor force constant, lbf/A (Model 15).
const KF: f64 = 2.9;
/// Back-EMF constant, V·s/in (4.002 V·s/ft).
const KB: f64 = 4.002 / 12.0;
/// Coil resistance, Ω.
const R_COIL: f64 = 1.4;
/// Amplifier voltage gain and current limit.
const AMP_GAIN: f64 = 10.0;
const AMP_LIMIT_A: f64 = 8.0;
/// Gauge codes per inch: 1000 V/in · 2¹⁹ codes / 10 V.
pub const CODES_PER_IN: f64 = 52_428_800.0;
const SUBSTEPS: u32 = 4;

/// The slide, its motor and amplifier, and the gauge.
pub struct Plant {
    /// Position along +Z, inches.
    x: f64,
    /// Velocity, in/s.
    v: f64,
    /// Amplifier input offset, volts.
    offset_v: f64,
    dt: f64,
    /// The gauge's reading of `x`, converted when the plant moves, so that a
    /// read costs the firmware what a real converter read would, not a
    /// soft-float conversion (it would distort `cargo xtask isr-cost`).
    code: i32,
    overrange: bool,
    /// Makes the gauge bus fail, for the fault-reaction check.
    pub gauge_bus_broken: bool,
}

impl Plant {
    pub fn new(x_in: f64, offset_v: f64, tick_hz: u32) -> Self {
        let mut p = Self {
            x: x_in,
            v: 0.0,
            offset_v,
            dt: 1.0 / f64::from(tick_hz) / f64::from(SUBSTEPS),
            code: 0,
            overrange: false,
            gauge_bus_broken: false,
        };
        p.convert();
        p
    }

    fn convert(&mut self) {
        let s = self.x * CODES_PER_IN;
        let r = if s >= 0.0 { s + 0.5 } else { s - 0.5 };
        self.code = (r as i64).clamp(-(1 << 19), (1 << 19) - 1) as i32;
        self.overrange = self.x.abs() * CODES_PER_IN > f64::from(1u32 << 19);
        self.publish_gauge();
    }

    /// Advances one tick with the DAC output held (zero-order hold); the
    /// amplifier drives no current when disabled.
    pub fn step(&mut self, dac_volts: f64, amplifier_enabled: bool) {
        for _ in 0..SUBSTEPS {
            let current = if amplifier_enabled {
                let coil_v = AMP_GAIN * (dac_volts + self.offset_v) - KB * self.v;
                (coil_v / R_COIL).clamp(-AMP_LIMIT_A, AMP_LIMIT_A)
            } else {
                0.0
            };
            let accel = (KF * current - FRICTION * self.v) / MASS;
            self.v += accel * self.dt;
            self.x += self.v * self.dt;
        }
        self.convert();
    }

    /// The gauge code the ADC would convert now (rounded, clamped).
    pub fn gauge_code(&self) -> i32 {
        self.code
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
