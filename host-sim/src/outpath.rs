//! Output paths checked before the work: a long run that fails only when it
//! writes its result wastes the run, and the OS's bare "No such file or
//! directory" names neither the option nor the path.

use anyhow::bail;
use std::path::Path;

/// `path` (given with option `flag`) can be written as a file: its
/// directory exists, it is not itself a directory, and a file can be
/// created (or opened for writing) there. Leaves no file behind that was
/// not there before.
pub fn check_file(flag: &str, path: &Path) -> anyhow::Result<()> {
    let shown = path.display();
    if path.is_dir() {
        bail!("{flag} {shown}: is a directory; give a file name");
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !parent.is_dir() {
        bail!(
            "{flag} {shown}: directory {} does not exist",
            parent.display()
        );
    }
    let existed = path.exists();
    let opened = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(false)
        .open(path);
    match opened {
        Ok(_) => {
            if !existed {
                // Best effort: the real write comes later and replaces it.
                let _ = std::fs::remove_file(path);
            }
            Ok(())
        }
        Err(e) => bail!("{flag} {shown}: cannot be written: {e}"),
    }
}

/// `dir` (given with option `flag`) is a directory the plots can go to:
/// created when missing, refused when it is a file or cannot be written.
pub fn check_dir(flag: &str, dir: &Path) -> anyhow::Result<()> {
    let shown = dir.display();
    if dir.exists() && !dir.is_dir() {
        bail!("{flag} {shown}: is a file; give a directory for the output files");
    }
    if let Err(e) = std::fs::create_dir_all(dir) {
        bail!("{flag} {shown}: cannot create the directory: {e}");
    }
    let probe = dir.join(".host-sim-write-check");
    match std::fs::write(&probe, b"") {
        Ok(()) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => bail!("{flag} {shown}: cannot write files in it: {e}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_in_a_missing_directory_is_refused_with_both_names() {
        let e = check_file("--svg", Path::new("/nonexistent-dir-7f3a/l.svg")).unwrap_err();
        let m = format!("{e:#}");
        assert!(m.contains("--svg /nonexistent-dir-7f3a/l.svg"), "{m}");
        assert!(
            m.contains("directory /nonexistent-dir-7f3a does not exist"),
            "{m}"
        );
    }

    #[test]
    fn an_existing_file_given_as_output_directory_is_refused() {
        let f = std::env::temp_dir().join(format!("outpath-file-{}", std::process::id()));
        std::fs::write(&f, b"x").unwrap();
        let m = format!("{:#}", check_dir("--out", &f).unwrap_err());
        let _ = std::fs::remove_file(&f);
        assert!(m.contains("is a file"), "{m}");
        assert!(m.starts_with("--out "), "{m}");
    }

    #[test]
    fn a_checked_new_file_is_not_left_behind() {
        let f = std::env::temp_dir().join(format!("outpath-new-{}", std::process::id()));
        let _ = std::fs::remove_file(&f);
        check_file("--csv", &f).unwrap();
        assert!(!f.exists());
    }
}
