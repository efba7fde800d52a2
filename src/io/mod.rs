//! Input and output of meshes and fields: gmsh `.msh` 4.1 in, VTU in.
//! (Run outputs — VTU/PVD pictures and probes — are written by [`crate::output`].)

mod msh;
mod vtu;

pub use msh::{read_msh, MshMesh};
pub use vtu::{read_vtu, VtuData};

/// An input file that cannot be read or understood.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    #[error("{file}: {message}")]
    File { file: String, message: String },
}

impl IoError {
    pub(crate) fn new(file: &std::path::Path, message: impl Into<String>) -> IoError {
        IoError::File {
            file: file.display().to_string(),
            message: message.into(),
        }
    }
}
