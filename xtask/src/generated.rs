//! The docs' generated reference sections, rewritten by `cargo xtask
//! figures` and checked by `--check` (and so by `cargo xtask test`).
//!
//! A section is the text between two HTML comments, which a rendered page
//! does not show:
//!
//! ```text
//! <!-- generated params -->
//! ...
//! <!-- /generated -->
//! ```
//!
//! * `params`: the servo parameters (`zslide::servo_parameters!`: id,
//!   name, unit, default, limits, meaning).
//! * `faults`: every fault (`zslide::safety::Fault::EACH`): what detects
//!   it, its reaction, its reason in words and when it may be cleared.
//! * `options PROGRAM SUB...`: a command's options from its clap
//!   definition (`PROGRAM`: `host-sim`, `zslide` or `xtask`).
//! * `commands PROGRAM [SUB...]`: a program's (sub)commands, each with
//!   its usage and what it does.
//!
//! Each is built from the code at the time it runs, so a parameter, fault
//! or option added to the code appears at the next `cargo xtask figures`,
//! and `--check` fails until it is run.

use std::fs;

use crate::doccmds::Program;
use crate::Result;

const OPEN: &str = "<!-- generated ";
const CLOSE: &str = "<!-- /generated -->";

/// The section a marker's words ask for.
pub fn render(spec: &str) -> std::result::Result<String, String> {
    let words: Vec<&str> = spec.split_whitespace().collect();
    match words.as_slice() {
        ["params"] => Ok(params()),
        ["faults"] => Ok(faults()),
        ["options", program, path @ ..] => options(program_of(program)?, path),
        ["commands", program, path @ ..] => commands(program_of(program)?, path),
        _ => Err(format!("unknown generated section {spec:?}")),
    }
}

fn program_of(name: &str) -> std::result::Result<Program, String> {
    match name {
        "host-sim" => Ok(Program::HostSim),
        "zslide" => Ok(Program::Zslide),
        "xtask" => Ok(Program::Xtask),
        _ => Err(format!("no program {name:?} (host-sim, zslide, xtask)")),
    }
}

/// A table cell: one line, `|` escaped.
fn cell(s: &str) -> String {
    s.split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .replace('|', "\\|")
}

/// A number as the parameter table writes it (no trailing zeros).
fn num(x: f64) -> String {
    let s = format!("{x}");
    if s.len() > 10 {
        format!("{x:.6}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        s
    }
}

struct Row {
    id: u16,
    name: &'static str,
    unit: &'static str,
    default: f64,
    min: f64,
    max: f64,
    doc: &'static str,
}

macro_rules! param_rows {
    (
        design { $(($id:literal, $name:ident, $ty:ident, $unit:literal, $default:expr,
            $min:expr, $max:expr, $doc:literal)),+ $(,)? }
        slide { $(($sid:literal, $sname:ident, $sfield:ident, $sty:ident, $sunit:literal,
            $sdefault:expr, $smin:expr, $smax:expr, $sdoc:literal)),+ $(,)? }
    ) => {
        vec![
            $(Row { id: $id, name: stringify!($name), unit: $unit, default: $default as f64,
                min: $min, max: $max, doc: $doc },)+
            $(Row { id: $sid, name: stringify!($sname), unit: $sunit, default: $sdefault as f64,
                min: $smin, max: $smax, doc: $sdoc },)+
        ]
    };
}

fn params() -> String {
    let rows: Vec<Row> = zslide::servo_parameters!(param_rows);
    let mut s = String::from(
        "| id | name | unit | default | min | max | meaning |\n|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s.push_str(&format!(
            "| {} | `{}` | {} | {} | {} | {} | {} |\n",
            r.id,
            r.name,
            cell(r.unit),
            num(r.default),
            num(r.min),
            num(r.max),
            cell(r.doc)
        ));
    }
    s
}

fn faults() -> String {
    use zslide::safety::{Clearing, Fault};
    let mut s = String::from(
        "| fault | detection | reaction | reason (as logged) | cleared |\n|---|---|---|---|---|\n",
    );
    let mut seen = Vec::new();
    for f in Fault::EACH {
        // One row a kind: the refused block twice in `EACH` has one row.
        let name = match f {
            Fault::Table(zslide::table::TableError::Missing) => "Table(Missing)".to_string(),
            Fault::Table(_) => "Table(e)".to_string(),
            Fault::Parameters(_) => "Parameters(e)".to_string(),
            other => format!("{other:?}"),
        };
        if seen.contains(&name) {
            continue;
        }
        seen.push(name.clone());
        let clear = match f.clearing() {
            Clearing::Disarmed => "when disarmed",
            Clearing::GaugeGood => "when disarmed and the gauge reads good",
            Clearing::AmplifierLineLow => "when disarmed and the amplifier's fault line is low",
            Clearing::NextBoot => "never (a good one at the next boot)",
        };
        s.push_str(&format!(
            "| `{name}` | {} | {:?} | {} | {clear} |\n",
            cell(f.detection()),
            f.reaction(),
            cell(f.reason())
        ));
    }
    s
}

/// The subcommand at `path` of `cmd`.
fn find<'a>(
    cmd: &'a clap::Command,
    path: &[&str],
) -> std::result::Result<&'a clap::Command, String> {
    let mut c = cmd;
    for p in path {
        c = c
            .find_subcommand(p)
            .ok_or_else(|| format!("{} has no command {p:?}", c.get_name()))?;
    }
    Ok(c)
}

fn about(c: &clap::Command) -> String {
    c.get_long_about()
        .or_else(|| c.get_about())
        .map(|a| cell(&a.to_string()))
        .unwrap_or_default()
}

/// A command's own arguments as the tables show them: (argument, its
/// value names, whether it takes a value); help, hidden and the program's
/// global options (`--connect`) left out.
fn own_args(c: &clap::Command) -> Vec<(&clap::Arg, Vec<String>, bool)> {
    c.get_arguments()
        .filter(|a| {
            let id = a.get_id().as_str();
            id != "help" && id != "version" && !a.is_hide_set() && !a.is_global_set()
        })
        .map(|a| {
            let names = a
                .get_value_names()
                .map(|v| v.iter().map(|v| v.to_string()).collect())
                .unwrap_or_else(|| vec![a.get_id().as_str().to_uppercase()]);
            let takes = a.get_num_args().is_some_and(|n| n.takes_values());
            (a, names, takes)
        })
        .collect()
}

fn options(program: Program, path: &[&str]) -> std::result::Result<String, String> {
    let mut cmd = program.command();
    cmd.build();
    let c = find(&cmd, path)?;
    let mut s = String::from("| option | default | what it does |\n|---|---|---|\n");
    for (a, names, takes) in own_args(c) {
        let mut flag = match (a.get_long(), a.get_short()) {
            (Some(l), _) => format!("--{l}"),
            (None, Some(c)) => format!("-{c}"),
            (None, None) => names.join(" "),
        };
        let values: Vec<String> = a
            .get_possible_values()
            .iter()
            .filter(|v| !v.is_hide_set())
            .map(|v| v.get_name().to_string())
            .collect();
        if a.get_long().is_some() || a.get_short().is_some() {
            if !values.is_empty() && takes {
                flag.push(' ');
                flag.push_str(&values.join("|"));
            } else if takes {
                flag.push(' ');
                flag.push_str(&names.join(" "));
            }
        }
        let default: Vec<String> = a
            .get_default_values()
            .iter()
            .map(|v| v.to_string_lossy().into_owned())
            .collect();
        let help = a
            .get_long_help()
            .or_else(|| a.get_help())
            .map(|h| h.to_string())
            .unwrap_or_default();
        s.push_str(&format!(
            "| `{}` | {} | {} |\n",
            cell(&flag),
            cell(&default.join(", ")),
            cell(&help)
        ));
    }
    Ok(s)
}

/// A command's synopsis from its arguments: `--flag VALUE`, `[...]` when
/// optional, positionals by their value names.
fn synopsis(c: &clap::Command) -> String {
    let mut words = Vec::new();
    for (a, names, takes) in own_args(c) {
        let w = match (a.get_long(), a.get_short()) {
            (Some(l), _) if takes => format!("--{l} {}", names.join(" ")),
            (Some(l), _) => format!("--{l}"),
            (None, Some(s)) if takes => format!("-{s} {}", names.join(" ")),
            (None, Some(s)) => format!("-{s}"),
            (None, None) => names.join(" "),
        };
        words.push(if a.is_required_set() {
            w
        } else {
            format!("[{w}]")
        });
    }
    words.join(" ")
}

/// The subcommands under `c`, depth first: (path, command).
fn leaves<'a>(
    c: &'a clap::Command,
    path: &mut Vec<String>,
    out: &mut Vec<(String, &'a clap::Command)>,
) {
    for sub in c.get_subcommands() {
        if sub.is_hide_set() || sub.get_name() == "help" {
            continue;
        }
        path.push(sub.get_name().to_string());
        if sub.has_subcommands() {
            leaves(sub, path, out);
        } else {
            out.push((path.join(" "), sub));
        }
        path.pop();
    }
}

fn commands(program: Program, path: &[&str]) -> std::result::Result<String, String> {
    let mut cmd = program.command();
    cmd.build();
    let c = find(&cmd, path)?;
    let prefix = std::iter::once(program.name())
        .chain(path.iter().copied())
        .collect::<Vec<_>>()
        .join(" ");
    let mut all = Vec::new();
    leaves(c, &mut Vec::new(), &mut all);
    let mut s = String::from("| command | what it does |\n|---|---|\n");
    for (name, sub) in all {
        let usage = format!("{prefix} {name} {}", synopsis(sub));
        s.push_str(&format!(
            "| `{}` | {} |\n",
            cell(usage.trim_end()),
            about(sub)
        ));
    }
    Ok(s)
}

/// Rewrites (or, with `check`, compares) every generated section of every
/// doc; returns (sections, `doc:line: ...` of each out of date).
pub fn run(check: bool) -> Result<(usize, Vec<String>)> {
    let mut count = 0;
    let mut stale = Vec::new();
    for (doc, rel, text) in crate::docnames::read_docs()? {
        let mut out = String::with_capacity(text.len());
        let mut at = 0;
        // A marker starts a line (one quoted in prose or code is not one).
        while let Some(k) = text[at..]
            .match_indices(OPEN)
            .map(|(k, _)| k)
            .find(|&k| at + k == 0 || text.as_bytes()[at + k - 1] == b'\n')
        {
            let start = at + k;
            let line = text[..start].matches('\n').count() + 1;
            let head_end = text[start..]
                .find("-->")
                .map(|e| start + e + 3)
                .ok_or_else(|| format!("{rel}:{line}: generated marker not closed"))?;
            let spec = &text[start + OPEN.len()..head_end - 3];
            let body_end = text[head_end..]
                .find(CLOSE)
                .map(|e| head_end + e)
                .ok_or_else(|| format!("{rel}:{line}: generated section without {CLOSE}"))?;
            let new = format!(
                "\n{}",
                render(spec).map_err(|e| format!("{rel}:{line}: {e}"))?
            );
            count += 1;
            if text[head_end..body_end] != new {
                stale.push(format!(
                    "{rel}:{line}: generated section `{}` is out of date (cargo xtask figures)",
                    spec.trim()
                ));
            }
            out.push_str(&text[at..head_end]);
            out.push_str(&new);
            at = body_end;
        }
        out.push_str(&text[at..]);
        if !check && out != text {
            fs::write(&doc, out).map_err(|e| format!("{}: {e}", doc.display()))?;
        }
    }
    Ok((count, stale))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_parameter_has_a_row_with_its_limits() {
        let t = params();
        assert_eq!(t.lines().count(), 2 + zslide::params::PARAMS.len());
        for p in &zslide::params::PARAMS {
            let row = t
                .lines()
                .find(|l| l.contains(&format!("| `{}` |", p.name)))
                .unwrap_or_else(|| panic!("{} has no row", p.name));
            assert!(row.starts_with(&format!("| {} |", p.id)), "{row}");
            assert!(
                row.contains(&format!("| {} | {} |", num(p.min), num(p.max))),
                "{row}"
            );
        }
    }

    #[test]
    fn the_fault_table_gives_each_kind_its_reaction_and_clear_rule() {
        let t = faults();
        let row = |k: &str| {
            t.lines()
                .find(|l| l.starts_with(&format!("| `{k}` |")))
                .unwrap_or_else(|| panic!("no row {k}"))
                .to_string()
        };
        assert!(row("FollowingError").contains("| RampToNull |"));
        assert!(row("Bus(GaugeAdc)").contains("the gauge reads good"));
        assert!(row("Parameters(e)").contains("| DisableAmplifier |"));
        assert!(row("Table(e)").contains("never"));
        assert_eq!(t.matches("| `Parameters(e)` |").count(), 1);
    }

    #[test]
    fn option_tables_come_from_clap_and_unknown_commands_are_refused() {
        let t = options(Program::HostSim, &["cut"]).unwrap();
        assert!(t.contains("`--controller "), "{t}");
        assert!(t.contains("`--holes "), "{t}");
        assert!(options(Program::HostSim, &["cutt"]).is_err());
        let c = commands(Program::Xtask, &[]).unwrap();
        assert!(
            c.contains("| `cargo xtask figures [--check] [--quick]` |"),
            "{c}"
        );
        assert!(render("nonsense").is_err());
    }
}
