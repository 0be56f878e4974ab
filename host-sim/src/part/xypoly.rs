//! XY polynomial: `z = Σ c_ij x^i y^j` (inches; `c_ij` in in^(1−i−j)).

use super::Sag;

#[derive(Clone, Debug, PartialEq)]
pub struct XyPolynomial {
    /// `(i, j, c_ij)`.
    pub terms: Vec<(u32, u32, f64)>,
}

/// Highest total degree accepted (beyond it the powers of a few inches
/// overflow any sensible coefficient's precision).
pub const MAX_DEGREE: u32 = 20;

impl XyPolynomial {
    pub fn new(terms: Vec<(u32, u32, f64)>) -> Result<Self, String> {
        if terms.is_empty() {
            return Err("surface.terms: at least one term is needed".into());
        }
        for (n, &(i, j, c)) in terms.iter().enumerate() {
            if i + j > MAX_DEGREE {
                return Err(format!(
                    "surface.terms[{n}]: x_power + y_power = {} exceeds {MAX_DEGREE}",
                    i + j
                ));
            }
            if !c.is_finite() {
                return Err(format!(
                    "surface.terms[{n}].coefficient = {c}: must be finite"
                ));
            }
            if terms[..n].iter().any(|&(a, b, _)| (a, b) == (i, j)) {
                return Err(format!("surface.terms[{n}]: x^{i} y^{j} is given twice"));
            }
        }
        Ok(Self { terms })
    }
}

fn pow(v: f64, n: u32) -> f64 {
    v.powi(n as i32)
}

impl Sag for XyPolynomial {
    fn sag(&self, x: f64, y: f64) -> f64 {
        self.terms
            .iter()
            .map(|&(i, j, c)| c * pow(x, i) * pow(y, j))
            .sum()
    }

    fn grad(&self, x: f64, y: f64) -> (f64, f64) {
        self.terms.iter().fold((0.0, 0.0), |(gx, gy), &(i, j, c)| {
            let dx = if i == 0 {
                0.0
            } else {
                f64::from(i) * pow(x, i - 1) * pow(y, j)
            };
            let dy = if j == 0 {
                0.0
            } else {
                f64::from(j) * pow(x, i) * pow(y, j - 1)
            };
            (gx + c * dx, gy + c * dy)
        })
    }

    fn describe(&self) -> String {
        format!("xy-polynomial, {} terms", self.terms.len())
    }
}
