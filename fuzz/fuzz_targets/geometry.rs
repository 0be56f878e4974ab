//! The table-geometry loader (`host_sim::geometry`) on arbitrary text, and
//! what the generator makes of what it accepts. Properties:
//! * a configuration refused by `to_spec` is refused naming one of the
//!   schema's fields (`section.key`, the module documentation's list);
//! * a specification it accepts generates (or is refused by the generator
//!   naming a field), and the generated image is one the firmware takes:
//!   it parses, its header is the specification's, its grid increases, and
//!   the command it gives at every node before the null zone passes the
//!   firmware's sign check (Z ≤ 1 µin at 16 angles, `max_φ Z = 0`).
#![no_main]

use host_sim::coeffgen::generate;
use host_sim::geometry::Config;
use libfuzzer_sys::fuzz_target;
use zslide::command::CommandGen;
use zslide::table::CoeffTable;
use zslide::units::SpindleAngle;

const FIELDS: [&str; 13] = [
    "surface.c_in",
    "surface.focal_length_in",
    "surface.s_y_in",
    "surface.tool_radius_in",
    "surface.compensation",
    "grid.x_min_in",
    "grid.x_max_in",
    "grid.step_in",
    "grid.x_null_in",
    "series.representation",
    "series.terms",
    "format.coeff_frac_bits",
    "format.x_frac_bits",
];

/// Generation evaluates the surface at every node: bound the work per input.
const MAX_NODES_PER_INPUT: usize = 400;

fn names_a_field(msg: &str) -> bool {
    let head = msg.split([' ', ':']).next().unwrap_or("");
    FIELDS.contains(&head)
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(cfg) = Config::from_toml(text) else {
        return;
    };
    let spec = match cfg.to_spec() {
        Ok(s) => s,
        Err(e) => {
            let msg = e.to_string();
            assert!(names_a_field(&msg), "refusal names no field: {msg:?}");
            return;
        }
    };
    if spec.node_count() > MAX_NODES_PER_INPUT {
        return;
    }
    let g = match generate(&spec) {
        Ok(g) => g,
        Err(e) => {
            let msg = e.to_string();
            assert!(
                names_a_field(&msg),
                "generator refusal names no field: {msg:?}"
            );
            return;
        }
    };
    let img = g.image().expect("the generator's image parses");
    let t = CoeffTable::parse(&img).expect("parses");
    let h = t.header();
    assert_eq!(h.node_count as usize, spec.node_count());
    assert_eq!(usize::from(h.terms), spec.columns());
    assert_eq!(h.representation, spec.representation);
    assert_eq!(
        (h.coeff_frac_bits, h.x_frac_bits),
        (spec.coeff_frac_bits, spec.x_frac_bits)
    );
    for n in 1..t.node_count() {
        assert!(
            t.node_x(n) > t.node_x(n - 1),
            "nodes {} and {n} coincide",
            n - 1
        );
    }
    let gen = CommandGen::new(t);
    for n in 0..t.node_count() {
        let x = t.node_x(n);
        if x > gen.x_null() {
            break;
        }
        let c = gen
            .coefficients(x)
            .expect("a node inside the table has coefficients");
        for k in 0..16u32 {
            let phi = SpindleAngle(k << 28);
            let z = gen.evaluate_phi(&c, phi).z;
            assert!(
                z.to_bits() <= 1074,
                "Z = {} in > 1 µin at node {n} (X = {}), φ = {}°: the firmware would refuse this table",
                z.to_f64(),
                x.to_f64(),
                phi.to_degrees()
            );
        }
    }
});
