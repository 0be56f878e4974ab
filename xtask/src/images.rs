//! The firmware images' builds: the NUCLEO's two (`cargo fw`) and the QEMU
//! board's (`boards/qemu`).

use crate::tools::run;
use crate::{cargo, qemu_dir, root, step, Result};

pub fn build_board() -> Result<()> {
    step("board firmware: cargo fw (NUCLEO-H743ZI2: zslide-fw, zslide-centre)");
    run(cargo().current_dir(root()).arg("fw"), "cargo fw")
}

pub fn build_qemu_image() -> Result<()> {
    build_qemu()
}

/// The QEMU image with extra cargo features of `boards/qemu` (e.g.
/// `modern-x`), at the same path as [`build_qemu_image`]'s: build the plain
/// one again before running the log check.
pub fn build_qemu_image_with(features: &str) -> Result<()> {
    step(&format!(
        "QEMU image: cargo build --release --features {features} (boards/qemu)"
    ));
    run(
        cargo()
            .current_dir(qemu_dir())
            .args(["build", "--release", "--features", features]),
        "QEMU image build",
    )
}

pub fn build_qemu() -> Result<()> {
    step("QEMU image: cargo build --release (boards/qemu, mps2-an386)");
    // From its own directory: that picks up its .cargo/config.toml (target,
    // runner) on top of the root one (linker, rustflags).
    run(
        cargo().current_dir(qemu_dir()).args(["build", "--release"]),
        "QEMU image build",
    )
}
