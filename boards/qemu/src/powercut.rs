//! The power-cut runs (`cargo xtask flash-cut`): the image boots its
//! parameters through the store on the flash model (`flash.rs`), says which
//! set it got, and, with the argument `save`, sets three parameters over
//! the link and saves them (`Request::SaveParams`, the station's own path,
//! the loop disarmed and ticking), power cut or not.
//!
//! The set is chosen on the semihosting command line as whole numbers,
//! `q=Q ms=M fe=F`: `hum_notch_q` Q, `following_error_ms` M,
//! `following_error_in` F µin. The boot reports the three in the same
//! units, so the host compares what it asked for with what booted.

use zslide::firmware::Shared;
use zslide::link::proto::{Reply, Request};
use zslide::link::station::Station;
use zslide::params::{self, ParamSource};
use zslide::servo::ServoDesign;
use zslide::store::{Store, StoreError};

use crate::flash::ImageFlash;
use crate::link::{self, Script, CAPTURE};

/// The three parameters a set moves, and the scale from a set's whole
/// number to the parameter's unit.
const SET: [(&str, &[u8], f64); 3] = [
    ("hum_notch_q", b"q=", 1.0),
    ("following_error_ms", b"ms=", 1.0),
    ("following_error_in", b"fe=", 1e-6),
];

/// The value of `name` in `d`, in the set's whole units.
fn whole(d: &ServoDesign, name: &str, scale: f64) -> u32 {
    params::by_name(name).map_or(u32::MAX, |p| (p.get(d) / scale + 0.5) as u32)
}

/// The boot's verdict and the set it booted with (the line the host reads).
pub fn report_boot(d: &ServoDesign, source: &ParamSource, ops: u32) {
    defmt::info!(
        "flash boot: {}; hum_notch_q {=u32}, following_error_ms {=u32}, following_error_in {=u32} uin; {=u32} flash operations",
        source,
        whole(d, SET[0].0, SET[0].2),
        whole(d, SET[1].0, SET[1].2),
        whole(d, SET[2].0, SET[2].2),
        ops
    );
}

/// Polls the station until the scripted host has the reply to `req`.
fn ask(
    req: &Request,
    station: &mut Station<CAPTURE>,
    shared: &Shared,
    host: &mut Script,
    store: &mut Store<ImageFlash>,
) -> Option<Reply> {
    host.send(req);
    // The loop tick answers within a few ticks; the save itself runs in
    // one poll.
    for _ in 0..100_000 {
        station.poll_with_store(&link::TAP, shared, host, store);
        if let Some(r) = host.reply() {
            return Some(r);
        }
        cortex_m::asm::wfi();
    }
    None
}

/// Sets the command line's set and saves it; ends the run (a power cut
/// ends it earlier, in `flash.rs`).
pub fn save(station: &mut Station<CAPTURE>, shared: &Shared, store: &mut Store<ImageFlash>) -> ! {
    let mut host = Script::new();
    for (name, key, scale) in SET {
        let (Some(p), Some(v)) = (params::by_name(name), link::value(key)) else {
            defmt::error!("FAIL: the save needs q=, ms= and fe= on the command line");
            zslide_qemu::exit(false);
        };
        let req = Request::Set {
            id: p.id,
            value: f64::from(v) * scale,
        };
        if !matches!(
            ask(&req, station, shared, &mut host, store),
            Some(Reply::Param { .. })
        ) {
            defmt::error!("FAIL: setting {=str} refused", name);
            zslide_qemu::exit(false);
        }
    }
    match ask(&Request::SaveParams, station, shared, &mut host, store) {
        Some(Reply::Saved { entries, crc }) => {
            defmt::info!(
                "saved: block of {=u16} entries, CRC {=u32:#010x}; {=u32} flash operations",
                entries,
                crc,
                store.flash().ops()
            );
            zslide_qemu::exit(true)
        }
        Some(Reply::Refused(zslide::link::proto::Refusal::Store(e))) => {
            defmt::error!("FAIL: save refused: {}", defmt::Display2Format(&e));
        }
        _ => defmt::error!("FAIL: no saved reply"),
    }
    zslide_qemu::exit(false)
}

/// Why the store could not be made, for the log.
pub fn refused(e: StoreError) -> ! {
    defmt::error!("FAIL: the parameter store: {}", defmt::Display2Format(&e));
    zslide_qemu::exit(false)
}
