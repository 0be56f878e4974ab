//! The firmware command path against the exact surface (eq 2-15 with FOREX4's
//! tool compensation, `host_sim::surface`): the acceptance numbers of
//! `accuracy` and `zcmd`, at points drawn from a seeded RNG.

use host_sim::cmd::accuracy::{default_table, measure};
use host_sim::cmd::zcmd::z_at;
use host_sim::surface::Surface;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use zslide::command::CommandGen;
use zslide::table::CoeffTable;

#[test]
fn zcmd_matches_the_exact_surface_within_a_tenth_of_a_microinch() {
    let img = default_table().unwrap();
    let gen = CommandGen::new(CoeffTable::parse(&img).unwrap());
    let s = Surface::dissertation();
    let mut rng = ChaCha8Rng::seed_from_u64(0x2_15);
    let mut worst = 0.0f64;
    for _ in 0..20_000 {
        let x = rng.random_range(0.0..=7.2);
        let phi = rng.random_range(-720.0..720.0);
        let z = z_at(&gen, x, phi).unwrap();
        let exact = s.z(x, f64::to_radians(phi)).unwrap();
        worst = worst.max((z - exact).abs());
    }
    assert!(worst <= 0.1e-6, "worst {} µin", worst * 1e6);
    // Beyond 7.2 in the slide is nulled, whatever φ.
    assert_eq!(z_at(&gen, 7.2001, 90.0).unwrap(), 0.0);
    assert!(z_at(&gen, -0.001, 90.0).is_err());
}

#[test]
fn accuracy_report_meets_the_goal() {
    // Coarse sampling keeps the test fast; the refinement around each X's
    // worst angle still finds the peak.
    let r = measure(&default_table().unwrap(), 3, 180).unwrap();
    assert!(r.max_error_uin <= 0.1, "{r:?}");
    assert!(r.max_error_at_nodes_uin <= r.max_error_uin);
    // The fixed-point share stays inside the 0.01 µin allowance.
    assert!(r.fixed_point_max_uin <= 0.01, "{r:?}");
    assert!((r.x_max_in - 7.2).abs() < 1e-7);
}

/// The analytic derivatives for feedforward against the exact surface's:
/// ∂Z/∂φ within what the 0.1 µin series can carry, ∂Z/∂X within the bound
/// of a piecewise-linear slope, ΔX/2 · max|∂²Z/∂X²| (mean-value theorem),
/// with ∂²Z/∂X² taken from the exact surface at the rim.
#[test]
fn derivatives_match_the_exact_surface() {
    let img = default_table().unwrap();
    let gen = CommandGen::new(CoeffTable::parse(&img).unwrap());
    let s = Surface::dissertation();
    let mut rng = ChaCha8Rng::seed_from_u64(215);
    let (mut wp, mut wx) = (0.0f64, 0.0f64);
    for _ in 0..5_000 {
        let x = rng.random_range(0.0..=7.2);
        let phi = rng.random_range(0.0..360.0);
        let a = zslide::units::SpindleAngle::from_degrees(phi);
        let c = gen.command(zslide::units::XInches::from_f64(x), a).unwrap();
        let sec = s.section(x).unwrap();
        let r = a.to_radians();
        wp = wp.max((c.dz_dphi.to_num::<f64>() - sec.dz_dphi(r)).abs());
        wx = wx.max((c.dz_dx.to_num::<f64>() - sec.dz_dx(r)).abs());
    }
    let h = 1e-3;
    let zxx = (0..360)
        .map(|d| {
            let r = f64::from(d).to_radians();
            let z = |x: f64| s.z(x, r).unwrap();
            ((z(7.2 + h) - 2.0 * z(7.2) + z(7.2 - h)) / (h * h)).abs()
        })
        .fold(0.0, f64::max);
    let t = CoeffTable::parse(&img).unwrap();
    let dx = t.node_x(1).to_f64() - t.node_x(0).to_f64();
    let bound = dx / 2.0 * zxx * 1.02;
    eprintln!("worst dZ/dphi {wp:e} in/rad, dZ/dX {wx:e} in/in (bound {bound:e})");
    assert!(wp < 1e-7, "∂Z/∂φ off by {wp:e} in/rad");
    assert!(wx <= bound, "∂Z/∂X off by {wx:e} in/in");
}
