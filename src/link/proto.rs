//! The host link's wire format: messages and the frame codec, shared by the
//! firmware and the host tool (`zslide`, `zslide-host/`).
//!
//! # Frame
//!
//! ```text
//! COBS( body ‖ CRC-32 of body, little-endian ) ‖ 0x00
//! body = postcard( version: u8, seq: u16, message )
//! ```
//!
//! * postcard (serde, varint integers; enums as a varint variant index) for
//!   the body; COBS so that 0x00 only ever ends a frame: a receiver that
//!   joins mid-stream, or loses bytes, resynchronises at the next 0x00.
//! * CRC-32/ISO-HDLC (the table's CRC, `table::crc32`) over the body.
//! * `version` ([`VERSION`]) first, so that a host and a firmware of
//!   different protocol versions refuse each other by name instead of
//!   misreading fields.
//! * `seq`: the host numbers its requests; the reply carries the same
//!   number (a reply to a frame whose number could not be read carries 0).
//!
//! One request in flight at a time; each request frame gets exactly one
//! reply frame. A request frame that is not one ([`FrameError`]) gets the
//! reply `Refused(Frame(e))` and is counted; a lone 0x00 (an empty frame)
//! is only counted. Requests are at most [`MAX_REQUEST`] encoded bytes (an
//! oversize frame is dropped up to its delimiter, counted and refused),
//! replies at most [`MAX_FRAME`].
//!
//! # Messages
//!
//! [`Request`] and [`Reply`] below (the variant order is the wire's: only
//! append). Units: gauge and DAC codes (20 bit, 2¹⁹ = 10 V; gauge 1 V/mil,
//! so 52.4288 codes per µin), X in I8F24 inches, φ in the binary angle
//! (2³² per turn), time in loop ticks.

use crate::firmware::excite::ExciteError;
use crate::params::{ParamError, ParamSource};
use crate::safety::Fault;
use crate::store::StoreError;
use crate::table::{crc32, TableError, TableIdentity};
use serde::{Deserialize, Serialize};

/// Protocol version carried by every frame.
pub const VERSION: u8 = 1;
/// Largest encoded request frame, delimiter included.
pub const MAX_REQUEST: usize = 64;
/// Largest encoded frame (a reply), delimiter included.
pub const MAX_FRAME: usize = 512;
/// Samples per [`Reply::Samples`] (each at most 30 bytes in postcard).
pub const SAMPLES_PER_FRAME: usize = 12;
/// Fault records per [`Reply::Faults`].
pub const FAULTS_PER_FRAME: usize = 8;
/// Largest body (before CRC and COBS) that fits [`MAX_FRAME`].
const MAX_BODY: usize = MAX_FRAME - 4 - MAX_FRAME / 254 - 2;

/// What the host asks.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Request {
    /// Mode, phase, fault, X, φ, speed, command/position/output, table
    /// identity, parameter source, counters, capture state.
    Status,
    /// Fault log records from number `from` (0 = oldest kept).
    Faults { from: u16 },
    /// Sign check, then bumpless engagement.
    Arm,
    /// Ramp to null, then amplifier off.
    Disarm,
    /// Clear the latched fault (refused while its cause is present or the
    /// loop is armed).
    Clear,
    /// Set servo parameter `id` (`params::PARAMS`): only while disarmed.
    Set { id: u16, value: f64 },
    /// Read servo parameter `id`.
    Get { id: u16 },
    /// Arm the capture: `samples` consecutive loop ticks, `pre` of them
    /// before the trigger.
    CaptureStart {
        samples: u16,
        pre: u16,
        trigger: Trigger,
    },
    /// The capture's state.
    CaptureInfo,
    /// Captured samples from number `from` (0 = oldest).
    CaptureRead { from: u16 },
    /// Identification: a sine of `amplitude` DAC codes, `step` binary
    /// angle per loop tick, added to the DAC for `ticks` ticks; only while
    /// engaged at null (`firmware::excite`). `ticks` 0 stops one.
    Excite {
        step: u32,
        amplitude: u32,
        ticks: u32,
    },
    /// Save every servo parameter in force to the parameter store (only
    /// while disarmed; the boot reads it back first, `store::boot`).
    SaveParams,
    /// [`Request::Excite`] anchored to a loop tick: the sine's phase 0 is
    /// on loop tick `at` (the status's `ticks` count), zeros before it.
    /// Refused (`ExciteError::StartTick`) when the loop takes the request
    /// on or after `at` (a late arm), or more than `EXCITE_MAX_S` ahead of
    /// it.
    ExciteAt {
        step: u32,
        amplitude: u32,
        ticks: u32,
        at: u32,
    },
}

/// Number of [`Request`] variants: a variant index at or above it is an
/// unknown command (not a malformed frame).
pub const REQUEST_KINDS: u32 = 13;

/// What starts a capture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Trigger {
    /// At once (the first sample recorded).
    Immediate,
    /// The tick a fault latches.
    Fault,
    /// The first tick on which |command − position| reaches `level` gauge
    /// codes from below (an edge: a level already exceeded when the
    /// capture is armed must first fall below it).
    FollowingError { level: u32 },
    /// Loop tick `tick` (the status's `ticks` count). A capture the loop
    /// takes on or after that tick never triggers: its state reads
    /// [`CaptureState::Late`].
    AtTick { tick: u32 },
}

/// The loop's engagement phase (`servo::Phase`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum LoopPhase {
    Disarmed,
    SignCheck,
    Engaging,
    Engaged,
    Disarming,
}

/// Where X comes from (`config::XMode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum XSource {
    None,
    LegacyHalfMil,
    Count,
}

/// Where the spindle angle comes from (`config::SpindleMode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum SpindleSource {
    None,
    Encoder,
    Tachometer,
}

/// Frames the firmware took and refused, by cause.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrameCounters {
    pub ok: u32,
    pub empty: u32,
    pub oversize: u32,
    pub bad_cobs: u32,
    pub bad_crc: u32,
    pub bad_version: u32,
    pub unknown_command: u32,
    pub malformed: u32,
}

/// What the loop tick reports when asked (`tap`): one consistent snapshot
/// of the loop, taken right after a loop tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LoopSnapshot {
    /// Loop ticks since boot (wrapping).
    pub ticks: u32,
    pub phase: LoopPhase,
    pub amplifier_enabled: bool,
    pub fault: Option<Fault>,
    /// A clear request found this fault's cause still present.
    pub clear_refused: Option<Fault>,
    /// X of the coefficients in use (None before the first X), I8F24 in.
    pub x_bits: Option<i32>,
    /// The command is null (X in the null zone, no X, no table).
    pub null_command: bool,
    /// Spindle angle (None: not referenced yet).
    pub phi: Option<u32>,
    /// Angle step per loop tick, binary angle Q8 (speed).
    pub phi_step_q8: Option<i64>,
    pub command: i32,
    pub position: i32,
    pub output: i32,
    pub table_command: i32,
    /// Servo configurations (new parameters) the tick applied, and refused
    /// because the loop was armed by then.
    pub configs_applied: u32,
    pub configs_refused: u32,
    /// The identification sine is on the DAC (`Request::Excite`).
    pub exciting: bool,
}

/// The firmware's state: the loop tick's snapshot and the background's own
/// records.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Status {
    pub state: LoopSnapshot,
    pub loop_hz: u32,
    pub x_source: XSource,
    pub spindle_source: SpindleSource,
    pub table: Result<TableIdentity, TableError>,
    pub params: ParamSource,
    pub x_accepted: u32,
    pub x_ignored: u32,
    pub index_events: u32,
    pub coefficient_sets: u32,
    /// Fault records ever logged (the log keeps the last [`FAULT_LOG`]).
    pub faults_logged: u32,
    pub frames: FrameCounters,
    pub capture: CaptureInfo,
}

/// Fault records the firmware keeps.
pub const FAULT_LOG: usize = 32;

/// One fault-log record: a fault latched, or cleared, at a loop tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FaultRecord {
    pub tick: u32,
    pub fault: Fault,
    /// This record is the fault's clear, not its latch.
    pub cleared: bool,
}

/// A page of the fault log.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FaultPage {
    /// Records ever logged (older ones than the kept ones are gone).
    pub total: u32,
    /// Records kept now.
    pub kept: u16,
    pub from: u16,
    pub records: heapless::Vec<FaultRecord, FAULTS_PER_FRAME>,
}

/// State of the capture.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum CaptureState {
    Idle,
    /// Recording the pre-trigger window, waiting for the trigger.
    Armed,
    /// Triggered, recording the rest.
    Triggered,
    /// Complete: `recorded` samples ready to read.
    Done,
    /// Armed for [`Trigger::AtTick`] after its tick had passed: nothing
    /// will be recorded (arm again for a later tick).
    Late,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct CaptureInfo {
    pub state: CaptureState,
    pub trigger: Trigger,
    pub samples: u16,
    pub pre: u16,
    /// Samples ready (Done): the pre-trigger ones present plus the rest.
    pub recorded: u16,
    /// Of them, before the trigger sample (fewer than `pre` when the
    /// trigger came before the window had filled).
    pub before_trigger: u16,
    /// Loop tick of the trigger sample.
    pub trigger_tick: u32,
    /// Largest `samples` this firmware holds.
    pub capacity: u16,
}

/// One loop tick as the capture recorded it (gauge/DAC codes, binary
/// angle, I8F24 inches).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Sample {
    pub command: i32,
    pub position: i32,
    /// command − position.
    pub error: i32,
    pub output: i32,
    pub phi: u32,
    /// X (I8F24 inches), or [`X_UNKNOWN`] on a tick before the first X
    /// reading.
    pub x_bits: i32,
}

/// A sample's `x_bits` when X was not known (−128 in: no slide's X).
pub const X_UNKNOWN: i32 = i32::MIN;

/// Why a request was not carried out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Refusal {
    /// The request frame was not a valid frame.
    Frame(FrameError),
    /// Arm refused: a fault that keeps the amplifier off is latched.
    ArmFault(Fault),
    /// Clear refused: the fault's cause is still present, or the loop is
    /// armed (disarm first).
    ClearCause(Fault),
    /// Clear: no fault is latched.
    NoFault,
    Param(ParamError),
    /// Parameters change only while the loop is disarmed.
    Armed,
    /// `samples` is 0 or above the capacity, or `pre` ≥ `samples`.
    CaptureSize {
        capacity: u16,
    },
    /// No complete capture to read.
    CaptureNotDone,
    /// `from` beyond the recorded samples or fault records.
    Range,
    /// The loop tick did not answer (it is not running).
    LoopSilent,
    /// An identification sine outside its bounds, or not at null.
    Excite(ExciteError),
    /// The parameters were not saved.
    Store(StoreError),
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Refusal::Frame(e) => write!(f, "the firmware refused the frame: {e}"),
            Refusal::ArmFault(fault) => write!(
                f,
                "arm refused: a fault that keeps the amplifier off is latched ({fault}); clear it first"
            ),
            Refusal::ClearCause(fault) => write!(
                f,
                "clear refused: the cause is still present or the loop is armed ({fault}); disarm and remove the cause first"
            ),
            Refusal::NoFault => f.write_str("clear: no fault is latched"),
            Refusal::Param(e) => write!(f, "parameter refused: {e}"),
            Refusal::Armed => f.write_str(
                "parameters change only while the loop is disarmed (the loop would restart from a new state): disarm first",
            ),
            Refusal::CaptureSize { capacity } => write!(
                f,
                "capture refused: samples must be 1..={capacity} and the pre-trigger count below them"
            ),
            Refusal::CaptureNotDone => f.write_str("no complete capture to read"),
            Refusal::Range => f.write_str("asked beyond the recorded samples or fault records"),
            Refusal::LoopSilent => f.write_str("the loop tick did not answer: it is not running"),
            Refusal::Excite(e) => write!(f, "{e}"),
            Refusal::Store(e) => write!(f, "{e}"),
        }
    }
}

/// What the firmware answers.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Reply {
    Status(Status),
    Faults(FaultPage),
    /// After arm or disarm: the loop's phase now.
    Phase(LoopPhase),
    /// The fault was cleared.
    Cleared(Fault),
    /// The parameter's value now in force (set or get).
    Param {
        id: u16,
        value: f64,
    },
    Capture(CaptureInfo),
    Samples {
        from: u16,
        samples: heapless::Vec<Sample, SAMPLES_PER_FRAME>,
    },
    Refused(Refusal),
    /// The identification sine runs (from the loop tick `tick`, phase 0
    /// there), for `ticks` ticks.
    Exciting {
        tick: u32,
        ticks: u32,
    },
    /// The parameter block saved to the store: `entries` parameters, its
    /// CRC.
    Saved {
        entries: u16,
        crc: u32,
    },
}

/// Why a received frame is not a request.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum FrameError {
    /// Longer than [`MAX_REQUEST`] (dropped up to its delimiter).
    Oversize,
    /// Not valid COBS.
    BadCobs,
    /// Too short to hold a version, a number and a CRC.
    Short,
    BadCrc {
        stored: u32,
        computed: u32,
    },
    /// Another protocol version.
    BadVersion(u8),
    /// A command this firmware does not know (its variant index).
    UnknownCommand(u32),
    /// A known command whose fields do not decode, or bytes after them.
    Malformed,
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            FrameError::Oversize => write!(f, "frame longer than {MAX_REQUEST} bytes"),
            FrameError::BadCobs => f.write_str("not a COBS-encoded frame"),
            FrameError::Short => f.write_str("frame too short for version, number and CRC"),
            FrameError::BadCrc { stored, computed } => write!(
                f,
                "frame corrupt: its CRC says {stored:#010x}, its bytes give {computed:#010x}"
            ),
            FrameError::BadVersion(v) => {
                write!(f, "protocol version {v}, this end speaks version {VERSION}")
            }
            FrameError::UnknownCommand(c) => write!(f, "unknown command number {c}"),
            FrameError::Malformed => f.write_str("the command's fields do not decode"),
        }
    }
}

/// Encodes `msg` as one frame (delimiter included) into `out`; `None` if
/// `out` is too small.
pub fn encode<'o, T: Serialize>(seq: u16, msg: &T, out: &'o mut [u8]) -> Option<&'o [u8]> {
    let mut body = [0u8; MAX_BODY + 4];
    let used = postcard::to_slice(&(VERSION, seq, msg), &mut body[..MAX_BODY])
        .ok()?
        .len();
    let crc = crc32(body.get(..used)?);
    body.get_mut(used..used + 4)?
        .copy_from_slice(&crc.to_le_bytes());
    let n = cobs::try_encode(body.get(..used + 4)?, out).ok()?;
    *out.get_mut(n)? = 0;
    out.get(..n + 1)
}

/// COBS-decodes `buf` in place (no 0x00 inside: the delimiter is not
/// part of it); returns the decoded length. Written here with checked
/// access instead of the `cobs` crate's decoder, whose indexing is correct
/// but not provably so: these bytes come from the host, and `cargo xtask
/// no-panic` holds the link's service to the interrupt handlers' rule.
/// (Tested against the `cobs` crate's decoder on arbitrary input.)
pub fn cobs_decode_in_place(buf: &mut [u8]) -> Option<usize> {
    let (mut src, mut dst) = (0usize, 0usize);
    while let Some(&code) = buf.get(src) {
        if code == 0 {
            return None;
        }
        src += 1;
        for _ in 1..code {
            let b = *buf.get(src)?;
            if b == 0 {
                return None;
            }
            *buf.get_mut(dst)? = b;
            src += 1;
            dst += 1;
        }
        if code != 0xFF && src < buf.len() {
            *buf.get_mut(dst)? = 0;
            dst += 1;
        }
    }
    Some(dst)
}

/// Decodes one frame's bytes (between delimiters, without the 0x00),
/// COBS-decoding them in place. Returns the sequence number and the
/// message, or why the bytes are not a frame of `T` (`kinds`: the number
/// of `T`'s variants, to tell an unknown command from a malformed one).
pub fn decode<'a, T: Deserialize<'a>>(
    frame: &'a mut [u8],
    kinds: u32,
) -> Result<(u16, T), (u16, FrameError)> {
    let n = cobs_decode_in_place(frame).ok_or((0, FrameError::BadCobs))?;
    let frame = frame.get(..n).ok_or((0, FrameError::BadCobs))?;
    let Some((body, tail)) = frame.split_last_chunk::<4>().filter(|(b, _)| b.len() >= 3) else {
        return Err((0, FrameError::Short));
    };
    let stored = u32::from_le_bytes(*tail);
    let computed = crc32(body);
    if stored != computed {
        return Err((0, FrameError::BadCrc { stored, computed }));
    }
    let (version, rest) =
        postcard::take_from_bytes::<u8>(body).map_err(|_| (0, FrameError::Short))?;
    if version != VERSION {
        return Err((0, FrameError::BadVersion(version)));
    }
    let (seq, rest) = postcard::take_from_bytes::<u16>(rest).map_err(|_| (0, FrameError::Short))?;
    let (kind, _) =
        postcard::take_from_bytes::<u32>(rest).map_err(|_| (seq, FrameError::Malformed))?;
    if kind >= kinds {
        return Err((seq, FrameError::UnknownCommand(kind)));
    }
    match postcard::take_from_bytes::<T>(rest) {
        Ok((msg, [])) => Ok((seq, msg)),
        _ => Err((seq, FrameError::Malformed)),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    fn frame<T: Serialize>(seq: u16, msg: &T) -> Vec<u8> {
        let mut out = [0u8; MAX_FRAME];
        encode(seq, msg, &mut out).unwrap().to_vec()
    }

    fn dec(bytes: &[u8]) -> Result<(u16, Request), (u16, FrameError)> {
        let mut b = bytes.to_vec();
        assert_eq!(b.pop(), Some(0), "frames end in the delimiter");
        decode(&mut b, REQUEST_KINDS)
    }

    /// The layout the module documents, checked byte by byte for one
    /// request: postcard(1, 7, Set{3, 0.5}) = 01 07 05 03 + f64 LE, then
    /// the CRC, COBS around it all, one 0x00 at the end and none inside.
    #[test]
    fn a_frame_is_cobs_of_body_and_its_crc() {
        let f = frame(7, &Request::Set { id: 3, value: 0.5 });
        let mut body = std::vec![1u8, 7, 5, 3];
        body.extend(0.5f64.to_le_bytes());
        let mut raw = body.clone();
        raw.extend(crc32(&body).to_le_bytes());
        let mut want = std::vec![0u8; raw.len() + 2];
        let n = cobs::encode(&raw, &mut want);
        want.truncate(n);
        want.push(0);
        assert_eq!(f, want);
        assert!(!f[..f.len() - 1].contains(&0));
        assert_eq!(dec(&f), Ok((7, Request::Set { id: 3, value: 0.5 })));
    }

    #[test]
    fn every_request_round_trips() {
        let all = [
            Request::Status,
            Request::Faults { from: 3 },
            Request::Arm,
            Request::Disarm,
            Request::Clear,
            Request::Set {
                id: 20,
                value: 1e-6,
            },
            Request::Get { id: 1 },
            Request::CaptureStart {
                samples: 1024,
                pre: 100,
                trigger: Trigger::FollowingError { level: 5243 },
            },
            Request::CaptureInfo,
            Request::CaptureRead { from: 1012 },
            Request::Excite {
                step: u32::MAX,
                amplitude: u32::MAX,
                ticks: u32::MAX,
            },
            Request::SaveParams,
            Request::ExciteAt {
                step: u32::MAX,
                amplitude: u32::MAX,
                ticks: u32::MAX,
                at: u32::MAX,
            },
        ];
        assert_eq!(all.len() as u32, REQUEST_KINDS);
        for (i, r) in all.iter().enumerate() {
            let f = frame(i as u16, r);
            assert!(f.len() <= MAX_REQUEST, "{r:?}: {} bytes", f.len());
            assert_eq!(dec(&f), Ok((i as u16, *r)));
        }
    }

    /// The largest replies fit a frame.
    #[test]
    fn the_largest_replies_fit_a_frame() {
        let worst = Sample {
            command: i32::MIN,
            position: i32::MIN,
            error: i32::MIN,
            output: i32::MIN,
            phi: u32::MAX,
            x_bits: i32::MIN,
        };
        let mut samples = heapless::Vec::new();
        while samples.push(worst).is_ok() {}
        let r = Reply::Samples { from: 1, samples };
        assert!(frame(1, &r).len() <= MAX_FRAME);
        let rec = FaultRecord {
            tick: u32::MAX,
            fault: Fault::Table(TableError::PayloadCrc {
                stored: u32::MAX,
                computed: u32::MAX,
            }),
            cleared: true,
        };
        let mut records = heapless::Vec::new();
        while records.push(rec).is_ok() {}
        let page = Reply::Faults(FaultPage {
            total: u32::MAX,
            kept: 32,
            from: 0,
            records,
        });
        assert!(frame(1, &page).len() <= MAX_FRAME);
    }

    /// The decoder agrees with the `cobs` crate's on what it accepts and
    /// what it makes of it, for every encoding and for arbitrary bytes.
    #[test]
    fn cobs_decoding_agrees_with_the_cobs_crate() {
        use proptest::prelude::*;
        proptest!(|(data in proptest::collection::vec(any::<u8>(), 0..700))| {
            let mut enc = std::vec![0u8; data.len() + data.len() / 254 + 2];
            let n = cobs::encode(&data, &mut enc);
            let mut ours = enc[..n].to_vec();
            prop_assert_eq!(cobs_decode_in_place(&mut ours), Some(data.len()));
            prop_assert_eq!(&ours[..data.len()], &data[..]);
            // Arbitrary bytes (no zero inside, as between delimiters).
            let raw: Vec<u8> = data.iter().map(|&b| b.max(1)).collect();
            let mut a = raw.clone();
            let mut b = raw.clone();
            let theirs = cobs::decode_in_place(&mut b).ok();
            let ours = cobs_decode_in_place(&mut a);
            if let (Some(x), Some(y)) = (ours, theirs) {
                prop_assert_eq!(&a[..x], &b[..y]);
            }
        });
    }

    #[test]
    fn each_defect_is_named() {
        let good = frame(9, &Request::Faults { from: 2 });
        // A flipped bit inside: the CRC (or COBS) refuses it.
        for at in 0..good.len() - 1 {
            let mut m = good.clone();
            m[at] ^= 0x10;
            if m[at] == 0 {
                continue;
            }
            let e = dec(&m).unwrap_err().1;
            assert!(
                matches!(
                    e,
                    FrameError::BadCrc { .. } | FrameError::BadCobs | FrameError::Short
                ),
                "byte {at}: {e:?}"
            );
        }
        // Truncated: the CRC no longer matches, or too short.
        for cut in 1..good.len() - 1 {
            let mut m = good[..cut].to_vec();
            m.push(0);
            assert!(dec(&m).is_err(), "cut at {cut}");
        }
        // Another version, an unknown command, trailing bytes, bad fields:
        // valid frames (CRC right) that are not requests of this version.
        let raw = |body: &[u8]| {
            let mut r = body.to_vec();
            r.extend(crc32(body).to_le_bytes());
            let mut out = std::vec![0u8; r.len() + 2];
            let n = cobs::encode(&r, &mut out);
            out.truncate(n);
            out.push(0);
            out
        };
        assert_eq!(
            dec(&raw(&[2, 5, 0])).unwrap_err(),
            (0, FrameError::BadVersion(2))
        );
        assert_eq!(
            dec(&raw(&[1, 5, 42])).unwrap_err(),
            (5, FrameError::UnknownCommand(42))
        );
        assert_eq!(
            dec(&raw(&[1, 5, 0, 0])).unwrap_err(),
            (5, FrameError::Malformed)
        );
        // Faults{from} with a varint that never ends.
        assert_eq!(
            dec(&raw(&[1, 5, 1, 0xFF, 0xFF, 0xFF])).unwrap_err(),
            (5, FrameError::Malformed)
        );
        assert_eq!(dec(&raw(&[1, 5])).unwrap_err().1, FrameError::Short);
    }
}
