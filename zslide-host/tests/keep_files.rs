//! A refused command leaves the user's files as they were: each command of
//! `zslide` that writes a file, refused after its output was named (by the
//! machine, the link, or the input), against an existing file.

use std::path::PathBuf;
use std::time::Duration;

use host_sim::serve::Setup;
use zslide_host::cli::run_line;
use zslide_host::client::Link;

mod machine;
use machine::Machine;

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../target/zslide-host-test")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes `text` to `dir/name`; the check that it is still there, and
/// that nothing else (a partial file) was left in `dir`.
fn keep(dir: &std::path::Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn unchanged(files: &[(&PathBuf, &str)]) {
    for (p, text) in files {
        assert_eq!(
            std::fs::read_to_string(p).unwrap(),
            *text,
            "{} was changed",
            p.display()
        );
    }
    let dir = files[0].0.parent().unwrap();
    assert_eq!(
        std::fs::read_dir(dir).unwrap().count(),
        files.len(),
        "a partial file left in {}",
        dir.display()
    );
}

#[test]
fn identify_refused_while_disarmed_keeps_the_old_fit() {
    let m = Machine::start(
        "keep-identify",
        Setup::new(host_sim::scenario::load("legacy-hw").unwrap()),
    );
    let mut link = Link::new(&m.addr, Duration::from_secs(10));
    let dir = scratch("keep-identify");
    let csv = keep(&dir, "idkeep.csv", "f_hz,mag_db\n100,1\n");
    let plant = keep(&dir, "idkeep.plant", "amp_gain = 1.1\n");
    let e = run_line(
        &mut link,
        &format!("identify --out {}", dir.join("idkeep").display()),
    )
    .unwrap_err();
    assert!(e.contains("identify needs the loop armed"), "{e}");
    unchanged(&[(&csv, "f_hz,mag_db\n100,1\n"), (&plant, "amp_gain = 1.1\n")]);
}

#[test]
fn a_capture_refused_by_the_link_or_without_a_trigger_keeps_the_old_csv() {
    let dir = scratch("keep-capture");
    let csv = keep(&dir, "keep2.csv", "t_s\n0\n");
    // Nobody listening.
    let mut nobody = Link::new(
        &format!("unix:{}", dir.join("nobody.sock").display()),
        Duration::from_secs(1),
    );
    let line = format!(
        "capture --samples 1024 --trigger ferr:9000 --wait-s 1 --csv {}",
        csv.display()
    );
    let e = run_line(&mut nobody, &line).unwrap_err();
    assert!(e.contains("nothing is listening"), "{e}");
    unchanged(&[(&csv, "t_s\n0\n")]);
    // A trigger that never comes.
    let m = Machine::start(
        "keep-capture",
        Setup::new(host_sim::scenario::load("legacy-hw").unwrap()),
    );
    let mut link = Link::new(&m.addr, Duration::from_secs(10));
    let e = run_line(&mut link, &line).unwrap_err();
    assert!(e.contains("no trigger within 1 s"), "{e}");
    unchanged(&[(&csv, "t_s\n0\n")]);
    // More samples than the firmware's ring: refused with its limit.
    let e = run_line(
        &mut link,
        &format!(
            "capture --samples 5000 --trigger immediate --csv {}",
            csv.display()
        ),
    )
    .unwrap_err();
    assert!(e.contains("1..=1024"), "{e}");
    let e = run_line(
        &mut link,
        &format!(
            "capture --samples 0 --trigger immediate --csv {}",
            csv.display()
        ),
    )
    .unwrap_err();
    assert!(e.contains("1..=1024"), "{e}");
    unchanged(&[(&csv, "t_s\n0\n")]);
}

#[test]
fn a_refused_table_or_block_keeps_the_old_file() {
    let dir = scratch("keep-table");
    let table = keep(&dir, "keep.zsct", "the user's table");
    // A bound the firmware's allowance alone uses up.
    let part = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tables/toric-lens.toml"),
    )
    .unwrap();
    let tight = dir.join("tight.toml");
    let mut text = String::new();
    for line in part.lines() {
        if line.starts_with("bound_uin") {
            text += "bound_uin = 0.005\n";
        } else {
            text += line;
            text += "\n";
        }
    }
    std::fs::write(&tight, text).unwrap();
    let mut link = Link::new("unix:/nonexistent", Duration::from_secs(1));
    let e = run_line(
        &mut link,
        &format!(
            "table build --config {} --out {}",
            tight.display(),
            table.display()
        ),
    )
    .unwrap_err();
    assert!(
        e.contains("firmware_allowance_uin = 0.01: must be in"),
        "{e}"
    );
    std::fs::remove_file(&tight).unwrap();
    unchanged(&[(&table, "the user's table")]);

    let block = keep(&dir, "keep.zspb", "the user's block");
    let e = run_line(
        &mut link,
        &format!("params block --set no_such=1 --out {}", block.display()),
    )
    .unwrap_err();
    assert!(e.contains("no_such"), "{e}");
    unchanged(&[(&table, "the user's table"), (&block, "the user's block")]);
}

#[test]
fn table_build_takes_a_part_file_of_another_kind_than_the_paraboloid_and_prints_no_csv() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = scratch("table-build");
    let mut link = Link::new("unix:/nonexistent", Duration::from_secs(1));
    // The part (a toric lens); its table costs 10 s of CPU in a
    // debug build, so one part only.
    let part = "toric-lens";
    let out = dir.join(format!("{part}.zsct"));
    let said = run_line(
        &mut link,
        &format!(
            "table build --config {} --out {}",
            root.join("tables").join(format!("{part}.toml")).display(),
            out.display()
        ),
    )
    .unwrap();
    assert!(said.starts_with(&format!("part {part}: ")), "{said}");
    assert!(said.lines().count() < 6, "{said}");
    // The same bytes as the committed table of the part.
    assert_eq!(
        std::fs::read(&out).unwrap(),
        std::fs::read(root.join("tables").join(format!("{part}.zsct"))).unwrap()
    );
}
