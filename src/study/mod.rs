//! The verification and benchmark harness, apart from the solver: the
//! convergence study against the FEniCSx references, the stability stress
//! suite and the report built from their CSVs.
//!
//! - [`converge`]: every variant of a case at every level, L2 error against the reference.
//! - [`reference`]: reading the FEniCSx P2 reference solutions (`refs/out`).
//! - [`verify`]: L2 errors between fields, observed orders.
//! - [`exact`]: code verification with exact solutions (a manufactured jump across a through-cut, the near-front Williams field).
//! - [`stress`]: the stress suite behind `xfem-cut stress`.
//! - [`fixtures`]: the clamped beam and the fragment spin that tests, benches and examples share.
//! - [`report`]: `reports/README.md` and its plots.
//! - [`sweep`]: a progressive cut's cost as a time series (CSV and SVG).
//! - [`ramp`]: what the ramp of corrected X-FEM buys on the beam against R / h.

pub mod converge;
pub mod exact;
pub mod fixtures;
pub mod one_mesh;
pub mod ramp;
pub mod reference;
pub mod report;
pub mod stress;
pub mod sweep;
pub mod verify;

use crate::cut::CutError;
use crate::dynamics::DynamicError;
use crate::io::IoError;
use crate::model::ModelError;
use crate::run::RunError;
use crate::scene::SceneError;
use crate::solve::SolveError;
use crate::statics::StaticError;

/// Why a study run could not be done; the causes keep their types.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Run(#[from] RunError),
    #[error(transparent)]
    Io(#[from] IoError),
    #[error(transparent)]
    Solve(#[from] SolveError),
    #[error(transparent)]
    Static(#[from] StaticError),
    #[error(transparent)]
    Dynamic(#[from] DynamicError),
    #[error(transparent)]
    Verify(#[from] verify::VerifyError),
    #[error(transparent)]
    SameMesh(#[from] reference::SameMeshError),
    #[error(transparent)]
    Cut(#[from] CutError),
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A run of the study failed: which (case, variant, level), and why.
    #[error("{run}: {source}")]
    In {
        run: String,
        #[source]
        source: Box<StudyError>,
    },
    /// A plot of the report could not be drawn or written.
    #[error("{}: cannot draw the plot: {source}", path.display())]
    Plot {
        path: std::path::PathBuf,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The study's own precondition is not met (no reference, no cut, …).
    #[error("{0}")]
    Precondition(String),
}

impl StudyError {
    /// This error, as the failure of `run`.
    pub fn during(self, run: impl Into<String>) -> StudyError {
        StudyError::In {
            run: run.into(),
            source: Box::new(self),
        }
    }
}
