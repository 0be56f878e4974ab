//! Reading a measured part: the files `compensate` accepts, each checked.
//!
//! Every file is in the part frame of docs/CUT.md: a point at radius X and
//! part angle φ is at `x = X cos φ`, `y = X sin φ` (eq 2-5, φ the angle of
//! the part, not of the firmware's command, from 0 to 360° in the sense
//! the part turns), in inches; the error is along the axis of turning, in
//! µin, **positive = excess stock** (the cut's own convention).
//!
//! * `cut --json`: the polar CMM grid (`phi_deg` rows × `x_in` columns,
//!   `cmm_grid_uin`, null inside a bolt hole) or, from `cut --grid`, the
//!   rectangular `grid.points` (`error_uin` null with an `absent` reason);
//! * `cut --out`'s `error_map.csv`: `phi_deg,X_1_in,..`, rows 0..360° (the
//!   360° row closes the curve and must repeat the 0° row), empty = hole;
//! * `cut --grid --out`'s `grid_error.csv`
//!   (`x_in,y_in,radius_in,phi_deg,error_uin,finish_uin,absent`);
//! * a shop's own points: the header `x_in,y_in,error_uin`, any layout.
//!
//! Refused, naming the line (or, in JSON, the field and element): a header
//! that is none of these (other units: `x_mm`, `error_um`, ...), a number
//! that does not parse or is NaN or infinite, a missing value (a short row,
//! an empty cell with no reason), two points at the same place, a radius
//! beyond the 8 in faceplate or an angle outside 0..360°, an error beyond
//! ±10 000 µin (0.01 in: a file in other units), a grid whose 360° row is
//! not its 0° row, a cut measured against the reversed nominal. A point a
//! file marks as unmeasured (in a hole, outside the cut) is counted and
//! reported, never fitted.

use super::fit::Point;
use sha2::{Digest, Sha256};

/// The faceplate's radius, in: no measured point lies beyond it.
pub const FACEPLATE_RADIUS_IN: f64 = 8.0;
/// Largest |error| a file may hold, µin (a file in mils or µm reads as
/// hundreds of times too large or small; too large is caught here).
pub const MAX_ERROR_UIN: f64 = 10_000.0;
/// Two points closer than this are the same place, in.
pub const SAME_PLACE_IN: f64 = 1e-6;

/// The instrument noise (1σ, µin) stated for a measurement that does not
/// state its own: chapter 5's CMM (`cut::cmm::CmmLevels::renault`), its
/// repeatability and its 1 µm step's rounding (step/√12) together.
pub fn cmm_noise_uin() -> f64 {
    let l = crate::cut::cmm::CmmLevels::renault();
    (l.repeatability_in.powi(2) + l.resolution_in.powi(2) / 12.0).sqrt() * 1e6
}

/// The noise stated for `cut --measure exact`'s grid, µin: the simulated
/// surface's own finish floor (feed marks, the loop's noise; docs/CUT.md).
pub const EXACT_NOISE_UIN: f64 = 2.0;

/// Which file it was.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    CutJsonPolar,
    CutJsonRectangular,
    ErrorMapCsv,
    GridCsv,
    PointsCsv,
}

/// A checked measurement.
#[derive(Clone, Debug)]
pub struct Measurement {
    pub kind: Kind,
    pub points: Vec<Point>,
    /// Points the file marks as unmeasured (holes, outside the cut).
    pub absent: usize,
    /// SHA-256 of the file's bytes, hex.
    pub sha256: String,
    /// The noise the file states (`cut --json`'s `measure`), µin, if any.
    pub stated_noise_uin: Option<f64>,
}

pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Reads and checks `bytes` (the file's name only labels the errors).
pub fn parse(bytes: &[u8]) -> Result<Measurement, String> {
    let text = std::str::from_utf8(bytes).map_err(|e| format!("not UTF-8 text: {e}"))?;
    let p = if text.trim_start().starts_with('{') {
        parse_json(text)?
    } else {
        parse_csv(text)?
    };
    check_duplicates(&p.points)?;
    Ok(Measurement {
        kind: p.kind,
        points: p.points.into_iter().map(|p| p.0).collect(),
        absent: p.absent,
        sha256: sha256_hex(bytes),
        stated_noise_uin: p.stated_noise_uin,
    })
}

/// A file's points, each with where it came from.
struct Parsed {
    kind: Kind,
    points: Vec<(Point, String)>,
    absent: usize,
    stated_noise_uin: Option<f64>,
}

/// A checked point (the line or element it came from names it).
fn point(x: f64, y: f64, e: f64, at: &dyn Fn() -> String) -> Result<Point, String> {
    for (what, v) in [("x", x), ("y", y), ("error", e)] {
        if !v.is_finite() {
            return Err(format!("{}: {what} = {v}: must be a finite number", at()));
        }
    }
    let r = x.hypot(y);
    if r > FACEPLATE_RADIUS_IN {
        return Err(format!(
            "{}: radius {r} in is beyond the {FACEPLATE_RADIUS_IN} in faceplate (a file in mm?)",
            at()
        ));
    }
    if e.abs() > MAX_ERROR_UIN {
        return Err(format!(
            "{}: error {e} µin is beyond ±{MAX_ERROR_UIN} µin (0.01 in, the gauge's range): the file \
             must be in µin",
            at()
        ));
    }
    Ok(Point {
        x_in: x,
        y_in: y,
        error_uin: e,
    })
}

fn polar(x: f64, phi_deg: f64, e: f64, at: &dyn Fn() -> String) -> Result<Point, String> {
    if !(x.is_finite() && x >= 0.0) {
        return Err(format!("{}: X = {x}: must be a radius >= 0 in", at()));
    }
    if !(phi_deg.is_finite() && (0.0..360.0).contains(&phi_deg)) {
        return Err(format!(
            "{}: φ = {phi_deg}°: the part angle runs 0 <= φ < 360°",
            at()
        ));
    }
    let (s, c) = phi_deg.to_radians().sin_cos();
    point(x * c, x * s, e, at)
}

fn check_duplicates(pts: &[(Point, String)]) -> Result<(), String> {
    let mut idx: Vec<usize> = (0..pts.len()).collect();
    idx.sort_by(|&a, &b| pts[a].0.x_in.total_cmp(&pts[b].0.x_in));
    for (k, &i) in idx.iter().enumerate() {
        for &j in &idx[k + 1..] {
            if pts[j].0.x_in - pts[i].0.x_in > SAME_PLACE_IN {
                break;
            }
            if (pts[j].0.y_in - pts[i].0.y_in).abs() <= SAME_PLACE_IN {
                let (a, b) = if i < j { (i, j) } else { (j, i) };
                return Err(format!(
                    "{} and {} measure the same place (x = {}, y = {} in): a duplicate point",
                    pts[a].1, pts[b].1, pts[a].0.x_in, pts[a].0.y_in
                ));
            }
        }
    }
    Ok(())
}

fn num(v: &serde_json::Value, at: &dyn Fn() -> String) -> Result<Option<f64>, String> {
    match v {
        serde_json::Value::Null => Ok(None),
        serde_json::Value::Number(n) => n
            .as_f64()
            .map(Some)
            .ok_or_else(|| format!("{}: {n} is not a number", at())),
        other => Err(format!("{}: {other} is not a number or null", at())),
    }
}

fn field<'a>(v: &'a serde_json::Value, name: &str) -> Result<&'a serde_json::Value, String> {
    v.get(name)
        .ok_or_else(|| format!("field `{name}` missing: not a `host-sim cut --json` output"))
}

fn array<'a>(v: &'a serde_json::Value, name: &str) -> Result<&'a Vec<serde_json::Value>, String> {
    field(v, name)?
        .as_array()
        .ok_or_else(|| format!("field `{name}` is not an array"))
}

fn parse_json(text: &str) -> Result<Parsed, String> {
    let v: serde_json::Value =
        serde_json::from_str(text).map_err(|e| format!("line {}: not JSON: {e}", e.line()))?;
    // The frame: the error is against the nominal surface, positive =
    // excess stock. A cut with the reversed command is measured against
    // the reversed nominal: its sign is the other way round.
    match field(&v, "command_sign")?.as_str() {
        Some("normal") => {}
        other => {
            return Err(format!(
                "command_sign = {other:?}: only a cut measured against the nominal (\"normal\") \
                 gives the part's error in the frame compensate uses"
            ))
        }
    }
    // A mean of n readings (`cut --cmm-readings`; absent in older files:
    // one) has one reading's noise over √n.
    let readings = match v.get("cmm_readings") {
        None => 1,
        Some(n) => match n.as_u64() {
            Some(n @ 1..) if n <= u64::from(crate::cut::cmm::MAX_READINGS) => n,
            _ => {
                return Err(format!(
                    "cmm_readings = {n}: a count of readings 1 ..= {} expected",
                    crate::cut::cmm::MAX_READINGS
                ))
            }
        },
    };
    let stated_noise_uin = match field(&v, "measure")?.as_str() {
        Some("cmm") => Some(cmm_noise_uin() / (readings as f64).sqrt()),
        Some("exact") => Some(EXACT_NOISE_UIN),
        other => {
            return Err(format!(
                "measure = {other:?}: \"cmm\" or \"exact\" expected"
            ))
        }
    };
    if let Some(g) = v.get("grid").filter(|g| !g.is_null()) {
        let pts = array(g, "points")?;
        let (mut points, mut absent) = (Vec::new(), 0);
        for (i, p) in pts.iter().enumerate() {
            let at = || format!("grid.points[{i}]");
            let x =
                num(field(p, "x_in")?, &at)?.ok_or_else(|| format!("{}: x_in is null", at()))?;
            let y =
                num(field(p, "y_in")?, &at)?.ok_or_else(|| format!("{}: y_in is null", at()))?;
            match num(field(p, "error_uin")?, &at)? {
                Some(e) => points.push((point(x, y, e, &at)?, at())),
                None if p.get("absent").is_some_and(|a| a.is_string()) => absent += 1,
                None => {
                    return Err(format!(
                        "{}: error_uin is null with no `absent` reason: a missing point",
                        at()
                    ))
                }
            }
        }
        return Ok(Parsed {
            kind: Kind::CutJsonRectangular,
            points,
            absent,
            stated_noise_uin,
        });
    }
    let phis = array(&v, "phi_deg")?;
    let xs = array(&v, "x_in")?;
    let rows = array(&v, "cmm_grid_uin")?;
    if rows.len() != phis.len() {
        return Err(format!(
            "cmm_grid_uin has {} rows for {} angles in phi_deg: missing rows",
            rows.len(),
            phis.len()
        ));
    }
    let xs: Vec<f64> = xs
        .iter()
        .enumerate()
        .map(|(j, x)| num(x, &|| format!("x_in[{j}]"))?.ok_or_else(|| format!("x_in[{j}] is null")))
        .collect::<Result<_, _>>()?;
    let (mut points, mut absent) = (Vec::new(), 0);
    for (i, (phi, row)) in phis.iter().zip(rows).enumerate() {
        let phi = num(phi, &|| format!("phi_deg[{i}]"))?
            .ok_or_else(|| format!("phi_deg[{i}] is null"))?;
        let row = row
            .as_array()
            .ok_or_else(|| format!("cmm_grid_uin[{i}] is not an array"))?;
        if row.len() != xs.len() {
            return Err(format!(
                "cmm_grid_uin[{i}] (φ = {phi}°) has {} values for {} radii: missing points",
                row.len(),
                xs.len()
            ));
        }
        for (j, (&x, e)) in xs.iter().zip(row).enumerate() {
            let at = || format!("cmm_grid_uin[{i}][{j}] (φ = {phi}°, X = {x} in)");
            match num(e, &at)? {
                Some(e) => points.push((polar(x, phi, e, &at)?, at())),
                // null: the probe could not measure (inside a bolt hole).
                None => absent += 1,
            }
        }
    }
    Ok(Parsed {
        kind: Kind::CutJsonPolar,
        points,
        absent,
        stated_noise_uin,
    })
}

fn cells(line: &str) -> Vec<&str> {
    line.split(',').map(str::trim).collect()
}

fn parse_f64(s: &str, what: &str, at: &dyn Fn() -> String) -> Result<f64, String> {
    s.parse::<f64>()
        .map_err(|_| format!("{}: {what} = {s:?} is not a number", at()))
}

fn parse_csv(text: &str) -> Result<Parsed, String> {
    // Lines numbered from 1; blank lines and `#` comments skipped.
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((hl, header)) = lines.next() else {
        return Err("the file is empty".into());
    };
    let head = cells(header);
    let body: Vec<(usize, &str)> = lines.collect();
    match head.as_slice() {
        ["x_in", "y_in", "error_uin"] => {
            let mut points = Vec::new();
            for (n, l) in body {
                let at = || format!("line {n}");
                let c = cells(l);
                if c.len() != 3 || c.iter().any(|v| v.is_empty()) {
                    return Err(format!(
                        "line {n}: {} values where x_in,y_in,error_uin are three: a missing value",
                        c.iter().filter(|v| !v.is_empty()).count()
                    ));
                }
                let x = parse_f64(c[0], "x_in", &at)?;
                let y = parse_f64(c[1], "y_in", &at)?;
                let e = parse_f64(c[2], "error_uin", &at)?;
                points.push((point(x, y, e, &at)?, at()));
            }
            Ok(Parsed {
                kind: Kind::PointsCsv,
                points,
                absent: 0,
                stated_noise_uin: None,
            })
        }
        ["x_in", "y_in", "radius_in", "phi_deg", "error_uin", "finish_uin", "absent"] => {
            let (mut points, mut absent) = (Vec::new(), 0);
            for (n, l) in body {
                let at = || format!("line {n}");
                let c = cells(l);
                if c.len() != 7 {
                    return Err(format!(
                        "line {n}: {} fields where the header has 7",
                        c.len()
                    ));
                }
                let x = parse_f64(c[0], "x_in", &at)?;
                let y = parse_f64(c[1], "y_in", &at)?;
                match (c[4], c[6]) {
                    ("", "") => {
                        return Err(format!(
                            "line {n}: error_uin is empty with no `absent` reason: a missing point"
                        ))
                    }
                    ("", _) => absent += 1,
                    (e, "") => {
                        let e = parse_f64(e, "error_uin", &at)?;
                        points.push((point(x, y, e, &at)?, at()));
                    }
                    (_, why) => {
                        return Err(format!(
                            "line {n}: an error value and absent = {why:?}: one or the other"
                        ))
                    }
                }
            }
            Ok(Parsed {
                kind: Kind::GridCsv,
                points,
                absent,
                stated_noise_uin: None,
            })
        }
        [first, radii @ ..] if *first == "phi_deg" && !radii.is_empty() => {
            let xs: Vec<f64> = radii
                .iter()
                .map(|h| {
                    h.strip_prefix("X_")
                        .and_then(|v| v.strip_suffix("_in"))
                        .and_then(|v| v.parse::<f64>().ok())
                        .ok_or_else(|| {
                            format!(
                                "line {hl}: column {h:?}: an error map's radii are `X_<inches>_in`"
                            )
                        })
                })
                .collect::<Result<_, _>>()?;
            let (mut points, mut absent) = (Vec::new(), 0);
            let mut first_row: Option<(usize, Vec<String>)> = None;
            for (n, l) in body {
                let at = || format!("line {n}");
                let c = cells(l);
                if c.len() != xs.len() + 1 {
                    return Err(format!(
                        "line {n}: {} fields where the header has {}: missing values",
                        c.len(),
                        xs.len() + 1
                    ));
                }
                let phi = parse_f64(c[0], "phi_deg", &at)?;
                if phi == 360.0 {
                    // The closing point of each curve: φ = 0 again.
                    match &first_row {
                        Some((n0, r)) if r[..] == c[1..] => continue,
                        Some((n0, _)) => {
                            return Err(format!(
                                "line {n}: the 360° row differs from the 0° row (line {n0}): \
                                 φ = 360° is φ = 0"
                            ))
                        }
                        None => return Err(format!("line {n}: a 360° row with no 0° row")),
                    }
                }
                if phi == 0.0 {
                    first_row = Some((n, c[1..].iter().map(|s| s.to_string()).collect()));
                }
                for (j, &x) in xs.iter().enumerate() {
                    let atj = || format!("line {n}, X = {x} in");
                    match c[j + 1] {
                        "" => absent += 1,
                        e => {
                            let e = parse_f64(e, "error", &atj)?;
                            points.push((polar(x, phi, e, &atj)?, atj()));
                        }
                    }
                }
            }
            Ok(Parsed {
                kind: Kind::ErrorMapCsv,
                points,
                absent,
                stated_noise_uin: None,
            })
        }
        _ => Err(format!(
            "line {hl}: header {header:?}: expected `x_in,y_in,error_uin` (inches, µin, positive = \
             excess stock), `cut --out`'s error_map.csv (`phi_deg,X_1_in,..`) or `cut --grid \
             --out`'s grid_error.csv"
        )),
    }
}
