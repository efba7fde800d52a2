//! Scenes: the TOML case file (schema in DESIGN.md, "Case files") → [`Scene`].
//!
//! Reading a case is two steps: [`schema`] deserialises the file into serde
//! structs (unknown keys are errors, the key path is kept), and
//! [`schema::validate`] checks the values and builds the [`Scene`]. Every error
//! names the file, the key and the value. The scene becomes a model in
//! [`crate::setup`]; what a run will do is its [`crate::plan::Plan`]; the
//! memory a level needs is checked before anything large is allocated
//! ([`budget`]).

pub mod budget;
pub mod schema;

use crate::cut::PlanarPatch;
use crate::dynamics::DynamicOptions;
use crate::io::MeshNotes;
use crate::material::Material;
use crate::mesh::{box_mesh, ElementKind, TetMesh};
use crate::model::Formulation;
use crate::statics::StaticOptions;
use nalgebra::{Point3, Vector3};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{file}: cannot read: {source}")]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: TOML syntax error at line {line}: {message}")]
    Syntax {
        file: String,
        line: usize,
        message: String,
    },
    #[error("{file}: key `{key}`: {message}")]
    Key {
        file: String,
        key: String,
        message: String,
    },
    #[error("{file}: mesh `{mesh}`: {source}")]
    Mesh {
        file: String,
        mesh: String,
        #[source]
        source: crate::io::IoError,
    },
    #[error("{file}: mesh `{mesh}` is a Tet10 mesh but element = \"tet4\"")]
    MeshKind { file: String, mesh: String },
    #[error("{file}: level {level} does not exist (the case has {count} level{}: 0..={})", if *count == 1 { "" } else { "s" }, count.saturating_sub(1))]
    Level {
        file: String,
        level: usize,
        count: usize,
    },
    #[error("{file}: {source}")]
    Cut {
        file: String,
        #[source]
        source: crate::cut::CutError,
    },
    #[error("{file}: {source}")]
    Model {
        file: String,
        #[source]
        source: crate::model::ModelError,
    },
    #[error("{file}: a static scene has a part that floats free: {part}")]
    FloatingPart { file: String, part: String },
    #[error("{file}: key `{key}`: {source}")]
    Surface {
        file: String,
        key: String,
        #[source]
        source: crate::surface::SurfaceError,
    },
    #[error("{file}: {source}")]
    Blade {
        file: String,
        #[source]
        source: crate::blade::BladeError,
    },
    #[error("{file}: key `{key}`: {what} is not supported in this build")]
    Unsupported {
        file: String,
        key: String,
        what: String,
    },
    #[error("{file}: key `{key}`: {what} needs at least {} of memory, more than {} (75 % of this machine's {})", budget::gib(*needed), budget::gib(*allowed), budget::gib(*total))]
    Memory {
        file: String,
        key: String,
        what: String,
        needed: f64,
        allowed: f64,
        total: f64,
    },
}

/// Where the body's mesh comes from.
#[derive(Debug, Clone)]
pub enum BodyGeometry {
    Box {
        min: Point3<f64>,
        max: Point3<f64>,
        levels: Vec<[usize; 3]>,
    },
    Meshes(Vec<PathBuf>),
}

/// A Dirichlet condition on the nodes inside a closed box.
#[derive(Debug, Clone)]
pub struct Fix {
    pub min: [f64; 3],
    pub max: [f64; 3],
    pub displacement: [f64; 3],
    pub components: [bool; 3],
}

/// A traction on the boundary faces whose vertices all lie in a closed box.
#[derive(Debug, Clone)]
pub struct TractionSpec {
    pub min: [f64; 3],
    pub max: [f64; 3],
    pub traction: [f64; 3],
}

/// The surface of one `[[cut]]`.
#[derive(Debug, Clone)]
pub enum CutGeometry {
    /// `origin`, `u`, `v`: origin + s u + t v, s, t ∈ [0, 1].
    Patch(PlanarPatch),
    /// `surface`: a triangulated surface (STL or gmsh `.msh`), the path
    /// resolved against the case file's folder; the file exists.
    Surface(PathBuf),
    /// `blade`: the cutting edge [a, b] at increasing times, linear in
    /// between (`travel` + `start` + `end` is normalised to the two keyframes
    /// (start, [a, b]) and (end, [a + travel, b + travel]), and `travel`
    /// kept as given: the completed sweep is then the patch origin = a,
    /// u = b − a, v = travel to the last bit, not v = (a + travel) − a).
    Blade {
        keyframes: Vec<(f64, [Point3<f64>; 2])>,
        travel: Option<Vector3<f64>>,
    },
}

/// How a crack front inside elements is treated (`front`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FrontMode {
    /// Branch-function tip enrichment.
    Tip,
    /// The seed's: the cut extended to the faces of the elements it ends in.
    Extend,
}

/// One validated `[[cut]]`.
#[derive(Debug, Clone)]
pub struct CutSpec {
    pub geometry: CutGeometry,
    /// Nodes closer than `snap` × the local element size lie on the cut
    /// (default [`crate::cut::DEFAULT_SNAP`]).
    pub snap: f64,
    /// `front`, as given; `None`: not given (DESIGN.md's default is "tip").
    pub front: Option<FrontMode>,
    /// `tip_radius` (m, > 0): tip-enrich every node within it of the front.
    pub tip_radius: Option<f64>,
    /// `event_travel` (m, > 0; blades only): a cut event once the blade's
    /// edge has moved this far since the last one ([`crate::blade::event_due`]).
    pub event_travel: Option<f64>,
    /// The blending elements' treatment; `None` (what a case file gives):
    /// [`crate::cut::Blending::for_cut`]. Not a case key: examples set it to
    /// compare the ramp with standard X-FEM (`examples/error_map.rs`).
    pub blending: Option<crate::cut::Blending>,
}

#[derive(Debug, Clone)]
pub enum Analysis {
    Static(StaticOptions),
    Dynamic {
        options: DynamicOptions,
        output_every: usize,
    },
}

/// A parsed, validated case file.
#[derive(Debug, Clone)]
pub struct Scene {
    pub file: PathBuf,
    pub name: String,
    pub description: String,
    pub geometry: BodyGeometry,
    pub element: ElementKind,
    pub material: Material,
    pub cuts: Vec<CutSpec>,
    pub fixes: Vec<Fix>,
    pub tractions: Vec<TractionSpec>,
    pub gravity: Option<Vector3<f64>>,
    pub formulation: Formulation,
    pub analysis: Analysis,
    pub probes: Vec<Point3<f64>>,
    /// Where each of `probes` was given: its `[[probe]]` table and its
    /// place in that table's `points` (for errors naming the key).
    pub probe_keys: Vec<(usize, usize)>,
}

impl Scene {
    /// The `[[probe]]` table of probe `index` and its place in that table's
    /// `points` (a scene built without keys: table 0, the index itself).
    pub fn probe_key(&self, index: usize) -> (usize, usize) {
        self.probe_keys.get(index).copied().unwrap_or((0, index))
    }

    /// Reads and validates a case file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Read {
            file: path.display().to_string(),
            source,
        })?;
        Scene::parse(&text, path)
    }

    /// Parses and validates case-file text; `path` names it in errors and
    /// anchors relative mesh and surface paths.
    pub fn parse(text: &str, path: &Path) -> Result<Scene, SceneError> {
        let case = schema::deserialize(text, path)?;
        schema::validate(case, path)
    }

    pub(crate) fn file(&self) -> String {
        self.file.display().to_string()
    }

    pub fn n_levels(&self) -> usize {
        match &self.geometry {
            BodyGeometry::Box { levels, .. } => levels.len(),
            BodyGeometry::Meshes(m) => m.len(),
        }
    }

    /// Whether a `[[cut]]` is a blade.
    pub fn has_blade(&self) -> bool {
        self.cuts
            .iter()
            .any(|c| matches!(c.geometry, CutGeometry::Blade { .. }))
    }

    pub fn is_dynamic(&self) -> bool {
        matches!(self.analysis, Analysis::Dynamic { .. })
    }

    /// The patch of each planar cut (the other kinds are skipped).
    pub fn patches(&self) -> impl Iterator<Item = &PlanarPatch> {
        self.cuts.iter().filter_map(|c| match &c.geometry {
            CutGeometry::Patch(p) => Some(p),
            _ => None,
        })
    }

    fn check_level(&self, level: usize) -> Result<(), SceneError> {
        let count = self.n_levels();
        if level >= count {
            return Err(SceneError::Level {
                file: self.file(),
                level,
                count,
            });
        }
        Ok(())
    }

    /// The mesh of a level, in the scene's element kind. A box level is
    /// refused before meshing when the scene would not fit in memory
    /// ([`Scene::check_memory`]).
    pub fn mesh(&self, level: usize) -> Result<TetMesh, SceneError> {
        self.mesh_noted(level).map(|(mesh, _)| mesh)
    }

    /// [`Scene::mesh`] with what its file's reader changed.
    pub fn mesh_noted(&self, level: usize) -> Result<(TetMesh, MeshNotes), SceneError> {
        self.check_level(level)?;
        self.check_memory(level)?;
        let (mesh, mut notes) = match &self.geometry {
            BodyGeometry::Box { min, max, levels } => {
                (box_mesh(*min, *max, levels[level]), MeshNotes::default())
            }
            BodyGeometry::Meshes(files) => self.read_mesh_noted(&files[level])?,
        };
        let mesh = match self.element {
            ElementKind::Tet4 if mesh.kind == ElementKind::Tet10 => {
                return Err(SceneError::MeshKind {
                    file: self.file(),
                    mesh: format!("level {level}"),
                })
            }
            ElementKind::Tet4 => mesh,
            ElementKind::Tet10 => {
                notes.promoted = matches!(self.geometry, BodyGeometry::Meshes(_))
                    && mesh.kind == ElementKind::Tet4;
                mesh.to_tet10()
            }
        };
        Ok((mesh, notes))
    }

    /// Reads a gmsh mesh file.
    pub fn read_mesh(&self, path: &Path) -> Result<TetMesh, SceneError> {
        self.read_mesh_noted(path).map(|(mesh, _)| mesh)
    }

    /// [`Scene::read_mesh`] with what the reader changed: Tet10 mid-nodes
    /// moved onto their edges ([`crate::mesh::TetMesh::straighten_edges`]),
    /// nodes no tetrahedron uses left out.
    pub fn read_mesh_noted(&self, path: &Path) -> Result<(TetMesh, MeshNotes), SceneError> {
        crate::io::read_msh(path)
            .map(|m| (m.mesh, m.notes))
            .map_err(|source| SceneError::Mesh {
                file: self.file(),
                mesh: path.display().to_string(),
                source,
            })
    }
}
