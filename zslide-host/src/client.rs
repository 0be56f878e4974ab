//! The host's end of the firmware's link (`zslide::link`, protocol in
//! `docs/BOARD.md`): a byte stream, one request and one reply at a time.
//!
//! The stream is a TCP port (an RTT-to-TCP bridge on the NUCLEO's link
//! channel, or `host-sim serve`), a Unix socket (the QEMU image's UART0,
//! `cargo xtask qemu-link`, or `host-sim serve --listen unix:PATH`) or,
//! with the `probe` feature, RTT channel 1 through the probe-rs library.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::os::unix::net::UnixStream;
use std::time::{Duration, Instant};

use zslide::link::proto::{
    self, CaptureInfo, CaptureState, FaultRecord, Reply, Request, Sample, Status, Trigger,
    MAX_FRAME,
};

use crate::Result;

/// Where the link is when no `--connect` (or `ZSLIDE_CONNECT`) says: the
/// RTT bridge's usual port (`docs/BOARD.md`).
pub const DEFAULT_ADDR: &str = "tcp:127.0.0.1:9090";

/// A byte stream to the firmware whose reads time out (`WouldBlock` or
/// `TimedOut`) rather than block.
pub trait Transport: Read + Write + Send {}
impl<T: Read + Write + Send> Transport for T {}

/// Why a connection failed, and where to look: nothing listening is the
/// usual first-day mistake, so the refusal names the ways to start a link.
fn connect_error(addr: &str, e: &std::io::Error) -> String {
    let hint = match e.kind() {
        std::io::ErrorKind::ConnectionRefused | std::io::ErrorKind::NotFound => format!(
            "\n  nothing is listening at {addr}. Start a link first, then give its address with \
             --connect (or ZSLIDE_CONNECT):\n    a simulated machine:  host-sim serve --scenario \
             legacy-hw --listen tcp:127.0.0.1:9090\n    the QEMU image:       cargo xtask \
             qemu-link   (then --connect unix:target/zslide-link.sock)\n    a NUCLEO:             \
             the RTT bridge of docs/BOARD.md (port 9090){}",
            if cfg!(feature = "probe") {
                ", or --connect probe: (this build has the probe-rs library)"
            } else {
                ""
            }
        ),
        _ => String::new(),
    };
    format!("connecting to {addr}: {e}{hint}")
}

/// Opens `addr`: `tcp:HOST:PORT`, `unix:PATH` or (feature `probe`)
/// `probe:[SELECTOR]`.
pub fn open(addr: &str) -> Result<Box<dyn Transport>> {
    let poll = Some(Duration::from_millis(20));
    if let Some(a) = addr.strip_prefix("tcp:") {
        let s = TcpStream::connect(a).map_err(|e| connect_error(addr, &e))?;
        s.set_read_timeout(poll).map_err(|e| e.to_string())?;
        s.set_nodelay(true).map_err(|e| e.to_string())?;
        Ok(Box::new(s))
    } else if let Some(p) = addr.strip_prefix("unix:") {
        let s = UnixStream::connect(p).map_err(|e| connect_error(addr, &e))?;
        s.set_read_timeout(poll).map_err(|e| e.to_string())?;
        Ok(Box::new(s))
    } else if let Some(sel) = addr.strip_prefix("probe:") {
        #[cfg(feature = "probe")]
        {
            Ok(Box::new(crate::probe::RttLink::attach(sel)?))
        }
        #[cfg(not(feature = "probe"))]
        {
            let _ = sel;
            Err(format!(
                "{addr:?}: this zslide is built without the probe-rs library; reinstall it with \
                 `cargo install --path zslide-host --features probe`, or bridge RTT to TCP \
                 (docs/BOARD.md) and use --connect tcp:HOST:PORT"
            ))
        }
    } else {
        Err(format!(
            "{addr:?}: expected tcp:HOST:PORT, unix:PATH or probe:[SELECTOR]"
        ))
    }
}

/// A connection that speaks the protocol.
pub struct Client {
    s: Box<dyn Transport>,
    seq: u16,
    rx: Vec<u8>,
    timeout: Duration,
}

impl Client {
    pub fn connect(addr: &str, timeout: Duration) -> Result<Self> {
        Ok(Self::over(open(addr)?, timeout))
    }

    pub fn over(s: Box<dyn Transport>, timeout: Duration) -> Self {
        Self {
            s,
            seq: 0,
            rx: Vec::new(),
            timeout,
        }
    }

    /// Sends bytes as they are (the malformed-frame tests).
    pub fn send_raw(&mut self, bytes: &[u8]) -> Result<()> {
        self.s
            .write_all(bytes)
            .and_then(|()| self.s.flush())
            .map_err(|e| format!("link: {e}"))
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
                // A signal arriving mid-read (Ctrl-C) is noted by its
                // handler; the reply is still read.
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(format!("link: {e}")),
            }
        }
    }

    /// One request, its reply; none once a signal asked the command to
    /// stop (`crate::interrupt`): then only [`Client::make_safe`] talks.
    pub fn call(&mut self, req: &Request) -> Result<Reply> {
        if let Some(sig) = crate::interrupt::received() {
            return Err(crate::interrupt::refusal(sig));
        }
        self.exchange(req)
    }

    /// Leaves the machine as the loop alone drives it: a running
    /// excitation stopped (`Excite` with 0 ticks) and a capture still
    /// waiting for its trigger released (re-armed as one immediate
    /// sample, which completes on the next tick; a finished capture's
    /// samples stay). What a command that stops part-way, by an error or
    /// a signal, sends before it exits. Returns what it stopped.
    pub fn make_safe(&mut self) -> Result<Vec<&'static str>> {
        let mut did = Vec::new();
        let st = match self.exchange(&Request::Status)? {
            Reply::Status(s) => s,
            r => return Err(unexpected(&r)),
        };
        // A stop (0 ticks) is accepted in every phase, and sent even when
        // the status says none runs: one may start between the two.
        match self.exchange(&Request::Excite {
            step: 0,
            amplitude: 0,
            ticks: 0,
        })? {
            Reply::Exciting { .. } if st.state.exciting => did.push("excitation stopped"),
            Reply::Exciting { .. } => {}
            r => return Err(format!("stopping the excitation: {}", unexpected(&r))),
        }
        if matches!(
            st.capture.state,
            CaptureState::Armed | CaptureState::Triggered
        ) {
            match self.exchange(&Request::CaptureStart {
                samples: 1,
                pre: 0,
                trigger: Trigger::Immediate,
            })? {
                Reply::Capture(_) => did.push("armed capture released"),
                r => return Err(format!("releasing the capture: {}", unexpected(&r))),
            }
        }
        Ok(did)
    }

    fn exchange(&mut self, req: &Request) -> Result<Reply> {
        let before = self.seq;
        self.seq = self.seq.wrapping_add(1).max(1);
        let mut out = [0u8; MAX_FRAME];
        let frame = proto::encode(self.seq, req, &mut out).ok_or("request does not encode")?;
        self.send_raw(frame)?;
        loop {
            let (seq, reply) = self.receive()?;
            // The late reply to the request before, which a command
            // stopped part-way (an error, a signal) did not wait for: a
            // request's own reply is read only once.
            if seq == before && before != 0 {
                continue;
            }
            if seq != self.seq {
                return Err(format!(
                    "reply number {seq} to request number {}: out of step",
                    self.seq
                ));
            }
            return Ok(reply);
        }
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

/// A reply that is not the one asked for: a refusal in the firmware's
/// words, anything else as it came.
pub fn unexpected(r: &Reply) -> String {
    match r {
        Reply::Refused(why) => why.to_string(),
        r => format!("unexpected reply {r:?}"),
    }
}

/// The link, opened on first use.
pub struct Link {
    addr: String,
    timeout: Duration,
    client: Option<Client>,
}

impl Link {
    pub fn new(addr: &str, timeout: Duration) -> Self {
        Self {
            addr: addr.into(),
            timeout,
            client: None,
        }
    }

    /// An open connection (tests drive a session they opened).
    pub fn from_client(c: Client) -> Self {
        Self {
            addr: String::new(),
            timeout: Duration::ZERO,
            client: Some(c),
        }
    }

    /// [`Client::make_safe`] on the connection the command opened (none:
    /// the command never reached the machine, nothing to stop).
    pub fn make_safe(&mut self) -> Option<Result<Vec<&'static str>>> {
        self.client.as_mut().map(Client::make_safe)
    }

    pub fn client(&mut self) -> Result<&mut Client> {
        match &mut self.client {
            Some(c) => Ok(c),
            slot => Ok(slot.insert(Client::connect(&self.addr, self.timeout)?)),
        }
    }
}

pub(crate) fn set(c: &mut Client, id: u16, value: f64) -> Result<f64> {
    match c.call(&Request::Set { id, value })? {
        Reply::Param { value, .. } => Ok(value),
        r => Err(unexpected(&r)),
    }
}

pub(crate) fn get(c: &mut Client, id: u16) -> Result<f64> {
    match c.call(&Request::Get { id })? {
        Reply::Param { value, .. } => Ok(value),
        r => Err(unexpected(&r)),
    }
}
