//! The coefficient table in flash: byte format, parser, and encoder.
//!
//! The table replaces the 1983 EPROM. It holds, at each node of a uniform X
//! grid, the coefficients of a series in the spindle angle φ. The parser is
//! zero-copy (the table stays in flash) and never panics: every way a byte
//! image can be wrong is a distinct [`TableError`], and the firmware refuses a
//! bad table with a fault and a nulled slide.
//!
//! # Format, version 1 (all integers little-endian)
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | `[u8; 4]` | magic `b"ZSCT"` |
//! | 4 | `u16` | format version, = 1 |
//! | 6 | `u16` | header length, = 64 |
//! | 8 | `u8` | representation: 0 = sin-power, 1 = harmonic |
//! | 9 | `u8` | terms per node (columns), 1..=[`MAX_TERMS`] |
//! | 10 | `u8` | coefficient fraction bits `fc`, 0..=31 |
//! | 11 | `u8` | X fraction bits `fx`, 0..=31 |
//! | 12 | `u8` | length unit: 0 = inch |
//! | 13 | `[u8; 3]` | reserved, zero |
//! | 16 | `u32` | node count, 2..=[`MAX_NODES`] |
//! | 20 | `i32` | X of node 0, `fx` fraction bits |
//! | 24 | `i32` | grid step ΔX > 0, `fx` fraction bits |
//! | 28 | `i32` | X beyond which the slide is nulled, `fx` fraction bits |
//! | 32 | `i64` | geometry: parabola parameter c (x²+y² = c·z), nano-units |
//! | 40 | `i64` | geometry: off-axis distance S_y, nano-units |
//! | 48 | `i64` | geometry: tool-nose radius r_t, nano-units |
//! | 56 | `u32` | CRC-32 (ISO-HDLC) of the payload |
//! | 60 | `u32` | CRC-32 (ISO-HDLC) of header bytes 0..60 |
//!
//! The payload follows: `node count × terms` `i32` coefficients with `fc`
//! fraction bits (units of the length unit), node-major. Nothing may follow
//! the payload: trailing bytes are an error, not silently ignored.
//!
//! # In a flash region
//!
//! The boards keep the table in a flash region of its own, written without
//! rebuilding the firmware (`zslide table flash`, `docs/BOARD.md`).
//! [`CoeffTable::parse_region`] reads such a region: the image is the
//! prefix the header describes (what follows it is erased flash); a region
//! whose whole header is erased (0xFF, flash) or zero (QEMU's RAM that no
//! loader wrote) holds no table, [`TableError::Missing`]. There is no
//! fallback to a built-in table: a machine must cut the part the machinist
//! flashed or none (the decision and its reasons: `docs/BOARD.md`).
//!
//! Column `j` of a node means, for the two representations (φ of eq 2-5):
//! * sin-power: `Z = Σ_j c_j sin^j φ` (eq 2-19 is the four-column case C00..C03);
//! * harmonic: column 0 is `C_0`, then `C_k, S_k` pairs for k = 1.. :
//!   `Z = C_0 + Σ_k C_k cos kφ + S_k sin kφ` (eq 2-17); the column count is odd.

pub mod interp;
pub mod interrupt;

use crate::units::XInches;
use crc::{Crc, CRC_32_ISO_HDLC};
use fixed::types::I8F24;

pub const MAGIC: [u8; 4] = *b"ZSCT";
pub const FORMAT_VERSION: u16 = 1;
pub const HEADER_LEN: usize = 64;
/// Largest grid accepted: 8 in at 0.001 in, far more than any sensible table.
pub const MAX_NODES: u32 = 8192;
/// Largest number of columns: 0..=15 harmonics, or sin powers 0..=30.
pub const MAX_TERMS: u8 = 31;

pub(crate) const CRC32: Crc<u32> = Crc::<u32>::new(&CRC_32_ISO_HDLC);

/// CRC-32/ISO-HDLC (the zlib/PNG CRC), the table's checksum.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// How a node's columns combine with the spindle angle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Representation {
    /// `Z = Σ_j c_j sin^j φ` (eq 2-19).
    SinPower = 0,
    /// `Z = C_0 + Σ_k C_k cos kφ + S_k sin kφ` (eq 2-17).
    Harmonic = 1,
}

/// Why a byte image is not a usable table. Each is a distinct, named failure.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum TableError {
    /// The table region holds no table: its header bytes are all erased
    /// (0xFF) or all zero. Only [`CoeffTable::parse_region`] reports it.
    Missing,
    /// Fewer bytes than the header, or than the header says the payload needs.
    Truncated {
        needed: u32,
        got: u32,
    },
    /// Bytes left after the payload.
    TrailingBytes {
        expected: u32,
        got: u32,
    },
    BadMagic,
    UnsupportedVersion(u16),
    BadHeaderLength(u16),
    HeaderCrc {
        stored: u32,
        computed: u32,
    },
    PayloadCrc {
        stored: u32,
        computed: u32,
    },
    UnknownRepresentation(u8),
    UnknownUnit(u8),
    ReservedNotZero,
    /// Node count, column count or fraction bits outside what the format allows.
    AbsurdSize,
    /// Harmonic tables need an odd column count (C_0, then C_k/S_k pairs).
    HarmonicColumnsNotOdd(u8),
    /// ΔX ≤ 0: the grid must increase strictly.
    NonMonotonicGrid,
    /// ΔX below one LSB of the core's X format (`x_frac_bits` > 24): nodes
    /// would coincide once X is in `I8F24`, and an interval of zero width
    /// has no interpolation.
    GridStepBelowResolution,
    /// The last node's X does not fit the X format.
    GridOverflow,
    /// The null-zone start lies outside the grid.
    NullZoneOutsideGrid,
    /// A geometry field is not positive (c, S_y) or negative (r_t).
    BadGeometry,
    /// The table parses but its command is positive somewhere (a correct
    /// command has max over φ of Z = 0, Z ≤ 0): wrong sign convention or a
    /// table for another surface. Found by the firmware's load check.
    SignCheck,
}

/// The refusal in words, for a machinist reading a log or a terminal.
impl core::fmt::Display for TableError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            TableError::Missing => f.write_str(
                "no coefficient table in the table region (erased, or never written): write one with `zslide table flash FILE.zsct`",
            ),
            TableError::Truncated { needed, got } => write!(
                f,
                "the image is cut short: {got} bytes where {needed} are needed"
            ),
            TableError::TrailingBytes { expected, got } => write!(
                f,
                "{got} bytes where the header describes {expected}: extra bytes after the coefficients"
            ),
            TableError::BadMagic => f.write_str("not a coefficient table (the file does not start with the table's magic)"),
            TableError::UnsupportedVersion(v) => {
                write!(f, "table format version {v} is not one this firmware reads")
            }
            TableError::BadHeaderLength(n) => {
                write!(f, "header length {n} bytes is not this format version's")
            }
            TableError::HeaderCrc { stored, computed } => write!(
                f,
                "the header is corrupt: its CRC says {stored:#010x}, its bytes give {computed:#010x}"
            ),
            TableError::PayloadCrc { stored, computed } => write!(
                f,
                "the coefficients are corrupt: their CRC says {stored:#010x}, their bytes give {computed:#010x}"
            ),
            TableError::UnknownRepresentation(r) => {
                write!(f, "unknown series representation code {r} (sin-power or harmonic expected)")
            }
            TableError::UnknownUnit(u) => write!(f, "unknown length unit code {u}"),
            TableError::ReservedNotZero => f.write_str("reserved header bytes are not zero"),
            TableError::AbsurdSize => f.write_str(
                "node count, column count or fraction bits outside what the format allows",
            ),
            TableError::HarmonicColumnsNotOdd(n) => write!(
                f,
                "a harmonic table needs an odd number of columns (C0, then C_k/S_k pairs); it has {n}"
            ),
            TableError::NonMonotonicGrid => f.write_str("the X grid does not increase (step <= 0)"),
            TableError::GridStepBelowResolution => f.write_str(
                "the X grid step is finer than the firmware's X resolution (2^-24 in): nodes would coincide",
            ),
            TableError::GridOverflow => {
                f.write_str("the last node's X does not fit the firmware's X format")
            }
            TableError::NullZoneOutsideGrid => f.write_str("the null-zone start lies outside the X grid"),
            TableError::BadGeometry => f.write_str(
                "a geometry field is out of range (c and S_y must be positive, the tool radius not negative)",
            ),
            TableError::SignCheck => f.write_str(
                "the command is positive somewhere (Z must be <= 0 everywhere): a reversed sign convention, or a table for another surface",
            ),
        }
    }
}

/// Everything in the header, decoded and checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct TableHeader {
    pub representation: Representation,
    pub terms: u8,
    pub coeff_frac_bits: u8,
    pub x_frac_bits: u8,
    pub node_count: u32,
    /// Raw X of node 0, `x_frac_bits` fraction bits.
    pub x0_raw: i32,
    /// Raw ΔX, `x_frac_bits` fraction bits.
    pub dx_raw: i32,
    /// Raw null-zone start, `x_frac_bits` fraction bits.
    pub x_null_raw: i32,
    pub geometry: Geometry,
}

/// Surface geometry the table was generated for, in nano-inches. Carried for
/// traceability: a table always says which part it cuts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Geometry {
    pub c_nin: i64,
    pub s_y_nin: i64,
    pub tool_radius_nin: i64,
}

/// A checked table: header plus a borrowed payload, read in place.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoeffTable<'a> {
    header: TableHeader,
    payload: &'a [u8],
    /// The header's own CRC (bytes 60..64): it covers the payload CRC too,
    /// so it names the whole image.
    image_crc: u32,
}

/// What a table is, in a few numbers: the part it cuts (geometry), its
/// grid and series, and the CRC that names the image. The firmware
/// reports it at boot and over the host link; `zslide table flash`
/// prints the same for the file, so the two can be compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct TableIdentity {
    pub geometry: Geometry,
    pub representation: Representation,
    pub terms: u8,
    pub node_count: u32,
    /// X of node 0, grid step and null-zone start, I8F24 inches.
    pub x0_bits: i32,
    pub dx_bits: i32,
    pub x_null_bits: i32,
    /// Bytes of the image.
    pub len: u32,
    /// CRC-32 of the header (which holds the payload's CRC): the image's name.
    pub crc: u32,
}

impl core::fmt::Display for TableIdentity {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let inch = |bits: i32| f64::from(bits) / f64::from(1u32 << 24);
        let nin = |v: i64| v as f64 / 1e9;
        write!(
            f,
            "c = {} in, S_y = {} in, tool radius {} in; {} {} terms, {} nodes, X {:.6} .. {:.6} in (step {:.6} in), null beyond {:.6} in; {} bytes, CRC {:#010x}",
            nin(self.geometry.c_nin),
            nin(self.geometry.s_y_nin),
            nin(self.geometry.tool_radius_nin),
            match self.representation {
                Representation::SinPower => "sin-power",
                Representation::Harmonic => "harmonic",
            },
            self.terms,
            self.node_count,
            inch(self.x0_bits),
            inch(self.x0_bits.saturating_add(self.dx_bits.saturating_mul(self.node_count.saturating_sub(1) as i32))),
            inch(self.dx_bits),
            inch(self.x_null_bits),
            self.len,
            self.crc
        )
    }
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}
fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}
fn i32_at(b: &[u8], at: usize) -> i32 {
    u32_at(b, at) as i32
}
fn i64_at(b: &[u8], at: usize) -> i64 {
    (u64::from(u32_at(b, at)) | (u64::from(u32_at(b, at + 4)) << 32)) as i64
}

/// Converts a raw X with `frac` fraction bits to `I8F24`, or `None` if it does
/// not fit.
fn x_from_raw(raw: i32, frac: u8) -> Option<XInches> {
    let shift = i32::from(frac) - 24;
    let bits = if shift >= 0 {
        // Round half up when dropping fraction bits.
        let v = i64::from(raw);
        if shift == 0 {
            v
        } else {
            (v + (1 << (shift - 1))) >> shift
        }
    } else {
        i64::from(raw) << (-shift)
    };
    i32::try_from(bits)
        .ok()
        .map(|b| XInches(I8F24::from_bits(b)))
}

impl<'a> CoeffTable<'a> {
    /// Checks a byte image and returns the table, or the first thing wrong
    /// with it. Checks run in an order where each error is meaningful: size,
    /// magic, version, header CRC, field sanity, payload size, payload CRC.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, TableError> {
        let got = u32::try_from(bytes.len()).unwrap_or(u32::MAX);
        if bytes.len() < HEADER_LEN {
            return Err(TableError::Truncated {
                needed: HEADER_LEN as u32,
                got,
            });
        }
        if bytes[0..4] != MAGIC {
            return Err(TableError::BadMagic);
        }
        let version = u16_at(bytes, 4);
        if version != FORMAT_VERSION {
            return Err(TableError::UnsupportedVersion(version));
        }
        let header_len = u16_at(bytes, 6);
        if usize::from(header_len) != HEADER_LEN {
            return Err(TableError::BadHeaderLength(header_len));
        }
        let stored = u32_at(bytes, 60);
        let computed = crc32(&bytes[0..60]);
        if stored != computed {
            return Err(TableError::HeaderCrc { stored, computed });
        }
        let representation = match bytes[8] {
            0 => Representation::SinPower,
            1 => Representation::Harmonic,
            other => return Err(TableError::UnknownRepresentation(other)),
        };
        let terms = bytes[9];
        let coeff_frac_bits = bytes[10];
        let x_frac_bits = bytes[11];
        if bytes[12] != 0 {
            return Err(TableError::UnknownUnit(bytes[12]));
        }
        if bytes[13..16] != [0, 0, 0] {
            return Err(TableError::ReservedNotZero);
        }
        let node_count = u32_at(bytes, 16);
        if terms == 0
            || terms > MAX_TERMS
            || coeff_frac_bits > 31
            || x_frac_bits > 31
            || !(2..=MAX_NODES).contains(&node_count)
        {
            return Err(TableError::AbsurdSize);
        }
        if representation == Representation::Harmonic && terms.is_multiple_of(2) {
            return Err(TableError::HarmonicColumnsNotOdd(terms));
        }
        let x0_raw = i32_at(bytes, 20);
        let dx_raw = i32_at(bytes, 24);
        let x_null_raw = i32_at(bytes, 28);
        if dx_raw <= 0 {
            return Err(TableError::NonMonotonicGrid);
        }
        // Node X values rounded to I8F24 from raw values ≥ 2^(fx−24) apart
        // differ by at least one LSB; closer ones can round together.
        if x_frac_bits > 24 && dx_raw < 1 << (x_frac_bits - 24) {
            return Err(TableError::GridStepBelowResolution);
        }
        let last = i64::from(x0_raw) + i64::from(dx_raw) * i64::from(node_count - 1);
        let last_raw = i32::try_from(last).map_err(|_| TableError::GridOverflow)?;
        if x_from_raw(x0_raw, x_frac_bits).is_none() || x_from_raw(last_raw, x_frac_bits).is_none()
        {
            return Err(TableError::GridOverflow);
        }
        if x_null_raw < x0_raw || x_null_raw > last_raw {
            return Err(TableError::NullZoneOutsideGrid);
        }
        let geometry = Geometry {
            c_nin: i64_at(bytes, 32),
            s_y_nin: i64_at(bytes, 40),
            tool_radius_nin: i64_at(bytes, 48),
        };
        if geometry.c_nin <= 0 || geometry.s_y_nin <= 0 || geometry.tool_radius_nin < 0 {
            return Err(TableError::BadGeometry);
        }
        // node_count ≤ 8192 and terms ≤ 31: the product cannot overflow.
        let payload_len = node_count as usize * usize::from(terms) * 4;
        let expected = HEADER_LEN + payload_len;
        if bytes.len() < expected {
            return Err(TableError::Truncated {
                needed: expected as u32,
                got,
            });
        }
        if bytes.len() > expected {
            return Err(TableError::TrailingBytes {
                expected: expected as u32,
                got,
            });
        }
        let payload = &bytes[HEADER_LEN..];
        let stored = u32_at(bytes, 56);
        let computed = crc32(payload);
        if stored != computed {
            return Err(TableError::PayloadCrc { stored, computed });
        }
        Ok(Self {
            image_crc: u32_at(bytes, 60),
            header: TableHeader {
                representation,
                terms,
                coeff_frac_bits,
                x_frac_bits,
                node_count,
                x0_raw,
                dx_raw,
                x_null_raw,
                geometry,
            },
            payload,
        })
    }

    /// Reads the table a flash region holds (module docs): the image is
    /// the prefix its header describes, the rest of the region is ignored.
    /// A region whose header bytes are all erased or all zero holds no
    /// table ([`TableError::Missing`]); anything else that is not a valid
    /// image is refused exactly as [`Self::parse`] refuses it (a header
    /// whose size fields are garbage is caught by its CRC first).
    pub fn parse_region(region: &'a [u8]) -> Result<Self, TableError> {
        if let Some(h) = region.get(..HEADER_LEN) {
            if h.iter().all(|&b| b == 0xFF) || h.iter().all(|&b| b == 0) {
                return Err(TableError::Missing);
            }
            let nodes = u32_at(region, 16);
            let terms = region[9];
            if nodes <= MAX_NODES && terms <= MAX_TERMS {
                let len = HEADER_LEN + nodes as usize * usize::from(terms) * 4;
                if let Some(image) = region.get(..len) {
                    return Self::parse(image);
                }
            }
        }
        Self::parse(region)
    }

    /// The numbers that identify this table (geometry, grid, CRC).
    pub fn identity(&self) -> TableIdentity {
        let h = &self.header;
        TableIdentity {
            geometry: h.geometry,
            representation: h.representation,
            terms: h.terms,
            node_count: h.node_count,
            x0_bits: self.node_x(0).to_bits(),
            dx_bits: self
                .node_x(1)
                .to_bits()
                .wrapping_sub(self.node_x(0).to_bits()),
            x_null_bits: self.x_null().to_bits(),
            len: h.image_len() as u32,
            crc: self.image_crc,
        }
    }

    pub fn header(&self) -> &TableHeader {
        &self.header
    }
    pub fn node_count(&self) -> u32 {
        self.header.node_count
    }
    pub fn terms(&self) -> u8 {
        self.header.terms
    }
    pub fn representation(&self) -> Representation {
        self.header.representation
    }

    /// X of node `i` (saturating past the last node), in the core's X format.
    pub fn node_x(&self, i: u32) -> XInches {
        let i = i.min(self.header.node_count - 1);
        // Lies between node 0 and the last node, both range-checked at parse.
        let raw = i64::from(self.header.x0_raw) + i64::from(self.header.dx_raw) * i64::from(i);
        x_from_raw(raw as i32, self.header.x_frac_bits).unwrap_or(XInches::ZERO)
    }

    /// Start of the null zone: for X beyond it the command is zero.
    pub fn x_null(&self) -> XInches {
        x_from_raw(self.header.x_null_raw, self.header.x_frac_bits).unwrap_or(XInches::ZERO)
    }

    /// The raw bytes of one node's row (`terms` little-endian `i32`s), or an
    /// empty slice past the last node. Lets a reader that needs several
    /// columns of two adjacent nodes check bounds once per row instead of
    /// once per value (the interpolator's hot path).
    pub fn node_row(&self, node: u32) -> &'a [u8] {
        let w = usize::from(self.header.terms) * 4;
        let at = (node as usize).saturating_mul(w);
        self.payload.get(at..at.saturating_add(w)).unwrap_or(&[])
    }

    /// Raw coefficient at (node, column), `coeff_frac_bits` fraction bits.
    /// Out-of-range indices read as zero rather than panicking.
    pub fn coeff_raw(&self, node: u32, column: u8) -> i32 {
        if node >= self.header.node_count || column >= self.header.terms {
            return 0;
        }
        let at = (node as usize * usize::from(self.header.terms) + usize::from(column)) * 4;
        i32_at(self.payload, at)
    }
}

impl TableHeader {
    /// Bytes of the whole image this header describes.
    pub fn image_len(&self) -> usize {
        HEADER_LEN + self.node_count as usize * usize::from(self.terms) * 4
    }

    /// Writes header and payload into `out`, computing both CRCs. The payload
    /// is node-major, `node_count × terms` values. Returns the bytes written.
    /// This is the one writer of the format: the host generator calls it, so
    /// the parser and the writer cannot drift apart.
    pub fn encode(&self, payload: &[i32], out: &mut [u8]) -> Result<usize, TableError> {
        let len = self.image_len();
        if payload.len() != self.node_count as usize * usize::from(self.terms) {
            return Err(TableError::AbsurdSize);
        }
        if out.len() < len {
            return Err(TableError::Truncated {
                needed: len as u32,
                got: out.len() as u32,
            });
        }
        let out = &mut out[..len];
        out[0..4].copy_from_slice(&MAGIC);
        out[4..6].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
        out[6..8].copy_from_slice(&(HEADER_LEN as u16).to_le_bytes());
        out[8] = self.representation as u8;
        out[9] = self.terms;
        out[10] = self.coeff_frac_bits;
        out[11] = self.x_frac_bits;
        out[12] = 0;
        out[13..16].copy_from_slice(&[0, 0, 0]);
        out[16..20].copy_from_slice(&self.node_count.to_le_bytes());
        out[20..24].copy_from_slice(&self.x0_raw.to_le_bytes());
        out[24..28].copy_from_slice(&self.dx_raw.to_le_bytes());
        out[28..32].copy_from_slice(&self.x_null_raw.to_le_bytes());
        out[32..40].copy_from_slice(&self.geometry.c_nin.to_le_bytes());
        out[40..48].copy_from_slice(&self.geometry.s_y_nin.to_le_bytes());
        out[48..56].copy_from_slice(&self.geometry.tool_radius_nin.to_le_bytes());
        for (chunk, v) in out[HEADER_LEN..].chunks_exact_mut(4).zip(payload) {
            chunk.copy_from_slice(&v.to_le_bytes());
        }
        let payload_crc = crc32(&out[HEADER_LEN..]);
        out[56..60].copy_from_slice(&payload_crc.to_le_bytes());
        let header_crc = crc32(&out[0..60]);
        out[60..64].copy_from_slice(&header_crc.to_le_bytes());
        Ok(len)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec;
    use std::vec::Vec;

    fn header(nodes: u32, terms: u8) -> TableHeader {
        TableHeader {
            representation: Representation::SinPower,
            terms,
            coeff_frac_bits: 30,
            x_frac_bits: 24,
            node_count: nodes,
            x0_raw: 0,
            dx_raw: 1 << 24 >> 3, // 0.125 in
            x_null_raw: (1 << 24) * 7 / 10,
            geometry: Geometry {
                c_nin: 316_700_000_000,
                s_y_nin: 28_000_000_000,
                tool_radius_nin: 125_000_000,
            },
        }
    }

    fn image(h: &TableHeader) -> Vec<u8> {
        let payload: Vec<i32> = (0..h.node_count as i32 * i32::from(h.terms))
            .map(|i| i * 7919 - 100_000)
            .collect();
        let mut out = vec![0u8; h.image_len()];
        h.encode(&payload, &mut out).unwrap();
        out
    }

    /// Rewrites a header field and fixes up the header CRC, so that the check
    /// under test is the one that fires, not the CRC.
    fn patch(img: &mut [u8], at: usize, bytes: &[u8]) {
        img[at..at + bytes.len()].copy_from_slice(bytes);
        let crc = crc32(&img[0..60]);
        img[60..64].copy_from_slice(&crc.to_le_bytes());
    }

    #[test]
    fn round_trip_is_exact() {
        let h = header(9, 4);
        let img = image(&h);
        let t = CoeffTable::parse(&img).unwrap();
        assert_eq!(*t.header(), h);
        for n in 0..9 {
            for c in 0..4 {
                assert_eq!(
                    t.coeff_raw(n, c),
                    (n as i32 * 4 + i32::from(c)) * 7919 - 100_000
                );
            }
        }
        assert_eq!(t.node_x(8).to_f64(), 1.0);
        assert_eq!(t.coeff_raw(9, 0), 0);
        assert_eq!(t.coeff_raw(0, 4), 0);
    }

    #[test]
    fn each_defect_has_its_own_error() {
        let h = header(9, 4);
        let good = image(&h);
        let n = good.len() as u32;

        assert_eq!(
            CoeffTable::parse(&good[..10]),
            Err(TableError::Truncated {
                needed: 64,
                got: 10
            })
        );
        assert_eq!(
            CoeffTable::parse(&good[..good.len() - 1]),
            Err(TableError::Truncated {
                needed: n,
                got: n - 1
            })
        );
        let mut long = good.clone();
        long.push(0);
        assert_eq!(
            CoeffTable::parse(&long),
            Err(TableError::TrailingBytes {
                expected: n,
                got: n + 1
            })
        );

        let mut m = good.clone();
        m[0] = b'X';
        assert_eq!(CoeffTable::parse(&m), Err(TableError::BadMagic));

        let mut m = good.clone();
        patch(&mut m, 4, &2u16.to_le_bytes());
        assert_eq!(
            CoeffTable::parse(&m),
            Err(TableError::UnsupportedVersion(2))
        );

        let mut m = good.clone();
        patch(&mut m, 6, &32u16.to_le_bytes());
        assert_eq!(CoeffTable::parse(&m), Err(TableError::BadHeaderLength(32)));

        let mut m = good.clone();
        m[17] ^= 1;
        assert!(matches!(
            CoeffTable::parse(&m),
            Err(TableError::HeaderCrc { .. })
        ));

        let mut m = good.clone();
        m[HEADER_LEN + 5] ^= 0x10;
        assert!(matches!(
            CoeffTable::parse(&m),
            Err(TableError::PayloadCrc { .. })
        ));

        let mut m = good.clone();
        patch(&mut m, 8, &[7]);
        assert_eq!(
            CoeffTable::parse(&m),
            Err(TableError::UnknownRepresentation(7))
        );

        let mut m = good.clone();
        patch(&mut m, 12, &[3]);
        assert_eq!(CoeffTable::parse(&m), Err(TableError::UnknownUnit(3)));

        let mut m = good.clone();
        patch(&mut m, 14, &[1]);
        assert_eq!(CoeffTable::parse(&m), Err(TableError::ReservedNotZero));

        for (at, bytes) in [
            (9usize, vec![0u8]),
            (9, vec![32]),
            (10, vec![32]),
            (16, 1u32.to_le_bytes().to_vec()),
            (16, (MAX_NODES + 1).to_le_bytes().to_vec()),
        ] {
            let mut m = good.clone();
            patch(&mut m, at, &bytes);
            assert_eq!(
                CoeffTable::parse(&m),
                Err(TableError::AbsurdSize),
                "field at {at}"
            );
        }

        let mut m = good.clone();
        patch(&mut m, 8, &[1]);
        assert_eq!(
            CoeffTable::parse(&m),
            Err(TableError::HarmonicColumnsNotOdd(4))
        );

        for dx in [0i32, -(1 << 21)] {
            let mut m = good.clone();
            patch(&mut m, 24, &dx.to_le_bytes());
            assert_eq!(CoeffTable::parse(&m), Err(TableError::NonMonotonicGrid));
        }

        // Found by the table_parse fuzz target: with 31 X fraction bits a
        // step of 2^6 raw is 0.5 LSB of I8F24, and node 0 and 1 coincided.
        let mut m = good.clone();
        patch(&mut m, 11, &[31]);
        patch(&mut m, 24, &(1i32 << 6).to_le_bytes());
        patch(&mut m, 28, &0i32.to_le_bytes());
        assert_eq!(
            CoeffTable::parse(&m),
            Err(TableError::GridStepBelowResolution)
        );
        let mut m = good.clone();
        patch(&mut m, 11, &[31]);
        patch(&mut m, 24, &(1i32 << 7).to_le_bytes());
        patch(&mut m, 28, &0i32.to_le_bytes());
        let t = CoeffTable::parse(&m).unwrap();
        assert_eq!(t.node_x(1).to_bits() - t.node_x(0).to_bits(), 1);

        let mut m = good.clone();
        patch(&mut m, 24, &(i32::MAX / 4).to_le_bytes());
        assert_eq!(CoeffTable::parse(&m), Err(TableError::GridOverflow));

        let mut m = good.clone();
        patch(&mut m, 28, &(2i32 << 24).to_le_bytes());
        assert_eq!(CoeffTable::parse(&m), Err(TableError::NullZoneOutsideGrid));

        let mut m = good.clone();
        patch(&mut m, 40, &0i64.to_le_bytes());
        assert_eq!(CoeffTable::parse(&m), Err(TableError::BadGeometry));
    }

    /// A region holds the image and erased flash after it; an erased or
    /// zeroed region holds no table; a region too small for the image the
    /// header describes is cut short, by the numbers.
    #[test]
    fn a_region_is_read_up_to_the_image_its_header_describes() {
        let h = header(9, 4);
        let img = image(&h);
        let mut region = img.clone();
        region.extend([0xFFu8; 1000]);
        let t = CoeffTable::parse_region(&region).unwrap();
        assert_eq!(t, CoeffTable::parse(&img).unwrap());
        let id = t.identity();
        assert_eq!(id.len as usize, img.len());
        assert_eq!(id.crc, u32_at(&img, 60));
        assert_eq!((id.node_count, id.terms), (9, 4));
        assert_eq!(id.dx_bits, 1 << 21);
        for erased in [0xFFu8, 0] {
            assert_eq!(
                CoeffTable::parse_region(&[erased; 4096]),
                Err(TableError::Missing)
            );
        }
        let n = img.len() as u32;
        assert_eq!(
            CoeffTable::parse_region(&img[..100]),
            Err(TableError::Truncated {
                needed: n,
                got: 100
            })
        );
        // Garbage is not "missing": it is refused for what it is.
        let mut junk = region.clone();
        junk[0] = b'Q';
        assert_eq!(CoeffTable::parse_region(&junk), Err(TableError::BadMagic));
        let mut junk = region.clone();
        junk[70] ^= 1;
        assert!(matches!(
            CoeffTable::parse_region(&junk),
            Err(TableError::PayloadCrc { .. })
        ));
    }

    /// The format's ranges are inclusive at their stated ends (module
    /// docs): 31 columns, 31 coefficient fraction bits, a null X on either
    /// end of the grid and a tool radius of zero parse; one step past each
    /// end is refused with its own error.
    #[test]
    fn each_header_range_holds_its_stated_ends() {
        let good = image(&header(9, 4));
        let last_raw = 8 * (1i32 << 21);
        let wide = image(&header(9, MAX_TERMS));
        assert_eq!(CoeffTable::parse(&wide).unwrap().terms(), 31);
        for (at, bytes, field) in [
            (10usize, vec![31u8], "fc = 31"),
            (28, 0i32.to_le_bytes().to_vec(), "x_null on node 0"),
            (
                28,
                last_raw.to_le_bytes().to_vec(),
                "x_null on the last node",
            ),
            (48, 0i64.to_le_bytes().to_vec(), "tool radius 0"),
        ] {
            let mut m = good.clone();
            patch(&mut m, at, &bytes);
            assert!(CoeffTable::parse(&m).is_ok(), "{field}");
        }
        for x_null in [-1i32, last_raw + 1] {
            let mut m = good.clone();
            patch(&mut m, 28, &x_null.to_le_bytes());
            let want = Err(TableError::NullZoneOutsideGrid);
            assert_eq!(CoeffTable::parse(&m), want, "x_null {x_null}");
        }
        let mut m = good.clone();
        patch(&mut m, 48, &(-1i64).to_le_bytes());
        assert_eq!(CoeffTable::parse(&m), Err(TableError::BadGeometry));
    }

    /// The grid's last node is node_count − 1 steps from node 0: a grid
    /// ending on the largest X the core holds (I8F24 at fx = 24: raw
    /// i32::MAX) parses, and node X past the last saturates there. With
    /// fewer X fraction bits than the core's, a grid whose last node is
    /// beyond the core's range (2²⁷ raw at fx = 20 is 128 in) is refused,
    /// as is one whose node 0 is.
    #[test]
    fn the_grid_ends_on_its_last_node_and_must_fit_the_core_x() {
        let mut h = header(9, 2);
        h.dx_raw = i32::MAX / 8;
        let img = image(&h);
        let t = CoeffTable::parse(&img).unwrap();
        let last = 8 * (i32::MAX / 8);
        assert_eq!(t.node_x(8).to_bits(), last);
        assert_eq!(t.node_x(9).to_bits(), last, "past the last node");
        assert_eq!(t.node_x(u32::MAX).to_bits(), last);

        let good = image(&header(9, 4));
        let mut m = good.clone();
        patch(&mut m, 11, &[20]);
        patch(&mut m, 24, &(1i32 << 24).to_le_bytes());
        assert_eq!(CoeffTable::parse(&m), Err(TableError::GridOverflow));
        let mut m = good.clone();
        patch(&mut m, 11, &[20]);
        patch(&mut m, 20, &(-(1i32 << 27) - 1).to_le_bytes());
        patch(&mut m, 28, &(-(1i32 << 27) + 1).to_le_bytes());
        assert_eq!(CoeffTable::parse(&m), Err(TableError::GridOverflow));
    }

    /// A header alone (64 bytes, no payload) is cut short by the size its
    /// fields describe, not by the header's own length.
    #[test]
    fn a_header_without_its_payload_is_truncated_by_the_payload_size() {
        let good = image(&header(9, 4));
        assert_eq!(
            CoeffTable::parse(&good[..HEADER_LEN]),
            Err(TableError::Truncated {
                needed: good.len() as u32,
                got: 64
            })
        );
    }

    #[test]
    fn every_single_byte_corruption_is_caught() {
        let good = image(&header(5, 3));
        for at in 0..good.len() {
            for bit in 0..8 {
                let mut m = good.clone();
                m[at] ^= 1 << bit;
                assert!(
                    CoeffTable::parse(&m).is_err(),
                    "flip of bit {bit} in byte {at} went unseen"
                );
            }
        }
    }

    mod prop {
        use super::*;
        use proptest::prelude::*;

        proptest! {
            #![proptest_config(ProptestConfig::with_cases(1024))]
            /// Arbitrary bytes never panic the parser.
            #[test]
            fn never_panics_on_garbage(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
                let _ = CoeffTable::parse(&bytes);
            }

            /// A valid image with any header fields mutated (CRC fixed up)
            /// either parses to exactly those fields or fails cleanly:
            /// the one writer of the format, given the parsed header and
            /// payload, writes back the very image that was parsed.
            #[test]
            fn plausible_headers_parse_to_exactly_their_fields_or_fail(
                fields in proptest::collection::vec((8usize..56, 0u8..40), 1..4),
                nodes in 0u32..20, terms in 0u8..8,
            ) {
                // One to three header bytes (fields 8..56) set to small
                // values (plausible for the byte fields and the low bytes
                // of the integers): a good part of these still parse, so
                // the round-trip check below runs.
                let h = header(nodes.max(2), terms.max(1));
                let mut m = image(&h);
                for (at, b) in fields {
                    patch(&mut m, at, &[b]);
                }
                if let Ok(t) = CoeffTable::parse(&m) {
                    for n in 0..t.node_count() { let _ = t.node_x(n); }
                    let _ = t.x_null();
                    let payload: Vec<i32> = (0..t.node_count())
                        .flat_map(|n| (0..t.terms()).map(move |c| (n, c)))
                        .map(|(n, c)| t.coeff_raw(n, c))
                        .collect();
                    let mut back = vec![0u8; t.header().image_len()];
                    let len = t.header().encode(&payload, &mut back).unwrap();
                    prop_assert_eq!(&back[..], &m[..len]);
                    prop_assert_eq!(len, m.len());
                }
            }
        }
    }
}
