//! Sag on a rectangular grid from a CSV file, interpolated bicubically.
//!
//! File: one point a line, `x_in,y_in,z_in` (a first line that does not
//! parse as numbers is taken as a header); the points must fill a uniform
//! rectangular grid (any order, each node once, at least 4 × 4).
//!
//! Interpolation: bicubic convolution (Keys 1981, a = −½, the Catmull–Rom
//! spline) along x then y: it passes through the nodes, is C¹, and errs by
//! O(h³) times the third derivatives; at the edges the missing neighbour is
//! Keys' cubic extrapolation `f₋₁ = 3f₀ − 3f₁ + f₂`, which keeps that
//! order. Outside the grid the sag is undefined (NaN; the split names the
//! point).

use super::Sag;
use std::path::Path;

#[derive(Clone, Debug, PartialEq)]
pub struct SagGrid {
    pub x0: f64,
    pub y0: f64,
    pub hx: f64,
    pub hy: f64,
    pub nx: usize,
    pub ny: usize,
    /// Row-major `z[iy * nx + ix]`.
    pub z: Vec<f64>,
    pub source: String,
}

/// Catmull–Rom value and derivative (per unit t) through p0..p3 at t ∈ [0, 1].
fn cr(p: [f64; 4], t: f64) -> (f64, f64) {
    let a = 2.0 * p[1];
    let b = p[2] - p[0];
    let c = 2.0 * p[0] - 5.0 * p[1] + 4.0 * p[2] - p[3];
    let d = -p[0] + 3.0 * p[1] - 3.0 * p[2] + p[3];
    (
        0.5 * (a + t * (b + t * (c + t * d))),
        0.5 * (b + t * (2.0 * c + t * 3.0 * d)),
    )
}

impl SagGrid {
    /// From the points of a file (`source` names it in errors).
    pub fn from_points(points: &[(f64, f64, f64)], source: &str) -> Result<Self, String> {
        let uniq = |v: Vec<f64>| -> Vec<f64> {
            let mut v = v;
            v.sort_by(f64::total_cmp);
            v.dedup();
            v
        };
        let xs = uniq(points.iter().map(|p| p.0).collect());
        let ys = uniq(points.iter().map(|p| p.1).collect());
        let (nx, ny) = (xs.len(), ys.len());
        if nx < 4 || ny < 4 {
            return Err(format!(
                "{source}: {nx} × {ny} distinct x × y values; at least 4 × 4 needed for bicubic interpolation"
            ));
        }
        if nx * ny != points.len() {
            return Err(format!(
                "{source}: {} points do not fill the {nx} × {ny} grid of their x and y values once each",
                points.len()
            ));
        }
        let step = |v: &[f64], axis: &str| -> Result<f64, String> {
            let h = (v[v.len() - 1] - v[0]) / (v.len() - 1) as f64;
            for (i, w) in v.windows(2).enumerate() {
                if ((w[1] - w[0]) - h).abs() > 1e-6 * h {
                    return Err(format!(
                        "{source}: {axis} values are not uniformly spaced ({} to {} after {i} steps of {h})",
                        w[0], w[1]
                    ));
                }
            }
            Ok(h)
        };
        let (hx, hy) = (step(&xs, "x")?, step(&ys, "y")?);
        let mut z = vec![f64::NAN; nx * ny];
        for &(x, y, v) in points {
            let ix = ((x - xs[0]) / hx).round() as usize;
            let iy = ((y - ys[0]) / hy).round() as usize;
            if !z[iy * nx + ix].is_nan() {
                return Err(format!("{source}: node ({x}, {y}) given twice"));
            }
            z[iy * nx + ix] = v;
        }
        Ok(Self {
            x0: xs[0],
            y0: ys[0],
            hx,
            hy,
            nx,
            ny,
            z,
            source: source.to_string(),
        })
    }

    /// Reads the CSV at `path`.
    pub fn read(path: &Path) -> Result<Self, String> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| format!("reading {name}: {e}"))?;
        let mut pts = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() {
                continue;
            }
            let f: Vec<&str> = line.split(',').map(str::trim).collect();
            let nums: Option<Vec<f64>> = f.iter().map(|s| s.parse().ok()).collect();
            match nums {
                Some(v) if v.len() == 3 && v.iter().all(|x| x.is_finite()) => {
                    pts.push((v[0], v[1], v[2]))
                }
                _ if n == 0 => {} // header
                _ => {
                    return Err(format!(
                    "{name} line {}: expected three finite numbers `x_in,y_in,z_in`, got {line:?}",
                    n + 1
                ))
                }
            }
        }
        Self::from_points(&pts, &name)
    }

    fn node(&self, ix: isize, iy: usize) -> f64 {
        // Keys' edge extrapolation f₋₁ = 3f₀ − 3f₁ + f₂ (and mirrored).
        let n = self.nx as isize;
        let row = &self.z[iy * self.nx..(iy + 1) * self.nx];
        if ix < 0 {
            3.0 * row[0] - 3.0 * row[1] + row[2]
        } else if ix >= n {
            let l = self.nx - 1;
            3.0 * row[l] - 3.0 * row[l - 1] + row[l - 2]
        } else {
            row[ix as usize]
        }
    }

    /// Value, ∂/∂x, ∂/∂y; NaN outside the grid.
    fn eval(&self, x: f64, y: f64) -> (f64, f64, f64) {
        let u = (x - self.x0) / self.hx;
        let v = (y - self.y0) / self.hy;
        let (mx, my) = ((self.nx - 1) as f64, (self.ny - 1) as f64);
        if !((0.0..=mx).contains(&u) && (0.0..=my).contains(&v)) {
            return (f64::NAN, f64::NAN, f64::NAN);
        }
        let ix = (u.floor() as usize).min(self.nx - 2);
        let iy = (v.floor() as usize).min(self.ny - 2);
        let (tu, tv) = (u - ix as f64, v - iy as f64);
        let mut col = [0.0; 4];
        let mut dcol = [0.0; 4];
        for (k, (cv, dv)) in col.iter_mut().zip(dcol.iter_mut()).enumerate() {
            let j = iy as isize + k as isize - 1;
            // Rows beyond the edge by the same extrapolation, per column.
            let row_vals = |jj: isize| -> [f64; 4] {
                let get = |jy: usize| {
                    let mut p = [0.0; 4];
                    for (q, pv) in p.iter_mut().enumerate() {
                        *pv = self.node(ix as isize + q as isize - 1, jy);
                    }
                    p
                };
                let ny = self.ny as isize;
                if jj < 0 {
                    let (a, b, c) = (get(0), get(1), get(2));
                    std::array::from_fn(|q| 3.0 * a[q] - 3.0 * b[q] + c[q])
                } else if jj >= ny {
                    let l = self.ny - 1;
                    let (a, b, c) = (get(l), get(l - 1), get(l - 2));
                    std::array::from_fn(|q| 3.0 * a[q] - 3.0 * b[q] + c[q])
                } else {
                    get(jj as usize)
                }
            };
            (*cv, *dv) = cr(row_vals(j), tu);
        }
        let (z, dzv) = cr(col, tv);
        let (dzu, _) = cr(dcol, tv);
        (z, dzu / self.hx, dzv / self.hy)
    }
}

impl Sag for SagGrid {
    fn sag(&self, x: f64, y: f64) -> f64 {
        self.eval(x, y).0
    }

    fn grad(&self, x: f64, y: f64) -> (f64, f64) {
        let (_, gx, gy) = self.eval(x, y);
        (gx, gy)
    }

    fn describe(&self) -> String {
        format!(
            "sag grid {} ({} × {} nodes, x {}..{} in, y {}..{} in), bicubic (Catmull–Rom)",
            self.source,
            self.nx,
            self.ny,
            self.x0,
            self.x0 + self.hx * (self.nx - 1) as f64,
            self.y0,
            self.y0 + self.hy * (self.ny - 1) as f64
        )
    }
}
