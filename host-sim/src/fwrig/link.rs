//! The firmware's host link on the simulated machine, wired as the boards
//! wire it (`src/main.rs`, `boards/qemu`): the loop tick's tap
//! (`zslide::link::tap::TickTap::after_tick`, at the end of every loop
//! tick), the background's station (`zslide::link::station::Station::poll`,
//! in thread mode: one pass after each loop tick, between ticks and never
//! inside one) and the transport with the NUCLEO's RTT buffer sizes: the
//! host (probe-rs) moves bytes in and out at its polling period, a down
//! buffer of 128 bytes, an up buffer of 1024. A host that sends faster
//! than the firmware reads waits for room, as it does on the board.
//!
//! Only the background's pass after a loop tick is modelled (the board's
//! background also runs after every X and index interrupt): the simulated
//! station gets fewer passes than the board's, never more.
//!
//! The link posts operator requests straight into the firmware's `Shared`,
//! which a replay recording does not see: a world with a recorder refuses
//! the link ([`attach`]).
//!
//! The world runs the tap as one of its tick hooks ([`TickHook`]); the
//! background and the host's polling are event sources that hold the same
//! link.

use super::world::{Cpu, FirmwareWorld, TickHook};
use crate::sched::{prio, EventSource, Nanos, Scheduler};
use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;
use zslide::firmware::{LoopState, Shared};
use zslide::link::proto::{FrameCounters, SpindleSource, XSource};
use zslide::link::station::{LinkIo, Station, StationConfig};
use zslide::link::tap::{Scope, TapShared, TickTap};
use zslide::params::ParamSource;
use zslide::servo::ServoDesign;

/// Capture ring of the simulated link, samples: the boards'.
pub use zslide::link::CAPTURE;
/// RTT down channel (host → firmware), bytes (`src/board/link.rs`).
pub const DOWN_BYTES: usize = 128;
/// RTT up channel (firmware → host), bytes.
pub const UP_BYTES: usize = 1024;
/// How often the host moves bytes through the RTT buffers, ns (probe-rs
/// polls its RTT channels about every millisecond).
pub const HOST_POLL_NS: Nanos = 1_000_000;

/// The link's three parts and the transport between the firmware and the
/// host.
pub struct HostLink {
    tap: TickTap,
    /// The tap's queues and capture ring: a `static` on the boards, leaked
    /// here (one per simulated firmware, a few kB).
    shared: &'static TapShared<'static, CAPTURE>,
    station: Station<CAPTURE>,
    /// RTT buffers in the MCU's RAM.
    down: VecDeque<u8>,
    up: VecDeque<u8>,
    /// Bytes the host has yet to write, and the bytes it has read.
    backlog: VecDeque<u8>,
    received: Vec<u8>,
    /// The parameter store on the machine's flash model (`host-sim
    /// serve`); `None`: saves are refused as on a board without a driver.
    store: Option<ParamsStore>,
}

/// The NUCLEO's parameter region as the store sees it: two 128 KiB
/// sectors of bank 2 (memory.x `ZSPB`), programmed in 32-byte flash words.
pub type ParamsFlash = zslide::store::ram::Bank2Region;
/// The parameter region's size, bytes.
pub const PARAMS_REGION_BYTES: usize = zslide::store::ram::BANK2_REGION_BYTES;
/// The parameter store on [`ParamsFlash`].
pub type ParamsStore = zslide::store::Store<ParamsFlash>;

/// The RTT channel pair as the station sees it: never blocking.
struct Rtt<'a> {
    down: &'a mut VecDeque<u8>,
    up: &'a mut VecDeque<u8>,
}

impl LinkIo for Rtt<'_> {
    fn read(&mut self, buf: &mut [u8]) -> usize {
        let n = buf.len().min(self.down.len());
        for (b, d) in buf.iter_mut().zip(self.down.drain(..n)) {
            *b = d;
        }
        n
    }
    fn write(&mut self, bytes: &[u8]) -> usize {
        // NoBlockTrim: as much as fits.
        let n = bytes.len().min(UP_BYTES - self.up.len());
        self.up.extend(&bytes[..n]);
        n
    }
}

impl HostLink {
    pub fn new(cfg: StationConfig) -> Self {
        let scope: &'static Scope<CAPTURE> = Box::leak(Box::new(Scope::new()));
        Self {
            tap: TickTap::new(),
            shared: Box::leak(Box::new(TapShared::new(scope))),
            station: Station::new(cfg),
            down: VecDeque::with_capacity(DOWN_BYTES),
            up: VecDeque::with_capacity(UP_BYTES),
            backlog: VecDeque::new(),
            received: Vec::new(),
            store: None,
        }
    }

    /// Gives the station a parameter store (the machine's flash).
    pub fn set_store(&mut self, store: ParamsStore) {
        self.store = Some(store);
    }

    /// The parameter store's flash, while the station has it.
    pub fn store_flash(&mut self) -> Option<&mut ParamsFlash> {
        self.store.as_mut().map(|s| s.flash())
    }

    /// The parameter store back (its flash outlives this firmware).
    pub fn take_store(&mut self) -> Option<ParamsStore> {
        self.store.take()
    }

    /// One background pass.
    pub fn poll(&mut self, shared: &Shared) {
        let mut io = Rtt {
            down: &mut self.down,
            up: &mut self.up,
        };
        match self.store.as_mut() {
            Some(st) => self
                .station
                .poll_with_store(self.shared, shared, &mut io, st),
            None => self.station.poll(self.shared, shared, &mut io),
        }
    }

    /// The host's side of one RTT poll: what fits of its backlog into the
    /// down buffer, everything of the up buffer out.
    pub fn host_transfer(&mut self) {
        let room = DOWN_BYTES - self.down.len();
        let n = room.min(self.backlog.len());
        self.down.extend(self.backlog.drain(..n));
        self.received.extend(self.up.drain(..));
    }

    /// Queues bytes for the host to write.
    pub fn send(&mut self, bytes: &[u8]) {
        self.backlog.extend(bytes);
    }

    /// Bytes the host has not yet handed to the firmware (its backlog and
    /// the down buffer).
    pub fn unread(&self) -> usize {
        self.backlog.len() + self.down.len()
    }

    /// Everything the host has read from the firmware so far.
    pub fn received(&self) -> &[u8] {
        &self.received
    }

    /// What the host has read from the firmware since the last call
    /// (`serve`'s socket takes it).
    pub fn take_received(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.received)
    }

    /// The station's frame counters.
    pub fn frames(&self) -> FrameCounters {
        self.station.frames()
    }
}

impl TickHook for HostLink {
    /// At the end of the loop-tick handler.
    fn after_tick(&mut self, lp: &mut LoopState) {
        self.tap.after_tick(self.shared, lp);
    }
}

/// The background (thread mode): one station pass after each loop tick.
struct Background {
    link: Rc<RefCell<HostLink>>,
    period_ns: Nanos,
    next: Nanos,
}

impl EventSource<FirmwareWorld> for Background {
    fn next_time(&self) -> Option<Nanos> {
        Some(self.next)
    }
    fn priority(&self) -> u8 {
        // Below every handler: at a loop tick's instant it runs after it.
        prio::BACKGROUND
    }
    fn name(&self) -> &str {
        "background"
    }
    fn fire(&mut self, _now: Nanos, w: &mut FirmwareWorld) {
        self.next += self.period_ns;
        if w.cpu == Cpu::Halted {
            return;
        }
        self.link.borrow_mut().poll(w.fw.shared());
    }
}

/// The debug probe's RTT polling.
struct HostPoll {
    link: Rc<RefCell<HostLink>>,
    next: Nanos,
}

impl EventSource<FirmwareWorld> for HostPoll {
    fn next_time(&self) -> Option<Nanos> {
        Some(self.next)
    }
    fn priority(&self) -> u8 {
        // Outside the MCU: the probe reads and writes RAM whatever runs.
        prio::PLANT_INPUT
    }
    fn name(&self) -> &str {
        "rtt_host"
    }
    fn fire(&mut self, _now: Nanos, _w: &mut FirmwareWorld) {
        self.next += HOST_POLL_NS;
        self.link.borrow_mut().host_transfer();
    }
}

/// Gives the world's firmware its host link (as booted: no table identity
/// beyond the loaded table's, the scenario's design, built-in parameters)
/// and registers the background and the host's polling with the
/// scheduler. `loop_hz`: the loop-tick rate (one background pass per tick).
/// Returns the host's handle on the link.
pub fn attach(
    w: &mut FirmwareWorld,
    s: &mut Scheduler<FirmwareWorld>,
    loop_hz: u32,
    design: ServoDesign,
    params: ParamSource,
) -> anyhow::Result<Rc<RefCell<HostLink>>> {
    if w.recorder.is_some() {
        anyhow::bail!(
            "the host link posts requests a replay recording does not see: record without it"
        );
    }
    let table = w.fw.table_identity();
    let (x_source, spindle_source) = match &w.machine {
        None => (XSource::None, SpindleSource::None),
        Some(_) => (
            if w.x_latch().is_some() {
                XSource::LegacyHalfMil
            } else {
                XSource::Count
            },
            if w.spindle_is_encoder() {
                SpindleSource::Encoder
            } else {
                SpindleSource::Tachometer
            },
        ),
    };
    let link = Rc::new(RefCell::new(HostLink::new(StationConfig {
        loop_hz,
        x_source,
        spindle_source,
        table,
        design,
        params,
    })));
    let period_ns = 1_000_000_000 / Nanos::from(loop_hz.max(1));
    w.hooks.push(Box::new(link.clone()));
    s.add(Background {
        link: link.clone(),
        period_ns,
        next: period_ns,
    });
    s.add(HostPoll {
        link: link.clone(),
        next: HOST_POLL_NS,
    });
    Ok(link)
}
