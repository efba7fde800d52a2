//! The verification and benchmark harness, apart from the solver: the
//! convergence study against the FEniCSx references, the stability stress
//! suite and the report built from their CSVs.
//!
//! - [`converge`]: every variant of a case at every level, L2 error against the reference.
//! - [`reference`]: reading the FEniCSx P2 reference solutions (`refs/out`).
//! - [`verify`]: L2 errors between fields, observed orders.
//! - [`stress`]: the stress suite behind `xfem-cut stress`.
//! - [`report`]: `reports/README.md` and its plots.

pub mod converge;
pub mod reference;
pub mod report;
pub mod stress;
pub mod verify;
