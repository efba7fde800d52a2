//! xfem-cut: surgical cutting of soft tissue.
//!
//! Corotational linear FEM on Tet4/Tet10, implicit Newmark time stepping, and
//! cuts by X-FEM with shifted Heaviside enrichment, after the thesis in
//! `../shared/seed` (equation numbers in doc comments refer to it).
//!
//! Once vs every step: [`model::Model`] is built once from a scene (element
//! data, enrichment, DOF numbering, sparsity pattern, loads, mass) and
//! [`solve::Cholesky`] holds the symbolic factorisation; [`statics`] and
//! [`dynamics`] borrow them and allocate nothing per step.

// Index loops read like the formulas in numeric kernels.
#![allow(clippy::needless_range_loop)]

pub mod assembly;
pub mod blade;
pub mod corotation;
pub mod cut;
pub mod dynamics;
pub mod element;
pub mod front;
pub mod io;
pub mod kernel;
pub mod locate;
pub mod mass;
pub mod material;
pub mod mesh;
pub mod model;
pub mod output;
pub mod plan;
pub mod quadrature;
pub mod run;
pub mod scene;
pub mod setup;
pub mod solve;
pub mod statics;
pub mod study;
pub mod surface;
