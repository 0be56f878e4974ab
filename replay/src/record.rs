//! The recorder side (host-sim): taps that log every SPI transaction and
//! LDAC level of the firmware's devices, the handler calls with their
//! inputs, and what each call changed; [`Recorder::finish`] codes the run.
//! Also [`alter`]: one recorded code changed, for the self-check that the
//! replay notices it.

use std::cell::RefCell;
use std::rc::Rc;
use std::string::{String, ToString};
use std::vec::Vec;

use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::spi::{ErrorType, Operation, SpiDevice};
use zslide::firmware::{FirmwareConfig, Request, SpindleReading, TickInput};
use zslide::safety::Fault;

use crate::frames;
use crate::player::fault_text;
use crate::setup::setup_of;
use crate::wire::{Codec, Dev, Event, Io, Req, Setup, Spindle, XResult};

/// An event with owned text (the recorder's copy).
#[derive(Clone, Debug, PartialEq)]
enum Owned {
    Ev(Event<'static>),
    Fault(String),
}

#[derive(Default)]
struct Inner {
    name: String,
    setup: Option<(u32, &'static [u8], FirmwareConfig)>,
    /// The interruption block the firmware took (empty: none).
    interruptions: Vec<u8>,
    events: Vec<Owned>,
    /// The call under way and the bus items it produced so far.
    call: Option<Event<'static>>,
    io: Vec<Event<'static>>,
    enable: bool,
    fault: String,
    error: Option<String>,
}

/// A handle on one run's recording (clones share it).
#[derive(Clone, Default)]
pub struct Recorder(Rc<RefCell<Inner>>);

impl Recorder {
    pub fn new(name: &str) -> Self {
        let r = Self::default();
        r.0.borrow_mut().name = name.to_string();
        r
    }

    /// The firmware configuration and table of the run (once, when the
    /// firmware is built).
    pub fn set_setup(&self, table: &'static [u8], fc: &FirmwareConfig) {
        let mut i = self.0.borrow_mut();
        i.setup = Some((fc.loop_cfg.rate_hz, table, *fc));
    }

    /// The interruption block the firmware took
    /// (`Firmware::set_interruptions`, before the first tick): the player
    /// hands it the same bytes.
    pub fn set_interruptions(&self, block: &[u8]) {
        self.0.borrow_mut().interruptions = block.to_vec();
    }

    /// A loop tick begins with `input`.
    #[cold]
    #[inline(never)]
    pub fn begin_tick(&self, input: &TickInput) {
        self.begin(Event::Tick {
            now: input.now,
            spindle: match input.spindle {
                SpindleReading::None => Spindle::None,
                SpindleReading::Encoder(s) => Spindle::Encoder {
                    count: s.count,
                    edge_ticks: s.edge_ticks,
                },
                SpindleReading::Tach(mv) => Spindle::Tach(mv),
            },
            x_count: input.x_count,
            amplifier_fault: input.amplifier_fault,
        });
    }

    /// A handler call begins (`Event::Boot`, `Tick`, `X` with any result,
    /// `Index`).
    #[cold]
    #[inline(never)]
    pub fn begin(&self, call: Event<'static>) {
        let mut i = self.0.borrow_mut();
        if i.call.is_some() && i.error.is_none() {
            i.error = Some("a handler call began inside another".into());
        }
        i.call = Some(call);
        i.io.clear();
    }

    /// An operator request (takes effect at the next loop tick).
    pub fn request(&self, r: Request) {
        let req = match r {
            Request::Arm => Req::Arm,
            Request::Disarm => Req::Disarm,
            Request::ClearFault => Req::ClearFault,
        };
        self.0
            .borrow_mut()
            .events
            .push(Owned::Ev(Event::Request(req)));
    }

    /// The call ends: its record, its bus items, then what it changed.
    #[cold]
    #[inline(never)]
    pub fn end(&self, x_result: Option<XResult>, enable: bool, fault: Option<Fault>) {
        let mut i = self.0.borrow_mut();
        let Some(mut call) = i.call.take() else {
            if i.error.is_none() {
                i.error = Some("a handler call ended that did not begin".into());
            }
            return;
        };
        if let (Event::X { result, .. }, Some(r)) = (&mut call, x_result) {
            *result = r;
        }
        i.events.push(Owned::Ev(call));
        let io = std::mem::take(&mut i.io);
        i.events.extend(io.into_iter().map(Owned::Ev));
        if enable != i.enable {
            i.enable = enable;
            i.events.push(Owned::Ev(Event::Enable(enable)));
        }
        let text = fault_text(fault);
        if text.as_str() != i.fault {
            i.fault = text.as_str().to_string();
            let f = i.fault.clone();
            i.events.push(Owned::Fault(f));
        }
    }

    fn item(&self, ev: Event<'static>) {
        let mut i = self.0.borrow_mut();
        if i.call.is_none() {
            if i.error.is_none() {
                i.error = Some(format!("bus activity outside a handler call: {ev:?}"));
            }
            return;
        }
        i.io.push(ev);
    }

    fn fail(&self, what: String) {
        let mut i = self.0.borrow_mut();
        if i.error.is_none() {
            i.error = Some(what);
        }
    }

    /// Handler calls recorded so far (loop ticks, X, index).
    pub fn calls(&self) -> usize {
        self.0
            .borrow()
            .events
            .iter()
            .filter(|e| {
                matches!(
                    e,
                    Owned::Ev(Event::Tick { .. } | Event::X { .. } | Event::Index { .. })
                )
            })
            .count()
    }

    /// The run's bytes (setup, then the coded events), or why it cannot be
    /// replayed.
    pub fn finish(&self) -> Result<Vec<u8>, String> {
        let i = self.0.borrow();
        if let Some(e) = &i.error {
            return Err(format!("run {}: {e}", i.name));
        }
        if i.call.is_some() {
            return Err(format!("run {}: a handler call did not end", i.name));
        }
        let Some((_, table, fc)) = &i.setup else {
            return Err(format!("run {}: no firmware configuration", i.name));
        };
        let setup = setup_of(&i.name, table, &i.interruptions, fc).ok_or_else(|| {
            format!(
                "run {}: the loop is not the default design at {} Hz (a recording carries the rate only)",
                i.name, fc.loop_cfg.rate_hz
            )
        })?;
        encode(&setup, &i.events)
    }
}

fn encode(setup: &Setup<'_>, events: &[Owned]) -> Result<Vec<u8>, String> {
    let mut out = postcard::to_allocvec(setup).map_err(|e| e.to_string())?;
    let mut codec = Codec::default();
    for e in events {
        match e {
            Owned::Ev(ev) => codec.encode(ev, &mut out),
            Owned::Fault(s) => codec.encode(&Event::Fault(s), &mut out),
        }
    }
    Ok(out)
}

/// A tap on an SPI device: passes every transaction through and, when
/// recording, logs it.
pub struct Tap<S> {
    inner: S,
    dev: Dev,
    rec: Option<Recorder>,
}

impl<S> Tap<S> {
    pub fn new(inner: S, dev: Dev, rec: Option<Recorder>) -> Self {
        Self { inner, dev, rec }
    }
    pub fn inner(&self) -> &S {
        &self.inner
    }
}

impl<S: ErrorType> ErrorType for Tap<S> {
    type Error = S::Error;
}

impl<S: SpiDevice> SpiDevice for Tap<S> {
    #[inline]
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), S::Error> {
        match &self.rec {
            None => self.inner.transaction(ops),
            Some(rec) => recorded(rec, self.dev, &mut self.inner, ops),
        }
    }
}

/// The recording path, out of line: a tap that does not record costs the
/// simulator's hot path one branch and changes no inlining around it.
#[cold]
#[inline(never)]
fn recorded<S: SpiDevice>(
    rec: &Recorder,
    dev: Dev,
    inner: &mut S,
    ops: &mut [Operation<'_, u8>],
) -> Result<(), S::Error> {
    let mosi = frames::mosi(ops);
    let r = inner.transaction(ops);
    match (mosi, frames::miso(ops)) {
        (Some(o), Some(i)) => rec.item(Event::Spi(Io {
            dev,
            ok: r.is_ok(),
            mosi_len: o.len,
            mosi: o.word,
            miso_len: i.len,
            miso: i.word,
        })),
        _ => rec.fail(format!(
            "{}: a transaction longer than 3 bytes each way",
            dev.name()
        )),
    }
    r
}

/// A tap on the LDAC pin.
pub struct TapPin<P> {
    inner: P,
    rec: Option<Recorder>,
}

impl<P> TapPin<P> {
    pub fn new(inner: P, rec: Option<Recorder>) -> Self {
        Self { inner, rec }
    }
}

impl<P: PinErrorType> PinErrorType for TapPin<P> {
    type Error = P::Error;
}

impl<P: OutputPin> OutputPin for TapPin<P> {
    fn set_low(&mut self) -> Result<(), P::Error> {
        if let Some(r) = &self.rec {
            r.item(Event::Pin(false));
        }
        self.inner.set_low()
    }
    fn set_high(&mut self) -> Result<(), P::Error> {
        if let Some(r) = &self.rec {
            r.item(Event::Pin(true));
        }
        self.inner.set_high()
    }
}

/// What [`alter`] changed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Alteration {
    /// Loop tick (from 1) whose amplifier-DAC frame was changed.
    pub tick: u32,
    pub original: u32,
    pub altered: u32,
}

/// The run with the amplifier-DAC frame of its `nth` loop tick that wrote
/// one (from 0) changed in its least significant code bit: the replay of
/// the result must report exactly that frame.
pub fn alter(run: &'static [u8], nth: usize) -> Result<(Vec<u8>, Alteration), String> {
    let (setup, mut rest) = crate::wire::take::<Setup<'static>>(run).map_err(|e| e.to_string())?;
    let mut codec = Codec::default();
    let mut events = Vec::new();
    let mut ticks = 0u32;
    let mut seen = 0usize;
    let mut done = None;
    let mut in_tick = false;
    while !rest.is_empty() {
        let (mut ev, r) = codec.decode(rest).map_err(|e| e.to_string())?;
        rest = r;
        match &mut ev {
            Event::Tick { .. } => {
                ticks += 1;
                in_tick = true;
            }
            Event::Spi(io) if in_tick && io.dev == Dev::AmpDac && io.mosi_len == 3 => {
                if done.is_none() {
                    if seen == nth {
                        let original = io.mosi;
                        io.mosi ^= 1;
                        done = Some(Alteration {
                            tick: ticks,
                            original,
                            altered: io.mosi,
                        });
                    }
                    seen += 1;
                }
            }
            Event::Spi(_) | Event::Pin(_) | Event::Enable(_) | Event::Fault(_) => {}
            _ => in_tick = false,
        }
        events.push(match ev {
            Event::Fault(s) => Owned::Fault(s.to_string()),
            e => Owned::Ev(e.detach().ok_or("a fault outside its arm")?),
        });
    }
    let a = done.ok_or_else(|| format!("the run has fewer than {} DAC frames", nth + 1))?;
    Ok((encode(&setup, &events)?, a))
}

/// The run with its setup's interruption block replaced by `block` (empty:
/// none), its events as recorded: the firmware that replays it is given
/// another part, so a block that acted on the run must show in its frames.
pub fn with_interruptions(run: &[u8], block: &[u8]) -> Result<Vec<u8>, String> {
    let (setup, rest) = crate::wire::take::<Setup<'_>>(run).map_err(|e| e.to_string())?;
    let setup = Setup {
        interruptions: block,
        ..setup
    };
    let mut out = postcard::to_allocvec(&setup).map_err(|e| e.to_string())?;
    out.extend_from_slice(rest);
    Ok(out)
}
