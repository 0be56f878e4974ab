//! The simulator's VCDs open in the viewers the docs name: GTKWave's own
//! converter (`vcd2fst`, Debian package `gtkwave`) reads the whole file,
//! and libsigrok (`sigrok-cli -I vcd`, Debian package `sigrok-cli`, what
//! PulseView uses) decodes its 1-bit lines, with one `loop_tick` edge per
//! loop-tick handler run.
//!
//! `cargo xtask test` installs both tools where missing and sets
//! `ZSLIDE_REQUIRE_VIEWERS=1`, so there a missing tool fails this test; a
//! plain `cargo test` on a machine without them says so and skips.

use std::path::Path;
use std::process::Command;

fn tool(name: &str) -> bool {
    let found = Command::new("sh")
        .args(["-c", &format!("command -v {name}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        assert!(
            std::env::var_os("ZSLIDE_REQUIRE_VIEWERS").is_none(),
            "{name} is not installed (Debian: apt-get install gtkwave sigrok-cli)"
        );
        eprintln!("skipped: {name} is not installed");
    }
    found
}

/// `vcd2fst` converts the file; its exit status and a non-empty FST.
pub fn gtkwave_reads(vcd: &Path) {
    let fst = vcd.with_extension("fst");
    let out = Command::new("vcd2fst").arg(vcd).arg(&fst).output().unwrap();
    let len = std::fs::metadata(&fst).map_or(0, |m| m.len());
    let _ = std::fs::remove_file(&fst);
    assert!(
        out.status.success() && len > 0,
        "vcd2fst refused {}: {}{}",
        vcd.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The 1-bit channels libsigrok decodes (names, in order) and the number
/// of level changes of each, sampled at 1 MHz.
pub fn sigrok_edges(vcd: &Path) -> Vec<(String, usize)> {
    let out = Command::new("sigrok-cli")
        .args(["-I", "vcd:downsample=1000", "-i"])
        .arg(vcd)
        .args(["-O", "csv"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "sigrok-cli failed on {}",
        vcd.display()
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let mut names: Vec<String> = Vec::new();
    let mut edges: Vec<usize> = Vec::new();
    let mut last: Option<Vec<String>> = None;
    for line in text.lines() {
        if let Some(ch) = line.strip_prefix("; Channels") {
            let list = ch.split_once(':').map_or("", |(_, l)| l);
            names = list.split(',').map(|n| n.trim().to_string()).collect();
            edges = vec![0; names.len()];
            continue;
        }
        if line.starts_with(';') || line.starts_with("META") || line.starts_with("logic") {
            continue;
        }
        let row: Vec<String> = line.split(',').map(str::to_string).collect();
        if let Some(prev) = &last {
            for (k, (a, b)) in prev.iter().zip(&row).enumerate() {
                if a != b {
                    edges[k] += 1;
                }
            }
        }
        last = Some(row);
    }
    names.into_iter().zip(edges).collect()
}

#[test]
fn machine_vcd_opens_in_gtkwave_and_its_wires_decode_in_sigrok() {
    if !(tool("vcd2fst") && tool("sigrok-cli")) {
        return;
    }
    let sc = host_sim::scenario::load("legacy-hw").unwrap();
    let path = std::env::temp_dir().join(format!("zslide-viewers-{}.vcd", std::process::id()));
    let stats = host_sim::cmd::bench::write_vcd(&path, 20_000, &sc).unwrap();
    gtkwave_reads(&path);
    let edges = sigrok_edges(&path);
    let _ = std::fs::remove_file(&path);
    let names: Vec<&str> = edges.iter().map(|(n, _)| n.as_str()).collect();
    // every 1-bit signal of the machine's set, and nothing else
    let wires: Vec<&str> = host_sim::vcd::machine::SIGNALS
        .iter()
        .filter(|(_, k)| *k == host_sim::vcd::SignalKind::Bit)
        .map(|(n, _)| *n)
        .collect();
    assert_eq!(names, wires);
    let count = |n: &str| edges.iter().find(|(m, _)| m == n).unwrap().1;
    // 250 ms at 20 kHz: one level change per loop-tick run (the first
    // toggle happens at the first sample, which is the CSV's first row)
    assert!((4998..=5000).contains(&count("loop_tick")), "{edges:?}");
    assert!(
        count("index") as u64 <= stats.index_events
            && stats.index_events <= count("index") as u64 + 1,
        "{edges:?} vs {stats:?}"
    );
}
