//! Parts other than the dissertation's paraboloid sector: a surface in the
//! part frame, the tool that cuts it, the split of eq 2-8 into the axial
//! slide's `Y(X)` and the Z slide's `Z(X, φ)`, and a harmonic table for the
//! firmware (`docs/PARTS.md`).
//!
//! # The part frame
//!
//! The frame turns with the spindle: `z` lies along the axis of turning
//! (the dissertation's `z3`, relabelled `Y_t`), and a point at radius `X`
//! and spindle angle `φ` has `x = X cos φ`, `y = X sin φ` (eq 2-5). A
//! surface kind gives its sag `z(x, y)` and the gradient in this frame;
//! material lies on the −z side (the face looks toward +z, as the
//! dissertation's concave sector does).
//!
//! * [`conic::OffAxisConic`]: a conic of revolution, its sector centred off
//!   axis and tilted so that the turning axis is the normal there (eq
//!   2-1..2-4, any conic constant);
//! * [`biconic::Biconic`], [`biconic::Toric`];
//! * [`xypoly::XyPolynomial`];
//! * [`zernike::Zernike`] (fringe or standard (Noll) ordering);
//! * [`sinusoid::SinusoidalGrid`], the usual fast-tool-servo test surface;
//! * [`saggrid::SagGrid`], a CSV of sag on a rectangular grid, bicubic.
//!
//! [`split`] compensates the tool nose and splits the motion; [`table`]
//! makes, measures and picks the table; [`config`] reads a part file.

pub mod axial;
pub mod biconic;
pub mod config;
pub mod plan;
pub mod reference;
pub mod conic;
pub mod saggrid;
pub mod sinusoid;
pub mod split;
pub mod table;
pub mod xypoly;
pub mod zernike;

#[cfg(test)]
mod tests;

/// A surface in the part frame (module doc). `sag` and `grad` return NaN
/// where the surface is not defined (outside a sag grid, beyond a conic's
/// edge); the split reports such a point by its X and φ.
pub trait Sag: Send + Sync + std::fmt::Debug {
    /// Height along the axis of turning at `(x, y)`, inches.
    fn sag(&self, x: f64, y: f64) -> f64;
    /// `(∂z/∂x, ∂z/∂y)`.
    fn grad(&self, x: f64, y: f64) -> (f64, f64);
    /// One line naming the kind and its parameters (reports, plots).
    fn describe(&self) -> String;
    /// The table header's geometry fields for this surface: the
    /// paraboloid's `c` and `S_y` only for an off-axis paraboloid with the
    /// dissertation's tilt (the one surface the header can name), else
    /// [`NOT_A_PARABOLOID_NIN`].
    fn paraboloid_geometry(&self) -> Option<(f64, f64)> {
        None
    }
}

/// The part angle (radians) under the tool when the firmware's angle is
/// `command_rad`. The part turns in +φ past a still tool, so the point
/// under the tool runs backwards: `φ_part = 180° − φ_command`, the index at
/// 90° of both (`cut::frame`, docs/CUT.md "Conventions"). A table holds Z
/// in the firmware's angle, so a part's table is this map applied to the
/// part-frame surface (`table::columns`); the map is its own inverse.
pub fn part_angle(command_rad: f64) -> f64 {
    std::f64::consts::PI - command_rad
}

/// What a table header's `c` and `S_y` (nano-inches) hold when the part is
/// not an off-axis paraboloid: 1 nin each, the smallest the format accepts
/// (it refuses zero). No real paraboloid has them; `accuracy --table` then
/// asks for the part file as the reference instead of reading the header as
/// a paraboloid.
pub const NOT_A_PARABOLOID_NIN: i64 = 1;

/// True when a header's geometry marks a part that is not a paraboloid.
pub fn header_is_not_a_paraboloid(g: &zslide::table::Geometry) -> bool {
    g.c_nin == NOT_A_PARABOLOID_NIN && g.s_y_nin == NOT_A_PARABOLOID_NIN
}
