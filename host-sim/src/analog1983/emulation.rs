//! The 1983 loop run in the time domain: its controller co-simulated
//! against the rig every substep, and the loop closed around the plant as
//! one linear system.

use super::transfer::{close_loop, PositionLoop1983};
use crate::plant::linear::LinearSystem;
use crate::plant::ZSlideParams;

/// The analog controller run in the time domain against the [`Rig`]
/// (gauge noise, saturation, amplifier limits and trip included). The
/// controller's linear dynamics are stepped exactly (ZOH) between samples
/// of the gauge taken every `substep_ns`; the 1983 loop had no DAC, so its
/// output drives the amplifier input directly. The sampling adds on
/// average half a substep of delay (2.5 µs at the default 5 µs: 0.9° at
/// 1 kHz), which the frequency-domain `close_loop` does not have.
///
/// [`Rig`]: crate::plant::Rig
pub struct AnalogController {
    pub cache: crate::plant::linear::ZohCache,
    pub x: nalgebra::DVector<f64>,
    tmp: nalgebra::DVector<f64>,
    pub substep_ns: u64,
    /// Reference input (R1 or R2 of the loop), V = mil.
    pub reference_v: f64,
}

impl AnalogController {
    pub fn new(ctrl: LinearSystem, substep_ns: u64) -> Self {
        let n = ctrl.states();
        Self {
            cache: crate::plant::linear::ZohCache::new(ctrl, 4),
            x: nalgebra::DVector::zeros(n),
            tmp: nalgebra::DVector::zeros(n),
            substep_ns,
            reference_v: 0.0,
        }
    }
    /// The 1983 position loop (eq 4-45 around the emulated velocity loop).
    pub fn position_loop(p: &PositionLoop1983) -> Self {
        Self::new(p.controller(), 5_000)
    }
    /// Output (amplifier input, V) for the gauge reading `y_v`, then
    /// advances the controller state by `dt_ns` with its inputs held.
    pub fn step(&mut self, dt_ns: u64, y_v: f64) -> f64 {
        let r = self.reference_v;
        let s = self.cache.system();
        let mut out = s.d[(0, 0)] * r + s.d[(0, 1)] * y_v;
        for k in 0..s.states() {
            out += s.c[(0, k)] * self.x[k];
        }
        let d = self.cache.get(dt_ns);
        d.phi.mul_to(&self.x, &mut self.tmp);
        self.tmp.axpy(r, &d.gamma.column(0), 1.0);
        self.tmp.axpy(y_v, &d.gamma.column(1), 1.0);
        std::mem::swap(&mut self.x, &mut self.tmp);
        out
    }
    /// One substep against the rig: read the gauge, drive the amplifier.
    pub fn tick(&mut self, rig: &mut crate::plant::Rig) {
        let y = rig.gauge.volts(rig.t_ns, rig.slide.gauge_position_in());
        rig.v_in = self.step(self.substep_ns, y);
    }
}

/// The 1983 loop closed around the plant as one linear system, stepped
/// exactly between events: the fast way to run the legacy controller over a
/// whole cut (one ≈ 13-state step per event instead of 5 µs co-simulation
/// substeps). Inputs held over a step: reference (V = mil), cutting force
/// (lbf), gauge noise (in; sample it at the event and hold it). The
/// amplifier is linear here: a step that ends with |i| above the limit or
/// the gauge beyond ±10 V is counted in `nonlinear_steps` (then use
/// [`AnalogController`] on the [`crate::plant::Rig`], which models them).
pub struct AnalogClosedLoop {
    cache: crate::plant::linear::ZohCache,
    pub x: nalgebra::DVector<f64>,
    tmp: nalgebra::DVector<f64>,
    current_limit_a: f64,
    pub nonlinear_steps: u64,
}

impl AnalogClosedLoop {
    pub fn new(p: &ZSlideParams, ctrl: &LinearSystem, ka: f64, current_limit_a: f64) -> Self {
        let sys = close_loop(p, ka, ctrl);
        let n = sys.states();
        Self {
            cache: crate::plant::linear::ZohCache::new(sys, 16),
            x: nalgebra::DVector::zeros(n),
            tmp: nalgebra::DVector::zeros(n),
            current_limit_a,
            nonlinear_steps: 0,
        }
    }
    /// The default 1983 position loop on the Model 15 plant.
    pub fn legacy() -> Self {
        Self::new(
            &ZSlideParams::model15(),
            &PositionLoop1983::default().controller(),
            10.0,
            8.0,
        )
    }
    pub fn system(&self) -> &LinearSystem {
        self.cache.system()
    }
    /// Advances `dt_ns` with reference `r_v`, force `f_lbf`, gauge noise
    /// `n_in` held.
    pub fn step(&mut self, dt_ns: u64, r_v: f64, f_lbf: f64, n_in: f64) {
        if dt_ns == 0 {
            return;
        }
        let d = self.cache.get(dt_ns);
        d.phi.mul_to(&self.x, &mut self.tmp);
        self.tmp.axpy(r_v, &d.gamma.column(0), 1.0);
        self.tmp.axpy(f_lbf, &d.gamma.column(1), 1.0);
        self.tmp.axpy(n_in, &d.gamma.column(2), 1.0);
        std::mem::swap(&mut self.x, &mut self.tmp);
        let gauge = self.gauge_v(0.0, n_in);
        if self.current_a().abs() > self.current_limit_a || gauge.abs() > 10.0 {
            self.nonlinear_steps += 1;
        }
    }
    /// Gauge output (V) for reference and noise now applied.
    pub fn gauge_v(&self, r_v: f64, n_in: f64) -> f64 {
        let s = self.cache.system();
        let mut y = s.d[(0, 0)] * r_v + s.d[(0, 2)] * n_in;
        for k in 0..s.states() {
            y += s.c[(0, k)] * self.x[k];
        }
        y
    }
    pub fn current_a(&self) -> f64 {
        self.x[crate::plant::zslide::st::I]
    }
    /// Slide position (in, without the mode).
    pub fn position_in(&self) -> f64 {
        self.x[crate::plant::zslide::st::Z]
    }
}
