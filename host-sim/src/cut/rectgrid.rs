//! The rectangular CMM grid a part may be measured on (issue 23,
//! `cut --part --grid NX,NY`; the measurement: `gridcut`).
//!
//! Points in the part frame of `frame.rs` (eq 2-5): `x = X cos φ`,
//! `y = X sin φ`, so a point (x, y) is measured at radius `X = hypot(x, y)`
//! and part angle `φ = atan2(y, x)` (turns, 0..1). As the polar grid of
//! `partcut`, X is a tool-centre radius. The grid is NX × NY points evenly
//! over the square inscribed in the circle `X = x_null` (half side
//! `x_null/√2`, corners on that circle), x the fast index. A point outside
//! the cut range `x_min ≤ X < x_null` is absent, never dropped: the corners
//! (where the table nulls the slide) and, for odd NX and NY, the centre
//! (on the axis, where the part angle is undefined, even when x_min = 0).

use std::f64::consts::TAU;

/// Fewest and most points a side.
pub const SIDE_MIN: usize = 2;
pub const SIDE_MAX: usize = 200;

/// The corners are on the null circle: within this of it (1 nin, the
/// table's geometry unit) a point counts as on it.
const ON_NULL_IN: f64 = 1e-9;

/// One grid point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridPoint {
    pub x_in: f64,
    pub y_in: f64,
    /// Tool-centre radius, in.
    pub radius_in: f64,
    /// Part-frame angle, turns (0..1).
    pub phi_turns: f64,
    /// Inside the cut range (else reported as absent).
    pub cut: bool,
}

/// The grid's x and y coordinates, in, and its points (`[iy][ix]`).
#[derive(Clone, Debug, PartialEq)]
pub struct RectGrid {
    pub x_in: Vec<f64>,
    pub y_in: Vec<f64>,
    pub points: Vec<Vec<GridPoint>>,
}

impl RectGrid {
    /// The points inside the cut range.
    pub fn cut_points(&self) -> impl Iterator<Item = &GridPoint> {
        self.points.iter().flatten().filter(|p| p.cut)
    }

    /// The grid of `--grid NX,NY`.
    pub fn parse(arg: &str, x_min: f64, x_null: f64) -> anyhow::Result<Self> {
        let side = |v: Option<&str>| v.and_then(|v| v.trim().parse::<usize>().ok());
        let mut it = arg.split(',');
        match (side(it.next()), side(it.next()), it.next()) {
            (Some(nx), Some(ny), None) => Self::new(nx, ny, x_min, x_null),
            _ => anyhow::bail!(
                "--grid {arg}: expected NX,NY, two whole numbers of points a side ({SIDE_MIN}..={SIDE_MAX}), e.g. --grid 9,9"
            ),
        }
    }

    pub fn new(nx: usize, ny: usize, x_min: f64, x_null: f64) -> anyhow::Result<Self> {
        for (name, n) in [("NX", nx), ("NY", ny)] {
            anyhow::ensure!(
                (SIDE_MIN..=SIDE_MAX).contains(&n),
                "--grid {nx},{ny}: {name} = {n} is outside {SIDE_MIN}..={SIDE_MAX}"
            );
        }
        let h = x_null / 2f64.sqrt();
        let side = |n: usize| -> Vec<f64> {
            (0..n)
                .map(|i| -h + 2.0 * h * i as f64 / (n - 1) as f64)
                .collect()
        };
        let (xs, ys) = (side(nx), side(ny));
        let points = ys
            .iter()
            .map(|&y| {
                xs.iter()
                    .map(|&x| {
                        let r = x.hypot(y);
                        GridPoint {
                            x_in: x,
                            y_in: y,
                            radius_in: r,
                            phi_turns: y.atan2(x).rem_euclid(TAU) / TAU,
                            cut: r >= x_min.max(ON_NULL_IN) && r < x_null - ON_NULL_IN,
                        }
                    })
                    .collect()
            })
            .collect();
        Ok(Self {
            x_in: xs,
            y_in: ys,
            points,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 × 3 grid on x_null = √2 (half side 1): the points are the nine
    /// of {−1, 0, 1}², radius √(x² + y²), angle a multiple of ⅛ turn; the
    /// four corners lie on the null circle and the centre at the axis
    /// (below x_min), so only the four edge midpoints are cut.
    #[test]
    fn a_three_by_three_grid_is_the_unit_square_with_only_edge_midpoints_cut() {
        let g = RectGrid::new(3, 3, 0.1, 2f64.sqrt()).unwrap();
        for (iy, row) in g.points.iter().enumerate() {
            for (ix, p) in row.iter().enumerate() {
                let (x, y) = (ix as f64 - 1.0, iy as f64 - 1.0);
                assert!((p.x_in - x).abs() < 1e-15 && (p.y_in - y).abs() < 1e-15);
                assert!((p.radius_in - (x * x + y * y).sqrt()).abs() < 1e-15);
                let edge_midpoint = (ix + iy) % 2 == 1;
                assert_eq!(p.cut, edge_midpoint, "point ({x}, {y})");
            }
        }
        // Angles: +x is 0, +y is ¼ turn, −x ½, −y ¾, the corner (1, 1) ⅛.
        let turns = |ix: usize, iy: usize| g.points[iy][ix].phi_turns;
        for (ix, iy, t) in [
            (2, 1, 0.0),
            (1, 2, 0.25),
            (0, 1, 0.5),
            (1, 0, 0.75),
            (2, 2, 0.125),
        ] {
            assert!(
                (turns(ix, iy) - t).abs() < 1e-15,
                "({ix}, {iy}): {}",
                turns(ix, iy)
            );
        }
    }

    #[test]
    fn the_centre_on_the_axis_is_never_cut() {
        let g = RectGrid::new(3, 3, 0.0, 2.0).unwrap();
        assert!(!g.points[1][1].cut);
        assert_eq!(g.points.iter().flatten().filter(|p| p.cut).count(), 4);
    }

    #[test]
    fn grid_sides_outside_two_to_two_hundred_are_refused() {
        for (nx, ny) in [(1, 5), (5, 1), (201, 5), (5, 201)] {
            let e = RectGrid::new(nx, ny, 0.1, 2.0).unwrap_err().to_string();
            assert!(e.contains(&format!("--grid {nx},{ny}")), "{e}");
        }
        assert!(RectGrid::new(2, 200, 0.1, 2.0).is_ok());
        for bad in ["9", "9,", "9,x", "9,9,9", "-1,5", "9;9"] {
            let e = RectGrid::parse(bad, 0.1, 2.0).unwrap_err().to_string();
            assert!(e.contains(&format!("--grid {bad}: expected NX,NY")), "{e}");
        }
        assert_eq!(RectGrid::parse(" 4, 6", 0.1, 2.0).unwrap().points.len(), 6);
    }
}
