//! The 1983 loop as transfer functions: the velocity and position loops'
//! design (module doc of [`super`]), the loop closed around the plant, and
//! the published closed loops (eq 4-44, 4-47, 4-49) it is held against.

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
