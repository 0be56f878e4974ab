//! The 1983 analog Z-slide loop, emulated around the simulated plant as a
//! comparison controller (chapter 4).
//!
//! **Velocity loop (eq 4-37..4-44).** Fig 4-4/4-19: the reference R1 and the
//! differentiated gauge signal are summed, shaped, amplified (K_A = 10) and
//! drive the motor; velocity feedback is the gauge signal through the
//! differentiating network `Hv = Kfv s / (1 + s/ωf)²` with both filters at
//! ≈ 1050 Hz (the final network after the National Semiconductor note,
//! Fig 4-23). The final circuit's gains are not published; only the
//! measured closed loop is (eq 4-44, Model 15 motor):
//! `Z/R1 = 674 / (s (1 + s/1162.4)(1 + s/7634.1))`.
//! We keep the published structure and fit the unpublished values — the
//! forward gain `Kg`, a first-order lead `(1 + s/ωz)/(1 + s/ωp)` in the
//! forward path, and `Kfv` — by least squares of the complex log-ratio to
//! eq 4-44 over 1 Hz..1 kHz with the Model 15 plant *including* the 3150 Hz
//! mode (script and residuals in `docs/PLANT.md`). The result agrees with
//! eq 4-44 within 0.3 dB and 1° to 1 kHz; above, the mode shows.
//!
//! **Position loop (eq 4-45..4-47).** `Goc = 12 Ko (1 + s/4.16667) /
//! ((1 + s/0.378788)(1 + s/3030.3))` on the position error (1 V/mil gauge),
//! its output is R1. Kv = 8088 · Ko (eq 4-46); Ko = 0.5934 gives the
//! published Kv ≈ 4800 1/s.

//!
//! The folder: the loop as transfer functions ([`transfer`]: the design,
//! its fit and the published equations), and the loop run in the time
//! domain against the rig ([`emulation`]: co-simulated every substep;
//! [`exact`]: exact closed-loop steps while it is linear; [`drive`]: the
//! two handed over as the loop leaves and re-enters the linear range), and
//! the 1983 command generator's analog half ([`generator`]: the
//! tachometer-driven sine oscillator reset at the index, the multipliers;
//! [`lag`]: a first-order lag on the command path into the loop).

pub mod drive;
pub mod emulation;
pub mod generator;
pub mod lag;
pub mod exact;
pub mod transfer;

pub use drive::{AnalogDrive, RELINEAR_NS};
pub use emulation::{AnalogClosedLoop, AnalogController};
pub use exact::ClosedLoopExact;
pub use transfer::{
    close_loop, eq4_44, eq4_47, eq4_49, plant_open, tf, PositionLoop1983, VelocityLoop1983,
    GAUGE_V_PER_IN,
};
