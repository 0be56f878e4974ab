//! The part on the slides: a surface of revolution placed off centre, with
//! some out-of-roundness of its own.

/// One lobe term of the part's out-of-roundness: `amp·cos(k ψ + phase)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobe {
    pub k: u32,
    pub amp_in: f64,
    pub phase_rad: f64,
}

#[derive(Clone, Debug)]
pub struct Part {
    /// Radius at the transducer's latitude, inches.
    pub radius_in: f64,
    /// Where the operator put it: centre in the table frame, inches.
    pub offset_in: [f64; 2],
    pub lobes: Vec<Lobe>,
}

impl Part {
    /// Radius in the part's own angle ψ.
    pub fn radius_at(&self, psi: f64) -> f64 {
        self.radius_in
            + self
                .lobes
                .iter()
                .map(|l| l.amp_in * (f64::from(l.k) * psi + l.phase_rad).cos())
                .sum::<f64>()
    }

    /// Distance from the table axis, along the transducer's line (space +x),
    /// of the surface point the plunger touches, for the table at angle
    /// `theta` and the part's centre at `centre` (table frame). Exact for a
    /// circle; for the lobes the contact angle is that of the circle's point.
    pub fn surface_x(&self, theta: f64, centre: [f64; 2]) -> f64 {
        let (s, c) = theta.sin_cos();
        let cx = centre[0] * c - centre[1] * s;
        let cy = centre[0] * s + centre[1] * c;
        // Contact on the line y = 0: angle of that point seen from the part
        // centre, in space, then in the part's (table-fixed) frame.
        let rho0 = self.radius_in;
        let dx = (rho0 * rho0 - cy * cy).max(0.0).sqrt();
        let psi = (-cy).atan2(dx) - theta;
        let rho = self.radius_at(psi);
        cx + (rho * rho - cy * cy).max(0.0).sqrt()
    }
}
