//! The probe's side of RTT (SEGGER's control block, which `rtt-target`
//! lays out in the image's RAM): up channels read and their read offsets
//! advanced, down channel 1 written and its write offset advanced, by
//! memory accesses between instructions, the way a debug probe reads and
//! writes RAM while the core runs. Channel 1 is bridged to a Unix socket
//! (as OpenOCD's `rtt server` bridges it to TCP on the board), channel 0
//! (the defmt log) to a file.

use std::io::{ErrorKind, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};

use unicorn_engine::Unicorn;

use crate::board::Board;

/// SEGGER_RTT_CB: 16-byte id, max up, max down, then the buffers (24
/// bytes each: name, buffer, size, write offset, read offset, flags).
const ID: &[u8; 10] = b"SEGGER RTT";

pub struct Rtt {
    cb: u32,
    max_up: u32,
    pub socket: Option<UnixListener>,
    client: Option<UnixStream>,
    pub log: Vec<u8>,
    pub link_bytes: (u64, u64),
    pub client_gone: bool,
    pub end_on_close: bool,
}

fn rd(uc: &Unicorn<Board>, a: u32) -> u32 {
    let mut b = [0u8; 4];
    let _ = uc.mem_read(u64::from(a), &mut b);
    u32::from_le_bytes(b)
}
fn wr(uc: &mut Unicorn<Board>, a: u32, v: u32) {
    let _ = uc.mem_write(u64::from(a), &v.to_le_bytes());
}

impl Rtt {
    pub fn new(cb: u32, socket: Option<UnixListener>) -> Self {
        Self {
            cb,
            max_up: 0,
            socket,
            client: None,
            log: Vec::new(),
            link_bytes: (0, 0),
            client_gone: false,
            end_on_close: false,
        }
    }

    /// Whether the firmware has written its control block yet.
    fn ready(&mut self, uc: &Unicorn<Board>) -> bool {
        if self.max_up != 0 {
            return true;
        }
        let mut id = [0u8; 10];
        if uc.mem_read(u64::from(self.cb), &mut id).is_err() || &id != ID {
            return false;
        }
        self.max_up = rd(uc, self.cb + 16);
        self.max_up != 0
    }

    fn up(&self, ch: u32) -> u32 {
        self.cb + 24 + 24 * ch
    }
    fn down(&self, ch: u32) -> u32 {
        self.cb + 24 + 24 * self.max_up + 24 * ch
    }

    /// Takes what up channel `ch` holds.
    fn read_up(&self, uc: &mut Unicorn<Board>, ch: u32) -> Vec<u8> {
        let d = self.up(ch);
        let (buf, size, wr_off, mut rd_off) =
            (rd(uc, d + 4), rd(uc, d + 8), rd(uc, d + 12), rd(uc, d + 16));
        let mut out = Vec::new();
        if size == 0 {
            return out;
        }
        while rd_off != wr_off {
            let end = if wr_off > rd_off { wr_off } else { size };
            let mut b = vec![0u8; (end - rd_off) as usize];
            let _ = uc.mem_read(u64::from(buf + rd_off), &mut b);
            out.extend_from_slice(&b);
            rd_off = if end == size { 0 } else { end };
        }
        wr(uc, d + 16, rd_off);
        out
    }

    /// Puts as much of `bytes` into down channel `ch` as fits; how much.
    fn write_down(&self, uc: &mut Unicorn<Board>, ch: u32, bytes: &[u8]) -> usize {
        let d = self.down(ch);
        let (buf, size, mut wr_off, rd_off) =
            (rd(uc, d + 4), rd(uc, d + 8), rd(uc, d + 12), rd(uc, d + 16));
        let mut n = 0;
        for &b in bytes {
            let next = (wr_off + 1) % size.max(1);
            if next == rd_off || size == 0 {
                break;
            }
            let _ = uc.mem_write(u64::from(buf + wr_off), &[b]);
            wr_off = next;
            n += 1;
        }
        wr(uc, d + 12, wr_off);
        n
    }

    /// A client has come and gone: with `--end-on-close` the run ends, so
    /// no other is accepted; otherwise the next one may connect.
    fn client_gone_latched(&mut self) -> bool {
        if self.end_on_close {
            return self.client_gone;
        }
        self.client_gone = false;
        false
    }

    /// One probe pass: the log out, the link both ways.
    pub fn poll(&mut self, uc: &mut Unicorn<Board>, pending_down: &mut Vec<u8>) {
        if !self.ready(uc) {
            return;
        }
        let log = self.read_up(uc, 0);
        self.log.extend_from_slice(&log);
        if self.client.is_none() && !self.client_gone_latched() {
            if let Some(l) = &self.socket {
                if let Ok((s, _)) = l.accept() {
                    let _ = s.set_nonblocking(true);
                    self.client = Some(s);
                }
            }
        }
        let up = self.read_up(uc, 1);
        self.link_bytes.0 += up.len() as u64;
        if let Some(c) = &mut self.client {
            if !up.is_empty() {
                let _ = c.set_nonblocking(false);
                let _ = c.write_all(&up);
                let _ = c.set_nonblocking(true);
            }
            let mut b = [0u8; 512];
            match c.read(&mut b) {
                Ok(0) => {
                    self.client = None;
                    self.client_gone = true;
                }
                Ok(n) => pending_down.extend_from_slice(&b[..n]),
                Err(e) if e.kind() == ErrorKind::WouldBlock => {}
                Err(_) => {
                    self.client = None;
                    self.client_gone = true;
                }
            }
        }
        if !pending_down.is_empty() {
            let n = self.write_down(uc, 1, pending_down);
            self.link_bytes.1 += n as u64;
            pending_down.drain(..n);
        }
    }
}
