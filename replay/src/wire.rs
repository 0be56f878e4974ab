//! The recording format: what one run holds and how it is coded.
//!
//! A run is its [`Setup`] followed by [`Event`]s in the order the handlers
//! ran: each handler call (boot, loop tick, X event, index event, operator
//! request) with the inputs it saw, then every SPI transaction and pin
//! level it produced during that call ([`Event::Spi`], [`Event::Pin`]),
//! then what changed in its outputs after it ([`Event::Enable`],
//! [`Event::Fault`]). On the wire each event is a postcard-encoded
//! [`Wire`] (varints) holding differences from the previous values
//! ([`Codec`]): a loop tick costs about 15 bytes.

use serde::{Deserialize, Serialize};

/// The devices on the firmware's buses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dev {
    /// Gauge ADC (AD4020 class), read by the loop tick.
    GaugeAdc = 0,
    /// Amplifier DAC (AD5791 class), written by the loop tick and at boot.
    AmpDac = 1,
    /// Coefficient DAC (AD5686 class), written by the X handler.
    QuadDac = 2,
}

impl Dev {
    pub const ALL: [Dev; 3] = [Dev::GaugeAdc, Dev::AmpDac, Dev::QuadDac];

    pub fn name(self) -> &'static str {
        match self {
            Dev::GaugeAdc => "gauge ADC",
            Dev::AmpDac => "amplifier DAC",
            Dev::QuadDac => "coefficient DAC",
        }
    }
    fn from_bits(b: u8) -> Option<Dev> {
        Dev::ALL.get(usize::from(b)).copied()
    }
}

/// One SPI transaction: the bytes the firmware sent (MOSI, its output)
/// and the bytes the device returned (MISO, its input), each up to three
/// (every converter frame is 24 bits), as big-endian words, and whether
/// the bus reported an error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Io {
    pub dev: Dev,
    pub ok: bool,
    pub mosi_len: u8,
    pub mosi: u32,
    pub miso_len: u8,
    pub miso: u32,
}

/// Longest transaction a recording holds, bytes each way.
pub const MAX_FRAME_BYTES: u8 = 3;

/// The spindle reading a loop tick was given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Spindle {
    None,
    Encoder { count: u32, edge_ticks: u32 },
    Tach(i32),
}

/// What an X event returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum XResult {
    Ignored,
    Update,
    Fault,
}

/// An operator request ([`zslide::firmware::Request`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Req {
    Arm,
    Disarm,
    ClearFault,
}

/// One recorded item, absolute values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event<'a> {
    /// Boot: the converter drivers' initialisation (its frames follow).
    Boot,
    Request(Req),
    /// A loop tick with its `TickInput`; the gauge frame it read follows as
    /// an [`Event::Spi`].
    Tick {
        now: u32,
        spindle: Spindle,
        x_count: u32,
        amplifier_fault: bool,
    },
    /// An X event: the latch word and the clock at entry, and its result.
    X {
        word: u32,
        now: u32,
        result: XResult,
    },
    /// An index event: the edge's timestamp and the count at the index.
    Index {
        edge_ticks: u32,
        count: u32,
    },
    Spi(Io),
    /// A level set on the coefficient DAC's LDAC pin (true = high).
    Pin(bool),
    /// The amplifier enable after the call it follows.
    Enable(bool),
    /// The latched fault after the call it follows, as its `Debug` text
    /// ("" = none).
    Fault(&'a str),
}

impl Event<'_> {
    /// The event without its borrowed text: `None` for [`Event::Fault`].
    pub fn detach(self) -> Option<Event<'static>> {
        Some(match self {
            Event::Boot => Event::Boot,
            Event::Request(r) => Event::Request(r),
            Event::Tick {
                now,
                spindle,
                x_count,
                amplifier_fault,
            } => Event::Tick {
                now,
                spindle,
                x_count,
                amplifier_fault,
            },
            Event::X { word, now, result } => Event::X { word, now, result },
            Event::Index { edge_ticks, count } => Event::Index { edge_ticks, count },
            Event::Spi(io) => Event::Spi(io),
            Event::Pin(l) => Event::Pin(l),
            Event::Enable(v) => Event::Enable(v),
            Event::Fault(_) => return None,
        })
    }
}

/// The firmware a run was recorded with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Setup<'a> {
    pub name: &'a str,
    /// Loop rate; the loop is `ServoConfig::at_rate(loop_hz)`.
    pub loop_hz: u32,
    /// The coefficient table image the firmware was built from.
    pub table: &'a [u8],
    /// The interruption block the firmware was given
    /// (`Firmware::set_interruptions`), empty when it was given none.
    pub interruptions: &'a [u8],
    pub spindle: SpindleSetup,
    pub x: XSetup,
    pub coefficient_output: bool,
    pub gauge_reversed: bool,
}

/// `zslide::firmware::SpindleMode` in plain numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum SpindleSetup {
    None,
    Encoder {
        counts_per_rev: u32,
        ticks_per_s: u32,
        min_rpm: u32,
        max_rpm: u32,
        index_tolerance_counts: u32,
        index_angle: u32,
        /// `EdgeStamps::Captured` (else `AtRead`).
        captured: bool,
    },
    Tach {
        ticks_per_s: u32,
        mv_at_300_rpm: u32,
        min_rpm: u32,
        max_rpm: u32,
        index_tolerance_permille: u32,
        index_angle: u32,
    },
}

/// `zslide::firmware::XMode` in plain numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum XSetup {
    None,
    Legacy {
        clock_hz: u32,
    },
    Count {
        counts_per_inch: i32,
        zero_count: u32,
        max_step_counts: u32,
    },
}

/// An [`Event`] as coded: differences from the [`Codec`]'s last values.
#[derive(Debug, Serialize, Deserialize)]
enum Wire<'a> {
    Boot,
    Request(u8),
    Tick {
        /// Change of the tick period (second difference of the clock).
        ddt: i32,
        spindle: WireSpindle,
        dx: i32,
    },
    /// A tick with the amplifier's fault line high.
    TickAmplifierFault {
        ddt: i32,
        spindle: WireSpindle,
        dx: i32,
    },
    X {
        word: u32,
        /// Clock from the last tick's.
        since_tick: i32,
        result: u8,
    },
    Index {
        since_tick: i32,
        /// Count from the last encoder count.
        dcount: i32,
    },
    /// A transaction that only reads (`hdr`: dev | ok << 2 | miso_len << 5).
    SpiIn {
        hdr: u8,
        dmiso: i32,
    },
    /// A transaction that only writes (`hdr`: dev | ok << 2 | mosi_len << 3).
    SpiOut {
        hdr: u8,
        dmosi: i32,
    },
    /// Both ways (`hdr`: dev | ok << 2 | mosi_len << 3 | miso_len << 5).
    Spi {
        hdr: u8,
        dmosi: i32,
        dmiso: i32,
    },
    Pin(bool),
    Enable(bool),
    Fault(&'a str),
}

#[derive(Debug, Serialize, Deserialize)]
enum WireSpindle {
    None,
    /// Count change, and how long before the tick the last edge was.
    Encoder {
        dcount: i32,
        age: i32,
    },
    Tach(i32),
}

/// One item of a recording from the front of `bytes`, and the rest; read
/// only in its canonical encoding (every varint in its shortest form, what
/// the writers produce), anything else is [`FormatError::Item`]. postcard
/// reads a length (`&str`, `&[u8]`) as a `usize` varint: up to 10 bytes on
/// the 64-bit host, 5 on the 32-bit target, so an overlong length the host
/// player took would be refused by the target's (found by the
/// `replay_recording` fuzz target). Requiring the shortest form makes both
/// read every recording alike and refuse the same damaged ones.
pub fn take<'a, T>(bytes: &'a [u8]) -> Result<(T, &'a [u8]), FormatError>
where
    T: Deserialize<'a> + Serialize,
{
    let (v, rest) = postcard::take_from_bytes::<T>(bytes).map_err(|_| FormatError::Item)?;
    let canonical = postcard::serialize_with_flavor(&v, postcard::ser_flavors::Size::default())
        .map_err(|_| FormatError::Item)?;
    if canonical != bytes.len() - rest.len() {
        return Err(FormatError::Item);
    }
    Ok((v, rest))
}

/// A recording that cannot be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormatError {
    /// No recording where one should be (no magic).
    Missing,
    /// The container's CRC or length does not match.
    Corrupt,
    /// A version this code does not read.
    Version(u32),
    /// An item that does not decode.
    Item,
}

impl core::fmt::Display for FormatError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FormatError::Missing => write!(f, "no recording (magic missing)"),
            FormatError::Corrupt => write!(f, "recording corrupt (length or CRC)"),
            FormatError::Version(v) => write!(f, "recording version {v} not supported"),
            FormatError::Item => write!(f, "recording item does not decode"),
        }
    }
}

/// The last values the differences refer to; the encoder and the decoder
/// keep the same.
#[derive(Clone, Debug, Default)]
pub struct Codec {
    tick_now: u32,
    tick_dt: u32,
    count: u32,
    mv: i32,
    x: u32,
    mosi: [u32; 3],
    miso: [u32; 3],
}

/// The gauge ADC's frame with its four constant low bits (over-range and
/// the 0b010 pattern) moved above the 20-bit result, so that successive
/// frames differ by the result's change alone.
#[cfg(feature = "record")]
fn rotate(w: u32) -> u32 {
    ((w >> 4) & 0xF_FFFF) | ((w & 0xF) << 20)
}
fn unrotate(w: u32) -> u32 {
    ((w & 0xF_FFFF) << 4) | ((w >> 20) & 0xF)
}

#[cfg(feature = "record")]
fn diff(a: u32, b: u32) -> i32 {
    a.wrapping_sub(b) as i32
}
fn add(b: u32, d: i32) -> u32 {
    b.wrapping_add(d as u32)
}

impl Req {
    #[cfg(feature = "record")]
    fn code(self) -> u8 {
        match self {
            Req::Arm => 0,
            Req::Disarm => 1,
            Req::ClearFault => 2,
        }
    }
    fn from_code(c: u8) -> Option<Req> {
        [Req::Arm, Req::Disarm, Req::ClearFault]
            .get(usize::from(c))
            .copied()
    }
}

impl XResult {
    #[cfg(feature = "record")]
    fn code(self) -> u8 {
        match self {
            XResult::Ignored => 0,
            XResult::Update => 1,
            XResult::Fault => 2,
        }
    }
    fn from_code(c: u8) -> Option<XResult> {
        [XResult::Ignored, XResult::Update, XResult::Fault]
            .get(usize::from(c))
            .copied()
    }
}

impl Codec {
    fn tick(
        &mut self,
        ddt: i32,
        spindle: WireSpindle,
        dx: i32,
        amplifier_fault: bool,
    ) -> Event<'static> {
        self.tick_dt = add(self.tick_dt, ddt);
        self.tick_now = self.tick_now.wrapping_add(self.tick_dt);
        let now = self.tick_now;
        let spindle = match spindle {
            WireSpindle::None => Spindle::None,
            WireSpindle::Encoder { dcount, age } => {
                self.count = add(self.count, dcount);
                Spindle::Encoder {
                    count: self.count,
                    edge_ticks: now.wrapping_sub(age as u32),
                }
            }
            WireSpindle::Tach(d) => {
                self.mv = self.mv.wrapping_add(d);
                Spindle::Tach(self.mv)
            }
        };
        self.x = add(self.x, dx);
        Event::Tick {
            now,
            spindle,
            x_count: self.x,
            amplifier_fault,
        }
    }

    fn spi(&mut self, hdr: u8, dmosi: i32, dmiso: i32) -> Result<Event<'static>, FormatError> {
        let dev = Dev::from_bits(hdr & 0b11).ok_or(FormatError::Item)?;
        let d = dev as usize;
        let mosi_len = (hdr >> 3) & 0b11;
        let miso_len = (hdr >> 5) & 0b11;
        if let Some(m) = self.mosi.get_mut(d) {
            *m = add(*m, dmosi);
        }
        if let Some(m) = self.miso.get_mut(d) {
            *m = add(*m, dmiso);
        }
        // A direction not used reads as no bytes (its last frame is kept
        // for the next difference).
        let mosi = match mosi_len {
            0 => 0,
            _ => self.mosi.get(d).copied().unwrap_or(0),
        };
        let miso = match (miso_len, dev) {
            (0, _) => 0,
            (_, Dev::GaugeAdc) => unrotate(self.miso.get(d).copied().unwrap_or(0)),
            _ => self.miso.get(d).copied().unwrap_or(0),
        };
        Ok(Event::Spi(Io {
            dev,
            ok: hdr & 0b100 != 0,
            mosi_len,
            mosi,
            miso_len,
            miso,
        }))
    }

    /// Decodes the next event of `bytes`; returns it and the rest.
    pub fn decode<'a>(&mut self, bytes: &'a [u8]) -> Result<(Event<'a>, &'a [u8]), FormatError> {
        let (w, rest) = take::<Wire<'a>>(bytes)?;
        let ev = match w {
            Wire::Boot => Event::Boot,
            Wire::Request(c) => Event::Request(Req::from_code(c).ok_or(FormatError::Item)?),
            Wire::Tick { ddt, spindle, dx } => self.tick(ddt, spindle, dx, false),
            Wire::TickAmplifierFault { ddt, spindle, dx } => self.tick(ddt, spindle, dx, true),
            Wire::X {
                word,
                since_tick,
                result,
            } => Event::X {
                word,
                now: add(self.tick_now, since_tick),
                result: XResult::from_code(result).ok_or(FormatError::Item)?,
            },
            Wire::Index { since_tick, dcount } => Event::Index {
                edge_ticks: add(self.tick_now, since_tick),
                count: add(self.count, dcount),
            },
            Wire::SpiIn { hdr, dmiso } => self.spi(hdr, 0, dmiso)?,
            Wire::SpiOut { hdr, dmosi } => self.spi(hdr, dmosi, 0)?,
            Wire::Spi { hdr, dmosi, dmiso } => self.spi(hdr, dmosi, dmiso)?,
            Wire::Pin(l) => Event::Pin(l),
            Wire::Enable(e) => Event::Enable(e),
            Wire::Fault(s) => Event::Fault(s),
        };
        Ok((ev, rest))
    }

    /// Appends `ev` to `out`. Frames longer than [`MAX_FRAME_BYTES`] are
    /// refused (the caller checks: the recorder names the device).
    #[cfg(feature = "record")]
    pub fn encode(&mut self, ev: &Event<'_>, out: &mut std::vec::Vec<u8>) {
        let w = match *ev {
            Event::Boot => Wire::Boot,
            Event::Request(r) => Wire::Request(r.code()),
            Event::Tick {
                now,
                spindle,
                x_count,
                amplifier_fault,
            } => {
                let dt = now.wrapping_sub(self.tick_now);
                let ddt = diff(dt, self.tick_dt);
                self.tick_dt = dt;
                self.tick_now = now;
                let spindle = match spindle {
                    Spindle::None => WireSpindle::None,
                    Spindle::Encoder { count, edge_ticks } => {
                        let dcount = diff(count, self.count);
                        self.count = count;
                        WireSpindle::Encoder {
                            dcount,
                            age: diff(now, edge_ticks),
                        }
                    }
                    Spindle::Tach(mv) => {
                        let d = mv.wrapping_sub(self.mv);
                        self.mv = mv;
                        WireSpindle::Tach(d)
                    }
                };
                let dx = diff(x_count, self.x);
                self.x = x_count;
                if amplifier_fault {
                    Wire::TickAmplifierFault { ddt, spindle, dx }
                } else {
                    Wire::Tick { ddt, spindle, dx }
                }
            }
            Event::X { word, now, result } => Wire::X {
                word,
                since_tick: diff(now, self.tick_now),
                result: result.code(),
            },
            Event::Index { edge_ticks, count } => Wire::Index {
                since_tick: diff(edge_ticks, self.tick_now),
                dcount: diff(count, self.count),
            },
            Event::Spi(io) => {
                let d = io.dev as usize;
                let miso = if io.dev == Dev::GaugeAdc {
                    rotate(io.miso)
                } else {
                    io.miso
                };
                let (mosi_len, miso_len) = (io.mosi_len & 0b11, io.miso_len & 0b11);
                let hdr =
                    (io.dev as u8) | (u8::from(io.ok) << 2) | (mosi_len << 3) | (miso_len << 5);
                // A direction not used keeps its last frame.
                let dmosi = if mosi_len > 0 {
                    diff(io.mosi, self.mosi[d])
                } else {
                    0
                };
                let dmiso = if miso_len > 0 {
                    diff(miso, self.miso[d])
                } else {
                    0
                };
                self.mosi[d] = self.mosi[d].wrapping_add(dmosi as u32);
                self.miso[d] = self.miso[d].wrapping_add(dmiso as u32);
                match (mosi_len > 0, miso_len > 0) {
                    (false, _) => Wire::SpiIn { hdr, dmiso },
                    (true, false) => Wire::SpiOut { hdr, dmosi },
                    (true, true) => Wire::Spi { hdr, dmosi, dmiso },
                }
            }
            Event::Pin(l) => Wire::Pin(l),
            Event::Enable(e) => Wire::Enable(e),
            Event::Fault(s) => Wire::Fault(s),
        };
        // Serialising into a Vec cannot fail for these types.
        if let Ok(v) = postcard::to_extend(&w, core::mem::take(out)) {
            *out = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `bytes` with the one-byte length at `at` written in `n` bytes
    /// instead (the same value, LEB128 continued with zero groups).
    fn lengthened(bytes: &[u8], at: usize, n: usize) -> heapless::Vec<u8, 64> {
        let mut v = heapless::Vec::new();
        v.extend_from_slice(&bytes[..at]).unwrap();
        v.push(bytes[at] | 0x80).unwrap();
        for _ in 2..n {
            v.push(0x80).unwrap();
        }
        v.push(0x00).unwrap();
        v.extend_from_slice(&bytes[at + 1..]).unwrap();
        v
    }

    /// A text's length (a `usize` varint to postcard) in a longer form than
    /// its shortest is refused, whether the host would have read it (up to
    /// 10 bytes) or not, as the 32-bit target refuses it beyond 5 bytes.
    #[test]
    fn a_fault_text_or_setup_name_with_a_lengthened_length_is_refused() {
        let mut buf = [0u8; 64];
        // Wire::Fault: its variant number (one byte), then the length.
        let f = postcard::to_slice(&Wire::Fault("Bus(GaugeAdc)"), &mut buf).unwrap();
        let f: heapless::Vec<u8, 64> = heapless::Vec::from_slice(f).unwrap();
        assert_eq!(f[1], 13);
        assert_eq!(
            Codec::default().decode(&f),
            Ok((Event::Fault("Bus(GaugeAdc)"), &[][..]))
        );
        for n in [2, 5, 6, 10] {
            let long = lengthened(&f, 1, n);
            assert_eq!(
                Codec::default().decode(&long),
                Err(FormatError::Item),
                "{n}"
            );
        }
        // Setup: its name's length first.
        let s = Setup {
            name: "run",
            loop_hz: 20_000,
            table: &[1, 2, 3],
            interruptions: &[4, 5],
            spindle: SpindleSetup::None,
            x: XSetup::None,
            coefficient_output: false,
            gauge_reversed: false,
        };
        let b = postcard::to_slice(&s, &mut buf).unwrap();
        let b: heapless::Vec<u8, 64> = heapless::Vec::from_slice(b).unwrap();
        assert_eq!(take::<Setup<'_>>(&b), Ok((s, &[][..])));
        for n in [2, 5, 6, 10] {
            assert_eq!(
                take::<Setup<'_>>(&lengthened(&b, 0, n)).err(),
                Some(FormatError::Item),
                "{n}"
            );
        }
    }
}
