//! Whole files or none: every output is written to `<file>.tmp` beside it and renamed over
//! `<file>` once complete, so that a run killed at any moment leaves each output complete or
//! absent (a `.tmp` left behind by a killed run is partial; the next run into the folder
//! removes those of the kinds it writes).

use std::ffi::OsString;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// `<path>.tmp`, next to `path` so that the rename stays on one file system.
pub(crate) fn tmp_path(path: &Path) -> PathBuf {
    let mut s: OsString = path.as_os_str().to_owned();
    s.push(".tmp");
    PathBuf::from(s)
}

/// Writes through `f` into `<path>.tmp`, then renames it to `path`. With `sync` the data
/// reach the disk before the rename (checkpoints: they must survive a crash of the machine
/// too); without, the rename still keeps readers and killed runs from partial files.
pub(crate) fn write_atomic(
    path: &Path,
    sync: bool,
    f: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> io::Result<()> {
    let tmp = tmp_path(path);
    let result = (|| {
        let mut w = BufWriter::new(File::create(&tmp)?);
        f(&mut w)?;
        w.flush()?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        if sync {
            file.sync_all()?;
        }
        drop(file);
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        // Best effort: do not leave a stale temporary behind.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Removes the temporaries a killed run may have left in `dir`: the files whose names end with
/// one of `endings` (e.g. `.vtu.tmp`; best effort, a missing folder is fine). Only the
/// run's own kinds: a `--rerun` recording under way in the same folder is left alone.
pub(crate) fn remove_temporaries(dir: &Path, endings: &[&str]) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else {
            continue;
        };
        if endings.iter().any(|e| name.ends_with(e)) && entry.path().is_file() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tmp_is_sibling() {
        assert_eq!(
            tmp_path(Path::new("out/a.vtu")),
            PathBuf::from("out/a.vtu.tmp")
        );
    }

    #[test]
    fn whole_file_or_none() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        write_atomic(&path, true, |w| w.write_all(b"complete")).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"complete");
        // A writer that fails half-way leaves the old file and no temporary.
        let failed = write_atomic(&path, false, |w| {
            w.write_all(b"part")?;
            Err(io::Error::other("disk full"))
        });
        assert!(failed.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"complete");
        assert!(!tmp_path(&path).exists());
        std::fs::write(tmp_path(&path), b"stale").unwrap();
        let other = dir.path().join("run.rrd.tmp");
        std::fs::write(&other, b"a recording under way").unwrap();
        remove_temporaries(dir.path(), &[".txt.tmp"]);
        assert!(!tmp_path(&path).exists());
        assert!(path.exists());
        assert!(other.exists());
    }
}
