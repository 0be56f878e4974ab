//! The interruption block (`zslide::table::interrupt`, the part's holes as
//! the firmware receives them), from arbitrary bytes: a mode byte, then
//!
//! * 0: the bytes as they are;
//! * 1: the same with the CRC recomputed over everything before the last
//!   four bytes (so the field checks behind the CRC are reached).
//!
//! Properties, against an independent reading of the format (this file's
//! own field reads and bitwise CRC-32): the parser never panics; it accepts
//! exactly the blocks whose length, magic, version, count, CRC, reserved
//! bytes and every hole's fields are valid, refusing the first defect in
//! that order; an accepted block yields its holes bit for bit and
//! re-encodes through the one writer to exactly its bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use zslide::table::interrupt::{
    InterruptError, Interruptions, HEADER_LEN, HOLE_LEN, MAX_DIAMETER_UIN, MAX_HOLES,
    MAX_RADIUS_UIN,
};

/// CRC-32/ISO-HDLC, bit by bit: the reference for the firmware's
/// table-driven one.
fn crc32(b: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &x in b {
        c ^= u32::from(x);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// The verdict the format's table gives, independently of the parser.
fn expected(b: &[u8]) -> Result<Vec<(u32, u32, u32)>, &'static str> {
    if b.len() < HEADER_LEN + 4 {
        return Err("truncated");
    }
    if &b[0..4] != b"ZSIB" {
        return Err("magic");
    }
    if u16::from_le_bytes([b[4], b[5]]) != 1 {
        return Err("version");
    }
    let n = usize::from(u16::from_le_bytes([b[6], b[7]]));
    if n > MAX_HOLES {
        return Err("count");
    }
    let len = HEADER_LEN + n * HOLE_LEN + 4;
    if b.len() < len {
        return Err("truncated");
    }
    if b.len() > len {
        return Err("trailing");
    }
    if u32_at(b, len - 4) != crc32(&b[..len - 4]) {
        return Err("crc");
    }
    if b[8..12] != [0; 4] {
        return Err("reserved");
    }
    let mut holes = Vec::new();
    for k in 0..n {
        let at = HEADER_LEN + k * HOLE_LEN;
        let (r, a, d) = (u32_at(b, at), u32_at(b, at + 4), u32_at(b, at + 8));
        if r == 0 || r > MAX_RADIUS_UIN {
            return Err("radius");
        }
        if d == 0 || d > MAX_DIAMETER_UIN {
            return Err("diameter");
        }
        if u64::from(d) >= 2 * u64::from(r) {
            return Err("axis");
        }
        holes.push((r, a, d));
    }
    Ok(holes)
}

fn kind(e: &InterruptError) -> &'static str {
    match e {
        InterruptError::Truncated { .. } => "truncated",
        InterruptError::TrailingBytes { .. } => "trailing",
        InterruptError::BadMagic => "magic",
        InterruptError::UnsupportedVersion(_) => "version",
        InterruptError::TooManyHoles(_) => "count",
        InterruptError::ReservedNotZero => "reserved",
        InterruptError::BadCrc { .. } => "crc",
        InterruptError::RadiusOutOfRange { .. } => "radius",
        InterruptError::DiameterOutOfRange { .. } => "diameter",
        InterruptError::CoversTheAxis { .. } => "axis",
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let mut b = rest.to_vec();
    if mode & 1 == 1 && b.len() >= 4 {
        let n = b.len();
        let c = crc32(&b[..n - 4]);
        b[n - 4..].copy_from_slice(&c.to_le_bytes());
    }
    let got = Interruptions::parse(&b);
    match (expected(&b), got) {
        (Ok(holes), Ok(i)) => {
            let read: Vec<(u32, u32, u32)> = i
                .holes()
                .iter()
                .map(|h| (h.centre_radius_uin, h.angle.0, h.diameter_uin))
                .collect();
            assert_eq!(read, holes);
            let mut out = vec![0u8; b.len()];
            let n = Interruptions::encode(i.holes(), &mut out).expect("room for its own bytes");
            assert_eq!(&out[..n], &b[..]);
        }
        (Err(want), Err(e)) => assert_eq!(kind(&e), want, "{e}"),
        (want, got) => panic!("expected {want:?}, the parser gave {got:?}"),
    }
});
