//! Plays a recorded run through the firmware's own entry points
//! (`Firmware::{loop_tick, x_event, index_event, request}`) with the core's
//! converter drivers on replay devices: every read gets the recorded bytes,
//! every frame the firmware writes is compared with the recorded one at the
//! moment it is written, and after every call the amplifier enable, the
//! latched fault and an X event's result. The first difference ends the
//! run ([`Mismatch`]).

use core::cell::RefCell;
use core::fmt::Write as _;

use embedded_hal::digital::{ErrorType as PinErrorType, OutputPin};
use embedded_hal::spi::{ErrorKind, ErrorType, Operation, SpiDevice};
use heapless::{Deque, String};
use zslide::drivers::{ad4020::Ad4020, ad5686::Ad5686, ad5791::Ad5791};
use zslide::firmware::{Firmware, Request, SpindleReading, TickInput};
use zslide::hw::{EncoderSample, XLatchWord};
use zslide::safety::{Device, Fault};
use zslide::xpos::XEvent;

use crate::frames::{self, Frame};
use crate::wire::{Codec, Dev, Event, FormatError, Io, Req, Setup, Spindle, XResult};

/// Frames and pin levels one call may produce (boot: 5; a loop tick: 2-3).
const MAX_ITEMS: usize = 16;
/// Longest fault text compared (`Debug` of `Option<Fault>`'s content).
pub type Text = String<48>;

/// Which handler call a difference was found in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Call {
    Boot,
    LoopTick,
    XEvent,
    IndexEvent,
    Request,
}

/// Which output differed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    /// A frame the firmware wrote (or the transaction's length).
    Frame(Dev),
    /// The firmware made a transaction the recording does not have.
    ExtraFrame(Dev),
    /// The recording has a transaction (or pin level) the firmware did
    /// not make.
    MissingFrame,
    /// The coefficient DAC's LDAC line.
    Ldac,
    AmplifierEnable,
    Fault,
    XResult,
    /// The recording itself (unreadable from here on).
    Recording,
}

/// A value compared.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Value {
    /// A frame: its bytes as a big-endian word, and their count.
    Frame(Frame),
    /// A recorded transaction or pin level (what was expected where the
    /// firmware did something else).
    Item(Item),
    None,
    Level(bool),
    Text(Text),
    XResult(XResult),
}

/// One expected bus item of a call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Item {
    Spi(Io),
    Pin(bool),
}

/// The first difference of a run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mismatch {
    /// Loop ticks played in the run, this one included when `call` is a
    /// loop tick (the recording's tick number, from 1).
    pub tick: u32,
    pub call: Call,
    pub output: Output,
    pub expected: Value,
    pub got: Value,
}

impl core::fmt::Display for Value {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Value::Frame(fr) => write!(f, "{:#08x} ({} bytes)", fr.word, fr.len),
            Value::Item(Item::Spi(io)) => write!(
                f,
                "{} frame {:#08x} ({} bytes)",
                io.dev.name(),
                io.mosi,
                io.mosi_len
            ),
            Value::Item(Item::Pin(l)) => write!(f, "LDAC {}", if *l { "high" } else { "low" }),
            Value::None => write!(f, "nothing"),
            Value::Level(l) => write!(f, "{l}"),
            Value::Text(t) => write!(f, "{t}"),
            Value::XResult(r) => write!(f, "{r:?}"),
        }
    }
}

impl core::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let output: &str = match self.output {
            Output::Frame(d) | Output::ExtraFrame(d) => d.name(),
            Output::MissingFrame => "bus item",
            Output::Ldac => "LDAC",
            Output::AmplifierEnable => "amplifier enable",
            Output::Fault => "fault",
            Output::XResult => "X event result",
            Output::Recording => "recording",
        };
        let what = match self.output {
            Output::Frame(_) => " frame",
            Output::ExtraFrame(_) => " frame (unrecorded)",
            _ => "",
        };
        write!(
            f,
            "tick {} ({:?}): {output}{what}: expected {}, got {}",
            self.tick, self.call, self.expected, self.got
        )
    }
}

/// What a run played.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Played {
    pub ticks: u32,
    pub x_events: u32,
    pub index_events: u32,
    pub requests: u32,
    /// SPI transactions compared (frames out) and fed (frames in).
    pub frames: u32,
    /// LDAC levels compared.
    pub pin_levels: u32,
    /// The fault latched at the end of the run ("" = none).
    pub final_fault: Text,
}

/// Why a run could not be played to its end.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RunError {
    Format(FormatError),
    /// The recorded configuration is refused by this firmware.
    Config,
    /// The recorded interruption block is refused by this firmware.
    Interruptions(zslide::table::interrupt::InterruptError),
    Mismatch(Mismatch),
}

impl core::fmt::Display for RunError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RunError::Format(e) => write!(f, "{e}"),
            RunError::Config => write!(f, "the recorded firmware configuration is refused"),
            RunError::Interruptions(e) => write!(f, "the recorded {e}"),
            RunError::Mismatch(m) => write!(f, "{m}"),
        }
    }
}

/// The expected items of the current call, shared by the replay devices.
struct Bus {
    items: Deque<Item, MAX_ITEMS>,
    /// The first difference the devices saw in this call.
    mismatch: Option<(Output, Value, Value)>,
    frames: u32,
    pin_levels: u32,
}

impl Bus {
    fn differ(&mut self, output: Output, expected: Value, got: Value) {
        if self.mismatch.is_none() {
            self.mismatch = Some((output, expected, got));
        }
    }
}

#[derive(Debug)]
pub struct ReplayError;
impl embedded_hal::spi::Error for ReplayError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}
impl embedded_hal::digital::Error for ReplayError {
    fn kind(&self) -> embedded_hal::digital::ErrorKind {
        embedded_hal::digital::ErrorKind::Other
    }
}

/// An SPI device that answers with the recording and checks what it is sent.
struct ReplaySpi<'b> {
    bus: &'b RefCell<Bus>,
    dev: Dev,
}

impl ErrorType for ReplaySpi<'_> {
    type Error = ReplayError;
}

impl SpiDevice for ReplaySpi<'_> {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), ReplayError> {
        let mut bus = self.bus.borrow_mut();
        let got = frames::mosi(ops).unwrap_or(Frame {
            len: u8::MAX,
            word: 0,
        });
        let io = match bus.items.pop_front() {
            Some(Item::Spi(io)) if io.dev == self.dev => io,
            other => {
                let expected = other.map_or(Value::None, Value::Item);
                bus.differ(Output::ExtraFrame(self.dev), expected, Value::Frame(got));
                return Err(ReplayError);
            }
        };
        bus.frames += 1;
        let expected = Frame {
            len: io.mosi_len,
            word: io.mosi,
        };
        if got != expected {
            bus.differ(
                Output::Frame(self.dev),
                Value::Frame(expected),
                Value::Frame(got),
            );
        }
        frames::fill_miso(
            ops,
            Frame {
                len: io.miso_len,
                word: io.miso,
            },
        );
        if io.ok {
            Ok(())
        } else {
            Err(ReplayError)
        }
    }
}

/// The coefficient DAC's LDAC pin: each level set is compared.
struct ReplayPin<'b> {
    bus: &'b RefCell<Bus>,
}

impl PinErrorType for ReplayPin<'_> {
    type Error = ReplayError;
}

impl ReplayPin<'_> {
    fn set(&mut self, level: bool) -> Result<(), ReplayError> {
        let mut bus = self.bus.borrow_mut();
        match bus.items.pop_front() {
            Some(Item::Pin(l)) if l == level => {
                bus.pin_levels += 1;
                Ok(())
            }
            other => {
                let expected = other.map_or(Value::None, Value::Item);
                bus.differ(Output::Ldac, expected, Value::Level(level));
                Err(ReplayError)
            }
        }
    }
}

impl OutputPin for ReplayPin<'_> {
    fn set_low(&mut self) -> Result<(), ReplayError> {
        self.set(false)
    }
    fn set_high(&mut self) -> Result<(), ReplayError> {
        self.set(true)
    }
}

/// `Debug` of a latched fault, "" for none: the recording's form.
pub fn fault_text(f: Option<Fault>) -> Text {
    let mut t = Text::new();
    if let Some(f) = f {
        // A longer text is cut; the recorder writes the same cut.
        let _ = write!(Truncating(&mut t), "{f:?}");
    }
    t
}

/// Writes what fits.
struct Truncating<'a>(&'a mut Text);
impl core::fmt::Write for Truncating<'_> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        for c in s.chars() {
            if self.0.push(c).is_err() {
                break;
            }
        }
        Ok(())
    }
}

fn request(r: Req) -> Request {
    match r {
        Req::Arm => Request::Arm,
        Req::Disarm => Request::Disarm,
        Req::ClearFault => Request::ClearFault,
    }
}

/// A run played: its name ("" when even its setup is unreadable) and how
/// it went.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outcome {
    pub name: &'static str,
    pub result: Result<Played, RunError>,
}

/// Plays one run (its bytes as the container holds them). `'static`: the
/// firmware keeps the recorded table image.
pub fn play_run(run: &'static [u8]) -> Outcome {
    match crate::wire::take::<Setup<'static>>(run) {
        Ok((setup, rest)) => Outcome {
            name: setup.name,
            result: play(&setup, rest),
        },
        Err(_) => Outcome {
            name: "",
            result: Err(RunError::Format(FormatError::Item)),
        },
    }
}

// The error is returned once per run and the crate is `no_std` without an
// allocator to box it in.
#[allow(clippy::result_large_err)]
fn play(setup: &Setup<'static>, mut rest: &'static [u8]) -> Result<Played, RunError> {
    let cfg = setup.firmware_config().ok_or(RunError::Config)?;

    let bus = RefCell::new(Bus {
        items: Deque::new(),
        mismatch: None,
        frames: 0,
        pin_levels: 0,
    });
    let mut adc = Ad4020::new(ReplaySpi {
        bus: &bus,
        dev: Dev::GaugeAdc,
    });
    let mut dac = Ad5791::new(ReplaySpi {
        bus: &bus,
        dev: Dev::AmpDac,
    });
    let mut quad: Option<Ad5686<ReplaySpi<'_>, ReplayPin<'_>>> = None;
    let mut fw: Option<Firmware> = None;
    let mut codec = Codec::default();
    let mut played = Played::default();
    let mut enable = false;
    let mut fault = Text::new();
    let mut lookahead: Option<Event<'static>> = None;

    loop {
        let ev = match lookahead.take() {
            Some(e) => e,
            None if rest.is_empty() => break,
            None => {
                let (e, r) = codec.decode(rest).map_err(RunError::Format)?;
                rest = r;
                e
            }
        };
        // The call's bus items follow it.
        {
            let mut b = bus.borrow_mut();
            b.items.clear();
            while !rest.is_empty() {
                let (e, r) = codec.decode(rest).map_err(RunError::Format)?;
                rest = r;
                let item = match e {
                    Event::Spi(io) => Item::Spi(io),
                    Event::Pin(l) => Item::Pin(l),
                    other => {
                        lookahead = Some(other);
                        break;
                    }
                };
                if b.items.push_back(item).is_err() {
                    return Err(RunError::Format(FormatError::Item));
                }
            }
        }
        let mut x_result = None;
        let call = match ev {
            Event::Boot => {
                let init_failed = dac.init().is_err();
                let q = Ad5686::new(
                    ReplaySpi {
                        bus: &bus,
                        dev: Dev::QuadDac,
                    },
                    ReplayPin { bus: &bus },
                );
                let mut f = Firmware::with_table(setup.table, cfg).map_err(|_| RunError::Config)?;
                if !setup.interruptions.is_empty() {
                    f.set_interruptions(setup.interruptions)
                        .map_err(RunError::Interruptions)?;
                }
                if init_failed {
                    f.trip(Fault::Bus(Device::AmplifierDac));
                }
                if q.is_err() {
                    f.trip(Fault::Bus(Device::CoefficientDac));
                }
                quad = q.ok();
                fw = Some(f);
                Call::Boot
            }
            Event::Request(r) => {
                played.requests += 1;
                if let Some(f) = fw.as_mut() {
                    f.request(request(r));
                }
                Call::Request
            }
            Event::Tick {
                now,
                spindle,
                x_count,
                amplifier_fault,
            } => {
                played.ticks += 1;
                let input = TickInput {
                    now,
                    spindle: match spindle {
                        Spindle::None => SpindleReading::None,
                        Spindle::Encoder { count, edge_ticks } => {
                            SpindleReading::Encoder(EncoderSample { count, edge_ticks })
                        }
                        Spindle::Tach(mv) => SpindleReading::Tach(mv),
                    },
                    x_count,
                    amplifier_fault,
                };
                if let Some(f) = fw.as_mut() {
                    f.loop_tick(&input, &mut adc, &mut dac);
                }
                Call::LoopTick
            }
            Event::X { word, now, result } => {
                played.x_events += 1;
                if let (Some(f), Some(q)) = (fw.as_mut(), quad.as_mut()) {
                    let got = match f.x_event(XLatchWord(word), now, q) {
                        Ok(XEvent::Ignored) => XResult::Ignored,
                        Ok(XEvent::Update(_)) => XResult::Update,
                        Err(_) => XResult::Fault,
                    };
                    x_result = Some((result, got));
                }
                Call::XEvent
            }
            Event::Index { edge_ticks, count } => {
                played.index_events += 1;
                if let Some(f) = fw.as_mut() {
                    f.index_event(edge_ticks, count);
                }
                Call::IndexEvent
            }
            Event::Spi(_) | Event::Pin(_) | Event::Enable(_) | Event::Fault(_) => {
                // Outside a call: the recording is out of order.
                return Err(RunError::Format(FormatError::Item));
            }
        };
        let mismatch = |output, expected, got| {
            RunError::Mismatch(Mismatch {
                tick: played.ticks,
                call,
                output,
                expected,
                got,
            })
        };
        {
            let mut b = bus.borrow_mut();
            if let Some((o, e, g)) = b.mismatch.take() {
                return Err(mismatch(o, e, g));
            }
            if let Some(item) = b.items.pop_front() {
                return Err(mismatch(
                    Output::MissingFrame,
                    Value::Item(item),
                    Value::None,
                ));
            }
        }
        if let Some((expected, got)) = x_result {
            if expected != got {
                return Err(mismatch(
                    Output::XResult,
                    Value::XResult(expected),
                    Value::XResult(got),
                ));
            }
        }
        // What changed after the call.
        if lookahead.is_none() && !rest.is_empty() {
            let (e, r) = codec.decode(rest).map_err(RunError::Format)?;
            rest = r;
            lookahead = Some(e);
        }
        while let Some(e) = lookahead {
            match e {
                Event::Enable(v) => enable = v,
                Event::Fault(s) => {
                    fault.clear();
                    let _ = Truncating(&mut fault).write_str(s);
                }
                _ => break,
            }
            lookahead = None;
            if !rest.is_empty() {
                let (e, r) = codec.decode(rest).map_err(RunError::Format)?;
                rest = r;
                lookahead = Some(e);
            }
        }
        if let Some(f) = fw.as_ref() {
            if f.amplifier_enable() != enable {
                return Err(mismatch(
                    Output::AmplifierEnable,
                    Value::Level(enable),
                    Value::Level(f.amplifier_enable()),
                ));
            }
            let got = fault_text(f.fault());
            if got != fault {
                return Err(mismatch(
                    Output::Fault,
                    Value::Text(fault.clone()),
                    Value::Text(got),
                ));
            }
        }
    }
    let b = bus.borrow();
    played.frames = b.frames;
    played.pin_levels = b.pin_levels;
    played.final_fault = fault;
    Ok(played)
}
