//! Scenario files (TOML): the plant, noise and machine a simulation runs
//! on, in the machine's own units (inches, µin, rpm, lbf; motor constants in
//! the dissertation's foot units so they can be checked against chapter 4).
//!
//! Every field is required (a scenario says what it simulates; nothing is
//! silently defaulted) except the optional `[mode]` table (absent = rigid
//! slide). Unknown fields are refused with their name, and every value is
//! range-checked with a message naming the field and the accepted range.
//! The schema, field by field, is the documentation of the structs below
//! and of `scenarios/legacy-hw.toml`.
//!
//! `load("legacy-hw")` finds `scenarios/legacy-hw.toml` of the workspace
//! (the two standard files are also compiled in, so the binary works from
//! any directory); anything else is read as a path. Commands take it as
//! `--scenario NAME|PATH` (see [`ScenarioArg`]).

use crate::machine::spindle::SpindleConfig;
use crate::machine::xslide::{FeedSegment, XSlideConfig};
use crate::machine::{MachineConfig, SpindleSensor, XInterface};
use crate::plant::amplifier::AmplifierParams;
use crate::plant::cutting::{BoltHoles, CuttingParams};
use crate::plant::gauge::GaugeParams;
use crate::plant::zslide::{ModeParams, ZSlideParams};
use crate::plant::RigConfig;
use anyhow::{bail, Context};
use serde::Deserialize;
use std::path::Path;
use zslide::servo::{ServoConfig, ServoDesign, SlideModel};

/// lbm per slug.
const LBM_PER_SLUG: f64 = 32.174;

const LEGACY_HW: &str = include_str!("../../scenarios/legacy-hw.toml");
const MODERN_HW: &str = include_str!("../../scenarios/modern-hw.toml");

/// A scenario file.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// Short name (reports quote it).
    pub name: String,
    /// One line: what the scenario represents.
    pub description: String,
    /// Master seed; every random stream (gauge noise, X jitter, spindle
    /// index noise, tachometer noise) is derived from it.
    pub seed: u64,
    pub motor: Motor,
    /// Coil-frame structural mode; absent = rigid slide.
    pub mode: Option<Mode>,
    pub amplifier: Amplifier,
    pub gauge: Gauge,
    #[serde(rename = "loop")]
    pub loop_: Loop,
    pub cutting: Cutting,
    pub x: XSlide,
    pub spindle: Spindle,
    /// The digital loop's design (`zslide::servo::ServoDesign`); absent
    /// fields take the firmware's defaults, the slide model is `[motor]`.
    #[serde(default)]
    pub servo: ServoSection,
    /// Error sources beyond the loop and their levels (`cut::errors`);
    /// absent fields are 0 (off).
    #[serde(default)]
    pub errors: crate::error_levels::ErrorLevels,
}

// `[servo]` from the firmware's one parameter table
// (`zslide::servo::parameters`): a key per design field, nothing restated.
macro_rules! servo_section {
    (
        design { $(($id:literal, $name:ident, $ty:ident, $unit:literal, $default:expr,
            $min:expr, $max:expr, $doc:literal)),+ $(,)? }
        slide { $($slide:tt)* }
    ) => {
        /// `[servo]`: the loop's gains, filters, learning and limits, in physical
        /// units (see `docs/TUNING.md`). Every field is optional. The slide
        /// model's parameters come from `[motor]` instead.
        #[derive(Clone, Debug, Default, Deserialize, PartialEq)]
        #[serde(deny_unknown_fields)]
        pub struct ServoSection {
            $(#[doc = $doc] pub $name: Option<$ty>,)+
        }

        impl ServoSection {
            /// The design: the firmware's defaults at `rate_hz` for the slide the
            /// scenario describes, overridden field by field.
            pub fn design(&self, rate_hz: u32, slide: SlideModel) -> ServoDesign {
                let mut d = ServoDesign::brief(rate_hz);
                d.slide = slide;
                $(if let Some(v) = self.$name {
                    d.$name = v;
                })+
                d
            }
        }
    };
}
zslide::servo_parameters!(servo_section);

/// Voice-coil motor and slide (chapter 4).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Motor {
    /// Force constant Kf, lbf/A (Model 15: 2.9).
    pub kf_lbf_per_a: f64,
    /// Back-EMF constant Kb, V·s/ft (Model 15: 4.002).
    pub kb_v_s_per_ft: f64,
    /// Coil resistance, Ω (Model 15: 1.4).
    pub r_ohm: f64,
    /// Electrical time constant L/R, ms (0.26).
    pub l_over_r_ms: f64,
    /// Moving mass, lbm (6.25).
    pub moving_mass_lbm: f64,
    /// Air-film viscous friction B, lbf·s/ft (eq 4-32: 51.2).
    pub b_lbf_s_per_ft: f64,
}

/// The structural mode as the gauge sees it (docs/PLANT.md).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Mode {
    /// Pole pair, Hz (3150, Fig 4-31).
    pub pole_hz: f64,
    /// Zero pair, Hz, below the pole (2950 chosen).
    pub zero_hz: f64,
    /// Pole damping ratio (0.02 chosen).
    pub zeta: f64,
}

/// Linear power amplifier.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Amplifier {
    /// Voltage gain, V/V (10).
    pub gain: f64,
    /// Current limit, A (8).
    pub current_limit_a: f64,
    /// Output rail, V (48, assumed).
    pub rail_v: f64,
    /// Time in current limit before it trips, ms (2, assumed).
    pub trip_after_ms: f64,
}

/// Capacitance gauge.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Gauge {
    /// Sensitivity, V per mil (1).
    pub v_per_mil: f64,
    /// Output range, ±V (10).
    pub range_v: f64,
    /// Gauge mounted reversed (+Z reads negative volts).
    pub reversed: bool,
    /// Broadband noise RMS, µin.
    pub white_rms_uin: f64,
    /// Broadband noise bandwidth (first order), Hz.
    pub white_bw_hz: f64,
    /// Power-line hum amplitude (peak), µin.
    pub hum_uin: f64,
    /// Hum frequency, Hz (120).
    pub hum_hz: f64,
    /// Second hum harmonic amplitude (peak), µin.
    pub hum2_uin: f64,
}

/// The board's timing as the firmware meets it (`docs/BOARD.md`, Timers;
/// `docs/PLANT.md`, Board timing). Instants are from the loop-timer event
/// (the timer update that starts the gauge's conversion).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Loop {
    /// Loop-tick rate, Hz (≥ 1000).
    pub rate_hz: u32,
    /// The free-running clock the firmware reads and the input captures
    /// latch, Hz: its period is the capture resolution.
    pub clock_hz: u64,
    /// Pin to capture, ns: the input filter and resynchronisation of the
    /// timers (the encoder's count changes as late).
    pub capture_delay_ns: u64,
    /// Loop-timer event to the gauge's sampling instant, ns (0: CNV from
    /// the timer, the converter holds at its rising edge).
    pub adc_sample_ns: u64,
    /// The gauge converter's conversion time, ns: its result must be
    /// ready when the handler reads it.
    pub adc_conversion_ns: u64,
    /// Loop-timer event to the handler's reads of the clock, the spindle
    /// encoder or tachometer and the X count, ns (interrupt compare plus
    /// entry).
    pub handler_entry_ns: u64,
    /// Loop-timer event to the end of the handler's DAC frame, ns: the
    /// entry, the handler's own work before its DAC write, the frame.
    pub dac_latency_ns: u64,
}

/// Cutting force model (docs/PLANT.md).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Cutting {
    /// Specific cutting pressure, psi.
    pub k_t_psi: f64,
    /// Edge (ploughing) force per inch of engaged edge, lbf/in.
    pub k_e_lbf_per_in: f64,
    /// Tool nose radius, in (0.125).
    pub tool_radius_in: f64,
    /// Side of the stock along Z: +1 or −1.
    pub part_side: f64,
    pub bolt_holes: Holes,
}

/// Bolt holes in the part face (interrupted cut).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Holes {
    pub count: u32,
    /// Bolt-circle radius, in.
    pub circle_radius_in: f64,
    /// Countersink diameter, in.
    pub diameter_in: f64,
    /// Angle of the first hole, degrees.
    pub phase_deg: f64,
    /// Holes filled with cast material (no interruption).
    pub filled: bool,
}

/// X slide and its interface to the firmware.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct XSlide {
    /// "legacy-bcd" (half-mil interrupt, latched BCD digits) or
    /// "quadrature" (interferometer count, 1 µin, read every tick).
    pub interface: String,
    /// X at t = 0, in.
    pub x0_in: f64,
    /// Feed, in/min (0.2 in 1983; up to 100).
    pub feed_in_per_min: f64,
    /// Slide vibration amplitude, µin, and frequency, Hz (counter reversals).
    pub vibration_uin: f64,
    pub vibration_hz: f64,
    /// Uniform position jitter, ± µin.
    pub jitter_uin: f64,
    /// Probability that the latch catches a carry mid-ripple.
    pub ripple_prob: f64,
}

/// Spindle and its angle sensor.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Spindle {
    /// "tach-index" (tachometer + once-per-rev index) or "encoder-index".
    pub sensor: String,
    /// Speed, rpm (300 nominal).
    pub rpm: f64,
    /// Acceleration limit, rpm/s.
    pub accel_rpm_per_s: f64,
    /// Speed lost under full cutting load, rpm (no regulation in 1983).
    pub sag_rpm: f64,
    /// Once-per-rev speed ripple, rpm.
    pub ripple_rpm: f64,
    /// Probability that an index pulse is lost.
    pub index_loss_prob: f64,
    /// Spurious index pulses per revolution (mean).
    pub index_noise_per_rev: f64,
    /// Angle φ of the index mark, degrees.
    pub index_phase_deg: f64,
    /// Encoder counts per revolution (after quadrature).
    pub encoder_cpr: u32,
    /// Tachometer sensitivity, mV/rpm (5000/300).
    pub tach_mv_per_rpm: f64,
    /// Tachometer relative gain error.
    pub tach_gain_error: f64,
    /// Tachometer noise, mV RMS.
    pub tach_noise_mv: f64,
    /// The encoder's edge timestamps: "captured" (both edges of both lines
    /// captured on the clock, i.e. every count: the NUCLEO) or "at-read"
    /// (the count read at the loop tick and a change stamped with the
    /// read time: a board without capture wiring).
    pub encoder_edges: String,
    /// Timing jitter of the index edge, µs RMS (0 when absent).
    #[serde(default)]
    pub index_jitter_us: f64,
    /// Random speed drift, a new offset each revolution, rpm RMS (0 when
    /// absent).
    #[serde(default)]
    pub speed_noise_rpm: f64,
    /// Speed band the firmware accepts, rpm.
    pub min_rpm: u32,
    pub max_rpm: u32,
}

/// A loaded scenario: the configs the simulator runs.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    pub file: ScenarioFile,
    pub rig: RigConfig,
    pub machine: MachineConfig,
    pub cutting: CuttingParams,
    pub loop_hz: u32,
    /// The digital loop's design and its integer configuration.
    pub servo_design: ServoDesign,
    pub servo: ServoConfig,
}

fn check(field: &str, v: f64, lo: f64, hi: f64) -> anyhow::Result<()> {
    if !(v.is_finite() && v >= lo && v <= hi) {
        bail!("{field} = {v} is out of range [{lo}, {hi}]");
    }
    Ok(())
}

impl ScenarioFile {
    /// Range checks, each naming its field.
    pub fn validate(&self) -> anyhow::Result<()> {
        self.errors.validate()?;
        let m = &self.motor;
        check("motor.kf_lbf_per_a", m.kf_lbf_per_a, 0.01, 100.0)?;
        check("motor.kb_v_s_per_ft", m.kb_v_s_per_ft, 0.0, 100.0)?;
        check("motor.r_ohm", m.r_ohm, 0.01, 100.0)?;
        check("motor.l_over_r_ms", m.l_over_r_ms, 0.001, 100.0)?;
        check("motor.moving_mass_lbm", m.moving_mass_lbm, 0.1, 1000.0)?;
        check("motor.b_lbf_s_per_ft", m.b_lbf_s_per_ft, 0.0, 10_000.0)?;
        if let Some(md) = &self.mode {
            check("mode.pole_hz", md.pole_hz, 10.0, 100_000.0)?;
            check("mode.zero_hz", md.zero_hz, 1.0, md.pole_hz)?;
            check("mode.zeta", md.zeta, 0.0001, 1.0)?;
        }
        let a = &self.amplifier;
        check("amplifier.gain", a.gain, 0.01, 1000.0)?;
        check("amplifier.current_limit_a", a.current_limit_a, 0.01, 100.0)?;
        check("amplifier.rail_v", a.rail_v, 0.1, 1000.0)?;
        check("amplifier.trip_after_ms", a.trip_after_ms, 0.0, 60_000.0)?;
        let g = &self.gauge;
        check("gauge.v_per_mil", g.v_per_mil, 0.001, 1000.0)?;
        check("gauge.range_v", g.range_v, 0.1, 100.0)?;
        check("gauge.white_rms_uin", g.white_rms_uin, 0.0, 10_000.0)?;
        check("gauge.white_bw_hz", g.white_bw_hz, 1.0, 1.0e6)?;
        check("gauge.hum_uin", g.hum_uin, 0.0, 10_000.0)?;
        check("gauge.hum_hz", g.hum_hz, 0.0, 100_000.0)?;
        check("gauge.hum2_uin", g.hum2_uin, 0.0, 10_000.0)?;
        let l = &self.loop_;
        check("loop.rate_hz", f64::from(l.rate_hz), 1000.0, 1.0e6)?;
        let period_ns = 1.0e9 / f64::from(l.rate_hz);
        check("loop.clock_hz", l.clock_hz as f64, 1000.0, 4.0e9)?;
        check(
            "loop.capture_delay_ns",
            l.capture_delay_ns as f64,
            0.0,
            100_000.0,
        )?;
        check(
            "loop.handler_entry_ns",
            l.handler_entry_ns as f64,
            0.0,
            period_ns,
        )?;
        // The gauge is sampled before the handler reads it, and the result
        // is ready by then (otherwise the handler reads the previous one:
        // a board like that is not modelled).
        check(
            "loop.adc_sample_ns",
            l.adc_sample_ns as f64,
            0.0,
            l.handler_entry_ns as f64,
        )?;
        check(
            "loop.adc_conversion_ns",
            l.adc_conversion_ns as f64,
            0.0,
            (l.handler_entry_ns - l.adc_sample_ns) as f64,
        )?;
        // The DAC frame ends after the handler's reads and within the period.
        check(
            "loop.dac_latency_ns",
            l.dac_latency_ns as f64,
            l.handler_entry_ns as f64,
            period_ns,
        )?;
        let c = &self.cutting;
        check("cutting.k_t_psi", c.k_t_psi, 0.0, 1.0e8)?;
        check("cutting.k_e_lbf_per_in", c.k_e_lbf_per_in, 0.0, 1.0e6)?;
        check("cutting.tool_radius_in", c.tool_radius_in, 0.0001, 10.0)?;
        if c.part_side != 1.0 && c.part_side != -1.0 {
            bail!("cutting.part_side = {} must be +1 or -1", c.part_side);
        }
        let h = &c.bolt_holes;
        check("cutting.bolt_holes.count", f64::from(h.count), 0.0, 360.0)?;
        check(
            "cutting.bolt_holes.circle_radius_in",
            h.circle_radius_in,
            0.0,
            100.0,
        )?;
        check("cutting.bolt_holes.diameter_in", h.diameter_in, 0.0, 100.0)?;
        check("cutting.bolt_holes.phase_deg", h.phase_deg, -360.0, 360.0)?;
        let x = &self.x;
        if !matches!(x.interface.as_str(), "legacy-bcd" | "quadrature") {
            bail!(
                "x.interface = {:?}: expected \"legacy-bcd\" or \"quadrature\"",
                x.interface
            );
        }
        check("x.x0_in", x.x0_in, 0.0, 9.999)?;
        check("x.feed_in_per_min", x.feed_in_per_min, -100.0, 100.0)?;
        check("x.vibration_uin", x.vibration_uin, 0.0, 1000.0)?;
        check("x.vibration_hz", x.vibration_hz, 0.0, 100_000.0)?;
        check("x.jitter_uin", x.jitter_uin, 0.0, 1000.0)?;
        check("x.ripple_prob", x.ripple_prob, 0.0, 1.0)?;
        let s = &self.spindle;
        if !matches!(s.encoder_edges.as_str(), "at-read" | "captured") {
            anyhow::bail!(
                "spindle.encoder_edges = {:?}: expected \"at-read\" or \"captured\"",
                s.encoder_edges
            );
        }
        if !matches!(s.sensor.as_str(), "tach-index" | "encoder-index") {
            bail!(
                "spindle.sensor = {:?}: expected \"tach-index\" or \"encoder-index\"",
                s.sensor
            );
        }
        check("spindle.min_rpm", f64::from(s.min_rpm), 1.0, 10_000.0)?;
        check(
            "spindle.max_rpm",
            f64::from(s.max_rpm),
            f64::from(s.min_rpm),
            10_000.0,
        )?;
        check(
            "spindle.rpm",
            s.rpm,
            f64::from(s.min_rpm),
            f64::from(s.max_rpm),
        )?;
        // The firmware times a revolution with its 32-bit clock and refuses a
        // band whose slowest revolution does not fit (zslide::spindle).
        if self.loop_.clock_hz * 60 / u64::from(s.min_rpm) > u64::from(u32::MAX) {
            bail!(
                "spindle.min_rpm = {} is too slow for loop.clock_hz = {}: a revolution must \
                 fit the firmware's 32-bit clock (min_rpm >= {})",
                s.min_rpm,
                self.loop_.clock_hz,
                (self.loop_.clock_hz * 60).div_ceil(u64::from(u32::MAX) + 1)
            );
        }
        check("spindle.accel_rpm_per_s", s.accel_rpm_per_s, 0.0, 1.0e6)?;
        check("spindle.sag_rpm", s.sag_rpm, 0.0, s.rpm)?;
        check("spindle.ripple_rpm", s.ripple_rpm, 0.0, s.rpm)?;
        check("spindle.index_loss_prob", s.index_loss_prob, 0.0, 1.0)?;
        check(
            "spindle.index_noise_per_rev",
            s.index_noise_per_rev,
            0.0,
            100.0,
        )?;
        check("spindle.index_phase_deg", s.index_phase_deg, -360.0, 360.0)?;
        check("spindle.encoder_cpr", f64::from(s.encoder_cpr), 4.0, 1.0e8)?;
        check("spindle.tach_mv_per_rpm", s.tach_mv_per_rpm, 0.001, 1000.0)?;
        check("spindle.tach_gain_error", s.tach_gain_error, -0.5, 0.5)?;
        check("spindle.tach_noise_mv", s.tach_noise_mv, 0.0, 1000.0)?;
        check("spindle.index_jitter_us", s.index_jitter_us, 0.0, 1000.0)?;
        check(
            "spindle.speed_noise_rpm",
            s.speed_noise_rpm,
            0.0,
            s.rpm / 10.0,
        )?;
        Ok(())
    }

    /// The simulator's configs (after [`Self::validate`]).
    pub fn build(&self) -> anyhow::Result<Scenario> {
        self.validate()?;
        let m = &self.motor;
        let mut slide = ZSlideParams::from_ft_units(
            m.kf_lbf_per_a,
            m.kb_v_s_per_ft,
            m.r_ohm,
            m.l_over_r_ms * 1e-3,
            m.moving_mass_lbm / LBM_PER_SLUG,
            m.b_lbf_s_per_ft,
        );
        slide.mode = self.mode.as_ref().map(|md| ModeParams {
            pole_hz: md.pole_hz,
            zero_hz: md.zero_hz,
            zeta: md.zeta,
        });
        let a = &self.amplifier;
        let g = &self.gauge;
        let rig = RigConfig {
            slide,
            amplifier: AmplifierParams {
                gain: a.gain,
                current_limit_a: a.current_limit_a,
                rail_v: a.rail_v,
                trip_after_s: a.trip_after_ms * 1e-3,
            },
            gauge: GaugeParams {
                v_per_in: g.v_per_mil * 1000.0,
                range_v: g.range_v,
                reversed: g.reversed,
                white_rms_in: g.white_rms_uin * 1e-6,
                white_bw_hz: g.white_bw_hz,
                hum_amp_in: g.hum_uin * 1e-6,
                hum_hz: g.hum_hz,
                hum2_amp_in: g.hum2_uin * 1e-6,
            },
            seed: self.seed,
            dac_latency_ns: self.loop_.dac_latency_ns,
            clock_hz: self.loop_.clock_hz,
            adc_sample_ns: self.loop_.adc_sample_ns,
            handler_entry_ns: self.loop_.handler_entry_ns,
        };
        let x = &self.x;
        let xcfg = XSlideConfig {
            x0_in: x.x0_in,
            feed: vec![FeedSegment {
                t_start_s: 0.0,
                feed_in_per_min: x.feed_in_per_min,
            }],
            vibration_uin: x.vibration_uin,
            vibration_hz: x.vibration_hz,
            jitter_uin: x.jitter_uin,
            ripple_prob: x.ripple_prob,
            seed: self.seed ^ 0x58,
        };
        let s = &self.spindle;
        let machine = MachineConfig {
            x: if x.interface == "legacy-bcd" {
                XInterface::LegacyBcd(xcfg)
            } else {
                XInterface::Quadrature(xcfg)
            },
            spindle: SpindleConfig {
                rpm0: s.rpm,
                accel_rpm_per_s: s.accel_rpm_per_s,
                sag_rpm: s.sag_rpm,
                ripple_rpm: s.ripple_rpm,
                index_loss_prob: s.index_loss_prob,
                index_noise_per_rev: s.index_noise_per_rev,
                index_phase_turns: s.index_phase_deg / 360.0,
                encoder_cpr: s.encoder_cpr,
                tach_mv_per_rpm: s.tach_mv_per_rpm,
                tach_gain_error: s.tach_gain_error,
                tach_noise_mv: s.tach_noise_mv,
                index_jitter_us: s.index_jitter_us,
                speed_noise_rpm: s.speed_noise_rpm,
                ticks_per_s: self.loop_.clock_hz as f64,
                capture_delay_ns: self.loop_.capture_delay_ns,
                seed: self.seed ^ 0x5350,
            },
            encoder_edges: if s.encoder_edges == "captured" {
                zslide::spindle::EdgeStamps::Captured
            } else {
                zslide::spindle::EdgeStamps::AtRead
            },
            sensor: if s.sensor == "tach-index" {
                SpindleSensor::TachIndex
            } else {
                SpindleSensor::EncoderIndex
            },
            spindle_step_ns: 250_000,
            x_step_ns: 100_000,
            window_ns: 5_000_000,
            min_rpm: s.min_rpm,
            max_rpm: s.max_rpm,
            coefficient_output: false,
        };
        let c = &self.cutting;
        let h = &c.bolt_holes;
        let cutting = CuttingParams {
            k_t_psi: c.k_t_psi,
            k_e_lbf_per_in: c.k_e_lbf_per_in,
            tool_radius_in: c.tool_radius_in,
            part_side: c.part_side,
            bolt_holes: BoltHoles {
                count: h.count,
                circle_radius_in: h.circle_radius_in,
                diameter_in: h.diameter_in,
                phase_deg: h.phase_deg,
                filled: h.filled,
            },
        };
        let slide_model = SlideModel {
            kf_lbf_per_a: m.kf_lbf_per_a,
            kb_v_s_per_in: m.kb_v_s_per_ft / 12.0,
            r_ohm: m.r_ohm,
            mass_lbf_s2_per_in: m.moving_mass_lbm / LBM_PER_SLUG / 12.0,
            b_lbf_s_per_in: m.b_lbf_s_per_ft / 12.0,
            amp_gain: self.amplifier.gain,
            gauge_v_per_in: self.gauge.v_per_mil * 1000.0,
        };
        let servo_design = self.servo.design(self.loop_.rate_hz, slide_model);
        let servo = servo_design
            .config()
            .map_err(|e| anyhow::anyhow!("servo.{}", servo_design.refusal(e)))?;
        Ok(Scenario {
            file: self.clone(),
            rig,
            machine,
            cutting,
            loop_hz: self.loop_.rate_hz,
            servo_design,
            servo,
        })
    }
}

/// Parses scenario TOML (`origin` names it in errors).
pub fn parse(text: &str, origin: &str) -> anyhow::Result<Scenario> {
    let f: ScenarioFile =
        toml::from_str(text).with_context(|| format!("scenario {origin}: cannot parse"))?;
    f.build().with_context(|| format!("scenario {origin}"))
}

/// `legacy-hw` / `modern-hw` (built in) or a path to a TOML file.
pub fn load(name_or_path: &str) -> anyhow::Result<Scenario> {
    match name_or_path {
        "legacy-hw" => parse(LEGACY_HW, "legacy-hw"),
        "modern-hw" => parse(MODERN_HW, "modern-hw"),
        p => {
            let path = Path::new(p);
            let text = std::fs::read_to_string(path).with_context(|| {
                format!(
                    "scenario {p:?}: not a built-in name (legacy-hw, modern-hw) and not a readable file"
                )
            })?;
            parse(&text, p)
        }
    }
}

/// `--scenario NAME|PATH` for any command (flatten it into the command's
/// clap `Args`).
#[derive(clap::Args, Debug, Clone)]
pub struct ScenarioArg {
    /// Scenario: `legacy-hw`, `modern-hw`, or a path to a TOML file.
    #[arg(long, default_value = "legacy-hw")]
    pub scenario: String,
}

impl ScenarioArg {
    pub fn load(&self) -> anyhow::Result<Scenario> {
        load(&self.scenario)
    }
}
