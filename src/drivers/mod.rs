//! Drivers of the external converters, generic over embedded-hal 1.0
//! `SpiDevice` (and `OutputPin` where the chip has a control line). Frame
//! formats are fixed by the board design (`docs/ARCHITECTURE.md`, COMMON
//! converter section): every frame 24 bits, MSB first.
//!
//! Every bus or pin error becomes [`crate::hw::BusError`]; the caller turns
//! it into [`crate::safety::Fault::Bus`] with the device named.

pub mod ad4020;
pub mod ad5686;
pub mod ad5791;

/// 24-bit frame as the three bytes sent MSB first.
#[inline]
pub(crate) fn frame_bytes(frame: u32) -> [u8; 3] {
    [(frame >> 16) as u8, (frame >> 8) as u8, frame as u8]
}

#[inline]
pub(crate) fn bytes_frame(b: [u8; 3]) -> u32 {
    (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2])
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
pub(crate) mod fake;
