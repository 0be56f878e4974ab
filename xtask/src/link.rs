//! `cargo xtask link ...`: the host side of the firmware's link
//! (`zslide::link`, protocol in `docs/BOARD.md`), and `cargo xtask
//! qemu-link`, which starts the QEMU image as a link session for it.
//!
//! The transport is a byte stream: a TCP port (OpenOCD's RTT server on the
//! NUCLEO's link channel, `docs/BOARD.md`) or a Unix socket (QEMU's UART0).
//! Every command is one request and one reply; a refusal prints the
//! firmware's reason in words and exits 1.
//!
//! `end_to_end` is the test `cargo xtask test` runs: a QEMU link session
//! driven through these same commands (status, fault log, arm/disarm,
//! clear, parameters in and out of limits, a fault-triggered capture saved
//! as CSV), plus malformed frames sent raw.

use std::fs;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use zslide::link::proto::{
    self, CaptureInfo, CaptureState, FaultRecord, FrameError, LoopPhase, Refusal, Reply, Request,
    Sample, Status, Trigger, MAX_FRAME,
};
use zslide::params;

use crate::Result;

/// Gauge codes per µin (20 bits over ±0.010 in: 2¹⁹ / 10 000 µin).
pub const CODES_PER_UIN: f64 = zslide::codes::GAUGE_CODES_PER_INCH / 1e6;
/// Volts per DAC code (±10 V over 20 bits).
const V_PER_CODE: f64 = 10.0 / 524_288.0;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where the firmware's link is: `tcp:HOST:PORT` (OpenOCD's RTT server
    /// on the board) or `unix:PATH` (`cargo xtask qemu-link`).
    #[arg(long, value_name = "ADDR", default_value = "tcp:127.0.0.1:9090")]
    connect: String,
    /// How long to wait for each reply, ms.
    #[arg(long, value_name = "MS", default_value_t = 3000)]
    timeout_ms: u64,
    #[command(subcommand)]
    cmd: LinkCmd,
}

#[derive(clap::Subcommand, Debug, Clone)]
pub enum LinkCmd {
    /// Mode, phase, fault, X, φ, speed, command, table identity, counters.
    Status,
    /// The fault log, oldest first, with times and reasons.
    Faults,
    /// Arm: sign check, then bumpless engagement.
    Arm,
    /// Disarm: ramp to null, amplifier off.
    Disarm,
    /// Clear the latched fault (refused while its cause is present).
    Clear,
    /// Set a servo parameter (only while disarmed; `params` lists them).
    Set { name: String, value: f64 },
    /// Read a servo parameter.
    Get { name: String },
    /// Every servo parameter with its value, unit and limits.
    Params,
    /// Capture consecutive loop ticks (command, position, error, output,
    /// φ, X) around a trigger and save them as CSV.
    Capture(CaptureArgs),
}

#[derive(clap::Args, Debug, Clone)]
pub struct CaptureArgs {
    /// Loop ticks to record.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    samples: u16,
    /// Of them, before the trigger.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pre: u16,
    /// `immediate`, `fault`, or `ferr:UIN` (|command − position| ≥ UIN µin).
    #[arg(long, value_name = "T", value_parser = parse_trigger)]
    trigger: Trigger,
    /// The CSV file to write.
    #[arg(long, value_name = "FILE")]
    csv: PathBuf,
    /// Also plot it: FILE.svg and FILE.png.
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
    /// Seconds to wait for the trigger.
    #[arg(long, value_name = "S", default_value_t = 30)]
    wait_s: u64,
}

fn parse_trigger(s: &str) -> std::result::Result<Trigger, String> {
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

// ------------------------------------------------------------- transport

enum Stream {
    Tcp(TcpStream),
    Unix(UnixStream),
}

impl Read for Stream {
    fn read(&mut self, b: &mut [u8]) -> std::io::Result<usize> {
        match self {
            Stream::Tcp(s) => s.read(b),
            Stream::Unix(s) => s.read(b),
        }
    }
}
impl Write for Stream {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        match self {
            Stream::Tcp(s) => s.write(b),
            Stream::Unix(s) => s.write(b),
        }
    }
    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Stream::Tcp(s) => s.flush(),
            Stream::Unix(s) => s.flush(),
        }
    }
}

/// A connection that speaks the protocol: one request, one reply.
pub struct Client {
    s: Stream,
    seq: u16,
    rx: Vec<u8>,
    timeout: Duration,
}

impl Client {
    pub fn connect(addr: &str, timeout: Duration) -> Result<Self> {
        let s = if let Some(a) = addr.strip_prefix("tcp:") {
            let s = TcpStream::connect(a).map_err(|e| format!("connecting to {a}: {e}"))?;
            s.set_read_timeout(Some(Duration::from_millis(20)))
                .map_err(|e| e.to_string())?;
            Stream::Tcp(s)
        } else if let Some(p) = addr.strip_prefix("unix:") {
            let s = UnixStream::connect(p).map_err(|e| format!("connecting to {p}: {e}"))?;
            s.set_read_timeout(Some(Duration::from_millis(20)))
                .map_err(|e| e.to_string())?;
            Stream::Unix(s)
        } else {
            return Err(format!("{addr:?}: expected tcp:HOST:PORT or unix:PATH"));
        };
        Ok(Self {
            s,
            seq: 0,
            rx: Vec::new(),
            timeout,
        })
    }

    /// Sends bytes as they are (the malformed-frame test).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<()> {
        self.s.write_all(bytes).map_err(|e| format!("link: {e}"))
    }

    /// The next frame from the firmware, decoded.
    pub fn receive(&mut self) -> Result<(u16, Reply)> {
        let start = Instant::now();
        loop {
            if let Some(end) = self.rx.iter().position(|&b| b == 0) {
                let mut frame: Vec<u8> = self.rx.drain(..=end).collect();
                frame.pop();
                if frame.is_empty() {
                    continue;
                }
                return proto::decode::<Reply>(&mut frame, u32::MAX)
                    .map_err(|(_, e)| format!("a reply from the firmware is not a frame: {e}"));
            }
            if start.elapsed() > self.timeout {
                return Err(format!(
                    "no reply within {} ms (is the firmware running, and the link connected?)",
                    self.timeout.as_millis()
                ));
            }
            let mut buf = [0u8; 1024];
            match self.s.read(&mut buf) {
                Ok(0) => return Err("the link closed".into()),
                Ok(n) => {
                    self.rx.extend_from_slice(&buf[..n]);
                    if self.rx.len() > 4 * MAX_FRAME {
                        return Err("the firmware sent an over-long frame".into());
                    }
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(e) => return Err(format!("link: {e}")),
            }
        }
    }

    /// One request, its reply.
    pub fn call(&mut self, req: &Request) -> Result<Reply> {
        self.seq = self.seq.wrapping_add(1).max(1);
        let mut out = [0u8; MAX_FRAME];
        let frame = proto::encode(self.seq, req, &mut out).ok_or("request does not encode")?;
        self.send_raw(frame)?;
        let (seq, reply) = self.receive()?;
        if seq != self.seq {
            return Err(format!(
                "reply number {seq} to request number {}: out of step",
                self.seq
            ));
        }
        Ok(reply)
    }

    pub fn status(&mut self) -> Result<Status> {
        match self.call(&Request::Status)? {
            Reply::Status(s) => Ok(s),
            r => Err(unexpected(&r)),
        }
    }

    pub fn fault_log(&mut self) -> Result<(u32, Vec<FaultRecord>)> {
        let mut all = Vec::new();
        loop {
            match self.call(&Request::Faults {
                from: all.len() as u16,
            })? {
                Reply::Faults(p) => {
                    let n = p.records.len();
                    all.extend(p.records);
                    if n == 0 || all.len() >= usize::from(p.kept) {
                        return Ok((p.total, all));
                    }
                }
                r => return Err(unexpected(&r)),
            }
        }
    }

    pub fn capture_info(&mut self) -> Result<CaptureInfo> {
        match self.call(&Request::CaptureInfo)? {
            Reply::Capture(c) => Ok(c),
            r => Err(unexpected(&r)),
        }
    }

    pub fn capture_read(&mut self, recorded: u16) -> Result<Vec<Sample>> {
        let mut all = Vec::new();
        while all.len() < usize::from(recorded) {
            match self.call(&Request::CaptureRead {
                from: all.len() as u16,
            })? {
                Reply::Samples { from, samples } if usize::from(from) == all.len() => {
                    if samples.is_empty() {
                        return Err("the firmware sent no samples".into());
                    }
                    all.extend(samples);
                }
                r => return Err(unexpected(&r)),
            }
        }
        Ok(all)
    }
}

fn unexpected(r: &Reply) -> String {
    match r {
        Reply::Refused(why) => why.to_string(),
        r => format!("unexpected reply {r:?}"),
    }
}

// ------------------------------------------------------------- words

fn phase_words(p: LoopPhase) -> &'static str {
    match p {
        LoopPhase::Disarmed => "disarmed",
        LoopPhase::SignCheck => "armed, sign check running",
        LoopPhase::Engaging => "armed, engaging",
        LoopPhase::Engaged => "armed, engaged",
        LoopPhase::Disarming => "disarming (ramping to null)",
    }
}

fn inch(bits: i32) -> f64 {
    f64::from(bits) / f64::from(1u32 << 24)
}
fn deg(phi: u32) -> f64 {
    f64::from(phi) * 360.0 / 4_294_967_296.0
}
fn uin(codes: i32) -> f64 {
    f64::from(codes) / CODES_PER_UIN
}

pub fn status_text(s: &Status) -> String {
    let mut t = String::new();
    let secs = f64::from(s.state.ticks) / f64::from(s.loop_hz.max(1));
    t += &format!(
        "loop: {} ({}), {} Hz, tick {} ({secs:.3} s); X from {:?}, spindle from {:?}\n",
        phase_words(s.state.phase),
        if s.state.amplifier_enabled {
            "amplifier enabled"
        } else {
            "amplifier off"
        },
        s.loop_hz,
        s.state.ticks,
        s.x_source,
        s.spindle_source
    );
    t += &match s.state.fault {
        Some(f) => format!("fault: {f} ({:?})\n", f.reaction()),
        None => "fault: none\n".into(),
    };
    if let Some(f) = s.state.clear_refused {
        t += &format!("last clear refused: {f}\n");
    }
    let x = s.state.x_bits.map_or("unknown (no X yet)".into(), |b| {
        format!("{:.6} in", inch(b))
    });
    let phi = s
        .state
        .phi
        .map_or("not referenced (no index yet)".into(), |p| {
            format!("{:.3} deg", deg(p))
        });
    let rpm = s.state.phi_step_q8.map_or("unknown".into(), |q| {
        let turns_per_tick = q as f64 / 256.0 / 4_294_967_296.0;
        format!("{:.2} rpm", turns_per_tick * f64::from(s.loop_hz) * 60.0)
    });
    t += &format!(
        "X {x}{}; phi {phi}; spindle {rpm}\n",
        if s.state.null_command {
            " (command null)"
        } else {
            ""
        }
    );
    t += &format!(
        "command {:.3} uin ({} codes), position {:.3} uin, error {:.3} uin, table command {:.3} uin, output {:.5} V\n",
        uin(s.state.command),
        s.state.command,
        uin(s.state.position),
        uin(s.state.command.saturating_sub(s.state.position)),
        uin(s.state.table_command),
        f64::from(s.state.output) * V_PER_CODE
    );
    t += &match s.table {
        Ok(id) => format!("table: {id}\n"),
        Err(e) => format!("table: REFUSED: {e}\n"),
    };
    t += &format!("servo parameters: {}\n", s.params);
    t += &format!(
        "counters: X events {} accepted / {} ignored, coefficient sets {}, index events {}, faults logged {}\n",
        s.x_accepted, s.x_ignored, s.coefficient_sets, s.index_events, s.faults_logged
    );
    let f = s.frames;
    t += &format!(
        "link frames: {} ok, {} empty; refused: {} oversize, {} bad COBS, {} bad CRC, {} other version, {} unknown command, {} malformed\n",
        f.ok, f.empty, f.oversize, f.bad_cobs, f.bad_crc, f.bad_version, f.unknown_command, f.malformed
    );
    let c = s.capture;
    t += &format!(
        "capture: {:?}, {} samples ({} before the trigger), trigger {:?}; holds up to {}\n",
        c.state, c.samples, c.pre, c.trigger, c.capacity
    );
    t
}

fn record_text(r: &FaultRecord, loop_hz: u32) -> String {
    format!(
        "t = {:>10.5} s (tick {:>9}): {} {}",
        f64::from(r.tick) / f64::from(loop_hz.max(1)),
        r.tick,
        if r.cleared { "cleared" } else { "LATCHED" },
        r.fault
    )
}

/// The capture as CSV: time from the trigger, loop tick, command,
/// position, error (µin), output (V), φ (deg), X (in).
pub fn capture_csv(info: &CaptureInfo, samples: &[Sample], loop_hz: u32) -> String {
    let mut t = String::from("t_s,tick,command_uin,position_uin,error_uin,output_v,phi_deg,x_in\n");
    let first = info
        .trigger_tick
        .wrapping_sub(u32::from(info.before_trigger));
    for (i, s) in samples.iter().enumerate() {
        let k = i as i64 - i64::from(info.before_trigger);
        t += &format!(
            "{:.6},{},{:.4},{:.4},{:.4},{:.6},{:.4},{:.7}\n",
            k as f64 / f64::from(loop_hz.max(1)),
            first.wrapping_add(i as u32),
            uin(s.command),
            uin(s.position),
            uin(s.error),
            f64::from(s.output) * V_PER_CODE,
            deg(s.phi),
            inch(s.x_bits)
        );
    }
    t
}

fn plot_capture(stem: &Path, info: &CaptureInfo, samples: &[Sample], loop_hz: u32) -> Result<()> {
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
        &format!("capture, trigger {:?} at t = 0", info.trigger),
        "time from the trigger (ms)",
        "µin",
        &[
            series("command", |s| s.command),
            series("position", |s| s.position),
            series("error", |s| s.error),
        ],
    )
    .map_err(|e| e.to_string())
}

/// Runs one CLI command on a connection; its report goes to `out`.
pub fn execute(c: &mut Client, cmd: &LinkCmd, out: &mut impl Write) -> Result<()> {
    let mut say =
        |s: String| -> Result<()> { writeln!(out, "{}", s.trim_end()).map_err(|e| e.to_string()) };
    let param = |name: &str| {
        params::by_name(name).ok_or_else(|| {
            let names: Vec<&str> = params::PARAMS.iter().map(|p| p.name).collect();
            format!(
                "no servo parameter {name:?}; the parameters are: {}",
                names.join(", ")
            )
        })
    };
    match cmd {
        LinkCmd::Status => say(status_text(&c.status()?)),
        LinkCmd::Faults => {
            let hz = c.status()?.loop_hz;
            let (total, log) = c.fault_log()?;
            say(format!(
                "fault log: {} records kept of {total} logged",
                log.len()
            ))?;
            for r in &log {
                say(record_text(r, hz))?;
            }
            Ok(())
        }
        LinkCmd::Arm | LinkCmd::Disarm => {
            let req = if matches!(cmd, LinkCmd::Arm) {
                Request::Arm
            } else {
                Request::Disarm
            };
            match c.call(&req)? {
                Reply::Phase(p) => say(format!("loop {}", phase_words(p))),
                r => Err(unexpected(&r)),
            }
        }
        LinkCmd::Clear => match c.call(&Request::Clear)? {
            Reply::Cleared(f) => say(format!("cleared: {f}")),
            r => Err(unexpected(&r)),
        },
        LinkCmd::Set { name, value } => {
            let p = param(name)?;
            match c.call(&Request::Set {
                id: p.id,
                value: *value,
            })? {
                Reply::Param { value, .. } => {
                    say(format!("{} = {value} {} (in force)", p.name, p.unit))
                }
                r => Err(unexpected(&r)),
            }
        }
        LinkCmd::Get { name } => {
            let p = param(name)?;
            match c.call(&Request::Get { id: p.id })? {
                Reply::Param { value, .. } => say(format!("{} = {value} {}", p.name, p.unit)),
                r => Err(unexpected(&r)),
            }
        }
        LinkCmd::Params => {
            for p in params::PARAMS.iter() {
                match c.call(&Request::Get { id: p.id })? {
                    Reply::Param { value, .. } => say(format!(
                        "{:<26} = {:<12} {:<18} limits {} .. {}",
                        p.name, value, p.unit, p.min, p.max
                    ))?,
                    r => return Err(unexpected(&r)),
                }
            }
            Ok(())
        }
        LinkCmd::Capture(a) => {
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
                "capture armed: {} samples, {} before the trigger {:?}; waiting up to {} s",
                a.samples, a.pre, a.trigger, a.wait_s
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
            fs::write(&a.csv, capture_csv(&info, &samples, hz))
                .map_err(|e| format!("{}: {e}", a.csv.display()))?;
            say(format!(
                "captured {} samples ({} before the trigger at tick {}) -> {}",
                samples.len(),
                info.before_trigger,
                info.trigger_tick,
                a.csv.display()
            ))?;
            if let Some(stem) = &a.plot {
                plot_capture(stem, &info, &samples, hz)?;
                say(format!(
                    "plot -> {}.svg, {}.png",
                    stem.display(),
                    stem.display()
                ))?;
            }
            Ok(())
        }
    }
}

pub fn run(args: &Args) -> Result<u8> {
    let mut c = Client::connect(&args.connect, Duration::from_millis(args.timeout_ms))?;
    let mut out = std::io::stdout();
    execute(&mut c, &args.cmd, &mut out)?;
    Ok(0)
}

// ------------------------------------------------------------- QEMU session

#[derive(clap::Args, Debug)]
pub struct SessionArgs {
    /// The Unix socket QEMU's UART0 listens on.
    #[arg(long, value_name = "PATH", default_value = "target/zslide-link.sock")]
    socket: PathBuf,
    /// The table to load into the table region (default: tables/default.zsct).
    #[arg(long, value_name = "FILE")]
    table: Option<PathBuf>,
    /// A parameter block to load into the parameter region.
    #[arg(long, value_name = "FILE")]
    params: Option<PathBuf>,
}

/// A QEMU link session: the image, its UART0 on a Unix socket.
pub struct Session {
    qemu: Child,
    pub socket: PathBuf,
}

impl Drop for Session {
    fn drop(&mut self) {
        let _ = self.qemu.kill();
        let _ = self.qemu.wait();
        let _ = fs::remove_file(&self.socket);
    }
}

/// Starts the (built) QEMU image as a link session; QEMU waits for the
/// first connection before it runs the image.
pub fn start_session(socket: &Path, table: &Path, params: Option<&Path>) -> Result<Session> {
    let _ = fs::remove_file(socket);
    let qemu = crate::qemu_command_with(
        &crate::qemu_elf(),
        &crate::QemuRegions {
            table: Some(table),
            params,
        },
        &format!("unix:{},server=on,wait=on", socket.display()),
        "enable=on,target=native,arg=zslide,arg=link",
    )
    .stdin(Stdio::null())
    .stdout(Stdio::null())
    .spawn()
    .map_err(|e| format!("cannot start qemu-system-arm: {e}"))?;
    let s = Session {
        qemu,
        socket: socket.to_path_buf(),
    };
    let start = Instant::now();
    while !socket.exists() {
        if start.elapsed() > Duration::from_secs(10) {
            return Err(format!("QEMU did not open {}", socket.display()));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(s)
}

pub fn run_session(args: &SessionArgs) -> Result<u8> {
    crate::require_for_qemu()?;
    crate::build_qemu_image()?;
    let table = args.table.clone().unwrap_or_else(crate::default_table_path);
    let mut s = start_session(&args.socket, &table, args.params.as_deref())?;
    eprintln!(
        "QEMU link session on {} (table {}); in another shell:\n  cargo xtask link --connect unix:{} status\nCtrl-C stops it.",
        args.socket.display(),
        table.display(),
        args.socket.display()
    );
    let status = s.qemu.wait().map_err(|e| e.to_string())?;
    Ok(status.code().unwrap_or(1).clamp(0, 255) as u8)
}

// ------------------------------------------------------------- the test

fn cli(c: &mut Client, line: &str) -> Result<String> {
    use clap::Parser;
    #[derive(clap::Parser)]
    struct One {
        #[command(subcommand)]
        cmd: LinkCmd,
    }
    let one = One::try_parse_from(std::iter::once("link").chain(line.split_whitespace()))
        .map_err(|e| format!("`{line}`: {e}"))?;
    let mut out = Vec::new();
    execute(c, &one.cmd, &mut out).map_err(|e| format!("`link {line}`: {e}"))?;
    let text = String::from_utf8_lossy(&out).into_owned();
    for l in text.lines() {
        eprintln!("  link {line:<40} | {l}");
    }
    Ok(text)
}

fn expect_refused(c: &mut Client, line: &str, words: &str) -> Result<String> {
    match cli(c, line) {
        Ok(out) => Err(format!("`link {line}` was accepted: {out}")),
        Err(e) if e.contains(words) => {
            eprintln!("  link {line:<40} | refused: {e}");
            Ok(e)
        }
        Err(e) => Err(format!("`link {line}`: refused for another reason: {e}")),
    }
}

fn wait_for(c: &mut Client, what: &str, f: impl Fn(&Status) -> bool) -> Result<Status> {
    let start = Instant::now();
    loop {
        let s = c.status()?;
        if f(&s) {
            return Ok(s);
        }
        if start.elapsed() > Duration::from_secs(30) {
            return Err(format!(
                "{what}: not within 30 s; status:\n{}",
                status_text(&s)
            ));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The end-to-end link test on the built QEMU image (`cargo xtask test`).
/// Returns the number of checks that passed.
pub fn end_to_end() -> Result<u32> {
    crate::step("host link end to end: QEMU link session over UART0 (cargo xtask link ...)");
    let dir = crate::root().join("target/link-e2e");
    fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let table = crate::default_table_path();
    // A parameter block in the parameter region: the hum notch's Q from
    // 20 to 10 (within its limits), read at boot.
    let block = dir.join("params.zspb");
    let q = params::by_name("hum_notch_q").ok_or("hum_notch_q")?;
    let mut bytes = vec![0u8; params::HEADER_LEN + params::ENTRY_LEN];
    let n = params::encode_block(
        &[(q.id, 10.0)],
        &zslide::servo::ServoDesign::brief(crate::regions::LOOP_HZ),
        &mut bytes,
    )
    .map_err(|e| e.to_string())?;
    fs::write(&block, &bytes[..n]).map_err(|e| e.to_string())?;
    let session = start_session(&dir.join("uart0.sock"), &table, Some(&block))?;
    let mut c = Client::connect(
        &format!("unix:{}", session.socket.display()),
        Duration::from_secs(10),
    )?;
    let mut checks = Checks(0);
    let mut check = |ok: bool, what: &str| checks.ok(ok, what);

    // Status: disarmed, the table of the region, the loop running.
    let out = cli(&mut c, "status")?;
    let s = c.status()?;
    let file = fs::read(&table).map_err(|e| e.to_string())?;
    let want = zslide::table::CoeffTable::parse(&file)
        .map_err(|e| e.to_string())?
        .identity();
    check(
        s.state.phase == LoopPhase::Disarmed && !s.state.amplifier_enabled,
        "status: not disarmed at boot",
    )?;
    check(
        s.table == Ok(want),
        "status: the table identity is not the file's",
    )?;
    check(
        out.contains(&format!("CRC {:#010x}", want.crc)),
        "status text lacks the table CRC",
    )?;
    check(
        matches!(s.params, params::ParamSource::Block { entries: 1, .. }),
        "status: the parameter block was not read",
    )?;
    check(
        cli(&mut c, "get hum_notch_q")?.contains("hum_notch_q = 10 "),
        "the parameter block's value is not in force",
    )?;
    wait_for(&mut c, "the spindle referenced", |s| {
        s.state.phi.is_some() && s.state.x_bits.is_some()
    })?;

    // Parameters out of and within their limits.
    expect_refused(
        &mut c,
        "set following_error_in 0.5",
        "outside its limits 0.000001 .. 0.01 in",
    )?;
    expect_refused(
        &mut c,
        "set learning_lead_bins 3.5",
        "must be a whole number",
    )?;
    expect_refused(
        &mut c,
        "set bandwidth_hz 1000",
        "bandwidth_hz: must be > 0 and below rate_hz / 20",
    )?;
    // A following-error limit of 1 µin with no persistence: the first
    // tick that tracks worse than that trips the fault.
    cli(&mut c, "set following_error_in 0.000001")?;
    cli(&mut c, "set following_error_ms 0")?;
    let got = cli(&mut c, "get following_error_in")?;
    check(
        got.contains("following_error_in = 0.000001 in"),
        "get after set",
    )?;

    // A capture armed on the fault, then arm: the fault triggers it.
    let csv = dir.join("fault.csv");
    // The CLI's capture waits for its trigger, and the link carries one
    // request at a time: here the capture is armed first, the loop armed
    // after, and the CLI's own reader and CSV writer take the result.
    match c.call(&Request::CaptureStart {
        samples: 600,
        pre: 200,
        trigger: Trigger::Fault,
    })? {
        Reply::Capture(i) => check(i.state == CaptureState::Armed, "capture not armed")?,
        r => return Err(unexpected(&r)),
    }
    let armed = cli(&mut c, "arm")?;
    check(armed.contains("armed"), "arm")?;
    let s = wait_for(&mut c, "the 1 µin following-error fault", |s| {
        s.state.fault.is_some()
    })?;
    check(
        s.state.fault == Some(zslide::safety::Fault::FollowingError),
        &format!(
            "expected the following-error fault, got {:?}",
            s.state.fault
        ),
    )?;
    let info = {
        let start = Instant::now();
        loop {
            let i = c.capture_info()?;
            if i.state == CaptureState::Done || start.elapsed() > Duration::from_secs(10) {
                break i;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    check(
        info.state == CaptureState::Done,
        "the fault did not trigger the capture",
    )?;
    // The fault may come before the 200-tick window has filled (it trips
    // soon after the arm): the capture holds what there was, and all 400
    // ticks from the trigger on.
    check(
        info.before_trigger <= 200
            && info.before_trigger > 0
            && info.recorded == info.before_trigger + 400,
        &format!("capture window: {info:?}"),
    )?;
    let samples = c.capture_read(info.recorded)?;
    fs::write(&csv, capture_csv(&info, &samples, s.loop_hz)).map_err(|e| e.to_string())?;
    // The trigger sample is the tick the fault latched: its |error| is over
    // the 1 µin (52 codes) limit; the loop was engaged before it.
    let trig = samples[usize::from(info.before_trigger)];
    check(
        trig.error.unsigned_abs() > 52,
        &format!(
            "trigger sample error {} codes, not over the limit",
            trig.error
        ),
    )?;
    let text = fs::read_to_string(&csv).map_err(|e| e.to_string())?;
    check(
        text.lines().count() == usize::from(info.recorded) + 1
            && text
                .starts_with("t_s,tick,command_uin,position_uin,error_uin,output_v,phi_deg,x_in"),
        "capture CSV",
    )?;

    // The fault log has it, at the capture's trigger tick, in words.
    let log = cli(&mut c, "faults")?;
    let (_, records) = c.fault_log()?;
    check(
        records.iter().any(|r| {
            r.fault == zslide::safety::Fault::FollowingError
                && !r.cleared
                && r.tick == info.trigger_tick
        }),
        "fault log: the following-error record at the trigger tick",
    )?;
    check(
        log.contains("LATCHED following error beyond its limit"),
        "fault log words",
    )?;

    // Clear: refused while armed (the fault ramps to null with the loop
    // closed), accepted once disarmed.
    expect_refused(&mut c, "clear", "clear refused")?;
    expect_refused(
        &mut c,
        "set following_error_in 0.004",
        "only while the loop is disarmed",
    )?;
    cli(&mut c, "disarm")?;
    wait_for(&mut c, "disarmed", |s| s.state.phase == LoopPhase::Disarmed)?;
    let cleared = cli(&mut c, "clear")?;
    check(
        cleared.contains("cleared: following error beyond its limit"),
        "clear",
    )?;
    check(
        c.status()?.state.fault.is_none(),
        "fault still latched after the clear",
    )?;
    let (_, records) = c.fault_log()?;
    check(
        records.last().is_some_and(|r| r.cleared),
        "the clear is not in the log",
    )?;
    expect_refused(&mut c, "clear", "no fault is latched")?;

    // Back to the built-in limits; arm; an immediate capture through the
    // CLI, with its plot; then a following-error-level trigger.
    cli(&mut c, "set following_error_in 0.004")?;
    cli(&mut c, "set following_error_ms 2")?;
    cli(&mut c, "arm")?;
    wait_for(&mut c, "engaged", |s| s.state.phase == LoopPhase::Engaged)?;
    let csv2 = dir.join("immediate.csv");
    cli(
        &mut c,
        &format!(
            "capture --samples 400 --trigger immediate --csv {} --plot {}",
            csv2.display(),
            dir.join("immediate").display()
        ),
    )?;
    check(
        fs::read_to_string(&csv2)
            .map_err(|e| e.to_string())?
            .lines()
            .count()
            == 401,
        "immediate capture CSV",
    )?;
    check(
        dir.join("immediate.svg").exists() && dir.join("immediate.png").exists(),
        "capture plot",
    )?;
    let csv3 = dir.join("ferr.csv");
    cli(
        &mut c,
        &format!(
            "capture --samples 100 --pre 50 --trigger ferr:1 --csv {}",
            csv3.display()
        ),
    )?;
    let i3 = c.capture_info()?;
    let s3 = c.capture_read(i3.recorded)?;
    let t3 = s3[usize::from(i3.before_trigger)];
    check(
        t3.error.unsigned_abs() >= 52,
        "following-error trigger sample below its level",
    )?;
    check(
        s3[usize::from(i3.before_trigger) - 1].error.unsigned_abs() < 52,
        "the sample before the following-error trigger already over its level",
    )?;
    expect_refused(
        &mut c,
        "capture --samples 2000 --trigger immediate --csv /dev/null",
        "samples must be 1..=1024",
    )?;
    cli(&mut c, "disarm")?;

    // Malformed frames, sent raw: each refused by name and counted; the
    // firmware keeps answering.
    let before = c.status()?.frames;
    let mut good = [0u8; MAX_FRAME];
    let good = proto::encode(9, &Request::Faults { from: 0 }, &mut good)
        .ok_or("encode")?
        .to_vec();
    let raw = host_sim::faults::link::frame;
    let mut bad_crc = good.clone();
    bad_crc[3] ^= 0x08;
    let mut truncated = good[..good.len() - 4].to_vec();
    truncated.push(0);
    let mut oversize = vec![0x42u8; 300];
    oversize.push(0);
    let cases: [(&str, Vec<u8>); 6] = [
        ("garbage", vec![0x13, 0x37, 0xFF, 0x01, 0x00]),
        ("truncated", truncated),
        ("bad CRC", bad_crc),
        ("unknown command", raw(&[proto::VERSION, 9, 77])),
        ("other version", raw(&[9, 9, 0])),
        ("oversize", oversize),
    ];
    for (name, bytes) in cases {
        c.send_raw(&bytes)?;
        match c.receive()? {
            (_, Reply::Refused(Refusal::Frame(e))) => {
                eprintln!("  raw {name:<36} | refused: {e}");
                let fits = match name {
                    "unknown command" => e == FrameError::UnknownCommand(77),
                    "other version" => e == FrameError::BadVersion(9),
                    "oversize" => e == FrameError::Oversize,
                    "bad CRC" => matches!(e, FrameError::BadCrc { .. }),
                    _ => true,
                };
                check(fits, &format!("{name}: refused as {e:?}"))?;
            }
            (_, r) => return Err(format!("{name}: answered {r:?}")),
        }
    }
    let after = cli(&mut c, "status").and_then(|_| c.status())?.frames;
    let refused = |f: proto::FrameCounters| {
        f.oversize + f.bad_cobs + f.bad_crc + f.bad_version + f.unknown_command + f.malformed
    };
    check(
        refused(after) - refused(before) == 6,
        "malformed frames not counted",
    )?;
    drop(session);
    let n = checks.0;
    eprintln!(
        "host link end to end: {n} checks passed (files in {})",
        dir.display()
    );
    Ok(n)
}

struct Checks(u32);
impl Checks {
    fn ok(&mut self, ok: bool, what: &str) -> Result<()> {
        if ok {
            self.0 += 1;
            Ok(())
        } else {
            Err(format!("link end to end: {what}"))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triggers_parse_and_refuse_nonsense() {
        assert_eq!(parse_trigger("immediate"), Ok(Trigger::Immediate));
        assert_eq!(parse_trigger("fault"), Ok(Trigger::Fault));
        // 10 µin = 524.288 gauge codes.
        assert_eq!(
            parse_trigger("ferr:10"),
            Ok(Trigger::FollowingError { level: 524 })
        );
        for bad in ["ferr:", "ferr:-1", "ferr:x", "sometimes", "ferr:20000"] {
            assert!(parse_trigger(bad).is_err(), "{bad}");
        }
    }

    /// CSV values are the codes in the documented units: 52.4288 codes per
    /// µin, 10 V per 2¹⁹ codes, 2³² per turn, 2²⁴ per inch; time from the
    /// trigger at the loop rate.
    #[test]
    fn capture_csv_converts_codes_to_units() {
        let info = CaptureInfo {
            state: CaptureState::Done,
            trigger: Trigger::Immediate,
            samples: 2,
            pre: 1,
            recorded: 2,
            before_trigger: 1,
            trigger_tick: 101,
            capacity: 1024,
        };
        let s = Sample {
            command: 524_288,
            position: 0,
            error: 524_288,
            output: -262_144,
            phi: 1 << 30,
            x_bits: 3 << 23,
        };
        let csv = capture_csv(&info, &[s, s], 20_000);
        let rows: Vec<&str> = csv.lines().collect();
        assert_eq!(
            rows[1],
            "-0.000050,100,10000.0000,0.0000,10000.0000,-5.000000,90.0000,1.5000000"
        );
        assert!(rows[2].starts_with("0.000000,101,"));
    }
}
