//! The recording as it sits in the target's flash: several runs, each a
//! postcard byte string ([`crate::wire::Setup`] then its events), behind a
//! magic, a version, the length and a CRC-32, so that an absent or damaged
//! recording is refused, never played.
//!
//! ```text
//! "ZSRP" | version u32 LE | payload length u32 LE | payload | CRC-32 (ISO-HDLC) of payload, u32 LE
//! payload = run count (varint) | run bytes (varint length + bytes) ...
//! ```
//!
//! The varints are LEB128 in their shortest form (`wire::take`).

use crate::wire::{take, FormatError};

pub const MAGIC: [u8; 4] = *b"ZSRP";
/// 2: a run's setup carries the part's interruption block.
pub const VERSION: u32 = 2;
const CRC: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    let w = b.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
}

/// The runs of a recording found at the start of `region` (which may be
/// longer than the recording).
pub fn runs(region: &[u8]) -> Result<Runs<'_>, FormatError> {
    if region.get(..4) != Some(&MAGIC[..]) {
        return Err(FormatError::Missing);
    }
    let version = u32_at(region, 4).ok_or(FormatError::Corrupt)?;
    if version != VERSION {
        return Err(FormatError::Version(version));
    }
    let len = u32_at(region, 8).ok_or(FormatError::Corrupt)? as usize;
    let end = 12usize.checked_add(len).ok_or(FormatError::Corrupt)?;
    let payload = region.get(12..end).ok_or(FormatError::Corrupt)?;
    let crc = u32_at(region, end).ok_or(FormatError::Corrupt)?;
    if CRC.checksum(payload) != crc {
        return Err(FormatError::Corrupt);
    }
    let (count, rest) = take::<u32>(payload)?;
    Ok(Runs { left: count, rest })
}

/// Iterator over the runs' byte strings.
pub struct Runs<'a> {
    left: u32,
    rest: &'a [u8],
}

impl<'a> Runs<'a> {
    /// Runs not yet taken.
    pub fn remaining(&self) -> u32 {
        self.left
    }
}

impl<'a> Iterator for Runs<'a> {
    type Item = Result<&'a [u8], FormatError>;
    fn next(&mut self) -> Option<Self::Item> {
        if self.left == 0 {
            return None;
        }
        self.left -= 1;
        Some(match take::<&'a [u8]>(self.rest) {
            Ok((run, rest)) => {
                self.rest = rest;
                Ok(run)
            }
            Err(_) => {
                self.left = 0;
                Err(FormatError::Item)
            }
        })
    }
}

/// The container around `runs` (each a run's bytes).
#[cfg(feature = "record")]
pub fn build(runs: &[std::vec::Vec<u8>]) -> std::vec::Vec<u8> {
    let mut payload = std::vec::Vec::new();
    let mut push = |bytes: std::vec::Vec<u8>| payload.extend_from_slice(&bytes);
    if let Ok(b) = postcard::to_allocvec(&(runs.len() as u32)) {
        push(b);
    }
    for r in runs {
        if let Ok(b) = postcard::to_allocvec(&r.as_slice()) {
            push(b);
        }
    }
    let mut out = std::vec::Vec::with_capacity(payload.len() + 16);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    out.extend_from_slice(&payload);
    out.extend_from_slice(&CRC.checksum(&payload).to_le_bytes());
    out
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    fn container(payload: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
        out.extend_from_slice(payload);
        out.extend_from_slice(&CRC.checksum(payload).to_le_bytes());
        out
    }

    fn all(region: &[u8]) -> Vec<Result<&[u8], FormatError>> {
        runs(region).unwrap().collect()
    }

    /// Found by the `replay_recording` fuzz target: a run length of 0 in
    /// nine varint bytes was a run on the host (postcard reads a `usize`
    /// length in up to 10 bytes there) and would be refused by the
    /// 32-bit target (5). Only the shortest form is a length now, on both.
    #[test]
    fn a_varint_not_in_its_shortest_form_is_refused_on_every_platform() {
        // One run "abc": count 1, length 3.
        assert_eq!(
            all(&container(&[1, 3, b'a', b'b', b'c'])),
            [Ok(&b"abc"[..])]
        );
        let longer: [&[u8]; 4] = [
            &[0x83, 0x00],
            &[0x83, 0x80, 0x80, 0x80, 0x00],
            &[0x83, 0x80, 0x80, 0x80, 0x80, 0x00],
            &[0x83, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x00],
        ];
        for len in longer {
            let mut p = std::vec![1];
            p.extend_from_slice(len);
            p.extend_from_slice(b"abc");
            assert_eq!(all(&container(&p)), [Err(FormatError::Item)], "{len:02x?}");
        }
        // The fuzz input's own run: length 0 in nine bytes, after a good one.
        let mut p = std::vec![2, 1, b'a'];
        p.extend_from_slice(&[0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x00]);
        assert_eq!(all(&container(&p)), [Ok(&b"a"[..]), Err(FormatError::Item)]);
        // The run count likewise.
        let c = container(&[0x81, 0x00, 3, b'a', b'b', b'c']);
        assert_eq!(runs(&c).err(), Some(FormatError::Item));
    }
}
