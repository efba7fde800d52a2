//! The case file as serde structs ([`CaseFile`]) and the checks that turn it
//! into a [`Scene`] ([`validate`]).
//!
//! Deserialisation refuses unknown keys (`deny_unknown_fields`) and values of
//! the wrong type, naming the key path (`serde_path_to_error`); `validate`
//! refuses what is well-typed but wrong (non-finite numbers, empty selections
//! of components, unstable Newmark parameters, blade keyframes out of order …).

use super::{
    Analysis, BodyGeometry, CutGeometry, CutSpec, Fix, FrontMode, Scene, SceneError, TractionSpec,
};
use crate::cut::{PlanarPatch, DEFAULT_SNAP};
use crate::dynamics::{DynamicOptions, LinearSolver, MassKind, DEFAULT_LAGGED};
use crate::material::Material;
use crate::mesh::ElementKind;
use crate::model::Formulation;
use crate::statics::StaticOptions;
use nalgebra::{Point3, Vector3};
use serde::Deserialize;
use std::path::Path;
use toml::Value;

type Vec3 = [f64; 3];

/// The whole case file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaseFile {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub body: BodyFile,
    pub material: MaterialFile,
    #[serde(default)]
    pub cut: Vec<CutFile>,
    #[serde(default)]
    pub fix: Vec<FixFile>,
    #[serde(default)]
    pub traction: Vec<TractionFile>,
    pub gravity: Option<GravityFile>,
    pub analysis: AnalysisFile,
    #[serde(default)]
    pub probe: Vec<ProbeFile>,
}

#[derive(Debug, Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
pub enum ElementFile {
    Tet4,
    Tet10,
}

/// `[body]`: `box` + `levels`, or `mesh` (one file or a list, one per level).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyFile {
    #[serde(rename = "box")]
    pub bbox: Option<[Vec3; 2]>,
    pub levels: Option<Vec<[i64; 3]>>,
    pub mesh: Option<Value>,
    pub element: Option<ElementFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialFile {
    pub young: f64,
    pub poisson: f64,
    pub density: f64,
}

/// `[[cut]]`: exactly one of the patch (`origin`, `u`, `v`), `surface` or `blade`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CutFile {
    pub origin: Option<Vec3>,
    pub u: Option<Vec3>,
    pub v: Option<Vec3>,
    pub surface: Option<String>,
    pub blade: Option<[Vec3; 2]>,
    pub travel: Option<Vec3>,
    pub start: Option<f64>,
    pub end: Option<f64>,
    pub path: Option<Vec<[Vec3; 2]>>,
    pub times: Option<Vec<f64>>,
    pub snap: Option<f64>,
    pub front: Option<FrontMode>,
    pub tip_radius: Option<f64>,
    pub event_travel: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FixFile {
    pub min: Vec3,
    pub max: Vec3,
    pub displacement: Option<Vec3>,
    pub components: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TractionFile {
    pub min: Vec3,
    pub max: Vec3,
    pub traction: Vec3,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GravityFile {
    pub acceleration: Vec3,
}

#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum AnalysisKind {
    Static,
    Dynamic,
}

#[derive(Debug, Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
pub enum FormulationFile {
    Linear,
    Corotational,
}

#[derive(Debug, Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
pub enum MassFile {
    Lumped,
    Consistent,
}

#[derive(Debug, Deserialize, Clone, Copy)]
#[serde(rename_all = "lowercase")]
pub enum SolverFile {
    Direct,
    Pcg,
    /// CG preconditioned by the last factor warped by per-node rotations.
    #[serde(rename = "warped_pcg")]
    WarpedPcg,
    /// Modified Newton on a factor kept for 5 steps.
    Lagged,
}

/// `[analysis]`: the keys of both types; `validate` refuses those of the other type.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalysisFile {
    #[serde(rename = "type")]
    pub kind: AnalysisKind,
    pub formulation: Option<FormulationFile>,
    pub tolerance: Option<f64>,
    pub max_iterations: Option<i64>,
    pub load_steps: Option<i64>,
    pub dt: Option<f64>,
    pub steps: Option<i64>,
    pub newmark: Option<NewmarkFile>,
    pub rayleigh: Option<RayleighFile>,
    pub ramp: Option<f64>,
    pub mass: Option<MassFile>,
    pub linear_solver: Option<SolverFile>,
    pub output_every: Option<i64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NewmarkFile {
    pub beta: f64,
    pub gamma: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RayleighFile {
    pub mass: Option<f64>,
    pub stiffness: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeFile {
    pub points: Vec<Vec3>,
}

/// Parses `text` into a [`CaseFile`]; a type error or an unknown or missing
/// key names its path (`cut[0].v`, `material.young`).
pub fn deserialize(text: &str, path: &Path) -> Result<CaseFile, SceneError> {
    let file = path.display().to_string();
    let de = toml::Deserializer::parse(text).map_err(|e| SceneError::Syntax {
        file: file.clone(),
        line: line_of(text, e.span()),
        message: one_line(e.message()),
    })?;
    let case: CaseFile = serde_path_to_error::deserialize(de).map_err(|e| {
        let mut key = e.path().to_string();
        let message = one_line(e.inner().message());
        // A missing or unknown key is named by its own path, not its table's.
        let named = ["missing field `", "unknown field `"]
            .iter()
            .find_map(|p| message.strip_prefix(p))
            .and_then(|rest| rest.split('`').next());
        let message = match named {
            Some(k) => {
                if !(key == k || key.ends_with(&format!(".{k}"))) {
                    key = if key == "." || key.is_empty() {
                        k.to_string()
                    } else {
                        format!("{key}.{k}")
                    };
                }
                if message.starts_with("missing") {
                    "missing required key".to_string()
                } else {
                    message.replacen("unknown field", "unknown key", 1)
                }
            }
            None => message,
        };
        if key == "." || key.is_empty() {
            // No key to name (e.g. the document is not a table): a syntax error.
            SceneError::Syntax {
                file,
                line: line_of(text, e.inner().span()),
                message,
            }
        } else {
            SceneError::Key { file, key, message }
        }
    })?;
    // The typed read takes a point's first three numbers and a box's first
    // two corners and drops the rest: refuse those instead.
    if let Ok(table) = text.parse::<toml::Table>() {
        check_lengths(&table, "").map_err(|(key, message)| SceneError::Key {
            file: path.display().to_string(),
            key,
            message,
        })?;
    }
    Ok(case)
}

/// Keys holding pairs of points (a box's corners, a blade's ends; each
/// keyframe of a `path`).
const PAIRS: [&str; 4] = ["box", "bbox", "blade", "path"];

/// Every array of numbers in `table` (a point, a vector, a level's
/// divisions) has 3 entries, `times` apart; the pairs of [`PAIRS`] have 2.
fn check_lengths(table: &toml::Table, prefix: &str) -> Result<(), (String, String)> {
    use toml::Value;
    fn numbers(key: &str, v: &[Value], pair: bool) -> Result<(), (String, String)> {
        let is_number = |x: &Value| matches!(x, Value::Integer(_) | Value::Float(_));
        if !v.is_empty() && v.iter().all(is_number) {
            if v.len() != 3 {
                return Err((
                    key.to_string(),
                    format!("expected 3 numbers, got {}", v.len()),
                ));
            }
            return Ok(());
        }
        let arrays: Vec<&Vec<Value>> = v.iter().filter_map(Value::as_array).collect();
        if pair && arrays.len() == v.len() && !arrays.is_empty() {
            // A pair of points, or (a path) a list of pairs.
            if arrays.iter().all(|a| a.iter().all(is_number)) {
                if v.len() != 2 {
                    return Err((
                        key.to_string(),
                        format!("expected 2 points, got {}", v.len()),
                    ));
                }
            } else {
                for (i, a) in arrays.iter().enumerate() {
                    numbers(&format!("{key}[{i}]"), a, true)?;
                }
                return Ok(());
            }
        }
        for (i, a) in arrays.iter().enumerate() {
            numbers(&format!("{key}[{i}]"), a, false)?;
        }
        Ok(())
    }
    for (k, v) in table {
        let key = format!("{prefix}{k}");
        match v {
            Value::Table(t) => check_lengths(t, &format!("{key}."))?,
            Value::Array(items) if items.iter().all(Value::is_table) && !items.is_empty() => {
                for (i, t) in items.iter().enumerate() {
                    if let Some(t) = t.as_table() {
                        check_lengths(t, &format!("{key}[{i}]."))?;
                    }
                }
            }
            Value::Array(items) if k != "times" => {
                numbers(&key, items, PAIRS.contains(&k.as_str()))?
            }
            _ => {}
        }
    }
    Ok(())
}

fn one_line(s: &str) -> String {
    s.trim().replace('\n', " ")
}

fn line_of(text: &str, span: Option<std::ops::Range<usize>>) -> usize {
    span.map_or(0, |s| {
        let end = s.start.min(text.len());
        // The span may fall inside a multi-byte character.
        let end = (0..=end)
            .rev()
            .find(|&i| text.is_char_boundary(i))
            .unwrap_or(0);
        text[..end].lines().count().max(1)
    })
}

/// Builds key errors for one file.
struct Checker<'a> {
    file: &'a str,
}

impl Checker<'_> {
    fn err(&self, key: impl Into<String>, message: impl Into<String>) -> SceneError {
        SceneError::Key {
            file: self.file.to_string(),
            key: key.into(),
            message: message.into(),
        }
    }

    fn finite(&self, key: &str, x: f64) -> Result<f64, SceneError> {
        if x.is_finite() {
            Ok(x)
        } else {
            Err(self.err(key, format!("must be a finite number, got {x}")))
        }
    }

    fn finite3(&self, key: &str, v: Vec3) -> Result<Vec3, SceneError> {
        for x in v {
            self.finite(key, x)?;
        }
        Ok(v)
    }

    /// Box corners: ±inf allowed, NaN not.
    fn corner(&self, key: &str, v: Vec3) -> Result<Vec3, SceneError> {
        if let Some(x) = v.iter().find(|x| x.is_nan()) {
            return Err(self.err(key, format!("must be a number, got {x}")));
        }
        Ok(v)
    }

    fn positive(&self, key: &str, x: f64) -> Result<f64, SceneError> {
        let x = self.finite(key, x)?;
        if x <= 0.0 {
            return Err(self.err(key, format!("must be positive, got {x}")));
        }
        Ok(x)
    }

    fn count(&self, key: &str, i: Option<i64>) -> Result<Option<usize>, SceneError> {
        match i {
            Some(i) if i > 0 => usize::try_from(i)
                .map(Some)
                .map_err(|_| self.err(key, format!("too large for this machine, got {i}"))),
            Some(i) => Err(self.err(key, format!("expected a positive integer, got {i}"))),
            None => Ok(None),
        }
    }

    /// Refuses `key` (given when `present`) with `why`.
    fn absent(&self, key: &str, present: bool, why: &str) -> Result<(), SceneError> {
        if present {
            return Err(self.err(key, why));
        }
        Ok(())
    }
}

/// Checks a deserialised case and builds the [`Scene`]; `path` names the
/// file and anchors relative paths.
pub fn validate(case: CaseFile, path: &Path) -> Result<Scene, SceneError> {
    let file = path.display().to_string();
    let c = Checker { file: &file };
    let base = path.parent().unwrap_or(Path::new("."));

    // [body]
    let b = case.body;
    let element = match b.element.unwrap_or(ElementFile::Tet4) {
        ElementFile::Tet4 => ElementKind::Tet4,
        ElementFile::Tet10 => ElementKind::Tet10,
    };
    let geometry = match (b.bbox, b.mesh) {
        (Some(_), Some(_)) => {
            return Err(c.err("body.mesh", "give either `box` or `mesh`, not both"))
        }
        (None, None) => {
            return Err(c.err("body.box", "missing: give `box` (with `levels`) or `mesh`"))
        }
        (Some([min, max]), None) => {
            let min = c.finite3("body.box", min)?;
            let max = c.finite3("body.box", max)?;
            if (0..3).any(|k| max[k] <= min[k]) {
                return Err(c.err(
                    "body.box",
                    format!("max must exceed min on every axis, got {min:?} {max:?}"),
                ));
            }
            let lv = b
                .levels
                .ok_or_else(|| c.err("body.levels", "missing required key"))?;
            if lv.is_empty() {
                return Err(c.err(
                    "body.levels",
                    "expected a non-empty list of [nx, ny, nz], got []",
                ));
            }
            let mut levels = Vec::with_capacity(lv.len());
            for l in lv {
                let mut div = [0usize; 3];
                for (o, &x) in div.iter_mut().zip(&l) {
                    if !(1..=1000).contains(&x) {
                        return Err(c.err(
                            "body.levels",
                            format!("divisions must be integers in 1..=1000, got {x}"),
                        ));
                    }
                    *o = x as usize;
                }
                levels.push(div);
            }
            BodyGeometry::Box {
                min: Point3::from(min),
                max: Point3::from(max),
                levels,
            }
        }
        (None, Some(mv)) => {
            c.absent("body.levels", b.levels.is_some(), "only with `box`")?;
            let list: Vec<&Value> = match &mv {
                Value::String(_) => vec![&mv],
                Value::Array(a) if !a.is_empty() => a.iter().collect(),
                other => {
                    return Err(c.err(
                        "body.mesh",
                        format!("expected a file name or a list of them, got {other}"),
                    ))
                }
            };
            let mut files = Vec::with_capacity(list.len());
            for m in list {
                let s = m
                    .as_str()
                    .ok_or_else(|| c.err("body.mesh", format!("expected a file name, got {m}")))?;
                files.push(base.join(s));
            }
            BodyGeometry::Meshes(files)
        }
    };

    // [material]
    let m = case.material;
    let young = c.positive("material.young", m.young)?;
    let poisson = c.finite("material.poisson", m.poisson)?;
    if !(-1.0 < poisson && poisson < 0.5) {
        return Err(c.err(
            "material.poisson",
            format!("must lie in (-1, 0.5), got {poisson}"),
        ));
    }
    let density = c.positive("material.density", m.density)?;
    let material = Material {
        young,
        poisson,
        density,
    };

    // [[cut]]
    let mut cuts = Vec::with_capacity(case.cut.len());
    for (i, t) in case.cut.into_iter().enumerate() {
        cuts.push(validate_cut(&c, &format!("cut[{i}]"), t, base)?);
    }

    // [[fix]]
    let mut fixes = Vec::with_capacity(case.fix.len());
    for (i, t) in case.fix.into_iter().enumerate() {
        let k = format!("fix[{i}]");
        let min = c.corner(&format!("{k}.min"), t.min)?;
        let max = c.corner(&format!("{k}.max"), t.max)?;
        let displacement = c.finite3(
            &format!("{k}.displacement"),
            t.displacement.unwrap_or([0.0; 3]),
        )?;
        let components = match t.components {
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
                                format!("{k}.components"),
                                format!("must be letters of \"xyz\", got {s:?}"),
                            ))
                        }
                    }
                }
                if !comp.iter().any(|&b| b) {
                    return Err(c.err(format!("{k}.components"), "selects no component"));
                }
                comp
            }
        };
        fixes.push(Fix {
            min,
            max,
            displacement,
            components,
        });
    }
    if fixes.is_empty() {
        return Err(c.err("fix", "missing: at least one [[fix]] is needed"));
    }

    // [[traction]] (extension: force per area on boundary faces inside a box)
    let mut tractions = Vec::with_capacity(case.traction.len());
    for (i, t) in case.traction.into_iter().enumerate() {
        let k = format!("traction[{i}]");
        tractions.push(TractionSpec {
            min: c.corner(&format!("{k}.min"), t.min)?,
            max: c.corner(&format!("{k}.max"), t.max)?,
            traction: c.finite3(&format!("{k}.traction"), t.traction)?,
        });
    }

    // [gravity]
    let gravity = match case.gravity {
        Some(g) => Some(Vector3::from(
            c.finite3("gravity.acceleration", g.acceleration)?,
        )),
        None => None,
    };

    // [analysis]
    let (formulation, analysis) = validate_analysis(&c, case.analysis)?;
    // A dynamic run's blade must start cutting before the run's last step
    // (a static scene takes the completed sweep, whenever it happens).
    if let Analysis::Dynamic { options, .. } = &analysis {
        let last = options.dt * options.steps as f64;
        for (i, cut) in cuts.iter().enumerate() {
            if let CutGeometry::Blade { keyframes, travel } = &cut.geometry {
                let start = keyframes[0].0;
                if start >= last {
                    let key = if travel.is_some() { "start" } else { "times" };
                    return Err(c.err(
                        format!("cut[{i}].{key}"),
                        format!(
                            "the blade starts at t = {start} s, when the run has ended (steps × dt = {} × {} = {last} s): it would never cut",
                            options.steps, options.dt
                        ),
                    ));
                }
            }
        }
    }

    // [[probe]]
    let mut probes = Vec::new();
    let mut probe_keys = Vec::new();
    for (i, p) in case.probe.into_iter().enumerate() {
        if p.points.is_empty() {
            return Err(c.err(
                format!("probe[{i}].points"),
                "is empty: a [[probe]] lists at least one point",
            ));
        }
        for (k, x) in p.points.into_iter().enumerate() {
            probes.push(Point3::from(c.finite3(&format!("probe[{i}].points"), x)?));
            probe_keys.push((i, k));
        }
    }

    Ok(Scene {
        file: path.to_path_buf(),
        name: case.name,
        description: case.description,
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
        probe_keys,
    })
}

/// One `[[cut]]` under key prefix `k`.
fn validate_cut(c: &Checker, k: &str, t: CutFile, base: &Path) -> Result<CutSpec, SceneError> {
    let key = |s: &str| format!("{k}.{s}");
    let patch = t.origin.is_some() || t.u.is_some() || t.v.is_some();
    let blade_keys = t.travel.is_some()
        || t.start.is_some()
        || t.end.is_some()
        || t.path.is_some()
        || t.times.is_some()
        || t.event_travel.is_some();
    // A blade given by its path alone: the edge at the first keyframe.
    let inferred = t.blade.is_none() && !patch && t.surface.is_none() && t.travel.is_none();
    let blade = match (&t.blade, &t.path) {
        (Some(b), _) => Some(*b),
        (None, Some(path)) if inferred => path.first().copied(),
        _ => None,
    };
    let kinds = [patch, t.surface.is_some(), blade.is_some()];
    match kinds.iter().filter(|&&b| b).count() {
        0 if blade_keys => {
            return Err(c.err(
                key("blade"),
                "missing: travel/path/times/start/end/event_travel need a blade",
            ))
        }
        0 => {
            return Err(c.err(
                key("origin"),
                "missing: give the patch (origin, u, v), a surface or a blade",
            ))
        }
        1 => {}
        _ => {
            return Err(c.err(
                k,
                "give exactly one of the patch (origin, u, v), surface or blade",
            ))
        }
    }
    if blade.is_none() && blade_keys {
        let name = [
            ("travel", t.travel.is_some()),
            ("start", t.start.is_some()),
            ("end", t.end.is_some()),
            ("path", t.path.is_some()),
            ("times", t.times.is_some()),
            ("event_travel", t.event_travel.is_some()),
        ]
        .into_iter()
        .find(|(_, b)| *b)
        .map_or("travel", |(n, _)| n);
        return Err(c.err(key(name), "only with a blade"));
    }

    let geometry = if patch {
        let get = |name: &str, v: Option<Vec3>| -> Result<Vector3<f64>, SceneError> {
            let v = v.ok_or_else(|| c.err(key(name), "missing required key"))?;
            Ok(Vector3::from(c.finite3(&key(name), v)?))
        };
        let origin = Point3::from(get("origin", t.origin)?);
        let u = get("u", t.u)?;
        let v = get("v", t.v)?;
        if spans_no_area(&u, &v) {
            return Err(c.err(
                key("v"),
                format!(
                    "u and v span no area (u = {:?}, v = {:?})",
                    u.as_slice(),
                    v.as_slice()
                ),
            ));
        }
        CutGeometry::Patch(PlanarPatch { origin, u, v })
    } else if let Some(s) = t.surface {
        let lower = s.to_ascii_lowercase();
        if !(lower.ends_with(".stl") || lower.ends_with(".msh")) {
            return Err(c.err(
                key("surface"),
                format!("must be an .stl or .msh file, got {s:?}"),
            ));
        }
        let p = base.join(&s);
        if !p.is_file() {
            return Err(c.err(key("surface"), format!("no such file: {}", p.display())));
        }
        CutGeometry::Surface(p)
    } else {
        let [a, b] = blade.expect("one kind is given");
        let a = Point3::from(c.finite3(&key("blade"), a)?);
        let b = Point3::from(c.finite3(&key("blade"), b)?);
        if (b - a).norm() == 0.0 {
            return Err(c.err(key("blade"), "the edge a–b has zero length"));
        }
        let (keyframes, travel) = match (t.travel, t.path) {
            (Some(_), Some(_)) => {
                return Err(c.err(
                    key("path"),
                    "give either travel (with start, end) or path (with times), not both",
                ))
            }
            (None, None) => {
                return Err(c.err(
                    key("travel"),
                    "missing: a blade needs travel (with start, end) or path (with times)",
                ))
            }
            (Some(travel), None) => {
                c.absent(&key("times"), t.times.is_some(), "only with path")?;
                let travel = Vector3::from(c.finite3(&key("travel"), travel)?);
                if spans_no_area(&(b - a), &travel) {
                    return Err(c.err(
                        key("travel"),
                        format!(
                            "the edge sweeps no area (b − a = {:?}, travel = {:?})",
                            (b - a).as_slice(),
                            travel.as_slice()
                        ),
                    ));
                }
                let start = t
                    .start
                    .ok_or_else(|| c.err(key("start"), "missing required key (with travel)"))?;
                let end = t
                    .end
                    .ok_or_else(|| c.err(key("end"), "missing required key (with travel)"))?;
                let start = c.finite(&key("start"), start)?;
                let end = c.finite(&key("end"), end)?;
                if start < 0.0 {
                    return Err(c.err(key("start"), format!("must be non-negative, got {start}")));
                }
                if end <= start {
                    return Err(c.err(
                        key("end"),
                        format!("must be later than start = {start}, got {end}"),
                    ));
                }
                (
                    vec![(start, [a, b]), (end, [a + travel, b + travel])],
                    Some(travel),
                )
            }
            (None, Some(path)) => {
                c.absent(&key("start"), t.start.is_some(), "only with travel")?;
                c.absent(&key("end"), t.end.is_some(), "only with travel")?;
                let times = t
                    .times
                    .ok_or_else(|| c.err(key("times"), "missing required key (with path)"))?;
                // The blade may be left out of the path: then it is the
                // keyframe at times[0] and the path's edges follow it.
                let path: Vec<[Vec3; 2]> = if times.len() == path.len() + 1 && !inferred {
                    std::iter::once([a.coords.into(), b.coords.into()])
                        .chain(path)
                        .collect()
                } else {
                    path
                };
                if times.len() != path.len() {
                    return Err(c.err(
                        key("times"),
                        if inferred {
                            format!(
                                "has {} entries but path has {} keyframes",
                                times.len(),
                                path.len()
                            )
                        } else {
                            format!(
                                "has {} entries but path has {} keyframes (or {} with the blade first)",
                                times.len(),
                                path.len(),
                                path.len() + 1
                            )
                        },
                    ));
                }
                if path.is_empty() {
                    return Err(c.err(key("path"), "needs at least one keyframe"));
                }
                let mut frames = Vec::with_capacity(path.len());
                for (j, (&time, [pa, pb])) in times.iter().zip(&path).enumerate() {
                    let time = c.finite(&key("times"), time)?;
                    if time < 0.0 {
                        return Err(
                            c.err(key("times"), format!("must be non-negative, got {time}"))
                        );
                    }
                    if let Some(&(prev, _)) = frames.last() {
                        if time <= prev {
                            return Err(c.err(
                                key("times"),
                                format!("must increase: entry {j} = {time} after {prev}"),
                            ));
                        }
                    }
                    let pa = Point3::from(c.finite3(&key("path"), *pa)?);
                    let pb = Point3::from(c.finite3(&key("path"), *pb)?);
                    if (pb - pa).norm() == 0.0 {
                        return Err(c.err(
                            key("path"),
                            format!("keyframe {j}: the edge has zero length"),
                        ));
                    }
                    frames.push((time, [pa, pb]));
                }
                // The blade is the edge at the first keyframe.
                let [p0, p1] = frames[0].1;
                if (p0 - a).norm() > 0.0 || (p1 - b).norm() > 0.0 {
                    return Err(c.err(key("path"), "the first keyframe must be the blade [a, b]"));
                }
                (frames, None)
            }
        };
        CutGeometry::Blade { keyframes, travel }
    };

    let snap = match t.snap {
        Some(s) => {
            if !(0.0..0.5).contains(&s) {
                return Err(c.err(key("snap"), format!("must lie in [0, 0.5), got {s}")));
            }
            s
        }
        None => DEFAULT_SNAP,
    };
    let tip_radius = match t.tip_radius {
        Some(r) => Some(c.positive(&key("tip_radius"), r)?),
        None => None,
    };
    if tip_radius.is_some() && t.front == Some(FrontMode::Extend) {
        return Err(c.err(
            key("tip_radius"),
            "only with front = \"tip\" (an extended front has no tip enrichment)",
        ));
    }
    let event_travel = match t.event_travel {
        Some(d) => Some(c.positive(&key("event_travel"), d)?),
        None => None,
    };
    Ok(CutSpec {
        geometry,
        snap,
        front: t.front,
        tip_radius,
        event_travel,
        blending: None,
    })
}

/// Whether u and v span no area (parallel, or one of them zero).
fn spans_no_area(u: &Vector3<f64>, v: &Vector3<f64>) -> bool {
    u.norm() == 0.0 || v.norm() == 0.0 || u.cross(v).norm() <= 1e-14 * u.norm() * v.norm()
}

fn validate_analysis(c: &Checker, a: AnalysisFile) -> Result<(Formulation, Analysis), SceneError> {
    let formulation = match a.formulation.unwrap_or(FormulationFile::Linear) {
        FormulationFile::Linear => Formulation::Linear,
        FormulationFile::Corotational => Formulation::Corotational,
    };
    let tolerance = match a.tolerance {
        Some(t) => Some(c.positive("analysis.tolerance", t)?),
        None => None,
    };
    let max_iterations = c.count("analysis.max_iterations", a.max_iterations)?;
    let analysis = match a.kind {
        AnalysisKind::Static => {
            for (k, present) in [
                ("dt", a.dt.is_some()),
                ("steps", a.steps.is_some()),
                ("newmark", a.newmark.is_some()),
                ("rayleigh", a.rayleigh.is_some()),
                ("ramp", a.ramp.is_some()),
                ("mass", a.mass.is_some()),
                ("linear_solver", a.linear_solver.is_some()),
                ("output_every", a.output_every.is_some()),
            ] {
                c.absent(
                    &format!("analysis.{k}"),
                    present,
                    "only for type = \"dynamic\"",
                )?;
            }
            let mut o = StaticOptions::default();
            if let Some(s) = c.count("analysis.load_steps", a.load_steps)? {
                o.load_steps = s;
            }
            if let Some(t) = tolerance {
                o.tolerance = t;
            }
            if let Some(m) = max_iterations {
                o.max_iterations = m;
            }
            Analysis::Static(o)
        }
        AnalysisKind::Dynamic => {
            c.absent(
                "analysis.load_steps",
                a.load_steps.is_some(),
                "only for type = \"static\"",
            )?;
            let dt = a.dt.ok_or_else(|| {
                c.err("analysis.dt", "missing required key for a dynamic analysis")
            })?;
            let mut o = DynamicOptions {
                dt: c.positive("analysis.dt", dt)?,
                ..DynamicOptions::default()
            };
            o.steps = c.count("analysis.steps", a.steps)?.ok_or_else(|| {
                c.err(
                    "analysis.steps",
                    "missing required key for a dynamic analysis",
                )
            })?;
            // The run's times must be numbers: a dt that overflows them
            // solved every step and then failed writing its frames' times.
            let end = o.dt * o.steps as f64;
            if !end.is_finite() {
                return Err(c.err(
                    "analysis.dt",
                    format!("{:e} over {} steps ends at t = {end}", o.dt, o.steps),
                ));
            }
            if let Some(n) = a.newmark {
                o.beta = c.positive("analysis.newmark.beta", n.beta)?;
                o.gamma = c.positive("analysis.newmark.gamma", n.gamma)?;
                // (A relative 1e-12 below the bound: β = (γ + ½)²/4 written
                // out, e.g. 0.3025 for γ = 0.6, rounds below the product.)
                if o.gamma < 0.5 || o.beta < 0.25 * (o.gamma + 0.5).powi(2) * (1.0 - 1e-12) {
                    return Err(c.err("analysis.newmark", format!("beta = {}, gamma = {} is not unconditionally stable (need gamma >= 0.5, beta >= (gamma + 0.5)^2 / 4)", o.beta, o.gamma)));
                }
            }
            if let Some(r) = a.rayleigh {
                o.rayleigh_mass = c.finite("analysis.rayleigh.mass", r.mass.unwrap_or(0.0))?;
                o.rayleigh_stiffness =
                    c.finite("analysis.rayleigh.stiffness", r.stiffness.unwrap_or(0.0))?;
                if o.rayleigh_mass < 0.0 || o.rayleigh_stiffness < 0.0 {
                    return Err(c.err(
                        "analysis.rayleigh",
                        format!(
                            "coefficients must be non-negative, got mass = {}, stiffness = {}",
                            o.rayleigh_mass, o.rayleigh_stiffness
                        ),
                    ));
                }
            }
            o.ramp = c.finite("analysis.ramp", a.ramp.unwrap_or(0.0))?;
            if o.ramp < 0.0 {
                return Err(c.err(
                    "analysis.ramp",
                    format!("must be non-negative, got {}", o.ramp),
                ));
            }
            o.mass = match a.mass.unwrap_or(MassFile::Lumped) {
                MassFile::Lumped => MassKind::Lumped,
                MassFile::Consistent => MassKind::Consistent,
            };
            if let Some(t) = tolerance {
                o.tolerance = t;
            }
            if let Some(m) = max_iterations {
                o.max_iterations = m;
            }
            // Corotational scenes default to modified Newton on a lagged
            // factor of the exact tangent (examples/fast_step.rs: bend_dynamic
            // L0 0.52 against 2.2 ms a step, within 2e-9 of the refactorising
            // step over 1000 steps; the undamped gravity beam 3.3 against
            // 5.1 ms); a linear scene factorises once whatever this says.
            o.linear_solver = match a.linear_solver.unwrap_or(SolverFile::Lagged) {
                SolverFile::Direct => LinearSolver::Direct,
                SolverFile::Pcg => LinearSolver::Pcg {
                    tolerance: 1e-8,
                    max_cg: 25,
                },
                // CG to 1e-10 relative follows the refactorising step to ~1e-15
                // over 1000 steps of bend_dynamic L1 (examples/fast_step.rs).
                SolverFile::WarpedPcg => LinearSolver::WarpedPcg {
                    tolerance: 1e-10,
                    max_cg: 50,
                },
                SolverFile::Lagged => DEFAULT_LAGGED,
            };
            let output_every = c
                .count("analysis.output_every", a.output_every)?
                .unwrap_or_else(|| o.steps.div_ceil(100).max(1));
            Analysis::Dynamic {
                options: o,
                output_every,
            }
        }
    };
    Ok((formulation, analysis))
}
