//! `host-sim serve`: the whole simulated machine (the firmware rig: the
//! core's firmware on the simulated chips, amplifier, slide, gauge,
//! spindle and X slide) behind the firmware's own link
//! (`crate::fwrig::link`: tap, station and the RTT buffers of the NUCLEO), on a
//! TCP port or a Unix socket, running in simulated real time. Every
//! `zslide` command works on it as on a board.
//!
//! Time: the simulation advances in steps of [`STEP_NS`] of machine time,
//! never ahead of the wall clock × `speed`; after each step the bytes the
//! host sent go into the link's host backlog and the bytes the firmware
//! sent go out. A simulation that falls behind the wall clock (a slow
//! machine) runs as fast as it can: the firmware never sees time skip.
//!
//! Lockstep (`--lockstep`, [`Setup::lockstep`]): machine time advances
//! only while a request is in flight. A whole request frame (up to its
//! 0x00) is handed to the link, the machine runs as fast as it can until
//! the reply's delimiter comes back, and stops there until the next
//! frame. What the firmware sees is then a function of the host's requests
//! alone, never of when they arrive: a slow or loaded host (or one that
//! sleeps between frames) gets bit-identical answers. The link's protocol
//! allows it: one request in flight, exactly one reply to each non-empty
//! frame. A board has no such mode: its loop runs in real time whatever
//! the host does.
//!
//! One host at a time, as on the board's RTT channel: a second connection
//! waits until the first closes. The machine keeps running between
//! connections.

use crate::cut::test_cut::{TestCut, TestCutHook};
use crate::fwrig::link::{ParamsFlash, ParamsStore, PARAMS_REGION_BYTES};
use crate::fwrig::{machine_with_table, FirmwareWorld};
use crate::machine::xslide::FeedSegment;
use crate::scenario::Scenario;
use crate::sched::{Nanos, Scheduler};
use anyhow::{bail, Context};
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zslide::params::ParamSource;
use zslide::safety::Fault;

/// Machine time per step between socket transfers, ns (the host's RTT
/// polling period of the board, `link::HOST_POLL_NS`).
pub const STEP_NS: Nanos = crate::fwrig::link::HOST_POLL_NS;

/// Where the machine listens.
pub enum Listener {
    Tcp(TcpListener),
    Unix(UnixListener, PathBuf),
}

impl Listener {
    /// `tcp:HOST:PORT` or `unix:PATH` (port 0: any free port; see
    /// [`Listener::address`]).
    pub fn bind(addr: &str) -> anyhow::Result<Self> {
        let l = if let Some(a) = addr.strip_prefix("tcp:") {
            Listener::Tcp(TcpListener::bind(a).with_context(|| format!("listening on {addr}"))?)
        } else if let Some(p) = addr.strip_prefix("unix:") {
            let path = PathBuf::from(p);
            if path.exists() {
                // Only a socket left by an earlier run is replaced.
                if UnixStream::connect(&path).is_ok() {
                    bail!("listening on {addr}: another machine already serves there");
                }
                std::fs::remove_file(&path)
                    .with_context(|| format!("listening on {addr}: cannot replace {p}"))?;
            }
            Listener::Unix(
                UnixListener::bind(&path).with_context(|| format!("listening on {addr}"))?,
                path,
            )
        } else {
            bail!("--listen {addr:?}: expected tcp:HOST:PORT or unix:PATH");
        };
        match &l {
            Listener::Tcp(t) => t.set_nonblocking(true)?,
            Listener::Unix(u, _) => u.set_nonblocking(true)?,
        }
        Ok(l)
    }

    /// The address a host connects to (`zslide --connect`).
    pub fn address(&self) -> String {
        match self {
            Listener::Tcp(t) => t
                .local_addr()
                .map_or("tcp:?".into(), |a| format!("tcp:{a}")),
            Listener::Unix(_, p) => format!("unix:{}", p.display()),
        }
    }

    fn accept(&self) -> std::io::Result<Option<Box<dyn Conn>>> {
        let r = match self {
            Listener::Tcp(t) => t.accept().map(|(s, _)| {
                let _ = s.set_nodelay(true);
                Box::new(s) as Box<dyn Conn>
            }),
            Listener::Unix(u, _) => u.accept().map(|(s, _)| Box::new(s) as Box<dyn Conn>),
        };
        match r {
            Ok(c) => {
                c.nonblocking()?;
                Ok(Some(c))
            }
            Err(e) if e.kind() == ErrorKind::WouldBlock => Ok(None),
            Err(e) => Err(e),
        }
    }
}

impl Drop for Listener {
    fn drop(&mut self) {
        if let Listener::Unix(_, p) = self {
            let _ = std::fs::remove_file(p);
        }
    }
}

trait Conn: Read + Write {
    fn nonblocking(&self) -> std::io::Result<()>;
}
impl Conn for TcpStream {
    fn nonblocking(&self) -> std::io::Result<()> {
        self.set_nonblocking(true)
    }
}
impl Conn for UnixStream {
    fn nonblocking(&self) -> std::io::Result<()> {
        self.set_nonblocking(true)
    }
}

/// The host's handle on the machine's link.
pub type SharedLink = std::rc::Rc<std::cell::RefCell<crate::fwrig::HostLink>>;

/// The machine `serve` runs.
#[derive(Clone)]
pub struct Setup {
    pub scenario: Scenario,
    /// The table image in the table region.
    pub table: &'static [u8],
    /// Where the X slide stands, inches, and its feed, in/min (0: still).
    pub x_in: f64,
    pub feed_in_per_min: f64,
    /// Spindle speed, rpm.
    pub rpm: f64,
    /// Machine seconds per wall-clock second (not with `lockstep`).
    pub speed: f64,
    /// Machine time advances only while a host request awaits its reply
    /// (module docs): the wall clock has no say.
    pub lockstep: bool,
    /// The parameter region's flash: shared by the clones of a setup, so
    /// a machine served again from a clone boots from what the last one
    /// saved (a power cycle of the board).
    pub params_flash: Arc<Mutex<ParamsFlash>>,
    /// A file holding the parameter region's image across runs of
    /// `host-sim serve` (the board's flash across power cycles): read at
    /// the start, rewritten whole after every flash operation.
    pub params_file: Option<PathBuf>,
    /// The tool engaged in a light test cut at the null position
    /// (`cut::test_cut`), in the scenario's force model (its `cutting`).
    pub cut: Option<TestCut>,
}

impl Setup {
    /// The scenario's machine as it stands: its X position, still, at its
    /// spindle speed, the built-in table, real time.
    pub fn new(scenario: Scenario) -> Self {
        let x_in = match &scenario.machine.x {
            crate::machine::XInterface::LegacyBcd(c)
            | crate::machine::XInterface::Quadrature(c) => c.x0_in,
        };
        let rpm = scenario.machine.spindle.rpm0;
        Self {
            scenario,
            table: zslide::DEFAULT_TABLE,
            x_in,
            feed_in_per_min: 0.0,
            rpm,
            speed: 1.0,
            lockstep: false,
            params_flash: Arc::new(Mutex::new(ParamsFlash::new())),
            params_file: None,
            cut: None,
        }
    }

    /// The parameter region's flash kept in `path`: its image when the file
    /// exists (it must be a whole region, as this wrote it), erased flash
    /// when it does not (the file appears at the first save).
    pub fn with_params_file(mut self, path: PathBuf) -> anyhow::Result<Self> {
        let flash = match std::fs::read(&path) {
            Ok(image) => {
                anyhow::ensure!(
                    image.len() == PARAMS_REGION_BYTES,
                    "{}: {} bytes, but a parameter region image is {PARAMS_REGION_BYTES} \
                     (the file `host-sim serve --params-flash` writes)",
                    path.display(),
                    image.len()
                );
                ParamsFlash::with_image(&image)
            }
            Err(e) if e.kind() == ErrorKind::NotFound => ParamsFlash::new(),
            Err(e) => bail!("{}: cannot read: {e}", path.display()),
        };
        self.params_flash = Arc::new(Mutex::new(flash));
        self.params_file = Some(path);
        Ok(self)
    }

    /// Refuses settings no machine can be built with (before anything
    /// is announced or bound).
    pub fn check(&self) -> anyhow::Result<()> {
        if !(self.speed > 0.0 && self.speed <= 100.0) {
            bail!("--speed {}: must be in (0, 100]", self.speed);
        }
        if self.lockstep && self.speed != 1.0 {
            bail!(
                "--speed {} with --lockstep: a machine in lockstep runs only while a request \
                 awaits its reply, at no pace of the wall clock",
                self.speed
            );
        }
        if let Some(c) = &self.cut {
            c.check()?;
        }
        Ok(())
    }

    /// The world, disarmed as a board boots, with its link attached.
    pub fn build(&self) -> anyhow::Result<(FirmwareWorld, Scheduler<FirmwareWorld>, SharedLink)> {
        self.check()?;
        let sc = &self.scenario;
        let mut machine = sc.machine.clone();
        match &mut machine.x {
            crate::machine::XInterface::LegacyBcd(c)
            | crate::machine::XInterface::Quadrature(c) => {
                c.x0_in = self.x_in;
                c.feed = vec![FeedSegment {
                    t_start_s: 0.0,
                    feed_in_per_min: self.feed_in_per_min,
                }];
            }
        }
        machine.spindle.rpm0 = self.rpm;
        // The boot's parameter order (`zslide::store::boot`): the store's
        // last block, else the region's raw block (none here: an erased
        // header), else the scenario's design.
        let flash = self
            .params_flash
            .lock()
            .map_err(|_| anyhow::anyhow!("the parameter flash's lock is poisoned"))?
            .clone();
        let mut store = ParamsStore::new(flash, 0..PARAMS_REGION_BYTES as u32)
            .map_err(|e| anyhow::anyhow!("the parameter store: {e}"))?;
        let erased = [0xFF; zslide::params::HEADER_LEN];
        let (design, cfg, source) =
            zslide::store::boot::at_boot(&mut store, &erased, &sc.servo_design).map_err(|e| {
                anyhow::anyhow!("the scenario's servo design is refused: {}", e.reason())
            })?;
        let cfg = match source {
            ParamSource::Block { .. } => cfg,
            _ => sc.servo,
        };
        let (mut w, mut s) =
            machine_with_table(sc.rig.clone(), &machine, sc.loop_hz, cfg, self.table);
        if let ParamSource::Refused(e) = source {
            w.fw.trip(Fault::Parameters(e));
        }
        if let Some(cut) = self.cut {
            w.hooks.push(Box::new(TestCutHook::new(
                cut,
                sc.cutting.clone(),
                sc.file.errors.cut_force_noise_lbf,
                sc.rig.seed,
            )));
        }
        let link = crate::fwrig::link::attach(&mut w, &mut s, sc.loop_hz, design, source)?;
        link.borrow_mut().set_store(store);
        Ok((w, s, link))
    }
}

/// Lockstep: machine time a request may take before the machine stops
/// waiting for its reply (the station answers every request within its
/// own deadline, `Refusal::LoopSilent`, far sooner: this only keeps a
/// lost reply from running the machine on for ever).
pub const LOCKSTEP_REPLY_NS: Nanos = 10_000_000_000;

/// Runs the machine behind `listener` until `stop` is set (never, from the
/// command line).
pub fn serve(setup: &Setup, listener: &Listener, stop: &AtomicBool) -> anyhow::Result<()> {
    let (mut w, mut s, link) = setup.build()?;
    let mut conn: Option<Box<dyn Conn>> = None;
    let start = Instant::now();
    let mut t: Nanos = 0;
    let mut buf = [0u8; 4096];
    let mut flash_ops = link.borrow_mut().store_flash().map(|f| f.ops);
    // Lockstep: the host's bytes not yet handed to the link, and the
    // machine time at which the request in flight was handed over.
    let mut held: Vec<u8> = Vec::new();
    let mut asked: Option<Nanos> = None;
    while !stop.load(Ordering::Relaxed) {
        if conn.is_none() {
            conn = listener.accept().context("accepting a host")?;
        }
        if let Some(c) = conn.as_mut() {
            let mut closed = false;
            loop {
                match c.read(&mut buf) {
                    Ok(0) => {
                        closed = true;
                        break;
                    }
                    Ok(n) if setup.lockstep => held.extend_from_slice(&buf[..n]),
                    Ok(n) => link.borrow_mut().send(&buf[..n]),
                    Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                    Err(e) if e.kind() == ErrorKind::Interrupted => {}
                    Err(_) => {
                        closed = true;
                        break;
                    }
                }
            }
            if closed {
                conn = None;
                // A frame the host never finished is no request.
                held.clear();
            }
        }
        if setup.lockstep {
            if asked.is_none() {
                // One whole frame at a time: a lone delimiter (an empty
                // frame) gets no reply, any other frame exactly one.
                let Some(end) = held.iter().position(|&b| b == 0) else {
                    std::thread::sleep(Duration::from_micros(100));
                    continue;
                };
                let frame: Vec<u8> = held.drain(..=end).collect();
                link.borrow_mut().send(&frame);
                if frame.len() == 1 {
                    continue;
                }
                asked = Some(t);
            }
        } else {
            // Never ahead of the wall clock.
            let wall = (start.elapsed().as_secs_f64() * setup.speed * 1e9) as Nanos;
            if t + STEP_NS > wall {
                std::thread::sleep(Duration::from_nanos((t + STEP_NS - wall).min(1_000_000)));
                continue;
            }
        }
        t += STEP_NS;
        s.run_until(&mut w, t);
        if let Some(path) = &setup.params_file {
            let mut l = link.borrow_mut();
            if let Some(f) = l.store_flash().filter(|f| Some(f.ops) != flash_ops) {
                flash_ops = Some(f.ops);
                crate::outpath::replace(path, f.bytes)?;
            }
        }
        let out = link.borrow_mut().take_received();
        if let Some(at) = asked {
            if out.contains(&0) || t - at >= LOCKSTEP_REPLY_NS {
                asked = None;
            }
        }
        if let (Some(c), false) = (conn.as_mut(), out.is_empty()) {
            if write_all_nonblocking(c.as_mut(), &out).is_err() {
                conn = None;
            }
        }
    }
    // The firmware stops; its flash stays for the next boot.
    if let (Some(st), Ok(mut f)) = (link.borrow_mut().take_store(), setup.params_flash.lock()) {
        *f = st.into_flash();
    }
    Ok(())
}

fn write_all_nonblocking(c: &mut dyn Conn, mut out: &[u8]) -> std::io::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(2);
    while !out.is_empty() {
        match c.write(out) {
            Ok(0) => return Err(ErrorKind::WriteZero.into()),
            Ok(n) => out = &out[n..],
            Err(e) if e.kind() == ErrorKind::WouldBlock && Instant::now() < deadline => {
                std::thread::sleep(Duration::from_micros(200));
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}
