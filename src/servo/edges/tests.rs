//! The edges' profile against the closed-form geometry of a hole crossing
//! a circle, and the step's learning against a simulated observer.

use super::*;
use crate::table::interrupt::Hole;

const RC_UIN: u32 = 3_500_000;
const DIA_UIN: u32 = 750_000;
/// The brief's nose, 0.125 in, nin (the table's `tool_radius_nin`).
const NOSE_NIN: i64 = 125_000_000;
/// The finishing pass's depth of cut, µin (chapter 5).
const FINISH_UIN: u32 = 300;

fn one_hole(angle_deg: f64) -> Interruptions {
    let hole = Hole {
        centre_radius_uin: RC_UIN,
        angle: SpindleAngle::from_degrees(angle_deg),
        diameter_uin: DIA_UIN,
    };
    let mut b = [0u8; 64];
    let n = Interruptions::encode(&[hole], &mut b).unwrap_or(0);
    Interruptions::parse(&b[..n]).unwrap_or_default()
}

fn ready(angle_deg: f64, x_in: f64) -> Edges {
    ready_at_depth(angle_deg, x_in, FINISH_UIN)
}

fn ready_at_depth(angle_deg: f64, x_in: f64, depth_uin: u32) -> Edges {
    let mut e = Edges::new(one_hole(angle_deg), contact_chord_uin(depth_uin, NOSE_NIN));
    e.set_x(XInches::from_f64(x_in));
    e.refresh_step();
    e
}

/// Half-width (degrees) of the hole at radius r (inches): the law of
/// cosines on the triangle axis, hole centre, rim point.
fn half_width_deg(r: f64) -> f64 {
    let (rc, rho) = (f64::from(RC_UIN) * 1e-6, f64::from(DIA_UIN) * 0.5e-6);
    ((r * r + rc * rc - rho * rho) / (2.0 * r * rc))
        .acos()
        .to_degrees()
}

/// The versine of the half-width is the closed form's to 1e-8 (absolute,
/// of a versine ~6e-3) at radii across the hole, and 0 off its annulus.
#[test]
fn the_half_width_versine_is_the_law_of_cosines() {
    for r_in in [3.13, 3.2, 3.4, 3.5, 3.6, 3.8, 3.87] {
        let v =
            f64::from(versine_at((r_in * 1e6) as i64, i64::from(RC_UIN), 375_000)) / 2f64.powi(31);
        let want = 1.0 - half_width_deg(r_in).to_radians().cos();
        assert!((v - want).abs() < 1e-8, "r {r_in}: {v} vs {want}");
    }
    assert_eq!(versine_at(3_000_000, i64::from(RC_UIN), 375_000), 0);
    assert_eq!(versine_at(4_000_000, i64::from(RC_UIN), 375_000), 0);
}

/// The contact chord is the closed form √(2 r_t d) (the nose's circle
/// cut by the stock's plane d below its lowest point, for d ≪ r_t) to
/// under 1 µin short, from the finest depth to the deepest roughing pass
/// and for noses of 1/64 .. 1/2 in: 8660 µin for the brief's finishing
/// pass, 50 000 µin (0.050 in) at 0.010 in deep.
#[test]
fn the_contact_chord_is_the_closed_form_root_of_2_r_d() {
    for r_in in [0.015_625, 0.125, 0.5] {
        for d_uin in [1, 300, 2_000, 5_000, 10_000] {
            let got = contact_chord_uin(d_uin, (r_in * 1e9) as i64) as f64;
            let want = (2.0 * r_in * f64::from(d_uin) * 1e-6).sqrt() * 1e6;
            assert!(
                got <= want + 1e-6 && got > want - 1.0,
                "r {r_in} in, d {d_uin} µin: {got} vs {want}"
            );
        }
    }
    assert_eq!(contact_chord_uin(10_000, NOSE_NIN), 50_000);
    assert_eq!(contact_chord_uin(FINISH_UIN, NOSE_NIN), 8_660);
    // No table (no nose) or a nonsense radius: bounded, no panic.
    assert_eq!(contact_chord_uin(10_000, -1), 0);
    assert!(contact_chord_uin(10_000, i64::MAX) <= 1 << 32);
}

/// On the bolt circle the whole chord is over the hole within the half-
/// width of its inner end and none of it beyond the outer end's: the
/// expected step is the amplitude inside, zero outside, and the switch
/// angles are the closed form's (to 0.01°), for the finishing pass's
/// chord and a 0.010 in roughing pass's (0.050 in: at X = 3.3 in the
/// inner end's half-width is 4.75° against the finishing chord's 5.26°).
#[test]
fn the_step_is_expected_between_the_chord_ends_half_widths() {
    let x = 3.3;
    for depth_uin in [FINISH_UIN, 10_000] {
        let mut e = ready_at_depth(40.0, x, depth_uin);
        e.amplitude_q8 = 1 << 20;
        let chord_in = (2.0 * 0.125 * f64::from(depth_uin) * 1e-6).sqrt();
        let inner = half_width_deg(x - chord_in);
        let outer = half_width_deg(x + CONTACT_OUTSIDE_UIN as f64 * 1e-6);
        let (lo, hi) = (inner.min(outer), inner.max(outer));
        for sign in [-1.0, 1.0] {
            let at = |deg: f64| e.expected_q8(SpindleAngle::from_degrees(40.0 + sign * deg));
            assert_eq!(at(0.0), 1 << 20);
            assert_eq!(at(lo - 0.01), 1 << 20, "{depth_uin} µin: inside {lo}");
            assert_eq!(at(hi + 0.01), 0, "{depth_uin} µin: outside {hi}");
            let mid = at(0.5 * (lo + hi));
            assert!(mid > 0 && mid < 1 << 20, "{depth_uin} µin: between: {mid}");
        }
    }
    let mut e = ready(40.0, x);
    e.amplitude_q8 = 1 << 20;
    // Far from the hole, and off its annulus, nothing.
    assert_eq!(e.expected_q8(SpindleAngle::from_degrees(200.0)), 0);
    let off = ready(40.0, 3.0);
    assert_eq!(off.expected_q8(SpindleAngle::from_degrees(40.0)), 0);
}

/// Where the chord lies half on the annulus (X inside the hole's inner
/// rim by half the chord), at most half of it is ever over the hole.
#[test]
fn a_chord_half_over_the_annulus_expects_half_the_step() {
    let rim = f64::from(RC_UIN - DIA_UIN / 2) * 1e-6;
    let inside = contact_chord_uin(FINISH_UIN, NOSE_NIN);
    let half = (inside + CONTACT_OUTSIDE_UIN) as f64 * 0.5e-6;
    let x = rim + half - CONTACT_OUTSIDE_UIN as f64 * 1e-6;
    let mut e = ready(10.0, x);
    e.amplitude_q8 = 1 << 20;
    let c = e.expected_q8(SpindleAngle::from_degrees(10.0));
    assert!((c - (1 << 19)).abs() < (1 << 20) / 50, "{c}");
}

/// The observer's disturbance as a first-order lag toward the cut's force
/// (time constant 12 ticks, or 200 ticks) from where the feedforward put
/// it: the force before a hole is `−step`, over it 0. The amplitude
/// converges to the true step for a fast and a slow observer, from zero
/// and from twice it, and a lag that leaves the hole's window far from
/// converged does not move it.
#[test]
fn the_learned_amplitude_converges_to_the_true_step_whatever_the_observer_speed() {
    let true_step = 3_000 * 256;
    let base = -true_step;
    for (lag, start) in [(0.08, 0), (0.005, 0), (0.08, 2 * true_step), (0.0005, 0)] {
        let mut e = ready(40.0, 3.5);
        e.amplitude_q8 = start;
        // The true force's shape: the same geometry at a unit amplitude.
        let mut shape = ready(40.0, 3.5);
        shape.amplitude_q8 = 1 << 16;
        // 0.09° a tick (300 rpm at 20 kHz).
        let step = SpindleAngle::from_degrees(0.09).0;
        let mut phi = SpindleAngle::from_degrees(0.0);
        let mut d = f64::from(base);
        let mut ff_last = 0;
        for _ in 0..(4000 * 60) {
            let ff = e.expected_q8(phi);
            d += f64::from(ff - ff_last);
            ff_last = ff;
            let frac = f64::from(shape.expected_q8(phi)) / 65_536.0;
            let target = f64::from(base) + f64::from(true_step) * frac;
            d += lag * (target - d);
            e.learn(phi, d as i32, true);
            phi = SpindleAngle(phi.0.wrapping_add(step));
        }
        let a = e.amplitude_q8();
        assert!(e.crossings_learned() > 20);
        assert!(
            (a - true_step).abs() < true_step / 50,
            "lag {lag}, from {start}: {a} vs {true_step}"
        );
    }
}

/// No holes: nothing is ever expected or learned.
#[test]
fn no_interruptions_expect_nothing() {
    let mut e = Edges::new(Interruptions::NONE, contact_chord_uin(FINISH_UIN, NOSE_NIN));
    e.set_x(XInches::from_f64(3.5));
    e.refresh_step();
    e.learn(SpindleAngle(0), 1000, true);
    assert_eq!(e.expected_q8(SpindleAngle(0)), 0);
    assert_eq!(e.amplitude_q8(), 0);
}
