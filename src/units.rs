//! Typed quantities: every length, angle and code in the core carries its unit,
//! its fixed-point format and its sign convention in its type.
//!
//! # Sign conventions (the 1983 part was ruined once by a reversed sign)
//!
//! * **X** ([`XInches`]) is the radius of the *tool centre* from the spindle
//!   axis, positive outward, in the sector's coordinate system (eq 2-5:
//!   `x3 = R cos φ`, `y3 = R sin φ`, with `R = X`).
//! * **φ** ([`SpindleAngle`]) is the spindle angle of eq 2-5, counter-clockwise
//!   seen from +Y_t, zero on the x3 axis, as a binary angle (one turn = 2³²).
//! * **Z** ([`ZInches`]) is the Z-slide displacement along +Y_t of eq 2-8,
//!   `Y_t(X, φ) = Y(X) + Z(X, φ)`. With eq 2-14 corrected (its printed form
//!   lost a leading `1 −`, `docs/COEFFICIENTS.md`) the
//!   command satisfies `max_φ Z(X, φ) = 0`, so a correct command is never
//!   positive: the sign check in `safety` relies on that.
//!
//! # Number formats
//!
//! | type | backing | range | LSB |
//! |---|---|---|---|
//! | [`XInches`] | `I8F24` | ±128 in | 5.96e-8 in (0.06 µin) |
//! | [`ZInches`] | `I2F30` | ±2 in | 9.31e-10 in (0.00093 µin) |
//! | [`SpindleAngle`] | `u32` | one turn, wrapping | 1.46e-9 rad |
//! | [`TableInches`] | `I2F30` | ±2 in | 9.31e-10 in |
//!
//! * **Centring lengths** ([`TableInches`], `crate::centring`) are in the
//!   rotary table's frame: X′ and Y′ along the two cross slides, positive
//!   where the slide moves the part when driven positive; the table angle
//!   θ (a [`SpindleAngle`]) is zero when X′ points at the transducer and
//!   grows counter-clockwise seen from above. A part centred at (x, y)
//!   reads `x cos θ − y sin θ` (plus its radius) at the transducer.
//!
//! The Z LSB is three orders of magnitude below the 0.1 µin command-accuracy
//! goal, so quantisation of a sum of a few terms stays negligible in the error
//! budget (`docs/ARCHITECTURE.md`).

use fixed::types::{I2F30, I8F24};

/// Micro-inches per inch.
pub const UIN_PER_IN: f64 = 1.0e6;

/// Tool-centre radius from the spindle axis, inches, `I8F24`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct XInches(pub I8F24);

/// Z-slide displacement along +Y_t (eq 2-8), inches, `I2F30`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ZInches(pub I2F30);

/// Spindle angle φ of eq 2-5 as a binary angle: 2³² counts per turn, wrapping.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct SpindleAngle(pub u32);

/// A length in the rotary table's frame (centring: off-centre, slide
/// displacement, transducer reading), inches, `I2F30`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct TableInches(pub I2F30);

impl TableInches {
    pub const ZERO: Self = Self(I2F30::ZERO);

    pub const fn from_bits(bits: i32) -> Self {
        Self(I2F30::from_bits(bits))
    }
    pub const fn to_bits(self) -> i32 {
        self.0.to_bits()
    }
    /// Host-side convenience; saturates outside ±2 in.
    pub fn from_f64(inches: f64) -> Self {
        Self(I2F30::saturating_from_num(inches))
    }
    pub fn to_f64(self) -> f64 {
        self.0.to_num()
    }
}

#[cfg(target_os = "none")]
impl defmt::Format for TableInches {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "{=i32}/2^30in", self.to_bits())
    }
}

// `fixed` has no defmt support; log the raw bits with their scale so a trace
// reader can convert without floats on the target.
#[cfg(target_os = "none")]
impl defmt::Format for XInches {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "X={=i32}/2^24in", self.to_bits())
    }
}
#[cfg(target_os = "none")]
impl defmt::Format for ZInches {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "Z={=i32}/2^30in", self.to_bits())
    }
}

impl XInches {
    pub const ZERO: Self = Self(I8F24::ZERO);

    /// Raw `I8F24` bits.
    pub const fn from_bits(bits: i32) -> Self {
        Self(I8F24::from_bits(bits))
    }
    pub const fn to_bits(self) -> i32 {
        self.0.to_bits()
    }
    /// Nearest representable value; saturates outside ±128 in. Host-side
    /// convenience (tables, tests); the firmware never converts from floats.
    pub fn from_f64(inches: f64) -> Self {
        Self(I8F24::saturating_from_num(inches))
    }
    pub fn to_f64(self) -> f64 {
        self.0.to_num()
    }
}

impl ZInches {
    pub const ZERO: Self = Self(I2F30::ZERO);
    pub const MAX: Self = Self(I2F30::MAX);
    pub const MIN: Self = Self(I2F30::MIN);

    pub const fn from_bits(bits: i32) -> Self {
        Self(I2F30::from_bits(bits))
    }
    pub const fn to_bits(self) -> i32 {
        self.0.to_bits()
    }
    pub fn from_f64(inches: f64) -> Self {
        Self(I2F30::saturating_from_num(inches))
    }
    pub fn to_f64(self) -> f64 {
        self.0.to_num()
    }
    pub fn to_uin(self) -> f64 {
        self.to_f64() * UIN_PER_IN
    }
    pub fn saturating_add(self, rhs: Self) -> Self {
        Self(self.0.saturating_add(rhs.0))
    }
    pub fn saturating_sub(self, rhs: Self) -> Self {
        Self(self.0.saturating_sub(rhs.0))
    }
    pub fn saturating_neg(self) -> Self {
        Self(self.0.saturating_neg())
    }
}

impl SpindleAngle {
    /// Counts per turn as a float, for host-side conversions.
    const TURN: f64 = 4_294_967_296.0;

    /// From degrees (any real value; wraps). Host-side convenience.
    pub fn from_degrees(deg: f64) -> Self {
        // core has no `round`: round half away from zero by hand, then let the
        // i64 → u32 cast wrap modulo one turn, as an angle must.
        let counts = deg / 360.0 * Self::TURN;
        let rounded = if counts >= 0.0 {
            counts + 0.5
        } else {
            counts - 0.5
        } as i64;
        Self(rounded as u32)
    }
    pub fn to_degrees(self) -> f64 {
        f64::from(self.0) * 360.0 / Self::TURN
    }
    pub fn to_radians(self) -> f64 {
        f64::from(self.0) * core::f64::consts::TAU / Self::TURN
    }
    /// `k·φ`, wrapping: harmonics of the spindle angle are exact in this format.
    pub const fn times(self, k: u32) -> Self {
        Self(self.0.wrapping_mul(k))
    }
    pub const fn wrapping_add(self, rhs: Self) -> Self {
        Self(self.0.wrapping_add(rhs.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angle_degrees_round_trip_and_wrap() {
        for deg in [0.0, 10.0, 90.0, 180.0, 270.0, 350.0, 359.999] {
            let a = SpindleAngle::from_degrees(deg);
            assert!((a.to_degrees() - deg).abs() < 1e-6, "{deg}");
        }
        assert_eq!(SpindleAngle::from_degrees(360.0), SpindleAngle(0));
        assert_eq!(
            SpindleAngle::from_degrees(-90.0),
            SpindleAngle::from_degrees(270.0)
        );
        assert_eq!(SpindleAngle::from_degrees(90.0).times(4), SpindleAngle(0));
    }

    #[test]
    fn z_saturates_instead_of_wrapping() {
        assert_eq!(
            ZInches::MAX.saturating_add(ZInches::from_f64(1.0)),
            ZInches::MAX
        );
        assert_eq!(ZInches::MIN.saturating_neg(), ZInches::MAX);
        assert_eq!(ZInches::from_f64(10.0), ZInches::MAX);
    }

    #[test]
    fn lsb_sizes_match_documented_formats() {
        assert_eq!(ZInches::from_bits(1).to_f64(), 2f64.powi(-30));
        assert_eq!(XInches::from_bits(1).to_f64(), 2f64.powi(-24));
        // One microinch is about 1074 Z LSBs: far below the 0.1 µin goal.
        assert_eq!(ZInches::from_f64(1e-6).to_bits(), 1074);
    }

    mod prop {
        use super::*;
        use proptest::prelude::*;

        proptest! {
            /// Every X and Z value survives the trip through f64 exactly
            /// (both formats have fewer than 53 significant bits).
            #[test]
            fn fixed_to_f64_and_back_is_exact(bits in any::<i32>()) {
                prop_assert_eq!(XInches::from_f64(XInches::from_bits(bits).to_f64()).to_bits(), bits);
                prop_assert_eq!(ZInches::from_f64(ZInches::from_bits(bits).to_f64()).to_bits(), bits);
            }

            /// Conversion from inches is monotonic, nearest (within half an
            /// LSB inside the range) and saturating outside it.
            #[test]
            fn from_f64_is_monotonic_nearest_and_saturating(a in -300.0f64..300.0, b in -300.0f64..300.0) {
                let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
                prop_assert!(XInches::from_f64(lo) <= XInches::from_f64(hi));
                prop_assert!(ZInches::from_f64(lo / 100.0) <= ZInches::from_f64(hi / 100.0));
                let x = XInches::from_f64(a).to_f64();
                if a.abs() < 127.999 {
                    prop_assert!((x - a).abs() <= 0.5 / 16_777_216.0);
                } else if a.abs() >= 128.0 {
                    prop_assert!((x.abs() - 128.0).abs() <= 1.0 / 16_777_216.0);
                }
                let z = ZInches::from_f64(a / 100.0).to_f64();
                if a.abs() < 199.999 {
                    prop_assert!((z - a / 100.0).abs() <= 0.5 / 1_073_741_824.0);
                } else if a.abs() >= 200.0 {
                    prop_assert!((z.abs() - 2.0).abs() <= 1.0 / 1_073_741_824.0);
                }
            }

            /// A binary angle survives degrees and back; whole turns added
            /// in degrees change nothing (the format wraps like an angle).
            #[test]
            fn angle_degrees_round_trip_and_turns(a in any::<u32>(), turns in -5i32..5) {
                let deg = SpindleAngle(a).to_degrees();
                prop_assert_eq!(SpindleAngle::from_degrees(deg), SpindleAngle(a));
                let d = SpindleAngle::from_degrees(deg + 360.0 * f64::from(turns)).0.wrapping_sub(a);
                prop_assert!(d.min(d.wrapping_neg()) <= 1, "{} counts", d);
                prop_assert!((SpindleAngle(a).to_radians() - deg.to_radians()).abs() < 1e-12);
            }
        }
    }
}
