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

use zslide::hw::{AmplifierDac, BusError, GaugeAdc, GaugeSample};

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

impl GaugeAdc for Plant {
    fn read(&mut self) -> Result<GaugeSample, BusError> {
        if self.gauge_bus_broken {
            return Err(BusError);
        }
        Ok(GaugeSample {
            code: self.code,
            overrange: self.overrange,
        })
    }
}

/// The amplifier DAC (AD5791 behaviour at the level of `AmplifierDac`):
/// clamped to ground from power-on until the first write, and once clamped
/// by the firmware it stays clamped.
#[derive(Default)]
pub struct Dac {
    code: i32,
    clamped: bool,
    pub writes: u32,
}

impl Dac {
    pub fn volts(&self) -> f64 {
        if self.clamped {
            0.0
        } else {
            10.0 * f64::from(self.code) / f64::from(1u32 << 19)
        }
    }
    pub fn clamped(&self) -> bool {
        self.clamped
    }
}

impl AmplifierDac for Dac {
    fn write(&mut self, code: i32) -> Result<(), BusError> {
        self.code = code;
        self.writes = self.writes.wrapping_add(1);
        Ok(())
    }
    fn clamp_to_ground(&mut self) -> Result<(), BusError> {
        self.clamped = true;
        Ok(())
    }
}
