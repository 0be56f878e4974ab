extern crate std;
use super::*;
use crate::table::{Geometry, TableHeader};
use std::vec;
use std::vec::Vec;

/// A table image of `payload` (also the legacy output's tests').
pub(crate) fn table(repr: Representation, terms: u8, payload: &[i32], nodes: u32) -> Vec<u8> {
    let h = TableHeader {
        representation: repr,
        terms,
        coeff_frac_bits: 30,
        x_frac_bits: 24,
        node_count: nodes,
        x0_raw: 0,
        dx_raw: 1 << 22, // 0.25 in
        x_null_raw: (nodes as i32 - 2) << 22,
        geometry: Geometry {
            c_nin: 316_700_000_000,
            s_y_nin: 28_000_000_000,
            tool_radius_nin: 125_000_000,
        },
    };
    let mut out = vec![0u8; h.image_len()];
    h.encode(payload, &mut out).unwrap();
    out
}

pub(crate) fn q30(v: f64) -> i32 {
    (v * 2f64.powi(30)).round() as i32
}

/// Both representations of the same trigonometric polynomial give the
/// same Z and derivatives, against closed forms evaluated in f64.
#[test]
fn harmonic_and_sin_power_agree_with_closed_forms() {
    // Node n: C0 = -1e-4 n, S1 = 2e-4 n, C2 = 1e-3 n, S3 = -3e-5 n.
    let nodes = 6u32;
    let coef = |n: f64| (-1e-4 * n, 2e-4 * n, 1e-3 * n, -3e-5 * n);
    let mut harm = Vec::new();
    let mut pow = Vec::new();
    for n in 0..nodes {
        let (c0, s1, c2, s3) = coef(f64::from(n));
        harm.extend([q30(c0), 0, q30(s1), q30(c2), 0, 0, q30(s3)]);
        pow.extend([
            q30(c0 + c2),
            q30(s1 + 3.0 * s3),
            q30(-2.0 * c2),
            q30(-4.0 * s3),
        ]);
    }
    let ih = table(Representation::Harmonic, 7, &harm, nodes);
    let ip = table(Representation::SinPower, 4, &pow, nodes);
    let gh = CommandGen::new(CoeffTable::parse(&ih).unwrap());
    let gp = CommandGen::new(CoeffTable::parse(&ip).unwrap());
    let lsb = 2f64.powi(-30);
    for xi in 0..40 {
        let x = XInches::from_f64(f64::from(xi) * 0.0249);
        let u = x.to_f64() / 0.25;
        let (c0, s1, c2, s3) = coef(u);
        for deg in (0..360).step_by(7) {
            let phi = SpindleAngle::from_degrees(f64::from(deg) + 0.3);
            let p = phi.to_radians();
            let z = c0 + s1 * p.sin() + c2 * (2.0 * p).cos() + s3 * (3.0 * p).sin();
            let dz = s1 * p.cos() - 2.0 * c2 * (2.0 * p).sin() + 3.0 * s3 * (3.0 * p).cos();
            let ddz = -s1 * p.sin() - 4.0 * c2 * (2.0 * p).cos() - 9.0 * s3 * (3.0 * p).sin();
            let (a0, a1, a2, a3) = coef(1.0);
            let dzdx = (a0 + a1 * p.sin() + a2 * (2.0 * p).cos() + a3 * (3.0 * p).sin()) / 0.25;
            for g in [&gh, &gp] {
                let cmd = g.command(x, phi).unwrap();
                let fast = g.evaluate_phi(&g.coefficients(x).unwrap(), phi);
                assert_eq!(
                    (fast.z, fast.dz_dphi, fast.d2z_dphi2),
                    (cmd.z, cmd.dz_dphi, cmd.d2z_dphi2)
                );
                assert!(
                    (cmd.z.to_f64() - z).abs() < 12.0 * lsb,
                    "z at {deg} x={x:?} {} {z}",
                    cmd.z.to_f64()
                );
                assert!((cmd.dz_dphi.to_num::<f64>() - dz).abs() < 40.0 * lsb);
                assert!((cmd.d2z_dphi2.to_num::<f64>() - ddz).abs() < 80.0 * lsb);
                assert!((cmd.dz_dx.to_num::<f64>() - dzdx).abs() < 1e-6);
            }
        }
    }
}

/// The derivatives are those of the command itself: a central difference
/// of Z over a small angle matches ∂Z/∂φ.
#[test]
fn dz_dphi_is_the_slope_of_z() {
    let nodes = 4u32;
    let mut harm = Vec::new();
    for n in 0..nodes as i32 {
        harm.extend([
            q30(-3e-4) * n,
            q30(1e-4),
            q30(-5e-4) * n,
            q30(2e-3) * n,
            q30(1e-5),
            q30(4e-6),
            q30(-4e-5) * n,
        ]);
    }
    let img = table(Representation::Harmonic, 7, &harm, nodes);
    let g = CommandGen::new(CoeffTable::parse(&img).unwrap());
    let x = XInches::from_f64(0.4);
    let h = 1u32 << 20; // 1.5e-3 rad
    let hr = f64::from(h) * core::f64::consts::TAU / 2f64.powi(32);
    for k in 0..64u32 {
        let phi = SpindleAngle(k.wrapping_mul(67_108_864 + 12_345));
        let at = |h: u32| {
            let zp = g.z(x, phi.wrapping_add(SpindleAngle(h))).unwrap().to_f64();
            let zm = g
                .z(x, SpindleAngle(phi.0.wrapping_sub(h)))
                .unwrap()
                .to_f64();
            (zp, zm)
        };
        let c = g.command(x, phi).unwrap();
        let (zp, zm) = at(h);
        let slope = (zp - zm) / (2.0 * hr);
        // Curvature needs a wider step: Z's LSB over h² would swamp it.
        let (zp, zm) = at(h << 4);
        let curv = (zp + zm - 2.0 * c.z.to_f64()) / (256.0 * hr * hr);
        assert!(
            (c.dz_dphi.to_num::<f64>() - slope).abs() < 6e-7,
            "k={k} {} {slope}",
            c.dz_dphi
        );
        assert!(
            (c.d2z_dphi2.to_num::<f64>() - curv).abs() < 2e-5,
            "k={k} {} {curv}",
            c.d2z_dphi2
        );
    }
}

/// A table holding one harmonic k at a time: Z is C_k cos kφ + S_k sin kφ
/// within the recurrence's documented 4k LSB (plus rounding), for
/// k = 1..=15, against libm.
#[test]
fn high_harmonics_within_the_recurrence_bound() {
    let one = 1 << 26; // 1/16 in
    for k in 1..=15usize {
        let mut row = [0i32; 31];
        row[2 * k - 1] = one;
        row[2 * k] = one / 2;
        let payload: Vec<i32> = [row, row, row].concat();
        let img = table(Representation::Harmonic, 31, &payload, 3);
        let g = CommandGen::new(CoeffTable::parse(&img).unwrap());
        let mut a: u32 = 7;
        for _ in 0..500 {
            a = a.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let phi = SpindleAngle(a).to_radians() * k as f64;
            let want = (phi.cos() + 0.5 * phi.sin()) / 16.0;
            let got = g
                .z(XInches::from_f64(0.1), SpindleAngle(a))
                .unwrap()
                .to_f64();
            // 4k LSB of the sines, scaled by the 1/16 in amplitude (×1.5), + 1 LSB.
            let bound = (4.0 * k as f64 * 1.5 / 16.0 + 1.5) * 2f64.powi(-30);
            assert!((got - want).abs() <= bound, "k={k}: {got} vs {want}");
        }
    }
}

/// The single-multiply path taken for tables of machine size gives the
/// same bits as the saturating path.
#[test]
fn small_path_equals_saturating_path() {
    let g = CommandGen::new(CoeffTable::parse(crate::DEFAULT_TABLE).unwrap());
    assert!(g.small);
    let slow = CommandGen { small: false, ..g };
    let mut a: u32 = 99;
    for k in 0..3000u32 {
        a = a.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        let x = XInches::from_bits((k * 40_427) as i32 % (121 << 20));
        let c = g.coefficients(x).unwrap();
        assert_eq!(
            g.evaluate(&c, SpindleAngle(a)),
            slow.evaluate(&c, SpindleAngle(a))
        );
    }
}

#[test]
fn null_zone_and_outside_table() {
    let nodes = 5u32;
    let pow: Vec<i32> = (0..nodes as i32 * 4).map(|i| -1000 * i).collect();
    let img = table(Representation::SinPower, 4, &pow, nodes);
    let g = CommandGen::new(CoeffTable::parse(&img).unwrap());
    // x_null = 0.75 in: at the boundary the command is live, beyond it null.
    let phi = SpindleAngle::from_degrees(90.0);
    assert_ne!(g.z(XInches::from_f64(0.75), phi).unwrap(), ZInches::ZERO);
    assert_eq!(
        g.z(XInches::from_f64(0.7500001), phi).unwrap(),
        ZInches::ZERO
    );
    assert_eq!(
        g.command(XInches::from_f64(50.0), phi).unwrap(),
        Command::default()
    );
    assert_eq!(
        g.z(XInches::from_f64(-1e-6), phi),
        Err(Fault::XOutsideTable)
    );
}

mod prop {
    use super::*;
    use proptest::prelude::*;

    fn default_gen() -> CommandGen<'static> {
        CommandGen::new(CoeffTable::parse(crate::DEFAULT_TABLE).unwrap())
    }

    proptest! {
        /// The default table over the whole X range (and beyond) and
        /// every φ: no fault above X = 0, a command that is never
        /// positive beyond the error budget (max over φ of Z is 0), of
        /// the size the machine needs (< 0.008 in), and continuous in X:
        /// one X LSB (6e-8 in) moves Z by at most slope·LSB + rounding.
        #[test]
        fn default_table_over_all_x_and_phi(xbits in 0i32..(9 << 24), phi in any::<u32>()) {
            let g = default_gen();
            let x = XInches::from_bits(xbits);
            let c = g.command(x, SpindleAngle(phi)).unwrap();
            let z = c.z.to_f64();
            prop_assert!(z <= 0.1e-6 && z > -0.008, "Z({x:?}) = {z}");
            let n = g.command(XInches::from_bits(xbits + 1), SpindleAngle(phi)).unwrap();
            if x < g.x_null() {
                // |∂Z/∂X| < 0.002 in/in: 6e-8 in of X moves Z < 1.2e-10 in,
                // plus a few LSB of rounding (9.3e-10 in each).
                prop_assert!((n.z.to_f64() - z).abs() < 5e-9, "jump at {x:?}");
                prop_assert!(c.dz_dx.to_num::<f64>().abs() < 0.002);
            }
        }

        /// Crossing a grid node of the default table exactly: no step.
        #[test]
        fn default_table_continuous_at_every_node(node in 1u32..230, phi in any::<u32>()) {
            let g = default_gen();
            let xn = g.interpolator().table().node_x(node);
            let a = g.z(XInches::from_bits(xn.to_bits() - 1), SpindleAngle(phi)).unwrap();
            let b = g.z(xn, SpindleAngle(phi)).unwrap();
            prop_assert!((a.to_f64() - b.to_f64()).abs() < 5e-9);
        }

        /// No overflow or panic anywhere in X and φ, for any coefficient
        /// values the format can hold, in both representations; and
        /// with coefficients of machine size (|c| ≤ 0.02 in) Z stays
        /// within Σ|c| (no wrap-around).
        #[test]
        fn no_overflow_over_x_and_phi(
            vals in proptest::collection::vec(any::<i32>(), 28),
            small in proptest::collection::vec(-21_474_836i32..21_474_836, 28),
            harmonic in any::<bool>(),
            xbits in any::<i32>(), phi in any::<u32>(),
        ) {
            let (repr, terms) = if harmonic { (Representation::Harmonic, 7u8) } else { (Representation::SinPower, 7u8) };
            for payload in [&vals, &small] {
                let img = table(repr, terms, payload, 4);
                let g = CommandGen::new(CoeffTable::parse(&img).unwrap());
                let r = g.command(XInches::from_bits(xbits), SpindleAngle(phi));
                if payload == &small {
                    if let Ok(c) = r {
                        let bound: f64 = small.iter().map(|v| f64::from(*v).abs()).sum::<f64>() * 2f64.powi(-30);
                        prop_assert!(c.z.to_f64().abs() <= bound + 1e-8);
                    }
                }
            }
        }
    }
}
