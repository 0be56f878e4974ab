//! The host link's frames (`zslide::link`), from arbitrary bytes.
//!
//! 1. The decoder on one frame: never panics; a frame it accepts
//!    re-encodes (through the one encoder) to a frame that decodes to the
//!    same number and request.
//! 2. The firmware's link service on an arbitrary byte stream, with the
//!    loop ticking between its passes: every non-empty frame (bytes up to a
//!    0x00) gets exactly one reply, each reply is a valid frame, and the
//!    service's counters account for every frame (accepted + refused +
//!    empty = delimiters seen).
#![no_main]

use std::collections::VecDeque;

use libfuzzer_sys::fuzz_target;
use zslide::firmware::{Firmware, Shared, TickInput};
use zslide::hw::{AmplifierDac, BusError, GaugeAdc, GaugeSample};
use zslide::link::proto::{self, Reply, Request, SpindleSource, XSource, MAX_FRAME, REQUEST_KINDS};
use zslide::link::station::{LinkIo, Station, StationConfig};
use zslide::link::tap::{Scope, TapShared, TickTap};
use zslide::params::ParamSource;
use zslide::servo::ServoDesign;
use zslide::table::TableError;

struct Gauge;
impl GaugeAdc for Gauge {
    fn read(&mut self) -> Result<GaugeSample, BusError> {
        Ok(GaugeSample {
            code: 100,
            overrange: false,
        })
    }
}
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

#[derive(Default)]
struct Pipe {
    rx: VecDeque<u8>,
    tx: Vec<u8>,
}
impl LinkIo for Pipe {
    fn read(&mut self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        while n < buf.len() {
            let Some(b) = self.rx.pop_front() else { break };
            buf[n] = b;
            n += 1;
        }
        n
    }
    fn write(&mut self, bytes: &[u8]) -> usize {
        self.tx.extend_from_slice(bytes);
        bytes.len()
    }
}

fuzz_target!(|data: &[u8]| {
    // 1. One frame.
    let mut frame = data.to_vec();
    if let Ok((seq, req)) = proto::decode::<Request>(&mut frame, REQUEST_KINDS) {
        let mut out = [0u8; MAX_FRAME];
        let enc = proto::encode(seq, &req, &mut out).expect("a decoded request encodes");
        let mut again = enc[..enc.len() - 1].to_vec();
        let (seq2, req2) = proto::decode::<Request>(&mut again, REQUEST_KINDS)
            .expect("a re-encoded request decodes");
        assert_eq!(seq2, seq);
        assert!(
            req2 == req || format!("{req2:?}") == format!("{req:?}"),
            "{req:?} / {req2:?}"
        );
    }

    // 2. A stream into the firmware's service.
    let mut d = ServoDesign::brief(20_000);
    d.sign_check_v = 0.0;
    let (mut lp, _, _) = Firmware::new(d.config().unwrap()).into_parts();
    let shared = Shared::new();
    let scope: Box<Scope<64>> = Box::new(Scope::new());
    let tap_shared: TapShared<64> = TapShared::new(&scope);
    let mut tap = TickTap::new();
    let mut station: Station<64> = Station::new(StationConfig {
        loop_hz: 20_000,
        x_source: XSource::None,
        spindle_source: SpindleSource::None,
        table: Err(TableError::Missing),
        design: d,
        params: ParamSource::BuiltIn,
    });
    let mut pipe = Pipe::default();
    pipe.rx.extend(data);
    let delimiters = data.iter().filter(|&&b| b == 0).count() as u32;
    let mut nonempty = 0u32;
    let mut len = 0;
    for &b in data {
        if b == 0 {
            nonempty += u32::from(len > 0);
            len = 0;
        } else {
            len += 1;
        }
    }
    let mut idle = 0;
    for _ in 0..(data.len() * 4 + 64) {
        lp.loop_tick(&shared, &TickInput::NONE, &mut Gauge, &mut Dac);
        tap.after_tick(&tap_shared, &mut lp);
        let before = (pipe.rx.len(), pipe.tx.len());
        station.poll(&tap_shared, &shared, &mut pipe);
        if pipe.rx.is_empty() && before == (pipe.rx.len(), pipe.tx.len()) {
            idle += 1;
            if idle > 4 {
                break;
            }
        } else {
            idle = 0;
        }
    }
    assert!(pipe.rx.is_empty(), "input not consumed");
    let mut replies = 0;
    for f in pipe.tx.split(|&b| b == 0).filter(|f| !f.is_empty()) {
        let mut f = f.to_vec();
        let r = proto::decode::<Reply>(&mut f, u32::MAX);
        assert!(r.is_ok(), "a reply is not a frame: {r:?}");
        replies += 1;
    }
    assert_eq!(
        pipe.tx.last().copied().unwrap_or(0),
        0,
        "a reply left unterminated"
    );
    assert_eq!(replies, nonempty, "one reply per non-empty frame");
    let c = station.frames();
    let counted = c.ok
        + c.empty
        + c.oversize
        + c.bad_cobs
        + c.bad_crc
        + c.bad_version
        + c.unknown_command
        + c.malformed;
    assert_eq!(counted, delimiters, "frames not all counted: {c:?}");
});
