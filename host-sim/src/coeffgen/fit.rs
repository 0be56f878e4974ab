//! The series of `Z(X, ·)` at one X: its Fourier harmonics by the trapezoid
//! rule, and the same series as sin-power or harmonic columns (module doc
//! of [`super`]).

use crate::surface::Section;
use std::f64::consts::PI;
use zslide::table::Representation;

/// Samples per turn of the trapezoid-rule Fourier transform.
pub const FOURIER_SAMPLES: usize = 256;

/// Fourier coefficients of `Z(X, φ)` at one X: `Z = c[0] + Σ c[k] cos kφ +
/// s[k] sin kφ`, k = 1..=K; `s[0] = 0`.
#[derive(Clone, Debug, PartialEq)]
pub struct Harmonics {
    pub c: Vec<f64>,
    pub s: Vec<f64>,
}

impl Harmonics {
    /// Highest harmonic K.
    pub fn k_max(&self) -> usize {
        self.c.len() - 1
    }

    /// The series evaluated at φ, truncated after harmonic `k_max` (≤ K).
    pub fn eval(&self, phi: f64, k_max: usize) -> f64 {
        let mut z = self.c[0];
        for k in 1..=k_max.min(self.k_max()) {
            let (sk, ck) = (k as f64 * phi).sin_cos();
            z += self.c[k] * ck + self.s[k] * sk;
        }
        z
    }

    /// Chebyshev coefficients `b_n` of `Z` in `s = sin φ`, n = 0..=K:
    /// `Z = Σ b_n T_n(s)`.
    pub fn chebyshev(&self) -> Vec<f64> {
        (0..=self.k_max())
            .map(|n| {
                let sign = if (n / 2) % 2 == 0 { 1.0 } else { -1.0 };
                sign * if n % 2 == 0 { self.c[n] } else { self.s[n] }
            })
            .collect()
    }

    /// The N-term sin-power form: `Z ≈ Σ_{j<N} a_j sin^j φ` (harmonics
    /// 0..N−1 rewritten in powers of `sin φ`; N = 4 is eq 2-19..2-23).
    pub fn sin_power(&self, n_terms: usize) -> Vec<f64> {
        let b = self.chebyshev();
        chebyshev_to_monomial(&b[..n_terms.min(b.len())], n_terms)
    }

    /// Table 2-2's columns from C0, S1, C2, S3 by eq 2-20..2-23.
    pub fn c00_c03(&self) -> [f64; 4] {
        [
            self.c[0] + self.c[2],
            self.s[1] + 3.0 * self.s[3],
            -2.0 * self.c[2],
            -4.0 * self.s[3],
        ]
    }
}

/// Monomial coefficients (length `n_out`) of `Σ b_n T_n(s)`.
fn chebyshev_to_monomial(b: &[f64], n_out: usize) -> Vec<f64> {
    let mut a = vec![0.0; n_out];
    // T_n coefficients by T_{n+1} = 2s T_n − T_{n−1}; integers, exact in f64
    // up to degree 30 (largest ≈ 3e11 < 2^53).
    let mut t_prev = vec![0.0; n_out.max(1)];
    let mut t_cur = vec![0.0; n_out.max(1)];
    t_prev[0] = 1.0; // T_0
    if n_out > 1 {
        t_cur[1] = 1.0; // T_1
    }
    for (n, &bn) in b.iter().enumerate() {
        let t = if n == 0 { &t_prev } else { &t_cur };
        for (aj, tj) in a.iter_mut().zip(t) {
            *aj += bn * tj;
        }
        if n >= 1 {
            let mut next = vec![0.0; n_out];
            for j in 0..n_out {
                let shifted = if j >= 1 { 2.0 * t_cur[j - 1] } else { 0.0 };
                next[j] = shifted - t_prev[j];
            }
            t_prev = std::mem::replace(&mut t_cur, next);
        }
    }
    a
}

/// Evaluates `Σ a_j s^j` (Horner).
pub fn eval_sin_power(a: &[f64], s: f64) -> f64 {
    a.iter().rev().fold(0.0, |acc, &aj| acc * s + aj)
}

/// Fourier coefficients of `Z` at a section up to harmonic `k_max`, by the
/// trapezoid rule on [`FOURIER_SAMPLES`] (or more, for high harmonics) points.
pub fn harmonics(sec: &Section, k_max: usize) -> Harmonics {
    let m = FOURIER_SAMPLES.max((4 * (k_max + 1)).next_power_of_two());
    harmonics_with(sec, k_max, m)
}

/// As [`harmonics`] with an explicit sample count `m` (convergence studies).
pub fn harmonics_with(sec: &Section, k_max: usize, m: usize) -> Harmonics {
    // One table of correctly rounded sin/cos(2πj/m), indexed by j·k mod m:
    // no angle recurrence (FORIF's accumulates rounding over the harmonics).
    let (sin_t, cos_t): (Vec<f64>, Vec<f64>) = (0..m)
        .map(|j| (2.0 * PI * j as f64 / m as f64).sin_cos())
        .unzip();
    let z: Vec<f64> = sin_t.iter().map(|&s| sec.z_of_sin(s)).collect();
    let mut c = vec![0.0; k_max + 1];
    let mut s = vec![0.0; k_max + 1];
    c[0] = z.iter().sum::<f64>() / m as f64;
    for k in 1..=k_max {
        let (mut ck, mut sk) = (0.0, 0.0);
        for (j, zj) in z.iter().enumerate() {
            let idx = (j * k) % m;
            ck += zj * cos_t[idx];
            sk += zj * sin_t[idx];
        }
        // Exact zeros by the φ → π − φ symmetry (module doc).
        if k % 2 == 0 {
            c[k] = 2.0 * ck / m as f64;
        } else {
            s[k] = 2.0 * sk / m as f64;
        }
    }
    Harmonics { c, s }
}

/// Columns of one node: sin-power `a_0..a_{N−1}`, or harmonic
/// `C_0, C_1, S_1, .., C_K, S_K`.
pub fn columns_of(sec: &Section, rep: Representation, terms: usize) -> Vec<f64> {
    match rep {
        Representation::SinPower => harmonics(sec, terms.saturating_sub(1)).sin_power(terms),
        Representation::Harmonic => {
            let h = harmonics(sec, terms);
            let mut v = vec![h.c[0]];
            for k in 1..=terms {
                v.push(h.c[k]);
                v.push(h.s[k]);
            }
            v
        }
    }
}

/// Series value of one node's columns at φ.
pub fn eval_columns(rep: Representation, cols: &[f64], phi: f64) -> f64 {
    match rep {
        Representation::SinPower => eval_sin_power(cols, phi.sin()),
        Representation::Harmonic => {
            let mut z = cols[0];
            for (k, pair) in cols[1..].chunks_exact(2).enumerate() {
                let (sk, ck) = ((k + 1) as f64 * phi).sin_cos();
                z += pair[0] * ck + pair[1] * sk;
            }
            z
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::Surface;

    #[test]
    fn chebyshev_conversion_is_eq_2_20_to_2_23() {
        let h = Harmonics {
            c: vec![0.3, 0.0, -0.7, 0.0],
            s: vec![0.0, 1.1, 0.0, 0.13],
        };
        let a = h.sin_power(4);
        let e = h.c00_c03();
        for j in 0..4 {
            assert!((a[j] - e[j]).abs() < 1e-15, "{a:?} vs {e:?}");
        }
        // And the two forms agree as functions of φ.
        for i in 0..50 {
            let phi = i as f64 * 0.13;
            assert!((eval_sin_power(&a, phi.sin()) - h.eval(phi, 3)).abs() < 1e-14);
        }
    }

    #[test]
    fn high_order_sin_power_equals_harmonic_series() {
        let sec = Surface::dissertation().section(8.0).unwrap();
        let h = harmonics(&sec, 9);
        let a = h.sin_power(10);
        for i in 0..100 {
            let phi = i as f64 * 0.0628;
            let d = eval_sin_power(&a, phi.sin()) - h.eval(phi, 9);
            assert!(d.abs() < 1e-17, "{d}");
        }
    }
}
