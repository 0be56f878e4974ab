//! Firmware entry for the real board. Built only for the target; on the host
//! this file is an empty program so that `cargo test` links.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("zslide-fw runs on the board: build it with `cargo fw`");
}
