//! The servo parameter block (`zslide::params::load_region`, read at boot
//! from its flash region), from arbitrary bytes: a mode byte, then
//!
//! * 0: the region as it is;
//! * 1: the same with the CRC recomputed over what the header's count
//!   covers (so the checks behind the CRC are reached);
//! * 2: a block written here from the format's table (`params` module
//!   docs) out of (id, value) pairs the input chooses, mostly known ids and
//!   values inside their limits, so that accepted blocks are common.
//!
//! Properties, against an independent reading of the format (this file's
//! own field reads and bitwise CRC-32): the parser's verdict is the first
//! defect in the order the format is checked (length, erased, magic,
//! version, count, reserved, length of the entries, CRC; then per entry:
//! reserved, id, duplicate, limits, whole number; then the design as a
//! whole); an accepted block sets exactly its entries' values (bit for
//! bit) and leaves every other parameter at the built-in one, reports its
//! entry count and CRC, and re-encodes through the one writer
//! (`params::encode_block`) to exactly its bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use zslide::params::{
    encode_block, load_region, ParamError, ParamSource, ENTRY_LEN, FORMAT_VERSION, HEADER_LEN,
    MAGIC, PARAMS,
};
use zslide::servo::ServoDesign;

/// CRC-32/ISO-HDLC, bit by bit (reflected 0xEDB88320, init and final
/// complement): the reference for the firmware's table-driven one.
fn crc32(parts: &[&[u8]]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for p in parts {
        for &b in *p {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    (c >> 1) ^ 0xEDB8_8320
                } else {
                    c >> 1
                };
            }
        }
    }
    !c
}

fn le16(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}
fn le32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// What the format says of `r`: built-in, the entries it sets, or the
/// first defect (the design's verdict is not modelled: `Ok(Some)` means
/// "every entry passes its own checks").
fn reference(r: &[u8]) -> Result<Option<Vec<(u16, f64)>>, ParamError> {
    let got = r.len() as u32;
    if r.len() < 16 {
        return Err(ParamError::BlockTruncated { needed: 16, got });
    }
    let h = &r[..16];
    if h.iter().all(|&b| b == 0xFF) || h.iter().all(|&b| b == 0) {
        return Ok(None);
    }
    if h[..4] != *b"ZSPB" {
        return Err(ParamError::BlockMagic);
    }
    if le16(h, 4) != 1 {
        return Err(ParamError::BlockVersion(le16(h, 4)));
    }
    let n = le16(h, 6);
    if usize::from(n) > PARAMS.len() {
        return Err(ParamError::BlockTooMany(n));
    }
    if le32(h, 8) != 0 {
        return Err(ParamError::BlockReserved);
    }
    let end = 16 + 12 * usize::from(n);
    if r.len() < end {
        return Err(ParamError::BlockTruncated {
            needed: end as u32,
            got,
        });
    }
    let stored = le32(h, 12);
    let computed = crc32(&[&h[..12], &r[16..end]]);
    if stored != computed {
        return Err(ParamError::BlockCrc { stored, computed });
    }
    let mut out: Vec<(u16, f64)> = Vec::new();
    for k in 0..usize::from(n) {
        let e = &r[16 + 12 * k..16 + 12 * (k + 1)];
        let id = le16(e, 0);
        if le16(e, 2) != 0 {
            return Err(ParamError::BlockReserved);
        }
        let value = f64::from_le_bytes(e[4..12].try_into().unwrap());
        let Some(p) = PARAMS.iter().find(|p| p.id == id) else {
            return Err(ParamError::Unknown(id));
        };
        if out.iter().any(|&(i, _)| i == id) {
            return Err(ParamError::BlockDuplicate(id));
        }
        let v = zslide::params::Value::new(value);
        if !(p.min..=p.max).contains(&value) {
            return Err(ParamError::OutOfRange { id, value: v });
        }
        if p.integer && value.fract() != 0.0 {
            return Err(ParamError::NotInteger { id, value: v });
        }
        out.push((id, value));
    }
    Ok(Some(out))
}

/// A block from `bytes`: 9 bytes per entry (a selector, then 8 bytes).
fn structured(bytes: &[u8]) -> Vec<u8> {
    let mut entries: Vec<(u16, f64)> = Vec::new();
    for c in bytes.chunks_exact(9).take(PARAMS.len() + 2) {
        let sel = c[0];
        let raw = u64::from_le_bytes(c[1..9].try_into().unwrap());
        let p = &PARAMS[usize::from(sel & 0x3F) % PARAMS.len()];
        let id = if sel & 0x40 != 0 { raw as u16 } else { p.id };
        let value = if sel & 0x80 != 0 {
            f64::from_bits(raw)
        } else {
            let v = p.min + (p.max - p.min) * ((raw >> 11) as f64 / (1u64 << 53) as f64);
            if p.integer {
                v.round()
            } else {
                v
            }
        };
        entries.push((id, value));
    }
    let n = entries.len();
    let mut b = Vec::with_capacity(HEADER_LEN + n * ENTRY_LEN);
    b.extend_from_slice(&MAGIC);
    b.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    b.extend_from_slice(&(n as u16).to_le_bytes());
    b.extend_from_slice(&[0; 4]);
    b.extend_from_slice(&[0; 4]);
    for (id, v) in entries {
        b.extend_from_slice(&id.to_le_bytes());
        b.extend_from_slice(&[0, 0]);
        b.extend_from_slice(&v.to_le_bytes());
    }
    let crc = crc32(&[&b[..12], &b[HEADER_LEN..]]);
    b[12..16].copy_from_slice(&crc.to_le_bytes());
    b
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let mut region = rest.to_vec();
    match mode % 3 {
        0 => {}
        1 => {
            if region.len() >= 16 {
                let n = usize::from(le16(&region, 6)).min(PARAMS.len());
                let end = (16 + 12 * n).min(region.len());
                let crc = crc32(&[&region[..12], &region[16..end]]);
                region[12..16].copy_from_slice(&crc.to_le_bytes());
            }
        }
        _ => region = structured(rest),
    }
    let base = ServoDesign::brief(20_000);
    let got = load_region(&region, &base);
    match (reference(&region), &got) {
        (Err(e), _) => assert_eq!(got.as_ref().err(), Some(&e), "{region:02x?}"),
        (Ok(None), Ok((d, cfg, src))) => {
            assert_eq!(*src, ParamSource::BuiltIn);
            assert_eq!(*d, base);
            assert_eq!(*cfg, base.config().unwrap());
        }
        (Ok(None), Err(e)) => panic!("an erased header refused: {e:?}"),
        (Ok(Some(_)), Err(e)) => {
            // Every entry passed its own checks: only the design as a
            // whole may refuse them.
            assert!(matches!(e, ParamError::Design(_)), "{e:?}");
        }
        (Ok(Some(entries)), Ok((d, cfg, src))) => {
            let n = entries.len();
            assert_eq!(
                *src,
                ParamSource::Block {
                    entries: n as u16,
                    crc: le32(&region, 12),
                }
            );
            for p in PARAMS.iter() {
                let want = entries
                    .iter()
                    .find(|&&(id, _)| id == p.id)
                    .map_or(p.get(&base), |&(_, v)| v);
                assert_eq!(p.get(d).to_bits(), want.to_bits(), "{}", p.name);
            }
            assert_eq!(*cfg, d.config().unwrap());
            let mut out = vec![0u8; HEADER_LEN + n * ENTRY_LEN];
            let len =
                encode_block(&entries, &base, &mut out).expect("an accepted block re-encodes");
            assert_eq!(out[..len], region[..len]);
        }
    }
});
