//! `host-sim serve`: the simulated machine behind the firmware's link
//! (`crate::serve`), for `zslide` without a board.

use crate::scenario::ScenarioArg;
use crate::serve::{serve, Listener, Setup};
use anyhow::Context;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

#[derive(clap::Args, Debug, Clone)]
pub struct Args {
    #[command(flatten)]
    pub scenario: ScenarioArg,
    /// Where `zslide --connect` finds it: tcp:HOST:PORT or unix:PATH.
    #[arg(long, value_name = "ADDR", default_value = "tcp:127.0.0.1:9090")]
    pub listen: String,
    /// The coefficient table in the table region (default: the built-in
    /// default table, tables/default.zsct).
    #[arg(long, value_name = "FILE")]
    pub table: Option<PathBuf>,
    /// Where the X slide stands, inches (default: the scenario's x0_in).
    #[arg(long, value_name = "IN", allow_hyphen_values = true)]
    pub x_in: Option<f64>,
    /// X feed, in/min (default 0: X still).
    #[arg(
        long,
        value_name = "IN_PER_MIN",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub feed: f64,
    /// Spindle speed, rpm (default: the scenario's).
    #[arg(long, value_name = "RPM", allow_hyphen_values = true)]
    pub rpm: Option<f64>,
    /// Machine seconds per wall-clock second (1: real time).
    #[arg(
        long,
        value_name = "X",
        default_value_t = 1.0,
        allow_hyphen_values = true
    )]
    pub speed: f64,
    /// Machine time advances only while a request awaits its reply, as
    /// fast as the simulation runs: the firmware sees the same machine
    /// whenever the host's frames arrive (a slow host changes nothing).
    /// For reproducible measurements; a board has no such mode.
    #[arg(long, conflicts_with = "speed")]
    pub lockstep: bool,
    /// The plant's differences from the scenario's model (the firmware's
    /// design keeps the model): a machine to identify and tune.
    #[command(flatten)]
    pub perturb: crate::perturb::Perturbation,
    /// Keep the parameter region's flash in FILE: a machine served again
    /// with it boots with what `zslide params save` saved (a power cycle).
    /// Without it the flash starts erased and is lost at exit.
    #[arg(long, value_name = "FILE")]
    pub params_flash: Option<PathBuf>,
    /// The tool in a light test cut of this depth at the null position,
    /// µin (`zslide identify --in-cut` measures the process on it):
    /// the scenario's force model on solid stock (`cut::test_cut`).
    #[arg(long, value_name = "UIN")]
    pub cut_depth: Option<f64>,
    /// The test cut's feed per spindle revolution, µin.
    #[arg(
        long,
        value_name = "UIN",
        default_value_t = 100.0,
        requires = "cut_depth"
    )]
    pub cut_feed: f64,
    /// Scale the force model's edge constant k_e by this factor (as
    /// `cut --ke-scale`): a blunter or sharper tool, another material.
    #[arg(long, value_name = "X", default_value_t = 1.0, requires = "cut_depth")]
    pub ke_scale: f64,
}

pub fn setup(a: &Args) -> anyhow::Result<Setup> {
    let mut sc = a.scenario.load()?;
    a.perturb.apply(&mut sc)?;
    let mut s = Setup::new(sc);
    if let Some(f) = &a.params_flash {
        crate::outpath::check_file("--params-flash", f)?;
        s = s.with_params_file(f.clone())?;
    }
    if let Some(t) = &a.table {
        let bytes = std::fs::read(t).with_context(|| format!("{}: cannot read", t.display()))?;
        zslide::firmware::config::check_table(&bytes)
            .map_err(|e| anyhow::anyhow!("{}: table refused: {e}", t.display()))?;
        s.table = Box::leak(bytes.into_boxed_slice());
    }
    if let Some(x) = a.x_in {
        anyhow::ensure!(
            (0.0..10.0).contains(&x),
            "--x-in {x}: X must be in [0, 10) in"
        );
        s.x_in = x;
    }
    anyhow::ensure!(
        a.feed.is_finite() && a.feed.abs() <= 10.0,
        "--feed {}: must be within ±10 in/min",
        a.feed
    );
    s.feed_in_per_min = a.feed;
    if let Some(r) = a.rpm {
        anyhow::ensure!(r > 0.0 && r <= 3000.0, "--rpm {r}: must be in (0, 3000]");
        s.rpm = r;
    }
    s.speed = a.speed;
    s.lockstep = a.lockstep;
    if let Some(d) = a.cut_depth {
        anyhow::ensure!(
            a.ke_scale.is_finite() && a.ke_scale > 0.0 && a.ke_scale <= 10.0,
            "--ke-scale {}: must be in (0, 10]",
            a.ke_scale
        );
        s.scenario.cutting.k_e_lbf_per_in *= a.ke_scale;
        s.cut = Some(crate::cut::test_cut::TestCut {
            depth_in: d * 1e-6,
            feed_per_rev_in: a.cut_feed * 1e-6,
        });
    }
    s.check()?;
    Ok(s)
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let s = setup(&a)?;
    let l = Listener::bind(&a.listen)?;
    let cut = s.cut.map_or(String::new(), |c| {
        format!(
            ", the tool in a test cut {:.0} uin deep at {:.0} uin/rev (k_e {} lbf/in: {:.0} lbf/in)",
            c.depth_in * 1e6,
            c.feed_per_rev_in * 1e6,
            s.scenario.cutting.k_e_lbf_per_in,
            crate::cut::sensitivity::stiffness_lbf_per_in(
                &s.scenario.cutting,
                c.depth_in,
                c.feed_per_rev_in
            )
        )
    });
    eprintln!(
        "{}: the simulated machine ({}, X {} in, {} rpm{cut}), disarmed, on {}; in another \
         shell:\n  zslide --connect {} link status",
        s.scenario.file.name,
        s.scenario.file.description,
        s.x_in,
        s.rpm,
        l.address(),
        l.address()
    );
    serve(&s, &l, &AtomicBool::new(false))
}
