//! The tools the commands need (Rust target, flip-link, defmt-print, QEMU,
//! the VCD viewers): found on PATH, installed when possible, otherwise named
//! with the exact command that installs them; and the small process helpers
//! every command uses.

use std::env;
use std::process::{Command, Stdio};

use crate::{cargo, step, Result, TARGET};

/// Runs a command to completion; Ok if it exits 0.
pub fn run(cmd: &mut Command, what: &str) -> Result<()> {
    let status = cmd
        .status()
        .map_err(|e| format!("{what}: cannot start {:?}: {e}", cmd.get_program()))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{what} failed ({status})"))
    }
}

/// Whether `program args` starts and exits 0 (used to probe for tools).
pub fn works(program: &str, args: &[&str]) -> bool {
    Command::new(program)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .map(|s| s.success())
        .unwrap_or(false)
}

/// Whether an executable named `bin` is on PATH (for tools, like flip-link,
/// that have no harmless "print your version" call).
pub fn on_path(bin: &str) -> bool {
    env::var_os("PATH")
        .map(|paths| env::split_paths(&paths).any(|dir| dir.join(bin).is_file()))
        .unwrap_or(false)
}

pub fn output_of(program: &str, args: &[&str]) -> Option<String> {
    output(program, args)
}

pub fn output(program: &str, args: &[&str]) -> Option<String> {
    let out = Command::new(program).args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).into_owned())
}

#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Tool {
    Target,
    FlipLink,
    DefmtPrint,
    Qemu,
    Viewers,
}

/// `bin` from Debian's `package`: there already, or installed with apt-get
/// when running as root; otherwise the exact command to run.
pub fn apt_tool(bin: &str, package: &str, what: &str) -> Result<()> {
    if on_path(bin) {
        return Ok(());
    }
    let root = output("id", &["-u"])
        .map(|s| s.trim() == "0")
        .unwrap_or(false);
    let apt = works("apt-get", &["--version"]);
    if root && apt {
        step(&format!("installing {package} (apt-get)"));
        let env = [("DEBIAN_FRONTEND", "noninteractive")];
        run(
            Command::new("apt-get").arg("update").envs(env),
            "apt-get update",
        )
        .and_then(|()| {
            run(
                Command::new("apt-get")
                    .args(["install", "-y", "--no-install-recommends", package])
                    .envs(env),
                &format!("apt-get install {package}"),
            )
        })
        .map_err(|e| format!("{bin} ({e})"))?;
        if on_path(bin) {
            Ok(())
        } else {
            Err(format!(
                "{bin} (package {package} installed but {bin} not found)"
            ))
        }
    } else if apt {
        Err(format!(
            "{bin}: run `sudo apt-get update && sudo apt-get install -y {package}` (not root, so \
             xtask does not)"
        ))
    } else {
        Err(format!(
            "{bin} ({what}): no apt-get here; install it with your package manager"
        ))
    }
}

/// Makes sure each tool is there, installing it when possible. Returns the
/// list of what is still missing, each with the exact remedy.
pub fn ensure(tools: &[Tool]) -> Vec<String> {
    let mut missing = Vec::new();
    for &tool in tools {
        if let Err(e) = ensure_one(tool) {
            missing.push(e);
        }
    }
    missing
}

pub fn ensure_one(tool: Tool) -> Result<()> {
    match tool {
        Tool::Target => {
            let installed = output("rustup", &["target", "list", "--installed"]);
            match installed {
                Some(list) if list.lines().any(|l| l.trim() == TARGET) => Ok(()),
                Some(_) => {
                    step(&format!("installing the Rust target {TARGET}"));
                    run(
                        Command::new("rustup").args(["target", "add", TARGET]),
                        "rustup target add",
                    )
                    .map_err(|e| {
                        format!("Rust target {TARGET} ({e}); run `rustup target add {TARGET}`")
                    })
                }
                None => Err(format!(
                    "rustup (to add the {TARGET} target); install rustup from https://rustup.rs, \
                     or provide a toolchain with the {TARGET} standard library"
                )),
            }
        }
        Tool::FlipLink => cargo_install("flip-link", &["flip-link", "--locked"]),
        Tool::DefmtPrint => cargo_install(
            "defmt-print",
            // defmt-print 1.x decodes defmt 1.x frames.
            &["defmt-print", "--locked", "--version", "^1"],
        ),
        Tool::Qemu => apt_tool(
            "qemu-system-arm",
            "qemu-system-arm",
            "QEMU ≥ 7 with the mps2-an386 machine",
        ),
        // The VCD viewers' readers the host tests check the VCDs with
        // (`trace::check_both`): GTKWave's converter, libsigrok.
        Tool::Viewers => apt_tool("vcd2fst", "gtkwave", "GTKWave's vcd2fst")
            .and_then(|()| apt_tool("sigrok-cli", "sigrok-cli", "sigrok-cli (libsigrok)")),
    }
}

pub fn cargo_install(bin: &str, install: &[&str]) -> Result<()> {
    if on_path(bin) {
        return Ok(());
    }
    step(&format!("installing {bin} (cargo install)"));
    let mut cmd = cargo();
    cmd.arg("install").args(install);
    run(&mut cmd, &format!("cargo install {bin}"))
        .map_err(|e| format!("{bin} ({e}); run `cargo install {}`", install.join(" ")))?;
    if on_path(bin) {
        Ok(())
    } else {
        Err(format!(
            "{bin}: installed but not on PATH; add ~/.cargo/bin to PATH"
        ))
    }
}

pub fn require(tools: &[Tool]) -> Result<()> {
    let missing = ensure(tools);
    if missing.is_empty() {
        return Ok(());
    }
    let mut msg = String::from("missing, and could not be installed:");
    for m in &missing {
        msg.push_str("\n  - ");
        msg.push_str(m);
    }
    Err(msg)
}

pub fn require_for_qemu() -> Result<()> {
    require(&[Tool::Target, Tool::FlipLink, Tool::Qemu])
}

/// The tools a QEMU run with its log decoded needs: the target, flip-link,
/// QEMU and defmt-print.
pub fn require_for_qemu_log() -> Result<()> {
    require(&[Tool::Target, Tool::FlipLink, Tool::Qemu, Tool::DefmtPrint])
}
