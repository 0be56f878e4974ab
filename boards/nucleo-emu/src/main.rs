//! `nucleo-emu`: the unmodified `zslide-fw` ELF on an emulated
//! NUCLEO-H743ZI2 (`docs/BOARD.md`, "Emulated NUCLEO"). `cargo xtask
//! nucleo` builds and drives it; by hand:
//!
//! ```sh
//! nucleo-emu --elf target/thumbv7em-none-eabihf/release/zslide-fw \
//!     --table tables/default.zsct --bank2 target/nucleo/bank2.bin \
//!     --ms 300 [--socket target/nucleo/link.sock] [--press 20..60] \
//!     [--break-gauge-at 250] [--log target/nucleo/defmt.bin]
//! ```
//!
//! It prints one JSON object: how far the run got, what stopped it (an
//! unmodelled register or a broken rule, by name and address), and what
//! the board saw. With `--socket` the firmware's RTT link channel is there
//! for `zslide --connect unix:PATH` (one client at a time, the next one
//! after a disconnect); with `--end-on-close` the run ends when the first
//! client disconnects (or at `--ms`). `NUCLEO_EMU_DEBUG=1` prints the
//! core's PC, SP, LR and active exceptions at the end (bring-up aid).

mod adc;
mod board;
mod clocks;
mod converters;
mod cpu;
mod elf;
mod flash;
mod gpio;
mod link;
mod scs;
mod spi;
mod system;
mod timers;
mod world;

use std::path::PathBuf;
use std::process::ExitCode;

/// Why a register access stopped the run.
#[derive(Debug)]
pub enum Violation {
    /// No model implements the register.
    Unmodelled,
    /// The access breaks a rule of RM0433 or a converter's datasheet.
    Rule(String),
}

impl Violation {
    pub fn rule(s: impl Into<String>) -> Self {
        Violation::Rule(s.into())
    }
}

/// The table region (`memory.x`: ZSCT, bank 1 sector 7).
const ZSCT: u32 = 0x080E_0000;
const ZSCT_SIZE: usize = 128 * 1024;
const MS: u64 = 1_000_000_000;

struct Args {
    elf: PathBuf,
    table: Option<PathBuf>,
    bank2: Option<PathBuf>,
    ms: u64,
    socket: Option<PathBuf>,
    press: Vec<(u64, u64)>,
    break_gauge_at: Option<u64>,
    log: Option<PathBuf>,
    end_on_close: bool,
}

fn parse() -> Result<Args, String> {
    let mut a = Args {
        elf: PathBuf::new(),
        table: None,
        bank2: None,
        ms: 300,
        socket: None,
        press: Vec::new(),
        break_gauge_at: None,
        log: None,
        end_on_close: false,
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let mut v = || it.next().ok_or(format!("{k}: needs a value"));
        let ms = |s: String| {
            s.parse::<f64>()
                .map(|x| (x * MS as f64) as u64)
                .map_err(|e| format!("{s}: {e}"))
        };
        match k.as_str() {
            "--elf" => a.elf = v()?.into(),
            "--table" => a.table = Some(v()?.into()),
            "--bank2" => a.bank2 = Some(v()?.into()),
            "--ms" => a.ms = v()?.parse().map_err(|e| format!("--ms: {e}"))?,
            "--socket" => a.socket = Some(v()?.into()),
            "--press" => {
                let s = v()?;
                let (f, t) = s.split_once("..").ok_or("--press FROM..TO (ms)")?;
                a.press.push((ms(f.into())?, ms(t.into())?));
            }
            "--break-gauge-at" => a.break_gauge_at = Some(ms(v()?)?),
            "--log" => a.log = Some(v()?.into()),
            "--end-on-close" => a.end_on_close = true,
            _ => return Err(format!("unknown argument {k}")),
        }
    }
    if a.elf.as_os_str().is_empty() {
        return Err("--elf PATH is required".into());
    }
    Ok(a)
}

fn main() -> ExitCode {
    match run() {
        Ok(ok) => {
            if ok {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(1)
            }
        }
        Err(e) => {
            eprintln!("nucleo-emu: {e}");
            ExitCode::from(2)
        }
    }
}

fn run() -> Result<bool, String> {
    let args = parse()?;
    let bytes = std::fs::read(&args.elf).map_err(|e| format!("{}: {e}", args.elf.display()))?;
    let image = elf::load(&bytes)?;
    let mut segments = image.segments.clone();
    if let Some(t) = &args.table {
        let table = std::fs::read(t).map_err(|e| format!("{}: {e}", t.display()))?;
        if table.len() > ZSCT_SIZE {
            return Err(format!("{}: larger than the table region", t.display()));
        }
        segments.push((ZSCT, table));
    }
    let bank2 = match &args.bank2 {
        Some(p) if p.exists() => {
            let b = std::fs::read(p).map_err(|e| format!("{}: {e}", p.display()))?;
            if b.len() != flash::BANK2_SIZE {
                return Err(format!("{}: not a 1 MiB bank-2 image", p.display()));
            }
            b
        }
        _ => vec![0xFF; flash::BANK2_SIZE],
    };
    // Erased flash (bank 1) around the image.
    let mut bank1 = vec![0xFFu8; cpu::BANK1.1];
    let mut rest = Vec::new();
    for (a, d) in segments {
        if (cpu::BANK1.0..cpu::BANK1.0 + cpu::BANK1.1 as u32).contains(&a) {
            let o = (a - cpu::BANK1.0) as usize;
            bank1[o..o + d.len()].copy_from_slice(&d);
        } else {
            rest.push((a, d));
        }
    }
    rest.insert(0, (cpu::BANK1.0, bank1));
    let vtor = cpu::BANK1.0;
    let mut b = board::Board::new(bank2, vtor);
    b.world.button = args.press.clone();
    b.gauge_break_at = args.break_gauge_at;
    let mut cpu = cpu::Cpu::new(b, &rest, vtor)?;

    let listener = match &args.socket {
        Some(p) => {
            let _ = std::fs::remove_file(p);
            let l = std::os::unix::net::UnixListener::bind(p)
                .map_err(|e| format!("{}: {e}", p.display()))?;
            l.set_nonblocking(true).map_err(|e| e.to_string())?;
            Some(l)
        }
        None => None,
    };
    let session = listener.is_some() && args.end_on_close;
    // Commands on standard input (a test's hand on the machine):
    // `break-gauge` sticks the gauge ADC's SDO high from now on;
    // `press MS` holds the arm button for MS ms from now.
    let (tx, commands) = std::sync::mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in std::io::stdin().lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut rtt = image.rtt.map(|cb| {
        let mut r = link::Rtt::new(cb, listener);
        r.end_on_close = args.end_on_close;
        r
    });
    let mut pending = Vec::new();
    let mut last_poll = 0u64;
    let end = args.ms * MS;
    let wall = std::time::Instant::now();
    let mut bad_command = None;
    let stop = cpu.run(end, |cpu| {
        let t = cpu.board().t;
        while let Ok(c) = commands.try_recv() {
            let mut w = c.split_whitespace();
            match (w.next(), w.next().map(str::parse::<f64>)) {
                (Some("break-gauge"), None) => cpu.board().gauge_break_at = Some(t),
                (Some("press"), Some(Ok(ms))) => cpu
                    .board()
                    .world
                    .button
                    .push((t, t + (ms * MS as f64) as u64)),
                _ => bad_command = Some(c),
            }
        }
        if t >= last_poll + 20_000_000 {
            last_poll = t;
            if let Some(r) = &mut rtt {
                r.poll(&mut cpu.uc, &mut pending);
                if session && r.client_gone {
                    cpu.board().until = 0;
                    cpu.board()
                        .violation
                        .get_or_insert_with(|| String::from("client closed"));
                }
            }
        }
    });
    if let Some(c) = bad_command {
        return Err(format!(
            "unknown command on stdin: {c:?} (break-gauge, press MS)"
        ));
    }
    let (stop, client_closed) = match stop {
        Some(s) if s == "client closed" => (None, true),
        s => (s, false),
    };
    if let Some(r) = &mut rtt {
        r.poll(&mut cpu.uc, &mut pending);
    }
    if std::env::var_os("NUCLEO_EMU_DEBUG").is_some() {
        use unicorn_engine::RegisterARM as R;
        let pc = cpu.uc.reg_read(R::PC).unwrap_or(0);
        let sp = cpu.uc.reg_read(R::SP).unwrap_or(0);
        let lr = cpu.uc.reg_read(R::LR).unwrap_or(0);
        eprintln!(
            "pc {pc:#x} sp {sp:#x} lr {lr:#x} active {:?}",
            cpu.board().active
        );
    }
    let b = cpu.board();
    if let Some(p) = &args.bank2 {
        if let Some(d) = p.parent() {
            let _ = std::fs::create_dir_all(d);
        }
        std::fs::write(p, &b.flash.bank2).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    if let (Some(p), Some(r)) = (&args.log, &rtt) {
        std::fs::write(p, &r.log).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    let unmodelled = stop.as_deref().is_some_and(|s| s.starts_with("unmodelled"));
    let touched: Vec<String> = {
        let mut names: Vec<String> = b.touched.values().map(|(n, _)| n.clone()).collect();
        names.sort();
        names.dedup();
        names
    };
    let report = serde_json::json!({
        "machine_ms": b.t as f64 / MS as f64,
        "wall_s": wall.elapsed().as_secs_f64(),
        "instructions": b.instructions,
        "stop": stop,
        "client_closed": client_closed,
        "unmodelled_accesses": u32::from(unmodelled),
        "loop_ticks": b.stats.loop_ticks,
        "cpu_slices": b.stats.slices,
        "max_tick_latency_ns": b.stats.max_tick_latency_ps / 1000,
        "index_pulses": b.stats.index_pulses,
        "x_events": b.world.x_events,
        "dac_writes": b.dac.writes,
        "dac_volts_max": b.stats.dac_volts_max,
        "gauge_conversions": b.adc.conversions,
        "gauge_reads": b.adc.reads,
        "quad_frames": b.quad.frames,
        "amplifier_enabled": b.amp_enabled(),
        "position_in": b.world.position_in(),
        "watchdog_feeds": b.iwdg.feeds,
        "flash_erases": b.flash.erases,
        "flash_programs": b.flash.programs,
        "registers_touched": touched,
        "rtt_link_bytes": rtt.as_ref().map(|r| [r.link_bytes.0, r.link_bytes.1]),
        "defmt_bytes": rtt.as_ref().map(|r| r.log.len()),
    });
    println!("{report}");
    Ok(stop.is_none())
}
