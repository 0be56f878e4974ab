//! Bit-exact replay on the emulated Cortex-M4F: the runs host-sim recorded
//! (`host-sim replay-record`, `host-sim/src/replay.rs`) played through the
//! firmware's own entry points and converter drivers
//! (`zslide_replay::play_run`), every frame, LDAC level, amplifier enable,
//! fault and X-event result compared with host-sim's. The recording is in
//! the last 448 KiB of the emulated flash (`memory.x`: `__replay_start`), put
//! there by QEMU's loader (`cargo xtask qemu`).
//!
//! Logs one line per run and exits (semihosting) with status 0 only when
//! every run played to its end without a difference; the first difference
//! of a run is logged as `FAIL: replay <run>: tick <n> (<handler>):
//! <output>: expected <value>, got <value>`.
#![no_std]
#![no_main]

use cortex_m_rt::{entry, exception, ExceptionFrame};
use defmt::Display2Format;
use defmt_semihosting as _;
// The board's vector table (every device interrupt unused here).
use zslide_qemu::exit;
use zslide_replay::{container, play_run};

extern "C" {
    /// Start and length of the recording's flash region (`memory.x`).
    static __replay_start: u8;
    static __replay_len: u8;
}

#[entry]
fn main() -> ! {
    // SAFETY: `__replay_start` and `__replay_len` are defined by memory.x:
    // the first is the start of the 448 KiB REPLAY region of the emulated
    // flash, the second's address is that region's length. The region is
    // not part of the image's sections, nothing writes it while the image
    // runs, and QEMU backs it with memory (zeros when no recording was
    // loaded, which `container::runs` refuses), so a shared 'static slice
    // over it is valid.
    let region: &'static [u8] = unsafe {
        let len = core::ptr::addr_of!(__replay_len) as usize;
        core::slice::from_raw_parts(core::ptr::addr_of!(__replay_start), len)
    };
    let runs = match container::runs(region) {
        Ok(r) => r,
        Err(e) => {
            defmt::error!("FAIL: {}", Display2Format(&e));
            exit(false);
        }
    };
    defmt::info!("replay: {=u32} recorded runs", runs.remaining());
    let mut ok = true;
    for run in runs {
        let run = match run {
            Ok(r) => r,
            Err(e) => {
                defmt::error!("FAIL: {}", Display2Format(&e));
                exit(false);
            }
        };
        let outcome = play_run(run);
        match outcome.result {
            Ok(p) => defmt::info!(
                "replay {=str}: bit-exact: {=u32} loop ticks, {=u32} X events, {=u32} index events, {=u32} requests, {=u32} SPI frames, {=u32} LDAC levels; fault at end {=str}",
                outcome.name,
                p.ticks,
                p.x_events,
                p.index_events,
                p.requests,
                p.frames,
                p.pin_levels,
                if p.final_fault.is_empty() { "none" } else { p.final_fault.as_str() }
            ),
            Err(e) => {
                defmt::error!("FAIL: replay {=str}: {}", outcome.name, Display2Format(&e));
                ok = false;
            }
        }
    }
    if ok {
        defmt::info!("PASS");
    }
    exit(ok)
}

// cortex-m-rt requires the HardFault handler to be an `unsafe fn`; its body
// does nothing unsafe itself.
#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    defmt::error!("FAIL: hard fault at pc {=u32:#010x}", ef.pc());
    exit(false)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("FAIL: panic: {}", Display2Format(info));
    exit(false)
}
