//! The core's own hardware traits (`zslide::hw`) backed by the machine
//! models, and the links that let the scheduler deliver the models' events
//! (half-mil interrupts, index pulses) at their exact instants.
//!
//! # Time
//! The scheduler asks a source for its next event before the plant has
//! reached it, so the event-producing models run *ahead* of simulation time
//! in windows (`window_ns`) and queue what they find. Polled hardware (the
//! encoder counter, the tachometer ADC, the X quadrature counter) must still
//! answer for the instant it is read: the spindle link keeps the grid states
//! of the model between the current time and the model's own time and
//! interpolates the angle between them exactly as the model places its own
//! events (linear in angle inside a step), so an encoder count, its
//! captured edge timestamp and the index pulse's latched count agree to the
//! count. What runs ahead: a change of spindle load (sag) reaches the model
//! up to one window late (1 ms by default, against a 200 ms revolution).
//!
//! # Encoder edges and the index, as the board captures them
//! Encoder edges are not interrupts on the target: a timer in encoder mode
//! counts them, behind an input filter (`SpindleConfig::capture_delay_ns`:
//! the count read at time t is the true count at t − delay). What the edge
//! timestamp is depends on the board (`zslide::spindle::EdgeStamps`, the
//! firmware is told the same): the NUCLEO captures every edge of both
//! lines on its free-running clock (`Captured`: the stamp is
//! ⌊(t_edge + delay)·f_clock⌋, `SpindleConfig::capture_ticks`, so the
//! clock's resolution and the filter are both paid); a board without
//! capture wiring stamps a changed count with the clock at the read
//! (`AtRead`). The index is captured the same way (time on the clock,
//! count on the encoder timer, `IndexPulse`). Nothing the firmware gets
//! is earlier or finer than the board's registers.

use super::spindle::{IndexPulse, Spindle, SpindleConfig};
use super::xslide::{XInterrupt, XSlide, XSlideConfig};
use crate::chips::SimTime;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::cell::{Cell, RefCell};
use std::collections::VecDeque;
use std::rc::Rc;
use zslide::hw::{Encoder, EncoderSample, Tachometer, XLatch, XLatchWord};
use zslide::spindle::EdgeStamps;

/// Clock ticks at `t_ns` for a clock of `ticks_per_s` (wrapping at 2³²),
/// the same rounding as [`crate::chips::SimClock`].
pub fn ticks_at(t_ns: u64, ticks_per_s: u64) -> u32 {
    crate::chips::pins::clock_ticks(t_ns, ticks_per_s)
}

#[derive(Clone, Copy, Debug)]
struct Snap {
    t_ns: u64,
    turns: f64,
    rpm: f64,
    last_edge_ns: f64,
}

/// The spindle model run ahead of simulation time, with the grid states
/// needed to answer reads at any instant in between.
pub struct SpindleLink {
    model: Spindle,
    step_ns: u64,
    window_ns: u64,
    hist: VecDeque<Snap>,
    /// The grid step [a, b) that answered the last read: the next reads
    /// (several a tick, ticks 50 µs apart, steps 250 µs) mostly fall in it.
    seg: (Snap, Snap),
    pending: VecDeque<IndexPulse>,
    scratch: Vec<IndexPulse>,
    tach_rng: Xoshiro256PlusPlus,
}

impl SpindleLink {
    /// `step_ns`: the model's integration step (angle interpolated linearly
    /// inside it); `window_ns`: how far the model runs ahead per scan.
    pub fn new(cfg: SpindleConfig, step_ns: u64, window_ns: u64) -> Self {
        let tach_rng = Xoshiro256PlusPlus::seed_from_u64(cfg.seed ^ 0x7AC4_0000);
        let model = Spindle::new(cfg);
        let first = Snap {
            t_ns: 0,
            turns: model.turns(),
            rpm: model.rpm(),
            last_edge_ns: model.last_edge_ns(),
        };
        Self {
            model,
            step_ns: step_ns.max(1),
            window_ns: window_ns.max(step_ns.max(1)),
            hist: VecDeque::from([first]),
            seg: (first, first),
            pending: VecDeque::new(),
            scratch: Vec::new(),
            tach_rng,
        }
    }

    pub fn model(&self) -> &Spindle {
        &self.model
    }
    /// Speed set point and cutting load reach the model at its own time
    /// (up to one window ahead of the simulation).
    pub fn model_mut(&mut self) -> &mut Spindle {
        &mut self.model
    }

    /// Runs the model one window further, queueing index pulses in time order.
    pub fn scan(&mut self) {
        let end = self.model.time_ns() + self.window_ns;
        while self.model.time_ns() < end {
            let t = self.model.time_ns() + self.step_ns;
            self.model.advance(t, self.step_ns, &mut self.scratch);
            self.hist.push_back(Snap {
                t_ns: t,
                turns: self.model.turns(),
                rpm: self.model.rpm(),
                last_edge_ns: self.model.last_edge_ns(),
            });
        }
        // A spurious pulse is drawn after the true one of the same step.
        self.scratch.sort_by_key(|p| p.t_ns);
        self.pending.extend(self.scratch.drain(..));
    }

    /// Model time up to which pulses are known.
    pub fn scanned_to(&self) -> u64 {
        self.model.time_ns()
    }
    pub fn next_pulse(&self) -> Option<&IndexPulse> {
        self.pending.front()
    }
    pub fn pop_pulse(&mut self) -> Option<IndexPulse> {
        self.pending.pop_front()
    }

    /// The grid states around `t_ns` (scanning ahead if needed), dropping
    /// the ones no later read can need. Reads may trail the latest one by
    /// up to a model step (the loop handler reads the spindle after its
    /// event, the cut and the reports read at the event), so one step
    /// behind it is kept.
    #[inline]
    fn around(&mut self, t_ns: u64) -> (Snap, Snap) {
        let (a, b) = self.seg;
        if a.t_ns <= t_ns && t_ns < b.t_ns {
            return self.seg;
        }
        self.around_slow(t_ns)
    }

    #[inline(never)]
    fn around_slow(&mut self, t_ns: u64) -> (Snap, Snap) {
        while self.model.time_ns() < t_ns {
            self.scan();
        }
        let keep_from = t_ns.saturating_sub(self.step_ns);
        while self.hist.len() > 2 && self.hist.get(1).is_some_and(|s| s.t_ns <= keep_from) {
            self.hist.pop_front();
        }
        let i = usize::from(self.hist.len() > 2 && self.hist[1].t_ns <= t_ns);
        let a = self.hist[i];
        debug_assert!(
            a.t_ns <= t_ns,
            "spindle read at {t_ns} ns, more than a step behind an earlier read"
        );
        let b = self.hist.get(i + 1).copied().unwrap_or(a);
        self.seg = (a, b);
        (a, b)
    }

    fn cpr(&self) -> f64 {
        f64::from(self.model.config().encoder_cpr)
    }

    /// True angle (turns, not wrapped) at `t_ns`.
    pub fn turns_at(&mut self, t_ns: u64) -> f64 {
        let (a, b) = self.around(t_ns);
        if b.t_ns == a.t_ns {
            return a.turns;
        }
        let f = (t_ns - a.t_ns) as f64 / (b.t_ns - a.t_ns) as f64;
        a.turns + (b.turns - a.turns) * f
    }

    /// Speed at `t_ns`, rpm.
    pub fn rpm_at(&mut self, t_ns: u64) -> f64 {
        let (a, b) = self.around(t_ns);
        if b.t_ns == a.t_ns {
            return a.rpm;
        }
        let f = (t_ns - a.t_ns) as f64 / (b.t_ns - a.t_ns) as f64;
        a.rpm + (b.rpm - a.rpm) * f
    }

    /// The encoder's true count at `t_ns` and the exact time of the edge
    /// that made it, ns.
    pub fn encoder_at(&mut self, t_ns: u64) -> (u32, f64) {
        let (a, b) = self.around(t_ns);
        let cpr = self.cpr();
        let now = if b.t_ns == a.t_ns {
            a.turns
        } else {
            a.turns + (b.turns - a.turns) * (t_ns - a.t_ns) as f64 / (b.t_ns - a.t_ns) as f64
        };
        let count = |turns: f64| crate::fastmath::floor_i64(turns * cpr);
        let c_now = count(now);
        let edge_ns = if c_now == count(a.turns) || b.turns == a.turns {
            a.last_edge_ns
        } else {
            // The last boundary crossed, placed as the model places events.
            let edge = c_now as f64 / cpr;
            let f = ((edge - a.turns) / (b.turns - a.turns)).clamp(0.0, 1.0);
            a.t_ns as f64 + (b.t_ns - a.t_ns) as f64 * f
        };
        (c_now as u32, edge_ns)
    }

    /// The tachometer at `t_ns`: 1 mV quantisation, gain error, uniform
    /// noise of the configured RMS (its own seeded stream).
    pub fn tach_mv_at(&mut self, t_ns: u64) -> i32 {
        let rpm = self.rpm_at(t_ns);
        let c = self.model.config();
        let (k, gain, noise_rms) = (c.tach_mv_per_rpm, c.tach_gain_error, c.tach_noise_mv);
        let noise = if noise_rms > 0.0 {
            self.tach_rng.random_range(-1.0..1.0) * noise_rms * 3f64.sqrt()
        } else {
            0.0
        };
        crate::fastmath::round_i32(rpm * k * (1.0 + gain) + noise)
    }
}

/// Shared handle on the spindle link (the index source and the polled
/// devices read the same model).
pub type SharedSpindle = Rc<RefCell<SpindleLink>>;

/// `zslide::hw::Encoder` for the spindle encoder, read at simulation time
/// (the loop handler's read instant), as the board presents it: the
/// counter behind the input filter (the count `capture_delay_ns` late), and
/// either every edge captured on the clock (`Captured`: the NUCLEO's TIM2
/// CH3/CH4 on both edges of A and B) or a change stamped with the clock at
/// the read (`AtRead`: a board without capture wiring).
#[derive(Clone)]
pub struct SimSpindleEncoder {
    pub link: SharedSpindle,
    pub time: SimTime,
    pub edges: EdgeStamps,
    /// The last sample (for `AtRead`: a count seen again keeps its stamp).
    pub last: Option<EncoderSample>,
}

impl Encoder for SimSpindleEncoder {
    fn sample(&mut self) -> EncoderSample {
        let t = self.time.get();
        let mut link = self.link.borrow_mut();
        let cfg = link.model().config();
        let (delay, tps) = (cfg.capture_delay_ns, cfg.ticks_per_s);
        let (count, edge_ns) = link.encoder_at(t.saturating_sub(delay));
        match self.edges {
            EdgeStamps::Captured => EncoderSample {
                count,
                edge_ticks: link.model().config().capture_ticks(edge_ns),
            },
            EdgeStamps::AtRead => match self.last {
                Some(l) if l.count == count => l,
                _ => {
                    let l = EncoderSample {
                        count,
                        edge_ticks: ticks_at(t, tps as u64),
                    };
                    self.last = Some(l);
                    l
                }
            },
        }
    }
}

/// `zslide::hw::Tachometer`, read at simulation time.
#[derive(Clone)]
pub struct SimTachometer {
    pub link: SharedSpindle,
    pub time: SimTime,
}

impl Tachometer for SimTachometer {
    fn millivolts(&mut self) -> i32 {
        self.link.borrow_mut().tach_mv_at(self.time.get())
    }
}

/// `zslide::hw::XLatch`: the BCD latch register, loaded by the half-mil
/// interrupt's edge ([`XHalfMilLink`] writes it just before the handler).
#[derive(Clone, Default)]
pub struct SimXLatch(pub Rc<Cell<XLatchWord>>);

impl XLatch for SimXLatch {
    fn read(&mut self) -> XLatchWord {
        self.0.get()
    }
}

/// The X slide's BCD chain run ahead in windows, its half-mil interrupts
/// queued with their latched words (false interrupts and ripple glitches
/// included, as the model produces them).
pub struct XHalfMilLink {
    model: XSlide,
    step_ns: u64,
    window_ns: u64,
    pending: VecDeque<XInterrupt>,
    scratch: Vec<XInterrupt>,
    pub latch: SimXLatch,
}

impl XHalfMilLink {
    pub fn new(cfg: XSlideConfig, step_ns: u64, window_ns: u64) -> Self {
        Self {
            model: XSlide::new(cfg),
            step_ns: step_ns.max(1),
            window_ns: window_ns.max(step_ns.max(1)),
            pending: VecDeque::new(),
            scratch: Vec::new(),
            latch: SimXLatch::default(),
        }
    }
    pub fn model(&self) -> &XSlide {
        &self.model
    }
    pub fn scan(&mut self) {
        let end = self.model.time_ns() + self.window_ns;
        self.model.advance(end, self.step_ns, &mut self.scratch);
        self.pending.extend(self.scratch.drain(..));
    }
    pub fn scanned_to(&self) -> u64 {
        self.model.time_ns()
    }
    pub fn next_interrupt(&self) -> Option<&XInterrupt> {
        self.pending.front()
    }
    /// Takes the interrupt due now and loads the latch with its word.
    pub fn take(&mut self) -> Option<XInterrupt> {
        let i = self.pending.pop_front()?;
        self.latch.0.set(i.word);
        Some(i)
    }
}

/// `zslide::hw::Encoder` for the modern X: the interferometer's up/down
/// count (1 µin per count) as a quadrature counter, read at simulation time.
/// The model is advanced to the read instant (it produces no events); the
/// captured edge time is the end of the model step in which the count last
/// changed (within `step_ns` of the true edge).
pub struct SimXQuadrature {
    model: XSlide,
    step_ns: u64,
    time: SimTime,
    ticks_per_s: u64,
    last_count: i64,
    edge_ticks: u32,
    scratch: Vec<XInterrupt>,
}

impl SimXQuadrature {
    pub fn new(cfg: XSlideConfig, step_ns: u64, time: SimTime, ticks_per_s: u64) -> Self {
        let model = XSlide::new(cfg);
        Self {
            last_count: model.count(),
            model,
            step_ns: step_ns.max(1),
            time,
            ticks_per_s,
            edge_ticks: 0,
            scratch: Vec::new(),
        }
    }
    pub fn model(&self) -> &XSlide {
        &self.model
    }
}

impl Encoder for SimXQuadrature {
    fn sample(&mut self) -> EncoderSample {
        let now = self.time.get();
        while self.model.time_ns() < now {
            let t = (self.model.time_ns() + self.step_ns).min(now);
            self.model.advance(t, self.step_ns, &mut self.scratch);
            if self.model.count() != self.last_count {
                self.last_count = self.model.count();
                self.edge_ticks = ticks_at(t, self.ticks_per_s);
            }
        }
        self.scratch.clear();
        EncoderSample {
            count: self.model.count() as u32,
            edge_ticks: self.edge_ticks,
        }
    }
}
