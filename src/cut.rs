//! Cut geometry: level sets, classification of tetrahedra, sub-tetrahedra.
//! (Interface stub; the full module is being written.)
use nalgebra::Point3;

pub struct SubTet {
    pub vertices: [Point3<f64>; 4],
    pub side: i8,
}
pub enum ElementCut {
    Uncut,
    Touched {
        side: i8,
    },
    Cut {
        sub_tets: Vec<SubTet>,
        partial: bool,
    },
}
pub struct CutSetup {
    pub phi: Vec<f64>,
    pub node_side: Vec<i8>,
    pub enriched: Vec<Option<usize>>,
    pub n_enriched: usize,
    pub elements: Vec<ElementCut>,
}
pub fn psi(side: i8, node_side: i8) -> f64 {
    f64::from(side - node_side) / 2.0
}
use nalgebra::Vector3;
pub const DEFAULT_SNAP: f64 = 1e-4;
pub struct PlanarPatch {
    pub origin: Point3<f64>,
    pub u: Vector3<f64>,
    pub v: Vector3<f64>,
}
pub trait CutSurface: Send + Sync {}
impl CutSurface for PlanarPatch {}
#[derive(Debug, thiserror::Error)]
#[error("cutting not implemented yet")]
pub struct CutError;
pub fn setup_cut(
    _mesh: &crate::mesh::TetMesh,
    _surfaces: &[&dyn CutSurface],
    _snap: f64,
) -> Result<CutSetup, CutError> {
    Err(CutError)
}
