//! Every command the docs show, parsed by the argument parser of the
//! program that would receive it (part of `cargo xtask figures --check
//! --quick`, and so of `cargo xtask test`).
//!
//! What is a shown command: each line of a `sh` (or `bash`, `shell`, or
//! untagged) fenced block, and each backticked span in a table cell or in
//! prose, that runs `cargo sim`, `cargo run -p host-sim|zslide-host|xtask`,
//! `cargo xtask`, `host-sim` or `zslide` (`cargo test` too: one name
//! filter before `--`). Cargo's aliases are expanded from
//! `.cargo/config.toml` as cargo expands them, so `cargo sim -- --flag`
//! reaches host-sim as `cut -- --flag`, which host-sim refuses.
//!
//! The parsers are the programs' own clap definitions, reached through
//! their libraries (`host_sim::cli::command`, `zslide_host::cli::Cli`) and
//! this crate's `Cli`: nothing is re-described here, so a removed or
//! renamed option fails the check the day it goes.
//!
//! Usage notation is read as a reader reads it: `[...]` marks optional
//! words (they are parsed too), `a\|b` in a table cell gives one command
//! per alternative, `...` elides the rest (a missing subcommand or
//! argument is then not an error), and an upper-case word (`N`, `F.zsct`,
//! `ferr:UIN`) or a shell variable (`$s`) is a placeholder: a value the
//! parser refuses only because it is a placeholder is not an error.
//!
//! A fenced block opened with ```` ```sh quick ```` also runs, whole, as
//! a `sh -e` script in a scratch directory (`target/doc-commands/`, with
//! the repository's `tables/` and `scenarios/` linked in) with the debug
//! `host-sim` and `zslide` first on PATH: keep such blocks to commands
//! that take seconds in a debug build.

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use clap::error::{ContextKind, ContextValue, ErrorKind};
use clap::{CommandFactory, FromArgMatches, Parser};

use crate::{cargo, root, step, target_dir, Result};

/// Where a command was shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// A line of a fenced shell block.
    Block,
    /// A backticked span in a table cell: usage notation allowed.
    Cell,
    /// A backticked span in prose: usage notation allowed, and a command
    /// may be named without the arguments it needs (`zslide table flash`
    /// in a sentence), but every word it shows must parse.
    Prose,
}

/// One command as a doc shows it.
#[derive(Clone, Debug, PartialEq)]
pub struct Shown {
    pub line: usize,
    pub text: String,
    pub origin: Origin,
}

/// A fenced block marked `quick`: (first line of its body, its text).
#[derive(Clone, Debug, PartialEq)]
pub struct QuickBlock {
    pub line: usize,
    pub script: String,
}

const SHELLS: &[&str] = &["", "sh", "bash", "shell"];

/// The commands shown in `text`, and its blocks marked `quick`.
pub fn shown(text: &str) -> (Vec<Shown>, Vec<QuickBlock>) {
    let mut out = Vec::new();
    let mut quick = Vec::new();
    // Some((is a shell block, quick block index)) while inside a fence.
    let mut fence: Option<(bool, Option<usize>)> = None;
    let mut pending: Option<(usize, String)> = None;
    // A block's `NAME=value` lines, substituted for `$NAME` below them.
    let mut vars: Vec<(String, String)> = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let n = k + 1;
        let t = line.trim_start();
        if let Some(info) = t.strip_prefix("```") {
            if fence.is_some() {
                fence = None;
                pending = None;
                vars.clear();
            } else {
                let words: Vec<&str> = info.split_whitespace().collect();
                let shell = SHELLS.contains(&words.first().copied().unwrap_or(""));
                let q = (shell && words.get(1) == Some(&"quick")).then(|| {
                    quick.push(QuickBlock {
                        line: n + 1,
                        script: String::new(),
                    });
                    quick.len() - 1
                });
                fence = Some((shell, q));
            }
            continue;
        }
        match fence {
            Some((shell, q)) => {
                if let Some(i) = q {
                    quick[i].script.push_str(line);
                    quick[i].script.push('\n');
                }
                if !shell {
                    continue;
                }
                // A trailing backslash continues the command on the next line.
                let (start, mut joined) = pending.take().unwrap_or((n, String::new()));
                if let Some(head) = line.strip_suffix('\\') {
                    joined.push_str(head);
                    joined.push(' ');
                    pending = Some((start, joined));
                    continue;
                }
                joined.push_str(line);
                let mut body = joined.trim().trim_start_matches("$ ").to_string();
                if let Some((name, value)) = assignment(&body) {
                    vars.push((name, value));
                    continue;
                }
                // Longest names first, so that `$PATH` is not `$P` + `ATH`.
                vars.sort_by_key(|(n, _)| std::cmp::Reverse(n.len()));
                for (name, value) in &vars {
                    body = body
                        .replace(&format!("${{{name}}}"), value)
                        .replace(&format!("${name}"), value);
                }
                if names_a_tool(&body) {
                    out.push(Shown {
                        line: start,
                        text: body,
                        origin: Origin::Block,
                    });
                }
            }
            None => {
                let origin = if line.trim_start().starts_with('|') {
                    Origin::Cell
                } else {
                    Origin::Prose
                };
                for span in spans_of(line) {
                    if names_a_tool(&span) {
                        out.push(Shown {
                            line: n,
                            text: span,
                            origin,
                        });
                    }
                }
            }
        }
    }
    (out, quick)
}

/// `NAME=value` alone on a line (the value unquoted).
fn assignment(line: &str) -> Option<(String, String)> {
    let (name, value) = line.split_once('=')?;
    if name.is_empty()
        || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        || name.starts_with(|c: char| c.is_ascii_digit())
    {
        return None;
    }
    let words = simple_commands(value);
    (words.len() <= 1).then(|| (name.to_string(), words.concat().join(" ")))
}

/// The backticked spans of one line of prose or of a table row.
fn spans_of(line: &str) -> Vec<String> {
    let parts: Vec<&str> = line.split('`').collect();
    parts
        .iter()
        .enumerate()
        .filter(|(i, p)| i % 2 == 1 && i + 1 < parts.len() && !p.is_empty())
        .map(|(_, p)| p.to_string())
        .collect()
}

/// Whether a shell line or a span runs one of the checked programs.
fn names_a_tool(s: &str) -> bool {
    s.split([';', '|', '&', '(', '{']).any(|c| {
        matches!(
            first_words(c).as_slice(),
            ["cargo", "sim" | "xtask" | "run" | "test", ..] | ["host-sim" | "zslide", _, ..]
        )
    })
}

fn first_words(s: &str) -> Vec<&str> {
    s.split_whitespace().take(2).collect()
}

// ------------------------------------------------------------ shell words

/// The simple commands of a shell line: words split at `;`, `|`, `&`,
/// `&&`, `||` and grouping; quotes and escapes resolved; comments,
/// redirections (with their target) and leading `VAR=value` dropped.
pub fn simple_commands(line: &str) -> Vec<Vec<String>> {
    let mut cmds = Vec::new();
    let mut words: Vec<String> = Vec::new();
    let mut word = String::new();
    let mut in_word = false;
    let mut skip_next = false;
    let mut chars = line.chars().peekable();
    let end_word =
        |word: &mut String, in_word: &mut bool, words: &mut Vec<String>, skip: &mut bool| {
            if *in_word {
                if *skip {
                    *skip = false;
                } else {
                    words.push(std::mem::take(word));
                }
                word.clear();
                *in_word = false;
            }
        };
    while let Some(c) = chars.next() {
        match c {
            '\'' => {
                in_word = true;
                for d in chars.by_ref() {
                    if d == '\'' {
                        break;
                    }
                    word.push(d);
                }
            }
            '"' => {
                in_word = true;
                while let Some(d) = chars.next() {
                    match d {
                        '"' => break,
                        '\\' => {
                            if let Some(e) = chars.next() {
                                word.push(e);
                            }
                        }
                        _ => word.push(d),
                    }
                }
            }
            '\\' => {
                in_word = true;
                if let Some(e) = chars.next() {
                    word.push(e);
                }
            }
            '$' if chars.peek() == Some(&'(') => {
                // A command substitution is one word here.
                in_word = true;
                word.push('$');
                let mut depth = 0;
                for d in chars.by_ref() {
                    word.push(d);
                    match d {
                        '(' => depth += 1,
                        ')' => {
                            depth -= 1;
                            if depth == 0 {
                                break;
                            }
                        }
                        _ => {}
                    }
                }
            }
            '#' if !in_word => break,
            ' ' | '\t' => end_word(&mut word, &mut in_word, &mut words, &mut skip_next),
            ';' | '|' | '&' | '(' | ')' | '{' | '}' if !in_word || c != '{' && c != '}' => {
                end_word(&mut word, &mut in_word, &mut words, &mut skip_next);
                // `>&2` and `2>&1` are redirections, not separators.
                if c == '&' && words.last().is_some_and(|w| w.ends_with('>')) {
                    continue;
                }
                if !words.is_empty() {
                    cmds.push(std::mem::take(&mut words));
                }
            }
            '>' | '<' => {
                // `2>`, `>`, `>>`, `<`: the redirection and its target go.
                if in_word && word.chars().all(|d| d.is_ascii_digit()) {
                    word.clear();
                    in_word = false;
                } else {
                    end_word(&mut word, &mut in_word, &mut words, &mut skip_next);
                }
                while chars.peek().is_some_and(|d| *d == '>' || *d == '&') {
                    chars.next();
                }
                if chars.peek().is_some_and(|d| d.is_ascii_digit()) {
                    chars.next();
                } else {
                    skip_next = true;
                }
            }
            _ => {
                in_word = true;
                word.push(c);
            }
        }
    }
    end_word(&mut word, &mut in_word, &mut words, &mut skip_next);
    if !words.is_empty() {
        cmds.push(words);
    }
    for c in &mut cmds {
        // Shell keywords and environment assignments before the command.
        let lead = c
            .iter()
            .take_while(|w| {
                matches!(w.as_str(), "do" | "then" | "else" | "time" | "!")
                    || (w.contains('=') && !w.starts_with('-'))
            })
            .count();
        c.drain(..lead);
    }
    cmds.retain(|c| !c.is_empty());
    cmds
}

// ------------------------------------------------------------ the programs

/// A program whose parser the check reaches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Program {
    HostSim,
    Zslide,
    Xtask,
}

impl Program {
    pub fn name(self) -> &'static str {
        match self {
            Program::HostSim => "host-sim",
            Program::Zslide => "zslide",
            Program::Xtask => "cargo xtask",
        }
    }

    /// The program's own parser on `args`.
    fn parse(self, args: &[String]) -> std::result::Result<(), clap::Error> {
        let argv = std::iter::once(self.name().to_string()).chain(args.iter().cloned());
        match self {
            Program::HostSim => {
                let m = host_sim::cli::command().try_get_matches_from(argv)?;
                host_sim::cli::Cli::from_arg_matches(&m).map(|_| ())
            }
            Program::Zslide => zslide_host::cli::Cli::try_parse_from(argv).map(|_| ()),
            Program::Xtask => crate::Cli::try_parse_from(argv).map(|_| ()),
        }
    }

    /// The program's clap command (for the generated option tables).
    pub fn command(self) -> clap::Command {
        match self {
            Program::HostSim => host_sim::cli::command(),
            Program::Zslide => zslide_host::cli::Cli::command(),
            Program::Xtask => crate::Cli::command(),
        }
    }
}

/// Cargo's aliases (`.cargo/config.toml`'s `[alias]`), each as its words.
pub fn aliases(base: &Path) -> Result<HashMap<String, Vec<String>>> {
    let p = base.join(".cargo/config.toml");
    let text = fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
    let v: toml::Table = text.parse().map_err(|e| format!("{}: {e}", p.display()))?;
    let mut out = HashMap::new();
    if let Some(toml::Value::Table(a)) = v.get("alias") {
        for (k, v) in a {
            let words = match v {
                toml::Value::String(s) => s.split_whitespace().map(String::from).collect(),
                toml::Value::Array(a) => a
                    .iter()
                    .filter_map(|w| w.as_str().map(String::from))
                    .collect(),
                _ => continue,
            };
            out.insert(k.clone(), words);
        }
    }
    Ok(out)
}

/// Cargo's options (of `run` and `test`) that take a value.
const CARGO_VALUE_OPTS: &[&str] = &[
    "-p",
    "--package",
    "--bin",
    "--example",
    "--test",
    "--bench",
    "-F",
    "--features",
    "--target",
    "--profile",
    "-j",
    "--jobs",
    "--manifest-path",
    "--color",
    "--message-format",
    "--target-dir",
    "-Z",
    "--config",
    "--exclude",
];

/// Splits cargo's own words into (options with their values, positional
/// words) up to `--`.
fn cargo_words(words: &[String]) -> (Vec<(String, Option<String>)>, Vec<String>) {
    let mut opts = Vec::new();
    let mut positional = Vec::new();
    let mut i = 0;
    while i < words.len() {
        let w = &words[i];
        if w.starts_with('-') {
            if let Some((k, v)) = w.split_once('=') {
                opts.push((k.to_string(), Some(v.to_string())));
            } else if CARGO_VALUE_OPTS.contains(&w.as_str()) {
                opts.push((w.clone(), words.get(i + 1).cloned()));
                i += 1;
            } else {
                opts.push((w.clone(), None));
            }
        } else {
            positional.push(w.clone());
        }
        i += 1;
    }
    (opts, positional)
}

/// What one simple command runs: the program and its arguments, or what is
/// wrong with the cargo command around it; `None` when it is none of the
/// checked programs.
pub fn resolve(
    words: &[String],
    aliases: &HashMap<String, Vec<String>>,
) -> Option<std::result::Result<(Program, Vec<String>), String>> {
    match words.first()?.as_str() {
        "host-sim" => return Some(Ok((Program::HostSim, words[1..].to_vec()))),
        "zslide" => return Some(Ok((Program::Zslide, words[1..].to_vec()))),
        "cargo" => {}
        _ => return None,
    }
    let sub = words.get(1)?;
    if let Some(expansion) = aliases.get(sub.as_str()) {
        let mut expanded = vec!["cargo".to_string()];
        expanded.extend(expansion.iter().cloned());
        expanded.extend(words[2..].iter().cloned());
        if expansion.first() == Some(sub) {
            return None;
        }
        return resolve(&expanded, aliases);
    }
    let rest = &words[2..];
    let dashes = rest.iter().position(|w| w == "--");
    let (own, after) = match dashes {
        Some(k) => (&rest[..k], &rest[k + 1..]),
        None => (rest, &[][..]),
    };
    let (opts, positional) = cargo_words(own);
    match sub.as_str() {
        "run" => {
            let package = opts
                .iter()
                .find(|(k, _)| k == "-p" || k == "--package")
                .and_then(|(_, v)| v.clone());
            let bin = opts
                .iter()
                .find(|(k, _)| k == "--bin")
                .and_then(|(_, v)| v.clone());
            let program = match (package.as_deref(), bin.as_deref()) {
                (Some("host-sim"), _) | (None, Some("host-sim")) => Program::HostSim,
                (Some("zslide-host"), _) | (None, Some("zslide")) => Program::Zslide,
                (Some("xtask"), _) => Program::Xtask,
                _ => return None,
            };
            if !positional.is_empty() {
                return Some(Err(format!(
                    "cargo run has no argument {:?}: the program's arguments go after `--`",
                    positional[0]
                )));
            }
            Some(Ok((program, after.to_vec())))
        }
        "test" if positional.len() > 1 => Some(Err(format!(
            "cargo test takes one name filter, not {} ({}); more go after `--`",
            positional.len(),
            positional.join(", ")
        ))),
        _ => None,
    }
}

// ------------------------------------------------------------ notation

/// A placeholder: an upper-case word (`N`, `F.zsct`, `ferr:UIN`), a shell
/// variable, or `<name>`.
pub fn placeholder(v: &str) -> bool {
    v.contains('$')
        || v.contains('<')
        || v.split(|c: char| !c.is_ascii_alphanumeric() && c != '_')
            .any(|w| {
                w.starts_with(|c: char| c.is_ascii_uppercase())
                    && w.chars()
                        .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
            })
}

/// What a usage line leaves open: words elided (`...`), words optional
/// (`[...]`, each on its own, so two that exclude each other may both be
/// shown).
#[derive(Clone, Copy, Default)]
struct Notation {
    elided: bool,
    optional: bool,
    /// A command named in a sentence: what it needs may be left out.
    named: bool,
}

/// The commands a usage line stands for: `[`/`]` dropped, `...` dropped,
/// each `a|b` of a span's word expanded in turn.
fn readings(words: &[String], origin: Origin) -> (Vec<Vec<String>>, Notation) {
    let mut n = Notation {
        named: origin == Origin::Prose,
        ..Notation::default()
    };
    let mut base: Vec<String> = Vec::new();
    for w in words {
        n.optional |= w.starts_with('[') || w.ends_with(']');
        let w = w.trim_start_matches('[').trim_end_matches(']');
        if w.is_empty() {
            continue;
        }
        if w == "..." || w == "…" {
            n.elided = true;
            continue;
        }
        base.push(w.to_string());
    }
    let mut out = Vec::new();
    if origin != Origin::Block {
        let first = |w: &str| w.split('|').next().unwrap_or(w).to_string();
        let plain: Vec<String> = base.iter().map(|w| first(w)).collect();
        for (i, w) in base.iter().enumerate() {
            for alt in w.split('|').skip(1) {
                let mut v = plain.clone();
                v[i] = alt.to_string();
                out.push(v);
            }
        }
        out.insert(0, plain);
    } else {
        out.push(base);
    }
    (out, n)
}

/// Whether a parse error is only the notation's doing.
fn notation_error(e: &clap::Error, n: Notation) -> bool {
    match e.kind() {
        ErrorKind::DisplayHelp | ErrorKind::DisplayVersion => true,
        ErrorKind::InvalidValue | ErrorKind::ValueValidation => {
            match e.get(ContextKind::InvalidValue) {
                Some(ContextValue::String(v)) if v.is_empty() => n.named,
                Some(ContextValue::String(v)) => placeholder(v),
                _ => n.named,
            }
        }
        ErrorKind::MissingRequiredArgument
        | ErrorKind::MissingSubcommand
        | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => n.elided || n.named,
        ErrorKind::ArgumentConflict => n.optional,
        _ => false,
    }
}

/// The first line of a clap error (its message without the usage).
fn first_line(e: &clap::Error) -> String {
    let s = e.render().to_string();
    s.lines()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("")
        .trim_start_matches("error: ")
        .to_string()
}

/// Subcommands compiled only with a cargo feature of their program, which
/// the parser this crate links (default features) does not have:
/// (program, subcommand, feature). Their commands are not parsed.
const FEATURE_GATED: &[(Program, &str, &str)] = &[(Program::Zslide, "log", "defmt-log")];

/// What is wrong with one shown command, if anything.
pub fn check_one(shown: &Shown, aliases: &HashMap<String, Vec<String>>) -> Vec<String> {
    let text = if shown.origin != Origin::Block {
        // In a table cell `\|` is the alternation's bar.
        shown.text.replace("\\|", "\u{1}")
    } else {
        shown.text.clone()
    };
    let mut problems = Vec::new();
    for words in simple_commands(&text) {
        let words: Vec<String> = words.iter().map(|w| w.replace('\u{1}', "|")).collect();
        let (variants, notation) = readings(&words, shown.origin);
        for v in variants {
            match resolve(&v, aliases) {
                None => {}
                Some(Err(e)) => problems.push(e),
                Some(Ok((program, args))) => {
                    let gated = FEATURE_GATED.iter().any(|(p, sub, _)| {
                        *p == program && args.first().map(String::as_str) == Some(*sub)
                    });
                    if gated {
                        continue;
                    }
                    if let Err(e) = program.parse(&args) {
                        if !notation_error(&e, notation) {
                            problems.push(format!(
                                "{} receives `{}`: {}",
                                program.name(),
                                args.join(" "),
                                first_line(&e)
                            ));
                        }
                    }
                }
            }
        }
    }
    problems.dedup();
    problems
}

/// What [`check`] finds: the commands shown, `doc:line: ...` for each bad
/// one, and the quick blocks with their doc.
pub type Found = (usize, Vec<String>, Vec<(String, QuickBlock)>);

/// `doc:line: ...` for every bad command of every doc, and the docs' quick
/// blocks as (`doc`, block).
pub fn check() -> Result<Found> {
    let aliases = aliases(&root())?;
    let mut count = 0;
    let mut out = Vec::new();
    let mut quick = Vec::new();
    for (_, rel, text) in crate::docnames::read_docs()? {
        let (cmds, blocks) = shown(&text);
        count += cmds.len();
        for s in &cmds {
            for p in check_one(s, &aliases) {
                out.push(format!("{rel}:{}: `{}`: {p}", s.line, s.text));
            }
        }
        quick.extend(blocks.into_iter().map(|b| (rel.clone(), b)));
    }
    Ok((count, out, quick))
}

/// Runs the quick blocks; `doc:line: ...` for each that failed.
pub fn run_quick(blocks: &[(String, QuickBlock)]) -> Result<Vec<String>> {
    if blocks.is_empty() {
        return Ok(Vec::new());
    }
    step("the docs' quick command blocks: building host-sim and zslide (debug)");
    // One package a build, as `figures` builds host-sim: built together
    // their features would unify differently and rebuild shared crates.
    for package in ["host-sim", "zslide-host"] {
        let st = cargo()
            .current_dir(root())
            .args(["build", "-q", "-p", package])
            .status()
            .map_err(|e| format!("cargo build: {e}"))?;
        if !st.success() {
            return Err(format!("cargo build -p {package} failed"));
        }
    }
    let bin = target_dir().join("debug");
    let scratch = target_dir().join("doc-commands");
    let _ = fs::remove_dir_all(&scratch);
    fs::create_dir_all(&scratch).map_err(|e| format!("{}: {e}", scratch.display()))?;
    for d in ["tables", "scenarios"] {
        link_dir(&root().join(d), &scratch.join(d))?;
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    let mut paths = vec![bin];
    paths.extend(std::env::split_paths(&path));
    let path = std::env::join_paths(paths).map_err(|e| e.to_string())?;
    let mut failed = Vec::new();
    for (doc, b) in blocks {
        eprintln!(
            "  {doc}:{}: sh -e ({} lines)",
            b.line,
            b.script.lines().count()
        );
        let out = Command::new("sh")
            .args(["-e", "-c", &b.script])
            .current_dir(&scratch)
            .env("PATH", &path)
            .output()
            .map_err(|e| format!("sh: {e}"))?;
        if !out.status.success() {
            failed.push(format!(
                "{doc}:{}: the quick block failed ({}): {}",
                b.line,
                out.status,
                String::from_utf8_lossy(&out.stderr).trim()
            ));
        }
    }
    Ok(failed)
}

#[cfg(unix)]
fn link_dir(from: &Path, to: &PathBuf) -> Result<()> {
    std::os::unix::fs::symlink(from, to).map_err(|e| format!("{}: {e}", to.display()))
}

#[cfg(not(unix))]
fn link_dir(_: &Path, _: &PathBuf) -> Result<()> {
    Err("the docs' quick blocks run on Unix only".into())
}

#[cfg(test)]
mod tests;
