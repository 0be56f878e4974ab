//! The bit-exact replay step of `cargo xtask qemu` (and `test`): host-sim
//! records its runs (`host-sim replay-record`), the replay image
//! (`zslide-qemu-replay`) plays them on the emulated Cortex-M4F with the
//! recording loaded into its flash by QEMU's loader, and must report every
//! run bit-exact; then the same image is given the recording with one DAC
//! code altered and must fail naming exactly that tick, output and both
//! values (the proof that the comparison can fail).

use std::path::{Path, PathBuf};

use crate::{cargo, elf, root, run_qemu_elf, step, target_dir, QemuRegions, Result, TARGET};

/// The replay image.
pub fn replay_elf() -> PathBuf {
    target_dir().join(TARGET).join("release/zslide-qemu-replay")
}

/// What the recording step wrote: the files and the altered code.
struct Recorded {
    recording: PathBuf,
    altered: PathBuf,
    bytes: u64,
    runs: Vec<String>,
    /// The self-check's expected failure line (without the run name).
    altered_line: String,
    altered_run: String,
}

fn record() -> Result<Recorded> {
    let dir = target_dir().join("replay");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let recording = dir.join("recording.bin");
    let altered = dir.join("altered.bin");
    step("replay recording: cargo run -p host-sim -- replay-record");
    let out = cargo()
        .current_dir(root())
        .args([
            "run",
            "--quiet",
            "-p",
            "host-sim",
            "--",
            "replay-record",
            "--out",
        ])
        .arg(&recording)
        .arg("--altered-out")
        .arg(&altered)
        .output()
        .map_err(|e| format!("cannot start cargo run -p host-sim: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "host-sim replay-record failed ({}):\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout)
        .map_err(|e| format!("host-sim replay-record: unreadable summary: {e}"))?;
    let field = |v: &serde_json::Value, k: &str| -> Result<serde_json::Value> {
        v.get(k)
            .cloned()
            .ok_or_else(|| format!("host-sim replay-record: summary without {k}"))
    };
    let bytes = field(&v, "bytes")?.as_u64().unwrap_or(0);
    let runs = field(&v, "runs")?
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|r| r.get("name").and_then(|n| n.as_str()).map(String::from))
                .collect()
        })
        .unwrap_or_default();
    let a = field(&v, "altered")?;
    let s = |k: &str| -> Result<String> {
        Ok(match field(&a, k)? {
            serde_json::Value::String(s) => s,
            other => other.to_string(),
        })
    };
    eprintln!("recorded {bytes} bytes: {runs:?}");
    Ok(Recorded {
        recording,
        altered,
        bytes,
        runs,
        altered_line: format!(
            "tick {} (LoopTick): amplifier DAC frame: expected {} (3 bytes), got {} (3 bytes)",
            s("tick")?,
            s("altered")?,
            s("original")?
        ),
        altered_run: s("run")?,
    })
}

/// The recording region's address in the replay image (`memory.x`).
fn load_address(elf_path: &Path) -> Result<u32> {
    elf::image(elf_path)?
        .symbols
        .iter()
        .find(|s| s.0 == "__replay_start")
        .map(|s| s.1)
        .ok_or_else(|| format!("{}: no __replay_start", elf_path.display()))
}

fn play(recording: &Path) -> Result<(u8, Vec<String>)> {
    let elf_path = replay_elf();
    let addr = load_address(&elf_path)?;
    let loader = format!(
        "loader,file={},addr={addr:#x},force-raw=on",
        recording.display()
    );
    // The recording carries its own table; the table region stays empty.
    let regions = QemuRegions {
        table: None,
        params: None,
    };
    run_qemu_elf(&elf_path, &regions, &["-device", &loader])
}

/// Records, replays (must be bit-exact), replays the altered recording
/// (must fail at the altered code). Returns the summary line.
pub fn check() -> Result<String> {
    let r = record()?;
    step("QEMU replay: zslide-qemu-replay with the recording in its flash");
    let (code, lines) = play(&r.recording)?;
    let exact = lines.iter().filter(|l| l.contains("bit-exact")).count();
    if code != 0 || exact != r.runs.len() {
        return Err(format!(
            "the replay on the emulated Cortex-M4F failed (exit status {code}, {exact} of {} runs bit-exact)",
            r.runs.len()
        ));
    }
    step("QEMU replay self-check: one recorded DAC code altered must be reported");
    let (code, lines) = play(&r.altered)?;
    let want = format!("FAIL: replay {}: {}", r.altered_run, r.altered_line);
    if code == 0 || !lines.iter().any(|l| l.contains(&want)) {
        return Err(format!(
            "the replay did not report the altered code (exit status {code}); expected a line with\n  {want}"
        ));
    }
    eprintln!("the altered code was reported: {want}");
    Ok(format!(
        "{} runs bit-exact ({} bytes of recording); an altered DAC code is caught",
        r.runs.len(),
        r.bytes
    ))
}
