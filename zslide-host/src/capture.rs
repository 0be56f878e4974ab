//! `zslide capture`: consecutive loop ticks around a trigger, as CSV in
//! the user's units, and a plot.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use zslide::link::proto::{CaptureInfo, CaptureState, Reply, Request, Sample, Trigger, X_UNKNOWN};

use crate::client::{unexpected, Link};
use crate::report::say_to;
use crate::words::{deg, inch, uin, CODES_PER_UIN, V_PER_CODE};
use crate::Result;

#[derive(clap::Args, Debug, Clone)]
pub struct CaptureArgs {
    /// Loop ticks to record.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=zslide::link::CAPTURE as i64))]
    pub samples: u16,
    /// Of them, before the trigger (not with `--trigger immediate`).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub pre: u16,
    /// `immediate`, `fault`, or `ferr:UIN` (|command − position| ≥ UIN µin).
    #[arg(long, value_name = "T", value_parser = parse_trigger)]
    pub trigger: Trigger,
    /// The CSV file to write.
    #[arg(long, value_name = "FILE")]
    pub csv: PathBuf,
    /// Also plot it: FILE.svg and FILE.png.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// Seconds to wait for the trigger.
    #[arg(long, value_name = "S", default_value_t = 30)]
    pub wait_s: u64,
}

pub fn parse_trigger(s: &str) -> std::result::Result<Trigger, String> {
    match s {
        "immediate" => Ok(Trigger::Immediate),
        "fault" => Ok(Trigger::Fault),
        _ => {
            let uin = s
                .strip_prefix("ferr:")
                .ok_or_else(|| format!("{s:?}: expected immediate, fault or ferr:UIN"))?;
            let v: f64 = uin
                .parse()
                .map_err(|_| format!("{uin:?} is not a number of µin"))?;
            if !(v > 0.0 && v <= 10_000.0) {
                return Err(format!("ferr:{v}: the level must be in (0, 10000] µin"));
            }
            Ok(Trigger::FollowingError {
                level: (v * CODES_PER_UIN).round().max(1.0) as u32,
            })
        }
    }
}

/// The capture as CSV: time from the trigger, loop tick, command,
/// position, error (µin), output (V), φ (deg), X (in; empty on a tick
/// where the firmware did not know X).
pub fn csv(info: &CaptureInfo, samples: &[Sample], loop_hz: u32) -> String {
    let mut t = String::from("t_s,tick,command_uin,position_uin,error_uin,output_v,phi_deg,x_in\n");
    let first = info
        .trigger_tick
        .wrapping_sub(u32::from(info.before_trigger));
    for (i, s) in samples.iter().enumerate() {
        let k = i as i64 - i64::from(info.before_trigger);
        t += &format!(
            "{:.6},{},{:.4},{:.4},{:.4},{:.6},{:.4},{}\n",
            k as f64 / f64::from(loop_hz.max(1)),
            first.wrapping_add(i as u32),
            uin(s.command),
            uin(s.position),
            uin(s.error),
            f64::from(s.output) * V_PER_CODE,
            deg(s.phi),
            if s.x_bits == X_UNKNOWN {
                String::new()
            } else {
                format!("{:.7}", inch(s.x_bits))
            }
        );
    }
    t
}

/// The capture as FILE.svg and FILE.png: command, position, error in µin.
pub fn plot(stem: &Path, info: &CaptureInfo, samples: &[Sample], loop_hz: u32) -> Result<()> {
    use host_sim::plot::{write_images, Series};
    let t = |i: usize| (i as f64 - f64::from(info.before_trigger)) * 1e3 / f64::from(loop_hz);
    let series = |label: &str, f: fn(&Sample) -> i32| Series {
        label: label.into(),
        points: samples
            .iter()
            .enumerate()
            .map(|(i, s)| (t(i), uin(f(s))))
            .collect(),
    };
    let dir = stem
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = stem
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or("--plot needs a file name")?;
    write_images(
        dir,
        name,
        &format!(
            "capture, trigger {} at t = 0",
            crate::words::trigger(info.trigger)
        ),
        "time from the trigger (ms)",
        "µin",
        &[
            series("command", |s| s.command),
            series("position", |s| s.position),
            series("error", |s| s.error),
        ],
    )
    .map_err(|e| format!("{}: plot: {e}", stem.display()))
}

/// Refuses what the firmware would silently shorten: an immediate trigger
/// fires on the first recorded tick, so nothing can come before it.
pub fn check(a: &CaptureArgs) -> Result<()> {
    if a.trigger == Trigger::Immediate && a.pre > 0 {
        return Err(format!(
            "--pre {} with --trigger immediate: an immediate trigger is the first tick recorded, \
             so there is nothing before it (the capture would hold {} samples, not {}); use \
             --pre 0, or a fault or ferr:UIN trigger",
            a.pre,
            a.samples.saturating_sub(a.pre),
            a.samples
        ));
    }
    if a.pre >= a.samples {
        return Err(format!(
            "--pre {} must be below --samples {} (the trigger tick is recorded too)",
            a.pre, a.samples
        ));
    }
    Ok(())
}

pub fn run(link: &mut Link, a: &CaptureArgs, out: &mut dyn Write) -> Result<()> {
    let mut say = |s: String| say_to(out, &s);
    check(a)?;
    // The output is checked before the capture is armed: a bad path is
    // refused before the machine is asked for anything. The file itself
    // is replaced only when the capture is read whole.
    host_sim::outpath::check_file("--csv", &a.csv).map_err(|e| format!("{e:#}"))?;
    let c = link.client()?;
    let hz = c.status()?.loop_hz;
    match c.call(&Request::CaptureStart {
        samples: a.samples,
        pre: a.pre,
        trigger: a.trigger,
    })? {
        Reply::Capture(_) => {}
        r => return Err(unexpected(&r)),
    }
    say(format!(
        "capture armed: {} samples, {} before the trigger ({}); waiting up to {} s",
        a.samples,
        a.pre,
        crate::words::trigger(a.trigger),
        a.wait_s
    ))?;
    let start = Instant::now();
    let info = loop {
        let info = c.capture_info()?;
        if info.state == CaptureState::Done {
            break info;
        }
        if start.elapsed() > Duration::from_secs(a.wait_s) {
            return Err(format!(
                "no trigger within {} s (capture {:?})",
                a.wait_s, info.state
            ));
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let samples = c.capture_read(info.recorded)?;
    crate::write_file(&a.csv, csv(&info, &samples, hz))?;
    say(format!(
        "captured {} samples ({} before the trigger at tick {}) -> {}",
        samples.len(),
        info.before_trigger,
        info.trigger_tick,
        a.csv.display()
    ))?;
    if info.before_trigger < a.pre {
        say(format!(
            "note: {} ticks before the trigger were asked, {} were recorded: the trigger came {} \
             ticks after the capture was armed",
            a.pre, info.before_trigger, info.before_trigger
        ))?;
    }
    if let Some(stem) = &a.plot {
        plot(stem, &info, &samples, hz)?;
        say(format!(
            "plot -> {}.svg, {}.png",
            stem.display(),
            stem.display()
        ))?;
    }
    Ok(())
}
