//! The background's side of the host link: takes request frames from the
//! transport, answers them, and keeps the fault log. Runs at the lowest
//! priority (the boards' thread-mode loop), never in an interrupt.
//!
//! [`Station::poll`] does a bounded amount of work and returns; the board
//! calls it on every pass of its background loop. A request that needs the
//! loop tick (status, arm, disarm, clear, set) posts its request bits and
//! is answered on a later pass, once the tick's snapshot has arrived: a
//! reply always reflects the loop after the request took effect.

use super::proto::LoopSnapshot as Snapshot;
use super::proto::{
    self, CaptureInfo, CaptureState, FaultPage, FaultRecord, FrameCounters, FrameError, LoopPhase,
    Refusal, Reply, Request, SpindleSource, Status, Trigger, XSource, FAULTS_PER_FRAME, FAULT_LOG,
    MAX_FRAME, MAX_REQUEST, REQUEST_KINDS, SAMPLES_PER_FRAME,
};
use super::tap::{TapShared, REQ_CAPTURE, REQ_CONFIG, REQ_EXCITE, REQ_SNAPSHOT};
use crate::firmware::excite::{ExciteError, EXCITE_MAX_S};
use crate::handoff::{Request as LoopRequest, Shared};
use crate::params::{self, ParamSource};
use crate::safety::{Fault, Reaction};
use crate::servo::ServoDesign;
use crate::store::{NoStore, ParamStore, StoreError, MAX_BLOCK};
use crate::table::{TableError, TableIdentity};
use heapless::Deque;

/// The transport: bytes in and out, never blocking (RTT channels on the
/// NUCLEO, the CMSDK UART in QEMU).
pub trait LinkIo {
    /// Up to `buf.len()` received bytes; 0 when none are waiting.
    fn read(&mut self, buf: &mut [u8]) -> usize;
    /// Queues as many of `bytes` as fit now; returns how many.
    fn write(&mut self, bytes: &[u8]) -> usize;
}

/// Passes a request may wait for the loop tick's snapshot before it is
/// answered with [`Refusal::LoopSilent`] (each pass follows a wake-up by
/// an interrupt, normally the loop tick itself).
const SNAPSHOT_PATIENCE: u32 = 10_000;

/// What the board tells the station once, at boot.
#[derive(Clone, Copy, Debug)]
pub struct StationConfig {
    pub loop_hz: u32,
    pub x_source: XSource,
    pub spindle_source: SpindleSource,
    /// The table region's verdict (identity, or why it was refused).
    pub table: Result<TableIdentity, TableError>,
    /// The design in force and where it came from.
    pub design: ServoDesign,
    pub params: ParamSource,
}

/// A request waiting for the tick's snapshot. (One at a time, in the
/// station: the large variant costs its size once, there is no heap to box
/// it in.)
#[derive(Clone, Copy)]
#[allow(clippy::large_enum_variant)]
enum Waiting {
    Status,
    Armed,
    Disarmed,
    Cleared(Option<Fault>),
    /// Parameter `id` set to `value`, giving `design` once the tick has
    /// applied it (its count of applied configurations was `applied`).
    Set {
        id: u16,
        value: f64,
        applied: u32,
        design: ServoDesign,
    },
    /// A snapshot to decide whether a set may go ahead (disarmed?).
    SetCheck {
        id: u16,
        value: f64,
    },
    /// The identification sine handed to the tick: did it start? (`at`:
    /// its anchored start tick.)
    Excite {
        ticks: u32,
        at: Option<u32>,
    },
    /// A capture armed for a tick: has that tick passed unrecorded?
    CaptureInfo,
    /// A snapshot to decide whether a save may go ahead (disarmed?).
    Save,
}

pub struct Station<const N: usize> {
    cfg: StationConfig,
    rx: [u8; MAX_REQUEST],
    rx_len: usize,
    /// Dropping an oversize frame until its delimiter.
    rx_skip: bool,
    tx: [u8; MAX_FRAME],
    tx_len: usize,
    tx_sent: usize,
    waiting: Option<(u16, Waiting, u32)>,
    last: Option<Snapshot>,
    /// The fault log: the last [`FAULT_LOG`] records (a ring: the oldest
    /// goes when a new one comes).
    log: Deque<FaultRecord, FAULT_LOG>,
    logged: u32,
    frames: FrameCounters,
}

impl<const N: usize> Station<N> {
    pub fn new(cfg: StationConfig) -> Self {
        Self {
            cfg,
            rx: [0; MAX_REQUEST],
            rx_len: 0,
            rx_skip: false,
            tx: [0; MAX_FRAME],
            tx_len: 0,
            tx_sent: 0,
            waiting: None,
            last: None,
            log: Deque::new(),
            logged: 0,
            frames: FrameCounters::default(),
        }
    }

    /// The servo design in force (the parameter block's, then the host's).
    pub fn design(&self) -> &ServoDesign {
        &self.cfg.design
    }

    /// Frames taken and refused so far.
    pub fn frames(&self) -> FrameCounters {
        self.frames
    }

    /// The fault log, oldest first.
    pub fn fault_log(&self) -> impl Iterator<Item = &FaultRecord> {
        self.log.iter()
    }

    /// Fault records logged since boot.
    pub fn faults_logged(&self) -> u32 {
        self.logged
    }

    /// One background pass: log fault changes, answer a request whose
    /// snapshot came, send what is pending, take at most one new request.
    /// Never inlined: `cargo xtask no-panic` holds it, from its symbol, to
    /// the interrupt handlers' rule (no panic path), although it runs in
    /// thread mode: bytes from the host must never stop the firmware.
    #[inline(never)]
    pub fn poll(&mut self, tap: &TapShared<'_, N>, shared: &Shared, io: &mut impl LinkIo) {
        self.poll_with_store(tap, shared, io, &mut NoStore);
    }

    /// [`Station::poll`] on a board whose parameter region has a flash
    /// driver: a `SaveParams` request writes `store` (in this call: the
    /// erase and program times are the background's, never the tick's).
    /// Never inlined, for `cargo xtask no-panic` as [`Station::poll`].
    #[inline(never)]
    pub fn poll_with_store(
        &mut self,
        tap: &TapShared<'_, N>,
        shared: &Shared,
        io: &mut impl LinkIo,
        store: &mut impl ParamStore,
    ) {
        self.drain_faults(tap);
        if let Some((seq, w, waited)) = self.waiting {
            match tap.snapshots.dequeue() {
                Some(s) => {
                    self.last = Some(s);
                    self.waiting = None;
                    self.answer(seq, w, &s, tap, shared, store);
                }
                None if waited >= SNAPSHOT_PATIENCE => {
                    self.waiting = None;
                    self.reply(seq, &Reply::Refused(Refusal::LoopSilent));
                }
                None => self.waiting = Some((seq, w, waited + 1)),
            }
        }
        if self.tx_sent < self.tx_len {
            let sent = io.write(self.tx.get(self.tx_sent..self.tx_len).unwrap_or(&[]));
            self.tx_sent += sent;
            if self.tx_sent < self.tx_len {
                return;
            }
        }
        if self.waiting.is_some() {
            return;
        }
        // One byte at a time up to a delimiter: a request is small, and
        // bytes after it stay in the transport until this one is answered.
        let mut byte = [0u8; 1];
        while io.read(&mut byte) == 1 {
            if byte[0] != 0 {
                if self.rx_skip {
                    continue;
                }
                match self.rx.get_mut(self.rx_len) {
                    Some(slot) if self.rx_len < MAX_REQUEST - 1 => {
                        *slot = byte[0];
                        self.rx_len += 1;
                    }
                    _ => {
                        self.rx_skip = true;
                        self.rx_len = 0;
                    }
                }
                continue;
            }
            if self.rx_skip {
                self.rx_skip = false;
                self.frames.oversize += 1;
                self.refuse_frame(0, FrameError::Oversize);
                return;
            }
            let len = core::mem::take(&mut self.rx_len);
            if len == 0 {
                self.frames.empty += 1;
                continue;
            }
            let mut frame = self.rx;
            let Some(frame) = frame.get_mut(..len) else {
                return;
            };
            match proto::decode::<Request>(frame, REQUEST_KINDS) {
                Ok((seq, req)) => {
                    self.frames.ok += 1;
                    self.handle(seq, req, tap, shared);
                }
                Err((seq, e)) => {
                    let c = &mut self.frames;
                    match e {
                        FrameError::Oversize => c.oversize += 1,
                        FrameError::BadCobs => c.bad_cobs += 1,
                        FrameError::Short | FrameError::Malformed => c.malformed += 1,
                        FrameError::BadCrc { .. } => c.bad_crc += 1,
                        FrameError::BadVersion(_) => c.bad_version += 1,
                        FrameError::UnknownCommand(_) => c.unknown_command += 1,
                    }
                    self.refuse_frame(seq, e);
                }
            }
            return;
        }
    }

    fn drain_faults(&mut self, tap: &TapShared<'_, N>) {
        while let Some(e) = tap.faults.dequeue() {
            // A clear is logged with the fault it cleared.
            let record = match (e.fault, self.log.back()) {
                (Some(f), _) => Some(FaultRecord {
                    tick: e.tick,
                    fault: f,
                    cleared: false,
                }),
                (None, Some(last)) if !last.cleared => Some(FaultRecord {
                    tick: e.tick,
                    fault: last.fault,
                    cleared: true,
                }),
                _ => None,
            };
            if let Some(r) = record {
                if self.log.is_full() {
                    self.log.pop_front();
                }
                let _ = self.log.push_back(r);
                self.logged = self.logged.wrapping_add(1);
            }
        }
    }

    fn refuse_frame(&mut self, seq: u16, e: FrameError) {
        self.reply(seq, &Reply::Refused(Refusal::Frame(e)));
    }

    fn reply(&mut self, seq: u16, r: &Reply) {
        // Every reply fits MAX_FRAME (tested in `proto`); an encoding that
        // failed anyway is sent as nothing, and the host times out.
        self.tx_len = proto::encode(seq, r, &mut self.tx).map_or(0, <[u8]>::len);
        self.tx_sent = 0;
    }

    fn wait(&mut self, seq: u16, w: Waiting, tap: &TapShared<'_, N>) {
        // A snapshot left from before belongs to no request now.
        while tap.snapshots.dequeue().is_some() {}
        tap.request(REQ_SNAPSHOT);
        self.waiting = Some((seq, w, 0));
    }

    fn handle(&mut self, seq: u16, req: Request, tap: &TapShared<'_, N>, shared: &Shared) {
        match req {
            Request::Status => self.wait(seq, Waiting::Status, tap),
            Request::Arm => {
                shared.request(LoopRequest::Arm);
                self.wait(seq, Waiting::Armed, tap);
            }
            Request::Disarm => {
                shared.request(LoopRequest::Disarm);
                self.wait(seq, Waiting::Disarmed, tap);
            }
            Request::Clear => {
                let before = self.last.and_then(|s| s.fault);
                shared.request(LoopRequest::ClearFault);
                self.wait(seq, Waiting::Cleared(before), tap);
            }
            Request::Set { id, value } => match params::set(&self.cfg.design, id, value) {
                Err(e) => self.reply(seq, &Reply::Refused(Refusal::Param(e))),
                Ok(_) => self.wait(seq, Waiting::SetCheck { id, value }, tap),
            },
            Request::Get { id } => match params::by_id(id) {
                Some(p) => {
                    let value = p.get(&self.cfg.design);
                    self.reply(seq, &Reply::Param { id, value });
                }
                None => self.reply(
                    seq,
                    &Reply::Refused(Refusal::Param(params::ParamError::Unknown(id))),
                ),
            },
            Request::CaptureStart {
                samples,
                pre,
                trigger,
            } => {
                let capacity = N as u16;
                if samples == 0 || usize::from(samples) > N || pre >= samples {
                    self.reply(seq, &Reply::Refused(Refusal::CaptureSize { capacity }));
                } else {
                    tap.scope.arm(samples, pre, trigger);
                    tap.request(REQ_CAPTURE);
                    self.reply(seq, &Reply::Capture(self.capture_info(tap)));
                }
            }
            Request::Excite {
                step,
                amplitude,
                ticks,
            } => self.excite(seq, [step, amplitude, ticks], None, tap),
            Request::ExciteAt {
                step,
                amplitude,
                ticks,
                at,
            } => self.excite(seq, [step, amplitude, ticks], Some(at), tap),
            Request::SaveParams => self.wait(seq, Waiting::Save, tap),
            Request::CaptureInfo => {
                let info = self.capture_info(tap);
                if info.state == CaptureState::Armed
                    && matches!(info.trigger, Trigger::AtTick { .. })
                {
                    // Only the loop's tick count tells a late arming.
                    self.wait(seq, Waiting::CaptureInfo, tap);
                } else {
                    self.reply(seq, &Reply::Capture(info));
                }
            }
            Request::CaptureRead { from } => {
                if tap.scope.state() != CaptureState::Done {
                    self.reply(seq, &Reply::Refused(Refusal::CaptureNotDone));
                    return;
                }
                let (recorded, _, _) = tap.scope.result();
                if from >= recorded {
                    self.reply(seq, &Reply::Refused(Refusal::Range));
                    return;
                }
                let mut samples = heapless::Vec::new();
                let end = recorded.min(from.saturating_add(SAMPLES_PER_FRAME as u16));
                for i in from..end {
                    let _ = samples.push(tap.scope.sample(i));
                }
                self.reply(seq, &Reply::Samples { from, samples });
            }
            Request::Faults { from } => {
                let kept = self.log.len() as u16;
                if from > kept {
                    self.reply(seq, &Reply::Refused(Refusal::Range));
                    return;
                }
                let mut records = heapless::Vec::new();
                for r in self
                    .log
                    .iter()
                    .skip(usize::from(from))
                    .take(FAULTS_PER_FRAME)
                {
                    let _ = records.push(*r);
                }
                let page = FaultPage {
                    total: self.logged,
                    kept,
                    from,
                    records,
                };
                self.reply(seq, &Reply::Faults(page));
            }
        }
    }

    /// Hands a checked sine to the tick (`at`: its start tick, refused
    /// there beyond [`EXCITE_MAX_S`] ahead).
    fn excite(
        &mut self,
        seq: u16,
        [step, amplitude, ticks]: [u32; 3],
        at: Option<u32>,
        tap: &TapShared<'_, N>,
    ) {
        if let Err(e) = crate::firmware::excite::check(step, amplitude, ticks, self.cfg.loop_hz) {
            self.reply(seq, &Reply::Refused(Refusal::Excite(e)));
            return;
        }
        let lead = at.map_or(0, |_| self.max_lead());
        for (slot, v) in tap
            .excite
            .iter()
            .zip([step, amplitude, ticks, at.unwrap_or(0), lead])
        {
            slot.store(v, core::sync::atomic::Ordering::Release);
        }
        tap.request(REQ_EXCITE);
        self.wait(seq, Waiting::Excite { ticks, at }, tap);
    }

    /// The furthest ahead an anchored sine may start, loop ticks.
    fn max_lead(&self) -> u32 {
        (EXCITE_MAX_S * f64::from(self.cfg.loop_hz)) as u32
    }

    fn capture_info(&self, tap: &TapShared<'_, N>) -> CaptureInfo {
        let sc = &tap.scope;
        let state = sc.state();
        let (recorded, before, tick) = if state == CaptureState::Done {
            sc.result()
        } else {
            (0, 0, 0)
        };
        CaptureInfo {
            state,
            trigger: sc.trigger(),
            samples: sc.samples(),
            pre: sc.pre(),
            recorded,
            before_trigger: before,
            trigger_tick: tick,
            capacity: N as u16,
        }
    }

    /// The answer to a request, from the snapshot taken after it.
    fn answer(
        &mut self,
        seq: u16,
        w: Waiting,
        s: &Snapshot,
        tap: &TapShared<'_, N>,
        shared: &Shared,
        store: &mut impl ParamStore,
    ) {
        // The snapshot came from the tick that took the request: a fault it
        // latched is in the queue by now.
        self.drain_faults(tap);
        let r = match w {
            Waiting::Status => Reply::Status(self.status(s, tap, shared)),
            Waiting::Armed => match s.fault {
                Some(f) if f.reaction() == Reaction::DisableAmplifier => {
                    Reply::Refused(Refusal::ArmFault(f))
                }
                _ => Reply::Phase(s.phase),
            },
            Waiting::Disarmed => Reply::Phase(s.phase),
            Waiting::Cleared(before) => match (s.fault, s.clear_refused, before) {
                (None, _, Some(f)) => Reply::Cleared(f),
                (Some(f), Some(_), _) => Reply::Refused(Refusal::ClearCause(f)),
                (Some(f), None, _) => Reply::Refused(Refusal::ClearCause(f)),
                (None, _, None) => Reply::Refused(Refusal::NoFault),
            },
            Waiting::SetCheck { id, value } => {
                if s.phase != LoopPhase::Disarmed {
                    Reply::Refused(Refusal::Armed)
                } else {
                    match params::set(&self.cfg.design, id, value) {
                        Err(e) => Reply::Refused(Refusal::Param(e)),
                        Ok((design, cfg)) => match tap.configs.enqueue(cfg) {
                            Ok(()) => {
                                tap.request(REQ_CONFIG);
                                self.wait(
                                    seq,
                                    Waiting::Set {
                                        id,
                                        value,
                                        applied: s.configs_applied,
                                        design,
                                    },
                                    tap,
                                );
                                return;
                            }
                            Err(_) => Reply::Refused(Refusal::LoopSilent),
                        },
                    }
                }
            }
            Waiting::Excite { ticks, at } => {
                // Unanchored, the sine's phase 0 is on the tick after the
                // snapshot's.
                let next = s.ticks.wrapping_add(1);
                if s.exciting || ticks == 0 {
                    Reply::Exciting {
                        tick: at.unwrap_or(next),
                        ticks,
                    }
                } else {
                    Reply::Refused(Refusal::Excite(match at {
                        Some(at) if at.wrapping_sub(next) > self.max_lead() => {
                            ExciteError::StartTick { at, now: s.ticks }
                        }
                        _ => ExciteError::NotAtNull,
                    }))
                }
            }
            Waiting::CaptureInfo => {
                let mut info = self.capture_info(tap);
                if let (CaptureState::Armed, Trigger::AtTick { tick }) = (info.state, info.trigger)
                {
                    // The tap records before it snapshots: armed in time,
                    // the capture would have triggered on `tick`.
                    if (s.ticks.wrapping_sub(tick) as i32) >= 0 {
                        info.state = CaptureState::Late;
                    }
                }
                Reply::Capture(info)
            }
            Waiting::Save => match s.phase {
                LoopPhase::Disarmed => self.save(store),
                _ => Reply::Refused(Refusal::Store(StoreError::Armed)),
            },
            Waiting::Set {
                id,
                value,
                applied,
                design,
            } => {
                if s.configs_applied != applied {
                    self.cfg.design = design;
                    Reply::Param { id, value }
                } else {
                    // Armed between the check and the tick: the tick kept
                    // the configuration it had; so does the station.
                    Reply::Refused(Refusal::Armed)
                }
            }
        };
        self.reply(seq, &r);
    }

    /// Every parameter of the design in force, as one block, into `store`.
    fn save(&mut self, store: &mut impl ParamStore) -> Reply {
        let d = &self.cfg.design;
        let mut block = [0u8; MAX_BLOCK];
        let len = match params::design_block(d, &mut block) {
            Ok(len) => len,
            Err(e) => return Reply::Refused(Refusal::Param(e)),
        };
        let block = block.get(..len).unwrap_or(&[]);
        match (store.save(block, d), params::load_region(block, d)) {
            (Ok(()), Ok((_, _, saved @ ParamSource::Block { entries, crc }))) => {
                // The flash holds this block now: the status says so, as
                // it would after the next boot.
                self.cfg.params = saved;
                Reply::Saved { entries, crc }
            }
            (Err(e), _) => Reply::Refused(Refusal::Store(e)),
            (Ok(()), Err(e)) => Reply::Refused(Refusal::Param(e)),
            // A block `encode_block` wrote is never empty.
            (Ok(()), Ok(_)) => Reply::Refused(Refusal::Store(StoreError::Map)),
        }
    }

    fn status(&self, s: &Snapshot, tap: &TapShared<'_, N>, shared: &Shared) -> Status {
        Status {
            state: *s,
            loop_hz: self.cfg.loop_hz,
            x_source: self.cfg.x_source,
            spindle_source: self.cfg.spindle_source,
            table: self.cfg.table,
            params: self.cfg.params,
            x_accepted: shared.x_accepted(),
            x_ignored: shared.x_ignored(),
            index_events: shared.index_events(),
            coefficient_sets: shared.coefficient_generation(),
            faults_logged: self.logged,
            frames: self.frames,
            capture: self.capture_info(tap),
        }
    }
}
