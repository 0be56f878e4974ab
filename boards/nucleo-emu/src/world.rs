//! The machine around the board: the project's one plant model
//! (`zslide-plant`: slide, motor, amplifier, gauge, as host-sim and the
//! QEMU image use it) driven by the AD5791's output and the enable pin,
//! converted by the AD4020 at each CNV; the spindle (encoder and index)
//! and the legacy X feed of the QEMU image's script
//! (`boards/qemu/src/scenario.rs`: 1200 rpm, 4096 counts a turn, the
//! first index at count 300; one half-mil every 1.5 ms from 2.0000 in,
//! a reversal at event 60, duplicates); the arm button.

use zslide_plant::slide::st;
use zslide_plant::{gauge, Amplifier, AmplifierParams, Gauge, GaugeParams, ZSlide, ZSlideParams};

pub const PS_PER_S: u64 = 1_000_000_000_000;

/// Spindle: counts a second (1200 rpm × 4096 / 60), counts a turn, the
/// count of the first index.
pub const COUNTS_PER_S: u64 = 1_200 * 4_096 / 60;
pub const CPR: u64 = 4_096;
pub const INDEX0: u64 = 300;
/// X feed: the first event, the interval, the start in half-mils.
pub const X_FIRST_PS: u64 = 10 * 50_000_000;
pub const X_EVERY_PS: u64 = 30 * 50_000_000;
pub const X_START_HM: u32 = 4_000;
const REVERSAL: u32 = 60;
const DUPLICATES: [u32; 4] = [15, 45, 75, 105];
/// The repeated latch of a duplicate, after its event.
const DUPLICATE_AFTER_PS: u64 = 1_000_000;
/// The slide at power-up, in (gauge code −52 429, as the QEMU image).
const START_IN: f64 = -0.001;
const SEED: u64 = 1983;

pub struct World {
    slide: ZSlide,
    amp: Amplifier,
    gauge: Gauge,
    t_ps: u64,
    v_in: f64,
    /// The next X event (by number) and whether its duplicate is due.
    next_x: u32,
    dup_due: Option<u64>,
    pub x_events: u32,
    /// When the arm button is held (ps).
    pub button: Vec<(u64, u64)>,
}

impl World {
    pub fn new() -> Self {
        let mut slide = ZSlide::new(ZSlideParams::model15());
        slide.x[st::Z] = START_IN;
        Self {
            slide,
            amp: Amplifier::new(AmplifierParams::default()),
            gauge: Gauge::new(GaugeParams::modern(), SEED),
            t_ps: 0,
            v_in: 0.0,
            next_x: 0,
            dup_due: None,
            x_events: 0,
            button: Vec::new(),
        }
    }

    /// The plant to `t` with the amplifier input and enable held since
    /// the last call, then the new ones.
    pub fn advance(&mut self, t: u64, v_in: f64, enabled: bool) {
        if t > self.t_ps {
            let dt_ns = (t - self.t_ps) / 1_000;
            self.amp.advance(&mut self.slide, dt_ns, self.v_in, 0.0);
            self.t_ps += dt_ns * 1_000;
        }
        self.v_in = v_in;
        if enabled != self.amp.enabled() {
            self.amp.set_enabled(enabled);
        }
    }

    /// The gauge converted at `t` (the plant advanced there first).
    pub fn convert(&mut self) -> (i32, bool) {
        let v = self
            .gauge
            .volts(self.t_ps / 1_000, self.slide.gauge_position_in());
        gauge::adc_convert(v)
    }

    pub fn position_in(&self) -> f64 {
        self.slide.gauge_position_in()
    }
    pub fn amp_fault(&self) -> bool {
        self.amp.tripped()
    }

    pub fn button_at(&self, t: u64) -> bool {
        self.button.iter().any(|&(a, b)| a <= t && t < b)
    }

    /// The spindle's count at `t` and the time of the edge that made it.
    pub fn spindle(t: u64) -> (u64, u64) {
        let c = (u128::from(t) * u128::from(COUNTS_PER_S) / u128::from(PS_PER_S)) as u64;
        (c, Self::edge_of(c))
    }
    pub fn edge_of(c: u64) -> u64 {
        (u128::from(c) * u128::from(PS_PER_S)).div_ceil(u128::from(COUNTS_PER_S)) as u64
    }
    /// The newest edge ≤ `t` of channel A (even counts) or B (odd), as
    /// (its count, its time).
    pub fn last_edge(t: u64, b: bool) -> Option<(u64, u64)> {
        let (c, _) = Self::spindle(t);
        let c = if (c % 2 == 1) == b {
            c
        } else {
            c.checked_sub(1)?
        };
        Some((c, Self::edge_of(c)))
    }
    /// The first index edge after `t`: (its count, its time).
    pub fn next_index(t: u64) -> (u64, u64) {
        let (c, _) = Self::spindle(t);
        let k = if c < INDEX0 {
            0
        } else {
            (c - INDEX0) / CPR + 1
        };
        let ci = INDEX0 + k * CPR;
        (ci, Self::edge_of(ci))
    }

    /// The next X event at or after now: (time, latch word).
    pub fn next_x(&self) -> (u64, u32) {
        if let Some(t) = self.dup_due {
            return (t, latch_word(x_script(self.next_x - 1)));
        }
        (
            X_FIRST_PS + X_EVERY_PS * u64::from(self.next_x),
            latch_word(x_script(self.next_x)),
        )
    }
    pub fn took_x(&mut self) {
        self.x_events += 1;
        if self.dup_due.take().is_some() {
            return;
        }
        let i = self.next_x;
        self.next_x += 1;
        if DUPLICATES.contains(&i) {
            self.dup_due = Some(X_FIRST_PS + X_EVERY_PS * u64::from(i) + DUPLICATE_AFTER_PS);
        }
    }
}

/// Half-mil position of X event `i`.
fn x_script(i: u32) -> u32 {
    if i < REVERSAL {
        X_START_HM + i
    } else {
        X_START_HM + i - 2
    }
}

/// The legacy latch's word for a position in half-mils (`src/hw.rs`,
/// `XLatch`: four BCD digits of mils, the half-mil and mil-zero flags).
pub fn latch_word(hm: u32) -> u32 {
    let mils = hm / 2;
    let d = |k: u32| (mils / 10u32.pow(k)) % 10;
    let mut w = d(0) | (d(1) << 4) | (d(2) << 8) | (d(3) << 12);
    if hm % 2 == 1 {
        w |= 1 << 16;
    }
    if d(0) == 0 {
        w |= 1 << 17;
    }
    w
}
