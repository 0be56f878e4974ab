//! `zslide scope`: a live scope in the terminal. Each frame is one capture
//! (the firmware's triggered capture of consecutive loop ticks): armed,
//! triggered, read and drawn, then armed again, so the picture is
//! continuous between frames the way a sampling scope's is: each trace is
//! `--samples` consecutive ticks, the time between traces is the link's.
//!
//! One panel per signal, each with its own axis and unit (µin for command,
//! position and following error, V for the DAC, degrees for φ), the
//! trigger instant at t = 0. Keys: `q` quits, `s` writes the frame shown
//! as CSV and PNG/SVG (`scope-N.csv`, `scope-N.png`), `+`/`-` double or
//! halve the time base, space holds the picture.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind};
use ratatui::layout::{Constraint, Layout};
use ratatui::style::{Color, Style};
use ratatui::symbols::Marker;
use ratatui::text::Line;
use ratatui::widgets::{Axis, Block, Chart, Dataset, GraphType, Paragraph};

use zslide::link::proto::{CaptureInfo, CaptureState, Reply, Request, Sample, Trigger};

use crate::client::unexpected;
use crate::client::Link;
use crate::words::{deg, uin, V_PER_CODE};
use crate::Result;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Signal {
    Command,
    Position,
    Error,
    Dac,
    Phi,
}

impl Signal {
    fn label(self) -> String {
        let (name, unit) = self.name_unit();
        format!("{name} ({unit})")
    }
    /// The signal's name and unit apart (the snapshot's panels).
    fn name_unit(self) -> (&'static str, &'static str) {
        match self {
            Signal::Command => ("command", "µin"),
            Signal::Position => ("position", "µin"),
            Signal::Error => ("following error", "µin"),
            Signal::Dac => ("DAC", "V"),
            Signal::Phi => ("φ", "deg"),
        }
    }
    fn value(self, s: &Sample) -> f64 {
        match self {
            Signal::Command => uin(s.command),
            Signal::Position => uin(s.position),
            Signal::Error => uin(s.error),
            Signal::Dac => f64::from(s.output) * V_PER_CODE,
            Signal::Phi => deg(s.phi),
        }
    }
}

#[derive(clap::Args, Debug, Clone)]
pub struct ScopeArgs {
    /// The signals, one panel each.
    #[arg(long, value_delimiter = ',', default_values = ["command", "position", "error", "dac"])]
    pub signals: Vec<Signal>,
    /// Time base: loop ticks per trace (20 000 a second); `+`/`-` change it.
    #[arg(long, value_name = "N", default_value_t = 400, value_parser = clap::value_parser!(u16).range(2..=zslide::link::CAPTURE as i64))]
    pub samples: u16,
    /// `immediate` (free-running), `fault`, or `ferr:UIN`.
    #[arg(long, value_name = "T", default_value = "immediate", value_parser = crate::capture::parse_trigger)]
    pub trigger: Trigger,
    /// Of the ticks, before the trigger (not with `immediate`).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub pre: u16,
    /// Where the `s` key writes its snapshots.
    #[arg(long, value_name = "DIR", default_value = ".")]
    pub snapshot_dir: PathBuf,
    /// Stop after this many frames (0: until `q`).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub frames: u32,
}

/// One frame: arms a capture, waits for it (keys still read), reads it.
/// `None`: no trigger yet (the caller draws the last frame again).
fn frame(
    link: &mut Link,
    a: &ScopeArgs,
    samples: u16,
    patience: Duration,
) -> Result<Option<(CaptureInfo, Vec<Sample>)>> {
    let c = link.client()?;
    match c.call(&Request::CaptureStart {
        samples,
        pre: a.pre.min(samples - 1),
        trigger: a.trigger,
    })? {
        Reply::Capture(_) => {}
        r => return Err(unexpected(&r)),
    }
    let start = Instant::now();
    loop {
        let info = c.capture_info()?;
        if info.state == CaptureState::Done {
            let s = c.capture_read(info.recorded)?;
            return Ok(Some((info, s)));
        }
        if start.elapsed() > patience {
            return Ok(None);
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

pub fn run(link: &mut Link, a: &ScopeArgs) -> Result<String> {
    if a.trigger == Trigger::Immediate && a.pre > 0 {
        return Err(
            "--pre with --trigger immediate: nothing comes before an immediate trigger".into(),
        );
    }
    if a.signals.is_empty() {
        return Err("--signals: name at least one of command, position, error, dac, phi".into());
    }
    std::fs::create_dir_all(&a.snapshot_dir)
        .map_err(|e| format!("{}: {e}", a.snapshot_dir.display()))?;
    let hz = link.client()?.status()?.loop_hz;
    let mut term = ratatui::init();
    let r = scope_loop(link, a, hz, &mut term);
    ratatui::restore();
    r
}

fn scope_loop(
    link: &mut Link,
    a: &ScopeArgs,
    hz: u32,
    term: &mut ratatui::DefaultTerminal,
) -> Result<String> {
    let mut samples = a.samples;
    let mut shown: Option<(CaptureInfo, Vec<Sample>)> = None;
    let mut held = false;
    let mut frames = 0u32;
    let mut snapshots = 0u32;
    let mut note = String::from("q quit · s snapshot · +/- time base · space hold");
    loop {
        if !held {
            if let Some(f) = frame(link, a, samples, Duration::from_millis(200))? {
                shown = Some(f);
                frames += 1;
            }
        }
        let title = format!(
            "zslide scope · {} ticks = {:.2} ms · trigger {} at t = 0 · frame {frames}{}",
            samples,
            f64::from(samples) * 1e3 / f64::from(hz.max(1)),
            crate::words::trigger(a.trigger),
            if held { " · HELD" } else { "" }
        );
        term.draw(|f| draw(f, &title, &note, a, shown.as_ref(), hz))
            .map_err(|e| format!("terminal: {e}"))?;
        while event::poll(Duration::from_millis(1)).map_err(|e| e.to_string())? {
            if let Event::Key(k) = event::read().map_err(|e| e.to_string())? {
                if k.kind != KeyEventKind::Press {
                    continue;
                }
                match k.code {
                    KeyCode::Char('q') | KeyCode::Esc => {
                        return Ok(format!("{frames} frames, {snapshots} snapshots"))
                    }
                    KeyCode::Char(' ') => held = !held,
                    KeyCode::Char('+') => {
                        samples = (samples.saturating_mul(2)).min(zslide::link::CAPTURE as u16)
                    }
                    KeyCode::Char('-') => samples = (samples / 2).max(2),
                    KeyCode::Char('s') => {
                        if let Some((info, s)) = &shown {
                            snapshots += 1;
                            let stem = a.snapshot_dir.join(format!("scope-{snapshots}"));
                            let csv = stem.with_extension("csv");
                            crate::write_file(&csv, crate::capture::csv(info, s, hz))?;
                            snapshot_plot(&stem, &a.signals, info, s, hz)?;
                            note = format!(
                                "snapshot {} -> {}, {}.png, {}.svg",
                                snapshots,
                                csv.display(),
                                stem.display(),
                                stem.display()
                            );
                        }
                    }
                    _ => {}
                }
            }
        }
        if a.frames > 0 && frames >= a.frames {
            return Ok(format!("{frames} frames, {snapshots} snapshots"));
        }
    }
}

/// The frame as the screen shows it, one panel per signal on the
/// trigger's time axis: `<stem>.svg` and `.png`.
pub fn snapshot_plot(
    stem: &std::path::Path,
    signals: &[Signal],
    info: &CaptureInfo,
    samples: &[Sample],
    hz: u32,
) -> Result<()> {
    use host_sim::scope::{Figure, Panel, Series};
    let ms = |i: usize| (i as f64 - f64::from(info.before_trigger)) * 1e3 / f64::from(hz.max(1));
    let panels: Vec<Panel> = signals
        .iter()
        .map(|sig| {
            let (name, unit) = sig.name_unit();
            Panel::analog(
                name,
                unit,
                vec![Series {
                    label: name.into(),
                    points: samples
                        .iter()
                        .enumerate()
                        .map(|(i, s)| (ms(i), sig.value(s)))
                        .collect(),
                }],
            )
        })
        .collect();
    let title = format!(
        "zslide scope: {} ticks, trigger {} at t = 0",
        samples.len(),
        crate::words::trigger(info.trigger)
    );
    let dir = stem
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    let name = stem
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or("snapshot: no file name")?;
    host_sim::scope::write_images(
        dir,
        name,
        &Figure {
            title: &title,
            subtitle: "",
            x_label: "time from the trigger (ms)",
            panels: &panels,
            markers: &[],
        },
    )
    .map_err(|e| format!("{}: snapshot: {e:#}", stem.display()))
}

fn draw(
    f: &mut ratatui::Frame,
    title: &str,
    note: &str,
    a: &ScopeArgs,
    shown: Option<&(CaptureInfo, Vec<Sample>)>,
    hz: u32,
) {
    let n = a.signals.len() as u32;
    let mut rows = vec![Constraint::Length(1)];
    rows.extend((0..n).map(|_| Constraint::Ratio(1, n)));
    rows.push(Constraint::Length(1));
    let areas = Layout::vertical(rows).split(f.area());
    f.render_widget(Paragraph::new(Line::from(title.to_string())), areas[0]);
    f.render_widget(
        Paragraph::new(Line::from(note.to_string())),
        areas[areas.len() - 1],
    );
    let Some((info, samples)) = shown else {
        f.render_widget(Paragraph::new("waiting for the trigger…"), areas[1]);
        return;
    };
    let ms = |i: usize| (i as f64 - f64::from(info.before_trigger)) * 1e3 / f64::from(hz.max(1));
    let (t0, t1) = (ms(0), ms(samples.len().saturating_sub(1)));
    let colours = [
        Color::Cyan,
        Color::Yellow,
        Color::Red,
        Color::Green,
        Color::Magenta,
    ];
    for (k, sig) in a.signals.iter().enumerate() {
        let pts: Vec<(f64, f64)> = samples
            .iter()
            .enumerate()
            .map(|(i, s)| (ms(i), sig.value(s)))
            .collect();
        let (lo, hi) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                (l.min(p.1), h.max(p.1))
            });
        let pad = ((hi - lo) * 0.1).max(1e-3);
        let (lo, hi) = (lo - pad, hi + pad);
        let data = Dataset::default()
            .marker(Marker::Braille)
            .graph_type(GraphType::Line)
            .style(Style::default().fg(colours[k % colours.len()]))
            .data(&pts);
        let chart = Chart::new(vec![data])
            .block(Block::bordered().title(sig.label()))
            .x_axis(Axis::default().bounds([t0, t1]).labels([
                format!("{t0:.2} ms"),
                format!("{:.2} ms", (t0 + t1) / 2.0),
                format!("{t1:.2} ms"),
            ]))
            .y_axis(
                Axis::default()
                    .bounds([lo, hi])
                    .labels([format!("{lo:.3}"), format!("{hi:.3}")]),
            );
        f.render_widget(chart, areas[k + 1]);
    }
}
