//! Servo parameters a machinist sets without rebuilding: the parameter
//! block in flash, read at boot, and the host link's `set`.
//!
//! Both change fields of the loop's design ([`ServoDesign`], physical units)
//! from the built-in default ([`ServoDesign::brief`]); the integer
//! configuration the loop runs ([`ServoConfig`]) is then designed from it
//! in the background, never in an interrupt. Every parameter has a name,
//! a unit and limits ([`PARAMS`], generated from the one parameter table,
//! `servo::parameters`); a value outside them, or a set of values
//! the design refuses as a whole (a bandwidth above a twentieth of the
//! loop rate, say), is refused with the reason in words ([`ParamError`]).
//!
//! # Parameter block, version 1 (little-endian)
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | `[u8; 4]` | magic `b"ZSPB"` |
//! | 4 | `u16` | format version, = 1 |
//! | 6 | `u16` | entry count n, 0..=[`PARAMS`]`.len()` |
//! | 8 | `u32` | reserved, zero |
//! | 12 | `u32` | CRC-32 (ISO-HDLC) of bytes 0..12 followed by the n entries |
//! | 16 | n × 12 bytes | entries: `u16` parameter id, `u16` zero, `f64` value |
//!
//! A parameter the block does not name keeps its built-in value; a
//! parameter named twice is an error (which one would the machinist have
//! meant?). Like the table, the block lives in a flash region of its own
//! (`docs/BOARD.md`); a region whose header is all erased or all zero holds
//! no block, and the built-in parameters apply. A block that is there but
//! wrong never falls back to them: the firmware latches
//! `Fault::Parameters` and keeps the amplifier off.

use crate::safety::DesignError;
pub use crate::safety::{ParamError, Value};
use crate::servo::design::{ServoConfig, ServoDesign};

pub const MAGIC: [u8; 4] = *b"ZSPB";
pub const FORMAT_VERSION: u16 = 1;
pub const HEADER_LEN: usize = 16;
pub const ENTRY_LEN: usize = 12;

/// One settable parameter: its wire id, name, unit and limits (inclusive).
pub struct Param {
    pub id: u16,
    pub name: &'static str,
    pub unit: &'static str,
    pub min: f64,
    pub max: f64,
    /// Whole numbers only (bins, shifts).
    pub integer: bool,
}

impl Param {
    /// The parameter's value in `d`.
    pub fn get(&self, d: &ServoDesign) -> f64 {
        field_get(self.id, d)
    }
    /// Writes `v` into `d` unchecked ([`set`] checks); for tools that
    /// rebuild a refused design to say which values broke it.
    pub fn set(&self, d: &mut ServoDesign, v: f64) {
        field_set(self.id, d, v);
    }
}

// The table and the two accessors from the one parameter table
// (`servo::parameters`), so that they cannot disagree. Accessors are
// `match`es, not function pointers: an indirect call in the link's service
// would make `cargo xtask no-panic` assume it reaches every function whose
// address the image holds.
macro_rules! param_table {
    (
        design { $(($id:literal, $name:ident, $ty:ident, $unit:literal, $default:expr,
            $min:expr, $max:expr, $doc:literal)),+ $(,)? }
        slide { $(($sid:literal, $sname:ident, $sfield:ident, $sty:ident, $sunit:literal,
            $sdefault:expr, $smin:expr, $smax:expr, $sdoc:literal)),+ $(,)? }
    ) => {
        /// Every settable parameter, in the table's order (`servo::parameters`:
        /// the design's, then the slide's).
        pub const PARAMS: [Param; [$($id),+, $($sid),+].len()] = [
            $(Param {
                id: $id,
                name: stringify!($name),
                unit: $unit,
                min: $min,
                max: $max,
                integer: param_table!(@integer $ty),
            },)+
            $(Param {
                id: $sid,
                name: stringify!($sname),
                unit: $sunit,
                min: $smin,
                max: $smax,
                integer: param_table!(@integer $sty),
            },)+
        ];

        fn field_get(id: u16, d: &ServoDesign) -> f64 {
            match id {
                $($id => param_table!(@get $ty, d.$name),)+
                $($sid => param_table!(@get $sty, d.slide.$sfield),)+
                _ => f64::NAN,
            }
        }

        fn field_set(id: u16, d: &mut ServoDesign, v: f64) {
            match id {
                $($id => param_table!(@set $ty, d.$name, v),)+
                $($sid => param_table!(@set $sty, d.slide.$sfield, v),)+
                _ => {}
            }
        }
    };
    (@integer f64) => { false };
    (@integer u32) => { true };
    (@get f64, $e:expr) => { $e };
    (@get u32, $e:expr) => { f64::from($e) };
    (@set f64, $e:expr, $v:ident) => { $e = $v };
    (@set u32, $e:expr, $v:ident) => { $e = $v as u32 };
}
crate::servo_parameters!(param_table);

/// The parameter with wire id `id`.
pub fn by_id(id: u16) -> Option<&'static Param> {
    PARAMS.iter().find(|p| p.id == id)
}

/// The parameter called `name` (the `[servo]` scenario field's name, or the
/// slide model's with its part: `motor_kf_lbf_per_a`, ...).
pub fn by_name(name: &str) -> Option<&'static Param> {
    PARAMS.iter().find(|p| p.name == name)
}

impl core::fmt::Display for ParamError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let name = |id: u16| by_id(id).map_or("?", |p| p.name);
        match *self {
            ParamError::Unknown(id) => write!(f, "no servo parameter has id {id}"),
            ParamError::OutOfRange { id, value } => match by_id(id) {
                Some(p) => write!(
                    f,
                    "{} = {} {} is outside its limits {} .. {} {}",
                    p.name,
                    value.get(),
                    p.unit,
                    p.min,
                    p.max,
                    p.unit
                ),
                None => write!(f, "parameter {id}: {} is out of range", value.get()),
            },
            ParamError::NotInteger { id, value } => {
                write!(f, "{} = {} must be a whole number", name(id), value.get())
            }
            ParamError::Design(e) => write!(f, "the loop design refuses it: {}", e.reason()),
            ParamError::BlockTruncated { needed, got } => write!(
                f,
                "the parameter block is cut short: {got} bytes where {needed} are needed"
            ),
            ParamError::BlockMagic => f.write_str(
                "not a parameter block (it does not start with the block's magic)",
            ),
            ParamError::BlockVersion(v) => {
                write!(f, "parameter block version {v} is not one this firmware reads")
            }
            ParamError::BlockReserved => f.write_str("reserved parameter block bytes are not zero"),
            ParamError::BlockTooMany(n) => write!(
                f,
                "the parameter block has {n} entries, more than there are parameters ({})",
                PARAMS.len()
            ),
            ParamError::BlockCrc { stored, computed } => write!(
                f,
                "the parameter block is corrupt: its CRC says {stored:#010x}, its bytes give {computed:#010x}"
            ),
            ParamError::BlockDuplicate(id) => {
                write!(f, "the parameter block sets {} twice", name(id))
            }
            ParamError::StoreUnreadable => f.write_str(
                "the parameter store is unreadable (corrupt, or its flash failed): save again, or erase the parameter region",
            ),
        }
    }
}

/// `value` checked against `p`'s limits.
fn check(p: &Param, value: f64) -> Result<(), ParamError> {
    let v = Value::new(value);
    // Written `!(in range)` so that a NaN is refused.
    #[allow(clippy::nonminimal_bool)]
    if !(value >= p.min && value <= p.max) {
        return Err(ParamError::OutOfRange { id: p.id, value: v });
    }
    if p.integer && value != libm::trunc(value) {
        return Err(ParamError::NotInteger { id: p.id, value: v });
    }
    Ok(())
}

/// `design` with parameter `id` set to `value`, and the loop configuration
/// designed from it; or why not (limits first, then the design as a whole).
/// f64 design work: background only.
pub fn set(
    design: &ServoDesign,
    id: u16,
    value: f64,
) -> Result<(ServoDesign, ServoConfig), ParamError> {
    let p = by_id(id).ok_or(ParamError::Unknown(id))?;
    check(p, value)?;
    let mut d = *design;
    p.set(&mut d, value);
    let cfg = d.config().map_err(ParamError::Design)?;
    Ok((d, cfg))
}

/// Where the running parameters came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ParamSource {
    /// No block in flash: the built-in design.
    BuiltIn,
    /// A block with this many entries and this CRC.
    Block { entries: u16, crc: u32 },
    /// The block was refused (the firmware latches `Fault::Parameters`).
    Refused(ParamError),
}

impl core::fmt::Display for ParamSource {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ParamSource::BuiltIn => f.write_str("built-in (no parameter block in flash)"),
            ParamSource::Block { entries, crc } => {
                write!(f, "parameter block of {entries} entries, CRC {crc:#010x}")
            }
            ParamSource::Refused(e) => write!(
                f,
                "parameter block REFUSED ({e}): amplifier kept off until a good block is written"
            ),
        }
    }
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}
fn u32_at(b: &[u8], at: usize) -> u32 {
    u16_at(b, at) as u32 | (u16_at(b, at + 2) as u32) << 16
}

/// Reads the parameter block a flash region holds (module docs) on top of
/// `base`: the design with the block's values and its configuration, and
/// where they came from. A refused block leaves `base` untouched and says
/// why; the caller must not run the loop on it (`Fault::Parameters`).
pub fn load_region(
    region: &[u8],
    base: &ServoDesign,
) -> Result<(ServoDesign, ServoConfig, ParamSource), ParamError> {
    let got = region.len() as u32;
    let Some(head) = region.get(..HEADER_LEN) else {
        return Err(ParamError::BlockTruncated {
            needed: HEADER_LEN as u32,
            got,
        });
    };
    if head.iter().all(|&b| b == 0xFF) || head.iter().all(|&b| b == 0) {
        let cfg = base.config().map_err(ParamError::Design)?;
        return Ok((*base, cfg, ParamSource::BuiltIn));
    }
    if head[0..4] != MAGIC {
        return Err(ParamError::BlockMagic);
    }
    let version = u16_at(head, 4);
    if version != FORMAT_VERSION {
        return Err(ParamError::BlockVersion(version));
    }
    let n = u16_at(head, 6);
    if usize::from(n) > PARAMS.len() {
        return Err(ParamError::BlockTooMany(n));
    }
    if u32_at(head, 8) != 0 {
        return Err(ParamError::BlockReserved);
    }
    let len = HEADER_LEN + usize::from(n) * ENTRY_LEN;
    let Some(entries) = region.get(HEADER_LEN..len) else {
        return Err(ParamError::BlockTruncated {
            needed: len as u32,
            got,
        });
    };
    let stored = u32_at(head, 12);
    let mut digest = crate::table::CRC32.digest();
    digest.update(&head[..12]);
    digest.update(entries);
    let computed = digest.finalize();
    if stored != computed {
        return Err(ParamError::BlockCrc { stored, computed });
    }
    let mut d = *base;
    let mut seen = 0u64;
    for e in entries.chunks_exact(ENTRY_LEN) {
        let id = u16_at(e, 0);
        if u16_at(e, 2) != 0 {
            return Err(ParamError::BlockReserved);
        }
        let mut raw = [0u8; 8];
        raw.copy_from_slice(&e[4..12]);
        let value = f64::from_le_bytes(raw);
        let p = by_id(id).ok_or(ParamError::Unknown(id))?;
        // Ids are 1..=64 by construction of PARAMS (checked by a test).
        let bit = 1u64 << (id & 63);
        if seen & bit != 0 {
            return Err(ParamError::BlockDuplicate(id));
        }
        seen |= bit;
        check(p, value)?;
        p.set(&mut d, value);
    }
    let cfg = d.config().map_err(ParamError::Design)?;
    Ok((
        d,
        cfg,
        ParamSource::Block {
            entries: n,
            crc: stored,
        },
    ))
}

/// The parameters a board boots with: the region's block on `base`; with a
/// refused block, `base` itself and the refusal (the board then latches
/// `Fault::Parameters`). `Err` only when `base` itself does not design (a
/// programming error: the board refuses to start).
pub fn at_boot(
    region: &[u8],
    base: &ServoDesign,
) -> Result<(ServoDesign, ServoConfig, ParamSource), DesignError> {
    match load_region(region, base) {
        Ok(p) => Ok(p),
        Err(e) => Ok((*base, base.config()?, ParamSource::Refused(e))),
    }
}

/// Writes a parameter block of `entries` (id, value) into `out`; returns
/// the bytes written. Every value is checked as the firmware will check it
/// (limits, then the design on top of `base`), so a block this writes is
/// one the firmware accepts. The one writer of the format.
pub fn encode_block(
    entries: &[(u16, f64)],
    base: &ServoDesign,
    out: &mut [u8],
) -> Result<usize, ParamError> {
    if entries.len() > PARAMS.len() {
        return Err(ParamError::BlockTooMany(entries.len() as u16));
    }
    let len = HEADER_LEN + entries.len() * ENTRY_LEN;
    let got = out.len() as u32;
    let Some(out) = out.get_mut(..len) else {
        return Err(ParamError::BlockTruncated {
            needed: len as u32,
            got,
        });
    };
    out[0..4].copy_from_slice(&MAGIC);
    out[4..6].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    out[6..8].copy_from_slice(&(entries.len() as u16).to_le_bytes());
    out[8..12].copy_from_slice(&[0; 4]);
    for (slot, &(id, value)) in out[HEADER_LEN..].chunks_exact_mut(ENTRY_LEN).zip(entries) {
        slot[0..2].copy_from_slice(&id.to_le_bytes());
        slot[2..4].copy_from_slice(&[0, 0]);
        slot[4..12].copy_from_slice(&value.to_le_bytes());
    }
    let mut digest = crate::table::CRC32.digest();
    digest.update(&out[..12]);
    digest.update(&out[HEADER_LEN..]);
    let crc = digest.finalize();
    out[12..16].copy_from_slice(&crc.to_le_bytes());
    load_region(out, base)?;
    Ok(len)
}

/// Every parameter of `design` as one block into `out` (what a save
/// stores); returns the bytes written.
pub fn design_block(design: &ServoDesign, out: &mut [u8]) -> Result<usize, ParamError> {
    let mut entries = heapless::Vec::<(u16, f64), { PARAMS.len() }>::new();
    for p in PARAMS.iter() {
        let _ = entries.push((p.id, p.get(design)));
    }
    encode_block(&entries, design, out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec;
    use std::vec::Vec;

    fn brief() -> ServoDesign {
        ServoDesign::brief(20_000)
    }

    fn block(entries: &[(u16, f64)]) -> Vec<u8> {
        let mut out = vec![0u8; HEADER_LEN + entries.len() * ENTRY_LEN];
        encode_block(entries, &brief(), &mut out).unwrap();
        out
    }

    #[test]
    fn ids_are_unique_small_and_every_default_is_inside_its_limits() {
        let d = brief();
        for (i, p) in PARAMS.iter().enumerate() {
            assert!((1..64).contains(&p.id), "{}", p.name);
            assert!(PARAMS[..i].iter().all(|q| q.id != p.id && q.name != p.name));
            let v = p.get(&d);
            assert!(
                check(p, v).is_ok(),
                "{} default {v} outside its limits",
                p.name
            );
            assert_eq!(by_name(p.name).map(|q| q.id), Some(p.id));
        }
    }

    /// Each parameter reaches the field it names: setting it to another
    /// value inside its limits changes that field of the design and no other.
    #[test]
    fn each_parameter_sets_its_own_field() {
        let d = brief();
        for p in PARAMS.iter() {
            let v = if p.get(&d) == p.max { p.min } else { p.max };
            let mut e = d;
            p.set(&mut e, v);
            assert_eq!(p.get(&e), v, "{}", p.name);
            for q in PARAMS.iter().filter(|q| q.id != p.id) {
                assert_eq!(q.get(&e), q.get(&d), "setting {} moved {}", p.name, q.name);
            }
        }
    }

    #[test]
    fn set_refuses_outside_the_limits_with_the_limits_in_words() {
        let d = brief();
        let id = by_name("following_error_in").unwrap().id;
        let e = set(&d, id, 0.02).unwrap_err();
        assert_eq!(
            e,
            ParamError::OutOfRange {
                id,
                value: Value::new(0.02)
            }
        );
        let words = std::format!("{e}");
        assert!(
            words
                .contains("following_error_in = 0.02 in is outside its limits 0.000001 .. 0.01 in"),
            "{words}"
        );
        assert!(matches!(
            set(&d, id, f64::NAN),
            Err(ParamError::OutOfRange { .. })
        ));
        assert_eq!(set(&d, 99, 1.0).unwrap_err(), ParamError::Unknown(99));
        let lead = by_name("learning_lead_bins").unwrap().id;
        assert!(matches!(
            set(&d, lead, 4.5),
            Err(ParamError::NotInteger { .. })
        ));
        let (d2, cfg) = set(&d, lead, 5.0).unwrap();
        assert_eq!(d2.learning_lead_bins, 5);
        assert_eq!(cfg.learning_lead_bins, 5);
    }

    /// Inside the parameter's own limits but not with the loop rate: the
    /// design's rule (bandwidth below rate / 20) refuses it, by name.
    #[test]
    fn set_refuses_what_the_design_refuses_as_a_whole() {
        let d = ServoDesign::brief(8_000);
        let bw = by_name("bandwidth_hz").unwrap().id;
        let e = set(&d, bw, 500.0).unwrap_err();
        assert_eq!(e, ParamError::Design(DesignError::Bandwidth));
        assert!(std::format!("{e}").contains("bandwidth_hz: must be > 0 and below rate_hz / 20"));
        // At 20 kHz the new following-error limit reaches the integer
        // configuration: 0.001 in = 52 428.8 gauge codes.
        let fe = by_name("following_error_in").unwrap().id;
        let (_, cfg) = set(&brief(), fe, 0.001).unwrap();
        assert_eq!(cfg.following_error_code, 52_428);
    }

    #[test]
    fn a_block_round_trips_and_an_empty_region_means_built_in() {
        let fe = by_name("following_error_in").unwrap().id;
        let q = by_name("hum_notch_q").unwrap().id;
        let img = block(&[(fe, 0.002), (q, 0.0)]);
        let (d, cfg, src) = load_region(&img, &brief()).unwrap();
        assert_eq!(d.following_error_in, 0.002);
        assert_eq!(d.hum_notch_q, 0.0);
        assert!(cfg.hum_canceller.is_none());
        assert!(matches!(src, ParamSource::Block { entries: 2, .. }));
        // Erased flash after the block changes nothing.
        let mut region = img.clone();
        region.extend([0xFF; 100]);
        assert_eq!(load_region(&region, &brief()).unwrap().0, d);
        for erased in [0xFFu8, 0] {
            let (d, _, src) = load_region(&[erased; 64], &brief()).unwrap();
            assert_eq!(src, ParamSource::BuiltIn);
            assert_eq!(d, brief());
        }
    }

    /// A refused block boots the built-in design with the refusal, for
    /// the board to latch; never the block's values.
    #[test]
    fn a_refused_block_boots_the_built_in_design_and_says_why() {
        let fe = by_name("following_error_in").unwrap().id;
        let mut img = block(&[(fe, 0.002)]);
        img[20] ^= 1;
        let (d, cfg, src) = at_boot(&img, &brief()).unwrap();
        assert_eq!(d, brief());
        assert_eq!(cfg, brief().config().unwrap());
        assert!(matches!(
            src,
            ParamSource::Refused(ParamError::BlockCrc { .. })
        ));
    }

    /// The entry count's bound (module docs: 0..=`PARAMS.len()`) is
    /// inclusive: a block naming every parameter once loads, and a header
    /// claiming one entry more is refused as too many, before its entries
    /// or CRC are read.
    #[test]
    fn a_block_may_name_every_parameter_once_and_no_more() {
        let b = brief();
        let all: Vec<(u16, f64)> = PARAMS.iter().map(|p| (p.id, p.get(&b))).collect();
        let img = block(&all);
        let (d, _, src) = load_region(&img, &b).unwrap();
        assert_eq!(d, b);
        assert!(
            matches!(src, ParamSource::Block { entries, .. } if usize::from(entries) == PARAMS.len())
        );
        let over = PARAMS.len() as u16 + 1;
        let mut m = img.clone();
        m[6..8].copy_from_slice(&over.to_le_bytes());
        assert_eq!(
            load_region(&m, &b).unwrap_err(),
            ParamError::BlockTooMany(over)
        );
    }

    #[test]
    fn each_block_defect_has_its_own_error() {
        let fe = by_name("following_error_in").unwrap().id;
        let good = block(&[(fe, 0.002)]);
        let b = brief();
        assert_eq!(
            load_region(&good[..20], &b).unwrap_err(),
            ParamError::BlockTruncated {
                needed: 28,
                got: 20
            }
        );
        let mut m = good.clone();
        m[0] = b'X';
        assert_eq!(load_region(&m, &b).unwrap_err(), ParamError::BlockMagic);
        let mut m = good.clone();
        m[4] = 2;
        assert_eq!(
            load_region(&m, &b).unwrap_err(),
            ParamError::BlockVersion(2)
        );
        let mut m = good.clone();
        m[20] ^= 1;
        assert!(matches!(
            load_region(&m, &b),
            Err(ParamError::BlockCrc { .. })
        ));
        // Every single-bit flip is caught.
        for at in 0..good.len() {
            for bit in 0..8 {
                let mut m = good.clone();
                m[at] ^= 1 << bit;
                assert!(load_region(&m, &b).is_err(), "bit {bit} of byte {at}");
            }
        }
        // Encoding refuses what loading would refuse.
        let mut out = [0u8; 64];
        assert_eq!(
            encode_block(&[(fe, 0.002), (fe, 0.003)], &b, &mut out).unwrap_err(),
            ParamError::BlockDuplicate(fe)
        );
        assert!(matches!(
            encode_block(&[(fe, 1.0)], &b, &mut out),
            Err(ParamError::OutOfRange { .. })
        ));
    }
}
