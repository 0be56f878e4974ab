//! The simulated converters decode hand-written frames of the formats in
//! `notes/COMMON.md` (written here from the datasheet-level description,
//! independently of any driver), and inject bus errors.

use embedded_hal::digital::OutputPin;
use embedded_hal::spi::{Operation, SpiDevice};
use host_sim::chips::{BusFault, SimAd4020, SimAd5686, SimAd5791, SimSpiError};
use std::cell::Cell;
use std::rc::Rc;

fn w24(w: u32) -> [u8; 3] {
    [(w >> 16) as u8, (w >> 8) as u8, w as u8]
}

fn dac() -> SimAd5791 {
    SimAd5791::new(Rc::new(Cell::new(0)))
}

#[test]
fn ad5791_power_on_clamped_then_twos_complement_output() {
    let mut d = dac();
    // DAC register write (R/W=0, reg 001) of +2^18: still clamped to ground
    d.write(&w24(0x1_40000)).unwrap();
    assert_eq!(d.state.borrow().output_volts(), 0.0);
    // control register (010): RBUF=1, OPGND=0, DACTRI=0, BIN/2sC=0
    d.write(&w24(0x2_00002)).unwrap();
    assert_eq!(d.state.borrow().output_volts(), 5.0);
    // −1 LSB = 0xFFFFF
    d.write(&w24(0x1_FFFFF)).unwrap();
    let v = d.state.borrow().output_volts();
    assert!((v + 10.0 / 524288.0).abs() < 1e-15, "{v}");
    // most negative code 0x80000 = −10 V, most positive 0x7FFFF
    d.write(&w24(0x1_80000)).unwrap();
    assert_eq!(d.state.borrow().output_volts(), -10.0);
    d.write(&w24(0x1_7FFFF)).unwrap();
    assert!((d.state.borrow().output_volts() - 10.0 * 524287.0 / 524288.0).abs() < 1e-15);
    // OPGND back on: clamped
    d.write(&w24(0x2_00004)).unwrap();
    assert_eq!(d.state.borrow().output_volts(), 0.0);
}

#[test]
fn ad5791_offset_binary_clearcode_reset_and_readback() {
    let mut d = dac();
    d.write(&w24(0x2_00012)).unwrap(); // BIN/2sC = 1: offset binary
    d.write(&w24(0x1_C0000)).unwrap(); // 0xC0000 − 2^19 = +2^18
    assert_eq!(d.state.borrow().output_volts(), 5.0);
    d.write(&w24(0x2_00002)).unwrap(); // back to two's complement
                                       // clearcode (011) = 0x20000 (+2.5 V); CLR via software control (100) bit 1
    d.write(&w24(0x3_20000)).unwrap();
    d.write(&w24(0x4_00002)).unwrap();
    assert_eq!(d.state.borrow().output_volts(), 2.5);
    // read control register: 1 010 ... then any frame clocks it out
    d.write(&w24(0xA0_0000)).unwrap();
    let mut r = w24(0x00_0000);
    d.transfer_in_place(&mut r).unwrap();
    assert_eq!(r, w24(0xA0_0002));
    // read DAC register
    d.write(&w24(0x90_0000)).unwrap();
    let mut r = [0u8; 3];
    d.read(&mut r).unwrap();
    assert_eq!(r, w24(0x92_0000));
    // software RESET (bit 2): power-on state, output clamped
    d.write(&w24(0x4_00004)).unwrap();
    let s = d.state.borrow();
    assert_eq!((s.ctrl, s.dac, s.output_volts()), (0b1100, 0, 0.0));
}

#[test]
fn ad5791_short_frame_ignored_and_output_changes_timestamped() {
    let t = Rc::new(Cell::new(1_000));
    let mut d = SimAd5791::new(t.clone());
    d.state.borrow_mut().latency_ns = 250;
    d.write(&w24(0x2_00002)).unwrap();
    d.write(&[0x14, 0x00]).unwrap(); // 16 bits: aborted
    assert_eq!(d.state.borrow().bad_frames, 1);
    t.set(5_000);
    // a frame split over two operations is still one frame
    d.transaction(&mut [Operation::Write(&[0x14]), Operation::Write(&[0x00, 0x00])])
        .unwrap();
    let s = d.state.borrow();
    assert_eq!(s.output_volts(), 5.0);
    assert_eq!(s.changes.back(), Some(&(5_250, 5.0)));
}

#[test]
fn ad5791_bus_errors() {
    let mut d = dac();
    d.write(&w24(0x2_00002)).unwrap();
    d.state.borrow_mut().faults.inject(BusFault::Error, 2);
    assert_eq!(d.write(&w24(0x1_40000)), Err(SimSpiError));
    assert_eq!(d.write(&w24(0x1_40000)), Err(SimSpiError));
    assert_eq!(
        d.state.borrow().output_volts(),
        0.0,
        "failed frames change nothing"
    );
    // silently dropped frame: Ok, but the write is lost
    d.state.borrow_mut().faults.inject(BusFault::Drop, 1);
    d.write(&w24(0x1_40000)).unwrap();
    assert_eq!(d.state.borrow().output_volts(), 0.0);
    // MOSI bit flip in the data: bit 19 turns +2^18 into a negative code
    d.state
        .borrow_mut()
        .faults
        .inject(BusFault::FlipMosi(19), 1);
    d.write(&w24(0x1_40000)).unwrap();
    assert_eq!(d.state.borrow().output_volts(), -5.0);
    d.write(&w24(0x1_40000)).unwrap();
    assert_eq!(d.state.borrow().output_volts(), 5.0);
    assert_eq!(d.state.borrow().faults.injected, 4);
}

#[test]
fn ad4020_frames_scale_overrange_and_pattern() {
    let mut a = SimAd4020::new();
    let read = |a: &mut SimAd4020| {
        let mut b = [0u8; 3];
        a.read(&mut b).unwrap();
        (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2])
    };
    a.state.borrow_mut().convert(5.0);
    assert_eq!(read(&mut a), (262_144 << 4) | 0b010);
    // −1 LSB (19.07 µV) → 0xFFFFF
    a.state.borrow_mut().convert(-10.0 / 524_288.0);
    assert_eq!(read(&mut a), (0xF_FFFF << 4) | 0b010);
    // 1 µV rounds to 0
    a.state.borrow_mut().convert(1e-6);
    assert_eq!(read(&mut a), 0b010);
    // full scale and beyond: clamped, OV set
    a.state.borrow_mut().convert(12.0);
    assert_eq!(read(&mut a), (0x7_FFFF << 4) | 0b1010);
    a.state.borrow_mut().convert(-10.0);
    assert_eq!(read(&mut a), (0x8_0000 << 4) | 0b1010);
    // a re-read returns the same conversion
    assert_eq!(read(&mut a), (0x8_0000 << 4) | 0b1010);
    assert_eq!(a.state.borrow().conversions, 5);
}

#[test]
fn ad4020_stuck_bus_fails_the_pattern() {
    let mut a = SimAd4020::new();
    a.state.borrow_mut().convert(1.0);
    a.state.borrow_mut().faults.inject(BusFault::StuckHigh, 1);
    a.state.borrow_mut().faults.inject(BusFault::StuckLow, 1);
    let mut b = [0u8; 3];
    a.read(&mut b).unwrap();
    assert_eq!(b, [0xFF; 3]);
    assert_ne!(b[2] & 0b111, 0b010);
    a.read(&mut b).unwrap();
    assert_eq!(b, [0; 3]);
    assert_ne!(b[2] & 0b111, 0b010);
    a.read(&mut b).unwrap();
    assert_eq!(b[2] & 0b111, 0b010);
    // random injection is seeded: the same seed fails the same reads
    let pattern = |seed| {
        let mut a = SimAd4020::new();
        a.state
            .borrow_mut()
            .faults
            .random(seed, 0.3, BusFault::Error);
        (0..64)
            .map(|_| a.read(&mut [0u8; 3]).is_err())
            .collect::<Vec<_>>()
    };
    assert_eq!(pattern(3), pattern(3));
    assert_ne!(pattern(3), pattern(4));
    let n = pattern(3).iter().filter(|e| **e).count();
    assert!((8..=32).contains(&n), "{n} of 64 at p = 0.3");
}

#[test]
fn ad5686_input_registers_ldac_strobe_and_scaling() {
    let mut q = SimAd5686::new();
    let mut ldac = q.ldac_pin();
    // mid-scale = 0 V at power-on
    assert_eq!(q.state.borrow().volts(0), 0.0);
    // Table 3-1: C00 = +0.001 in → 32768 + round(0.001 · 65536 / 0.020) = 36045
    let code = 32768 + (0.001f64 * 65536.0 / 0.020).round() as u32;
    assert_eq!(code, 36045);
    q.write(&w24((0b0001 << 20) | (0b0001 << 16) | code))
        .unwrap(); // A input
    q.write(&w24((0b0001 << 20) | (0b1000 << 16) | 0x4000))
        .unwrap(); // D input
    assert_eq!(q.state.borrow().volts(0), 0.0, "input register only");
    ldac.set_low().unwrap();
    ldac.set_high().unwrap();
    let s = q.state.borrow();
    assert!((s.volts(0) - (20.0 * 36045.0 / 65536.0 - 10.0)).abs() < 1e-12);
    assert_eq!(s.volts(3), -5.0);
    assert_eq!(s.strobes, 1);
    drop(s);
    // write-and-update to B and C at once
    q.write(&w24((0b0011 << 20) | (0b0110 << 16) | 0xC000))
        .unwrap();
    assert_eq!(
        (q.state.borrow().volts(1), q.state.borrow().volts(2)),
        (5.0, 5.0)
    );
    // update-from-input (0010) for A only after a new input write
    q.write(&w24((0b0001 << 20) | (0b0001 << 16))).unwrap();
    assert!(q.state.borrow().volts(0) > 0.0);
    q.write(&w24((0b0010 << 20) | (0b0001 << 16))).unwrap();
    assert_eq!(q.state.borrow().volts(0), -10.0);
    // LDAC held low: input writes go straight through
    ldac.set_low().unwrap();
    q.write(&w24((0b0001 << 20) | (0b0100 << 16) | 0x8000))
        .unwrap();
    assert_eq!(q.state.borrow().volts(2), 0.0);
    ldac.set_high().unwrap();
    // bus error: nothing written
    q.state.borrow_mut().faults.inject(BusFault::Error, 1);
    assert!(q
        .write(&w24((0b0011 << 20) | (0b0001 << 16) | 0xFFFF))
        .is_err());
    assert_eq!(q.state.borrow().volts(0), -10.0);
    // software reset (0110): everything mid-scale
    q.write(&w24(0b0110 << 20)).unwrap();
    assert!((0..4).all(|k| q.state.borrow().volts(k) == 0.0));
}
