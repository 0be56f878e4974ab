//! The rig: plant, amplifier and gauge behind the simulated chips.
//!
//! The firmware's drivers own the chip handles ([`Rig::devices`]); the rig
//! keeps clones of the same shared state. Time only moves in
//! [`Rig::advance_to`], which steps the linear plant exactly from one input
//! change to the next: DAC output changes (at the DAC frame end plus the
//! configured latency) and enable-line edges are applied at their own
//! instants, the cutting force when the caller sets it. The gauge ADC
//! converts when the loop timer fires ([`Rig::cnv`]).

use super::amplifier::{Amplifier, AmplifierParams};
use super::gauge::{Gauge, GaugeParams};
use super::zslide::{ZSlide, ZSlideParams};
use crate::chips::{
    SimAd4020, SimAd5686, SimAd5791, SimAmpEnablePin, SimClock, SimLdacPin, SimTime,
};
use crate::sched::World;
use std::cell::Cell;
use std::rc::Rc;

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RigConfig {
    pub slide: ZSlideParams,
    pub amplifier: AmplifierParams,
    pub gauge: GaugeParams,
    /// Seed of the gauge noise.
    pub seed: u64,
    /// Time from a loop-tick event to the end of its DAC frame, ns.
    pub dac_latency_ns: u64,
    /// Rate of the firmware's free-running clock, Hz.
    pub clock_hz: u64,
    /// Loop-tick event to the gauge's sampling instant, ns.
    pub adc_sample_ns: u64,
    /// Loop-tick event to the handler's reads (clock, spindle, X), ns;
    /// ≥ `adc_sample_ns`, ≤ `dac_latency_ns`.
    pub handler_entry_ns: u64,
}

impl RigConfig {
    /// The 1983 plant: Model 15 motor with the 3150 Hz mode, legacy gauge.
    pub fn legacy(seed: u64) -> Self {
        Self {
            slide: ZSlideParams::model15(),
            amplifier: AmplifierParams::default(),
            gauge: GaugeParams::legacy(),
            seed,
            dac_latency_ns: 0,
            clock_hz: 100_000_000,
            adc_sample_ns: 0,
            handler_entry_ns: 0,
        }
    }
    /// Same motor and slide, low-noise gauge.
    pub fn modern(seed: u64) -> Self {
        Self {
            gauge: GaugeParams::modern(),
            ..Self::legacy(seed)
        }
    }
}

pub struct Rig {
    pub time: SimTime,
    /// Time the plant state refers to, ns.
    pub t_ns: u64,
    pub slide: ZSlide,
    pub amp: Amplifier,
    pub gauge: Gauge,
    pub dac: SimAd5791,
    pub adc: SimAd4020,
    pub quad: SimAd5686,
    pub enable: SimAmpEnablePin,
    pub clock_hz: u64,
    /// Loop-tick event to the gauge's sampling instant and to the
    /// handler's reads, ns (`RigConfig`).
    pub adc_sample_ns: u64,
    pub handler_entry_ns: u64,
    /// Loop-tick event to the end of the DAC frame, ns (`RigConfig`).
    pub dac_latency_ns: u64,
    /// The configuration's seed (streams derived from it, e.g. the 1983
    /// loop's exact noise increments).
    pub seed: u64,
    /// Amplifier input now applied, V.
    pub v_in: f64,
    /// External (cutting) force now applied along +Z, lbf.
    pub f_ext: f64,
    /// Plant steps taken.
    pub steps: u64,
    /// A signal analyser's injection into the gauge's reading, in (the
    /// measurement disturbance the sensitivity functions are measured
    /// with; 0 otherwise).
    pub gauge_injection_in: f64,
    /// The gauge ADC's result frozen at its last conversion (a fault
    /// campaign's stuck converter: a plausible, in-range code that no
    /// longer follows the slide); false normally.
    pub gauge_frozen: bool,
}

impl Rig {
    pub fn new(cfg: RigConfig) -> Self {
        let time: SimTime = Rc::new(Cell::new(0));
        let dac = SimAd5791::new(time.clone());
        // The DAC frame is timed from the handler's reads (the simulated
        // clock stands there while the handler runs).
        let handler_entry_ns = cfg.handler_entry_ns.min(cfg.dac_latency_ns);
        dac.state.borrow_mut().latency_ns = cfg.dac_latency_ns - handler_entry_ns;
        Self {
            slide: ZSlide::new(cfg.slide),
            amp: Amplifier::new(cfg.amplifier),
            gauge: Gauge::new(cfg.gauge, cfg.seed),
            dac,
            adc: SimAd4020::new(),
            quad: SimAd5686::new(),
            enable: SimAmpEnablePin::new(time.clone()),
            clock_hz: cfg.clock_hz,
            adc_sample_ns: cfg.adc_sample_ns.min(handler_entry_ns),
            handler_entry_ns,
            dac_latency_ns: cfg.dac_latency_ns,
            seed: cfg.seed,
            time,
            t_ns: 0,
            v_in: 0.0,
            f_ext: 0.0,
            steps: 0,
            gauge_injection_in: 0.0,
            gauge_frozen: false,
        }
    }

    /// Device handles for the firmware (clones share the chips' state).
    pub fn devices(&self) -> Devices {
        Devices {
            amp_dac: self.dac.clone(),
            gauge_adc: self.adc.clone(),
            quad_dac: self.quad.clone(),
            ldac: self.quad.ldac_pin(),
            amp_enable: self.enable.clone(),
            clock: SimClock::new(self.time.clone(), self.clock_hz),
        }
    }

    /// Sets the cutting force from now on (advance to the instant first).
    pub fn set_force_lbf(&mut self, f: f64) {
        self.f_ext = f;
    }

    /// CNV: the gauge ADC converts the gauge output at the plant's time.
    pub fn cnv(&mut self) {
        if self.gauge_frozen {
            return;
        }
        let v = self.gauge.volts(
            self.t_ns,
            self.slide.gauge_position_in() + self.gauge_injection_in,
        );
        self.adc.state.borrow_mut().convert(v);
    }

    fn step_plain(&mut self, t: u64) {
        if t > self.t_ns {
            self.amp
                .advance(&mut self.slide, t - self.t_ns, self.v_in, self.f_ext);
            self.t_ns = t;
            self.steps += 1;
        }
    }

    /// Advances the plant to `t_ns`, applying DAC output changes and enable
    /// edges at their own instants on the way.
    pub fn advance_to(&mut self, t_ns: u64) {
        loop {
            let next_dac = self.dac.state.borrow().changes.front().map(|c| c.0);
            let next_en = self.enable.state.borrow().changes.first().map(|c| c.0);
            let next = match (next_dac, next_en) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
            match next {
                Some(tc) if tc <= t_ns => {
                    self.step_plain(tc);
                    if next_dac == Some(tc) {
                        if let Some((_, v)) = self.dac.state.borrow_mut().changes.pop_front() {
                            self.v_in = v;
                        }
                    } else {
                        let (_, level) = self.enable.state.borrow_mut().changes.remove(0);
                        self.amp.set_enabled(level);
                    }
                }
                _ => break,
            }
        }
        self.step_plain(t_ns);
    }
}

impl Rig {
    /// Drops the DAC output changes due by `t_ns` and applies the enable
    /// edges due by then: for a plant advanced by someone else (the 1983
    /// loop's exact steps, whose amplifier input is not the DAC).
    pub fn take_changes_to(&mut self, t_ns: u64) {
        let mut dac = self.dac.state.borrow_mut();
        while dac.changes.front().is_some_and(|c| c.0 <= t_ns) {
            dac.changes.pop_front();
        }
        let mut en = self.enable.state.borrow_mut();
        while en.changes.first().is_some_and(|c| c.0 <= t_ns) {
            let (_, level) = en.changes.remove(0);
            self.amp.set_enabled(level);
        }
    }
}

impl World for Rig {
    fn advance_to(&mut self, t_ns: u64) {
        Rig::advance_to(self, t_ns);
    }
    fn set_time(&mut self, t_ns: u64) {
        self.time.set(t_ns);
    }
}

/// What the firmware (or a test controller) is given.
#[derive(Clone, Debug)]
pub struct Devices {
    pub amp_dac: SimAd5791,
    pub gauge_adc: SimAd4020,
    pub quad_dac: SimAd5686,
    pub ldac: SimLdacPin,
    pub amp_enable: SimAmpEnablePin,
    pub clock: SimClock,
}
