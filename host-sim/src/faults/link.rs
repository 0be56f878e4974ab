//! The malformed-host-frame row: a flood of frames that are not requests
//! (garbage, truncated, corrupt, unknown commands, another protocol
//! version, undecodable fields, oversize, empty), with a few valid
//! read-only requests among them, written by the host into the running
//! cut's link (`crate::fwrig::link`) as fast as the RTT buffer takes them; and
//! what the host read back.
//!
//! The truncated and corrupted frames are made from every kind of request,
//! arm, disarm, clear and set included: a damaged disarm must not disarm.

use crate::fwrig::HostLink;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use zslide::link::proto::{
    self, FrameCounters, LoopPhase, Refusal, Reply, Request, Trigger, MAX_FRAME, MAX_REQUEST,
    REQUEST_KINDS, VERSION,
};

/// Frames of each malformed kind in the flood.
pub const GARBAGE: u32 = 120;
pub const TRUNCATED: u32 = 30;
pub const CORRUPT: u32 = 30;
pub const UNKNOWN_COMMAND: u32 = 15;
pub const OTHER_VERSION: u32 = 15;
pub const UNDECODABLE: u32 = 15;
pub const OVERSIZE: u32 = 10;
/// Lone delimiters (counted, never answered).
pub const EMPTY: u32 = 10;

/// Sequence number of the status request in the middle of the flood.
pub const STATUS_SEQ: u16 = 0x5151;

/// The bytes the host sends, and what they are.
#[derive(Clone, Debug)]
pub struct Flood {
    pub bytes: Vec<u8>,
    /// Non-empty frames that are not requests.
    pub malformed: u32,
    /// The valid requests, by sequence number.
    pub valid: Vec<(u16, Request)>,
    pub empty: u32,
}

/// What the host read back, judged.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LinkOutcome {
    pub frames_sent: u32,
    pub malformed_sent: u32,
    pub valid_sent: u32,
    pub empty_sent: u32,
    /// The station's counters at the end.
    pub counters: FrameCounters,
    /// Refused frames by the counters (every cause but `ok` and `empty`).
    pub refused: u32,
    /// Reply frames the host read, and how many of them refuse a frame.
    pub replies: u32,
    pub refusal_replies: u32,
    /// Every valid request got its own reply (by sequence number).
    pub valid_answered: bool,
    /// The status request's reply: the loop's phase and latched fault.
    pub status_phase: Option<String>,
    pub status_fault: Option<String>,
    /// The first refusal, in the firmware's words.
    pub first_refusal: Option<String>,
    /// Bytes the host never got to write (0: the flood was all taken).
    pub unread_bytes: usize,
}

/// A link frame around any body, right or wrong for the firmware: the
/// body, its CRC and the COBS delimiter, as a well-behaved host frames
/// (the malformed frames of the flood and of `cargo xtask link-test`).
pub fn frame(body: &[u8]) -> Vec<u8> {
    let mut v = body.to_vec();
    v.extend(zslide::table::crc32(body).to_le_bytes());
    let mut out = vec![0u8; cobs::max_encoding_length(v.len())];
    let n = cobs::encode(&v, &mut out);
    out.truncate(n);
    out.push(0);
    out
}

fn request_frame(seq: u16, r: &Request) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME];
    proto::encode(seq, r, &mut out)
        .expect("every request fits a frame")
        .to_vec()
}

/// Any request, the state-changing ones included (only ever sent damaged).
fn any_request(rng: &mut Xoshiro256PlusPlus) -> Request {
    match rng.random_range(0..REQUEST_KINDS) {
        0 => Request::Status,
        1 => Request::Faults { from: 0 },
        2 => Request::Arm,
        3 => Request::Disarm,
        4 => Request::Clear,
        5 => Request::Set { id: 1, value: 40.0 },
        6 => Request::Get { id: 1 },
        7 => Request::CaptureStart {
            samples: 64,
            pre: 8,
            trigger: Trigger::Fault,
        },
        8 => Request::CaptureInfo,
        _ => Request::CaptureRead { from: 0 },
    }
}

fn nonzero_bytes(rng: &mut Xoshiro256PlusPlus, n: usize) -> Vec<u8> {
    (0..n).map(|_| rng.random_range(1..=255u8)).collect()
}

/// The flood, from `seed`: every malformed frame and the valid requests
/// shuffled, the status request in the middle.
pub fn flood(seed: u64) -> Flood {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x1_14EF_100D);
    let mut frames: Vec<Vec<u8>> = Vec::new();
    for _ in 0..GARBAGE {
        let n = rng.random_range(1..=60);
        let mut f = nonzero_bytes(&mut rng, n);
        f.push(0);
        frames.push(f);
    }
    for _ in 0..TRUNCATED {
        let r = any_request(&mut rng);
        let mut f = request_frame(rng.random(), &r);
        f.pop();
        let keep = rng.random_range(1..f.len());
        f.truncate(keep);
        f.push(0);
        frames.push(f);
    }
    for _ in 0..CORRUPT {
        let r = any_request(&mut rng);
        let mut f = request_frame(rng.random(), &r);
        let at = rng.random_range(0..f.len() - 1);
        // One bit flipped, never into a delimiter.
        let mut bit = rng.random_range(0..8);
        if f[at] ^ (1 << bit) == 0 {
            bit = (bit + 1) % 8;
        }
        f[at] ^= 1 << bit;
        frames.push(f);
    }
    // Sequence numbers below 128 are one varint byte.
    for _ in 0..UNKNOWN_COMMAND {
        let kind = rng.random_range(REQUEST_KINDS as u8..128);
        frames.push(frame(&[VERSION, rng.random_range(0..128), kind]));
    }
    for _ in 0..OTHER_VERSION {
        let v = rng.random_range(VERSION + 1..=255);
        frames.push(frame(&[v, rng.random_range(0..128), 0]));
    }
    for k in 0..UNDECODABLE {
        let body = if k % 2 == 0 {
            // Set with its value cut short.
            vec![VERSION, rng.random_range(0..128), 5, 1, 0x40]
        } else {
            // Status with bytes after it.
            vec![VERSION, rng.random_range(0..128), 0, rng.random()]
        };
        frames.push(frame(&body));
    }
    for _ in 0..OVERSIZE {
        let n = rng.random_range(MAX_REQUEST..=400);
        let mut f = nonzero_bytes(&mut rng, n);
        f.push(0);
        frames.push(f);
    }
    let malformed = frames.len() as u32;
    for _ in 0..EMPTY {
        frames.push(vec![0]);
    }
    // Fisher-Yates with the run's generator.
    for i in (1..frames.len()).rev() {
        let j = rng.random_range(0..=i);
        frames.swap(i, j);
    }
    let mut valid = vec![
        (0x5152, Request::Get { id: 1 }),
        (0x5153, Request::Faults { from: 0 }),
        (0x5154, Request::CaptureInfo),
    ];
    for &(seq, r) in &valid {
        let at = rng.random_range(0..frames.len());
        frames.insert(at, request_frame(seq, &r));
    }
    let mid = frames.len() / 2;
    frames.insert(mid, request_frame(STATUS_SEQ, &Request::Status));
    valid.push((STATUS_SEQ, Request::Status));
    Flood {
        bytes: frames.concat(),
        malformed,
        valid,
        empty: EMPTY,
    }
}

/// The host's reading of what came back.
pub fn judge(f: &Flood, link: &HostLink) -> LinkOutcome {
    let c = link.frames();
    let refused =
        c.oversize + c.bad_cobs + c.bad_crc + c.bad_version + c.unknown_command + c.malformed;
    let mut replies = 0;
    let mut refusal_replies = 0;
    let mut answered = vec![false; f.valid.len()];
    let (mut status_phase, mut status_fault, mut first_refusal) = (None, None, None);
    for bytes in link.received().split(|&b| b == 0) {
        if bytes.is_empty() {
            continue;
        }
        replies += 1;
        let mut b = bytes.to_vec();
        let Ok((seq, reply)) = proto::decode::<Reply>(&mut b, u32::MAX) else {
            continue;
        };
        match reply {
            Reply::Refused(r @ Refusal::Frame(_)) => {
                refusal_replies += 1;
                if first_refusal.is_none() {
                    first_refusal = Some(r.to_string());
                }
            }
            r => {
                if let Some(k) = f.valid.iter().position(|&(s, _)| s == seq) {
                    answered[k] = true;
                }
                if let (STATUS_SEQ, Reply::Status(s)) = (seq, &r) {
                    status_phase = Some(format!("{:?}", s.state.phase));
                    status_fault = Some(format!("{:?}", s.state.fault));
                }
            }
        }
    }
    LinkOutcome {
        frames_sent: f.malformed + f.valid.len() as u32 + f.empty,
        malformed_sent: f.malformed,
        valid_sent: f.valid.len() as u32,
        empty_sent: f.empty,
        counters: c,
        refused,
        replies,
        refusal_replies,
        valid_answered: answered.iter().all(|&a| a),
        status_phase,
        status_fault,
        first_refusal,
        unread_bytes: link.unread(),
    }
}

impl LinkOutcome {
    /// Every malformed frame refused and counted, every valid request
    /// answered, one reply per non-empty frame, the flood all read, and
    /// the status answered with the loop engaged and no fault.
    pub fn all_served(&self) -> bool {
        self.refused == self.malformed_sent
            && self.refusal_replies == self.malformed_sent
            && self.counters.ok == self.valid_sent
            && self.counters.empty == self.empty_sent
            && self.replies == self.malformed_sent + self.valid_sent
            && self.valid_answered
            && self.unread_bytes == 0
            && self.status_phase.as_deref() == Some(&format!("{:?}", LoopPhase::Engaged))
            && self.status_fault.as_deref() == Some("None")
    }
}
