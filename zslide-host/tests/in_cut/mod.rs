//! `zslide identify --in-cut` on a served legacy-hw machine whose tool is
//! in a light test cut (`host-sim serve --cut-depth 300`, 100 µin/rev),
//! with the force model's edge constant k_e scaled, against the in-air
//! plant (the data sheet: the served machine is the nominal one).

use std::path::{Path, PathBuf};
use std::time::Duration;

use host_sim::cut::test_cut::TestCut;
use host_sim::serve::Setup;
use zslide::link::proto::LoopPhase;
use zslide_host::cli::run_line;
use zslide_host::client::Link;
use zslide_host::identify::{known_from_scenario, plant_text};
use zslide_host::process::{read_process, Process};

use crate::machine::Machine;
use crate::phase::wait_phase;

pub const DEPTH_IN: f64 = 300e-6;
pub const FEED_IN: f64 = 100e-6;

pub fn test_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/zslide-host-test");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The in-air plant file: the data sheet's (the nominal machine's).
pub fn air_plant(dir: &Path) -> PathBuf {
    let (_, sheet) = known_from_scenario("legacy-hw").unwrap();
    let path = dir.join("process-air.plant");
    std::fs::write(&path, plant_text(&sheet, "legacy-hw")).unwrap();
    path
}

/// One identification: the machine, and how the host reaches it.
pub struct Run<'a> {
    /// Names the socket and the output files.
    pub name: &'a str,
    pub ke_scale: f64,
    /// The rig's seed (None: the scenario's).
    pub seed: Option<u64>,
    /// `host-sim serve --lockstep`; otherwise real time (a board's pace).
    pub lockstep: bool,
    /// `--cut-repeats` (None: identify's default).
    pub repeats: Option<u32>,
    /// Where the host connects: the machine's address → the address to
    /// use (a test may put a relay between them).
    pub route: &'a dyn Fn(&str) -> String,
}

/// What `identify --in-cut` wrote.
pub struct Identified {
    pub process: Process,
    /// The files' bytes (tests/lockstep.rs compares them).
    #[allow(dead_code)]
    pub process_file: Vec<u8>,
    #[allow(dead_code)]
    pub csv: Vec<u8>,
    pub report: String,
}

pub fn identify(r: &Run) -> Identified {
    let mut sc = host_sim::scenario::load("legacy-hw").unwrap();
    sc.cutting.k_e_lbf_per_in *= r.ke_scale;
    if let Some(seed) = r.seed {
        sc.rig.seed = seed;
    }
    let mut setup = Setup::new(sc);
    setup.lockstep = r.lockstep;
    setup.cut = Some(TestCut {
        depth_in: DEPTH_IN,
        feed_per_rev_in: FEED_IN,
    });
    let m = Machine::start(r.name, setup);
    let mut link = Link::new(&(r.route)(&m.addr), Duration::from_secs(10));
    run_line(&mut link, "link arm").unwrap();
    wait_phase(&mut link, LoopPhase::Engaged);
    let dir = test_dir();
    let air = air_plant(&dir);
    let stem = dir.join(r.name);
    let repeats = r
        .repeats
        .map_or(String::new(), |n| format!(" --cut-repeats {n}"));
    let report = run_line(
        &mut link,
        &format!(
            "identify --in-cut {} --cut-depth {} --out {}{repeats}",
            air.display(),
            DEPTH_IN * 1e6,
            stem.display()
        ),
    )
    .unwrap();
    let process_path = stem.with_extension("process");
    Identified {
        process: read_process(&process_path).unwrap(),
        process_file: std::fs::read(&process_path).unwrap(),
        csv: std::fs::read(stem.with_extension("csv")).unwrap(),
        report,
    }
}
