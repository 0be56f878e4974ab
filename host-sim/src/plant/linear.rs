//! Continuous linear time-invariant systems and their exact zero-order-hold
//! discretisation.
//!
//! Every linear part of the simulated machine is stepped with
//! `x(t+h) = Φ(h) x(t) + Γ(h) u`, `Φ = e^{Ah}`, `Γ = ∫₀ʰ e^{Aτ} dτ B`, which is
//! exact for inputs held constant over the step, whatever `h` is. Both come
//! from one matrix exponential of the augmented matrix `[[A, B], [0, 0]] h`
//! (Van Loan), computed by nalgebra's scaling-and-squaring Padé `exp`. So the
//! 0.26 ms electrical pole and the 3150 Hz mode stay exact whether events are
//! 50 µs or 3 ns apart, where an explicit integrator would need steps far
//! below the fastest time constant.

use nalgebra::{Complex, DMatrix, DVector};

/// `x' = A x + B u`, `y = C x + D u`, continuous time.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearSystem {
    pub a: DMatrix<f64>,
    pub b: DMatrix<f64>,
    pub c: DMatrix<f64>,
    pub d: DMatrix<f64>,
}

/// The ZOH discretisation of a [`LinearSystem`] for one step length.
#[derive(Clone, Debug, PartialEq)]
pub struct Discrete {
    pub phi: DMatrix<f64>,
    pub gamma: DMatrix<f64>,
}

impl LinearSystem {
    /// Checks the dimensions once so the steppers can index freely.
    pub fn new(a: DMatrix<f64>, b: DMatrix<f64>, c: DMatrix<f64>, d: DMatrix<f64>) -> Self {
        let n = a.nrows();
        assert_eq!(a.ncols(), n, "A must be square");
        assert_eq!(b.nrows(), n, "B rows must match A");
        assert_eq!(c.ncols(), n, "C columns must match A");
        assert_eq!(d.nrows(), c.nrows(), "D rows must match C");
        assert_eq!(d.ncols(), b.ncols(), "D columns must match B");
        Self { a, b, c, d }
    }

    pub fn states(&self) -> usize {
        self.a.nrows()
    }
    pub fn inputs(&self) -> usize {
        self.b.ncols()
    }
    pub fn outputs(&self) -> usize {
        self.c.nrows()
    }

    /// Exact ZOH discretisation for a step of `h` seconds.
    pub fn zoh(&self, h: f64) -> Discrete {
        let n = self.states();
        let m = self.inputs();
        let mut big = DMatrix::<f64>::zeros(n + m, n + m);
        big.view_mut((0, 0), (n, n)).copy_from(&(&self.a * h));
        big.view_mut((0, n), (n, m)).copy_from(&(&self.b * h));
        let e = big.exp();
        Discrete {
            phi: e.view((0, 0), (n, n)).into_owned(),
            gamma: e.view((0, n), (n, m)).into_owned(),
        }
    }

    /// Output for a state and input.
    pub fn output(&self, x: &DVector<f64>, u: &DVector<f64>) -> DVector<f64> {
        &self.c * x + &self.d * u
    }

    /// Frequency response `C (jωI − A)⁻¹ B + D` from input `input` to
    /// output `output` at `w` rad/s. Used to cross-check the time-domain
    /// analyser, never as the analyser itself.
    pub fn freq_response(&self, w: f64, input: usize, output: usize) -> Complex<f64> {
        let n = self.states();
        let mut m = DMatrix::<Complex<f64>>::zeros(n, n);
        for r in 0..n {
            for c in 0..n {
                m[(r, c)] = Complex::new(-self.a[(r, c)], 0.0);
            }
            m[(r, r)] += Complex::new(0.0, w);
        }
        let rhs = DVector::<Complex<f64>>::from_fn(n, |r, _| Complex::new(self.b[(r, input)], 0.0));
        let x = m.lu().solve(&rhs).unwrap_or_else(|| DVector::zeros(n));
        let mut y = Complex::new(self.d[(output, input)], 0.0);
        for k in 0..n {
            y += x[k] * self.c[(output, k)];
        }
        y
    }

    /// Eigenvalues of A (the poles), sorted by real part then imaginary.
    pub fn poles(&self) -> Vec<Complex<f64>> {
        let mut p: Vec<Complex<f64>> = self.a.complex_eigenvalues().iter().copied().collect();
        p.sort_by(|a, b| {
            a.re.partial_cmp(&b.re)
                .unwrap_or(std::cmp::Ordering::Equal)
                .then(a.im.partial_cmp(&b.im).unwrap_or(std::cmp::Ordering::Equal))
        });
        p
    }

    /// Series connection `other ∘ self` (the output of `self` feeds `other`).
    pub fn series(&self, other: &LinearSystem) -> LinearSystem {
        assert_eq!(self.outputs(), other.inputs());
        let (n1, n2) = (self.states(), other.states());
        let mut a = DMatrix::zeros(n1 + n2, n1 + n2);
        a.view_mut((0, 0), (n1, n1)).copy_from(&self.a);
        a.view_mut((n1, 0), (n2, n1))
            .copy_from(&(&other.b * &self.c));
        a.view_mut((n1, n1), (n2, n2)).copy_from(&other.a);
        let mut b = DMatrix::zeros(n1 + n2, self.inputs());
        b.view_mut((0, 0), (n1, self.inputs())).copy_from(&self.b);
        b.view_mut((n1, 0), (n2, self.inputs()))
            .copy_from(&(&other.b * &self.d));
        let mut c = DMatrix::zeros(other.outputs(), n1 + n2);
        c.view_mut((0, 0), (other.outputs(), n1))
            .copy_from(&(&other.d * &self.c));
        c.view_mut((0, n1), (other.outputs(), n2))
            .copy_from(&other.c);
        let d = &other.d * &self.d;
        LinearSystem::new(a, b, c, d)
    }
}

/// A first-order section `k (1 + s/wz) / (1 + s/wp)` (lead or lag), one
/// input, one output; `wz = ∞` gives a plain low-pass.
pub fn lead_lag(k: f64, wz: f64, wp: f64) -> LinearSystem {
    // y = k [wp/wz + (1 − wp/wz) wp/(s + wp)] u
    let r = if wz.is_finite() { wp / wz } else { 0.0 };
    LinearSystem::new(
        DMatrix::from_element(1, 1, -wp),
        DMatrix::from_element(1, 1, wp),
        DMatrix::from_element(1, 1, k * (1.0 - r)),
        DMatrix::from_element(1, 1, k * r),
    )
}

/// A ZOH stepper for one system with a small cache of discretisations keyed
/// by the step length in integer nanoseconds: in a run the loop period and
/// a handful of other gaps repeat, so `exp` is computed a few times per run.
#[derive(Clone, Debug)]
pub struct ZohCache {
    sys: LinearSystem,
    entries: Vec<(u64, Discrete)>,
    capacity: usize,
    pub misses: u64,
}

impl ZohCache {
    pub fn new(sys: LinearSystem, capacity: usize) -> Self {
        Self {
            sys,
            entries: Vec::new(),
            capacity: capacity.max(1),
            misses: 0,
        }
    }
    pub fn system(&self) -> &LinearSystem {
        &self.sys
    }
    /// Discretisation for `dt_ns`; most recently used first so the loop
    /// period is found at once.
    pub fn get(&mut self, dt_ns: u64) -> &Discrete {
        if let Some(pos) = self.entries.iter().position(|(k, _)| *k == dt_ns) {
            if pos != 0 {
                let e = self.entries.remove(pos);
                self.entries.insert(0, e);
            }
        } else {
            self.misses += 1;
            let d = self.sys.zoh(dt_ns as f64 * 1e-9);
            if self.entries.len() >= self.capacity {
                self.entries.pop();
            }
            self.entries.insert(0, (dt_ns, d));
        }
        &self.entries[0].1
    }
}

/// The slide model's continuous state space (`zslide_plant`) as a
/// [`LinearSystem`], with outputs `y = [z_gauge, i, v, z]`
/// (`z_gauge = z + q` when the gauge sees the mode), for analysis:
/// poles, frequency responses, series connections.
pub trait StateSpace {
    /// See `zslide_plant::slide::ZSlideParams::continuous` for
    /// `current_held`.
    fn state_space(&self, current_held: bool) -> LinearSystem;
}

impl StateSpace for zslide_plant::ZSlideParams {
    fn state_space(&self, current_held: bool) -> LinearSystem {
        use zslide_plant::slide::st;
        let (a, b) = self.continuous(current_held);
        let n = st::N;
        let a = DMatrix::from_fn(n, n, |r, c| a[r][c]);
        let b = DMatrix::from_fn(n, 2, |r, c| b[r][c]);
        let mut c = DMatrix::zeros(4, n);
        c[(0, st::Z)] = 1.0;
        c[(0, st::Q)] = if self.gauge_sees_mode() { 1.0 } else { 0.0 };
        c[(1, st::I)] = 1.0;
        c[(2, st::V)] = 1.0;
        c[(3, st::Z)] = 1.0;
        LinearSystem::new(a, b, c, DMatrix::zeros(4, 2))
    }
}
