//! `zslide`'s command line and what each command does. The commands that
//! talk to a machine open the link only when they run, so `table` and
//! offline `params` commands need no machine.

use std::io::Write;
use std::path::PathBuf;

use zslide::link::proto::{Reply, Request};
use zslide::params;

use crate::capture::CaptureArgs;
use crate::client::{get, set, unexpected, Link, DEFAULT_ADDR};
use crate::regions::{self, NUCLEO, QEMU};
use crate::report::say_to;
use crate::{capture, flash, words, Result};

#[derive(clap::Parser, Debug)]
#[command(
    name = "zslide",
    version,
    about = "Commission and run a Z-slide machine: coefficient tables, servo parameters, the \
             firmware's link (status, faults, arm, disarm, clear), captures and traces",
    after_help = "The link is reached with --connect (or ZSLIDE_CONNECT): tcp:HOST:PORT (an RTT \
                  bridge to a NUCLEO, or `host-sim serve`), unix:PATH (`cargo xtask qemu-link`, \
                  `host-sim serve --listen unix:PATH`), or probe:[SELECTOR] when built with \
                  `--features probe`."
)]
pub struct Cli {
    /// Where the firmware's link is: tcp:HOST:PORT, unix:PATH or
    /// probe:[SELECTOR].
    #[arg(long, global = true, value_name = "ADDR", env = "ZSLIDE_CONNECT", default_value = DEFAULT_ADDR)]
    pub connect: String,
    /// How long to wait for each reply, ms.
    #[arg(long, global = true, value_name = "MS", default_value_t = 3000)]
    pub timeout_ms: u64,
    #[command(subcommand)]
    pub cmd: Cmd,
}

#[derive(clap::Subcommand, Debug)]
pub enum Cmd {
    /// Coefficient tables: build one from a part's configuration, check a
    /// file as the firmware will, write it to the board's table region.
    Table {
        #[command(subcommand)]
        cmd: TableCmd,
    },
    /// Servo parameters: read and set them on the machine, load a block
    /// file into it, write block files, write a block to the board's
    /// parameter region.
    Params {
        #[command(subcommand)]
        cmd: ParamsCmd,
    },
    /// The loop's state, fault log, arming and clearing.
    Link {
        #[command(subcommand)]
        cmd: LinkCmd,
    },
    /// Capture consecutive loop ticks (command, position, error, output,
    /// φ, X) around a trigger, as CSV (and a plot).
    Capture(CaptureArgs),
    /// A live scope in the terminal: chosen loop signals, trigger, time
    /// base; `s` writes the frame as CSV and PNG.
    Scope(crate::scope::ScopeArgs),
    /// Measure the slide's frequency response (a stepped sine added to
    /// the DAC by the firmware, engaged at null), fit the plant model
    /// (gain, mass, mode) and write the Bode CSV, plots and the fit.
    Identify(crate::identify::IdentifyArgs),
    /// Set the loop's slide model and mode notch from `identify`'s fit
    /// (checked by the firmware's design code; disarmed only).
    Tune(crate::identify::TuneArgs),
    /// A board's decoded defmt log with trace events (`--features trace`)
    /// as a VCD with the simulator's signal names.
    Trace2vcd(host_sim::cmd::trace2vcd::Args),
    /// Decode a raw defmt log (a file, or stdin) with the firmware's ELF,
    /// as `defmt-print -e ELF` does.
    #[cfg(feature = "defmt-log")]
    Log {
        /// The firmware image the log came from.
        #[arg(long, value_name = "ELF")]
        elf: PathBuf,
        /// The raw log (default: stdin).
        file: Option<PathBuf>,
    },
}

#[derive(clap::Subcommand, Debug)]
pub enum TableCmd {
    /// Make the table of a part file (docs/PARTS.md, every surface kind;
    /// the smallest table that meets its bound, as host-sim's part-table),
    /// or of a table configuration of host-sim's coeffs (tables/default.toml):
    /// `--config PART.toml --out PART.zsct`.
    Build(BuildArgs),
    /// A table compensating a measured part's error (host-sim's compensate,
    /// the same code): `MEASURED --out F.zsct [--from T.zsct] [--gain G]`.
    Compensate(host_sim::cmd::compensate::Args),
    /// Check a table file as the firmware checks it (parser, CRC, sign
    /// check, region size) and print its identity; an interruption block
    /// (`table holes`) likewise, with its holes.
    Check { file: PathBuf },
    /// Check a table file, then write it to the NUCLEO's table region; an
    /// interruption block to the NUCLEO's interruption region.
    Flash(FlashArgs),
    /// The part's interruption block (its bolt holes, for the hole edges'
    /// anticipation) from a scenario's `[cutting.bolt_holes]`, checked as
    /// the firmware checks it: `--config SCENARIO.toml --out PART.zsib`.
    Holes(HolesArgs),
}

#[derive(clap::Args, Debug, Clone)]
pub struct HolesArgs {
    /// The scenario file (or `legacy-hw` / `modern-hw`) whose
    /// `[cutting.bolt_holes]` the part has.
    #[arg(long, value_name = "FILE")]
    pub config: String,
    /// The interruption block to write.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

/// `table holes`: the block of the scenario's bolt holes (filled holes: an
/// empty block, a whole face), written whole.
fn table_holes(a: &HolesArgs, out: &mut dyn Write) -> Result<()> {
    host_sim::outpath::check_file("--out", &a.out).map_err(|e| format!("{e:#}"))?;
    let sc = host_sim::scenario::load(&a.config).map_err(|e| format!("{e:#}"))?;
    let block = host_sim::cut::interruptions::block_of(&sc.cutting.bolt_holes)
        .map_err(|e| format!("{}: {e:#}", a.config))?;
    let holes = zslide::table::interrupt::Interruptions::parse(&block)
        .map_err(|e| format!("{}: interruption block refused: {e}", a.config))?;
    crate::write_file(&a.out, &block)?;
    for line in regions::hole_lines(&holes) {
        say_to(out, &line)?;
    }
    say_to(
        out,
        &format!(
            "wrote {} ({} bytes, {} holes)",
            a.out.display(),
            block.len(),
            holes.holes().len()
        ),
    )
}

#[derive(clap::Args, Debug, Clone)]
pub struct BuildArgs {
    /// The part file, or a `host-sim coeffs` table configuration.
    #[arg(long, value_name = "FILE")]
    pub config: PathBuf,
    /// The table image to write.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

/// `table build`: the table image written whole, its report on `out`.
fn table_build(a: &BuildArgs, out: &mut dyn Write) -> Result<()> {
    let shown = a.config.display();
    let text =
        std::fs::read_to_string(&a.config).map_err(|e| format!("{shown}: cannot read: {e}"))?;
    host_sim::outpath::check_file("--out", &a.out).map_err(|e| format!("{e:#}"))?;
    // A table configuration has a [grid]; a part file has none.
    let is_config = text
        .parse::<toml::Table>()
        .is_ok_and(|t| t.contains_key("grid"));
    if is_config {
        // `host-sim coeffs --config FILE --out FILE --report`, its own
        // defaults for the rest.
        #[derive(clap::Parser)]
        struct Coeffs {
            #[command(flatten)]
            a: host_sim::cmd::coeffs::Args,
        }
        let c = <Coeffs as clap::Parser>::try_parse_from([
            "coeffs".as_ref(),
            "--config".as_ref(),
            a.config.as_os_str(),
            "--out".as_ref(),
            a.out.as_os_str(),
            "--report".as_ref(),
        ] as [&std::ffi::OsStr; 6])
        .map_err(|e| e.to_string())?;
        return host_sim::cmd::coeffs::run(c.a).map_err(|e| format!("{e:#}"));
    }
    let lp = host_sim::part::config::load_part(&a.config).map_err(|e| format!("{e:#}"))?;
    let (_, image, r) = host_sim::cmd::parttable::make(&lp).map_err(|e| format!("{e:#}"))?;
    crate::write_file(&a.out, &image)?;
    for line in host_sim::cmd::parttable::report_text(&r).lines() {
        say_to(out, line)?;
    }
    say_to(
        out,
        &format!("wrote {} ({} bytes)", a.out.display(), image.len()),
    )
}

#[derive(clap::Subcommand, Debug)]
pub enum ParamsCmd {
    /// Every servo parameter on the machine with its value, unit and limits.
    Show,
    /// One servo parameter's value on the machine.
    Get { name: String },
    /// Set a servo parameter on the machine (only while disarmed; in force
    /// at once, lost at power-off unless saved).
    Set {
        name: String,
        #[arg(allow_hyphen_values = true)]
        value: f64,
    },
    /// Set every parameter of a block file on the machine (only while
    /// disarmed).
    Load { file: PathBuf },
    /// Save every parameter in force to the machine's parameter store
    /// (only while disarmed); the machine boots with them.
    Save,
    /// Check a block file as the firmware checks it and list its entries.
    Check { file: PathBuf },
    /// Write a parameter block file.
    Block {
        /// A parameter and its value (`zslide params show` lists them);
        /// repeat for several.
        #[arg(
            long = "set",
            value_name = "NAME=VALUE",
            required = true,
            allow_hyphen_values = true
        )]
        set: Vec<String>,
        /// The block file to write.
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
    },
    /// Check a block file, then write it to the NUCLEO's parameter region.
    Flash(FlashArgs),
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
}

#[derive(clap::Args, Debug, Clone)]
pub struct FlashArgs {
    /// The file to write.
    pub file: PathBuf,
    /// Print what would be written, and how, instead of writing.
    #[arg(long)]
    pub dry_run: bool,
    /// The probe (`VID:PID[:SERIAL]`) when several are connected.
    #[arg(long, value_name = "SEL")]
    pub probe: Option<String>,
}

fn param(name: &str) -> Result<&'static params::Param> {
    params::by_name(name).ok_or_else(|| {
        let names: Vec<&str> = params::PARAMS.iter().map(|p| p.name).collect();
        format!(
            "no servo parameter {name:?}; the parameters are: {}",
            names.join(", ")
        )
    })
}

/// Runs one command; its report goes to `out`.
pub fn execute(cmd: &Cmd, link: &mut Link, out: &mut dyn Write) -> Result<()> {
    let mut say = |s: String| say_to(out, &s);
    match cmd {
        Cmd::Table { cmd } => match cmd {
            TableCmd::Build(a) => table_build(a, out),
            TableCmd::Compensate(a) => {
                host_sim::cmd::compensate::run(a.clone()).map_err(|e| format!("{e:#}"))
            }
            TableCmd::Holes(a) => table_holes(a, out),
            TableCmd::Check { file } if regions::is_interruption_file(file)? => {
                let holes = regions::check_interruptions_file(file, &NUCLEO)?;
                say(format!(
                    "{}: interruption block, {} holes",
                    file.display(),
                    holes.holes().len()
                ))?;
                for line in regions::hole_lines(&holes) {
                    say(line)?;
                }
                say(format!(
                    "fits the NUCLEO's interruption region ({} KiB){}",
                    NUCLEO.interruptions_len / 1024,
                    if regions::check_interruptions_file(file, &QEMU).is_ok() {
                        " and the QEMU image's"
                    } else {
                        ""
                    }
                ))
            }
            TableCmd::Flash(a) if regions::is_interruption_file(&a.file)? => {
                let holes = regions::check_interruptions_file(&a.file, &NUCLEO)?;
                say(format!(
                    "{}: interruption block, {} holes",
                    a.file.display(),
                    holes.holes().len()
                ))?;
                say(format!(
                    "interruption region of the NUCLEO-H743ZI2: {:#010x} ({} KiB)",
                    NUCLEO.interruptions_addr,
                    NUCLEO.interruptions_len / 1024
                ))?;
                flash::download(
                    &a.file,
                    NUCLEO.interruptions_addr,
                    a.probe.as_deref(),
                    a.dry_run,
                )
            }
            TableCmd::Check { file } => {
                let id = regions::check_table_file(file, &NUCLEO)?;
                say(format!("{}: {id}", file.display()))?;
                say(format!(
                    "fits the NUCLEO's table region ({} KiB){}",
                    NUCLEO.table_len / 1024,
                    if regions::check_table_file(file, &QEMU).is_ok() {
                        " and the QEMU image's"
                    } else {
                        ""
                    }
                ))
            }
            TableCmd::Flash(a) => {
                let id = regions::check_table_file(&a.file, &NUCLEO)?;
                say(format!("{}: {id}", a.file.display()))?;
                say(format!(
                    "table region of the NUCLEO-H743ZI2: {:#010x} ({} KiB)",
                    NUCLEO.table_addr,
                    NUCLEO.table_len / 1024
                ))?;
                flash::download(&a.file, NUCLEO.table_addr, a.probe.as_deref(), a.dry_run)
            }
        },
        Cmd::Params { cmd } => match cmd {
            ParamsCmd::Show => {
                let c = link.client()?;
                for p in params::PARAMS.iter() {
                    let v = get(c, p.id)?;
                    say(format!(
                        "{:<26} = {:>12} {:<18} limits {} .. {}",
                        p.name,
                        words::value(v),
                        p.unit,
                        words::value(p.min),
                        words::value(p.max)
                    ))?;
                }
                Ok(())
            }
            ParamsCmd::Get { name } => {
                let p = param(name)?;
                let v = get(link.client()?, p.id)?;
                say(format!("{} = {} {}", p.name, words::value(v), p.unit))
            }
            ParamsCmd::Set { name, value } => {
                let p = param(name)?;
                let v = set(link.client()?, p.id, *value)?;
                say(format!(
                    "{} = {} {} (in force)",
                    p.name,
                    words::value(v),
                    p.unit
                ))
            }
            ParamsCmd::Save => match link.client()?.call(&Request::SaveParams)? {
                Reply::Saved { entries, crc } => say(format!(
                    "saved {entries} parameters to the machine's parameter store (block CRC {crc:#010x}); the machine boots with them"
                )),
                r => Err(unexpected(&r)),
            },
            ParamsCmd::Load { file } => {
                let (src, entries) = regions::check_params_file(file, &NUCLEO)?;
                say(format!("{}: {src}", file.display()))?;
                let c = link.client()?;
                for (k, &(id, value)) in entries.iter().enumerate() {
                    let p = params::by_id(id).ok_or("checked block with an unknown id")?;
                    match set(c, id, value) {
                        Ok(v) => say(format!(
                            "{} = {} {} (in force)",
                            p.name,
                            words::value(v),
                            p.unit
                        ))?,
                        Err(e) => {
                            let rest: Vec<&str> = entries[k..]
                                .iter()
                                .filter_map(|&(id, _)| params::by_id(id).map(|p| p.name))
                                .collect();
                            return Err(format!(
                                "{}: {} refused: {e}; not set: {} ({k} of {} set before it)",
                                file.display(),
                                p.name,
                                rest.join(", "),
                                entries.len()
                            ));
                        }
                    }
                }
                Ok(())
            }
            ParamsCmd::Check { file } => {
                let (src, entries) = regions::check_params_file(file, &NUCLEO)?;
                say(format!("{}: {src}", file.display()))?;
                for (id, v) in entries {
                    if let Some(p) = params::by_id(id) {
                        say(format!("  {} = {} {}", p.name, words::value(v), p.unit))?;
                    }
                }
                Ok(())
            }
            ParamsCmd::Block { set, out: file } => {
                let entries = set
                    .iter()
                    .map(|s| regions::parse_setting(s))
                    .collect::<Result<Vec<_>>>()?;
                let bytes = regions::param_block(&entries)?;
                crate::write_file(file, &bytes)?;
                say(format!(
                    "{}: {} bytes, {} parameters",
                    file.display(),
                    bytes.len(),
                    entries.len()
                ))
            }
            ParamsCmd::Flash(a) => {
                let (src, _) = regions::check_params_file(&a.file, &NUCLEO)?;
                say(format!("{}: {src}", a.file.display()))?;
                // The firmware's store owns the region: the block goes in
                // as the store's one item (both sectors written).
                let block = std::fs::read(&a.file)
                    .map_err(|e| format!("{}: cannot read: {e}", a.file.display()))?;
                let image = regions::params_store_image(&block)
                    .map_err(|e| format!("{}: {e}", a.file.display()))?;
                let store = std::env::temp_dir()
                    .join(format!("zslide-params-store-{}.bin", std::process::id()));
                std::fs::write(&store, &image)
                    .map_err(|e| format!("{}: cannot write: {e}", store.display()))?;
                say(format!(
                    "parameter region of the NUCLEO-H743ZI2: {:#010x} ({} KiB), written as the firmware's parameter store holding this block ({})",
                    NUCLEO.params_addr,
                    NUCLEO.params_len / 1024,
                    store.display()
                ))?;
                let r = flash::download(&store, NUCLEO.params_addr, a.probe.as_deref(), a.dry_run);
                if !a.dry_run {
                    let _ = std::fs::remove_file(&store);
                }
                r
            }
        },
        Cmd::Link { cmd } => {
            let c = link.client()?;
            match cmd {
                LinkCmd::Status => say(words::status_text(&c.status()?)),
                LinkCmd::Faults => {
                    let hz = c.status()?.loop_hz;
                    let (total, log) = c.fault_log()?;
                    say(format!(
                        "fault log: {} records kept of {total} logged",
                        log.len()
                    ))?;
                    for r in &log {
                        say(words::record_text(r, hz))?;
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
                        Reply::Phase(p) => say(format!("loop {}", words::phase(p))),
                        r => Err(unexpected(&r)),
                    }
                }
                LinkCmd::Clear => match c.call(&Request::Clear)? {
                    Reply::Cleared(f) => say(format!("cleared: {f}")),
                    r => Err(unexpected(&r)),
                },
            }
        }
        Cmd::Capture(a) => capture::run(link, a, out),
        Cmd::Identify(a) => crate::identify::identify(link, a, out).map(|_| ()),
        Cmd::Tune(a) => crate::identify::tune(link, a, out).map(|_| ()),
        Cmd::Scope(a) => {
            let summary = crate::scope::run(link, a)?;
            say(format!("scope: {summary}"))
        }
        Cmd::Trace2vcd(a) => host_sim::cmd::trace2vcd::run(a.clone()).map_err(|e| format!("{e:#}")),
        #[cfg(feature = "defmt-log")]
        Cmd::Log { elf, file } => {
            let summary = crate::defmt_log::decode_file(elf, file.as_deref())?;
            eprintln!("{summary}");
            Ok(())
        }
    }
}

/// Parses `line` as the words after `zslide` and runs it on `link`: the
/// end-to-end tests drive the tool exactly as a user types it.
pub fn run_line(link: &mut Link, line: &str) -> Result<String> {
    use clap::Parser;
    let cli = Cli::try_parse_from(std::iter::once("zslide").chain(line.split_whitespace()))
        .map_err(|e| format!("`zslide {line}`: {e}"))?;
    let mut out = Vec::new();
    execute(&cli.cmd, link, &mut out).map_err(|e| format!("`zslide {line}`: {e}"))?;
    Ok(String::from_utf8_lossy(&out).into_owned())
}
