//! The axial slide's program of one part against another's: a compensated
//! table's `Y'(X)` (`crate::compensate`) against the nominal's `Y(X)`, for
//! the cutter (`cut::run`), which adds it to the tool's height.

use super::split::Part;

/// The axial slide's program of a compensated table against the nominal's:
/// `ΔY(X) = Y'(X) − Y(X)` on a grid, interpolated.
#[derive(Clone, Debug)]
pub struct AxialProgram {
    x0: f64,
    dx: f64,
    dy_in: Vec<f64>,
}

/// Node spacing of [`AxialProgram`], in.
const AXIAL_NODE_IN: f64 = 0.01;

impl AxialProgram {
    pub fn new(nominal: &Part, program: &Part, x_lo: f64, x_hi: f64) -> Result<Self, String> {
        let n = ((x_hi - x_lo) / AXIAL_NODE_IN).ceil() as usize + 1;
        let dy_in = (0..n)
            .map(|i| {
                let x = x_lo + i as f64 * AXIAL_NODE_IN;
                Ok(program.section(x)?.y - nominal.section(x)?.y)
            })
            .collect::<Result<Vec<_>, String>>()?;
        Ok(Self {
            x0: x_lo,
            dx: AXIAL_NODE_IN,
            dy_in,
        })
    }

    /// `ΔY` at tool-centre `x`, in (held at the ends).
    pub fn at(&self, x: f64) -> f64 {
        let u = ((x - self.x0) / self.dx).clamp(0.0, (self.dy_in.len() - 1) as f64);
        let i = (u.floor() as usize).min(self.dy_in.len().saturating_sub(2));
        let f = u - i as f64;
        match self.dy_in.get(i + 1) {
            Some(&b) => self.dy_in[i] * (1.0 - f) + b * f,
            None => self.dy_in[i],
        }
    }
}
