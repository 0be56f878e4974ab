//! A first-order lag on the 1983 loop's reference: the command path ahead
//! of the position loop's summing junction (the generator's output stage:
//! its summing amplifier into R2, Fig 3-5). Figure 4-33 measured the loop
//! from R2 on, so a lag here is outside every version of the loop the
//! seeds give (eq 4-47, eq 4-49, Fig 4-34); the seeds state none, so its
//! time constant is the scenario's labelled `[errors] cmd_lag_us`.
//!
//! A command `Z₂ cos ωt` reaches the loop as `Z₂ cos(ωt − atan ωτ)/√(1 +
//! (ωτ)²)`; the part's error at that harmonic is then `(1 − T·L)Z₂`: the
//! lag's angle adds in quadrature to the command (the same direction as
//! the loop's own lag error `(1 − T)`, which is within 2° of 90° at the
//! 2/rev, `host-sim/tests/cut_lag.rs`), so it grows the error rather than
//! turning it.
//!
//! Stepped exactly for an input linear between two calls (the generator's
//! output is a smooth function sampled every loop tick).

/// `τ dy/dt = u − y`.
#[derive(Clone, Debug)]
pub struct FirstOrderLag {
    tau_s: f64,
    /// Output and (time ns, input) at the last call.
    y: f64,
    last: Option<(u64, f64)>,
}

impl FirstOrderLag {
    pub fn new(tau_s: f64) -> Self {
        Self {
            tau_s,
            y: 0.0,
            last: None,
        }
    }

    /// The output at `t_ns` for the input `u` there (linear from the last
    /// call's input); the first call starts settled at `u`.
    pub fn at(&mut self, t_ns: u64, u: f64) -> f64 {
        let Some((t0, u0)) = self.last else {
            self.y = u;
            self.last = Some((t_ns, u));
            return u;
        };
        if t_ns > t0 && self.tau_s > 0.0 {
            // u(t) = u0 + m t over h: y(h) = a y0 + (1 − a) u0 + m (h − τ (1 − a)).
            let h = (t_ns - t0) as f64 * 1e-9;
            let a = (-h / self.tau_s).exp();
            let m = (u - u0) / h;
            self.y = a * self.y + (1.0 - a) * u0 + m * (h - self.tau_s * (1.0 - a));
        } else if self.tau_s <= 0.0 {
            self.y = u;
        }
        self.last = Some((t_ns, u));
        self.y
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// The shop's 2/rev (12 Hz at 360 rpm) sampled at the 20 kHz loop tick
    /// through τ = 330 µs and 1 ms: after ten time constants the output is
    /// `cos(ωt − atan ωτ)/√(1 + (ωτ)²)`.
    #[test]
    fn a_first_order_lag_tau_gives_a_2_per_rev_command_the_gain_and_phase_of_its_closed_form() {
        let w = 2.0 * TAU * 360.0 / 60.0;
        for tau in [330e-6, 1e-3] {
            let mut lag = FirstOrderLag::new(tau);
            let dt_ns = 50_000u64;
            // Start at rest at 0 (the sine's zero), not settled on a slope.
            lag.at(0, 0.0);
            let (g, ph) = (1.0 / (1.0 + (w * tau).powi(2)).sqrt(), (w * tau).atan());
            let mut worst: f64 = 0.0;
            for k in 1..40_000u64 {
                let t = (k * dt_ns) as f64 * 1e-9;
                let y = lag.at(k * dt_ns, (w * t).sin());
                if t > 10.0 * tau + 0.1 {
                    worst = worst.max((y - g * (w * t - ph).sin()).abs());
                }
            }
            eprintln!(
                "τ {:.0} µs: gain {g:.6}, phase {:.3}°, worst deviation {worst:.2e}",
                tau * 1e6,
                ph.to_degrees()
            );
            // The input's chords between ticks (ω h = 0.0038) bound it by (ωh)²/8 ≈ 2e-6.
            assert!(worst < 5e-6, "τ {tau}: {worst}");
        }
    }

    #[test]
    fn no_time_constant_passes_the_input() {
        let mut lag = FirstOrderLag::new(0.0);
        lag.at(0, 1.0);
        assert_eq!(lag.at(50_000, 2.5), 2.5);
    }
}
