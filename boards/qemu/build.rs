//! Puts this board's `memory.x` and `device.x` on the linker search path
//! ahead of anything a dependency provides, and relinks when they change.
//!
//! Generates the slide model's discretisations for the image
//! (`$OUT_DIR/plant_steps.rs`): the exact zero-order-hold matrices of
//! `zslide_plant` (the model host-sim steps), computed here on the host by
//! its own `zoh` (nalgebra's matrix exponential, which a `no_std` image does
//! not have), for every step the image takes: the loop period split at the
//! DAC latency, and the powers of two that compose any other interval (the
//! amplifier's current-limit entry and trip instants).
use std::{env, fmt::Write as _, fs, path::PathBuf};

use zslide_plant::slide::ZSlideParams;
use zslide_plant::zoh::zoh;

/// Loop period and DAC latency of the image (`src/main.rs`, `src/plant.rs`).
const PERIOD_NS: u64 = 50_000;
const DAC_LATENCY_NS: u64 = 8_500;

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    for name in ["memory.x", "device.x"] {
        fs::copy(name, out.join(name)).expect("copy linker script");
        println!("cargo:rerun-if-changed={name}");
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=build.rs");

    let params = ZSlideParams::model15();
    let mut dts = vec![PERIOD_NS, DAC_LATENCY_NS, PERIOD_NS - DAC_LATENCY_NS];
    let top = 64 - PERIOD_NS.leading_zeros();
    dts.extend((0..top).map(|k| 1u64 << k));
    let mut src = String::new();
    let n = 2 * dts.len();
    writeln!(src, "pub const STEPS: [Step; {n}] = [").unwrap();
    for held in [false, true] {
        let (a, b) = params.continuous(held);
        for &dt in &dts {
            let m = zoh(&a, &b, dt as f64 * 1e-9);
            writeln!(
                src,
                "    Step {{ dt_ns: {dt}, current_held: {held}, mats: Mats {{ phi: {:?}, gamma: {:?} }} }},",
                m.phi, m.gamma
            )
            .unwrap();
        }
    }
    writeln!(src, "];").unwrap();
    fs::write(out.join("plant_steps.rs"), src).expect("write plant_steps.rs");
}
