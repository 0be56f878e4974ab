//! Exact closed-loop steps of the 1983 loop while everything in it is
//! linear.

use crate::plant::linear::{LinearSystem, StateSpace};

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
