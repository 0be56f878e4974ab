//! The machine around the Z slide as a scenario configures it: how the
//! firmware learns X and the spindle angle, and the models' steps.

use super::spindle::SpindleConfig;
use super::xslide::XSlideConfig;

/// How the firmware learns X.
#[derive(Clone, Debug, PartialEq)]
pub enum XInterface {
    /// 1983: BCD counter chain, half-mil interrupt, latched digits.
    LegacyBcd(XSlideConfig),
    /// Interferometer count (1 µin) read every loop tick.
    Quadrature(XSlideConfig),
}

/// How the firmware learns the spindle angle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpindleSensor {
    /// 1983: tachometer (5 V at 300 rpm) + once-per-rev index.
    TachIndex,
    /// Rotary encoder with index.
    EncoderIndex,
}

/// The machine around the Z slide.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineConfig {
    pub x: XInterface,
    pub spindle: SpindleConfig,
    pub sensor: SpindleSensor,
    /// The encoder's edge timestamps as the board gives them.
    pub encoder_edges: zslide::spindle::EdgeStamps,
    /// Integration step of the spindle model, ns (speed changes over
    /// seconds: 250 µs keeps the angle's interpolation error far below a
    /// count; the angle is interpolated linearly inside a step).
    pub spindle_step_ns: u64,
    /// Sampling step of the X position (feed, vibration, jitter), ns.
    pub x_step_ns: u64,
    /// How far the event-producing models run ahead per scan, ns.
    pub window_ns: u64,
    /// Speed band the firmware accepts, rpm.
    pub min_rpm: u32,
    pub max_rpm: u32,
    /// Legacy coefficient-output mode (C00..C03 on the quad DAC at every
    /// accepted X event).
    pub coefficient_output: bool,
}

impl MachineConfig {
    /// 1983: BCD X at 0.2 in/min from 1 in, tachometer + index at 300 rpm.
    pub fn legacy(seed: u64) -> Self {
        Self {
            x: XInterface::LegacyBcd(XSlideConfig {
                x0_in: 1.0,
                seed: seed ^ 0x58,
                ..XSlideConfig::default()
            }),
            spindle: SpindleConfig {
                seed: seed ^ 0x5350,
                ..SpindleConfig::default()
            },
            sensor: SpindleSensor::TachIndex,
            encoder_edges: zslide::spindle::EdgeStamps::AtRead,
            spindle_step_ns: 250_000,
            x_step_ns: 100_000,
            window_ns: 5_000_000,
            min_rpm: 30,
            max_rpm: 600,
            coefficient_output: false,
        }
    }
    /// Modern: quadrature X, encoder + index.
    pub fn modern(seed: u64) -> Self {
        let l = Self::legacy(seed);
        let XInterface::LegacyBcd(x) = l.x.clone() else {
            unreachable!()
        };
        Self {
            x: XInterface::Quadrature(x),
            sensor: SpindleSensor::EncoderIndex,
            ..l
        }
    }
}
