//! The memory a scene needs at one level, estimated before anything large is
//! allocated, so that a case that cannot fit is refused with a one-line error
//! naming the key (`body.levels`, `body.mesh`, `analysis.steps`, `analysis.load_steps`) instead of
//! aborting on allocation or meeting the OOM killer.
//!
//! The estimate is a lower bound: mesh, element data, the stiffness pattern
//! (matrix, effective matrix and a factor at least as large), the state
//! vectors, and for a dynamic run the frames kept for output and one record
//! per step. It ignores enrichment and fill-in, so a refused scene surely does
//! not fit; a scene that passes may still be too large for the factorisation.

use super::{Analysis, BodyGeometry, Scene, SceneError};
use crate::mesh::{ElementKind, TetMesh};

/// Share of the machine's memory a scene may take.
pub const SHARE: f64 = 0.75;

/// A lower bound of the bytes a run needs, split by what drives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Mesh, element data, matrices and state: grows with the mesh.
    pub model: f64,
    /// Frames kept and per-step records: grows with `steps`.
    pub history: f64,
    pub nodes: f64,
    pub elements: f64,
}

impl Estimate {
    pub fn total(&self) -> f64 {
        self.model + self.history
    }
}

/// Lower bound for a mesh of `nodes` nodes and `elements` elements of `kind`.
pub fn estimate(kind: ElementKind, nodes: f64, elements: f64, analysis: &Analysis) -> Estimate {
    let dofs = 3.0 * nodes;
    // Element data per element (gradients and weights per integration
    // point, rotation) and stored entries of the symmetric pattern per node
    // (lower triangle of 3×3 blocks over the node's neighbours).
    let (per_element, entries_per_node) = match kind {
        ElementKind::Tet4 => (4.0 * 8.0 + 200.0, 60.0),
        ElementKind::Tet10 => (10.0 * 8.0 + 1000.0, 120.0),
    };
    let mesh = 24.0 * nodes + per_element * elements;
    // Pattern indices (4 B) and three value arrays (K, K_eff, factor ≥ K).
    let matrices = entries_per_node * nodes * (4.0 + 3.0 * 8.0);
    let state = 12.0 * dofs * 8.0;
    let history = match analysis {
        Analysis::Static(o) => 8.0 * o.load_steps as f64,
        Analysis::Dynamic {
            options,
            output_every,
        } => {
            let steps = options.steps as f64;
            let frames = (steps / *output_every as f64).floor() + 2.0;
            frames * (dofs * 8.0 + 48.0) + 8.0 * steps
        }
    };
    Estimate {
        model: mesh + matrices + state,
        history,
        nodes,
        elements,
    }
}

/// Physical memory of this machine (bytes), the smaller of `/proc/meminfo`'s
/// MemTotal and a cgroup v2 limit; `None` where neither can be read.
pub fn total_memory() -> Option<f64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok().and_then(|s| {
        s.lines()
            .find_map(|l| l.strip_prefix("MemTotal:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
            .map(|kb| kb * 1024.0)
    });
    let cgroup = std::fs::read_to_string("/sys/fs/cgroup/memory.max")
        .ok()
        .and_then(|s| s.trim().parse::<f64>().ok());
    match (meminfo, cgroup) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Bytes as "12.3 GiB".
pub fn gib(bytes: f64) -> String {
    let g = bytes / f64::from(1u32 << 30);
    if g >= 1024.0 {
        format!("{:.1} TiB", g / 1024.0)
    } else if g >= 0.1 {
        format!("{g:.1} GiB")
    } else {
        format!("{:.1} MiB", bytes / f64::from(1u32 << 20))
    }
}

impl Scene {
    /// The estimate for box level `level` from its divisions alone (before
    /// meshing); `None` for a mesh-file level or a level that does not exist.
    pub fn estimate(&self, level: usize) -> Option<Estimate> {
        let BodyGeometry::Box { levels, .. } = &self.geometry else {
            return None;
        };
        let [nx, ny, nz] = levels.get(level)?.map(|n| n as f64);
        let hexes = nx * ny * nz;
        let corners = (nx + 1.0) * (ny + 1.0) * (nz + 1.0);
        // Six tets per hex; a Tet10 mesh adds at least the seven edges of each hex.
        let nodes = match self.element {
            ElementKind::Tet4 => corners,
            ElementKind::Tet10 => corners + 7.0 * hexes,
        };
        Some(estimate(self.element, nodes, 6.0 * hexes, &self.analysis))
    }

    /// Refuses box level `level` when its estimate exceeds [`SHARE`] of this
    /// machine's memory (mesh-file levels are checked once read, in `build`).
    pub fn check_memory(&self, level: usize) -> Result<(), SceneError> {
        match self.estimate(level) {
            Some(e) => self.check_estimate(&e, &format!("level {level}"), "body.levels"),
            None => Ok(()),
        }
    }

    /// Refuses a model of `mesh` that would not fit (see [`Scene::check_memory`]).
    pub fn check_mesh_memory(&self, mesh: &TetMesh) -> Result<(), SceneError> {
        let e = estimate(
            mesh.kind,
            mesh.n_nodes() as f64,
            mesh.n_elements() as f64,
            &self.analysis,
        );
        let key = match self.geometry {
            BodyGeometry::Box { .. } => "body.levels",
            BodyGeometry::Meshes(_) => "body.mesh",
        };
        self.check_estimate(&e, "the mesh", key)
    }

    fn check_estimate(&self, e: &Estimate, what: &str, mesh_key: &str) -> Result<(), SceneError> {
        let Some(total) = total_memory() else {
            return Ok(());
        };
        let allowed = SHARE * total;
        if e.total() <= allowed {
            return Ok(());
        }
        let (key, what) = match &self.analysis {
            Analysis::Static(o) if e.history > e.model => (
                "analysis.load_steps".to_string(),
                format!("{} load steps", o.load_steps),
            ),
            Analysis::Dynamic { options, .. } if e.history > e.model => (
                "analysis.steps".to_string(),
                format!(
                    "{} steps ({} frames kept)",
                    options.steps,
                    crate::plan::frames_kept(&self.analysis)
                ),
            ),
            _ => (
                mesh_key.to_string(),
                format!(
                    "{what} ({:.3e} elements, {:.3e} nodes)",
                    e.elements, e.nodes
                ),
            ),
        };
        Err(SceneError::Memory {
            file: self.file(),
            key,
            what,
            needed: e.total(),
            allowed,
            total,
        })
    }
}
