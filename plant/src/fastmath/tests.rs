use super::{clamp_symmetric, round_i32, round_i64};

#[test]
fn clamp_symmetric_equals_std_clamp_on_valid_ranges() {
    for limit in [0.0, 1.0, 10.0, 48.0] {
        for x in [-100.0, -10.0, -9.999, -0.0, 0.0, 3.5, 10.0, 10.0001, 1e300] {
            assert_eq!(
                clamp_symmetric(x, limit).to_bits(),
                f64::clamp(x, -limit, limit).to_bits(),
                "{x} {limit}"
            );
        }
        assert!(clamp_symmetric(f64::NAN, limit).is_nan());
    }
}

#[test]
fn equals_std_round_at_the_edges() {
    let cases = [
        0.0,
        -0.0,
        0.5,
        -0.5,
        1.5,
        -1.5,
        2.5,
        -2.5,
        0.49999999999999994,
        -0.49999999999999994,
        4_503_599_627_370_495.5,
        -4_503_599_627_370_495.5,
        4_503_599_627_370_496.0,
        9.3e18,
        -9.3e18,
        1e300,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NAN,
        f64::MIN_POSITIVE,
        123_456.499_999_999_99,
    ];
    for x in cases {
        assert_eq!(round_i64(x), x.round() as i64, "x = {x:e}");
        assert_eq!(round_i32(x), x.round() as i32, "x = {x:e}");
    }
    // Dense sweep around half-integers.
    let mut x = -1000.0f64;
    while x < 1000.0 {
        for y in [x, x.next_up(), x.next_down()] {
            assert_eq!(round_i64(y), y.round() as i64, "x = {y:e}");
        }
        x += 0.25;
    }
}
