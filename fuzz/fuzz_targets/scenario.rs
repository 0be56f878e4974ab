//! The scenario loader (`host_sim::scenario::parse`) on arbitrary text.
//! Properties:
//! * a refused document that is valid TOML and has the schema's shape is
//!   refused by a range check whose message starts with the dotted path of
//!   a field that is present in the document;
//! * a refused document without the schema's shape gets serde's message,
//!   which names the field (in backquotes) or points at a line;
//! * an accepted document has no NaN or infinite number anywhere, the
//!   built configs carry its values, and the firmware's spindle estimators
//!   accept its speed band at its clock.
#![no_main]

use host_sim::scenario::{parse, ScenarioFile};
use libfuzzer_sys::fuzz_target;
use zslide::spindle::{EncoderAngle, EncoderConfig, TachAngle, TachConfig};
use zslide::units::SpindleAngle;

/// The value at a dotted path (`"cutting.bolt_holes.count"`).
fn lookup<'a>(doc: &'a toml::Table, path: &str) -> Option<&'a toml::Value> {
    let mut parts = path.split('.');
    let mut v = doc.get(parts.next()?)?;
    for p in parts {
        v = v.as_table()?.get(p)?;
    }
    Some(v)
}

fn all_finite(v: &toml::Value) -> bool {
    match v {
        toml::Value::Float(f) => f.is_finite(),
        toml::Value::Table(t) => t.values().all(all_finite),
        toml::Value::Array(a) => a.iter().all(all_finite),
        _ => true,
    }
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let result = parse(text, "fuzz");
    let doc = text.parse::<toml::Table>().ok();
    let shaped = toml::from_str::<ScenarioFile>(text).ok();
    match (result, doc, shaped) {
        (Ok(s), doc, shaped) => {
            let doc = doc.expect("accepted text that is not TOML");
            assert!(doc.values().all(all_finite), "accepted a non-finite number");
            let file = shaped.expect("accepted text without the schema's shape");
            assert_eq!(s.file, file);
            assert_eq!(s.loop_hz, file.loop_.rate_hz);
            assert_eq!(s.rig.seed, file.seed);
            assert_eq!(s.rig.gauge.v_per_in, file.gauge.v_per_mil * 1000.0);
            // The firmware's spindle estimators accept the band at the
            // scenario's clock (the rig builds them with `expect`).
            let ticks_per_s = u32::try_from(file.loop_.clock_hz).unwrap_or(u32::MAX);
            let enc = EncoderConfig {
                counts_per_rev: file.spindle.encoder_cpr,
                ticks_per_s,
                min_rpm: file.spindle.min_rpm,
                max_rpm: file.spindle.max_rpm,
                index_tolerance_counts: 2,
                index_angle: SpindleAngle(0),
                edge_stamps: zslide::spindle::EdgeStamps::Captured,
            };
            assert!(
                EncoderAngle::new(enc).is_some(),
                "accepted, but the encoder refuses {enc:?}"
            );
            let tach = TachConfig {
                ticks_per_s,
                mv_at_300_rpm: 5000,
                min_rpm: file.spindle.min_rpm,
                max_rpm: file.spindle.max_rpm,
                index_tolerance_permille: 20,
                index_angle: SpindleAngle(0),
            };
            assert!(
                TachAngle::new(tach).is_some(),
                "accepted, but the tachometer refuses {tach:?}"
            );
        }
        (Err(e), Some(doc), Some(_)) => {
            let msg = e.root_cause().to_string();
            let path = msg.split(' ').next().unwrap_or("");
            assert!(
                path.contains('.') && lookup(&doc, path).is_some(),
                "refusal does not start with a field of the document: {msg:?}"
            );
        }
        (Err(e), Some(_), None) => {
            let msg = format!("{e:#}");
            assert!(
                msg.contains('`') || msg.contains("line "),
                "schema refusal names no field and no line: {msg:?}"
            );
        }
        (Err(e), None, _) => {
            assert!(format!("{e:#}").contains("cannot parse"));
        }
    }
});
