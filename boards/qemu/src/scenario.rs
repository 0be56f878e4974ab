//! The synthetic machine the QEMU image runs against, and the run's script:
//! rates, the spindle (encoder and index), the X feed (legacy half-mil
//! events with duplicates and a reversal, or a count), when the trace
//! samples are taken and when the gauge bus breaks, and the part's
//! interruptions (the block the checked run hands the firmware). World time
//! is the loop tick count (`WORLD_TICK`); everything here is a pure
//! function of it.

use core::sync::atomic::{AtomicU32, Ordering};

use zslide::hw::EncoderSample;
use zslide::table::interrupt::{Hole, Interruptions, HEADER_LEN, HOLE_LEN};
use zslide::units::SpindleAngle;
use zslide::xpos::CountConfig;

/// Loop-tick rate, Hz (the real board's rate).
pub(crate) const LOOP_HZ: u32 = 20_000;
/// Firmware clock (`hw::Clock`): 25 MHz, 1250 counts per loop tick.
pub(crate) const CLOCK_HZ: u32 = 25_000_000;
pub(crate) const CLOCK_PER_TICK: u32 = CLOCK_HZ / LOOP_HZ;
/// Loop ticks the run lasts (0.3 s of world time; the loop tracks the
/// table for 0.23 s of it, ticks [`TRACK_FROM`]..=[`INJECT_AT`]).
pub(crate) const TICKS: u32 = 6_000;
/// The gauge bus breaks after this tick.
pub(crate) const INJECT_AT: u32 = 5_600;
/// Tracking is checked from this tick to [`INJECT_AT`].
pub(crate) const TRACK_FROM: u32 = 1_001;
/// The slide rests here at power-up, gauge codes (−0.001 in).
pub(crate) const START_CODE: i32 = -52_429;

/// Synthetic spindle: 1200 rpm, 4096 counts per turn, the first index at
/// count [`INDEX0`], then every turn.
pub(crate) const RPM: u64 = 1_200;
pub(crate) const CPR: u32 = 4_096;
pub(crate) const INDEX0: u32 = 300;
/// Synthetic X feed: from 2.0000 in, one half-mil every [`X_EVERY`] ticks
/// (0.0005 in / 1.5 ms = 20 in/min) from tick [`X_FIRST`].
pub(crate) const X_START_HM: u32 = 4_000;
pub(crate) const X_FIRST: u32 = 10;
pub(crate) const X_EVERY: u32 = 30;
/// Modern X (`modern-x`): counts per inch of the X count (0.5 µin each),
/// 1000 counts per half-mil.
pub(crate) const X_COUNTS_PER_INCH: i32 = 2_000_000;
pub(crate) const X_COUNT_CFG: CountConfig = CountConfig {
    counts_per_inch: X_COUNTS_PER_INCH,
    zero_count: 0,
    max_step_counts: 1_000,
};
/// Events (by number) that the latch repeats right away: debounced.
pub(crate) const DUPLICATES: [u32; 4] = [15, 45, 75, 105];
/// From this event on the feed reverses one half-mil and resumes.
pub(crate) const REVERSAL: u32 = 60;
/// No machine events after this tick (the bus-error phase follows).
pub(crate) const EVENTS_UNTIL: u32 = INJECT_AT - 100;
/// Ticks at which the handler records a trace sample for the log.
pub(crate) const TRACE_AT: [u32; 14] = [
    1, 50, 100, 200, 400, 800, 1600, 2400, 3200, 4000, 4800, 5600, 5601, 6000,
];

/// World time in loop ticks, published by the loop tick.
pub(crate) static WORLD_TICK: AtomicU32 = AtomicU32::new(0);

defmt::timestamp!(
    "{=u32:us}",
    WORLD_TICK.load(Ordering::Relaxed) * (1_000_000 / LOOP_HZ)
);

/// Spindle count at clock time `t`.
pub(crate) fn spindle_count(t: u64) -> u32 {
    (t * RPM * u64::from(CPR) / (60 * u64::from(CLOCK_HZ))) as u32
}
/// Clock time of the edge that brought count `c` (first instant at it).
pub(crate) fn spindle_edge(c: u32) -> u64 {
    let per = RPM * u64::from(CPR);
    (u64::from(c) * 60 * u64::from(CLOCK_HZ)).div_ceil(per)
}
/// The encoder reading at clock time `t`.
pub(crate) fn encoder_at(t: u64) -> EncoderSample {
    let count = spindle_count(t);
    EncoderSample {
        count,
        edge_ticks: spindle_edge(count) as u32,
    }
}
/// Half-mil position of X event number `i`.
pub(crate) fn x_script(i: u32) -> u32 {
    if i < REVERSAL {
        X_START_HM + i
    } else {
        X_START_HM + i - 2
    }
}
/// Tick of X event number `i`.
pub(crate) fn x_tick(i: u32) -> u32 {
    X_FIRST + X_EVERY * i
}
/// X events scheduled before [`EVENTS_UNTIL`] (none with a counted X).
pub(crate) fn x_events() -> u32 {
    if cfg!(feature = "modern-x") {
        return 0;
    }
    (EVENTS_UNTIL - X_FIRST).div_ceil(X_EVERY)
}
/// The X count at loop tick `n` (`modern-x`): the same 20 in/min from
/// 2.0000 in as the legacy script (one half-mil per [`X_EVERY`] ticks from
/// tick [`X_FIRST`]), continuous, until [`EVENTS_UNTIL`].
pub(crate) fn x_count_at(n: u32) -> u32 {
    let per_hm = (X_COUNTS_PER_INCH / 2000) as u32;
    let moved = n.clamp(X_FIRST, EVENTS_UNTIL) - X_FIRST;
    X_START_HM * per_hm + moved * per_hm / X_EVERY
}
/// Index pulses before [`EVENTS_UNTIL`].
pub(crate) fn index_pulses() -> u32 {
    let until = u64::from(EVENTS_UNTIL) * u64::from(CLOCK_PER_TICK);
    (0..16)
        .filter(|m| spindle_edge(INDEX0 + CPR * m) <= until)
        .count() as u32
}
/// The fault-path check's instant (`crate::INJECT`): the loop is engaged
/// and tracking there (the amplifier enabled).
pub(crate) const FAULT_AT: u32 = 3_000;

/// The part's interruptions: four holes of 0.25 in on a 2.05 in circle,
/// at 45°, 135°, 225° and 315° of the spindle angle. X runs from 2.0000 in
/// to 2.092 in, so the nose's whole contact chord (0.0087 in) crosses every
/// hole every turn: the edges' anticipation learns its step at every
/// crossing and the loop tick takes an edge's change about every 19 ticks
/// (the hole's 3.5° half-width at 0.36° a tick), the tick's worst path.
pub(crate) const HOLES: [Hole; 4] = {
    const fn hole(eighths: u32) -> Hole {
        Hole {
            centre_radius_uin: 2_050_000,
            angle: SpindleAngle(eighths << 29),
            diameter_uin: 250_000,
        }
    }
    [hole(1), hole(3), hole(5), hole(7)]
};
/// Bytes of [`HOLES`]' block.
pub(crate) const BLOCK_LEN: usize = HEADER_LEN + HOLES.len() * HOLE_LEN + 4;

/// The interruption block of [`HOLES`], as the part program writes it
/// (`Interruptions::encode`: the firmware's own format, CRC'd).
pub(crate) fn interruption_block() -> [u8; BLOCK_LEN] {
    let mut b = [0u8; BLOCK_LEN];
    // `BLOCK_LEN` is the length of `HOLES`' block: the encoder fills it.
    let _ = Interruptions::encode(&HOLES, &mut b);
    b
}
