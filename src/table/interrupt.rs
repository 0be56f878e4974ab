//! The interruption block: where the part's face is interrupted (bolt
//! holes), as the firmware receives it beside its coefficient table.
//!
//! Chapter 5: at each hole edge the cutting force vanishes or returns at
//! once. The part program knows every interruption; this block carries
//! them to the firmware, checked like the table: a magic, a version, limits
//! on every field, a CRC-32 (the table's, ISO-HDLC) over everything before
//! it, and no trailing bytes. A bad block is refused with an
//! [`InterruptError`] that says in words what is wrong; nothing in it is
//! dropped or clipped.
//!
//! # Format, version 1 (all integers little-endian)
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | `[u8; 4]` | magic `b"ZSIB"` |
//! | 4 | `u16` | format version, = 1 |
//! | 6 | `u16` | hole count, 0..=[`MAX_HOLES`] |
//! | 8 | `[u8; 4]` | reserved, zero |
//! | 12 | 12 bytes × count | holes (below) |
//! | end − 4 | `u32` | CRC-32 (ISO-HDLC) of every byte before it |
//!
//! A hole:
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | `u32` | centre radius, µin, 1..=[`MAX_RADIUS_UIN`] |
//! | 4 | `u32` | centre angle, the firmware's spindle angle ([`SpindleAngle`], 2³² a turn) |
//! | 8 | `u32` | diameter at the surface, µin, 1..=[`MAX_DIAMETER_UIN`], less than twice the centre radius (a hole may not cover the axis) |
//!
//! The angle is the firmware's own (the index defines its zero, and it
//! increases with time): the part program converts the part drawing's
//! angles, as the table's command is in that angle too.

use super::crc32;
use crate::units::SpindleAngle;

pub const MAGIC: [u8; 4] = *b"ZSIB";
pub const FORMAT_VERSION: u16 = 1;
pub const HEADER_LEN: usize = 12;
pub const HOLE_LEN: usize = 12;
/// Most holes a block may carry (a bolt circle of 32 is far beyond a
/// faceplate's).
pub const MAX_HOLES: usize = 32;
/// Largest centre radius, µin (10 in: beyond the slide's travel in X).
pub const MAX_RADIUS_UIN: u32 = 10_000_000;
/// Largest diameter, µin (4 in).
pub const MAX_DIAMETER_UIN: u32 = 4_000_000;

/// One interruption: a round hole in the face.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Hole {
    pub centre_radius_uin: u32,
    pub angle: SpindleAngle,
    pub diameter_uin: u32,
}

/// A checked block's holes (no allocation: a fixed array and its count).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Interruptions {
    holes: [Hole; MAX_HOLES],
    count: usize,
}

impl Default for Interruptions {
    fn default() -> Self {
        Self::NONE
    }
}

/// Why a block is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum InterruptError {
    /// Shorter than its header and CRC, or than the count it states.
    Truncated {
        len: usize,
        need: usize,
    },
    /// Longer than the count it states.
    TrailingBytes {
        len: usize,
        expected: usize,
    },
    BadMagic,
    UnsupportedVersion(u16),
    TooManyHoles(u16),
    ReservedNotZero,
    BadCrc {
        stored: u32,
        computed: u32,
    },
    /// Hole `index`'s centre radius is 0 or beyond the limit.
    RadiusOutOfRange {
        index: usize,
        radius_uin: u32,
    },
    /// Hole `index`'s diameter is 0 or beyond the limit.
    DiameterOutOfRange {
        index: usize,
        diameter_uin: u32,
    },
    /// Hole `index` would cover the axis (diameter ≥ 2 × radius).
    CoversTheAxis {
        index: usize,
    },
}

impl core::fmt::Display for InterruptError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Truncated { len, need } => write!(
                f,
                "interruption block truncated: {len} bytes, its header and holes need {need}"
            ),
            Self::TrailingBytes { len, expected } => write!(
                f,
                "interruption block has {} bytes after its CRC ({len} bytes, {expected} expected)",
                len - expected
            ),
            Self::BadMagic => write!(f, "not an interruption block (magic is not ZSIB)"),
            Self::UnsupportedVersion(v) => write!(
                f,
                "interruption block version {v}: this firmware reads version {FORMAT_VERSION}"
            ),
            Self::TooManyHoles(n) => write!(
                f,
                "interruption block lists {n} holes: at most {MAX_HOLES}"
            ),
            Self::ReservedNotZero => write!(f, "interruption block: reserved bytes 8..12 not zero"),
            Self::BadCrc { stored, computed } => write!(
                f,
                "interruption block CRC mismatch: stored {stored:#010x}, computed {computed:#010x}"
            ),
            Self::RadiusOutOfRange { index, radius_uin } => write!(
                f,
                "interruption block: hole {index} centre radius {radius_uin} µin outside 1..={MAX_RADIUS_UIN}"
            ),
            Self::DiameterOutOfRange {
                index,
                diameter_uin,
            } => write!(
                f,
                "interruption block: hole {index} diameter {diameter_uin} µin outside 1..={MAX_DIAMETER_UIN}"
            ),
            Self::CoversTheAxis { index } => write!(
                f,
                "interruption block: hole {index} covers the axis (its diameter is at least twice its centre radius)"
            ),
        }
    }
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    let mut w = [0u8; 2];
    w.copy_from_slice(&b[at..at + 2]);
    u16::from_le_bytes(w)
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    let mut w = [0u8; 4];
    w.copy_from_slice(&b[at..at + 4]);
    u32::from_le_bytes(w)
}

impl Interruptions {
    /// No interruption: the face is whole.
    pub const NONE: Self = Self {
        holes: [Hole {
            centre_radius_uin: 0,
            angle: SpindleAngle(0),
            diameter_uin: 0,
        }; MAX_HOLES],
        count: 0,
    };

    /// Checks and reads a block (never panics: every index below is
    /// within a length checked first).
    pub fn parse(b: &[u8]) -> Result<Self, InterruptError> {
        let min = HEADER_LEN + 4;
        if b.len() < min {
            return Err(InterruptError::Truncated {
                len: b.len(),
                need: min,
            });
        }
        if b[0..4] != MAGIC {
            return Err(InterruptError::BadMagic);
        }
        let version = u16_at(b, 4);
        if version != FORMAT_VERSION {
            return Err(InterruptError::UnsupportedVersion(version));
        }
        let n = u16_at(b, 6);
        if usize::from(n) > MAX_HOLES {
            return Err(InterruptError::TooManyHoles(n));
        }
        let expected = HEADER_LEN + usize::from(n) * HOLE_LEN + 4;
        if b.len() < expected {
            return Err(InterruptError::Truncated {
                len: b.len(),
                need: expected,
            });
        }
        if b.len() > expected {
            return Err(InterruptError::TrailingBytes {
                len: b.len(),
                expected,
            });
        }
        let stored = u32_at(b, expected - 4);
        let computed = crc32(&b[..expected - 4]);
        if stored != computed {
            return Err(InterruptError::BadCrc { stored, computed });
        }
        if b[8..12] != [0; 4] {
            return Err(InterruptError::ReservedNotZero);
        }
        let mut out = Self::NONE;
        for index in 0..usize::from(n) {
            let at = HEADER_LEN + index * HOLE_LEN;
            let h = Hole {
                centre_radius_uin: u32_at(b, at),
                angle: SpindleAngle(u32_at(b, at + 4)),
                diameter_uin: u32_at(b, at + 8),
            };
            if h.centre_radius_uin == 0 || h.centre_radius_uin > MAX_RADIUS_UIN {
                return Err(InterruptError::RadiusOutOfRange {
                    index,
                    radius_uin: h.centre_radius_uin,
                });
            }
            if h.diameter_uin == 0 || h.diameter_uin > MAX_DIAMETER_UIN {
                return Err(InterruptError::DiameterOutOfRange {
                    index,
                    diameter_uin: h.diameter_uin,
                });
            }
            if u64::from(h.diameter_uin) >= 2 * u64::from(h.centre_radius_uin) {
                return Err(InterruptError::CoversTheAxis { index });
            }
            out.holes[index] = h;
        }
        out.count = usize::from(n);
        Ok(out)
    }

    /// The block at the start of a board's interruption region (flash:
    /// `ZSIB` in `memory.x`, written by `zslide table flash F.zsib`), the
    /// region's bytes after it ignored. An erased region (its header all
    /// 0xFF, or all zeros where QEMU's loader wrote nothing) holds no block:
    /// `Ok(None)`, a whole face. Anything else is [`Self::parse`]d, its
    /// length from its own count: a refusal is the block's.
    pub fn parse_region(region: &[u8]) -> Result<Option<Self>, InterruptError> {
        if let Some(h) = region.get(..HEADER_LEN) {
            if h.iter().all(|&b| b == 0xFF) || h.iter().all(|&b| b == 0) {
                return Ok(None);
            }
            let n = usize::from(u16_at(region, 6));
            if n <= MAX_HOLES {
                if let Some(block) = region.get(..HEADER_LEN + n * HOLE_LEN + 4) {
                    return Self::parse(block).map(Some);
                }
            }
        }
        Self::parse(region).map(Some)
    }

    /// The holes, in the block's order.
    pub fn holes(&self) -> &[Hole] {
        self.holes.get(..self.count).unwrap_or(&[])
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Writes the block of `holes` into `out` (returns its length), or
    /// `None` when `out` is too small or there are more than
    /// [`MAX_HOLES`]. The values are not checked here: [`Self::parse`] is
    /// the one check, on the writer's side too.
    pub fn encode(holes: &[Hole], out: &mut [u8]) -> Option<usize> {
        if holes.len() > MAX_HOLES {
            return None;
        }
        let len = HEADER_LEN + holes.len() * HOLE_LEN + 4;
        let out = out.get_mut(..len)?;
        out[0..4].copy_from_slice(&MAGIC);
        out[4..6].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
        out[6..8].copy_from_slice(&(holes.len() as u16).to_le_bytes());
        out[8..12].fill(0);
        for (k, h) in holes.iter().enumerate() {
            let at = HEADER_LEN + k * HOLE_LEN;
            out[at..at + 4].copy_from_slice(&h.centre_radius_uin.to_le_bytes());
            out[at + 4..at + 8].copy_from_slice(&h.angle.0.to_le_bytes());
            out[at + 8..at + 12].copy_from_slice(&h.diameter_uin.to_le_bytes());
        }
        let crc = crc32(&out[..len - 4]);
        out[len - 4..].copy_from_slice(&crc.to_le_bytes());
        Some(len)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;
    use super::*;

    fn eight() -> [Hole; 8] {
        core::array::from_fn(|k| Hole {
            centre_radius_uin: 3_500_000,
            angle: SpindleAngle((k as u32) << 29 | 1 << 28),
            diameter_uin: 750_000,
        })
    }

    fn block(holes: &[Hole]) -> ([u8; 512], usize) {
        let mut buf = [0u8; 512];
        let n = Interruptions::encode(holes, &mut buf).unwrap();
        (buf, n)
    }

    /// Rewrites the CRC after an edit, so that the field check is reached.
    fn recrc(b: &mut [u8]) {
        let n = b.len();
        let c = crc32(&b[..n - 4]);
        b[n - 4..].copy_from_slice(&c.to_le_bytes());
    }

    #[test]
    fn a_block_reads_back_the_holes_written() {
        let (b, n) = block(&eight());
        assert_eq!(n, 12 + 8 * 12 + 4);
        let i = Interruptions::parse(&b[..n]).unwrap();
        assert_eq!(i.holes(), &eight());
        let (e, m) = block(&[]);
        assert!(Interruptions::parse(&e[..m]).unwrap().is_empty());
    }

    #[test]
    fn every_malformed_field_is_refused_with_its_reason() {
        let (b, n) = block(&eight());
        let good = &b[..n];
        let mut flipped = std::vec::Vec::from(good);
        flipped[20] ^= 1;
        assert!(matches!(
            Interruptions::parse(&flipped),
            Err(InterruptError::BadCrc { .. })
        ));
        assert_eq!(
            Interruptions::parse(&good[..n - 1]),
            Err(InterruptError::Truncated {
                len: n - 1,
                need: n
            })
        );
        let mut long = std::vec::Vec::from(good);
        long.push(0);
        assert_eq!(
            Interruptions::parse(&long),
            Err(InterruptError::TrailingBytes {
                len: n + 1,
                expected: n
            })
        );
        let mut magic = std::vec::Vec::from(good);
        magic[0] = b'X';
        assert_eq!(Interruptions::parse(&magic), Err(InterruptError::BadMagic));
        let mut version = std::vec::Vec::from(good);
        version[4] = 2;
        assert_eq!(
            Interruptions::parse(&version),
            Err(InterruptError::UnsupportedVersion(2))
        );
        let mut many = std::vec::Vec::from(good);
        many[6] = 33;
        assert_eq!(
            Interruptions::parse(&many),
            Err(InterruptError::TooManyHoles(33))
        );
        let mut reserved = std::vec::Vec::from(good);
        reserved[9] = 1;
        recrc(&mut reserved);
        assert_eq!(
            Interruptions::parse(&reserved),
            Err(InterruptError::ReservedNotZero)
        );
        let mut h = eight();
        h[3].centre_radius_uin = 0;
        let (z, m) = block(&h);
        assert_eq!(
            Interruptions::parse(&z[..m]),
            Err(InterruptError::RadiusOutOfRange {
                index: 3,
                radius_uin: 0
            })
        );
        let mut h = eight();
        h[5].diameter_uin = MAX_DIAMETER_UIN + 1;
        let (z, m) = block(&h);
        assert!(matches!(
            Interruptions::parse(&z[..m]),
            Err(InterruptError::DiameterOutOfRange { index: 5, .. })
        ));
        let mut h = eight();
        h[1].centre_radius_uin = 300_000;
        h[1].diameter_uin = 600_000;
        let (z, m) = block(&h);
        assert_eq!(
            Interruptions::parse(&z[..m]),
            Err(InterruptError::CoversTheAxis { index: 1 })
        );
    }

    #[test]
    fn a_region_holds_the_block_at_its_start_or_none_when_erased() {
        let (b, n) = block(&eight());
        for fill in [0xFF, 0x00] {
            let mut region = [fill; 4096];
            assert_eq!(Interruptions::parse_region(&region), Ok(None));
            region[..n].copy_from_slice(&b[..n]);
            let got = Interruptions::parse_region(&region).unwrap().unwrap();
            assert_eq!(got.holes(), &eight()[..]);
            // A damaged block in the region is refused, not taken for none.
            region[HEADER_LEN + 1] ^= 1;
            assert!(matches!(
                Interruptions::parse_region(&region),
                Err(InterruptError::BadCrc { .. })
            ));
        }
        // A count beyond the limit, or a block longer than its region.
        let mut region = [0xFF; 64];
        region[..n.min(64)].copy_from_slice(&b[..n.min(64)]);
        assert!(matches!(
            Interruptions::parse_region(&region),
            Err(InterruptError::Truncated { len: 64, .. })
        ));
        region[6..8].copy_from_slice(&40u16.to_le_bytes());
        assert_eq!(
            Interruptions::parse_region(&region),
            Err(InterruptError::TooManyHoles(40))
        );
    }

    #[test]
    fn a_refusal_reads_as_words() {
        let s = std::format!("{}", InterruptError::CoversTheAxis { index: 2 });
        assert!(s.contains("hole 2 covers the axis"), "{s}");
    }
}
