//! The frames of the cut: the command's angle and the part's (docs/CUT.md,
//! "Conventions").
//!
//! * **Part frame** (eq 2-5, the CMM's): `x3 = R cos φ`, `y3 = R sin φ`,
//!   `z3 = Y_t` along the outward normal at the sector centre; the concave
//!   face looks toward +Y_t, the material lies on −Y_t. Chapter 5's grid
//!   (φ = 0..350°, positive = excess stock) is reported in this frame.
//! * **Command angle** `φ_c`: the angle the command generator evaluates,
//!   increasing with time (the 1983 integrator of the tachometer, reset at
//!   the index; the firmware's angle from the tachometer or the encoder).
//! * **Sense of rotation.** The part turns in +φ (counter-clockwise seen
//!   from the tool, a lathe's forward sense); the tool stands still, so the
//!   point of the part under the tool runs *backwards* in φ:
//!   `φ_p = 180° − φ_c`. The generator resets to sine 0 at the index
//!   (φ_c = 0 there, φ_p = 180°). The seeds never state the sense: it is
//!   the one under which the simulated 1983 part correlates with eq 4-49's
//!   lag prediction (`host-sim/tests/cut_frame.rs`). The command is
//!   a polynomial in sin φ (eq 2-18..2-23) and `sin(180° − φ) = sin φ`:
//!   the nominal part cannot tell the sense (tested below). The dynamic
//!   errors can: a loop lagging by τ leaves `−τ dZ/dt = −τΩ ∂Z/∂φ_c` at the
//!   tool, which in the part frame is `+τΩ ∂Z/∂φ_p`, the sign of chapter
//!   5's measurement against the dissertation's own simulation (Appendix
//!   C's `ERR = R2 − Z` beside the measured error in Figures 5-7 and 5-9).

/// The part's angle (turns, 0..1) under the tool when the command's angle
/// is `command_turns`; the map is its own inverse.
pub fn part_turns(command_turns: f64) -> f64 {
    crate::fastmath::frac(0.5 - command_turns)
}

/// CMM angle index (0..`count`, part frame) of command-angle sample `k` of
/// `count` a turn.
pub fn part_index(k: i64, count: usize) -> usize {
    let n = count as i64;
    debug_assert!(n % 2 == 0, "the half turn must fall on a sample");
    (n / 2 - k).rem_euclid(n) as usize
}

/// An angle given in the part frame (degrees, e.g. the bolt holes' phase)
/// in the command's frame.
pub fn command_deg_of_part(part_deg: f64) -> f64 {
    (180.0 - part_deg).rem_euclid(360.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::Surface;
    use std::f64::consts::TAU;

    #[test]
    fn the_default_part_is_the_same_in_either_sense_of_rotation() {
        let t = zslide::table::CoeffTable::parse(zslide::DEFAULT_TABLE).unwrap();
        let s = Surface::from_table_geometry(&t.header().geometry).unwrap();
        let mut worst = 0.0f64;
        for x in [1.0, 3.0, 5.0, 7.0] {
            for j in 0..72 {
                let c = (f64::from(j) + 0.3) / 72.0;
                let a = s.z(x, c * TAU).unwrap();
                let b = s.z(x, part_turns(c) * TAU).unwrap();
                worst = worst.max((a - b).abs());
            }
        }
        assert!(worst < 1e-12, "{worst} in");
    }

    #[test]
    fn the_part_angle_runs_backwards_and_the_map_is_its_own_inverse() {
        let a = part_turns(0.10);
        let b = part_turns(0.11);
        assert!(b < a, "{a} {b}");
        assert!((part_turns(a) - 0.10).abs() < 1e-15);
        assert_eq!(part_index(0, 36), 18);
        assert_eq!(part_index(19, 36), 35);
        assert_eq!(part_index(18 + 36, 36), 0);
        assert_eq!(command_deg_of_part(22.5), 157.5);
    }
}
