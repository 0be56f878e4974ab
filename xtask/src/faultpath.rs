//! The emulated board's fault paths, in `cargo xtask qemu` and `test`:
//!
//! * a HardFault in the loop tick (a permanently undefined instruction at
//!   tick 3000, the loop engaged: semihosting argument `hardfault`) and a
//!   panic in the background (argument `panic`) each end in the image's
//!   real handler, which must drop the amplifier-enable output (FPGAIO
//!   LED0 bit 0, `boards/qemu/src/board.rs`) before anything else: the
//!   handler logs what the output held before its first store and what it
//!   reads back after;
//! * a corrupt servo-parameter block in the parameter region: the boot
//!   refuses it in words (`Fault::Parameters`), the amplifier is never
//!   enabled, the DAC never written and the slide stays at rest.

use std::fs;

use zslide::params;
use zslide::servo::ServoDesign;

use crate::{qemu_elf, run_qemu_elf_with, step, QemuRegions, Result};

/// The image's semihosting configuration with `word` on its command line.
fn semihosting(word: &str) -> String {
    format!("enable=on,target=native,arg=zslide,arg={word}")
}

/// Runs the image with each fault injected; returns the summary line.
pub fn check() -> Result<String> {
    let table = crate::default_table_path();
    let regions = QemuRegions {
        table: Some(&table),
        params: None,
    };
    for (word, what) in [
        ("hardfault", "hard fault at pc"),
        ("panic", "injected in the background"),
    ] {
        step(&format!(
            "QEMU fault path: {word} injected, the enable output"
        ));
        let (code, lines) =
            run_qemu_elf_with(&qemu_elf(), &regions, &semihosting(word), &[], false)?;
        let line = lines.iter().find(|l| l.contains(what));
        let dropped = line.is_some_and(|l| {
            l.contains("amplifier enable output was high true, now high false (read back)")
        });
        if code == 0 || !dropped {
            return Err(format!(
                "{word}: exit status {code} (a fault path must fail the run), handler line: {}",
                line.map_or("none", String::as_str)
            ));
        }
        eprintln!("  {word}: {}", line.map_or("", String::as_str));
    }
    Ok("a HardFault in the loop tick and a panic in the background each drop the amplifier-enable output (high before, low read back) before they log".into())
}

/// Boots the image with a corrupt parameter block; returns the checks
/// passed.
pub fn params_check() -> Result<u32> {
    step("QEMU parameter region: a corrupt block");
    let base = ServoDesign::brief(zslide_host::regions::LOOP_HZ);
    let setting = (
        params::by_name("following_error_in")
            .ok_or("no parameter following_error_in")?
            .id,
        0.003,
    );
    let mut block = vec![0u8; params::HEADER_LEN + params::ENTRY_LEN];
    let n = params::encode_block(&[setting], &base, &mut block).map_err(|e| e.to_string())?;
    block.truncate(n);
    // One bit of the value: only the CRC sees it.
    block[n - 1] ^= 0x01;
    let dir = crate::root().join("target/table-checks");
    fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let file = dir.join("corrupt.zspb");
    fs::write(&file, &block).map_err(|e| e.to_string())?;
    let table = crate::default_table_path();
    let regions = QemuRegions {
        table: Some(&table),
        params: Some(&file),
    };
    let (code, lines) =
        run_qemu_elf_with(&qemu_elf(), &regions, "enable=on,target=native", &[], false)?;
    let said = lines.iter().any(|l| {
        l.contains("servo parameter block refused, amplifier kept off") && l.contains("BlockCrc")
    });
    let off = lines.iter().find(|l| l.contains("refused parameters:"));
    if code != 0 || !said || off.is_none() {
        return Err(format!(
            "QEMU with {}: exit {code}, refused in words {said}, {}",
            file.display(),
            off.map_or("no refused-parameters line", String::as_str)
        ));
    }
    eprintln!(
        "{}: refused in words; {}",
        file.display(),
        off.map_or("", String::as_str)
    );
    Ok(1)
}
