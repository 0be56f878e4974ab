//! Timers: the loop tick with the gauge's conversion start, the hardware
//! clock, the defmt timestamp, and the independent watchdog.
//!
//! | timer | clock | use |
//! |---|---|---|
//! | TIM3 | 200 MHz, ARR = 200 MHz / [`LOOP_HZ`] − 1 | loop period; CH1 PWM = gauge CNV pulse on PC6, high for [`CNV_HIGH_TICKS`] from each update; CH2 compare at [`READ_AT_TICKS`] raises the loop-tick interrupt |
//! | TIM2 | 200 MHz, free-running 32 bit | `hw::Clock` (5 ns ticks, wraps every 21.5 s); input captures of the spindle index (CH1) and of every encoder edge (CH3/CH4), [`start_captures`] |
//! | TIM4 | encoder mode 3 | spindle count; CH3 captures it at the index |
//! | TIM5 | 1 MHz, free-running 32 bit | defmt timestamp, µs (wraps every 71.6 min) |
//! | IWDG1 | LSI 32 kHz / 4 | 5 ms watchdog, refreshed by the background when the loop tick ran (`zslide::watchdog`) |
//!
//! The AD4020 converts on CNV's rising edge (t_CONV ≤ 320 ns) and, in its
//! three-wire mode with SDI high, puts its result on SDO once CNV falls; so
//! the interrupt comes after CNV has fallen, and the sample instant is fixed
//! by hardware, free of interrupt-latency jitter.

use stm32h7::stm32h743v::{DBGMCU, IWDG, TIM2, TIM3, TIM4, TIM5};

use super::clocks::APB1_TIMER_HZ;

/// Loop-tick rate, Hz (≥ 20 kHz per the brief). Must divide 200 MHz into
/// at most 65 536 timer counts (≥ 3052 Hz).
pub const LOOP_HZ: u32 = 20_000;
const LOOP_ARR: u32 = APB1_TIMER_HZ / LOOP_HZ - 1;
const _: () = assert!(LOOP_ARR <= 0xFFFF && LOOP_ARR > 2 * READ_AT_TICKS);
/// CNV high time after each update: 1 µs (≥ t_CONV of 320 ns).
pub const CNV_HIGH_TICKS: u32 = 200;
/// Loop interrupt 100 ns after CNV falls.
pub const READ_AT_TICKS: u32 = 220;
/// Rate of [`now_ticks`].
pub const CLOCK_HZ: u32 = APB1_TIMER_HZ;

const SR_CC2IF: u32 = 1 << 2;

/// Starts TIM2 (hardware clock) and TIM5 (timestamp), free-running.
pub fn start_free_running(tim2: &TIM2, tim5: &TIM5) {
    // SAFETY: PSC/ARR/EGR/CR1 of two timers owned by this module: prescaler
    // (n − 1), full 32-bit period, an update event to load the prescaler,
    // then count enable.
    unsafe {
        tim2.psc().write(|w| w.bits(0));
        tim2.arr().write(|w| w.bits(u32::MAX));
        tim2.egr().write(|w| w.bits(1));
        tim2.cr1().write(|w| w.bits(1));
        tim5.psc().write(|w| w.bits(APB1_TIMER_HZ / 1_000_000 - 1));
        tim5.arr().write(|w| w.bits(u32::MAX));
        tim5.egr().write(|w| w.bits(1));
        tim5.cr1().write(|w| w.bits(1));
    }
}

/// TIM2's count (read-only register, so any context may call this).
pub fn now_ticks() -> u32 {
    // SAFETY: reading TIM2_CNT has no side effect.
    unsafe { (*TIM2::ptr()).cnt().read().bits() }
}

/// TIM5's count in µs.
pub fn micros() -> u32 {
    // SAFETY: reading TIM5_CNT has no side effect.
    unsafe { (*TIM5::ptr()).cnt().read().bits() }
}

/// Configures TIM3 for the loop tick at [`LOOP_HZ`] and starts it (the
/// NVIC line stays masked until `main` unmasks it).
pub fn start_loop_timer(tim3: &TIM3) {
    start_loop_timer_at(tim3, LOOP_HZ);
}

/// The same at `hz` (≥ 3052 Hz, dividing 200 MHz: the centring tick runs
/// at 10 kHz).
pub fn start_loop_timer_at(tim3: &TIM3, hz: u32) {
    let arr = (APB1_TIMER_HZ / hz.max(3_052) - 1).clamp(2 * READ_AT_TICKS + 1, 0xFFFF);
    // SAFETY: raw values into TIM3, which only this function and the loop
    // handler touch: CCMR1 OC1M = PWM mode 1 with preload (bits 6..4 = 110,
    // bit 3), CC2 as frozen output compare (its flag is the interrupt);
    // CCER CC1E; DIER CC2IE; CR1 ARPE | CEN.
    unsafe {
        tim3.cr1().write(|w| w.bits(0));
        tim3.psc().write(|w| w.bits(0));
        tim3.arr().write(|w| w.bits(arr));
        tim3.ccmr1_output()
            .write(|w| w.bits((0b110 << 4) | (1 << 3)));
        tim3.ccr1().write(|w| w.bits(CNV_HIGH_TICKS));
        tim3.ccr2().write(|w| w.bits(READ_AT_TICKS));
        tim3.ccer().write(|w| w.bits(1));
        tim3.egr().write(|w| w.bits(1));
        tim3.sr().write(|w| w.bits(0));
        tim3.dier().write(|w| w.bits(SR_CC2IF));
        tim3.cr1().write(|w| w.bits((1 << 7) | 1));
    }
}

/// Acknowledges the loop-tick interrupt (TIM3 CC2IF, write-0-to-clear).
pub fn ack_loop_tick() {
    // SAFETY: writing 0 to CC2IF and 1 to every other rc_w0 flag clears
    // exactly CC2IF; the loop handler is the only user of TIM3 SR.
    unsafe { (*TIM3::ptr()).sr().write(|w| w.bits(!SR_CC2IF)) };
}

/// Starts IWDG1 with a 5 ms timeout; frozen while a debugger halts the core.
///
/// 5 ms, not longer: until the reset the amplifier is driven by the DAC
/// code the stalled loop left, and the tool drifts into the part with the
/// part's 2/rev surface (docs/SAFETY.md, "Fault campaign": worst of a
/// sweep over the stall instant 272 µin at 10 ms, 155 µin at 5 ms, for a
/// 300 µin depth of cut). Not shorter than the background's longest pass
/// allows with margin: a parameter design inside a station poll, under
/// 1 ms with the handlers' load (docs/BOARD.md's `servo_design` and
/// `station_poll` rows, `cargo xtask isr-cost`).
pub fn start_watchdog(iwdg: &IWDG, dbgmcu: &DBGMCU) {
    // SAFETY: DBGMCU_APB4FZ1 bit 18 (DBG_IWDG1) only affects debug halts.
    // IWDG key sequence of RM0433 §45.3: start, unlock, prescaler /4
    // (PR = 0), reload 39 (`watchdog::IWDG_RELOAD`: 40 counts of 125 µs),
    // wait for the update, reload.
    unsafe {
        dbgmcu.apb4fz1().modify(|r, w| w.bits(r.bits() | (1 << 18)));
        iwdg.kr().write(|w| w.bits(0xCCCC));
        iwdg.kr().write(|w| w.bits(0x5555));
        iwdg.pr().write(|w| w.bits(0));
        iwdg.rlr().write(|w| w.bits(zslide::watchdog::IWDG_RELOAD));
        while iwdg.sr().read().bits() != 0 {}
        iwdg.kr().write(|w| w.bits(0xAAAA));
    }
}

/// Reloads the watchdog (from the background, through `zslide::watchdog::FeedGate`).
pub fn feed_watchdog() {
    // SAFETY: 0xAAAA into IWDG_KR only reloads the counter.
    unsafe { (*IWDG::ptr()).kr().write(|w| w.bits(0xAAAA)) };
}

/// Starts TIM4 as the spindle encoder's quadrature counter (CH1/CH2 on
/// PD12/PD13): both edges of both channels (×4), 16 bits, free-running.
pub fn start_spindle_encoder(tim4: &TIM4) {
    // SAFETY: raw values into TIM4, which only this module reads: CCMR1
    // CC1S = 01, CC2S = 01 (inputs TI1, TI2), IC1F = IC2F = 0011 (8-sample
    // filter against edge noise); SMCR SMS = 011 (encoder mode 3); full
    // 16-bit period; CEN.
    unsafe {
        tim4.cr1().write(|w| w.bits(0));
        tim4.ccmr1_input()
            .write(|w| w.bits(0b01 | (0b0011 << 4) | (0b01 << 8) | (0b0011 << 12)));
        tim4.smcr().write(|w| w.bits(0b011));
        tim4.arr().write(|w| w.bits(0xFFFF));
        tim4.cnt().write(|w| w.bits(0));
        tim4.cr1().write(|w| w.bits(1));
    }
}

/// TIM4's 16-bit count (read-only use, any context).
pub fn spindle_count16() -> u16 {
    // SAFETY: reading TIM4_CNT has no side effect.
    unsafe { (*TIM4::ptr()).cnt().read().bits() as u16 }
}

/// Configures TIM2's input captures (TIM2 already runs as the clock) and
/// TIM4's index-count capture, all behind the same 8-sample input filter
/// as the encoder inputs (IC filter 0011 at 200 MHz: the count and its
/// captures change at the same filtered edge, ≈ 50 ns after the pin):
///
/// | channel | pin | edges | captures |
/// |---|---|---|---|
/// | TIM2 CH1 | PA0, index | rising, interrupt (CC1IE) | the index's time |
/// | TIM2 CH3 | PB10, encoder A | both | time of A's every edge |
/// | TIM2 CH4 | PB11, encoder B | both | time of B's every edge |
/// | TIM4 CH3 | PB8, index | rising | the encoder count at the index |
///
/// Each edge of A or B is one count of the ×4 decoder, so CH3 and CH4
/// together stamp every count.
pub fn start_captures(tim2: &TIM2, tim4: &TIM4) {
    // SAFETY: raw values into capture registers only this module reads.
    // CCMRx input layout: CCyS (bits 1..0 / 9..8) = 01 (ICy on TIy),
    // ICyF (bits 7..4 / 15..12) = 0011. CCER: CC1E (bit 0) rising;
    // CC3E|CC3P|CC3NP (bits 8, 9, 11) and CC4E|CC4P|CC4NP (12, 13, 15) both
    // edges. DIER CC1IE (bit 1). TIM4 CCER CC3E (bit 8) rising; its
    // encoder inputs CH1/CH2 keep their polarity bits at 0 (non-inverted).
    // The CCyS fields are written while the channels are disabled.
    unsafe {
        tim2.ccmr1_input().write(|w| w.bits(0b01 | (0b0011 << 4)));
        tim2.ccmr2_input()
            .write(|w| w.bits(0b01 | (0b0011 << 4) | (0b01 << 8) | (0b0011 << 12)));
        tim2.ccer().write(|w| {
            w.bits(1 | (1 << 8) | (1 << 9) | (1 << 11) | (1 << 12) | (1 << 13) | (1 << 15))
        });
        tim2.dier().write(|w| w.bits(SR_CC1IF));
        tim4.ccmr2_input().write(|w| w.bits(0b01 | (0b0011 << 4)));
        tim4.ccer().write(|w| w.bits(1 << 8));
    }
}

const SR_CC1IF: u32 = 1 << 1;
const SR_CC3IF: u32 = 1 << 3;
const SR_CC4IF: u32 = 1 << 4;

/// The newer of two stamps taken within half a clock wrap of each other.
fn newer(a: Option<u32>, b: u32) -> Option<u32> {
    match a {
        Some(a) if (b.wrapping_sub(a) as i32) < 0 => Some(a),
        _ => Some(b),
    }
}

/// The spindle encoder as `hw::Encoder`, owned by the loop tick: TIM4's
/// 16-bit count extended to 32 bits (the tick samples it far more often
/// than every 32 768 counts), and the captured time of the edge that made
/// the last count change (TIM2 CH3/CH4: `EdgeStamps::Captured`).
pub struct SpindleEncoder {
    count: u32,
    edge: u32,
}

/// The loop tick's extended count, for the index handler (its low 16 bits
/// are TIM4's count at that tick, by construction).
pub static SPINDLE_COUNT: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

impl SpindleEncoder {
    pub fn new() -> Self {
        let count = u32::from(spindle_count16());
        SPINDLE_COUNT.store(count, core::sync::atomic::Ordering::Relaxed);
        Self {
            count,
            edge: now_ticks(),
        }
    }
}

impl zslide::hw::Encoder for SpindleEncoder {
    fn sample(&mut self) -> zslide::hw::EncoderSample {
        // SAFETY: TIM2's SR is only read here and in the index handler
        // (never written: each flag is cleared by reading its CCR), and
        // CCR3/CCR4 are read only here.
        let tim2 = unsafe { &*TIM2::ptr() };
        let mut raw = spindle_count16();
        let mut stamp = None;
        // The captures are read between two reads of the count until the
        // count holds still, so the newest stamp belongs to the edge that
        // made the count read (an edge between the reads is stamped and
        // counted on the next pass). Edges are ≥ 12 µs apart at 1200 rpm
        // and 4096 counts a turn and a pass takes ≈ 50 ns: one retry
        // suffices; three bound the handler.
        for _ in 0..3 {
            let sr = tim2.sr().read().bits();
            if sr & SR_CC3IF != 0 {
                stamp = newer(stamp, tim2.ccr3().read().bits());
            }
            if sr & SR_CC4IF != 0 {
                stamp = newer(stamp, tim2.ccr4().read().bits());
            }
            let again = spindle_count16();
            if again == raw {
                break;
            }
            raw = again;
        }
        let step = raw.wrapping_sub(self.count as u16) as i16;
        if step != 0 {
            self.count = self.count.wrapping_add(step as i32 as u32);
            // A count change comes with its capture (same filter, same
            // clock); should one ever be missing, the read time is a
            // bounded stand-in (late by less than a loop period).
            self.edge = stamp.unwrap_or_else(now_ticks);
            SPINDLE_COUNT.store(self.count, core::sync::atomic::Ordering::Relaxed);
        }
        zslide::hw::EncoderSample {
            count: self.count,
            edge_ticks: self.edge,
        }
    }
}

/// The index capture, for its interrupt (TIM2 CC1): the edge's time and
/// the encoder count at the edge, extended to 32 bits consistently with
/// the loop tick's [`SpindleEncoder`]; `None` when no index was captured
/// (a spurious entry).
pub fn index_capture() -> Option<(u32, u32)> {
    // SAFETY: TIM2 SR is read-only here; CCR1 (whose read clears CC1IF and
    // with it the interrupt request) and TIM4 CCR3 are read only here.
    let (tim2, tim4) = unsafe { (&*TIM2::ptr(), &*TIM4::ptr()) };
    if tim2.sr().read().bits() & SR_CC1IF == 0 {
        return None;
    }
    let edge = tim2.ccr1().read().bits();
    let count16 = tim4.ccr3().read().bits() as u16;
    let base = SPINDLE_COUNT.load(core::sync::atomic::Ordering::Relaxed);
    let step = count16.wrapping_sub(base as u16) as i16;
    Some((edge, base.wrapping_add(step as i32 as u32)))
}
