//! The plan a machinist runs before cutting a part: is it feasible on this
//! machine at this spindle speed, and how well will the loop follow it?
//!
//! From the exact sections of the part (its harmonics `C_k, S_k` of `Z`
//! at X across the table's range), at spindle speed ω:
//!
//! * **stroke**: `−min Z` against the firmware's command limit
//!   (`servo.command_limit_in`; it clamps beyond);
//! * **velocity, acceleration**: `Ż = ω Σ k(S_k cos kφ − C_k sin kφ)`,
//!   `Z̈ = −ω² Σ k²(C_k cos kφ + S_k sin kφ)`; **coil current**
//!   `(m·Z̈ + b·Ż)/K_f` (the motor's mass, air-film friction and force
//!   constant; cutting force not included) and amplifier voltage
//!   `R·i + K_b·Ż` against the loop's current limit, the amplifier's and
//!   its rail;
//! * **following error**: each harmonic `k` is at `k·rpm/60` Hz; the loop
//!   leaves `S(j2πf)·(C_k − jS_k)` of it, `S` the sensitivity of the
//!   firmware's digital loop on the scenario's plant as `response --loop
//!   digital` measures it (swept sine through the simulated chips). The
//!   map `e(X, φ)` is that sum. It leaves out what the loop adds on top of
//!   feedback (the plant-inverse feedforward of the command's derivatives
//!   and the per-revolution learning), so it is an upper estimate; the
//!   factor to `cut --part` is measured (docs/PARTS.md);
//! * **slope along the cut**: the tool moves along the surface at `ωX`
//!   while the Z slide moves at `Ż`; the flank below the edge rubs when
//!   `atan(|∂Z/∂φ| / X)` exceeds the tool's clearance angle;
//! * **X range** of the table, within the 8 in faceplate radius;
//! * the **highest spindle speed** (within the scenario's speed band)
//!   whose predicted following error stays within the part's bound.

use super::config::LoadedPart;
use super::split::SAMPLES;
use nalgebra::Complex;
use std::f64::consts::TAU;

/// Harmonics the plan follows (the most a table holds).
pub const K: usize = super::table::MAX_HARMONICS;
/// Radius of the faceplate, in (the 16 in part of chapter 5).
pub const FACEPLATE_RADIUS_IN: f64 = 8.0;

/// The machine the plan checks against.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Machine {
    pub scenario: String,
    pub command_limit_in: f64,
    pub loop_current_limit_a: f64,
    pub amplifier_current_limit_a: f64,
    pub rail_v: f64,
    pub mass_slug: f64,
    pub friction_lbf_s_per_ft: f64,
    pub kf_lbf_per_a: f64,
    pub kb_v_s_per_ft: f64,
    pub r_ohm: f64,
    pub bandwidth_hz: f64,
    pub min_rpm: f64,
    pub max_rpm: f64,
}

impl Machine {
    pub fn of(sc: &crate::scenario::Scenario) -> Self {
        let f = &sc.file;
        Self {
            scenario: f.name.clone(),
            command_limit_in: sc.servo_design.command_limit_in,
            loop_current_limit_a: sc.servo_design.current_limit_a,
            amplifier_current_limit_a: f.amplifier.current_limit_a,
            rail_v: f.amplifier.rail_v,
            mass_slug: f.motor.moving_mass_lbm / 32.174,
            friction_lbf_s_per_ft: f.motor.b_lbf_s_per_ft,
            kf_lbf_per_a: f.motor.kf_lbf_per_a,
            kb_v_s_per_ft: f.motor.kb_v_s_per_ft,
            r_ohm: f.motor.r_ohm,
            bandwidth_hz: sc.servo_design.bandwidth_hz,
            min_rpm: f64::from(f.spindle.min_rpm),
            max_rpm: f64::from(f.spindle.max_rpm),
        }
    }
}

/// The part's harmonics across X (computed once; every speed reuses them).
#[derive(Clone, Debug)]
pub struct Sections {
    pub x: Vec<f64>,
    /// `(C_k, S_k)`, k = 0..=K, per X.
    pub h: Vec<Vec<(f64, f64)>>,
    /// Lowest Z per X, in.
    pub z_min: Vec<f64>,
}

pub fn sections(lp: &LoadedPart, points: usize) -> Result<Sections, String> {
    let (lo, hi) = (lp.table.x_min, lp.table.x_null);
    let n = points.max(2);
    let mut s = Sections {
        x: Vec::new(),
        h: Vec::new(),
        z_min: Vec::new(),
    };
    for i in 0..n {
        let x = lo + (hi - lo) * i as f64 / (n - 1) as f64;
        let sec = lp.part.section(x)?;
        let hh = sec.harmonics(K);
        s.x.push(x);
        s.h.push((0..=K).map(|k| (hh.c[k], hh.s[k])).collect());
        s.z_min
            .push(sec.z_samples.iter().cloned().fold(f64::INFINITY, f64::min));
    }
    Ok(s)
}

/// One check: what, the value, its limit, pass.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Check {
    pub name: String,
    pub value: f64,
    pub limit: f64,
    pub unit: String,
    pub ok: bool,
    /// The reason in words when it fails.
    pub reason: Option<String>,
}

fn check(name: &str, value: f64, limit: f64, unit: &str, why: impl FnOnce() -> String) -> Check {
    let ok = value.is_finite() && value <= limit;
    Check {
        name: name.into(),
        value,
        limit,
        unit: unit.into(),
        ok,
        reason: (!ok).then(why),
    }
}

/// The plan at one speed.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Plan {
    pub part: String,
    pub surface: String,
    pub machine: Machine,
    pub rpm: f64,
    pub x_range_in: (f64, f64),
    pub checks: Vec<Check>,
    pub predicted_error_peak_uin: f64,
    pub predicted_error_rms_uin: f64,
    /// Highest harmonic frequency carrying more than 1 µin, Hz.
    pub highest_significant_hz: f64,
    /// Highest speed in the scenario's band keeping the predicted error
    /// within the bound (None: not even the lowest).
    pub max_rpm_for_bound: Option<f64>,
    pub error_bound_uin: f64,
    pub feasible: bool,
    /// `[X][φ]` predicted following error, µin, φ every 360/`PHI` degrees.
    #[serde(skip)]
    pub error_map_uin: Vec<Vec<f64>>,
    #[serde(skip)]
    pub x_in: Vec<f64>,
}

/// φ samples of the maps.
pub const PHI: usize = 72;

/// Peak and RMS of the predicted following-error map at `rpm`, and the map.
pub fn error_map(
    s: &Sections,
    rpm: f64,
    sens: &dyn Fn(f64) -> Complex<f64>,
) -> (f64, f64, Vec<Vec<f64>>) {
    let sk: Vec<Complex<f64>> = (0..=K).map(|k| sens(k as f64 * rpm / 60.0)).collect();
    let (mut peak, mut sum, mut n) = (0.0f64, 0.0, 0usize);
    let mut map = Vec::new();
    for h in &s.h {
        let row: Vec<f64> = (0..PHI)
            .map(|j| {
                let phi = TAU * j as f64 / PHI as f64;
                (1..=K)
                    .map(|k| {
                        let zk = Complex::new(h[k].0, -h[k].1);
                        (sk[k] * zk * Complex::from_polar(1.0, k as f64 * phi)).re
                    })
                    .sum::<f64>()
                    * 1e6
            })
            .collect();
        for v in &row {
            peak = peak.max(v.abs());
            sum += v * v;
            n += 1;
        }
        map.push(row);
    }
    (peak, (sum / n.max(1) as f64).sqrt(), map)
}

/// Plans the part at `rpm` on `machine`, with the loop's sensitivity
/// `sens(f_hz)`.
pub fn plan(
    lp: &LoadedPart,
    s: &Sections,
    machine: &Machine,
    rpm: f64,
    sens: &dyn Fn(f64) -> Complex<f64>,
) -> Plan {
    let w = TAU * rpm / 60.0;
    let (mut v_pk, mut a_pk, mut i_pk, mut u_pk, mut slope) =
        (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut slope_at = (0.0, 0.0);
    let mut hi_hz = 0.0f64;
    let m = machine;
    let slope_x_min = (0.02 * (s.x[s.x.len() - 1] - s.x[0])).max(0.01);
    for (x, h) in s.x.iter().zip(&s.h) {
        for (k, &(c, sn)) in h.iter().enumerate().skip(1) {
            if c.hypot(sn) > 1e-6 {
                hi_hz = hi_hz.max(k as f64 * rpm / 60.0);
            }
        }
        for j in 0..SAMPLES {
            let phi = TAU * j as f64 / SAMPLES as f64;
            let (mut dz, mut d2z) = (0.0, 0.0);
            for (k, &(c, sn)) in h.iter().enumerate().skip(1) {
                let kf = k as f64;
                let (sk, ck) = (kf * phi).sin_cos();
                dz += kf * (sn * ck - c * sk);
                d2z -= kf * kf * (c * ck + sn * sk);
            }
            let v = w * dz;
            let a = w * w * d2z;
            // in/s → ft/s for the motor's constants.
            let force = m.mass_slug * a / 12.0 + m.friction_lbf_s_per_ft * v / 12.0;
            let i = force / m.kf_lbf_per_a;
            let u = m.r_ohm * i + m.kb_v_s_per_ft * v / 12.0;
            v_pk = v_pk.max(v.abs());
            a_pk = a_pk.max(a.abs());
            i_pk = i_pk.max(i.abs());
            u_pk = u_pk.max(u.abs());
            if *x >= slope_x_min {
                let sl = (dz.abs() / x).atan().to_degrees();
                if sl > slope {
                    slope = sl;
                    slope_at = (*x, phi.to_degrees());
                }
            }
        }
    }
    let stroke = -s.z_min.iter().cloned().fold(0.0, f64::min);
    let (lo, hi) = (lp.table.x_min, lp.table.x_null);
    let (pk, rms, map) = error_map(s, rpm, sens);
    let bound = lp.plan_error_bound_uin;
    let i_lim = m.loop_current_limit_a.min(m.amplifier_current_limit_a);
    let clearance = lp.part.tool.clearance_deg;
    let checks = vec![
        check("z_stroke", stroke, m.command_limit_in, "in", || {
            format!(
                "the Z stroke {stroke:.6} in exceeds the slide's command range {} in (servo.command_limit_in): the firmware would clamp the command",
                m.command_limit_in
            )
        }),
        check("coil_current", i_pk, i_lim, "A", || {
            format!(
                "the peak coil current {i_pk:.2} A at {rpm} rpm (peak velocity {v_pk:.4} in/s, acceleration {a_pk:.2} in/s²) exceeds the limit {i_lim} A (loop's servo.current_limit_a, amplifier's current_limit_a): lower the speed"
            )
        }),
        check("amplifier_voltage", u_pk, m.rail_v, "V", || {
            format!(
                "the coil needs {u_pk:.1} V at {rpm} rpm, beyond the amplifier's rail of {} V",
                m.rail_v
            )
        }),
        check("slope_along_cut", slope, clearance, "deg", || {
            format!(
                "the surface slopes {slope:.2}° along the cut (at X = {:.3} in, φ = {:.1}°), more than the tool's clearance angle {clearance}° (tool.clearance_deg): the flank would rub",
                slope_at.0, slope_at.1
            )
        }),
        check("x_range", hi, FACEPLATE_RADIUS_IN, "in", || {
            format!(
                "the table's X range {lo}..{hi} in reaches beyond the faceplate radius {FACEPLATE_RADIUS_IN} in"
            )
        }),
        check(
            "rpm_band",
            (rpm - 0.5 * (m.min_rpm + m.max_rpm)).abs(),
            0.5 * (m.max_rpm - m.min_rpm),
            "rpm from mid-band",
            || {
                format!(
                    "{rpm} rpm is outside the speed band the firmware accepts ({}..{} rpm)",
                    m.min_rpm, m.max_rpm
                )
            },
        ),
        check("predicted_following_error", pk, bound, "µin", || {
            format!(
                "the predicted following error peaks at {pk:.2} µin at {rpm} rpm, beyond plan.error_bound_uin = {bound} µin (highest significant harmonic at {hi_hz:.1} Hz against the loop's {} Hz bandwidth): lower the speed",
                m.bandwidth_hz
            )
        }),
    ];
    // Highest speed with the predicted error within the bound: the error
    // grows with speed (|S| rises toward the bandwidth), so bisect.
    let ok_at = |r: f64| error_map(s, r, sens).0 <= bound;
    let max_rpm_for_bound = if !ok_at(m.min_rpm) {
        None
    } else if ok_at(m.max_rpm) {
        Some(m.max_rpm)
    } else {
        let (mut a, mut b) = (m.min_rpm, m.max_rpm);
        for _ in 0..30 {
            let mid = 0.5 * (a + b);
            if ok_at(mid) {
                a = mid;
            } else {
                b = mid;
            }
        }
        Some(a)
    };
    let feasible = checks.iter().all(|c| c.ok);
    Plan {
        part: lp.name.clone(),
        surface: lp.part.sag.describe(),
        machine: machine.clone(),
        rpm,
        x_range_in: (lo, hi),
        checks,
        predicted_error_peak_uin: pk,
        predicted_error_rms_uin: rms,
        highest_significant_hz: hi_hz,
        max_rpm_for_bound,
        error_bound_uin: bound,
        feasible,
        error_map_uin: map,
        x_in: s.x.clone(),
    }
}

/// The loop's sensitivity on a log grid of frequencies, interpolated
/// (magnitude and phase linear in log f; clamped at the ends).
#[derive(Clone, Debug)]
pub struct SensitivityTable {
    pub f_hz: Vec<f64>,
    pub s: Vec<Complex<f64>>,
}

impl SensitivityTable {
    pub fn at(&self, f: f64) -> Complex<f64> {
        let n = self.f_hz.len();
        if f <= self.f_hz[0] {
            return self.s[0];
        }
        if f >= self.f_hz[n - 1] {
            return self.s[n - 1];
        }
        let i = self.f_hz.partition_point(|&v| v <= f) - 1;
        let t = (f / self.f_hz[i]).ln() / (self.f_hz[i + 1] / self.f_hz[i]).ln();
        let (a, b) = (self.s[i], self.s[i + 1]);
        let mag = a.norm().ln() * (1.0 - t) + b.norm().ln() * t;
        let mut dp = b.arg() - a.arg();
        if dp > std::f64::consts::PI {
            dp -= TAU;
        } else if dp < -std::f64::consts::PI {
            dp += TAU;
        }
        Complex::from_polar(mag.exp(), a.arg() + t * dp)
    }
}
