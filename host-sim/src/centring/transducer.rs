//! The displacement transducer (Y-1594 ch. II): a spring-loaded linear
//! potentiometer, ±0.5 in of travel at 140 V/in (±70 V), its noise, and the
//! converter that digitises it (20 bits over ±70 V, 0.95 µin).

use crate::plant::gauge::gaussian;
use rand_chacha::ChaCha8Rng;

pub const VOLTS_PER_IN: f64 = 140.0;
pub const TRAVEL_IN: f64 = 0.5;
const ADC_BITS: i32 = 20;

#[derive(Clone, Debug)]
pub struct Transducer {
    /// Surface distance at which the plunger reads zero, inches.
    pub zero_in: f64,
    /// White noise per sample, inches rms.
    pub noise_in: f64,
}

impl Transducer {
    /// The converted reading, inches, and the plunger's true displacement.
    /// At the ends of the travel the plunger sits on its stop.
    pub fn read(&self, surface_in: f64, rng: &mut ChaCha8Rng) -> f64 {
        let d = (surface_in - self.zero_in).clamp(-TRAVEL_IN, TRAVEL_IN);
        let volts = (d + self.noise_in * gaussian(rng)) * VOLTS_PER_IN;
        let full = TRAVEL_IN * VOLTS_PER_IN;
        let lsb = 2.0 * full / f64::from(1 << ADC_BITS);
        let code = (volts / lsb).round().clamp(
            -f64::from(1 << (ADC_BITS - 1)),
            f64::from((1 << (ADC_BITS - 1)) - 1),
        );
        code * lsb / VOLTS_PER_IN
    }
}
