//! The coefficient-table parser (`zslide::table`) on arbitrary images.
//!
//! The first input byte chooses how the rest is used: as it is (the CRCs
//! must then be right by chance, so this mostly exercises the early
//! checks), or with both CRCs recomputed first, so that the fuzzer reaches
//! the field checks behind them. Properties:
//! * an accepted image re-encodes, through the format's one encoder
//!   (`TableHeader::encode`), to exactly the input bytes;
//! * its grid is strictly increasing and its null-zone start lies on it;
//! * a refused image is refused for the first defect the format's
//!   specification (the module documentation's table) lists, checked here
//!   by an independent reading of the header.
#![no_main]

use libfuzzer_sys::fuzz_target;
use zslide::table::{crc32, CoeffTable, TableError, HEADER_LEN, MAX_NODES, MAX_TERMS};

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}
fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
fn i32_at(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}
fn i64_at(b: &[u8], at: usize) -> i64 {
    i64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

/// Whether a raw X with `frac` fraction bits fits `I8F24` (|X| < 128 in),
/// by exact rational arithmetic: round(raw · 2^(24−frac)) within i32.
fn x_fits(raw: i64, frac: u8) -> bool {
    let v = if frac >= 24 {
        let s = u32::from(frac) - 24;
        if s == 0 {
            raw
        } else {
            (raw + (1i64 << (s - 1))) >> s
        }
    } else {
        raw << (24 - u32::from(frac))
    };
    i32::try_from(v).is_ok()
}

/// The defect the specification says is first, or `None` for a good image.
fn first_defect(b: &[u8]) -> Option<&'static str> {
    if b.len() < HEADER_LEN {
        return Some("Truncated");
    }
    if b[0..4] != *b"ZSCT" {
        return Some("BadMagic");
    }
    if u16_at(b, 4) != 1 {
        return Some("UnsupportedVersion");
    }
    if u16_at(b, 6) != 64 {
        return Some("BadHeaderLength");
    }
    if u32_at(b, 60) != crc32(&b[..60]) {
        return Some("HeaderCrc");
    }
    if b[8] > 1 {
        return Some("UnknownRepresentation");
    }
    if b[12] != 0 {
        return Some("UnknownUnit");
    }
    if b[13..16] != [0, 0, 0] {
        return Some("ReservedNotZero");
    }
    let (terms, fc, fx, nodes) = (b[9], b[10], b[11], u32_at(b, 16));
    if terms == 0 || terms > MAX_TERMS || fc > 31 || fx > 31 || !(2..=MAX_NODES).contains(&nodes) {
        return Some("AbsurdSize");
    }
    if b[8] == 1 && terms % 2 == 0 {
        return Some("HarmonicColumnsNotOdd");
    }
    let (x0, dx, xn) = (
        i64::from(i32_at(b, 20)),
        i64::from(i32_at(b, 24)),
        i64::from(i32_at(b, 28)),
    );
    if dx <= 0 {
        return Some("NonMonotonicGrid");
    }
    if fx > 24 && dx < 1 << (fx - 24) {
        return Some("GridStepBelowResolution");
    }
    let last = x0 + dx * i64::from(nodes - 1);
    if i32::try_from(last).is_err() || !x_fits(x0, fx) || !x_fits(last, fx) {
        return Some("GridOverflow");
    }
    if xn < x0 || xn > last {
        return Some("NullZoneOutsideGrid");
    }
    if i64_at(b, 32) <= 0 || i64_at(b, 40) <= 0 || i64_at(b, 48) < 0 {
        return Some("BadGeometry");
    }
    let len = HEADER_LEN + nodes as usize * usize::from(terms) * 4;
    if b.len() < len {
        return Some("Truncated");
    }
    if b.len() > len {
        return Some("TrailingBytes");
    }
    if u32_at(b, 56) != crc32(&b[HEADER_LEN..]) {
        return Some("PayloadCrc");
    }
    None
}

fn name(e: &TableError) -> &'static str {
    match e {
        TableError::Truncated { .. } => "Truncated",
        TableError::TrailingBytes { .. } => "TrailingBytes",
        TableError::BadMagic => "BadMagic",
        TableError::UnsupportedVersion(_) => "UnsupportedVersion",
        TableError::BadHeaderLength(_) => "BadHeaderLength",
        TableError::HeaderCrc { .. } => "HeaderCrc",
        TableError::PayloadCrc { .. } => "PayloadCrc",
        TableError::UnknownRepresentation(_) => "UnknownRepresentation",
        TableError::UnknownUnit(_) => "UnknownUnit",
        TableError::ReservedNotZero => "ReservedNotZero",
        TableError::AbsurdSize => "AbsurdSize",
        TableError::HarmonicColumnsNotOdd(_) => "HarmonicColumnsNotOdd",
        TableError::NonMonotonicGrid => "NonMonotonicGrid",
        TableError::GridStepBelowResolution => "GridStepBelowResolution",
        TableError::GridOverflow => "GridOverflow",
        TableError::NullZoneOutsideGrid => "NullZoneOutsideGrid",
        TableError::BadGeometry => "BadGeometry",
        TableError::SignCheck => "SignCheck",
        // Only `parse_region` reports an erased region.
        TableError::Missing => "Missing",
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    let mut img = rest.to_vec();
    if mode & 1 == 1 && img.len() >= HEADER_LEN {
        let payload_crc = crc32(&img[HEADER_LEN..]);
        img[56..60].copy_from_slice(&payload_crc.to_le_bytes());
        let header_crc = crc32(&img[..60]);
        img[60..64].copy_from_slice(&header_crc.to_le_bytes());
    }
    let parsed = CoeffTable::parse(&img);
    let want = first_defect(&img);
    match parsed {
        Err(e) => assert_eq!(Some(name(&e)), want, "refused as {e:?}"),
        Ok(t) => {
            assert_eq!(want, None, "accepted an image with a defect");
            let h = *t.header();
            let payload: Vec<i32> = (0..t.node_count())
                .flat_map(|n| (0..t.terms()).map(move |c| (n, c)))
                .map(|(n, c)| t.coeff_raw(n, c))
                .collect();
            let mut out = vec![0u8; h.image_len()];
            assert_eq!(h.encode(&payload, &mut out), Ok(img.len()));
            assert_eq!(out, img, "re-encoding differs from the accepted image");
            for n in 1..t.node_count() {
                assert!(
                    t.node_x(n) > t.node_x(n - 1),
                    "nodes {} and {n} coincide or decrease in the core X format",
                    n - 1
                );
            }
            let last = t.node_x(t.node_count() - 1);
            assert!(t.node_x(0) <= t.x_null() && t.x_null() <= last);
        }
    }
});
