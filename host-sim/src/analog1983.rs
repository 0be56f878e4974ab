//! The 1983 analog Z-slide loop, emulated around the simulated plant as a
//! comparison controller (chapter 4).
//!
//! **Velocity loop (eq 4-37..4-44).** Fig 4-4/4-19: the reference R1 and the
//! differentiated gauge signal are summed, shaped, amplified (K_A = 10) and
//! drive the motor; velocity feedback is the gauge signal through the
//! differentiating network `Hv = Kfv s / (1 + s/ωf)²` with both filters at
//! ≈ 1050 Hz (the final network after the National Semiconductor note,
//! Fig 4-23). The final circuit's gains are not published; only the
//! measured closed loop is (eq 4-44, Model 15 motor):
//! `Z/R1 = 674 / (s (1 + s/1162.4)(1 + s/7634.1))`.
//! We keep the published structure and fit the unpublished values — the
//! forward gain `Kg`, a first-order lead `(1 + s/ωz)/(1 + s/ωp)` in the
//! forward path, and `Kfv` — by least squares of the complex log-ratio to
//! eq 4-44 over 1 Hz..1 kHz with the Model 15 plant *including* the 3150 Hz
//! mode (script and residuals in `docs/PLANT.md`). The result agrees with
//! eq 4-44 within 0.3 dB and 1° to 1 kHz; above, the mode shows.
//!
//! **Position loop (eq 4-45..4-47).** `Goc = 12 Ko (1 + s/4.16667) /
//! ((1 + s/0.378788)(1 + s/3030.3))` on the position error (1 V/mil gauge),
//! its output is R1. Kv = 8088 · Ko (eq 4-46); Ko = 0.5934 gives the
//! published Kv ≈ 4800 1/s.

use crate::plant::linear::{lead_lag, LinearSystem, StateSpace};
use crate::plant::ZSlideParams;
use nalgebra::DMatrix;

/// Parameters of the emulated analog velocity loop (see module doc).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VelocityLoop1983 {
    /// Power amplifier gain, V/V.
    pub ka: f64,
    /// Forward gain before the amplifier, V/V (fitted).
    pub kg: f64,
    /// Forward lead zero and pole, rad/s (fitted).
    pub lead_zero: f64,
    pub lead_pole: f64,
    /// Differentiator gain, V per (V/s) of gauge signal (fitted).
    pub kfv: f64,
    /// Differentiator filter corner (two equal poles), rad/s.
    pub filter: f64,
}

impl Default for VelocityLoop1983 {
    fn default() -> Self {
        Self {
            ka: 10.0,
            kg: 0.443117,
            lead_zero: 2953.92,
            lead_pole: 8635.09,
            kfv: 9.405266e-4,
            filter: std::f64::consts::TAU * 1050.0,
        }
    }
}

/// The lag compensator of eq 4-45 with its gain.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PositionLoop1983 {
    pub ko: f64,
    pub velocity: VelocityLoop1983,
}

impl Default for PositionLoop1983 {
    fn default() -> Self {
        Self {
            ko: 0.5934,
            velocity: VelocityLoop1983::default(),
        }
    }
}

/// Gauge sensitivity used by the loops, V/in (1 V/mil).
pub const GAUGE_V_PER_IN: f64 = 1000.0;

/// A SISO transfer function `num(s)/den(s)` (descending powers, proper) in
/// controllable canonical form.
pub fn tf(num: &[f64], den: &[f64]) -> LinearSystem {
    let n = den.len() - 1;
    assert!(num.len() <= den.len(), "improper transfer function");
    let a0 = den[0];
    let a: Vec<f64> = den.iter().map(|d| d / a0).collect();
    let mut b = vec![0.0; n + 1 - num.len()];
    b.extend(num.iter().map(|x| x / a0));
    let mut am = DMatrix::zeros(n, n);
    for k in 0..n {
        am[(0, k)] = -a[k + 1];
        if k + 1 < n {
            am[(k + 1, k)] = 1.0;
        }
    }
    let mut bm = DMatrix::zeros(n, 1);
    if n > 0 {
        bm[(0, 0)] = 1.0;
    }
    let cm = DMatrix::from_fn(1, n, |_, k| b[k + 1] - a[k + 1] * b[0]);
    LinearSystem::new(am, bm, cm, DMatrix::from_element(1, 1, b[0]))
}

/// `[u1, u2] → u1 − H u2` for a SISO `H`.
fn minus_h(h: &LinearSystem) -> LinearSystem {
    let n = h.states();
    let mut b = DMatrix::zeros(n, 2);
    b.view_mut((0, 1), (n, 1)).copy_from(&h.b);
    let mut d = DMatrix::zeros(1, 2);
    d[(0, 0)] = 1.0;
    d[(0, 1)] = -h.d[(0, 0)];
    LinearSystem::new(h.a.clone(), b, -&h.c, d)
}

impl VelocityLoop1983 {
    /// The differentiating network `Hv`, gauge V → V.
    pub fn hv(&self) -> LinearSystem {
        let w = self.filter;
        tf(&[self.kfv * w * w, 0.0], &[1.0, 2.0 * w, w * w])
    }
    /// Controller with inputs `[r1 (V), gauge (V)]`, output the amplifier
    /// input (V).
    pub fn controller(&self) -> LinearSystem {
        minus_h(&self.hv()).series(&lead_lag(self.kg, self.lead_zero, self.lead_pole))
    }
}

impl PositionLoop1983 {
    /// Eq 4-45 compensator (error V → R1 V).
    pub fn goc(&self) -> LinearSystem {
        let (wz, wp1, wp2) = (4.16667, 0.378788, 3030.3);
        // 12 Ko (1 + s/wz) / ((1 + s/wp1)(1 + s/wp2))
        let k = 12.0 * self.ko * wp1 * wp2 / wz;
        tf(&[k, k * wz], &[1.0, wp1 + wp2, wp1 * wp2])
    }
    /// Controller with inputs `[r2 (V), gauge (V)]`, output amplifier input.
    pub fn controller(&self) -> LinearSystem {
        let g = self.goc();
        let n = g.states();
        // [r2, y] → [Goc (r2 − y), y]
        let mut b = DMatrix::zeros(n, 2);
        b.view_mut((0, 0), (n, 1)).copy_from(&g.b);
        b.view_mut((0, 1), (n, 1)).copy_from(&(-&g.b));
        let mut c = DMatrix::zeros(2, n);
        c.view_mut((0, 0), (1, n)).copy_from(&g.c);
        let mut d = DMatrix::zeros(2, 2);
        d[(0, 0)] = g.d[(0, 0)];
        d[(0, 1)] = -g.d[(0, 0)];
        d[(1, 1)] = 1.0;
        LinearSystem::new(g.a.clone(), b, c, d).series(&self.velocity.controller())
    }
    /// Velocity constant of eq 4-46 for this Ko, 1/s.
    pub fn kv_eq4_46(&self) -> f64 {
        self.ko * 1.9771851e13 * 4.16667 / (0.378788 * 3030.3 * 1162.4 * 7634.1)
    }
}

/// The plant from the amplifier input (V) to the gauge (V), amplifier in
/// voltage mode: inputs `[u, f_ext (lbf)]`, outputs `[gauge V, i, v, z]`.
pub fn plant_open(p: &ZSlideParams, ka: f64) -> LinearSystem {
    let mut s = p.state_space(false);
    for r in 0..s.states() {
        s.b[(r, 0)] *= ka;
    }
    for c in 0..s.states() {
        s.c[(0, c)] *= GAUGE_V_PER_IN;
    }
    s
}

/// Closes an analog loop (controller inputs `[r, gauge V]`, output the
/// amplifier input) around the plant, amplifier linear. Result: inputs
/// `[r, f_ext (lbf), gauge noise (in)]`, outputs `[gauge V, amplifier
/// input V, current A, z in]`, states `[plant; controller]`.
pub fn close_loop(p: &ZSlideParams, ka: f64, ctrl: &LinearSystem) -> LinearSystem {
    let pl = p.state_space(false);
    let (np, nc) = (pl.states(), ctrl.states());
    let g = GAUGE_V_PER_IN;
    let cz = pl.c.row(0).into_owned() * g; // gauge V per state
    let be = pl.b.column(0).into_owned() * ka;
    let bf = pl.b.column(1).into_owned();
    let (dr, dy) = (ctrl.d[(0, 0)], ctrl.d[(0, 1)]);
    let br = ctrl.b.column(0).into_owned();
    let by = ctrl.b.column(1).into_owned();
    let cc = ctrl.c.row(0).into_owned();
    let n = np + nc;
    let mut a = DMatrix::zeros(n, n);
    a.view_mut((0, 0), (np, np))
        .copy_from(&(&pl.a + &be * &cz * dy));
    a.view_mut((0, np), (np, nc)).copy_from(&(&be * &cc));
    a.view_mut((np, 0), (nc, np)).copy_from(&(&by * &cz));
    a.view_mut((np, np), (nc, nc)).copy_from(&ctrl.a);
    let mut b = DMatrix::zeros(n, 3);
    b.view_mut((0, 0), (np, 1)).copy_from(&(&be * dr));
    b.view_mut((0, 1), (np, 1)).copy_from(&bf);
    b.view_mut((0, 2), (np, 1)).copy_from(&(&be * dy * g));
    b.view_mut((np, 0), (nc, 1)).copy_from(&br);
    b.view_mut((np, 2), (nc, 1)).copy_from(&(&by * g));
    let mut c = DMatrix::zeros(4, n);
    c.view_mut((0, 0), (1, np)).copy_from(&cz);
    c.view_mut((1, 0), (1, np)).copy_from(&(&cz * dy));
    c.view_mut((1, np), (1, nc)).copy_from(&cc);
    c[(2, crate::plant::zslide::st::I)] = 1.0;
    c[(3, crate::plant::zslide::st::Z)] = 1.0;
    let mut d = DMatrix::zeros(4, 3);
    d[(0, 2)] = g;
    d[(1, 0)] = dr;
    d[(1, 2)] = dy * g;
    LinearSystem::new(a, b, c, d)
}

/// Eq 4-44, the measured closed velocity loop `Z/R1` (V/V), at `w` rad/s.
pub fn eq4_44(w: f64) -> nalgebra::Complex<f64> {
    let s = nalgebra::Complex::new(0.0, w);
    nalgebra::Complex::new(674.0, 0.0) / (s * (1.0 + s / 1162.4) * (1.0 + s / 7634.1))
}

/// Eq 4-47, the closed position loop `Z/R2` from eq 4-46, at `w` rad/s.
pub fn eq4_47(ko: f64, w: f64) -> nalgebra::Complex<f64> {
    let s = nalgebra::Complex::new(0.0, w);
    let k = ko * 1.9771851e13;
    let ol = k * (s + 4.16667) / (s * (s + 0.378788) * (s + 3030.3) * (s + 1162.4) * (s + 7634.1));
    ol / (1.0 + ol)
}

/// Eq 4-49, the synthesized final closed loop (`Z/R2`), at `w` rad/s.
pub fn eq4_49(w: f64) -> nalgebra::Complex<f64> {
    let s = nalgebra::Complex::new(0.0, w);
    let q = s / 691.2;
    nalgebra::Complex::new(1.0, 0.0)
        / ((1.0 + s / 2827.4) * (1.0 + s / 9110.6) * (1.0 + 2.0 * 0.5 * q + q * q))
}

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
