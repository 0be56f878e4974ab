//! The recording as it sits in the target's flash: several runs, each a
//! postcard byte string ([`crate::wire::Setup`] then its events), behind a
//! magic, a version, the length and a CRC-32, so that an absent or damaged
//! recording is refused, never played.
//!
//! ```text
//! "ZSRP" | version u32 LE | payload length u32 LE | payload | CRC-32 (ISO-HDLC) of payload, u32 LE
//! payload = run count (varint) | run bytes (varint length + bytes) ...
//! ```

use crate::wire::FormatError;

pub const MAGIC: [u8; 4] = *b"ZSRP";
pub const VERSION: u32 = 1;
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
    let (count, rest) = postcard::take_from_bytes::<u32>(payload).map_err(|_| FormatError::Item)?;
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
        Some(match postcard::take_from_bytes::<&'a [u8]>(self.rest) {
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
