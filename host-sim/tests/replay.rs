//! The replay of recorded runs through the firmware's entry points
//! (`zslide_replay`), on the host: what `cargo xtask qemu` runs on the
//! emulated Cortex-M4F. A recording played back on the machine that made
//! it must match frame for frame; one altered code must be reported with
//! its tick and both values; a damaged container must be refused.

use host_sim::replay::{record, record_all, record_cases, Case, CASES};
use zslide_replay::player::Value;
use zslide_replay::{container, play_run, Call, Dev, Output, RunError};

fn leak(v: Vec<u8>) -> &'static [u8] {
    Box::leak(v.into_boxed_slice())
}

/// Every recorded case plays back bit-exact on the host, and each covers
/// what it is there for.
#[test]
fn every_recorded_run_replays_bit_exact_on_the_host() {
    let (bytes, runs) = record_all().unwrap();
    let region = leak(bytes);
    let played: Vec<_> = container::runs(region)
        .unwrap()
        .map(|r| {
            let o = play_run(r.unwrap());
            (o.name, o.result.map_err(|e| e.to_string()).unwrap())
        })
        .collect();
    assert_eq!(played.len(), CASES.len());
    for ((name, p), (case, rec)) in played.iter().zip(CASES.iter().zip(&runs)) {
        assert_eq!(*name, case.name);
        // 20 kHz for 0.3 s: every loop tick replayed, its gauge frame fed
        // and (while no fault stops it) its DAC frame compared.
        assert_eq!(p.ticks, 6000, "{}", case.name);
        let per_tick = if case.fault { 1 } else { 2 };
        assert!(
            p.frames >= per_tick * p.ticks,
            "{}: {} frames",
            case.name,
            p.frames
        );
        assert_eq!(
            p.final_fault.as_str(),
            rec.final_fault
                .map(|f| format!("{f:?}"))
                .unwrap_or_default(),
        );
        assert!(p.index_events >= 1, "{}: no index", case.name);
    }
    // Legacy X: half-mil events accepted, the coefficient DACs written and
    // strobed at each (4 LDAC levels per event: idle high at boot, then
    // low-high pulses).
    assert!(played[0].1.x_events >= 20);
    assert!(played[0].1.pin_levels > 2 * 20);
    // Modern X: no X events, the count read by the tick.
    assert_eq!(played[1].1.x_events, 0);
    // The fault run took the operator's requests; the latched gauge fault
    // stopped the DAC frames for a while (fewer than two frames a tick),
    // and after the clear the re-arm engaged again: no fault at the end,
    // the amplifier enabled (the clamp released, its frames compared too).
    assert!(played[2].1.requests >= 5);
    assert!(played[2].1.frames < 2 * played[2].1.ticks);
    assert!(played[2].1.final_fault.is_empty());
    assert!(runs[2].engaged && runs[2].final_fault.is_none());
    // The interruption block's run: the edges' anticipation learned its
    // step at hole crossings (the block acted on the loop).
    assert!(CASES[3].holes);
    assert!(runs[3].edge_crossings >= 1, "{}", runs[3].edge_crossings);
}

/// The interruption block travels with the recording: the run made with
/// one replays bit-exact, and the same events replayed by a firmware given
/// no block, or the block with its holes turned 2°, differ at a loop tick's
/// DAC frame (what the block fed the loop).
#[test]
fn a_run_with_an_interruption_block_replays_only_with_its_block() {
    let case = CASES.iter().find(|c| c.holes).unwrap();
    let run = leak(record(case).unwrap().bytes);
    let o = play_run(run);
    o.result.map_err(|e| e.to_string()).unwrap();
    let mut turned = host_sim::replay::holes_at_x();
    turned.phase_deg += 2.0;
    let turned = host_sim::cut::interruptions::block_of(&turned).unwrap();
    for block in [&[][..], &turned[..]] {
        let other = leak(zslide_replay::record::with_interruptions(run, block).unwrap());
        let err = play_run(other).result.unwrap_err();
        let RunError::Mismatch(m) = err else {
            panic!("{err}");
        };
        assert_eq!(m.call, Call::LoopTick, "{m}");
        assert_eq!(m.output, Output::Frame(Dev::AmpDac), "{m}");
    }
}

/// Runs recorded shorter (`host-sim replay-record --ms`, the fuzz seeds)
/// are whole recordings of their length: each plays back bit-exact and
/// holds exactly its loop ticks (20 kHz × 2 ms = 40).
#[test]
fn a_shortened_recording_replays_bit_exact_for_its_length() {
    let cases = CASES.map(|c| Case {
        duration_ns: 2_000_000,
        ..c
    });
    let (bytes, _) = record_cases(&cases).unwrap();
    let region = leak(bytes);
    let mut n = 0;
    for (r, case) in container::runs(region).unwrap().zip(&cases) {
        let o = play_run(r.unwrap());
        assert_eq!(o.name, case.name);
        let p = o.result.map_err(|e| e.to_string()).unwrap();
        assert_eq!(p.ticks, 40, "{}", case.name);
        n += 1;
    }
    assert_eq!(n, CASES.len());
}

/// One DAC code changed in its least significant bit: the replay stops at
/// that loop tick and names the amplifier DAC, the recorded frame and the
/// firmware's.
#[test]
fn an_altered_dac_code_is_reported_at_its_tick() {
    let run = leak(record(&CASES[1]).unwrap().bytes);
    for nth in [0, 2500, 5000] {
        let (altered, a) = zslide_replay::record::alter(run, nth).unwrap();
        let err = play_run(leak(altered)).result.unwrap_err();
        let RunError::Mismatch(m) = err else {
            panic!("{err}");
        };
        assert_eq!(m.tick, a.tick);
        assert_eq!(m.call, Call::LoopTick);
        assert_eq!(m.output, Output::Frame(Dev::AmpDac));
        let (Value::Frame(e), Value::Frame(g)) = (&m.expected, &m.got) else {
            panic!("{m}");
        };
        assert_eq!((e.word, g.word), (a.altered, a.original), "{m}");
        assert_eq!(a.original ^ a.altered, 1);
    }
}

/// A recording whose bytes were damaged, or that is not there, is refused
/// before anything is played.
#[test]
fn a_damaged_or_missing_recording_is_refused() {
    let (bytes, _) = record_all().unwrap();
    let mut bad = bytes.clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x40;
    assert!(container::runs(leak(bad)).is_err());
    assert!(container::runs(&[0u8; 64]).is_err());
    assert!(container::runs(&bytes[..bytes.len() - 1]).is_err());
}
