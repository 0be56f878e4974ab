use super::{floor_i64, frac};

#[test]
fn phasor_follows_sin_at_even_and_uneven_spacings() {
    let w = std::f64::consts::TAU * 60.0;
    let mut p = super::Phasor::new(w);
    let mut t = 0u64;
    let mut worst = 0.0f64;
    for k in 0..50_000u64 {
        // Mostly 100 µs apart, now and then an odd spacing.
        t += if k % 997 == 0 { 37_123 } else { 100_000 };
        let want = (w * (t as f64 * 1e-9)).sin();
        worst = worst.max((p.sin_at(t) - want).abs());
    }
    assert!(worst < 1e-11, "{worst:e}");
}

#[test]
fn floor_and_frac_equal_std_bit_for_bit() {
    let mut cases = vec![
        0.0,
        -0.0,
        1.0,
        -1.0,
        -3.0,
        0.5,
        -0.5,
        1e-300,
        -1e-300,
        -1e-20,
        0.999_999_999_999_999_9,
        -0.999_999_999_999_999_9,
        4_503_599_627_370_495.5,
        -4_503_599_627_370_495.5,
        4_503_599_627_370_496.0,
        -4_503_599_627_370_497.0,
        1e300,
        -1e300,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NAN,
    ];
    let mut x = -70.0f64;
    while x < 70.0 {
        cases.extend([x, x.next_up(), x.next_down()]);
        x += 0.0625;
    }
    let mut g = 0x9E37_79B9_7F4A_7C15u64;
    for _ in 0..100_000 {
        g = g.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        cases.push(f64::from_bits(g) % 1e6);
    }
    for x in cases {
        assert_eq!(floor_i64(x), x.floor() as i64, "floor x = {x:e}");
        let (a, b) = (frac(x), x.rem_euclid(1.0));
        assert!(
            a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
            "frac x = {x:e}: {a:e} vs {b:e}"
        );
    }
}
