//! Exact zero-order-hold discretisation of the slide's state space (`std`
//! builds: the host, and the QEMU image's build script).
//!
//! `x(t+h) = Φ(h) x(t) + Γ(h) u`, `Φ = e^{Ah}`, `Γ = ∫₀ʰ e^{Aτ} dτ B`, exact
//! for inputs held over the step whatever `h` is. Both come from one matrix
//! exponential of the augmented matrix `[[A, B], [0, 0]] h` (Van Loan),
//! computed by nalgebra's scaling-and-squaring Padé `exp`. So the 0.26 ms
//! electrical pole and the 3150 Hz mode stay exact whether events are 50 µs
//! or 3 ns apart, where an explicit integrator would need steps far below
//! the fastest time constant.

use crate::statespace::{st, Mats};
use nalgebra::SMatrix;

/// States plus inputs of the augmented matrix.
const AUG: usize = st::N + 2;

/// `Φ` and `Γ` of `x' = A x + B u` for a step of `h` seconds.
pub fn zoh(a: &[[f64; st::N]; st::N], b: &[[f64; 2]; st::N], h: f64) -> Mats {
    let mut big = SMatrix::<f64, AUG, AUG>::zeros();
    for r in 0..st::N {
        for c in 0..st::N {
            big[(r, c)] = a[r][c] * h;
        }
        for c in 0..2 {
            big[(r, st::N + c)] = b[r][c] * h;
        }
    }
    let e = big.exp();
    let mut m = Mats {
        phi: [[0.0; st::N]; st::N],
        gamma: [[0.0; 2]; st::N],
    };
    for r in 0..st::N {
        for c in 0..st::N {
            m.phi[r][c] = e[(r, c)];
        }
        for c in 0..2 {
            m.gamma[r][c] = e[(r, st::N + c)];
        }
    }
    m
}
