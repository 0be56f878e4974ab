//! `cargo xtask isr-cost`: instructions per interrupt handler under QEMU.

pub fn run(_json: bool) -> Result<u8, String> {
    Err("isr-cost: not written yet".into())
}
