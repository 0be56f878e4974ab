//! Puts this board's `memory.x` and `device.x` on the linker search path
//! ahead of anything a dependency provides, and relinks when they change.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    for name in ["memory.x", "device.x"] {
        fs::copy(name, out.join(name)).expect("copy linker script");
        println!("cargo:rerun-if-changed={name}");
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=build.rs");
}
