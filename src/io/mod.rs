//! Files in and out: gmsh `.msh` 4.1 meshes in, VTU / PVD pictures and probe
//! CSVs out (and back in), every output written whole or not at all.
//!
//! - [`msh`]: [`read_msh`] — tetrahedra, node-tag map, physical groups.
//! - [`vtu`]: [`write_vtu`] (base64 binary), [`write_vtu_ascii`], [`read_vtu`]
//!   (ours and meshio's), [`write_pvd`] / [`read_pvd`] for time series.
//! - [`csv`]: [`write_probes_csv`] / [`read_probes_csv`].
//! - [`write_atomic`]: the temp-file-and-rename helper under all of them.
//!
//! Errors are [`IoError`]s naming the file; no input file makes these readers panic.

pub mod csv;
pub mod msh;
pub mod vtu;

pub use csv::{read_probes_csv, write_probes_csv};
pub use msh::{parse_msh, read_msh, MeshNotes, MshMesh, PhysicalName};
pub use vtu::{read_pvd, read_vtu, write_pvd, write_vtu, write_vtu_ascii, VtuData};

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A file that cannot be read, understood or written.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The operating system refused: missing file, permissions, full disk.
    #[error("{}: cannot {action}: {source}", file.display())]
    Os {
        file: PathBuf,
        action: &'static str,
        #[source]
        source: std::io::Error,
    },
    /// The content is malformed or inconsistent (or, for a writer, the data given is).
    #[error("{}: {message}", file.display())]
    Invalid { file: PathBuf, message: String },
    /// The arrays of a VTU grid do not fit together (read, or given to a writer).
    #[error("{}: {source}", file.display())]
    Grid {
        file: PathBuf,
        #[source]
        source: Box<vtu::GridError>,
    },
    /// Well-formed, but uses a feature we do not read (compression, hexahedra, …).
    #[error("{}: unsupported: {message}", file.display())]
    Unsupported { file: PathBuf, message: String },
}

impl IoError {
    /// Malformed or inconsistent content of `file`.
    pub fn invalid(file: &Path, message: impl Into<String>) -> IoError {
        IoError::Invalid {
            file: file.to_path_buf(),
            message: message.into(),
        }
    }

    /// An inconsistent VTU grid in (or for) `file`.
    pub fn grid(file: &Path, source: vtu::GridError) -> IoError {
        IoError::Grid {
            file: file.to_path_buf(),
            source: Box::new(source),
        }
    }

    /// A feature of `file` that we do not read.
    pub fn unsupported(file: &Path, message: impl Into<String>) -> IoError {
        IoError::Unsupported {
            file: file.to_path_buf(),
            message: message.into(),
        }
    }

    /// An operating-system error while doing `action` ("read", "write", …) on `file`.
    pub fn os(file: &Path, action: &'static str, source: std::io::Error) -> IoError {
        IoError::Os {
            file: file.to_path_buf(),
            action,
            source,
        }
    }

    /// Same as [`IoError::invalid`] (kept for existing callers).
    pub(crate) fn new(file: &Path, message: impl Into<String>) -> IoError {
        IoError::invalid(file, message)
    }

    /// The file the error is about.
    pub fn file(&self) -> &Path {
        match self {
            IoError::Os { file, .. }
            | IoError::Invalid { file, .. }
            | IoError::Grid { file, .. }
            | IoError::Unsupported { file, .. } => file,
        }
    }
}

/// Writes `path` whole or not at all: `write` fills a temporary file in the
/// same directory (buffered), which is flushed, synced and renamed over
/// `path`. On any error the temporary file is removed and `path` is left as
/// it was. The directory must exist.
///
/// ```no_run
/// # use std::io::Write;
/// xfem_cut::io::write_atomic(std::path::Path::new("out/summary.json"), |w| {
///     writeln!(w, "{{\"steps\": 200}}")
/// })?;
/// # Ok::<(), xfem_cut::io::IoError>(())
/// ```
pub fn write_atomic<F>(path: &Path, write: F) -> Result<(), IoError>
where
    F: FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
{
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .ok_or_else(|| IoError::invalid(path, "is not a file path"))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let tmp = dir.join(format!(
        ".{}.{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let file = File::options()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(|e| IoError::os(path, "create a temporary file for", e))?;
    let result = (|| {
        let mut w = BufWriter::with_capacity(1 << 20, file);
        write(&mut w)?;
        w.flush()?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()
    })()
    .map_err(|e| IoError::os(path, "write", e))
    .and_then(|()| std::fs::rename(&tmp, path).map_err(|e| IoError::os(path, "replace", e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Reads a whole file, naming it in the error.
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, IoError> {
    std::fs::read(path).map_err(|e| IoError::os(path, "read", e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn atomic_write_replaces_whole_or_leaves_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        write_atomic(&p, |w| w.write_all(b"first")).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "first");

        // A writer that fails halfway leaves the old content and no temporary file.
        let err = write_atomic(&p, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("a.txt"), "{err}");
        assert!(err.to_string().contains("disk full"), "{err}");
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "first");
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1);

        write_atomic(&p, |w| w.write_all(b"second")).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "second");
    }

    #[test]
    fn atomic_write_into_missing_directory_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/dir/a.txt");
        let err = write_atomic(&p, |w| w.write_all(b"x")).unwrap_err();
        assert!(matches!(err, IoError::Os { .. }));
        assert_eq!(err.file(), p);
    }
}
