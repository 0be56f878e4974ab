//! The replay recording (`zslide_replay`), as the QEMU replay image reads
//! it from flash: the container (`container::runs`), each run's setup
//! (postcard `Setup` through `wire::take`, then `Setup::firmware_config`) and its events
//! (`wire::Codec::decode`, to the end of the run). From arbitrary bytes: a
//! mode byte, then
//!
//! * 0: a flash region as it is;
//! * 1: the input wrapped in a valid header and CRC (so the payload's
//!   parse is reached), with trailing bytes after the recording;
//! * 2: runs cut from the input, built into a container by the one writer
//!   (`container::build`);
//! * 3: one run's bytes: its setup and events.
//!
//! Properties, against an independent reading of the container's format
//! (field reads, a bitwise CRC-32, a reader of LEB128 varints in their
//! shortest form, the only form the format has): the header's
//! verdict is the first defect in the format's order (magic, version,
//! length, CRC, run count); the runs come out in order, consecutive in the
//! payload, at most as many as the count says, the iteration ending at the
//! first that does not decode; built runs come back exactly. A decoded
//! setup converts to a firmware configuration exactly when its loop rate
//! designs, and back (`setup::setup_of`) to itself. Decoded events,
//! re-encoded by the recorder's encoder (`Codec::encode`) and decoded
//! again, are the same events: the decoder's state follows the encoder's.
#![no_main]

use libfuzzer_sys::fuzz_target;
use zslide::servo::ServoConfig;
use zslide_replay::container::{self, MAGIC, VERSION};
use zslide_replay::setup::setup_of;
use zslide_replay::wire::{self, Codec, Event, FormatError, Setup};

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

/// LEB128 (postcard's varint) of a u32 in its shortest form: the value and
/// its length. A longer form (a last byte of 0 after the first) is no
/// varint of the format.
fn varint_u32(b: &[u8]) -> Option<(u32, usize)> {
    let mut v: u64 = 0;
    for (k, &x) in b.iter().enumerate().take(5) {
        v |= u64::from(x & 0x7F) << (7 * k);
        if x & 0x80 == 0 {
            if k > 0 && x == 0 {
                return None;
            }
            return u32::try_from(v).ok().map(|v| (v, k + 1));
        }
    }
    None
}

fn le32(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

/// The container's header as the format states it: the payload, or the
/// first defect.
fn reference(r: &[u8]) -> Result<(u32, &[u8]), FormatError> {
    if r.get(..4) != Some(&b"ZSRP"[..]) {
        return Err(FormatError::Missing);
    }
    let v = le32(r, 4).ok_or(FormatError::Corrupt)?;
    if v != 2 {
        return Err(FormatError::Version(v));
    }
    let len = le32(r, 8).ok_or(FormatError::Corrupt)? as usize;
    let payload = r.get(12..12 + len).ok_or(FormatError::Corrupt)?;
    let crc = le32(r, 12 + len).ok_or(FormatError::Corrupt)?;
    if crc32(payload) != crc {
        return Err(FormatError::Corrupt);
    }
    let (count, n) = varint_u32(payload).ok_or(FormatError::Item)?;
    Ok((count, &payload[n..]))
}

fn check_container(region: &[u8], built: Option<&[Vec<u8>]>) {
    let got = container::runs(region);
    let want = reference(region);
    let (count, mut rest) = match (want, got) {
        (Err(e), got) => {
            assert_eq!(got.err(), Some(e));
            return;
        }
        (Ok(_), Err(e)) => panic!("a sound header refused: {e:?}"),
        (Ok((count, rest)), Ok(runs)) => {
            assert_eq!(runs.remaining(), count);
            (count, rest)
        }
    };
    let runs: Vec<_> = container::runs(region).unwrap().collect();
    assert!(runs.len() <= count as usize);
    for (k, r) in runs.iter().enumerate() {
        // Each run: a varint length and that many bytes, in order.
        let Some((len, n)) = varint_u32(rest).filter(|&(l, n)| n + l as usize <= rest.len()) else {
            assert_eq!(*r, Err(FormatError::Item), "run {k}");
            assert_eq!(
                k + 1,
                runs.len(),
                "the iteration ends at an undecodable run"
            );
            return;
        };
        let bytes = &rest[n..n + len as usize];
        assert_eq!(*r, Ok(bytes), "run {k}");
        rest = &rest[n + len as usize..];
    }
    assert_eq!(runs.len(), count as usize);
    if let Some(b) = built {
        let got: Vec<&[u8]> = runs.iter().map(|r| *r.as_ref().unwrap()).collect();
        assert_eq!(got, b.iter().map(|v| v.as_slice()).collect::<Vec<_>>());
    }
}

fn check_run(run: &[u8]) {
    let Ok((setup, mut rest)) = wire::take::<Setup<'_>>(run) else {
        return;
    };
    let designs = ServoConfig::at_rate(setup.loop_hz).is_ok();
    match setup.firmware_config() {
        Some(fc) => {
            assert!(designs);
            assert_eq!(
                setup_of(setup.name, setup.table, setup.interruptions, &fc),
                Some(setup)
            );
        }
        None => assert!(!designs, "{setup:?}"),
    }
    let mut dec = Codec::default();
    let mut events: Vec<Event<'_>> = Vec::new();
    while !rest.is_empty() && events.len() < 4096 {
        match dec.decode(rest) {
            Ok((e, r)) => {
                assert!(r.len() < rest.len(), "an event of no bytes");
                events.push(e);
                rest = r;
            }
            Err(e) => {
                assert_eq!(e, FormatError::Item);
                break;
            }
        }
    }
    let mut enc = Codec::default();
    let mut bytes = Vec::new();
    for e in &events {
        enc.encode(e, &mut bytes);
    }
    let mut again = Codec::default();
    let mut b = bytes.as_slice();
    for (k, e) in events.iter().enumerate() {
        let (e2, r) = again.decode(b).expect("re-encoded events decode");
        assert_eq!(e2, *e, "event {k} of {}", events.len());
        b = r;
    }
    assert!(b.is_empty());
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    match mode % 4 {
        0 => check_container(rest, None),
        1 => {
            let (payload, tail) = rest.split_at(rest.len() * 3 / 4);
            let mut r = MAGIC.to_vec();
            r.extend(VERSION.to_le_bytes());
            r.extend((payload.len() as u32).to_le_bytes());
            r.extend(payload);
            r.extend(crc32(payload).to_le_bytes());
            r.extend(tail);
            check_container(&r, None);
            for run in container::runs(&r).into_iter().flatten().flatten() {
                check_run(run);
            }
        }
        2 => {
            // Runs of lengths the input's bytes give, cut from the rest.
            let (lens, mut body) = rest.split_at(rest.len().min(8));
            let mut runs = Vec::new();
            for &l in lens {
                let (a, b) = body.split_at(usize::from(l).min(body.len()));
                runs.push(a.to_vec());
                body = b;
            }
            let mut r = container::build(&runs);
            r.extend(body);
            check_container(&r, Some(&runs));
        }
        _ => check_run(rest),
    }
});
