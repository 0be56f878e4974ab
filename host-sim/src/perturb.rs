//! A machine that differs from its scenario's model: the plant's amplifier
//! gain, moving mass and coil-frame mode scaled, the firmware's design left
//! as the scenario states it (what commissioning a real slide meets: the
//! data sheet's numbers in the loop, the slide's own in the hardware).

use crate::scenario::Scenario;
use anyhow::ensure;

/// Relative errors of the plant against the scenario's model (−0.15 = 15 %
/// less; a leading minus is accepted by `crate::cli`'s rule for every
/// option).
#[derive(Clone, Copy, Debug, Default, PartialEq, clap::Args)]
pub struct Perturbation {
    /// The amplifier's voltage gain differs by this fraction (−0.15: 15 %
    /// low).
    #[arg(
        long = "plant-gain-error",
        value_name = "FRACTION",
        default_value_t = 0.0
    )]
    pub gain: f64,
    /// The moving mass differs by this fraction.
    #[arg(
        long = "plant-mass-error",
        value_name = "FRACTION",
        default_value_t = 0.0
    )]
    pub mass: f64,
    /// The coil-frame mode (its pole and zero pairs) sits higher by this
    /// fraction.
    #[arg(
        long = "plant-mode-error",
        value_name = "FRACTION",
        default_value_t = 0.0
    )]
    pub mode: f64,
}

impl Perturbation {
    /// Applies the errors to the plant only (`rig`); the servo design
    /// (`servo_design`, `servo`) keeps the scenario's model.
    pub fn apply(&self, sc: &mut Scenario) -> anyhow::Result<()> {
        for (name, v) in [
            ("--plant-gain-error", self.gain),
            ("--plant-mass-error", self.mass),
            ("--plant-mode-error", self.mode),
        ] {
            ensure!(
                v.is_finite() && v.abs() <= 0.5,
                "{name} {v}: must be within ±0.5 (a fraction: -0.15 is 15 % low)"
            );
        }
        sc.rig.amplifier.gain *= 1.0 + self.gain;
        sc.rig.slide.mass_lbf_s2_per_in *= 1.0 + self.mass;
        if let Some(m) = &mut sc.rig.slide.mode {
            m.pole_hz *= 1.0 + self.mode;
            m.zero_hz *= 1.0 + self.mode;
        } else {
            ensure!(
                self.mode == 0.0,
                "--plant-mode-error {}: scenario {} has no [mode]",
                self.mode,
                sc.file.name
            );
        }
        Ok(())
    }
}

/// Sets servo parameters `NAME=VALUE` (`zslide::params`) in the
/// scenario's design, checked as the firmware checks a set.
pub fn set_params(sc: &mut Scenario, sets: &[String]) -> anyhow::Result<()> {
    for s in sets {
        let (name, value) = s
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("--param {s:?}: expected NAME=VALUE"))?;
        let p = zslide::params::by_name(name.trim())
            .ok_or_else(|| anyhow::anyhow!("--param {s:?}: no servo parameter {name:?}"))?;
        let v: f64 = value
            .trim()
            .parse()
            .map_err(|e| anyhow::anyhow!("--param {s:?}: {e}"))?;
        let (design, cfg) = zslide::params::set(&sc.servo_design, p.id, v)
            .map_err(|e| anyhow::anyhow!("--param {s:?}: {e}"))?;
        sc.servo_design = design;
        sc.servo = cfg;
    }
    Ok(())
}
