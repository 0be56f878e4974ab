//! `cargo xtask figures [--check] [--quick]`: the measured figures of
//! README.md and docs/*.md, each marked with the command that gives it.
//!
//! A figure is marked in the markdown with two HTML comments, which a
//! rendered page does not show:
//!
//! ```text
//! <!-- fig cmd="response --loop digital" path=".margins.phase_margin_deg" digits="0" -->40<!-- /fig -->
//! ```
//!
//! * `cmd`: `host-sim` arguments; `--json` is appended (before a `--`).
//!   Figures with the same `cmd` share one run.
//! * `path`: where the number is in the JSON (`.a.b`, `[k]` indexes an
//!   array; `[-1]` the last element).
//! * `digits`: decimals to print (default: as JSON prints it); `scale`
//!   multiplies first; `abs="1"` prints the magnitude; `plus="1"` writes
//!   a positive value with its `+`.
//! * `quick="1"`: cheap enough for `cargo xtask test` (run there with the
//!   debug build; the rest need `--release` minutes).
//!
//! A negative value is written with the document's minus: `−` (U+2212) if
//! the old value uses it, else `-`.
//!
//! The generated reference sections (`generated.rs`) are rewritten with
//! them, the names the docs cite checked (`docnames.rs`) and the commands
//! they show parsed (`doccmds.rs`).
//!
//! Without `--check` the marked values are rewritten in place; with it,
//! each figure that drifted is listed with doc:line, the old and the new
//! value, and the exit status is 1. A complete run that leaves every
//! figure current writes its date into README.md's
//! `<!-- figures-checked -->` block.

use crate::{cargo, root, step, target_dir, Result};
use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// List the figures that drifted (doc:line, old, new) instead of
    /// rewriting them; exit status 1 if any did.
    #[arg(long)]
    pub check: bool,
    /// Only the figures marked `quick` (what `cargo xtask test` runs).
    #[arg(long)]
    pub quick: bool,
}

const OPEN: &str = "<!-- fig ";
const CLOSE: &str = "<!-- /fig -->";
const DATE_OPEN: &str = "<!-- figures-checked -->";
const DATE_CLOSE: &str = "<!-- /figures-checked -->";

/// One marked figure.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    pub doc: PathBuf,
    pub line: usize,
    pub attrs: HashMap<String, String>,
    /// Byte range of the value between the two comments.
    pub value_at: (usize, usize),
    pub old: String,
}

impl Figure {
    fn attr(&self, k: &str) -> Option<&str> {
        self.attrs.get(k).map(String::as_str)
    }
    fn quick(&self) -> bool {
        self.attr("quick") == Some("1")
    }
}

/// `key="value"` pairs of a marker's opening comment.
pub fn parse_attrs(s: &str) -> std::result::Result<HashMap<String, String>, String> {
    let mut out = HashMap::new();
    let mut rest = s.trim();
    while !rest.is_empty() {
        let eq = rest
            .find('=')
            .ok_or_else(|| format!("expected key=\"value\" at {rest:?}"))?;
        let key = rest[..eq].trim().to_string();
        let after = rest[eq + 1..].trim_start();
        let body = after
            .strip_prefix('"')
            .ok_or_else(|| format!("{key}: the value must be in double quotes"))?;
        let end = body
            .find('"')
            .ok_or_else(|| format!("{key}: unterminated value"))?;
        out.insert(key, body[..end].to_string());
        rest = body[end + 1..].trim_start();
    }
    Ok(out)
}

/// The figures marked in `text` (of `doc`).
pub fn scan(doc: &Path, text: &str) -> Result<Vec<Figure>> {
    let mut out = Vec::new();
    let mut at = 0;
    while let Some(k) = text[at..].find(OPEN) {
        let start = at + k;
        let line = text[..start].matches('\n').count() + 1;
        let head_end = text[start..]
            .find("-->")
            .map(|e| start + e)
            .ok_or_else(|| format!("{}:{line}: figure marker not closed", doc.display()))?;
        let attrs = parse_attrs(&text[start + OPEN.len()..head_end])
            .map_err(|e| format!("{}:{line}: {e}", doc.display()))?;
        for need in ["cmd", "path"] {
            if !attrs.contains_key(need) {
                return Err(format!("{}:{line}: figure without {need}=", doc.display()));
            }
        }
        let v0 = head_end + 3;
        let v1 = text[v0..]
            .find(CLOSE)
            .map(|e| v0 + e)
            .ok_or_else(|| format!("{}:{line}: figure without {CLOSE}", doc.display()))?;
        if text[v0..v1].contains('\n') || text[v0..v1].contains("<!--") {
            return Err(format!(
                "{}:{line}: a figure's value must be on one line, before {CLOSE}",
                doc.display()
            ));
        }
        out.push(Figure {
            doc: doc.to_path_buf(),
            line,
            attrs,
            value_at: (v0, v1),
            old: text[v0..v1].to_string(),
        });
        at = v1 + CLOSE.len();
    }
    Ok(out)
}

/// The value at `path` (`.a.b[2].c`, `[-1]` = last) of `v`.
pub fn lookup<'a>(v: &'a serde_json::Value, path: &str) -> Option<&'a serde_json::Value> {
    let mut cur = v;
    let mut rest = path;
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix('.') {
            let end = r.find(['.', '[']).unwrap_or(r.len());
            cur = cur.get(&r[..end])?;
            rest = &r[end..];
        } else if let Some(r) = rest.strip_prefix('[') {
            let end = r.find(']')?;
            let k: i64 = r[..end].parse().ok()?;
            let a = cur.as_array()?;
            let i = if k < 0 { a.len() as i64 + k } else { k };
            cur = a.get(usize::try_from(i).ok()?)?;
            rest = &r[end + 1..];
        } else {
            return None;
        }
    }
    Some(cur)
}

/// The figure's new text from its command's JSON.
pub fn render(f: &Figure, json: &serde_json::Value) -> std::result::Result<String, String> {
    let path = f.attr("path").unwrap_or_default();
    let v = lookup(json, path).ok_or_else(|| format!("no {path} in the command's JSON"))?;
    let text = match v {
        serde_json::Value::Number(n) => {
            let mut x = n.as_f64().ok_or("not a number")?;
            if let Some(s) = f.attr("scale") {
                x *= s
                    .parse::<f64>()
                    .map_err(|_| format!("scale={s:?} is not a number"))?;
            }
            if f.attr("abs") == Some("1") {
                x = x.abs();
            }
            let s = match f.attr("digits") {
                Some(d) => {
                    let d: usize = d.parse().map_err(|_| format!("digits={d:?}"))?;
                    format!("{x:.d$}")
                }
                None => format!("{x}"),
            };
            // No "-0.0": a value that rounds to zero has no sign.
            let s = if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
                s[1..].to_string()
            } else {
                s
            };
            let s = if f.attr("plus") == Some("1") && !s.starts_with('-') {
                format!("+{s}")
            } else {
                s
            };
            if f.old.contains('−') {
                s.replace('-', "−")
            } else {
                s
            }
        }
        serde_json::Value::String(s) => s.clone(),
        serde_json::Value::Bool(b) => b.to_string(),
        other => return Err(format!("{path} is {other}, not a number or a word")),
    };
    Ok(text)
}

fn host_sim(release: bool) -> Result<PathBuf> {
    step(&format!(
        "building host-sim ({})",
        if release { "release" } else { "debug" }
    ));
    let mut c = cargo();
    c.current_dir(root())
        .args(["build", "-q", "-p", "host-sim"]);
    if release {
        c.arg("--release");
    }
    let st = c.status().map_err(|e| format!("cargo build: {e}"))?;
    if !st.success() {
        return Err("cargo build -p host-sim failed".into());
    }
    Ok(target_dir()
        .join(if release { "release" } else { "debug" })
        .join("host-sim"))
}

fn run_cmd(bin: &Path, cmd: &str) -> Result<serde_json::Value> {
    let mut args: Vec<&str> = cmd.split_whitespace().collect();
    if !args.contains(&"--json") {
        // Before a `--`: what follows it is another command's options
        // (`compensate-iterate -- CUT OPTIONS`).
        let at = args.iter().position(|a| *a == "--").unwrap_or(args.len());
        args.insert(at, "--json");
    }
    eprintln!("  host-sim {}", args.join(" "));
    let out = Command::new(bin)
        .current_dir(root())
        .args(&args)
        .output()
        .map_err(|e| format!("{}: {e}", bin.display()))?;
    if !out.status.success() {
        return Err(format!(
            "host-sim {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    serde_json::from_slice(&out.stdout)
        .map_err(|e| format!("host-sim {}: JSON: {e}", args.join(" ")))
}

/// Today's date (UTC), `YYYY-MM-DD`.
fn today() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    // Days to civil date (Howard Hinnant's algorithm).
    let z = (secs / 86_400) as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

/// Checks (or rewrites) the figures; returns (figures checked, drifted).
pub fn figures(check: bool, quick: bool) -> Result<(usize, Vec<String>)> {
    let mut all = Vec::new();
    let mut texts = HashMap::new();
    for doc in crate::docnames::docs()? {
        let text = fs::read_to_string(&doc).map_err(|e| format!("{}: {e}", doc.display()))?;
        all.extend(scan(&doc, &text)?);
        texts.insert(doc, text);
    }
    let chosen: Vec<&Figure> = all.iter().filter(|f| !quick || f.quick()).collect();
    let bin = host_sim(!quick)?;
    step(&format!(
        "figures: {} marked, running their commands",
        chosen.len()
    ));
    let mut runs: HashMap<String, serde_json::Value> = HashMap::new();
    let mut drift = Vec::new();
    // Per doc: (byte range of a value, its new text).
    type Edits = Vec<((usize, usize), String)>;
    let mut edits: HashMap<PathBuf, Edits> = HashMap::new();
    for f in &chosen {
        let cmd = f.attr("cmd").unwrap_or_default().to_string();
        if !runs.contains_key(&cmd) {
            runs.insert(cmd.clone(), run_cmd(&bin, &cmd)?);
        }
        let new = render(f, &runs[&cmd]).map_err(|e| format!("{}:{}: {e}", rel(&f.doc), f.line))?;
        if new != f.old {
            drift.push(format!(
                "{}:{}: {} was {:?}, now {:?} (host-sim {cmd} --json, {})",
                rel(&f.doc),
                f.line,
                f.attr("path").unwrap_or_default(),
                f.old,
                new,
                f.attr("path").unwrap_or_default()
            ));
            edits
                .entry(f.doc.clone())
                .or_default()
                .push((f.value_at, new));
        }
    }
    if !check {
        for (doc, mut e) in edits {
            let mut text = texts[&doc].clone();
            e.sort_by_key(|edit| std::cmp::Reverse(edit.0 .0));
            for ((a, b), new) in e {
                text.replace_range(a..b, &new);
            }
            fs::write(&doc, text).map_err(|e| format!("{}: {e}", doc.display()))?;
        }
    }
    if !quick && (!check || drift.is_empty()) {
        stamp_date(chosen.len())?;
    }
    Ok((chosen.len(), drift))
}

/// Writes the date of a complete, current run into README.md.
fn stamp_date(n: usize) -> Result<()> {
    let p = root().join("README.md");
    let text = fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
    let (Some(a), Some(b)) = (text.find(DATE_OPEN), text.find(DATE_CLOSE)) else {
        return Err(format!("README.md has no {DATE_OPEN} block"));
    };
    let mut t = text.clone();
    t.replace_range(
        a + DATE_OPEN.len()..b,
        &format!("{} ({n} figures)", today()),
    );
    if t != text {
        fs::write(&p, t).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    Ok(())
}

fn rel(p: &Path) -> String {
    p.strip_prefix(root()).unwrap_or(p).display().to_string()
}

/// The docs' checks besides the figures: the generated sections
/// (rewritten, or with `check` compared), the names they cite
/// (`docnames`), the commands they show (`doccmds`, the quick blocks run).
/// Returns a summary line and the problems, `doc:line: ...` each.
pub fn doc_checks(check: bool) -> Result<(String, Vec<String>)> {
    let (sections, stale) = crate::generated::run(check)?;
    let names = crate::docnames::check()?;
    let (shown, commands, quick) = crate::doccmds::check()?;
    let failed_blocks = crate::doccmds::run_quick(&quick)?;
    let summary = format!(
        "generated sections: {sections}, {} {}; names cited: {} not found; \
         commands shown: {shown}, {} refused; quick blocks: {}, {} failed",
        stale.len(),
        if check { "out of date" } else { "rewritten" },
        names.len(),
        commands.len(),
        quick.len(),
        failed_blocks.len()
    );
    let mut problems = names;
    problems.extend(commands);
    problems.extend(failed_blocks);
    if check {
        problems.extend(stale);
    }
    Ok((summary, problems))
}

pub fn run(args: &Args) -> Result<u8> {
    let (n, drift) = figures(args.check, args.quick)?;
    let (summary, problems) = doc_checks(args.check)?;
    for p in &problems {
        eprintln!("{p}");
    }
    if args.check {
        for d in &drift {
            eprintln!("{d}");
        }
        eprintln!("figures: {n} checked, {} drifted; {summary}", drift.len());
        Ok(u8::from(!drift.is_empty() || !problems.is_empty()))
    } else {
        eprintln!("figures: {n} checked, {} rewritten; {summary}", drift.len());
        Ok(u8::from(!problems.is_empty()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOC: &str = "a\nPM <!-- fig cmd=\"response --loop digital\" path=\".margins.pm\" digits=\"1\" -->40.1<!-- /fig --> deg\nband <!-- fig cmd=\"cut\" path=\".lo\" digits=\"1\" quick=\"1\" -->−8.0<!-- /fig -->\n";

    #[test]
    fn markers_are_found_with_their_line_attributes_and_value() {
        let f = scan(Path::new("d.md"), DOC).unwrap();
        assert_eq!(f.len(), 2);
        assert_eq!(f[0].line, 2);
        assert_eq!(f[0].attr("cmd"), Some("response --loop digital"));
        assert_eq!(f[0].old, "40.1");
        assert_eq!(&DOC[f[1].value_at.0..f[1].value_at.1], "−8.0");
        assert!(f[1].quick() && !f[0].quick());
    }

    #[test]
    fn values_render_with_digits_scale_and_the_documents_minus() {
        let f = scan(Path::new("d.md"), DOC).unwrap();
        let j = serde_json::json!({"margins": {"pm": 40.149}, "lo": -7.96});
        assert_eq!(render(&f[0], &j).unwrap(), "40.1");
        assert_eq!(render(&f[1], &j).unwrap(), "−8.0");
        let j = serde_json::json!({"margins": {"pm": -0.01}});
        assert_eq!(render(&f[0], &j).unwrap(), "0.0");
        let mut g = f[1].clone();
        g.attrs.insert("plus".into(), "1".into());
        assert_eq!(
            render(&g, &serde_json::json!({"lo": 26.2})).unwrap(),
            "+26.2"
        );
    }

    #[test]
    fn paths_index_objects_and_arrays_from_either_end() {
        let j = serde_json::json!({"rows": [{"x": 1}, {"x": 2}, {"x": 3}]});
        assert_eq!(lookup(&j, ".rows[1].x"), Some(&serde_json::json!(2)));
        assert_eq!(lookup(&j, ".rows[-1].x"), Some(&serde_json::json!(3)));
        assert_eq!(lookup(&j, ".rows[5].x"), None);
        assert_eq!(lookup(&j, ".nope"), None);
    }

    #[test]
    fn a_marker_without_a_command_or_closing_comment_is_refused_with_its_line() {
        let e = scan(
            Path::new("d.md"),
            "x\n<!-- fig path=\".a\" -->1<!-- /fig -->",
        )
        .unwrap_err();
        assert!(e.contains("d.md:2") && e.contains("cmd"), "{e}");
        let e = scan(Path::new("d.md"), "<!-- fig cmd=\"c\" path=\".a\" -->1").unwrap_err();
        assert!(e.contains("<!-- /fig -->"), "{e}");
    }

    #[test]
    fn the_civil_date_is_iso() {
        let d = today();
        assert_eq!(d.len(), 10);
        assert!(d.starts_with("20"), "{d}");
    }
}
