//! The scenario's `[errors]` section: the levels of the error sources
//! beyond the loop (issue 21). Data only, so that the scenario reads it
//! without reaching into the cut; their mechanisms are `cut::errors`.

use serde::Deserialize;

/// `[errors]` of a scenario: the levels of the sources. Every field is
/// optional (absent = 0: the source is off).
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct ErrorLevels {
    /// Gauge scale error ε (fraction; + = reads high): the loop drives the
    /// reading to the command, so the tool runs at Z/(1+ε) and leaves
    /// −ε·Z.
    pub gauge_scale_error: f64,
    /// Gauge nonlinearity: peak deviation from its line at full range
    /// (±0.010 in), µin, a quadratic bow `n (z/range)²`.
    pub gauge_nonlinearity_uin: f64,
    /// Gauge zero drift, µin per hour (+: reads high, the tool runs low).
    pub gauge_drift_uin_per_h: f64,
    /// X-zero error, in: the interferometer reads X + δ (the zero was set
    /// by hand at the axis, chapter 5); the command is Z(X + δ).
    pub x_zero_error_in: f64,
    /// Spindle axial error motion, synchronous part: amplitude, µin, at
    /// `spindle_sync_per_rev` per revolution (part frame).
    pub spindle_sync_uin: f64,
    pub spindle_sync_per_rev: u32,
    /// Spindle axial error motion, asynchronous part: RMS, µin (first-order
    /// noise of `spindle_async_bw_hz`).
    pub spindle_async_uin: f64,
    pub spindle_async_bw_hz: f64,
    /// Mains hum at the power amplifier's input, mV peak, and its
    /// frequency (chapter 6: ≥ 20 mV of noise reached the amplifier).
    pub amp_hum_mv: f64,
    pub amp_hum_frequency_hz: f64,
    /// Tool nose recession by wear, µin per 1000 in of cut length.
    pub tool_wear_uin_per_kin: f64,
    /// Thermal drift of the tool against the part along +Y_t, µin per hour
    /// of the pass.
    pub thermal_drift_uin_per_h: f64,
    /// The 1983 command generator (`analog1983::generator`), used by
    /// `--controller legacy-analog` in place of the firmware's command when
    /// `gen_calibrated_rpm > 0`: the speed its rate and amplitude were
    /// trimmed at (chapter 3: 5 V at 300 rpm), its tachometer's rate error
    /// (fraction), the reset one-shot's pulse (µs) and the mismatch of its
    /// multipliers' offsets (mV).
    pub gen_calibrated_rpm: f64,
    pub gen_tach_rate_error: f64,
    pub gen_reset_hold_us: f64,
    pub gen_multiplier_offset_mv: f64,
    /// Tilt the part's face gives the CMM's levelling (the face not flat
    /// under the three probe points), µin per in of radius, and the
    /// part-frame angle φ0 (degrees) where it crosses zero rising: the
    /// CMM's reading gains `δ·X·sin(φ − φ0)`, the part does not
    /// (`cut::cmm`).
    pub face_tilt_uin_per_in: f64,
    pub face_tilt_phase_deg: f64,
    /// The part as a plate clamped on the faceplate (`cut::ringing`):
    /// the faceplate's radius, the part's outer radius and thickness, in
    /// (chapter 5), its material (modulus psi, density lb/in³, Poisson's
    /// ratio) and the first mode's damping ratio. `part_thickness_in = 0`:
    /// the part is rigid.
    pub part_support_radius_in: f64,
    pub part_outer_radius_in: f64,
    pub part_thickness_in: f64,
    pub part_modulus_psi: f64,
    pub part_density_lb_per_in3: f64,
    pub part_poisson: f64,
    pub part_mode_zeta: f64,
    /// Broadband cutting-force fluctuation (chip formation), lbf RMS,
    /// white over the loop tick's band, on the tool and on the part.
    pub cut_force_noise_lbf: f64,
    /// The 1983 command path's first-order lag ahead of the position
    /// loop's summing junction (the generator's output stage, outside the
    /// loop Figure 4-33 measured), µs: the 1983 loop follows the command
    /// lagged by `atan(ωτ)` (`analog1983::lag`).
    pub cmd_lag_us: f64,
    /// The cutting force's surface-speed dependence (chapter 5: "the
    /// relative velocity between tool and part ... decreases with radius
    /// and permits less time for relief of tool cutting forces"): the
    /// force is `(V_ref/V)^n` times the force model's, `V` the surface
    /// speed at the tool, `n` this exponent and `V_ref` the speed the
    /// force constants hold at, ft/min (`cut::errors`).
    pub force_speed_exponent: f64,
    pub force_speed_ref_ft_per_min: f64,
}

impl ErrorLevels {
    /// Range checks naming the field.
    pub fn validate(&self) -> anyhow::Result<()> {
        let checks: [(&str, f64, f64, f64); 30] = [
            ("errors.cmd_lag_us", self.cmd_lag_us, 0.0, 100_000.0),
            (
                "errors.force_speed_exponent",
                self.force_speed_exponent,
                0.0,
                2.0,
            ),
            (
                "errors.force_speed_ref_ft_per_min",
                self.force_speed_ref_ft_per_min,
                0.0,
                1e5,
            ),
            (
                "errors.face_tilt_uin_per_in",
                self.face_tilt_uin_per_in,
                -1000.0,
                1000.0,
            ),
            (
                "errors.face_tilt_phase_deg",
                self.face_tilt_phase_deg,
                -360.0,
                360.0,
            ),
            (
                "errors.part_support_radius_in",
                self.part_support_radius_in,
                0.0,
                100.0,
            ),
            (
                "errors.part_outer_radius_in",
                self.part_outer_radius_in,
                0.0,
                100.0,
            ),
            (
                "errors.part_thickness_in",
                self.part_thickness_in,
                0.0,
                20.0,
            ),
            ("errors.part_modulus_psi", self.part_modulus_psi, 0.0, 1e9),
            (
                "errors.part_density_lb_per_in3",
                self.part_density_lb_per_in3,
                0.0,
                1.0,
            ),
            ("errors.part_poisson", self.part_poisson, 0.0, 0.5),
            ("errors.part_mode_zeta", self.part_mode_zeta, 0.0, 1.0),
            (
                "errors.cut_force_noise_lbf",
                self.cut_force_noise_lbf,
                0.0,
                100.0,
            ),
            (
                "errors.gauge_scale_error",
                self.gauge_scale_error,
                -0.2,
                0.2,
            ),
            (
                "errors.gauge_nonlinearity_uin",
                self.gauge_nonlinearity_uin,
                -1000.0,
                1000.0,
            ),
            (
                "errors.gauge_drift_uin_per_h",
                self.gauge_drift_uin_per_h,
                -1000.0,
                1000.0,
            ),
            ("errors.x_zero_error_in", self.x_zero_error_in, -0.1, 0.1),
            (
                "errors.spindle_sync_uin",
                self.spindle_sync_uin,
                0.0,
                1000.0,
            ),
            (
                "errors.spindle_sync_per_rev",
                f64::from(self.spindle_sync_per_rev),
                0.0,
                64.0,
            ),
            (
                "errors.spindle_async_uin",
                self.spindle_async_uin,
                0.0,
                1000.0,
            ),
            (
                "errors.spindle_async_bw_hz",
                self.spindle_async_bw_hz,
                0.0,
                5000.0,
            ),
            ("errors.amp_hum_mv", self.amp_hum_mv, 0.0, 1000.0),
            (
                "errors.amp_hum_frequency_hz",
                self.amp_hum_frequency_hz,
                0.0,
                5000.0,
            ),
            (
                "errors.tool_wear_uin_per_kin",
                self.tool_wear_uin_per_kin,
                0.0,
                100.0,
            ),
            (
                "errors.thermal_drift_uin_per_h",
                self.thermal_drift_uin_per_h,
                -1000.0,
                1000.0,
            ),
            (
                "errors.gen_calibrated_rpm",
                self.gen_calibrated_rpm,
                0.0,
                3000.0,
            ),
            (
                "errors.gen_tach_rate_error",
                self.gen_tach_rate_error,
                -0.1,
                0.1,
            ),
            (
                "errors.gen_reset_hold_us",
                self.gen_reset_hold_us,
                0.0,
                10_000.0,
            ),
            (
                "errors.gen_multiplier_offset_mv",
                self.gen_multiplier_offset_mv,
                -1000.0,
                1000.0,
            ),
            (
                "errors.spindle_async_bw_hz (needed with spindle_async_uin > 0)",
                if self.spindle_async_uin > 0.0 {
                    self.spindle_async_bw_hz
                } else {
                    1.0
                },
                1e-3,
                5000.0,
            ),
        ];
        for (f, v, lo, hi) in checks {
            if !(v.is_finite() && v >= lo && v <= hi) {
                anyhow::bail!("{f} = {v} is out of range [{lo}, {hi}]");
            }
        }
        if self.amp_hum_mv > 0.0 && self.amp_hum_frequency_hz <= 0.0 {
            anyhow::bail!("errors.amp_hum_frequency_hz must be > 0 when errors.amp_hum_mv > 0");
        }
        let gen_set = self.gen_tach_rate_error != 0.0
            || self.gen_reset_hold_us != 0.0
            || self.gen_multiplier_offset_mv != 0.0;
        if gen_set && self.gen_calibrated_rpm <= 0.0 {
            anyhow::bail!(
                "errors.gen_tach_rate_error/gen_reset_hold_us/gen_multiplier_offset_mv are set but \
                 errors.gen_calibrated_rpm is not: the 1983 command generator needs the speed it was trimmed at"
            );
        }
        if self.force_speed_exponent > 0.0 && self.force_speed_ref_ft_per_min <= 0.0 {
            anyhow::bail!(
                "errors.force_speed_exponent > 0 needs errors.force_speed_ref_ft_per_min > 0 \
                 (the surface speed the force constants hold at)"
            );
        }
        if self.part_thickness_in > 0.0 {
            let ok = self.part_outer_radius_in > self.part_support_radius_in
                && self.part_support_radius_in > 0.0
                && self.part_modulus_psi > 0.0
                && self.part_density_lb_per_in3 > 0.0
                && self.part_mode_zeta > 0.0
                && self.part_mode_zeta < 1.0;
            if !ok {
                anyhow::bail!(
                    "errors.part_thickness_in > 0 asks for the part's overhang mode: it needs \
                     0 < part_support_radius_in < part_outer_radius_in, part_modulus_psi > 0, \
                     part_density_lb_per_in3 > 0 and 0 < part_mode_zeta < 1"
                );
            }
        }
        Ok(())
    }
}
