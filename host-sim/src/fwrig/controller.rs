//! Who drives the amplifier: the firmware's digital loop or the 1983 analog
//! loop.

use super::world::FirmwareWorld;
use crate::sched::Scheduler;
use zslide::firmware::Request;

/// Which loop drives the amplifier.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Controller {
    /// The firmware's digital loop (`zslide::servo`) writes the amplifier
    /// DAC.
    Digital,
    /// The 1983 analog loop (eq 4-44 velocity loop, eq 4-45 lag at
    /// Ko = 0.5934: Kv ≈ 4800 1/s; `analog1983`) drives the amplifier from
    /// the gauge and the firmware's command. The 1983 command came from
    /// analog multipliers fed by the 8080's coefficient DACs and a sine
    /// generator; here it is the firmware's own command (the same table,
    /// angle and X), sampled at each loop tick and held, so the comparison
    /// isolates the loop. The firmware stays disarmed: its DAC holds 0 V
    /// and is not connected.
    LegacyAnalog,
}

impl Controller {
    pub fn name(self) -> &'static str {
        match self {
            Controller::Digital => "digital",
            Controller::LegacyAnalog => "legacy-analog",
        }
    }

    /// Puts this controller in charge of the amplifier of a freshly built
    /// world: the digital loop is armed (sign check, then bumpless
    /// engagement), the 1983 loop is attached (it runs inside the world's
    /// advance: [`crate::analog1983::AnalogDrive`]).
    pub fn attach(self, w: &mut FirmwareWorld, _s: &mut Scheduler<FirmwareWorld>) {
        match self {
            Controller::Digital => w.request(Request::Arm),
            Controller::LegacyAnalog => w.use_legacy_analog(),
        }
    }
}
