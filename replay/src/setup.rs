//! A run's firmware configuration in the recording, and back.

use crate::wire::{Setup, SpindleSetup, XSetup};
use zslide::firmware::{FirmwareConfig, SpindleMode, XMode};
use zslide::servo::ServoConfig;
use zslide::spindle::{EdgeStamps, EncoderConfig, TachConfig};
use zslide::units::SpindleAngle;
use zslide::xpos::CountConfig;

impl Setup<'_> {
    /// The firmware configuration the run was recorded with. The loop is
    /// the default design at the recorded rate, computed here (on the
    /// target: by its own f64 code, which must agree with the host's for
    /// the run to replay).
    pub fn firmware_config(&self) -> Option<FirmwareConfig> {
        Some(FirmwareConfig {
            loop_cfg: ServoConfig::at_rate(self.loop_hz).ok()?,
            spindle: match self.spindle {
                SpindleSetup::None => SpindleMode::None,
                SpindleSetup::Encoder {
                    counts_per_rev,
                    ticks_per_s,
                    min_rpm,
                    max_rpm,
                    index_tolerance_counts,
                    index_angle,
                    captured,
                } => SpindleMode::Encoder(EncoderConfig {
                    counts_per_rev,
                    ticks_per_s,
                    min_rpm,
                    max_rpm,
                    index_tolerance_counts,
                    index_angle: SpindleAngle(index_angle),
                    edge_stamps: if captured {
                        EdgeStamps::Captured
                    } else {
                        EdgeStamps::AtRead
                    },
                }),
                SpindleSetup::Tach {
                    ticks_per_s,
                    mv_at_300_rpm,
                    min_rpm,
                    max_rpm,
                    index_tolerance_permille,
                    index_angle,
                } => SpindleMode::Tach(TachConfig {
                    ticks_per_s,
                    mv_at_300_rpm,
                    min_rpm,
                    max_rpm,
                    index_tolerance_permille,
                    index_angle: SpindleAngle(index_angle),
                }),
            },
            x: match self.x {
                XSetup::None => XMode::None,
                XSetup::Legacy { clock_hz } => XMode::Legacy { clock_hz },
                XSetup::Count {
                    counts_per_inch,
                    zero_count,
                    max_step_counts,
                } => XMode::Count(CountConfig {
                    counts_per_inch,
                    zero_count,
                    max_step_counts,
                }),
            },
            coefficient_output: self.coefficient_output,
            gauge_reversed: self.gauge_reversed,
        })
    }
}

/// The recording's form of `fc`; `None` when its loop is not the default
/// design at its rate (a recording carries the rate only).
pub fn setup_of<'a>(
    name: &'a str,
    table: &'a [u8],
    interruptions: &'a [u8],
    fc: &FirmwareConfig,
) -> Option<Setup<'a>> {
    let loop_hz = fc.loop_cfg.rate_hz;
    if ServoConfig::at_rate(loop_hz).ok()? != fc.loop_cfg {
        return None;
    }
    Some(Setup {
        name,
        loop_hz,
        table,
        interruptions,
        spindle: match fc.spindle {
            SpindleMode::None => SpindleSetup::None,
            SpindleMode::Encoder(c) => SpindleSetup::Encoder {
                counts_per_rev: c.counts_per_rev,
                ticks_per_s: c.ticks_per_s,
                min_rpm: c.min_rpm,
                max_rpm: c.max_rpm,
                index_tolerance_counts: c.index_tolerance_counts,
                index_angle: c.index_angle.0,
                captured: c.edge_stamps == EdgeStamps::Captured,
            },
            SpindleMode::Tach(c) => SpindleSetup::Tach {
                ticks_per_s: c.ticks_per_s,
                mv_at_300_rpm: c.mv_at_300_rpm,
                min_rpm: c.min_rpm,
                max_rpm: c.max_rpm,
                index_tolerance_permille: c.index_tolerance_permille,
                index_angle: c.index_angle.0,
            },
        },
        x: match fc.x {
            XMode::None => XSetup::None,
            XMode::Legacy { clock_hz } => XSetup::Legacy { clock_hz },
            XMode::Count(c) => XSetup::Count {
                counts_per_inch: c.counts_per_inch,
                zero_count: c.zero_count,
                max_step_counts: c.max_step_counts,
            },
        },
        coefficient_output: fc.coefficient_output,
        gauge_reversed: fc.gauge_reversed,
    })
}
