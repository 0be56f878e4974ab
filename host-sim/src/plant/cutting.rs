//! Cutting force on the slide along Z, from the depth of cut and the tool's
//! engagement with the part, including the interrupted cut over the eight
//! countersunk bolt holes of the part face (chapter 5, Fig 5-1, 5-4).
//!
//! Model (thrust, i.e. the component along the spindle axis, which is the
//! slide axis):
//!
//! ```text
//! F = engaged · (k_t · d · f  +  k_e · l_c),   l_c = sqrt(2 r_t d) + f/2
//! ```
//! `d` depth of cut (in), `f` feed per revolution (in), `r_t` tool-nose
//! radius (0.125 in), `l_c` the length of cutting edge in contact (the
//! chord of the round nose that is in the cut). `k_t` is the specific
//! thrust pressure on the chip section and `k_e` an edge (ploughing) force
//! per unit engaged edge length; at the µin chips of a finishing pass the
//! edge term dominates, as it does in real ultra-precision turning.
//! `engaged` is the fraction of the contact chord not over a hole.
//!
//! Constants (not in the dissertation, so calibrated to its one datum):
//! roughing cuts of 0.010 in drew 3–4 A, i.e. 8.7–11.6 lbf at Kf = 2.9
//! lbf/A. With the X feed of 0.2 in/min at 300 rpm (667 µin/rev), k_t =
//! 200 000 psi and k_e = 150 lbf/in give 8.9 lbf (3.1 A). The finishing
//! pass (300 µin, 100 µin/rev) then cuts with ≈ 1.3 lbf (0.45 A).
//!
//! Direction: the part pushes the tool away from itself. `part_side` says
//! on which side of the tool the stock is (+1: the stock is toward +Z, so
//! the force on the slide is along −Z). The concave paraboloid's material
//! lies toward −Z (its face looks toward +Y_t, eq 2-14), so the default and
//! both scenarios are −1 (`cut::check_part_side`).

use std::f64::consts::TAU;

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CuttingParams {
    /// Specific thrust pressure on the chip section, lbf/in² (psi).
    pub k_t_psi: f64,
    /// Edge force per unit engaged edge length, lbf/in.
    pub k_e_lbf_per_in: f64,
    /// Tool-nose radius, in.
    pub tool_radius_in: f64,
    /// +1: stock toward +Z of the tool (force along −Z); −1: the opposite.
    pub part_side: f64,
    pub bolt_holes: BoltHoles,
}

impl Default for CuttingParams {
    fn default() -> Self {
        Self {
            k_t_psi: 2.0e5,
            k_e_lbf_per_in: 150.0,
            tool_radius_in: 0.125,
            part_side: -1.0,
            bolt_holes: BoltHoles::default(),
        }
    }
}

/// The eight countersunk bolt holes in the part face. The dissertation gives the
/// number and that the part sat on an 8 in faceplate; the bolt circle and
/// countersink size are chosen to fit inside it (documented assumption).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BoltHoles {
    pub count: u32,
    /// Bolt-circle radius, in (inside the 4 in faceplate radius).
    pub circle_radius_in: f64,
    /// Countersink diameter at the surface, in (3/8 in cap screws).
    pub diameter_in: f64,
    /// Angle φ of the first hole, degrees (eq 2-5 convention).
    pub phase_deg: f64,
    /// Holes filled with cast material (the second part of chapter 5).
    pub filled: bool,
}

impl Default for BoltHoles {
    fn default() -> Self {
        Self {
            count: 8,
            circle_radius_in: 3.5,
            diameter_in: 0.75,
            phase_deg: 22.5,
            filled: false,
        }
    }
}

impl BoltHoles {
    /// Whether the point at radius `r_in`, angle `phi_rad` is over a hole.
    pub fn over_hole(&self, r_in: f64, phi_rad: f64) -> bool {
        if self.filled || self.count == 0 {
            return false;
        }
        let (x, y) = (r_in * phi_rad.cos(), r_in * phi_rad.sin());
        let rr = (self.diameter_in / 2.0).powi(2);
        (0..self.count).any(|k| {
            let a = self.phase_deg.to_radians() + TAU * k as f64 / self.count as f64;
            let (hx, hy) = (
                self.circle_radius_in * a.cos(),
                self.circle_radius_in * a.sin(),
            );
            (x - hx).powi(2) + (y - hy).powi(2) < rr
        })
    }

    /// Fraction of a radial contact chord of length `chord_in` centred on
    /// radius `r_in` that is over solid material (sampled at 16 points, so
    /// the force falls in steps of 1/16 as the tool crosses a hole edge).
    pub fn engaged_fraction(&self, r_in: f64, phi_rad: f64, chord_in: f64) -> f64 {
        const N: usize = 16;
        let solid = (0..N)
            .filter(|&k| {
                let r = r_in + chord_in * ((k as f64 + 0.5) / N as f64 - 0.5);
                !self.over_hole(r, phi_rad)
            })
            .count();
        solid as f64 / N as f64
    }
}

impl CuttingParams {
    /// Engaged edge length for depth `d_in` and feed `f_in`, in.
    pub fn contact_length_in(&self, d_in: f64, f_in: f64) -> f64 {
        if d_in <= 0.0 {
            return 0.0;
        }
        (2.0 * self.tool_radius_in * d_in).sqrt() + f_in / 2.0
    }

    /// Magnitude of the thrust force for full engagement, lbf (0 when the
    /// tool is out of the material).
    pub fn thrust_lbf(&self, d_in: f64, f_in: f64) -> f64 {
        if d_in <= 0.0 {
            return 0.0;
        }
        self.k_t_psi * d_in * f_in + self.k_e_lbf_per_in * self.contact_length_in(d_in, f_in)
    }

    /// Force on the slide along +Z, lbf, at tool-centre radius `x_in` and
    /// spindle angle `phi_rad`, for depth of cut `d_in` and feed per rev
    /// `f_in`.
    pub fn force_on_slide_lbf(&self, x_in: f64, phi_rad: f64, d_in: f64, f_in: f64) -> f64 {
        let l = self.contact_length_in(d_in, f_in);
        let frac = self.bolt_holes.engaged_fraction(x_in, phi_rad, l.max(1e-6));
        -self.part_side * frac * self.thrust_lbf(d_in, f_in)
    }
}
