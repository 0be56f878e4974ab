//! The machine's error sources beyond the loop (issue 21): the scenario's
//! `[errors]` levels and their mechanisms, applied tick by tick by the
//! cutter (`run`). Every level is either from the seeds or a labelled
//! assumption (docs/CUT.md, "Error sources"); which ones a cut applies is
//! chosen by `--errors` ([`Selection`]).
//!
//! Signs: heights along +Y_t (the part frame, `frame`); a source that
//! lifts the tool's cutting point off the part leaves excess stock
//! (positive on the CMM).

use std::f64::consts::TAU;

pub use crate::error_levels::ErrorLevels;

/// One error source (the rows of `cut --budget`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Source {
    GaugeScale,
    GaugeNonlinearity,
    GaugeDrift,
    XZero,
    SpindleMotion,
    AmpHum,
    ToolWear,
    Thermal,
    /// The 1983 command generator (tach rate, index reset, amplitude
    /// trimmed at one speed; `analog1983::generator`): the 1983 loop only.
    CommandGenerator,
    /// The face the CMM levels on, not flat under its three probe
    /// points: a tilt of the reading, not of the part (`cmm`).
    FaceTilt,
    /// The overhang's first mode under the cutting force (`ringing`).
    PartRinging,
    /// A first-order lag on the 1983 loop's command path
    /// (`analog1983::lag`): the 1983 loop only.
    CommandLag,
    /// The cutting force rising as the surface speed falls toward the
    /// centre (chapter 5's explanation of the centre bias).
    SurfaceSpeedForce,
}

impl Source {
    pub const ALL: [Source; 13] = [
        Source::GaugeScale,
        Source::GaugeNonlinearity,
        Source::GaugeDrift,
        Source::XZero,
        Source::SpindleMotion,
        Source::AmpHum,
        Source::ToolWear,
        Source::Thermal,
        Source::CommandGenerator,
        Source::FaceTilt,
        Source::PartRinging,
        Source::CommandLag,
        Source::SurfaceSpeedForce,
    ];
    pub fn name(self) -> &'static str {
        match self {
            Source::GaugeScale => "gauge scale",
            Source::GaugeNonlinearity => "gauge nonlinearity",
            Source::GaugeDrift => "gauge drift",
            Source::XZero => "X zero",
            Source::SpindleMotion => "spindle error motion",
            Source::AmpHum => "120 Hz at the amplifier",
            Source::ToolWear => "tool wear",
            Source::Thermal => "thermal drift",
            Source::CommandGenerator => "1983 command generator",
            Source::FaceTilt => "face tilt (CMM levelling)",
            Source::PartRinging => "part ringing",
            Source::CommandLag => "1983 command lag",
            Source::SurfaceSpeedForce => "surface-speed force",
        }
    }
    /// Whether `levels` give this source a non-zero level.
    pub fn present(self, l: &ErrorLevels) -> bool {
        match self {
            Source::GaugeScale => l.gauge_scale_error != 0.0,
            Source::GaugeNonlinearity => l.gauge_nonlinearity_uin != 0.0,
            Source::GaugeDrift => l.gauge_drift_uin_per_h != 0.0,
            Source::XZero => l.x_zero_error_in != 0.0,
            Source::SpindleMotion => l.spindle_sync_uin != 0.0 || l.spindle_async_uin != 0.0,
            Source::AmpHum => l.amp_hum_mv != 0.0,
            Source::ToolWear => l.tool_wear_uin_per_kin != 0.0,
            Source::Thermal => l.thermal_drift_uin_per_h != 0.0,
            Source::CommandGenerator => l.gen_calibrated_rpm > 0.0,
            Source::FaceTilt => l.face_tilt_uin_per_in != 0.0,
            Source::PartRinging => l.part_thickness_in > 0.0,
            Source::CommandLag => l.cmd_lag_us > 0.0,
            Source::SurfaceSpeedForce => l.force_speed_exponent > 0.0,
        }
    }
    /// Whether the source exists with `controller` (the digital firmware
    /// has no analog command generator and no analog command path).
    pub fn applies(self, controller: crate::fwrig::Controller) -> bool {
        !matches!(self, Source::CommandGenerator | Source::CommandLag)
            || controller == crate::fwrig::Controller::LegacyAnalog
    }
    /// `levels` with only this source kept.
    pub fn alone(self, l: &ErrorLevels) -> ErrorLevels {
        let mut o = ErrorLevels {
            spindle_sync_per_rev: l.spindle_sync_per_rev,
            spindle_async_bw_hz: l.spindle_async_bw_hz,
            amp_hum_frequency_hz: l.amp_hum_frequency_hz,
            ..ErrorLevels::default()
        };
        match self {
            Source::GaugeScale => o.gauge_scale_error = l.gauge_scale_error,
            Source::GaugeNonlinearity => o.gauge_nonlinearity_uin = l.gauge_nonlinearity_uin,
            Source::GaugeDrift => o.gauge_drift_uin_per_h = l.gauge_drift_uin_per_h,
            Source::XZero => o.x_zero_error_in = l.x_zero_error_in,
            Source::SpindleMotion => {
                o.spindle_sync_uin = l.spindle_sync_uin;
                o.spindle_async_uin = l.spindle_async_uin;
            }
            Source::AmpHum => o.amp_hum_mv = l.amp_hum_mv,
            Source::ToolWear => o.tool_wear_uin_per_kin = l.tool_wear_uin_per_kin,
            Source::Thermal => o.thermal_drift_uin_per_h = l.thermal_drift_uin_per_h,
            Source::CommandGenerator => {
                o.gen_calibrated_rpm = l.gen_calibrated_rpm;
                o.gen_tach_rate_error = l.gen_tach_rate_error;
                o.gen_reset_hold_us = l.gen_reset_hold_us;
                o.gen_multiplier_offset_mv = l.gen_multiplier_offset_mv;
            }
            Source::FaceTilt => {
                o.face_tilt_uin_per_in = l.face_tilt_uin_per_in;
                o.face_tilt_phase_deg = l.face_tilt_phase_deg;
            }
            Source::PartRinging => {
                o.part_support_radius_in = l.part_support_radius_in;
                o.part_outer_radius_in = l.part_outer_radius_in;
                o.part_thickness_in = l.part_thickness_in;
                o.part_modulus_psi = l.part_modulus_psi;
                o.part_density_lb_per_in3 = l.part_density_lb_per_in3;
                o.part_poisson = l.part_poisson;
                o.part_mode_zeta = l.part_mode_zeta;
                o.cut_force_noise_lbf = l.cut_force_noise_lbf;
            }
            Source::CommandLag => o.cmd_lag_us = l.cmd_lag_us,
            Source::SurfaceSpeedForce => {
                o.force_speed_exponent = l.force_speed_exponent;
                o.force_speed_ref_ft_per_min = l.force_speed_ref_ft_per_min;
            }
        }
        o
    }
    /// `levels` with this source scaled by `k` (the budget's tolerance
    /// search; sources are linear in their level to first order).
    pub fn scaled(self, l: &ErrorLevels, k: f64) -> ErrorLevels {
        let mut o = self.alone(l);
        o.gauge_scale_error *= k;
        o.gauge_nonlinearity_uin *= k;
        o.gauge_drift_uin_per_h *= k;
        o.x_zero_error_in *= k;
        o.spindle_sync_uin *= k;
        o.spindle_async_uin *= k;
        o.amp_hum_mv *= k;
        o.tool_wear_uin_per_kin *= k;
        o.thermal_drift_uin_per_h *= k;
        o.gen_tach_rate_error *= k;
        o.gen_reset_hold_us *= k;
        o.gen_multiplier_offset_mv *= k;
        o.face_tilt_uin_per_in *= k;
        // The ringing scales with the force that drives it.
        o.cut_force_noise_lbf *= k;
        o.cmd_lag_us *= k;
        o.force_speed_exponent *= k;
        o
    }
    /// The level as the scenario states it, with its unit.
    pub fn level(self, l: &ErrorLevels) -> String {
        match self {
            Source::GaugeScale => format!("ε = {:.2} %", l.gauge_scale_error * 100.0),
            Source::GaugeNonlinearity => format!("{} µin at full range", l.gauge_nonlinearity_uin),
            Source::GaugeDrift => format!("{} µin/h", l.gauge_drift_uin_per_h),
            Source::XZero => format!("{} in", l.x_zero_error_in),
            Source::SpindleMotion => format!(
                "{} µin at {}/rev + {} µin RMS",
                l.spindle_sync_uin, l.spindle_sync_per_rev, l.spindle_async_uin
            ),
            Source::AmpHum => format!("{} mV at {} Hz", l.amp_hum_mv, l.amp_hum_frequency_hz),
            Source::ToolWear => format!("{} µin per 1000 in", l.tool_wear_uin_per_kin),
            Source::Thermal => format!("{} µin/h", l.thermal_drift_uin_per_h),
            Source::CommandGenerator => format!(
                "tach {} %, reset {} µs, offsets {} mV, trimmed at {} rpm",
                l.gen_tach_rate_error * 100.0,
                l.gen_reset_hold_us,
                l.gen_multiplier_offset_mv,
                l.gen_calibrated_rpm
            ),
            Source::FaceTilt => format!(
                "{} µin/in, zero at φ0 = {}°",
                l.face_tilt_uin_per_in, l.face_tilt_phase_deg
            ),
            Source::PartRinging => match super::ringing::PlateMode::of(l) {
                Some(m) => format!(
                    "{:.0} Hz, {:.2e} lbf/in at the rim, ζ {}, force noise {} lbf RMS",
                    m.freq_hz(),
                    m.k_lbf_per_in,
                    l.part_mode_zeta,
                    l.cut_force_noise_lbf
                ),
                None => "rigid".to_string(),
            },
            Source::CommandLag => format!("τ = {} µs, first order", l.cmd_lag_us),
            Source::SurfaceSpeedForce => format!(
                "(V_ref/V)^{}, V_ref = {} ft/min",
                l.force_speed_exponent, l.force_speed_ref_ft_per_min
            ),
        }
    }
}

/// Which sources a cut applies (`--errors`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Selection {
    /// None: the loop's own contribution (the digital loop's default).
    None,
    /// Every source at the scenario's level (the 1983 loop's default: the
    /// shop's machine as chapter 5 cut the part).
    All,
}

impl Selection {
    pub fn name(self) -> &'static str {
        match self {
            Selection::None => "none",
            Selection::All => "all",
        }
    }
}

/// Tool wear: nose recession proportional to the length of cut, from the
/// start of the pass (the outer edge; the pass feeds inward, so the
/// centre is cut last, with the most worn edge).
#[derive(Clone, Debug, PartialEq)]
pub struct ToolWear {
    /// Recession per inch of cut, in/in.
    pub rate: f64,
    /// Length cut so far, in.
    pub cut_length_in: f64,
}

impl ToolWear {
    /// The cut length a pass from `x_pass_start` reaches at tool-centre
    /// radius `x` with feed `f` per revolution: the spiral's length,
    /// `π (x_s² − x²)/f` (its turns are circles to 1e-9).
    pub fn length_to(x_pass_start: f64, x: f64, feed_in: f64) -> f64 {
        let x = x.clamp(0.0, x_pass_start);
        std::f64::consts::PI * (x_pass_start * x_pass_start - x * x) / feed_in
    }
    /// The wear state a band starting at `x` inherits from the pass.
    pub fn at(rate_uin_per_kin: f64, x_pass_start: f64, x: f64, feed_in: f64) -> Self {
        Self {
            rate: rate_uin_per_kin * 1e-6 / 1000.0,
            cut_length_in: Self::length_to(x_pass_start, x, feed_in),
        }
    }
    /// The tool cut `d_turns` of a revolution at radius `x` in contact.
    pub fn step(&mut self, x: f64, d_turns: f64) {
        self.cut_length_in += TAU * x.max(0.0) * d_turns.max(0.0);
    }
    /// Recession of the cutting point, in (+: the tool cuts less deep).
    pub fn recession_in(&self) -> f64 {
        self.rate * self.cut_length_in
    }
}

/// The per-tick state of the sources in one stretch.
pub struct ErrorState {
    pub levels: ErrorLevels,
    pub wear: ToolWear,
    /// Where the whole pass starts (tool-centre X) and its feed, in/s
    /// (positive, inward): the pass time at radius x is `(x_s − x)/v`.
    x_pass_start: f64,
    v_in_per_s: f64,
    /// The pass's spindle speed, rpm (the surface speed's).
    rpm: f64,
    /// Asynchronous axial motion (Ornstein–Uhlenbeck), in, and its stream.
    ou: f64,
    last_t: Option<f64>,
    rng: rand_xoshiro::Xoshiro256PlusPlus,
    /// The part (`with_part`): the axial slide's path `Y(X)` the X zero
    /// also acts through, and `dx1/dX` (surface radius per tool-centre
    /// radius) for the sources given on the part's radius.
    part: Option<crate::surface::Surface>,
    gain: f64,
    /// `dY/dX` of the axial path at the last 0.01 in bucket of X (the
    /// path's curvature, 1/161 in, moves it by 6e-5 across a bucket).
    axial_slope: (i64, f64),
    /// The overhang's mode, the generalised force held since `ring_t`,
    /// and the force noise's stream and held value.
    ringing: Option<super::ringing::Ringing>,
    ring_t: Option<f64>,
    ring_force: f64,
    noise_rng: rand_xoshiro::Xoshiro256PlusPlus,
}

impl ErrorState {
    pub fn new(
        levels: ErrorLevels,
        x_pass_start: f64,
        x_stretch_start: f64,
        feed_per_rev_in: f64,
        rpm: f64,
        seed: u64,
    ) -> Self {
        use rand::SeedableRng;
        Self {
            wear: ToolWear::at(
                levels.tool_wear_uin_per_kin,
                x_pass_start,
                x_stretch_start,
                feed_per_rev_in,
            ),
            ringing: super::ringing::PlateMode::of(&levels).map(super::ringing::Ringing::new),
            levels,
            x_pass_start,
            v_in_per_s: feed_per_rev_in * rpm / 60.0,
            rpm,
            ou: 0.0,
            last_t: None,
            rng: rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x5EED_E770),
            part: None,
            gain: 1.0,
            axial_slope: (i64::MIN, 0.0),
            ring_t: None,
            ring_force: 0.0,
            noise_rng: rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed ^ 0xC41F_0A15),
        }
    }

    /// The part being cut: the X zero then also moves the axial slide's
    /// path, and the ringing acts at the contact radius.
    pub fn with_part(mut self, surf: crate::surface::Surface) -> Self {
        self.gain = surf.contact_gain();
        self.part = Some(surf);
        self
    }

    /// `Y(x_read) − Y(x)`: the axial slide follows its program at the X
    /// it reads (the tape's zero is the same hand-set zero as the
    /// interferometer's, chapter 5), so the tool centre stands
    /// `Y′(x)·δ` higher along +Y_t than the part's radius asks: excess
    /// stock for δ > 0.
    fn axial_x_zero_in(&mut self, x: f64) -> f64 {
        let delta = self.levels.x_zero_error_in;
        let Some(surf) = self.part.as_ref() else {
            return 0.0;
        };
        if delta == 0.0 {
            return 0.0;
        }
        let bucket = crate::fastmath::floor_i64(x * 100.0);
        if bucket != self.axial_slope.0 {
            let xc = (bucket as f64 + 0.5) / 100.0;
            let h = 1e-3;
            let y = |x: f64| {
                surf.section(x.max(0.0))
                    .map_or(0.0, |s| s.tool_centre_axial())
            };
            self.axial_slope = (bucket, (y(xc + h) - y(xc - h)) / (2.0 * h));
        }
        self.axial_slope.1 * delta
    }

    /// The broadband cutting-force fluctuation of this tick, lbf (a new
    /// draw each call; 0 without the source).
    pub fn force_noise_lbf(&mut self) -> f64 {
        use rand_distr::Distribution;
        let sigma = self.levels.cut_force_noise_lbf;
        if sigma == 0.0 {
            return 0.0;
        }
        let w: f64 = rand_distr::StandardNormal.sample(&mut self.noise_rng);
        sigma * w
    }

    /// The overhang's mode is driven by the force `f_lbf` on the tool at
    /// tool-centre radius `x` from `t_s` on (held until the next call).
    pub fn drive_part(&mut self, t_s: f64, x: f64, f_lbf: f64) {
        let Some(r) = self.ringing.as_mut() else {
            return;
        };
        if let Some(t0) = self.ring_t {
            r.step(t_s - t0, self.ring_force);
        }
        self.ring_t = Some(t_s);
        self.ring_force = r.mode.shape(self.gain * x) * f_lbf;
    }

    /// The cutting force's factor at tool-centre radius `x`: `(V_ref/V)^n`,
    /// `V = 2π r N` the surface speed at the contact radius `r` at the
    /// pass's speed `N`; below 1 % of `V_ref` (the last hundredth of the
    /// radius) it is held at that speed's factor.
    pub fn force_speed_factor(&self, x: f64) -> f64 {
        let l = &self.levels;
        if l.force_speed_exponent == 0.0 {
            return 1.0;
        }
        let v_ft_per_min = TAU * self.gain * x * self.rpm / 12.0;
        let v_ref = l.force_speed_ref_ft_per_min;
        (v_ref / v_ft_per_min.max(0.01 * v_ref)).powf(l.force_speed_exponent)
    }

    /// Hours since the pass started when the tool is at radius `x`.
    fn pass_hours(&self, x: f64) -> f64 {
        ((self.x_pass_start - x) / self.v_in_per_s).max(0.0) / 3600.0
    }

    /// The part radius under the tool when the X the firmware reads is the
    /// machine's `x_read` (the interferometer's zero off by δ).
    pub fn x_part(&self, x_read: f64) -> f64 {
        x_read - self.levels.x_zero_error_in
    }

    /// What the gauge adds to the slide's true position, in (scale,
    /// nonlinearity, drift) at gauge position `z` and pass radius `x`.
    pub fn gauge_error_in(&self, z: f64, x: f64) -> f64 {
        let l = &self.levels;
        let u = z / 0.010;
        l.gauge_scale_error * z
            + l.gauge_nonlinearity_uin * 1e-6 * u * u
            + l.gauge_drift_uin_per_h * 1e-6 * self.pass_hours(x)
    }

    /// Whether the gauge needs the per-tick injection (nonzero terms).
    pub fn gauge_active(&self) -> bool {
        let l = &self.levels;
        l.gauge_scale_error != 0.0
            || l.gauge_nonlinearity_uin != 0.0
            || l.gauge_drift_uin_per_h != 0.0
    }

    /// The tool's cutting point above the slide's commanded frame, in,
    /// at time `t_s`, radius `x`, part angle `phi_p` (turns): wear and
    /// thermal drift lift it, the spindle's axial motion toward the tool
    /// (+Y_t) lowers it relative to the part. Advances the noise and the
    /// wear (`d_turns` turned in contact since the last call).
    pub fn tool_offset_in(&mut self, t_s: f64, x: f64, phi_p: f64, d_turns: f64) -> f64 {
        use rand_distr::Distribution;
        let l = &self.levels;
        self.wear.step(x, d_turns);
        let thermal = l.thermal_drift_uin_per_h * 1e-6 * self.pass_hours(x);
        let sync =
            l.spindle_sync_uin * 1e-6 * (TAU * f64::from(l.spindle_sync_per_rev) * phi_p).cos();
        if l.spindle_async_uin > 0.0 {
            let sigma = l.spindle_async_uin * 1e-6;
            let h = self.last_t.map_or(0.0, |t0| (t_s - t0).max(0.0));
            let a = (-TAU * l.spindle_async_bw_hz * h).exp();
            let w: f64 = rand_distr::StandardNormal.sample(&mut self.rng);
            self.ou = if self.last_t.is_none() {
                sigma * w
            } else {
                a * self.ou + sigma * (1.0 - a * a).sqrt() * w
            };
        }
        self.last_t = Some(t_s);
        // The face tilt is not cut: it is the CMM's levelling (`cmm`).
        let ring = self.ringing.as_ref().map_or(0.0, |r| r.at(self.gain * x));
        self.wear.recession_in() + thermal - sync - self.ou + ring + self.axial_x_zero_in(x)
    }

    /// The force the amplifier's input hum puts on the slide, lbf, at
    /// `t_s`: `Kf·K_A·v/R` through the coil's electrical lag (the linear
    /// amplifier in voltage mode, below its limits).
    pub fn hum_force_lbf(&self, t_s: f64, kf: f64, ka: f64, r_ohm: f64, tau_e_s: f64) -> f64 {
        let l = &self.levels;
        if l.amp_hum_mv == 0.0 {
            return 0.0;
        }
        let w = TAU * l.amp_hum_frequency_hz;
        let g = 1.0 / (1.0 + (w * tau_e_s).powi(2)).sqrt();
        let lag = (w * tau_e_s).atan();
        kf * ka * l.amp_hum_mv * 1e-3 / r_ohm * g * (w * t_s - lag).sin()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_runs_start_with_the_wear_a_whole_pass_reaches_at_their_radius() {
        // The whole pass from 7.2502 in stepped tick by tick (20 kHz at
        // 300 rpm, 100 µin/rev) down to 5.01 in, against the state a band
        // starting there inherits in closed form.
        let (f, rpm) = (100e-6, 300.0);
        let mut full = ToolWear::at(0.2, 7.2502, 7.2502, f);
        let dt = 1.0 / 20_000.0;
        let d_turns = rpm / 60.0 * dt;
        let mut x = 7.2502;
        while x > 5.01 {
            full.step(x, d_turns);
            x -= f * d_turns;
        }
        let band = ToolWear::at(0.2, 7.2502, x, f);
        let (a, b) = (full.recession_in(), band.recession_in());
        assert!(a > 50e-6, "{a}");
        assert!((a - b).abs() < 1e-4 * a, "full pass {a} vs band {b}");
    }

    #[test]
    fn wear_rises_toward_the_centre_as_the_cut_length() {
        let f = 100e-6;
        let at = |x| ToolWear::at(0.2, 7.25, x, f).recession_in();
        assert!(at(1.0) > at(4.0) && at(4.0) > at(7.0));
        let expect = 0.2e-9 * std::f64::consts::PI * (7.25f64.powi(2) - 1.0) / f;
        assert!((at(1.0) - expect).abs() < 1e-15);
    }

    #[test]
    fn an_x_zero_error_moves_the_part_under_the_tool_by_minus_delta() {
        let s = ErrorState::new(
            ErrorLevels {
                x_zero_error_in: 0.002,
                ..ErrorLevels::default()
            },
            7.25,
            7.25,
            1e-4,
            300.0,
            1,
        );
        assert!((s.x_part(5.0) - 4.998).abs() < 1e-15);
    }

    #[test]
    fn the_force_factor_is_the_surface_speed_ratio_to_the_power_n() {
        // V_ref at 7.25 in and 300 rpm: 2π·7.25·300/12 ft/min.
        let v_ref = TAU * 7.25 * 300.0 / 12.0;
        let at = |n: f64, rpm: f64, x: f64| {
            ErrorState::new(
                ErrorLevels {
                    force_speed_exponent: n,
                    force_speed_ref_ft_per_min: v_ref,
                    ..ErrorLevels::default()
                },
                7.25,
                7.25,
                1e-4,
                rpm,
                1,
            )
            .force_speed_factor(x)
        };
        assert!((at(0.5, 300.0, 7.25) - 1.0).abs() < 1e-12);
        // X = 1 in: V is 7.25 times lower, the force 7.25^n higher.
        assert!((at(0.5, 300.0, 1.0) - 7.25f64.sqrt()).abs() < 1e-12);
        assert!((at(0.1, 300.0, 1.0) - 7.25f64.powf(0.1)).abs() < 1e-12);
        // 360 rpm: (300/360)^n everywhere.
        assert!((at(1.0, 360.0, 7.25) - 300.0 / 360.0).abs() < 1e-12);
        // Held below 1 % of V_ref (0.0725 in at 300 rpm).
        assert!((at(1.0, 300.0, 0.01) - 100.0).abs() < 1e-9);
        assert_eq!(at(0.0, 300.0, 1.0), 1.0);
    }

    #[test]
    fn out_of_range_levels_are_refused_naming_the_field() {
        let l = ErrorLevels {
            gauge_scale_error: 0.5,
            ..ErrorLevels::default()
        };
        let e = l.validate().unwrap_err().to_string();
        assert!(e.contains("errors.gauge_scale_error"), "{e}");
        let l = ErrorLevels {
            amp_hum_mv: 5.0,
            ..ErrorLevels::default()
        };
        assert!(l.validate().is_err());
    }
}
