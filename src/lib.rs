//! xfem-cut: surgical cutting of soft tissue.
//!
//! Corotational linear FEM on Tet4/Tet10, implicit Newmark time stepping, and
//! cuts by X-FEM with shifted Heaviside enrichment, after the thesis in
//! `../shared/seed` (equation numbers in doc comments refer to it).
//!
//! Once vs every step: [`model::Model`] is built once from a scene (element
//! data, enrichment, sparsity pattern, symbolic factorisation); the solvers in
//! [`static_solve`] and [`dynamics`] borrow it and allocate nothing per step.

pub mod cut;
pub mod io;
pub mod mesh;
pub mod reference;
