//! Converter codes: the 20-bit gauge ADC and amplifier DAC scale
//! (2¹⁹ codes = 10 V; the gauge reads 1 V per mil, so 1 gauge code =
//! 0.010 in / 2¹⁹ = 0.0191 µin).

use crate::units::ZInches;

/// Largest 20-bit two's complement code (gauge ADC and amplifier DAC).
pub const CODE_MAX: i32 = (1 << 19) - 1;
/// Smallest 20-bit two's complement code.
pub const CODE_MIN: i32 = -(1 << 19);
/// Gauge codes per inch: 2¹⁹ codes = 10 V = 0.010 in (exact in f64:
/// 52 428 800; per µin 52.4288). For the host's and the boards' reports
/// and plants; the firmware itself converts in integers
/// ([`gauge_code_from_z`]).
pub const GAUGE_CODES_PER_INCH: f64 = 52_428_800.0;

/// The gauge code that reads `z` (gauge 1 V/mil, ±10 V = ±0.010 in over
/// ±2¹⁹ codes), rounded to nearest and clamped to the converter range.
///
/// `code = z · 2¹⁹ / 0.010 in = z_bits · 2¹⁹ / (0.010 · 2³⁰) = z_bits · 25 / 512`,
/// exact in integers.
pub const fn gauge_code_from_z(z: ZInches) -> i32 {
    let scaled = z.to_bits() as i64 * 25;
    let code = (scaled + 256) >> 9;
    if code > CODE_MAX as i64 {
        CODE_MAX
    } else if code < CODE_MIN as i64 {
        CODE_MIN
    } else {
        code as i32
    }
}
