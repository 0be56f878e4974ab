//! The exact surface: the Z-slide motion of eq 2-1..2-15 with the tool-centre
//! compensation of FOREX4 (appendix B-1), the reference every approximation of
//! the command (series, interpolation, fixed point) is measured against.
//!
//! # Definitions (all lengths in inches)
//!
//! Paraboloid `x1² + y1² = c·z1` (eq 2-1 with `c = 4p`), sector centred
//! `S_y` off axis, tool-nose radius `r_t`. With `sin θ = 2S_y/√(c²+4S_y²)`
//! (eq 2-3) and `R0 = S_y/sin θ = √(c²+4S_y²)/2`:
//!
//! * `Y_t(x, φ)` is eq 2-9 at *contact* radius `x` (φ of eq 2-5,
//!   `x3 = R cos φ`, `y3 = R sin φ`);
//! * `Y(x) = R0·(1 − √(1 − (x/R0)²))` is the corrected eq 2-14 (the printed
//!   one lost the leading `1 −`): the ridge `max_φ Y_t(x, φ)` of eq 2-11/2-13,
//!   which is a circle of radius `R0` about `(0, R0)`;
//! * `Z(x, φ) = Y_t(x, φ) − Y(x)` (eq 2-15), so `max_φ Z = 0`, `Z ≤ 0`.
//!
//! # What "the command at tool-centre X" means
//!
//! The X slide carries the tool *centre*; the interferometer reads its radius
//! `X`. FOREX4 offsets the contact point along the normal of the ridge circle
//! `Y(x)`: the tool centre of contact point `x1` is at radius
//! `X = x1 − r_t·sin α(x1)`, `tan α = x1/(R0 − Y(x1))`, axial
//! `Y(x1) + r_t·cos α`. The Z-slide command when the tool centre is at `X` is
//! therefore **`Z(x1(X), φ)`**, the surface's Z at the contact radius whose
//! tool centre is at `X`; the axial (Y) slide follows the smooth
//! `Y(x1) + r_t cos α`. This is exactly what Table 2-2 tabulates (it matches
//! to the last printed digit) and what [`Surface::z`] returns.
//!
//! FOREX4 stops the `x1` iteration after three passes; [`Surface::contact_radius`]
//! iterates to convergence (the map contracts by `r_t/R0 ≈ 8e-4` per pass, so
//! it takes about five). Because the ridge is a circle, `sin α = x1/R0`
//! exactly and the fixed point is `x1 = X·R0/(R0 − r_t)`; the tests check the
//! iteration against that closed form, and the derivative `dx1/dX` uses it.
//!
//! FOREX4 offsets along the ridge normal, not along the normal of the
//! surface's own meridional profile `Y_t(·, φ)`. For a nose arc in the
//! meridional plane (tool on centre height) the cut profile at φ is the
//! envelope of the arcs at successive X, so the profile normal is the exact
//! one. The two differ by `r_t·ε²/2`, ε the angle between the normals (≈ the
//! Z slope ∂Z/∂X): 0.05 µin at 4 in, 0.22 µin at 7.2 in, 0.30 µin at 8 in,
//! always with the profile-normal command higher. [`Compensation`] selects the
//! model; the default, and the reference of every accuracy figure, is
//! FOREX4's (Table 2-2 is built on it, and the table header has no field
//! that would tell a reader which model a table was made for).
//!
//! # Numerics
//!
//! `Z` is a difference of quantities of order `x²/(2R0)` ≈ 0.2 in, and eq 2-9
//! as printed subtracts numbers of order `S_y/sin³θ` ≈ 5300 in (FOREX4's `FUN`
//! loses ~1e-12 in to rounding there). Every function here is written in a
//! cancellation-free form (`1 − √(1+u) = −u/(1+√(1+u))`), so the absolute
//! rounding error of `Z` is ~1e-17 in.

use std::fmt;

/// c of the dissertation's FOREX4 (the text's focal length 79.15 in gives
/// c = 316.6; 316.7 is what reproduces Table 2-2).
pub const DISSERTATION_C_IN: f64 = 316.7;
/// Off-axis distance of the sector centre.
pub const DISSERTATION_SY_IN: f64 = 28.0;
/// Tool-nose radius.
pub const DISSERTATION_TOOL_RADIUS_IN: f64 = 0.125;

/// A geometry that cannot describe a surface, naming the field and its limit.
#[derive(Clone, Debug, PartialEq)]
pub enum SurfaceError {
    /// A size that must be a positive finite number is not.
    NotPositive { field: &'static str, value: f64 },
    /// A size that may be zero is negative or not finite.
    Negative { field: &'static str, value: f64 },
    /// The tool radius is not small against the ridge radius `R0`.
    ToolTooLarge {
        field: &'static str,
        value: f64,
        limit: f64,
    },
    /// An X outside the range where eq 2-15 has its two equal maxima per turn
    /// (eq 2-11), i.e. where `Z ≤ 0` with `max Z = 0`.
    XOutOfDomain {
        field: &'static str,
        value: f64,
        limit: f64,
    },
    /// The contact-radius iteration did not converge (cannot happen for a
    /// geometry that passed validation; reported rather than looping).
    NoConvergence { x: f64 },
}

impl fmt::Display for SurfaceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotPositive { field, value } => {
                write!(f, "{field} = {value}: must be a finite number > 0")
            }
            Self::Negative { field, value } => {
                write!(f, "{field} = {value}: must be a finite number >= 0")
            }
            Self::ToolTooLarge { field, value, limit } => write!(
                f,
                "{field} = {value} in: must be below {limit:.6} in (a tenth of the ridge radius R0 = S_y/sin θ)"
            ),
            Self::XOutOfDomain { field, value, limit } => write!(
                f,
                "{field} = {value} in: the surface (eq 2-15 with its maxima of eq 2-11) is defined for 0 <= X <= {limit:.6} in at this geometry"
            ),
            Self::NoConvergence { x } => {
                write!(f, "contact-radius iteration did not converge at X = {x} in")
            }
        }
    }
}

impl std::error::Error for SurfaceError {}

/// The off-axis paraboloid sector and tool, with the derived constants of
/// FOREX4. Construct with [`Surface::new`] (validated).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    c: f64,
    s_y: f64,
    r_t: f64,
    sin_t: f64,
    cos_t: f64,
    /// `cot θ = c/(2 S_y)`, FOREX4's `A3`.
    cot_t: f64,
    /// Ridge radius `R0 = S_y/sin θ = c/(2 cos θ)`.
    r0: f64,
    /// FOREX4's `A1 = 2 sin²θ cos θ / S_y`.
    a1: f64,
    /// FOREX4's `A2 = sin⁴θ / S_y²`.
    a2: f64,
    /// Largest tool-centre X of the domain (see [`Surface::x_limit`]).
    x_limit: f64,
    comp: Compensation,
}

/// How the tool-nose radius is compensated (module doc, "What the command
/// at tool-centre X means").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Compensation {
    /// FOREX4: offset along the normal of the ridge circle `Y(x)`, one
    /// contact radius per X for all φ. Reproduces Table 2-2; the default.
    #[default]
    Forex4,
    /// Offset along the normal of the surface's own meridional profile
    /// `Y_t(·, φ)`: the exact envelope of a nose arc lying in the meridional
    /// plane. Differs from FOREX4 by `r_t·ε²/2` (≤ 0.22 µin to 7.2 in).
    ProfileNormal,
}

/// The surface at one tool-centre X: contact radius solved once, then any φ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Section {
    surf: Surface,
    /// Tool-centre radius.
    pub x: f64,
    /// Contact radius `x1` whose tool centre is at `x`.
    pub x1: f64,
    /// Ridge height `Y(x1)` (corrected eq 2-14).
    pub y: f64,
    /// Passes of the FOREX4 iteration needed to converge.
    pub iterations: u32,
}

impl Surface {
    /// Validates and builds. `c` is the paraboloid parameter (`x²+y² = c·z`,
    /// `c = 4 × focal length`).
    pub fn new(c: f64, s_y: f64, tool_radius: f64) -> Result<Self, SurfaceError> {
        positive("surface.c_in", c)?;
        positive("surface.s_y_in", s_y)?;
        if !(tool_radius.is_finite() && tool_radius >= 0.0) {
            return Err(SurfaceError::Negative {
                field: "surface.tool_radius_in",
                value: tool_radius,
            });
        }
        let d = c.hypot(2.0 * s_y);
        let sin_t = 2.0 * s_y / d;
        let cos_t = c / d;
        let r0 = 0.5 * d;
        if tool_radius >= 0.1 * r0 {
            return Err(SurfaceError::ToolTooLarge {
                field: "surface.tool_radius_in",
                value: tool_radius,
                limit: 0.1 * r0,
            });
        }
        let mut s = Self {
            c,
            s_y,
            r_t: tool_radius,
            sin_t,
            cos_t,
            cot_t: c / (2.0 * s_y),
            r0,
            a1: 2.0 * sin_t * sin_t * cos_t / s_y,
            a2: (sin_t * sin_t / s_y).powi(2),
            x_limit: 0.0,
            comp: Compensation::Forex4,
        };
        s.x_limit = s.domain_limit();
        Ok(s)
    }

    /// The dissertation's part: c = 316.7 in, S_y = 28 in, r_t = 0.125 in.
    pub fn dissertation() -> Self {
        Self::new(
            DISSERTATION_C_IN,
            DISSERTATION_SY_IN,
            DISSERTATION_TOOL_RADIUS_IN,
        )
        .unwrap_or_else(|_| unreachable!("the dissertation geometry is valid"))
    }

    /// The surface a table image was generated for (its header's geometry,
    /// nano-inches), with FOREX4's compensation: the reference to check a
    /// table or the firmware's command path against.
    pub fn from_table_geometry(g: &zslide::table::Geometry) -> Result<Self, SurfaceError> {
        // Division, not multiplication by 1e-9: 316_700_000_000 / 1e9 is the
        // double nearest 316.7, as in the TOML the table came from.
        Self::new(
            g.c_nin as f64 / 1e9,
            g.s_y_nin as f64 / 1e9,
            g.tool_radius_nin as f64 / 1e9,
        )
    }

    /// Same surface, another tool radius.
    pub fn with_tool_radius(&self, tool_radius: f64) -> Result<Self, SurfaceError> {
        Ok(Self::new(self.c, self.s_y, tool_radius)?.with_compensation(self.comp))
    }

    /// Same surface, another tool-compensation model.
    pub fn with_compensation(&self, comp: Compensation) -> Self {
        Self { comp, ..*self }
    }

    pub fn compensation(&self) -> Compensation {
        self.comp
    }

    pub fn c(&self) -> f64 {
        self.c
    }
    pub fn s_y(&self) -> f64 {
        self.s_y
    }
    pub fn tool_radius(&self) -> f64 {
        self.r_t
    }
    pub fn sin_theta(&self) -> f64 {
        self.sin_t
    }
    pub fn cos_theta(&self) -> f64 {
        self.cos_t
    }
    /// Ridge radius `R0 = S_y/sin θ`.
    pub fn r0(&self) -> f64 {
        self.r0
    }

    /// Largest tool-centre X for which the surface is defined in the sense of
    /// eq 2-11..2-15: the two maxima per turn exist (`|sin φ_max| ≤ 1`), so
    /// that `Y(X)` is the ridge and `Z ≤ 0`. About 56 in for the dissertation's
    /// part, far outside its 8 in sector.
    pub fn x_limit(&self) -> f64 {
        self.x_limit
    }

    fn domain_limit(&self) -> f64 {
        // Contact-radius limit from |eq 2-11 argument| = 1, found by
        // bisection on x1 in (0, R0); the argument grows monotonically.
        let arg = |x1: f64| self.sin_phi_max(x1).abs();
        let (mut lo, mut hi) = (0.0, self.r0 * (1.0 - 1e-12));
        if arg(hi) <= 1.0 {
            lo = hi;
        } else {
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if arg(mid) <= 1.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
        }
        // Tool-centre X of that contact radius (closed form, see module doc).
        lo * (1.0 - self.r_t / self.r0)
    }

    /// `sin φ` at the maxima of `Y_t` at contact radius `x1` (eq 2-11).
    pub fn sin_phi_max(&self, x1: f64) -> f64 {
        if x1 == 0.0 {
            return 0.0;
        }
        let w = (x1 / self.r0).powi(2);
        // 1 − √(1−w) without cancellation.
        let one_minus = w / (1.0 + (1.0 - w).sqrt());
        -(self.c / (2.0 * x1 * self.sin_t)) * one_minus
    }

    /// Ridge `Y(x1) = max_φ Y_t(x1, φ)`: the corrected eq 2-14.
    pub fn ridge(&self, x1: f64) -> f64 {
        let w = (x1 / self.r0).powi(2);
        self.r0 * w / (1.0 + (1.0 - w).sqrt())
    }

    /// `dY/dx1` of the ridge.
    pub fn ridge_slope(&self, x1: f64) -> f64 {
        let v = x1 / self.r0;
        v / (1.0 - v * v).sqrt()
    }

    /// `Y_t(x1, φ)` of eq 2-9 at contact radius `x1`, given `s = sin φ` and
    /// `cc = cos² φ` (passed separately so neither is formed as `1 − other`).
    pub fn yt_sc(&self, x1: f64, s: f64, cc: f64) -> f64 {
        let u = self.a1 * x1 * s - self.a2 * x1 * x1 * cc;
        let q1 = 1.0 + (1.0 + u).sqrt();
        // A(1 − √(1+u)) + cot θ·x·s with A·A1 = 2 cot θ, A·A2 = 1/R0.
        self.cot_t * x1 * s * u / (q1 * q1) + x1 * x1 * cc / (self.r0 * q1)
    }

    /// `∂Y_t/∂x` at radius `x`, given `s = sin φ`, `cc = cos²φ`.
    fn slope_sc(&self, x: f64, s: f64, cc: f64) -> f64 {
        let u = self.a1 * x * s - self.a2 * x * x * cc;
        let q = (1.0 + u).sqrt();
        self.cot_t * s * u / (q * (1.0 + q)) + x * cc / (self.r0 * q)
    }

    /// `∂Y_t/∂φ` at radius `x`, given `s = sin φ`, `c = cos φ`.
    fn dyt_dphi(&self, x: f64, s: f64, c: f64) -> f64 {
        let cc = c * c;
        let u = self.a1 * x * s - self.a2 * x * x * cc;
        let q = (1.0 + u).sqrt();
        // dY_t/dφ = x cos φ [cot θ·u/(1+q) − x s/R0]/q, the bracket rewritten
        // with cot θ·A1 = 2cos²θ/R0 so that nothing cancels.
        let bracket = -(x * s / self.r0) * (2.0 * self.sin_t * self.sin_t + u / (1.0 + q))
            / (1.0 + q)
            - self.cot_t * self.a2 * x * x * cc / (1.0 + q);
        x * c * bracket / q
    }

    /// Eq 2-15 at contact radius `x1` (no tool compensation).
    pub fn z_contact(&self, x1: f64, phi: f64) -> f64 {
        let (s, c) = phi.sin_cos();
        self.yt_sc(x1, s, c * c) - self.ridge(x1)
    }

    /// Contact radius `x1` whose tool centre is at `x` (FOREX4's iteration,
    /// run to convergence). Returns `(x1, passes)`.
    pub fn contact_radius(&self, x: f64) -> Result<(f64, u32), SurfaceError> {
        if !(x.is_finite() && (0.0..=self.x_limit).contains(&x)) {
            return Err(SurfaceError::XOutOfDomain {
                field: "x",
                value: x,
                limit: self.x_limit,
            });
        }
        let mut x1 = x;
        for pass in 1..=64 {
            // α of FOREX4: tan α = x1 / (R0 − Y(x1)).
            let alpha = (x1 / (self.r0 - self.ridge(x1))).atan();
            let xtc = x1 - self.r_t * alpha.sin();
            let next = x + (x1 - xtc);
            if (next - x1).abs() <= 2.0 * f64::EPSILON * next.abs().max(f64::MIN_POSITIVE) {
                return Ok((next, pass));
            }
            x1 = next;
        }
        Err(SurfaceError::NoConvergence { x })
    }

    /// `dx1/dX`: constant, because the ridge is a circle (module doc).
    pub fn contact_gain(&self) -> f64 {
        self.r0 / (self.r0 - self.r_t)
    }

    /// The surface at tool-centre radius `x`.
    pub fn section(&self, x: f64) -> Result<Section, SurfaceError> {
        let (x1, iterations) = self.contact_radius(x)?;
        Ok(Section {
            surf: *self,
            x,
            x1,
            y: self.ridge(x1),
            iterations,
        })
    }

    /// The Z-slide command at tool-centre radius `x` and spindle angle `phi`
    /// (radians): `Z(x1(x), φ)`, inches, ≤ 0. Panics never; an X outside the
    /// domain is an error.
    pub fn z(&self, x: f64, phi: f64) -> Result<f64, SurfaceError> {
        Ok(self.section(x)?.z(phi))
    }
}

impl Section {
    pub fn surface(&self) -> &Surface {
        &self.surf
    }

    /// `Z` as a function of `s = sin φ` alone (eq 2-15 depends on φ only
    /// through `sin φ` and `cos² φ = (1−s)(1+s)`; so does the profile-normal
    /// compensation).
    pub fn z_of_sin(&self, s: f64) -> f64 {
        self.z_sc(s, (1.0 - s) * (1.0 + s))
    }

    /// `Z(X, φ)`, inches.
    pub fn z(&self, phi: f64) -> f64 {
        let (s, c) = phi.sin_cos();
        self.z_sc(s, c * c)
    }

    fn z_sc(&self, s: f64, cc: f64) -> f64 {
        let p = &self.surf;
        match p.comp {
            Compensation::Forex4 => p.yt_sc(self.x1, s, cc) - self.y,
            Compensation::ProfileNormal => {
                let xc = self.profile_contact(s, cc);
                let tan_b = p.slope_sc(xc, s, cc);
                // r_t (cos β − cos α) with cos α = √(1 − (x1/R0)²).
                let sin_a = self.x1 / p.r0;
                let cos_a = ((1.0 - sin_a) * (1.0 + sin_a)).sqrt();
                let cos_b = 1.0 / tan_b.hypot(1.0);
                (p.yt_sc(xc, s, cc) - self.y) + p.r_t * (cos_b - cos_a)
            }
        }
    }

    /// Contact radius on the profile `Y_t(·, φ)` whose normal-offset tool
    /// centre is at radius X: `xc − r_t sin β(xc) = X`, `tan β = ∂Y_t/∂x`.
    /// Fixed point from FOREX4's `x1`; contracts by `r_t·|∂²Y_t/∂x²| ≈ 1e-3`.
    fn profile_contact(&self, s: f64, cc: f64) -> f64 {
        let p = &self.surf;
        let mut xc = self.x1;
        for _ in 0..64 {
            let tan_b = p.slope_sc(xc, s, cc);
            let next = self.x + p.r_t * tan_b / tan_b.hypot(1.0);
            let done = (next - xc).abs() <= 4.0 * f64::EPSILON * next.abs().max(1.0);
            xc = next;
            if done {
                break;
            }
        }
        xc
    }

    /// `∂Z/∂φ` at this X, inches per radian (exact, cancellation-free). For
    /// the profile-normal model the envelope theorem gives `∂Y_t/∂φ` at the
    /// contact point.
    pub fn dz_dphi(&self, phi: f64) -> f64 {
        let p = &self.surf;
        let (s, c) = phi.sin_cos();
        let x = match p.comp {
            Compensation::Forex4 => self.x1,
            Compensation::ProfileNormal => self.profile_contact(s, c * c),
        };
        p.dyt_dphi(x, s, c)
    }

    /// `∂Z/∂X` at this tool-centre X, inches per inch: FOREX4,
    /// `(∂Y_t/∂x1 − Y'(x1))·dx1/dX`; profile-normal (envelope theorem),
    /// `tan β − tan α`.
    pub fn dz_dx(&self, phi: f64) -> f64 {
        let p = &self.surf;
        let (s, c) = phi.sin_cos();
        let cc = c * c;
        match p.comp {
            Compensation::Forex4 => {
                (p.slope_sc(self.x1, s, cc) - p.ridge_slope(self.x1)) * p.contact_gain()
            }
            Compensation::ProfileNormal => {
                let xc = self.profile_contact(s, cc);
                p.slope_sc(xc, s, cc) - p.ridge_slope(self.x1)
            }
        }
    }

    /// Axial position of the tool centre that the Y slide follows:
    /// `Y(x1) + r_t cos α` (FOREX4's `YTC`).
    pub fn tool_centre_axial(&self) -> f64 {
        let p = &self.surf;
        let sin_a = self.x1 / p.r0;
        self.y + p.r_t * ((1.0 - sin_a) * (1.0 + sin_a)).sqrt()
    }
}

fn positive(field: &'static str, v: f64) -> Result<(), SurfaceError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(SurfaceError::NotPositive { field, value: v })
    }
}

#[cfg(test)]
mod tests;
