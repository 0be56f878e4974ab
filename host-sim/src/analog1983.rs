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
        let y = rig.gauge.volts(
            rig.t_ns,
            rig.slide.gauge_position_in() + rig.gauge_injection_in,
        );
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

/// Exact closed-loop steps of the 1983 loop around the rig's plant while
/// everything in it is linear: the plant (`ZSlideParams::state_space`),
/// the amplifier in voltage mode (`gain`, no rail), the controller, and the
/// gauge with its noise as states — the broadband noise as the
/// Ornstein–Uhlenbeck process it is (`plant::gauge`), the hum as
/// oscillators — so one step of any length is exact: `X ← Φ X + Γ [r, f] +
/// L w`, `Φ = e^{Ah}`, `Γ = ∫e^{Aτ}dτ B` (reference and force held, as the
/// firmware's tick and the cut hold them), and `L Lᵀ = Q = ∫ e^{Aτ} G Gᵀ
/// e^{Aᵀτ} dτ` the covariance the white noise driving the noise filter adds
/// over the step (Van Loan), `w` standard normal. So the loop sees the
/// continuous noise (the co-simulation samples and holds it every 5 µs)
/// and its controller is continuous, as the 1983 circuit was.
pub struct ClosedLoopExact {
    /// States: plant 0..5, controller 5..5+nc, noise, hum (sin, cos),
    /// second hum harmonic (sin, cos).
    n: usize,
    nc: usize,
    a: nalgebra::DMatrix<f64>,
    b: nalgebra::DMatrix<f64>,
    g: nalgebra::DMatrix<f64>,
    x: Col,
    /// Gauge volts per state (y = cy·X, without saturation) and the
    /// controller's output per state and per (r, y).
    cy: Col,
    cu: Col,
    d_r: f64,
    ka: f64,
    /// Steps by length: (h ns, Φ, Γ, L (n × m), m), row-major.
    cache: Vec<ExactStep>,
    odd: usize,
    rng: rand_xoshiro::Xoshiro256PlusPlus,
}

/// States at most (plant 5, controller 5, noise 1, hum 4), the width of
/// the fixed-size columns below (padded with zeros).
const EXACT_MAX: usize = 16;
type Col = [f64; EXACT_MAX];

/// One step length's discretisation, as the columns of `[Φ | L | Γ]`
/// (n + m + 2 of them) against `[X | w | r, f]`: the step is a sum of
/// scaled fixed-width columns, which the compiler unrolls into packed
/// SSE2 (the row-by-row dot products ran ≈ 5 instructions a term).
struct ExactStep {
    h_ns: u64,
    cols: Vec<Col>,
    m: usize,
}

#[inline]
fn axpy(t: &mut Col, a: f64, c: &Col) {
    for i in 0..EXACT_MAX {
        t[i] += a * c[i];
    }
}

/// Σ a_i b_i over the fixed width (unrolled; the padding is zero).
#[inline]
fn dot16(a: &Col, b: &Col) -> f64 {
    let mut acc = [0.0; 2];
    for i in 0..EXACT_MAX / 2 {
        acc[0] += a[2 * i] * b[2 * i];
        acc[1] += a[2 * i + 1] * b[2 * i + 1];
    }
    acc[0] + acc[1]
}

/// Distinct odd step lengths discretised on their own (the loop period
/// first): any other odd step (an X event or index pulse splitting a
/// period) is composed of power-of-two steps, each exact, their noise
/// increments independent (exact in distribution). A discretisation costs
/// ≈ 1 M instructions (two 30 × 30 matrix exponentials and an eigen
/// decomposition), sixteen power-of-two steps ≈ 25 k.
const EXACT_ODD_MAX: usize = 2;

impl ClosedLoopExact {
    /// The loop `ctrl` (inputs `[r V, gauge V]`, output the amplifier
    /// input V) around `rig`'s plant, amplifier gain and gauge, starting
    /// from the rig's slide state, the controller state `xc`, noise drawn
    /// from its stationary distribution and the gauge's hum phases at
    /// `t_ns`; `seed` for the noise increments.
    pub fn new(ctrl: &LinearSystem, xc: &[f64], rig: &crate::plant::Rig, seed: u64) -> Self {
        use crate::plant::zslide::st;
        use rand::SeedableRng;
        let pl = rig.slide.params.state_space(false);
        let gp = &rig.gauge.params;
        let np = st::N;
        let nc = ctrl.states();
        let hum = gp.hum_amp_in != 0.0 || gp.hum2_amp_in != 0.0;
        let n = np + nc + 1 + if hum { 4 } else { 0 };
        assert!(n <= EXACT_MAX, "a 1983 loop of {n} states");
        let (io, ih) = (np + nc, np + nc + 1);
        let gv = if gp.reversed { -1.0 } else { 1.0 } * gp.v_per_in;
        // y = gv (z_gauge + noise + hum1 + hum2)
        let mut cy = [0.0; EXACT_MAX];
        for (k, c) in cy.iter_mut().enumerate().take(np) {
            *c = gv * pl.c[(0, k)];
        }
        cy[io] = gv;
        if hum {
            cy[ih] = gv * gp.hum_amp_in;
            cy[ih + 2] = gv * gp.hum2_amp_in;
        }
        let (d_r, d_y) = (ctrl.d[(0, 0)], ctrl.d[(0, 1)]);
        // u = C_c x_c + d_r r + d_y y
        let mut cu = [0.0; EXACT_MAX];
        for k in 0..nc {
            cu[np + k] = ctrl.c[(0, k)];
        }
        for k in 0..n {
            cu[k] += d_y * cy[k];
        }
        let ka = rig.amp.params.gain;
        let mut a = nalgebra::DMatrix::zeros(n, n);
        let mut b = nalgebra::DMatrix::zeros(n, 2);
        for r in 0..np {
            for c in 0..np {
                a[(r, c)] = pl.a[(r, c)];
            }
            for c in 0..n {
                a[(r, c)] += pl.b[(r, 0)] * ka * cu[c];
            }
            b[(r, 0)] = pl.b[(r, 0)] * ka * d_r;
            b[(r, 1)] = pl.b[(r, 1)];
        }
        for r in 0..nc {
            for c in 0..nc {
                a[(np + r, np + c)] = ctrl.a[(r, c)];
            }
            for c in 0..n {
                a[(np + r, c)] += ctrl.b[(r, 1)] * cy[c];
            }
            b[(np + r, 0)] = ctrl.b[(r, 0)];
        }
        let mut g = nalgebra::DMatrix::zeros(n, 1);
        let tau = 1.0 / (std::f64::consts::TAU * gp.white_bw_hz);
        a[(io, io)] = -1.0 / tau;
        // Stationary variance σ²: intensity 2σ²/τ.
        g[(io, 0)] = gp.white_rms_in * (2.0 / tau).sqrt();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut x = [0.0; EXACT_MAX];
        x[..np].copy_from_slice(&rig.slide.x);
        x[np..np + nc].copy_from_slice(xc);
        x[io] = gp.white_rms_in * crate::plant::gauge::gaussian(&mut rng);
        if hum {
            let w = std::f64::consts::TAU * gp.hum_hz;
            a[(ih, ih + 1)] = w;
            a[(ih + 1, ih)] = -w;
            a[(ih + 2, ih + 3)] = 2.0 * w;
            a[(ih + 3, ih + 2)] = -2.0 * w;
            let (p1, p2) = rig.gauge.hum_phases();
            let t = rig.t_ns as f64 * 1e-9;
            (x[ih], x[ih + 1]) = (w * t + p1).sin_cos();
            (x[ih + 2], x[ih + 3]) = (2.0 * w * t + p2).sin_cos();
        }
        Self {
            n,
            nc,
            a,
            b,
            g,

            x,
            cy,
            cu,
            d_r,
            ka,
            cache: Vec::new(),
            odd: 0,
            rng,
        }
    }

    fn discretise(&self, h_ns: u64) -> ExactStep {
        let n = self.n;
        let h = h_ns as f64 * 1e-9;
        let d = LinearSystem::new(
            self.a.clone(),
            self.b.clone(),
            nalgebra::DMatrix::zeros(1, n),
            nalgebra::DMatrix::zeros(1, 2),
        )
        .zoh(h);
        // Van Loan: expm([[−A, G Gᵀ], [0, Aᵀ]] h) = [[·, F12], [0, F22]],
        // Φ = F22ᵀ, Q = Φ F12.
        let mut vl = nalgebra::DMatrix::zeros(2 * n, 2 * n);
        vl.view_mut((0, 0), (n, n)).copy_from(&(-&self.a * h));
        vl.view_mut((0, n), (n, n))
            .copy_from(&(&self.g * self.g.transpose() * h));
        vl.view_mut((n, n), (n, n))
            .copy_from(&(self.a.transpose() * h));
        let e = vl.exp();
        let f12 = e.view((0, n), (n, n)).into_owned();
        let q = &d.phi * f12;
        let q = (&q + q.transpose()) * 0.5;
        // L with L Lᵀ = Q from the eigenvectors of the correlation matrix
        // (the states' variances span 15 decades: current against
        // position), keeping directions above 1e-12 of the largest: each
        // state's variance is kept to that relative accuracy.
        let sd: Vec<f64> = (0..n).map(|i| q[(i, i)].max(0.0).sqrt()).collect();
        let corr = nalgebra::DMatrix::from_fn(n, n, |i, j| {
            if sd[i] > 0.0 && sd[j] > 0.0 {
                q[(i, j)] / (sd[i] * sd[j])
            } else {
                0.0
            }
        });
        let eig = corr.symmetric_eigen();
        let top = eig.eigenvalues.iter().fold(0.0f64, |m, &v| m.max(v));
        let cols: Vec<usize> = (0..n)
            .filter(|&k| eig.eigenvalues[k] > top * 1e-12)
            .collect();
        let m = cols.len();
        let mut out = vec![[0.0; EXACT_MAX]; n + m + 2];
        for r in 0..n {
            for (c, col) in out.iter_mut().enumerate().take(n) {
                col[r] = d.phi[(r, c)];
            }
            for (j, &e) in cols.iter().enumerate() {
                out[n + j][r] = sd[r] * eig.eigenvectors[(r, e)] * eig.eigenvalues[e].sqrt();
            }
            out[n + m][r] = d.gamma[(r, 0)];
            out[n + m + 1][r] = d.gamma[(r, 1)];
        }
        ExactStep { h_ns, cols: out, m }
    }

    /// Advances `h_ns` with reference `r_v` and force `f_lbf` held.
    pub fn step(&mut self, h_ns: u64, r_v: f64, f_lbf: f64) {
        if h_ns == 0 {
            return;
        }
        let idx = match self.cache.iter().position(|e| e.h_ns == h_ns) {
            Some(i) => i,
            None if h_ns.is_power_of_two() || self.odd < EXACT_ODD_MAX => {
                self.odd += usize::from(!h_ns.is_power_of_two());
                let e = self.discretise(h_ns);
                self.cache.push(e);
                self.cache.len() - 1
            }
            None => {
                for k in (0..64).rev() {
                    if h_ns & (1 << k) != 0 {
                        self.step(1 << k, r_v, f_lbf);
                    }
                }
                return;
            }
        };
        if idx > 0 {
            // The loop period first: most steps find it at once.
            self.cache.swap(idx, 0);
        }
        let n = self.n;
        let s = &self.cache[0];
        let (phi, rest) = s.cols.split_at(n);
        let (l, gamma) = rest.split_at(s.m);
        let mut t = [0.0; EXACT_MAX];
        for (&xj, c) in self.x[..n].iter().zip(phi) {
            axpy(&mut t, xj, c);
        }
        for c in l {
            axpy(&mut t, crate::plant::gauge::gaussian(&mut self.rng), c);
        }
        axpy(&mut t, r_v, &gamma[0]);
        axpy(&mut t, f_lbf, &gamma[1]);
        self.x = t;
    }

    /// Gauge output now, V (unsaturated).
    pub fn gauge_v(&self) -> f64 {
        dot16(&self.cy, &self.x)
    }
    /// Amplifier input now, V (the controller's output).
    pub fn amp_input_v(&self, r_v: f64) -> f64 {
        self.d_r * r_v + dot16(&self.cu, &self.x)
    }
    /// Whether the loop is still inside its linear range with a margin:
    /// coil current and amplifier output within half their limits (from
    /// there the current cannot reach the limit inside a step without the
    /// amplifier's output leaving its half range first), the gauge 0.5 V
    /// (500 µin) inside its range (the slide moves ≤ 0.25 in/s: 12 µin in a
    /// loop period; the noise is 10 µin RMS).
    pub fn linear(&self, rig: &crate::plant::Rig, r_v: f64) -> bool {
        let p = &rig.amp.params;
        self.x[0].abs() < 0.5 * p.current_limit_a
            && (self.ka * self.amp_input_v(r_v)).abs() < 0.5 * p.rail_v
            && self.gauge_v().abs() < rig.gauge.params.range_v - 0.5
            && rig.amp.enabled()
            && !rig.amp.tripped()
    }
    /// Takes over the loop's state: plant, controller, broadband noise,
    /// and the hum at the rig's time (its phases are the gauge's).
    pub fn load(&mut self, plant: &[f64], ctrl: &[f64], noise_in: f64, rig: &crate::plant::Rig) {
        let np = crate::plant::zslide::st::N;
        self.x[..np].copy_from_slice(plant);
        self.x[np..np + self.nc].copy_from_slice(ctrl);
        let io = np + self.nc;
        self.x[io] = noise_in;
        if self.n > io + 1 {
            let w = std::f64::consts::TAU * rig.gauge.params.hum_hz;
            let (p1, p2) = rig.gauge.hum_phases();
            let t = rig.t_ns as f64 * 1e-9;
            (self.x[io + 1], self.x[io + 2]) = (w * t + p1).sin_cos();
            (self.x[io + 3], self.x[io + 4]) = (2.0 * w * t + p2).sin_cos();
        }
    }

    /// The broadband gauge noise state, in.
    pub fn noise_in(&self) -> f64 {
        self.x[crate::plant::zslide::st::N + self.nc]
    }
    /// The controller's states.
    pub fn controller_x(&self) -> &[f64] {
        let np = crate::plant::zslide::st::N;
        &self.x[np..np + self.nc]
    }
    /// The plant's states.
    pub fn plant_x(&self) -> [f64; crate::plant::zslide::st::N] {
        let mut p = [0.0; crate::plant::zslide::st::N];
        p.copy_from_slice(&self.x[..crate::plant::zslide::st::N]);
        p
    }
}

/// The 1983 loop driving the amplifier from the world's advance: exact
/// closed-loop steps ([`ClosedLoopExact`]) while it is linear, the
/// co-simulation against the rig ([`AnalogController`] every `substep_ns`,
/// with the amplifier's limit and trip and the gauge's saturation) from
/// the first step that leaves the linear range until the loop has been
/// back inside it for [`RELINEAR_NS`]. The reference (the firmware's
/// command, V = mil) is held from tick to tick.
pub struct AnalogDrive {
    pub ctrl: AnalogController,
    exact: Option<ClosedLoopExact>,
    /// The exact steps carry the loop now.
    in_exact: bool,
    /// Co-simulating: since when the loop is linear again, ns.
    linear_since: Option<u64>,
    next_substep_ns: u64,
    pub reference_v: f64,
    /// The command generator's sign (−1: the 1983 first part's mistake,
    /// `cut --command-sign reversed`).
    pub reference_sign: f64,
    /// Hand-overs to the co-simulation so far.
    pub nonlinear_spells: u64,
}

/// Time the co-simulated loop must stay linear before the exact steps take
/// over again, ns.
pub const RELINEAR_NS: u64 = 2_000_000;

impl AnalogDrive {
    /// The 1983 position loop on `rig`; `exact`: exact steps while linear
    /// (else the co-simulation throughout).
    pub fn position_loop(rig: &crate::plant::Rig, exact: bool, seed: u64) -> Self {
        let ctrl = AnalogController::position_loop(&PositionLoop1983::default());
        let exact =
            exact.then(|| ClosedLoopExact::new(ctrl.cache.system(), ctrl.x.as_slice(), rig, seed));
        // The first substep one substep after the hand-over (as a
        // periodic source added now would fire).
        let next_substep_ns = (rig.t_ns / ctrl.substep_ns + 1) * ctrl.substep_ns;
        Self {
            ctrl,
            in_exact: exact.is_some(),
            exact,
            linear_since: None,
            next_substep_ns,
            reference_v: 0.0,
            reference_sign: 1.0,
            nonlinear_spells: 0,
        }
    }

    /// Whether the exact steps carry the loop now.
    pub fn is_exact(&self) -> bool {
        self.in_exact
    }

    /// Advances the rig and the loop to `t_ns`.
    pub fn advance(&mut self, rig: &mut crate::plant::Rig, t_ns: u64) {
        if self.in_exact {
            let Some(ex) = self.exact.as_mut() else {
                return;
            };
            if t_ns > rig.t_ns {
                ex.step(t_ns - rig.t_ns, self.reference_v, rig.f_ext);
                rig.slide.x = ex.plant_x();
                rig.t_ns = t_ns;
                rig.steps += 1;
                rig.v_in = ex.amp_input_v(self.reference_v);
                // The firmware's DAC is not connected; enable edges still
                // reach the amplifier.
                rig.take_changes_to(t_ns);
                if !ex.linear(rig, self.reference_v) || rig.gauge_injection_in != 0.0 {
                    // Hand over: the rig carries the plant, the controller
                    // its state, the gauge the noise.
                    self.ctrl.x.copy_from_slice(ex.controller_x());
                    rig.gauge.continue_noise_from(ex.noise_in(), t_ns);
                    self.next_substep_ns =
                        t_ns.div_ceil(self.ctrl.substep_ns) * self.ctrl.substep_ns;
                    self.in_exact = false;
                    self.linear_since = None;
                    self.nonlinear_spells += 1;
                }
            }
            return;
        }
        while self.next_substep_ns < t_ns {
            rig.advance_to(self.next_substep_ns);
            self.ctrl.reference_v = self.reference_v;
            self.ctrl.tick(rig);
            self.next_substep_ns += self.ctrl.substep_ns;
        }
        rig.advance_to(t_ns);
        let Some(ex) = self.exact.as_mut() else {
            return;
        };
        // Back to the exact steps once linear long enough (with the same
        // margins; the amplifier in voltage control).
        let p = &rig.amp.params;
        let linear = rig.slide.current_a().abs() < 0.5 * p.current_limit_a
            && (p.gain * rig.v_in).abs() < 0.5 * p.rail_v
            && rig
                .gauge
                .volts_noiseless(rig.slide.gauge_position_in())
                .abs()
                < rig.gauge.params.range_v - 0.5
            && rig.amp.regime() == crate::plant::amplifier::AmpRegime::Voltage
            && rig.gauge_injection_in == 0.0;
        if !linear {
            self.linear_since = None;
            return;
        }
        let since = *self.linear_since.get_or_insert(t_ns);
        if t_ns - since >= RELINEAR_NS {
            ex.load(
                &rig.slide.x,
                self.ctrl.x.as_slice(),
                rig.gauge.noise_state(),
                rig,
            );
            // The rig's queues are taken over from here.
            rig.take_changes_to(t_ns);
            self.in_exact = true;
        }
    }

    /// The gauge's output now as the ADC converts it (saturated), V.
    pub fn gauge_volts(&self, rig: &crate::plant::Rig) -> Option<f64> {
        if !self.in_exact {
            return None;
        }
        let ex = self.exact.as_ref()?;
        let r = rig.gauge.params.range_v;
        Some(ex.gauge_v().clamp(-r, r))
    }
}
