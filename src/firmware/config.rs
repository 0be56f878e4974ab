//! What a firmware is built from: where X and the spindle angle come
//! from, the loop's configuration, and the table load with its sign check.

use crate::command::CommandGen;
use crate::servo::ServoConfig;
use crate::spindle::{EncoderConfig, TachConfig};
use crate::table::{CoeffTable, TableError};
use crate::units::SpindleAngle;
use crate::xpos::CountConfig;

/// Where the spindle angle comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpindleMode {
    /// No spindle: the angle is 0 and the table command stays null (bench
    /// use: the loop follows [`Firmware::set_target_code`] only).
    None,
    /// Encoder + index ([`EncoderAngle`]).
    Encoder(EncoderConfig),
    /// Tachometer + index, the 1983 scheme ([`TachAngle`]).
    Tach(TachConfig),
}

/// Where X comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum XMode {
    /// No X source: the table command stays null.
    None,
    /// The legacy half-mil interrupt ([`Firmware::x_event`]); `clock_hz` is
    /// the rate of the `now` timestamps (storm window). The null zone is the
    /// table's.
    Legacy { clock_hz: u32 },
    /// A count read every loop tick ([`TickInput::x_count`]).
    Count(CountConfig),
}

/// Everything a [`Firmware`] is built from besides its table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FirmwareConfig {
    pub loop_cfg: ServoConfig,
    pub spindle: SpindleMode,
    pub x: XMode,
    /// Legacy coefficient-output mode: each accepted X event also writes
    /// C00..C03 to the quad DAC and strobes it (Table 3-1 scaling).
    pub coefficient_output: bool,
    /// The gauge reads −Z (the 1983 gauge after it was moved): its codes are
    /// negated before the loop.
    pub gauge_reversed: bool,
}

/// A configuration that cannot run (a programming error, not a machine
/// fault: the board refuses to start).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ConfigError {
    /// [`EncoderAngle::new`] or [`TachAngle::new`] refused the configuration.
    Spindle,
    /// [`CountX::new`] refused the configuration.
    Count,
}

/// Largest positive command the load check lets pass: 1 µin (Q30). The
/// series is truncated and quantised, so the command's maximum over φ sits
/// a fraction of a µin around 0; a table for a wrong sign convention or a
/// different surface is off by thousands of µin.
pub(crate) const SIGN_TOLERANCE_Q30: i32 = 1074;
/// Angles per node of the load check (every 22.5°, both eq 2-11 maxima
/// bracketed).
pub(crate) const SIGN_ANGLES: u32 = 16;

/// Parses `bytes` and checks the command's sign at every node inside the
/// table's command range and 16 angles: Z ≤ 0 (within 1 µin,
/// the truncation and quantisation slack). Runs once, at construction.
pub fn load_table(bytes: &'static [u8]) -> Result<CommandGen<'static>, TableError> {
    sign_checked(CoeffTable::parse(bytes)?)
}

/// [`load_table`] for a flash region that holds the table
/// ([`CoeffTable::parse_region`]: an erased region is
/// [`TableError::Missing`]).
pub fn load_table_region(region: &'static [u8]) -> Result<CommandGen<'static>, TableError> {
    sign_checked(CoeffTable::parse_region(region)?)
}

/// The load checks of a table image at any lifetime (the host's
/// `cargo xtask flash-table` refuses what the firmware would refuse).
pub fn check_table(bytes: &[u8]) -> Result<CoeffTable<'_>, TableError> {
    let t = CoeffTable::parse(bytes)?;
    sign_checked(t)?;
    Ok(t)
}

fn sign_checked(table: CoeffTable<'_>) -> Result<CommandGen<'_>, TableError> {
    let gen = CommandGen::new(table);
    for n in 0..table.node_count() {
        let x = table.node_x(n);
        if x > gen.x_null() {
            break;
        }
        let c = gen.coefficients(x).map_err(|_| TableError::SignCheck)?;
        for k in 0..SIGN_ANGLES {
            let phi = SpindleAngle(k.wrapping_mul(u32::MAX / SIGN_ANGLES + 1));
            if gen.evaluate_phi(&c, phi).z.to_bits() > SIGN_TOLERANCE_Q30 {
                return Err(TableError::SignCheck);
            }
        }
    }
    Ok(gen)
}
