//! Atomic whole-file writes: temporary file beside the target, then rename.

use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::Error;

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// The temporary path [`write_atomic`] writes before renaming onto `path`:
/// `.{filename}.tmp-{pid}-{counter}` in the same folder (unique per call within a process).
pub fn atomic_temp_path(path: &Path) -> PathBuf {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let count = COUNTER.fetch_add(1, Ordering::Relaxed);
    let temp_name = format!(".{name}.tmp-{}-{count}", std::process::id());
    match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent.join(temp_name),
        _ => PathBuf::from(temp_name),
    }
}

/// Writes `bytes` to `path` atomically (temporary file in the same folder, flushed and synced,
/// then renamed over the target). On failure the temporary is removed and the error names `path`.
/// An existing directory, device, pipe or socket at `path` is refused, never replaced.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    if path.file_name().is_none() {
        return Err(Error::Format {
            path: path.to_path_buf(),
            message: "not a file path (no file name)".into(),
        });
    }
    // Renaming over a device, pipe or socket would silently replace it (e.g. `/dev/stdout`).
    if let Ok(meta) = std::fs::metadata(path) {
        let message = if meta.is_dir() {
            "cannot write: the target is a directory"
        } else if !meta.is_file() {
            "cannot write: the target is not a regular file (device, pipe or socket); refusing to replace it"
        } else {
            ""
        };
        if !message.is_empty() {
            return Err(Error::Format { path: path.to_path_buf(), message: message.into() });
        }
    }
    let temp = atomic_temp_path(path);
    let io_err = |source: std::io::Error| Error::Io { path: path.to_path_buf(), source };
    let mut file = OpenOptions::new().write(true).create_new(true).open(&temp).map_err(io_err)?;
    let written = file.write_all(bytes).and_then(|()| file.flush()).and_then(|()| file.sync_all());
    drop(file);
    if let Err(source) = written.and_then(|()| std::fs::rename(&temp, path)) {
        let _ = std::fs::remove_file(&temp);
        return Err(io_err(source));
    }
    Ok(())
}
