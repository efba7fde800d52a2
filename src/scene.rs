//! Scenes: the TOML case file (schema in DESIGN.md) → [`Scene`] → [`Plan`] and [`Model`].
//!
//! Every error names the file, the key and the value; unknown keys are errors.

use crate::cut::{CutSetup, PlanarPatch};
use crate::dynamics::{DynamicOptions, LinearSolver, MassKind};
use crate::material::Material;
use crate::mesh::{box_mesh, ElementKind, TetMesh};
use crate::model::{Formulation, Model, ModelError, ModelInput, Traction};
use crate::statics::StaticOptions;
use nalgebra::{Point3, Vector3};
use std::collections::BTreeSet;
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;
use toml::{Table, Value};

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{file}: cannot read: {message}")]
    Read { file: String, message: String },
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
    #[error("{file}: mesh `{mesh}`: {message}")]
    Mesh {
        file: String,
        mesh: String,
        message: String,
    },
    #[error("{file}: level {level} does not exist (the case has {count} levels: 0..{})", count.saturating_sub(1))]
    Level {
        file: String,
        level: usize,
        count: usize,
    },
    #[error("{file}: {message}")]
    Model { file: String, message: String },
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

#[derive(Debug, Clone)]
pub struct CutSpec {
    pub origin: Point3<f64>,
    pub u: Vector3<f64>,
    pub v: Vector3<f64>,
    pub snap: Option<f64>,
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
}

/// Reads one table strictly: every key must be consumed, else an error names it.
struct Reader<'a> {
    file: &'a str,
    path: String,
    table: &'a Table,
    used: BTreeSet<String>,
}

impl<'a> Reader<'a> {
    fn new(file: &'a str, path: &str, table: &'a Table) -> Self {
        Reader {
            file,
            path: path.to_string(),
            table,
            used: BTreeSet::new(),
        }
    }

    fn key(&self, k: &str) -> String {
        if self.path.is_empty() {
            k.to_string()
        } else {
            format!("{}.{}", self.path, k)
        }
    }

    fn err(&self, k: &str, message: impl Into<String>) -> SceneError {
        SceneError::Key {
            file: self.file.to_string(),
            key: self.key(k),
            message: message.into(),
        }
    }

    fn get(&mut self, k: &str) -> Option<&'a Value> {
        self.used.insert(k.to_string());
        self.table.get(k)
    }

    fn req(&mut self, k: &str) -> Result<&'a Value, SceneError> {
        self.get(k)
            .ok_or_else(|| self.err(k, "missing required key"))
    }

    fn num(&self, k: &str, v: &Value, allow_inf: bool) -> Result<f64, SceneError> {
        let x = match v {
            Value::Float(x) => *x,
            Value::Integer(i) => *i as f64,
            other => return Err(self.err(k, format!("expected a number, got {other}"))),
        };
        if x.is_nan() || (!allow_inf && x.is_infinite()) {
            return Err(self.err(k, format!("must be a finite number, got {x}")));
        }
        Ok(x)
    }

    fn f64(&mut self, k: &str) -> Result<f64, SceneError> {
        let v = self.req(k)?;
        self.num(k, v, false)
    }

    fn opt_f64(&mut self, k: &str) -> Result<Option<f64>, SceneError> {
        match self.get(k) {
            Some(v) => self.num(k, v, false).map(Some),
            None => Ok(None),
        }
    }

    fn positive(&mut self, k: &str) -> Result<f64, SceneError> {
        let x = self.f64(k)?;
        if x <= 0.0 {
            return Err(self.err(k, format!("must be positive, got {x}")));
        }
        Ok(x)
    }

    fn vec3_of(&self, k: &str, v: &Value, allow_inf: bool) -> Result<[f64; 3], SceneError> {
        let arr = v
            .as_array()
            .filter(|a| a.len() == 3)
            .ok_or_else(|| self.err(k, format!("expected 3 numbers, got {v}")))?;
        let mut out = [0.0; 3];
        for (o, x) in out.iter_mut().zip(arr) {
            *o = self.num(k, x, allow_inf)?;
        }
        Ok(out)
    }

    fn vec3(&mut self, k: &str, allow_inf: bool) -> Result<[f64; 3], SceneError> {
        let v = self.req(k)?;
        self.vec3_of(k, v, allow_inf)
    }

    fn string(&mut self, k: &str) -> Result<Option<&'a str>, SceneError> {
        match self.get(k) {
            Some(Value::String(s)) => Ok(Some(s.as_str())),
            Some(other) => Err(self.err(k, format!("expected a string, got {other}"))),
            None => Ok(None),
        }
    }

    fn usize(&mut self, k: &str) -> Result<Option<usize>, SceneError> {
        match self.get(k) {
            Some(Value::Integer(i)) if *i > 0 => Ok(Some(*i as usize)),
            Some(other) => Err(self.err(k, format!("expected a positive integer, got {other}"))),
            None => Ok(None),
        }
    }

    fn table(&mut self, k: &str) -> Result<Option<&'a Table>, SceneError> {
        match self.get(k) {
            Some(Value::Table(t)) => Ok(Some(t)),
            Some(other) => Err(self.err(k, format!("expected a table, got {other}"))),
            None => Ok(None),
        }
    }

    fn tables(&mut self, k: &str) -> Result<Vec<&'a Table>, SceneError> {
        match self.get(k) {
            Some(Value::Array(a)) => a
                .iter()
                .map(|v| {
                    v.as_table()
                        .ok_or_else(|| self.err(k, "expected an array of tables ([[...]])"))
                })
                .collect(),
            Some(other) => Err(self.err(
                k,
                format!("expected an array of tables ([[{k}]]), got {other}"),
            )),
            None => Ok(Vec::new()),
        }
    }

    fn finish(self) -> Result<(), SceneError> {
        for k in self.table.keys() {
            if !self.used.contains(k) {
                return Err(self.err(k, "unknown key"));
            }
        }
        Ok(())
    }
}

fn sub<'a>(file: &'a str, parent: &Reader<'_>, k: &str, t: &'a Table) -> Reader<'a> {
    Reader::new(file, &parent.key(k), t)
}

impl Scene {
    /// Reads and validates a case file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::Read {
            file: file.clone(),
            message: e.to_string(),
        })?;
        Scene::parse(&text, path)
    }

    /// Parses case-file text; `path` names it in errors and anchors relative mesh paths.
    pub fn parse(text: &str, path: &Path) -> Result<Scene, SceneError> {
        let file = path.display().to_string();
        let f = file.as_str();
        let root: Table = text.parse().map_err(|e: toml::de::Error| {
            let line = e.span().map_or(0, |s| {
                text[..s.start.min(text.len())].lines().count().max(1)
            });
            SceneError::Syntax {
                file: file.clone(),
                line,
                message: e.message().replace('\n', " "),
            }
        })?;
        let mut r = Reader::new(f, "", &root);
        let name = r
            .string("name")?
            .ok_or_else(|| r.err("name", "missing required key"))?
            .to_string();
        let description = r.string("description")?.unwrap_or("").to_string();

        // [body]
        let body_t = r
            .table("body")?
            .ok_or_else(|| r.err("body", "missing required table [body]"))?;
        let mut b = sub(f, &r, "body", body_t);
        let element = match b.string("element")?.unwrap_or("tet4") {
            "tet4" => ElementKind::Tet4,
            "tet10" => ElementKind::Tet10,
            other => {
                return Err(b.err(
                    "element",
                    format!("must be \"tet4\" or \"tet10\", got \"{other}\""),
                ))
            }
        };
        let geometry = match (b.table.contains_key("box"), b.table.contains_key("mesh")) {
            (true, true) => return Err(b.err("mesh", "give either `box` or `mesh`, not both")),
            (false, false) => {
                return Err(b.err("box", "missing: give `box` (with `levels`) or `mesh`"))
            }
            (true, false) => {
                let bx = b.req("box")?;
                let corners = bx
                    .as_array()
                    .filter(|a| a.len() == 2)
                    .ok_or_else(|| b.err("box", format!("expected [[x,y,z],[x,y,z]], got {bx}")))?;
                let min = b.vec3_of("box", &corners[0], false)?;
                let max = b.vec3_of("box", &corners[1], false)?;
                if (0..3).any(|k| max[k] <= min[k]) {
                    return Err(b.err(
                        "box",
                        format!("max must exceed min on every axis, got {min:?} {max:?}"),
                    ));
                }
                let lv = b.req("levels")?;
                let arr = lv.as_array().filter(|a| !a.is_empty()).ok_or_else(|| {
                    b.err(
                        "levels",
                        format!("expected a non-empty list of [nx, ny, nz], got {lv}"),
                    )
                })?;
                let mut levels = Vec::new();
                for l in arr {
                    let d = l.as_array().filter(|a| a.len() == 3).ok_or_else(|| {
                        b.err("levels", format!("expected [nx, ny, nz], got {l}"))
                    })?;
                    let mut div = [0usize; 3];
                    for (o, x) in div.iter_mut().zip(d) {
                        *o = match x {
                            Value::Integer(i) if *i > 0 && *i <= 1000 => *i as usize,
                            other => {
                                return Err(b.err(
                                    "levels",
                                    format!("divisions must be integers in 1..=1000, got {other}"),
                                ))
                            }
                        };
                    }
                    levels.push(div);
                }
                BodyGeometry::Box {
                    min: Point3::from(min),
                    max: Point3::from(max),
                    levels,
                }
            }
            (false, true) => {
                let mv = b.req("mesh")?;
                let list: Vec<&Value> = match mv {
                    Value::String(_) => vec![mv],
                    Value::Array(a) if !a.is_empty() => a.iter().collect(),
                    other => {
                        return Err(b.err(
                            "mesh",
                            format!("expected a file name or a list of them, got {other}"),
                        ))
                    }
                };
                let base = path.parent().unwrap_or(Path::new("."));
                let mut files = Vec::new();
                for m in list {
                    let s = m
                        .as_str()
                        .ok_or_else(|| b.err("mesh", format!("expected a file name, got {m}")))?;
                    files.push(base.join(s));
                }
                BodyGeometry::Meshes(files)
            }
        };
        b.finish()?;

        // [material]
        let mat_t = r
            .table("material")?
            .ok_or_else(|| r.err("material", "missing required table [material]"))?;
        let mut m = sub(f, &r, "material", mat_t);
        let young = m.positive("young")?;
        let poisson = m.f64("poisson")?;
        if !(-1.0 < poisson && poisson < 0.5) {
            return Err(m.err("poisson", format!("must lie in (-1, 0.5), got {poisson}")));
        }
        let density = m.positive("density")?;
        m.finish()?;
        let material = Material {
            young,
            poisson,
            density,
        };

        // [[cut]]
        let mut cuts = Vec::new();
        for (i, t) in r.tables("cut")?.into_iter().enumerate() {
            let mut c = sub(f, &r, &format!("cut[{i}]"), t);
            let origin = Point3::from(c.vec3("origin", false)?);
            let u = Vector3::from(c.vec3("u", false)?);
            let v = Vector3::from(c.vec3("v", false)?);
            if u.cross(&v).norm() <= 1e-14 * u.norm() * v.norm()
                || u.norm() == 0.0
                || v.norm() == 0.0
            {
                return Err(c.err(
                    "v",
                    format!(
                        "u and v span no area (u = {:?}, v = {:?})",
                        u.as_slice(),
                        v.as_slice()
                    ),
                ));
            }
            let snap = c.opt_f64("snap")?;
            if let Some(s) = snap {
                if !(0.0..0.5).contains(&s) {
                    return Err(c.err("snap", format!("must lie in [0, 0.5), got {s}")));
                }
            }
            c.finish()?;
            cuts.push(CutSpec { origin, u, v, snap });
        }

        // [[fix]]
        let mut fixes = Vec::new();
        for (i, t) in r.tables("fix")?.into_iter().enumerate() {
            let mut c = sub(f, &r, &format!("fix[{i}]"), t);
            let min = c.vec3("min", true)?;
            let max = c.vec3("max", true)?;
            let displacement = match c.get("displacement") {
                Some(v) => c.vec3_of("displacement", v, false)?,
                None => [0.0; 3],
            };
            let components = match c.string("components")? {
                None => [true; 3],
                Some(s) => {
                    let mut comp = [false; 3];
                    for ch in s.chars() {
                        match ch {
                            'x' => comp[0] = true,
                            'y' => comp[1] = true,
                            'z' => comp[2] = true,
                            _ => {
                                return Err(c.err(
                                    "components",
                                    format!("must be letters of \"xyz\", got \"{s}\""),
                                ))
                            }
                        }
                    }
                    if !comp.iter().any(|&b| b) {
                        return Err(c.err("components", "selects no component"));
                    }
                    comp
                }
            };
            c.finish()?;
            fixes.push(Fix {
                min,
                max,
                displacement,
                components,
            });
        }
        if fixes.is_empty() {
            return Err(r.err("fix", "missing: at least one [[fix]] is needed"));
        }

        // [[traction]] (extension: force per area on boundary faces inside a box)
        let mut tractions = Vec::new();
        for (i, t) in r.tables("traction")?.into_iter().enumerate() {
            let mut c = sub(f, &r, &format!("traction[{i}]"), t);
            let min = c.vec3("min", true)?;
            let max = c.vec3("max", true)?;
            let traction = c.vec3("traction", false)?;
            c.finish()?;
            tractions.push(TractionSpec { min, max, traction });
        }

        // [gravity]
        let gravity = match r.table("gravity")? {
            Some(t) => {
                let mut g = sub(f, &r, "gravity", t);
                let a = g.vec3("acceleration", false)?;
                g.finish()?;
                Some(Vector3::from(a))
            }
            None => None,
        };

        // [analysis]
        let an_t = r
            .table("analysis")?
            .ok_or_else(|| r.err("analysis", "missing required table [analysis]"))?;
        let mut a = sub(f, &r, "analysis", an_t);
        let formulation = match a.string("formulation")?.unwrap_or("linear") {
            "linear" => Formulation::Linear,
            "corotational" => Formulation::Corotational,
            other => {
                return Err(a.err(
                    "formulation",
                    format!("must be \"linear\" or \"corotational\", got \"{other}\""),
                ))
            }
        };
        let kind = a
            .string("type")?
            .ok_or_else(|| a.err("type", "missing required key (\"static\" or \"dynamic\")"))?;
        let tolerance = a.opt_f64("tolerance")?;
        let max_iterations = a.usize("max_iterations")?;
        let analysis = match kind {
            "static" => {
                let mut o = StaticOptions::default();
                if let Some(s) = a.usize("load_steps")? {
                    o.load_steps = s;
                }
                if let Some(t) = tolerance {
                    o.tolerance = t;
                }
                if let Some(m) = max_iterations {
                    o.max_iterations = m;
                }
                for k in [
                    "dt",
                    "steps",
                    "newmark",
                    "rayleigh",
                    "ramp",
                    "mass",
                    "output_every",
                ] {
                    if a.table.contains_key(k) {
                        return Err(a.err(k, "only for type = \"dynamic\""));
                    }
                }
                Analysis::Static(o)
            }
            "dynamic" => {
                let mut o = DynamicOptions {
                    dt: a.positive("dt")?,
                    ..DynamicOptions::default()
                };
                o.steps = a
                    .usize("steps")?
                    .ok_or_else(|| a.err("steps", "missing required key for a dynamic analysis"))?;
                if let Some(t) = a.table("newmark")? {
                    let mut n = sub(f, &a, "newmark", t);
                    o.beta = n.positive("beta")?;
                    o.gamma = n.positive("gamma")?;
                    n.finish()?;
                    if o.gamma < 0.5 || o.beta < 0.25 * (o.gamma + 0.5).powi(2) {
                        return Err(a.err("newmark", format!("beta = {}, gamma = {} is not unconditionally stable (need gamma >= 0.5, beta >= (gamma + 0.5)^2 / 4)", o.beta, o.gamma)));
                    }
                }
                if let Some(t) = a.table("rayleigh")? {
                    let mut n = sub(f, &a, "rayleigh", t);
                    o.rayleigh_mass = n.opt_f64("mass")?.unwrap_or(0.0);
                    o.rayleigh_stiffness = n.opt_f64("stiffness")?.unwrap_or(0.0);
                    n.finish()?;
                    if o.rayleigh_mass < 0.0 || o.rayleigh_stiffness < 0.0 {
                        return Err(a.err("rayleigh", "coefficients must be non-negative"));
                    }
                }
                o.ramp = a.opt_f64("ramp")?.unwrap_or(0.0);
                if o.ramp < 0.0 {
                    return Err(a.err("ramp", format!("must be non-negative, got {}", o.ramp)));
                }
                o.mass = match a.string("mass")?.unwrap_or("lumped") {
                    "lumped" => MassKind::Lumped,
                    "consistent" => MassKind::Consistent,
                    other => {
                        return Err(a.err(
                            "mass",
                            format!("must be \"lumped\" or \"consistent\", got \"{other}\""),
                        ))
                    }
                };
                if let Some(t) = tolerance {
                    o.tolerance = t;
                }
                if let Some(m) = max_iterations {
                    o.max_iterations = m;
                }
                o.linear_solver = match a.string("linear_solver")?.unwrap_or("direct") {
                    "direct" => LinearSolver::Direct,
                    "pcg" => LinearSolver::Pcg {
                        tolerance: 1e-8,
                        max_cg: 25,
                    },
                    other => {
                        return Err(a.err(
                            "linear_solver",
                            format!("must be \"direct\" or \"pcg\", got \"{other}\""),
                        ))
                    }
                };
                let output_every = a
                    .usize("output_every")?
                    .unwrap_or_else(|| o.steps.div_ceil(100).max(1));
                if a.table.contains_key("load_steps") {
                    return Err(a.err("load_steps", "only for type = \"static\""));
                }
                Analysis::Dynamic {
                    options: o,
                    output_every,
                }
            }
            other => {
                return Err(a.err(
                    "type",
                    format!("must be \"static\" or \"dynamic\", got \"{other}\""),
                ))
            }
        };
        a.finish()?;

        // [[probe]]
        let mut probes = Vec::new();
        for (i, t) in r.tables("probe")?.into_iter().enumerate() {
            let mut c = sub(f, &r, &format!("probe[{i}]"), t);
            let pts = c.req("points")?;
            let arr = pts.as_array().ok_or_else(|| {
                c.err("points", format!("expected a list of [x, y, z], got {pts}"))
            })?;
            for p in arr {
                probes.push(Point3::from(c.vec3_of("points", p, false)?));
            }
            c.finish()?;
        }
        r.finish()?;

        Ok(Scene {
            file: path.to_path_buf(),
            name,
            description,
            geometry,
            element,
            material,
            cuts,
            fixes,
            tractions,
            gravity,
            formulation,
            analysis,
            probes,
        })
    }

    fn file(&self) -> String {
        self.file.display().to_string()
    }

    pub fn n_levels(&self) -> usize {
        match &self.geometry {
            BodyGeometry::Box { levels, .. } => levels.len(),
            BodyGeometry::Meshes(m) => m.len(),
        }
    }

    pub fn is_dynamic(&self) -> bool {
        matches!(self.analysis, Analysis::Dynamic { .. })
    }

    /// The mesh of a level, in the scene's element kind.
    pub fn mesh(&self, level: usize) -> Result<TetMesh, SceneError> {
        let count = self.n_levels();
        if level >= count {
            return Err(SceneError::Level {
                file: self.file(),
                level,
                count,
            });
        }
        let mesh = match &self.geometry {
            BodyGeometry::Box { min, max, levels } => box_mesh(*min, *max, levels[level]),
            BodyGeometry::Meshes(files) => self.read_mesh(&files[level])?,
        };
        Ok(match self.element {
            ElementKind::Tet4 if mesh.kind == ElementKind::Tet10 => {
                return Err(SceneError::Mesh {
                    file: self.file(),
                    mesh: format!("level {level}"),
                    message: "is a Tet10 mesh but element = \"tet4\"".into(),
                })
            }
            ElementKind::Tet4 => mesh,
            ElementKind::Tet10 => mesh.to_tet10(),
        })
    }

    /// Reads a gmsh mesh file.
    pub fn read_mesh(&self, path: &Path) -> Result<TetMesh, SceneError> {
        crate::io::read_msh(path)
            .map(|m| m.mesh)
            .map_err(|e| SceneError::Mesh {
                file: self.file(),
                mesh: path.display().to_string(),
                message: e.to_string(),
            })
    }

    /// Builds the model of `mesh` and the plan saying what runs.
    pub fn build(&self, mesh: TetMesh) -> Result<(Model, Plan), SceneError> {
        let t0 = Instant::now();
        let file = self.file();
        let (lo, hi) = mesh.bounding_box();
        let tol = 1e-9 * (hi - lo).norm();
        let inside = |p: &Point3<f64>, min: &[f64; 3], max: &[f64; 3]| {
            (0..3).all(|k| p[k] >= min[k] - tol && p[k] <= max[k] + tol)
        };

        // Dirichlet nodes.
        let mut fixed_nodes: Vec<[Option<f64>; 3]> = vec![[None; 3]; mesh.n_nodes()];
        for (i, fx) in self.fixes.iter().enumerate() {
            let mut count = 0;
            for (n, p) in mesh.nodes.iter().enumerate() {
                if inside(p, &fx.min, &fx.max) {
                    count += 1;
                    for c in 0..3 {
                        if fx.components[c] {
                            fixed_nodes[n][c] = Some(fx.displacement[c]);
                        }
                    }
                }
            }
            if count == 0 {
                return Err(SceneError::Key {
                    file,
                    key: format!("fix[{i}]"),
                    message: format!("selects no node (box min {:?}, max {:?})", fx.min, fx.max),
                });
            }
        }
        let fixed: Vec<(usize, [Option<f64>; 3])> = fixed_nodes
            .into_iter()
            .enumerate()
            .filter(|(_, c)| c.iter().any(Option::is_some))
            .collect();

        // Tractions.
        let boundary = if self.tractions.is_empty() {
            Vec::new()
        } else {
            mesh.boundary_faces()
        };
        let mut tractions = Vec::new();
        for (i, t) in self.tractions.iter().enumerate() {
            let faces: Vec<_> = boundary
                .iter()
                .filter(|(tri, _)| tri.iter().all(|&v| inside(&mesh.nodes[v], &t.min, &t.max)))
                .copied()
                .collect();
            if faces.is_empty() {
                return Err(SceneError::Key {
                    file,
                    key: format!("traction[{i}]"),
                    message: "selects no boundary face".into(),
                });
            }
            tractions.push(Traction {
                faces,
                value: Vector3::from(t.traction),
            });
        }
        let t_setup = t0.elapsed().as_secs_f64();

        // Cut set-up.
        let t1 = Instant::now();
        let cut: Option<CutSetup> = if self.cuts.is_empty() {
            None
        } else {
            let patches: Vec<PlanarPatch> = self
                .cuts
                .iter()
                .map(|c| PlanarPatch {
                    origin: c.origin,
                    u: c.u,
                    v: c.v,
                })
                .collect();
            let surfaces: Vec<&dyn crate::cut::CutSurface> = patches
                .iter()
                .map(|p| p as &dyn crate::cut::CutSurface)
                .collect();
            let snap = self
                .cuts
                .iter()
                .filter_map(|c| c.snap)
                .fold(crate::cut::DEFAULT_SNAP, |_, s| s);
            // Today's behaviour until the schema's `front`/`tip_radius` are wired (issue 11).
            let inputs: Vec<crate::cut::CutInput> = surfaces
                .iter()
                .map(|s| crate::cut::CutInput::extend(*s, snap))
                .collect();
            Some(
                crate::cut::setup_cut(&mesh, &inputs).map_err(|e| SceneError::Model {
                    file: file.clone(),
                    message: e.to_string(),
                })?,
            )
        };
        let t_cut = t1.elapsed().as_secs_f64();

        let t2 = Instant::now();
        let need_mass = self.is_dynamic();
        let n_elements = mesh.n_elements();
        let model = Model::build(ModelInput {
            mesh,
            material: self.material,
            formulation: self.formulation,
            cut,
            fixed,
            gravity: self.gravity,
            body_force: None,
            tractions: &tractions,
            need_mass,
        })
        .map_err(|e: ModelError| SceneError::Model {
            file: file.clone(),
            message: e.to_string(),
        })?;
        let t_model = t2.elapsed().as_secs_f64();
        if let Some(part) = model.free_parts().first() {
            if !self.is_dynamic() {
                return Err(SceneError::Model {
                    file,
                    message: format!("a static scene has a part that floats free: {part}"),
                });
            }
        }
        let plan = Plan::new(self, &model, n_elements, [t_setup, t_cut, t_model]);
        Ok((model, plan))
    }
}

/// What a run does, and what it skips and why.
#[derive(Debug, Clone)]
pub struct Plan {
    pub stages: Vec<(String, bool, String)>,
    pub elements: usize,
    pub nodes: usize,
    pub dofs: usize,
    pub enriched: usize,
    pub free: usize,
    /// Seconds: selections, cut set-up, element data + pattern.
    pub times: [f64; 3],
}

impl Plan {
    fn new(scene: &Scene, model: &Model, elements: usize, times: [f64; 3]) -> Plan {
        let dynamic = scene.is_dynamic();
        let corot = scene.formulation == Formulation::Corotational;
        let cut = !scene.cuts.is_empty();
        let mut s: Vec<(String, bool, String)> = Vec::new();
        let mut add =
            |name: &str, run: bool, why: &str| s.push((name.to_string(), run, why.to_string()));
        add(
            "mesh",
            true,
            &format!(
                "{} {}",
                model.mesh.kind.name(),
                match scene.geometry {
                    BodyGeometry::Box { .. } => "structured box",
                    BodyGeometry::Meshes(_) => "gmsh file",
                }
            ),
        );
        add(
            "cut set-up (level set, classification, sub-tets, enrichment)",
            cut,
            if cut {
                "the scene has [[cut]]"
            } else {
                "no cut in the scene"
            },
        );
        add("element data (gradients, integration groups)", true, "once");
        add("sparsity pattern + symbolic factorisation", true, "once");
        add(
            "mass (lumped, eq. 81-82)",
            dynamic,
            if dynamic {
                "dynamic scene"
            } else {
                "static scene: no mass"
            },
        );
        add(
            "rotations (polar decomposition per group)",
            corot,
            if corot {
                "corotational"
            } else {
                "linear scene: R = I"
            },
        );
        let refactor = corot;
        add(
            "numeric factorisation every iteration",
            refactor,
            if refactor && dynamic {
                "tangent R K R^T changes"
            } else if refactor {
                "exact corotational tangent (rotation derivative included) changes"
            } else {
                "constant matrix: factorised once"
            },
        );
        add(
            "Newton load steps",
            corot && !dynamic,
            if corot && !dynamic {
                "corotational static"
            } else {
                "not needed"
            },
        );
        add(
            "Newmark time stepping",
            dynamic,
            if dynamic {
                "dynamic scene"
            } else {
                "static scene"
            },
        );
        Plan {
            stages: s,
            elements,
            nodes: model.mesh.n_nodes(),
            dofs: model.n_dofs(),
            enriched: model.n_enriched(),
            free: model.n_free,
            times,
        }
    }
}

impl fmt::Display for Plan {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "plan:")?;
        for (name, run, why) in &self.stages {
            writeln!(
                f,
                "  [{}] {name} ({why})",
                if *run { "run " } else { "skip" }
            )?;
        }
        write!(
            f,
            "size: {} elements, {} nodes, {} DOFs ({} enriched nodes), {} free DOFs",
            self.elements, self.nodes, self.dofs, self.enriched, self.free
        )
    }
}
