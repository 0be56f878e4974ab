//! The `name = value` files the tools write and read back (a plant's fit,
//! a measured process).

use std::path::Path;

use crate::Result;

/// A `name = value` file's fields (`#` comments and blank lines skipped).
pub fn read_fields(path: &Path) -> Result<std::collections::BTreeMap<String, f64>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let mut v = std::collections::BTreeMap::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (k, x) = line
            .split_once('=')
            .ok_or_else(|| format!("{}:{}: expected NAME = VALUE", path.display(), i + 1))?;
        let x: f64 = x
            .trim()
            .parse()
            .map_err(|e| format!("{}:{}: {}: {e}", path.display(), i + 1, x.trim()))?;
        v.insert(k.trim().to_string(), x);
    }
    Ok(v)
}
