//! Output files: their paths checked before the work (a long run that
//! fails only when it writes its result wastes the run, and the OS's bare
//! "No such file or directory" names neither the option nor the path), and
//! written whole or not at all ([`replace`], [`replace_with`]): a file is
//! written under a temporary name beside it and renamed onto its name only
//! when complete, so a refusal, an error or a Ctrl-C part-way leaves the
//! file that stood there as it was. Every command of `host-sim` and
//! `zslide` that writes a file writes it through these two.

use anyhow::{bail, Context};
use std::path::{Path, PathBuf};

/// The temporary name `path` is written under: hidden, in the same
/// directory (a rename within one file system is atomic), unique to this
/// process, and with `path`'s extension (the plot backends choose the
/// image format by it).
fn partial_name(path: &Path) -> PathBuf {
    let name = path
        .file_stem()
        .map_or_else(|| "out".into(), |s| s.to_string_lossy().into_owned());
    let ext = path
        .extension()
        .map_or_else(String::new, |e| format!(".{}", e.to_string_lossy()));
    path.with_file_name(format!(".{name}.partial-{}{ext}", std::process::id()))
}

/// A file being written under its temporary name: [`Partial::commit`]
/// renames it onto its name; dropped uncommitted (an error, a refusal,
/// an unwinding panic), the temporary file is removed and the file that
/// stood at the name is untouched.
pub struct Partial {
    tmp: PathBuf,
    path: PathBuf,
    committed: bool,
}

/// The temporary files being written now: what a Ctrl-C removes
/// ([`remove_partials_on_signal`]).
static LIVE: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn live() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// For a command that a signal ends where it stands (`host-sim`): on
/// SIGINT or SIGTERM, the temporary files being written are removed and
/// the process exits with 128 + the signal, as the default action would
/// end it; the files at their names were never touched.
#[cfg(unix)]
pub fn remove_partials_on_signal() -> std::io::Result<()> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM])?;
    std::thread::spawn(move || {
        if let Some(sig) = signals.forever().next() {
            for p in live().iter() {
                let _ = std::fs::remove_file(p);
            }
            std::process::exit(128 + sig);
        }
    });
    Ok(())
}

impl Partial {
    pub fn new(path: &Path) -> Self {
        let tmp = partial_name(path);
        live().push(tmp.clone());
        Self {
            tmp,
            path: path.to_path_buf(),
            committed: false,
        }
    }

    /// The temporary file, created, for a writer that streams (a VCD).
    pub fn create(path: &Path) -> anyhow::Result<(Self, std::fs::File)> {
        let p = Self::new(path);
        let f = std::fs::File::create(&p.tmp)
            .with_context(|| format!("{}: cannot write", path.display()))?;
        Ok((p, f))
    }

    /// Where the contents go until [`Partial::commit`].
    pub fn tmp(&self) -> &Path {
        &self.tmp
    }

    /// The temporary file onto the file's name: the new contents, whole.
    pub fn commit(mut self) -> anyhow::Result<()> {
        std::fs::rename(&self.tmp, &self.path).with_context(|| {
            format!(
                "{}: cannot write: renaming its new contents onto it",
                self.path.display()
            )
        })?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for Partial {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
        live().retain(|p| p != &self.tmp);
    }
}

/// Writes `path` through `fill`, which is given the temporary path to
/// write; `path` is replaced only when `fill` succeeds.
pub fn replace_with<T>(
    path: &Path,
    fill: impl FnOnce(&Path) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    let p = Partial::new(path);
    let v = fill(p.tmp())?;
    p.commit()?;
    Ok(v)
}

/// Writes `bytes` as the whole of `path` ([`replace_with`]).
pub fn replace(path: &Path, bytes: impl AsRef<[u8]>) -> anyhow::Result<()> {
    replace_with(path, |tmp| {
        std::fs::write(tmp, bytes.as_ref())
            .with_context(|| format!("{}: cannot write", path.display()))
    })
}

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

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("outpath-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn a_failed_write_leaves_the_old_file_and_no_partial_one() {
        let d = scratch("fail");
        let f = d.join("keep.csv");
        std::fs::write(&f, b"good").unwrap();
        let e = replace_with(&f, |tmp| -> anyhow::Result<()> {
            std::fs::write(tmp, b"half")?;
            bail!("refused part-way")
        })
        .unwrap_err();
        assert_eq!(format!("{e}"), "refused part-way");
        assert_eq!(std::fs::read(&f).unwrap(), b"good");
        let left: Vec<_> = std::fs::read_dir(&d).unwrap().collect();
        assert_eq!(left.len(), 1, "{left:?}");
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_completed_write_replaces_the_file_and_keeps_its_extension_while_written() {
        let d = scratch("ok");
        let f = d.join("plot.png");
        std::fs::write(&f, b"old").unwrap();
        replace_with(&f, |tmp| {
            assert_eq!(tmp.extension().unwrap(), "png");
            assert_eq!(tmp.parent(), f.parent());
            assert!(std::fs::read(&f).unwrap() == b"old");
            std::fs::write(tmp, b"new")?;
            Ok(())
        })
        .unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"new");
        replace(&f, "newer").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"newer");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_checked_new_file_is_not_left_behind() {
        let f = std::env::temp_dir().join(format!("outpath-new-{}", std::process::id()));
        let _ = std::fs::remove_file(&f);
        check_file("--csv", &f).unwrap();
        assert!(!f.exists());
    }
}
