//! The host link end to end on the host: the firmware's loop tick with the
//! link's tap, its background station, and a host that speaks the frames,
//! over an in-memory transport. (The same code runs in QEMU over the CMSDK
//! UART in `cargo xtask test`.)

use std::collections::VecDeque;

use zslide::firmware::{Firmware, LoopState, Shared, TickInput};
use zslide::hw::{AmplifierDac, BusError, GaugeAdc, GaugeSample};
use zslide::link::proto::{
    self, CaptureState, FrameError, LoopPhase, Refusal, Reply, Request, SpindleSource, Trigger,
    XSource, MAX_FRAME,
};
use zslide::link::station::{LinkIo, Station, StationConfig};
use zslide::link::tap::{Scope, TapShared, TickTap};
use zslide::params::{self, ParamError, ParamSource};
use zslide::safety::{Device, Fault};
use zslide::servo::{ServoConfig, ServoDesign};
use zslide::table::TableError;

const CAP: usize = 256;

struct Gauge(Result<GaugeSample, BusError>);
impl GaugeAdc for Gauge {
    fn read(&mut self) -> Result<GaugeSample, BusError> {
        self.0
    }
}
fn at(code: i32) -> Gauge {
    Gauge(Ok(GaugeSample {
        code,
        overrange: false,
    }))
}

#[derive(Default)]
struct Dac;
impl AmplifierDac for Dac {
    fn write(&mut self, _: i32) -> Result<(), BusError> {
        Ok(())
    }
    fn clamp_to_ground(&mut self) -> Result<(), BusError> {
        Ok(())
    }
    fn release_clamp(&mut self) -> Result<(), BusError> {
        Ok(())
    }
}

/// The transport: bytes the host sent, bytes the firmware wrote.
#[derive(Default)]
struct Pipe {
    to_fw: VecDeque<u8>,
    from_fw: Vec<u8>,
}
impl LinkIo for Pipe {
    fn read(&mut self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        while n < buf.len() {
            match self.to_fw.pop_front() {
                Some(b) => {
                    buf[n] = b;
                    n += 1;
                }
                None => break,
            }
        }
        n
    }
    fn write(&mut self, bytes: &[u8]) -> usize {
        // A slow transport: at most 7 bytes a pass.
        let n = bytes.len().min(7);
        self.from_fw.extend_from_slice(&bytes[..n]);
        n
    }
}

struct Rig {
    lp: LoopState,
    shared: &'static Shared,
    tap_shared: &'static TapShared<'static, CAP>,
    tap: TickTap,
    station: Station<CAP>,
    pipe: Pipe,
    gauge: Gauge,
    seq: u16,
}

/// The bench loop without the commissioning sign check (the test gauge
/// does not move when the DAC does).
fn design() -> ServoDesign {
    let mut d = ServoDesign::brief(20_000);
    d.sign_check_v = 0.0;
    d
}

impl Rig {
    fn new() -> Self {
        let cfg: ServoConfig = design().config().unwrap();
        let (lp, _, _) = Firmware::new(cfg).into_parts();
        let station = Station::new(StationConfig {
            loop_hz: 20_000,
            x_source: XSource::None,
            spindle_source: SpindleSource::None,
            table: Err(TableError::Missing),
            design: design(),
            params: ParamSource::BuiltIn,
        });
        Self {
            lp,
            shared: Box::leak(Box::new(Shared::new())),
            tap_shared: Box::leak(Box::new(TapShared::new(Box::leak(Box::new(Scope::new()))))),
            tap: TickTap::new(),
            station,
            pipe: Pipe::default(),
            gauge: at(0),
            seq: 0,
        }
    }

    /// One loop tick, then one background pass (as on the boards: the
    /// background wakes after each tick).
    fn step(&mut self) {
        self.lp
            .loop_tick(self.shared, &TickInput::NONE, &mut self.gauge, &mut Dac);
        self.tap.after_tick(self.tap_shared, &mut self.lp);
        self.station
            .poll(self.tap_shared, self.shared, &mut self.pipe);
    }

    fn send_raw(&mut self, bytes: &[u8]) {
        self.pipe.to_fw.extend(bytes);
    }

    /// The next complete reply frame, decoded.
    fn reply(&mut self) -> (u16, Reply) {
        for _ in 0..2000 {
            self.step();
            if let Some(end) = self.pipe.from_fw.iter().position(|&b| b == 0) {
                let mut frame: Vec<u8> = self.pipe.from_fw.drain(..=end).collect();
                frame.pop();
                return proto::decode::<Reply>(&mut frame, u32::MAX).unwrap();
            }
        }
        panic!("no reply within 2000 ticks");
    }

    fn ask(&mut self, r: Request) -> Reply {
        self.seq = self.seq.wrapping_add(1);
        let mut out = [0u8; MAX_FRAME];
        let f = proto::encode(self.seq, &r, &mut out).unwrap().to_vec();
        self.send_raw(&f);
        let (seq, reply) = self.reply();
        assert_eq!(seq, self.seq, "reply to another request");
        reply
    }

    /// The `recorded` samples of a done capture.
    fn read_capture(&mut self, recorded: u16) -> Vec<proto::Sample> {
        let mut s = Vec::new();
        while s.len() < usize::from(recorded) {
            // Each read must bring samples: any other reply, or none, would
            // repeat the same read forever.
            match self.ask(Request::CaptureRead {
                from: s.len() as u16,
            }) {
                Reply::Samples { samples, .. } if !samples.is_empty() => s.extend(samples),
                x => panic!("read from {} of {recorded}: {x:?}", s.len()),
            }
        }
        s
    }

    fn status(&mut self) -> proto::Status {
        match self.ask(Request::Status) {
            Reply::Status(s) => s,
            r => panic!("{r:?}"),
        }
    }
}

fn pid(name: &str) -> u16 {
    params::by_name(name).unwrap().id
}

#[test]
fn status_arm_disarm_and_parameters_within_and_outside_limits() {
    let mut r = Rig::new();
    let s = r.status();
    assert_eq!(s.state.phase, LoopPhase::Disarmed);
    assert!(!s.state.amplifier_enabled);
    assert_eq!(s.table, Err(TableError::Missing));
    // The bench firmware has no table and latches nothing for it.
    assert_eq!(s.state.fault, None);
    assert!(s.state.ticks > 0);

    // Parameters: out of limits refused with the limits; in limits
    // applied to the loop's integer configuration (0.0001 in = 5242 codes).
    let fe = pid("following_error_in");
    match r.ask(Request::Set { id: fe, value: 0.5 }) {
        Reply::Refused(Refusal::Param(ParamError::OutOfRange { id, .. })) => assert_eq!(id, fe),
        x => panic!("{x:?}"),
    }
    assert_eq!(
        r.ask(Request::Set {
            id: fe,
            value: 0.0001
        }),
        Reply::Param {
            id: fe,
            value: 0.0001
        }
    );
    assert_eq!(r.lp.config().following_error_code, 5242);
    assert_eq!(
        r.ask(Request::Get { id: fe }),
        Reply::Param {
            id: fe,
            value: 0.0001
        }
    );

    match r.ask(Request::Arm) {
        Reply::Phase(p) => assert_ne!(p, LoopPhase::Disarmed),
        x => panic!("{x:?}"),
    }
    assert!(r.status().state.amplifier_enabled);
    // Armed: parameters stay as they are.
    assert_eq!(
        r.ask(Request::Set {
            id: fe,
            value: 0.002
        }),
        Reply::Refused(Refusal::Armed)
    );
    assert_eq!(r.lp.config().following_error_code, 5242);
    match r.ask(Request::Disarm) {
        Reply::Phase(p) => assert!(matches!(p, LoopPhase::Disarming | LoopPhase::Disarmed)),
        x => panic!("{x:?}"),
    }
    for _ in 0..2000 {
        r.step();
    }
    assert_eq!(r.status().state.phase, LoopPhase::Disarmed);
}

/// A fault-triggered capture holds the pre-trigger window and the rest,
/// sample by sample as the loop saw them; the fault log has the latch and
/// the clear, with their ticks; a clear is refused while the cause is there.
#[test]
fn fault_capture_fault_log_and_clear() {
    let mut r = Rig::new();
    r.gauge = at(1234);
    assert!(matches!(r.ask(Request::Arm), Reply::Phase(_)));
    match r.ask(Request::CaptureStart {
        samples: 50,
        pre: 10,
        trigger: Trigger::Fault,
    }) {
        Reply::Capture(c) => assert_eq!(c.state, CaptureState::Armed),
        x => panic!("{x:?}"),
    }
    for _ in 0..40 {
        r.step();
    }
    // The gauge goes over range: GaugeRange, amplifier off.
    r.gauge = Gauge(Ok(GaugeSample {
        code: 9999,
        overrange: true,
    }));
    r.step();
    let fault_tick = r.lp.ticks();
    assert_eq!(r.lp.fault(), Some(Fault::GaugeRange));
    for _ in 0..60 {
        r.step();
    }
    let info = match r.ask(Request::CaptureInfo) {
        Reply::Capture(c) => c,
        x => panic!("{x:?}"),
    };
    assert_eq!(info.state, CaptureState::Done);
    assert_eq!((info.recorded, info.before_trigger), (50, 10));
    assert_eq!(info.trigger_tick, fault_tick);
    let mut samples = Vec::new();
    while samples.len() < 50 {
        match r.ask(Request::CaptureRead {
            from: samples.len() as u16,
        }) {
            Reply::Samples { from, samples: s } => {
                assert_eq!(usize::from(from), samples.len());
                samples.extend(s);
            }
            x => panic!("{x:?}"),
        }
    }
    // Before the fault the loop read 1234; from the fault on it holds its
    // last good sample (the over-range one is not a position).
    assert!(samples[..10].iter().all(|s| s.position == 1234));
    assert!(samples.iter().all(|s| s.error == s.command - s.position));
    assert!(
        samples[10..].iter().all(|s| s.output == 0),
        "amplifier off after the fault"
    );
    assert_eq!(
        r.ask(Request::CaptureRead { from: 50 }),
        Reply::Refused(Refusal::Range)
    );

    // Clear: refused while the gauge is over range, then the loop is
    // disarmed (the fault disarmed it) and the gauge good: cleared.
    assert_eq!(
        r.ask(Request::Clear),
        Reply::Refused(Refusal::ClearCause(Fault::GaugeRange))
    );
    r.gauge = at(1000);
    assert_eq!(r.ask(Request::Clear), Reply::Cleared(Fault::GaugeRange));
    assert_eq!(r.status().state.fault, None);
    assert_eq!(r.ask(Request::Clear), Reply::Refused(Refusal::NoFault));

    match r.ask(Request::Faults { from: 0 }) {
        Reply::Faults(p) => {
            assert_eq!(p.total, 2);
            assert_eq!(p.records.len(), 2);
            assert_eq!(p.records[0].fault, Fault::GaugeRange);
            assert_eq!(p.records[0].tick, fault_tick);
            assert!(!p.records[0].cleared);
            assert!(p.records[1].cleared);
            assert!(p.records[1].tick > fault_tick);
        }
        x => panic!("{x:?}"),
    }
    // An arm with a fault that keeps the amplifier off is refused by name.
    r.gauge = Gauge(Err(BusError));
    r.step();
    assert_eq!(
        r.ask(Request::Arm),
        Reply::Refused(Refusal::ArmFault(Fault::Bus(Device::GaugeAdc)))
    );
}

/// The following-error trigger fires on the first tick whose
/// |command − position| reaches the level; an immediate capture records
/// consecutive ticks.
#[test]
fn following_error_and_immediate_triggers() {
    let mut r = Rig::new();
    r.gauge = at(0);
    assert!(matches!(r.ask(Request::Arm), Reply::Phase(_)));
    for _ in 0..100 {
        r.step();
    }
    let level = 2_000;
    assert!(matches!(
        r.ask(Request::CaptureStart {
            samples: 40,
            pre: 20,
            trigger: Trigger::FollowingError { level },
        }),
        Reply::Capture(_)
    ));
    for _ in 0..50 {
        r.step();
    }
    // The command ramps toward a new target at the slew limit; the gauge
    // stays: the error grows through the level.
    r.lp.set_target_code(50_000);
    for _ in 0..400 {
        r.step();
    }
    let info = match r.ask(Request::CaptureInfo) {
        Reply::Capture(c) => c,
        x => panic!("{x:?}"),
    };
    assert_eq!(info.state, CaptureState::Done);
    assert_eq!(info.before_trigger, 20);
    let s = r.read_capture(info.recorded);
    assert!(s[20].error.unsigned_abs() >= level);
    assert!(s[19].error.unsigned_abs() < level);
    // Consecutive ticks: the command moves at most one slew step a tick
    // (0.25 in/s = 655 codes per tick).
    assert!(s
        .windows(2)
        .all(|w| (w[1].command - w[0].command).abs() <= 656));

    assert!(matches!(
        r.ask(Request::CaptureStart {
            samples: 5,
            pre: 0,
            trigger: Trigger::Immediate,
        }),
        Reply::Capture(_)
    ));
    for _ in 0..10 {
        r.step();
    }
    match r.ask(Request::CaptureInfo) {
        Reply::Capture(c) => assert_eq!((c.state, c.recorded), (CaptureState::Done, 5)),
        x => panic!("{x:?}"),
    }
    for bad in [(0, 0), (CAP as u16 + 1, 0), (10, 10)] {
        assert_eq!(
            r.ask(Request::CaptureStart {
                samples: bad.0,
                pre: bad.1,
                trigger: Trigger::Immediate
            }),
            Reply::Refused(Refusal::CaptureSize {
                capacity: CAP as u16
            })
        );
    }
}

/// Garbage, truncated, corrupt, unknown-command, other-version and
/// oversize frames: each refused by name and counted, and the link still
/// answers afterwards.
#[test]
fn malformed_frames_are_refused_counted_and_harmless() {
    let mut r = Rig::new();
    let mut out = [0u8; MAX_FRAME];
    let good = proto::encode(77, &Request::Faults { from: 0 }, &mut out)
        .unwrap()
        .to_vec();
    let refused = |r: &mut Rig, bytes: &[u8]| -> FrameError {
        r.send_raw(bytes);
        match r.reply() {
            (_, Reply::Refused(Refusal::Frame(e))) => e,
            x => panic!("{x:?}"),
        }
    };
    // Garbage (no valid COBS chain / CRC).
    let e = refused(&mut r, &[0x01, 0x02, 0x03, 0xFF, 0x00]);
    assert!(matches!(
        e,
        FrameError::BadCobs | FrameError::BadCrc { .. } | FrameError::Short
    ));
    // Truncated.
    let mut t = good[..good.len() - 3].to_vec();
    t.push(0);
    assert!(matches!(
        refused(&mut r, &t),
        FrameError::BadCrc { .. } | FrameError::BadCobs | FrameError::Short
    ));
    // A flipped bit: the CRC.
    let mut c = good.clone();
    c[3] ^= 0x04;
    assert!(matches!(refused(&mut r, &c), FrameError::BadCrc { .. }));
    // Well-formed frames that are not requests of this firmware.
    let raw = |body: &[u8]| {
        let mut v = body.to_vec();
        v.extend(zslide::table::crc32(body).to_le_bytes());
        let mut o = vec![0u8; v.len() + 2];
        let n = cobs::encode(&v, &mut o);
        o.truncate(n);
        o.push(0);
        o
    };
    assert_eq!(
        refused(&mut r, &raw(&[1, 9, 99])),
        FrameError::UnknownCommand(99)
    );
    assert_eq!(refused(&mut r, &raw(&[7, 9, 0])), FrameError::BadVersion(7));
    assert_eq!(refused(&mut r, &raw(&[1, 9, 0, 5])), FrameError::Malformed);
    // Oversize: dropped up to its delimiter.
    let big = vec![0x55u8; 300];
    r.send_raw(&big);
    assert_eq!(refused(&mut r, &[0]), FrameError::Oversize);
    // Empty frames are only counted.
    r.send_raw(&[0, 0, 0]);
    let s = r.status();
    let f = s.frames;
    assert_eq!(f.empty, 3);
    assert_eq!(f.oversize, 1);
    assert_eq!(f.bad_crc + f.bad_cobs + f.malformed, 4);
    assert_eq!(f.unknown_command, 1);
    assert_eq!(f.bad_version, 1);
    assert_eq!(f.ok, 1);
    assert_eq!(r.lp.fault(), None);
}

mod prop {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Any byte stream: the station never panics, answers every
        /// delimited frame, and a valid request after it is answered.
        /// Zeros (the delimiter) are drawn often, so a stream holds many
        /// frames; each non-empty frame gets exactly one reply frame (a
        /// refusal or an answer, decodable), an empty one none (it is
        /// only counted).
        #[test]
        fn any_bytes_then_a_request_is_answered(
            bytes in proptest::collection::vec(prop_oneof![1 => Just(0u8), 7 => any::<u8>()], 0..400),
        ) {
            let mut r = Rig::new();
            r.send_raw(&bytes);
            r.send_raw(&[0]);
            let mut stream = bytes.clone();
            stream.push(0);
            let frames = stream.split(|&b| b == 0).filter(|f| !f.is_empty()).count();
            for _ in 0..(bytes.len() * 8 + 200) {
                r.step();
            }
            let replies: Vec<Vec<u8>> = r
                .pipe
                .from_fw
                .split(|&b| b == 0)
                .map(<[u8]>::to_vec)
                .collect();
            // The stream ends on a delimiter: the last piece is empty.
            prop_assert_eq!(replies.last().map(Vec::len), Some(0));
            prop_assert_eq!(replies.len() - 1, frames, "{} frames sent", frames);
            for mut f in replies.into_iter().take(frames) {
                prop_assert!(proto::decode::<Reply>(&mut f, u32::MAX).is_ok());
            }
            r.pipe.from_fw.clear();
            let s = r.status();
            prop_assert_eq!(s.state.phase, LoopPhase::Disarmed);
            prop_assert_eq!(u64::from(s.frames.empty) + frames as u64, stream.split(|&b| b == 0).count() as u64 - 1);
        }
    }
}

/// Identification's sine and a capture anchored to a stated loop tick
/// (`Request::ExciteAt`, `Trigger::AtTick`): the sine's phase 0 and the
/// capture's trigger sample are that tick (the test gauge does not move,
/// so the DAC code is the loop's constant output plus the sine alone); a
/// start tick the loop has already reached, or one beyond the sine's
/// longest lead, is refused in words, and a capture armed for a passed
/// tick reads `Late`, never waits for ever.
#[test]
fn a_sine_and_a_capture_anchored_to_a_tick_start_on_it_and_late_ones_are_refused() {
    let mut r = Rig::new();
    r.gauge = at(0);
    assert!(matches!(r.ask(Request::Arm), Reply::Phase(_)));
    let mut engaged = false;
    for _ in 0..200 {
        if r.status().state.phase == LoopPhase::Engaged {
            engaged = true;
            break;
        }
        for _ in 0..100 {
            r.step();
        }
    }
    assert!(engaged, "the loop never engaged");
    let now = r.status().state.ticks;
    let start = now + 60;
    // 256 ticks a period: the peak 64 ticks after phase 0.
    let sine = |at| Request::ExciteAt {
        step: 1 << 24,
        amplitude: 10_000,
        ticks: 4_000,
        at,
    };
    assert_eq!(
        r.ask(sine(start)),
        Reply::Exciting {
            tick: start,
            ticks: 4_000
        }
    );
    let pre = 8u16;
    assert!(matches!(
        r.ask(Request::CaptureStart {
            samples: 100,
            pre,
            trigger: Trigger::AtTick { tick: start },
        }),
        Reply::Capture(c) if c.state == CaptureState::Armed
    ));
    for _ in 0..400 {
        r.step();
    }
    let info = match r.ask(Request::CaptureInfo) {
        Reply::Capture(c) => c,
        x => panic!("{x:?}"),
    };
    assert_eq!(
        (info.state, info.trigger_tick, info.before_trigger),
        (CaptureState::Done, start, pre)
    );
    let s = r.read_capture(info.recorded);
    let p = usize::from(pre);
    let u0 = s[0].output;
    assert!(
        s[..=p].iter().all(|x| x.output == u0),
        "no sine before its start tick (phase 0 is 0): {:?}",
        &s[..=p]
    );
    assert!(s[p + 1].output > u0, "the sine rises from its start tick");
    assert!(
        (s[p + 64].output - u0 - 10_000).abs() <= 2,
        "the peak a quarter period after the start tick: {}",
        s[p + 64].output - u0
    );

    // Late: the loop's tick has reached (passed) the start tick.
    let late = r.status().state.ticks;
    match r.ask(sine(late)) {
        Reply::Refused(why @ Refusal::Excite(_)) => {
            assert!(why.to_string().contains("late arm"), "{why}")
        }
        x => panic!("a passed start tick: {x:?}"),
    }
    // Too far ahead: more than the longest sine (10 s at 20 kHz).
    assert!(matches!(
        r.ask(sine(late + 200_000 + 1_000)),
        Reply::Refused(Refusal::Excite(_))
    ));
    assert!(!r.status().state.exciting, "a refused start leaves no sine");
    assert!(matches!(
        r.ask(Request::CaptureStart {
            samples: 16,
            pre: 0,
            trigger: Trigger::AtTick { tick: late },
        }),
        Reply::Capture(_)
    ));
    match r.ask(Request::CaptureInfo) {
        Reply::Capture(c) => assert_eq!(c.state, CaptureState::Late),
        x => panic!("{x:?}"),
    }
}
