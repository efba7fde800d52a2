#![allow(clippy::needless_range_loop)]
//! The command line: outputs of a run, and one-line errors on bad input.

use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_xfem-cut")
}

fn cases() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("cases")
}

const GOOD: &str = r#"
name = "tiny"
[body]
box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]
levels = [[1, 2, 4]]
[material]
young = 3.0e5
poisson = 0.35
density = 1070.0
[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
[gravity]
acceleration = [9.81, 0.0, 0.0]
[analysis]
type = "static"
[[probe]]
points = [[0.0, 0.03, 0.2], [0.03, 0.06, 0.2]]
"#;

/// Runs `xfem-cut run` on `text` written to a temp case file: its output.
fn run_output(text: &str) -> (std::process::Output, tempfile::TempDir) {
    run_text(text, &[])
}

/// Runs `xfem-cut run --mesh MESH` on `text` written to a temp case file:
/// its output.
fn run_on_mesh(text: &str, mesh: &Path) -> (std::process::Output, tempfile::TempDir) {
    run_text(text, &[std::ffi::OsStr::new("--mesh"), mesh.as_os_str()])
}

/// `xfem-cut run CASE ARGS --out DIR/out`, CASE `text` written to DIR/case.toml.
fn run_text(text: &str, args: &[&std::ffi::OsStr]) -> (std::process::Output, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("case.toml");
    std::fs::write(&case, text).unwrap();
    let out = Command::new(bin())
        .arg("run")
        .arg(&case)
        .args(args)
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    (out, dir)
}

/// Runs `xfem-cut run` on the shipped case `cases/NAME.toml` into a temp
/// directory: its output.
fn run_shipped(name: &str) -> (std::process::Output, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(bin())
        .arg("run")
        .arg(cases().join(format!("{name}.toml")))
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    (out, dir)
}

/// The stdout of a run that must have succeeded (else its stderr fails the test).
fn succeeded(out: &std::process::Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).to_string()
}

/// Runs `xfem-cut run` on `text` written to a temp case file.
fn run_case(text: &str) -> (bool, String, tempfile::TempDir) {
    let (out, dir) = run_output(text);
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).to_string(),
        dir,
    )
}

#[test]
fn run_writes_probes_and_vtu() {
    let (ok, err, dir) = run_case(GOOD);
    assert!(ok, "{err}");
    let csv = std::fs::read_to_string(dir.path().join("out/probes.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "x,y,z,ux,uy,uz");
    assert_eq!(lines.len(), 3);
    let ux: f64 = lines[1].split(',').nth(3).unwrap().parse().unwrap();
    assert!(ux > 0.0, "gravity in +x bends the tip in +x");
    let vtu = std::fs::read_to_string(dir.path().join("out/result.vtu")).unwrap();
    assert!(vtu.contains("<VTKFile") && vtu.ends_with("</VTKFile>\n"));
}

/// The stress suite's pushed-through cube (elements invert) solved as
/// `analysis` says, with a probe.
fn pushed_through(analysis: &str) -> String {
    let analysis = format!(
        "[analysis]\nformulation = \"corotational\"\n{analysis}\n[[probe]]\npoints = [[0.5, 0.5, 1.0]]\n"
    );
    xfem_cut::study::stress::pushed_through_cube(&analysis)
}

#[test]
fn a_state_turned_inside_out_is_written_with_a_one_line_warning() {
    // The model's answer is written (it converged), and stderr says in one
    // line that it is not physical: how many groups, how much of the body,
    // when, and why. A sound scene says nothing of the kind.
    for (analysis, when) in [
        (
            "type = \"static\"\nload_steps = 20\nmax_iterations = 100",
            "in the state the solve ended with",
        ),
        (
            "type = \"dynamic\"\ndt = 0.01\nsteps = 100\nramp = 0.5\nrayleigh = { mass = 0.1, stiffness = 0.01 }\noutput_every = 10",
            "by the output frame at t = 0.500000 s",
        ),
    ] {
        let (ok, err, dir) = run_case(&pushed_through(analysis));
        assert!(ok, "{err}");
        assert!(dir.path().join("out/probes.csv").exists());
        let warnings: Vec<&str> = err.lines().filter(|l| l.starts_with("warning: ")).collect();
        assert_eq!(warnings.len(), 1, "{err}");
        let w = warnings[0];
        assert!(w.contains("case.toml: ") && w.contains(when), "{w}");
        let groups: usize = w
            .split(": ")
            .nth(2)
            .and_then(|rest| rest.split(" integration groups inverted").next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("no count of groups: {w}"));
        assert!(groups >= 1, "{w}");
        assert!(w.contains("% of the body's volume") && w.contains("not physical"), "{w}");
    }
    let (ok, err, _dir) = run_case(GOOD);
    assert!(ok && !err.contains("warning"), "{err}");
}

#[test]
fn bad_input_gives_one_line_errors_naming_the_key() {
    let cases: Vec<(String, &str)> = vec![
        (GOOD.replace("poisson = 0.35", "poisson = 0.35\nstiffness = 3"), "material.stiffness"),
        (GOOD.replace("young = 3.0e5\n", ""), "material.young"),
        (GOOD.replace("young = 3.0e5", "young = nan"), "material.young"),
        (GOOD.replace("poisson = 0.35", "poisson = 0.5"), "material.poisson"),
        (GOOD.replace("max = [inf, inf, 0.0]", "max = [inf, inf, -1.0]"), "fix[0]"),
        (GOOD.replace("type = \"static\"", "type = \"quasi\""), "analysis.type"),
        (GOOD.replace("levels = [[1, 2, 4]]", "levels = [[1, 0, 4]]"), "body.levels"),
        (GOOD.replace("[gravity]", "[gravity]\nacceleration2 = 1"), "gravity.acceleration2"),
        (GOOD.replace("[[probe]]\npoints = [[0.0, 0.03, 0.2], [0.03, 0.06, 0.2]]", "[[probe]]\npoints = [[1.0, 0.03, 0.2]]"), "key `probe[0].points`: point 0"),
        (GOOD.replace("[[probe]]\npoints = [[0.0, 0.03, 0.2], [0.03, 0.06, 0.2]]", "[[probe]]\npoints = []"), "probe[0].points"),
        (GOOD.replace("density = 1070.0", "density = 1070.0\n[[cut]]\norigin = [0.0, 0.0, 0.1]\nu = [0.0, 0.0, 0.0]\nv = [0.0, 0.06, 0.0]"), "cut[0].v"),
        ("name = \"x\"\n[body\n".to_string(), "syntax"),
        // A point, vector or box with more entries than it has (the typed
        // read took the first ones and dropped the rest).
        (GOOD.replace("acceleration = [9.81, 0.0, 0.0]", "acceleration = [9.81, 0.0, 0.0, 1e9]"), "gravity.acceleration"),
        (GOOD.replace("levels = [[1, 2, 4]]", "levels = [[1, 2, 4, 99]]"), "body.levels[0]"),
        (GOOD.replace("box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]", "box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2], [5.0, 5.0, 5.0]]"), "body.box"),
        (GOOD.replace("[[probe]]\npoints = [[0.0, 0.03, 0.2], [0.03, 0.06, 0.2]]", "[[probe]]\npoints = [[0.0, 0.03, 0.2, 1.0]]"), "probe[0].points[0]"),
        (GOOD.replace("density = 1070.0", "density = 1070.0\n[[cut]]\norigin = [0.0, 0.0, 0.1]\nu = [0.015, 0.0, 0.0, 0.0]\nv = [0.0, 0.06, 0.0]"), "cut[0].u"),
        // Two fixes prescribing different displacements at the same nodes.
        (GOOD.replace("[gravity]", "[[fix]]\nmin = [-inf, -inf, 0.0]\nmax = [inf, inf, 0.0]\ndisplacement = [0.01, 0.0, 0.0]\n[gravity]"), "fix[1].displacement"),
        // A time step whose run ends at an infinite time (solved, then its
        // frames' times could not be written).
        (GOOD.replace("type = \"static\"", "type = \"dynamic\"\ndt = 1e308\nsteps = 2"), "analysis.dt"),
        // So many load steps that their record cannot fit: named as such.
        (GOOD.replace("type = \"static\"", "type = \"static\"\nformulation = \"corotational\"\nload_steps = 9223372036854775807"), "analysis.load_steps"),
    ];
    for (text, needle) in cases {
        let (ok, err, _dir) = run_case(&text);
        assert!(!ok, "accepted bad input (expected an error about {needle})");
        assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
        assert!(err.contains(needle), "error does not name {needle}: {err}");
        assert!(
            err.contains("case.toml"),
            "error does not name the file: {err}"
        );
    }
}

/// Newmark's parameters: γ ≥ ½ and β ≥ (γ + ½)²/4 are accepted on the
/// bound itself, written out as people write it (γ = 0.6, β = 0.3025: the
/// product rounds to 0.30250000000000005, which refused it before), and
/// refused, naming the key, below it.
#[test]
fn newmark_parameters_on_the_stability_bound_are_accepted() {
    let dynamic = |newmark: &str| {
        GOOD.replace(
            "type = \"static\"",
            &format!("type = \"dynamic\"\ndt = 0.01\nsteps = 2\nnewmark = {{ {newmark} }}"),
        )
    };
    for (gamma, beta) in [(0.6, 0.3025), (0.7, 0.36), (0.5, 0.25), (0.9, 0.49)] {
        let text = dynamic(&format!("beta = {beta}, gamma = {gamma}"));
        let scene = xfem_cut::scene::Scene::parse(&text, Path::new("case.toml"));
        assert!(scene.is_ok(), "γ = {gamma}, β = {beta}: {:?}", scene.err());
    }
    let text = dynamic("beta = 0.3, gamma = 0.6");
    let err = xfem_cut::scene::Scene::parse(&text, Path::new("case.toml"))
        .expect_err("below the bound")
        .to_string();
    assert!(
        err.contains("case.toml") && err.contains("analysis.newmark") && err.contains("0.3"),
        "{err}"
    );
}

#[test]
fn a_body_free_to_move_is_refused() {
    // Only z is held: the body can slide in x and y.
    let text = GOOD.replace(
        "max = [inf, inf, 0.0]",
        "max = [inf, inf, 0.0]\ncomponents = \"z\"",
    );
    let (ok, err, _dir) = run_case(&text);
    assert!(!ok);
    assert!(
        err.contains("floats free") && err.contains("free to") && err.lines().count() == 1,
        "{err}"
    );
}

/// A probe outside the body is refused before the solve, and nothing is written.
#[test]
fn a_probe_outside_the_body_is_refused_before_anything_is_written() {
    // The second point of the second [[probe]] table.
    let text = GOOD.replace(
        "points = [[0.0, 0.03, 0.2], [0.03, 0.06, 0.2]]",
        "points = [[0.0, 0.03, 0.2]]\n[[probe]]\npoints = [[0.03, 0.06, 0.2], [0.03, 0.06, 0.25]]",
    );
    let (out, dir) = run_output(&text);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("case.toml")
            && err.contains("key `probe[1].points`: point 1 at")
            && err.contains("0.25"),
        "{err}"
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(!stdout.contains("static: solve"), "{stdout}");
    assert!(!dir.path().join("out").exists());
}

#[test]
fn shipped_uncut_cases_run() {
    for name in ["gravity_uncut", "stretch_face_uncut", "slice_uncut"] {
        let (out, dir) = run_shipped(name);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            stdout.contains("[skip] cut set-up"),
            "{name}: plan must skip the cut: {stdout}"
        );
        assert!(dir.path().join("probes.csv").exists());
    }
}

/// `GOOD` with `[[cut]]` `cut` inserted before `[gravity]`.
fn with_cut(cut: &str) -> String {
    GOOD.replace("[gravity]", &format!("[[cut]]\n{cut}\n[gravity]"))
}

const PATCH: &str = "origin = [0.0, 0.0, 0.1]\nu = [0.015, 0.0, 0.0]\nv = [0.0, 0.06, 0.0]";

/// Each `(text, key, words)`: refused with one line naming the file, the key and the words.
fn assert_refused(cases: &[(String, &str, &str)]) {
    for (text, key, words) in cases {
        let (ok, err, _dir) = run_case(text);
        assert!(!ok, "accepted bad input (expected an error about {key})");
        assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
        assert!(
            err.contains(&format!("`{key}`")),
            "error does not name {key}: {err}"
        );
        assert!(err.contains(words), "error does not say {words:?}: {err}");
        assert!(
            err.contains("case.toml"),
            "error does not name the file: {err}"
        );
    }
}

#[test]
fn scenes_too_large_for_memory_are_refused_before_allocating() {
    // Both aborted or met the OOM killer before the memory estimate.
    assert_refused(&[
        (
            GOOD.replace("levels = [[1, 2, 4]]", "levels = [[1000, 1000, 1000]]"),
            "body.levels",
            "of memory",
        ),
        (
            GOOD.replace(
                "type = \"static\"",
                "type = \"dynamic\"\ndt = 0.01\nsteps = 100000000000000",
            ),
            "analysis.steps",
            "of memory",
        ),
        (
            GOOD.replace(
                "type = \"static\"",
                "type = \"dynamic\"\ndt = 0.01\nsteps = 100000000\noutput_every = 1",
            ),
            "analysis.steps",
            "of memory",
        ),
    ]);
}

#[test]
fn cut_keys_are_checked_per_cut() {
    let blade = "blade = [[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]]";
    assert_refused(&[
        (with_cut(&format!("{PATCH}\nfront = \"sideways\"")), "cut[0].front", "sideways"),
        (with_cut(&format!("{PATCH}\ntip_radius = -1.0")), "cut[0].tip_radius", "positive"),
        (with_cut(&format!("{PATCH}\ntip_radius = nan")), "cut[0].tip_radius", "finite"),
        (with_cut(&format!("{PATCH}\nfront = \"extend\"\ntip_radius = 0.01")), "cut[0].tip_radius", "only with front"),
        (with_cut(&format!("{PATCH}\nsurface = \"a.stl\"")), "cut[0]", "exactly one"),
        (with_cut(&format!("{PATCH}\n{blade}")), "cut[0]", "exactly one"),
        (with_cut("u = [0.015, 0.0, 0.0]\nv = [0.0, 0.06, 0.0]"), "cut[0].origin", "missing"),
        (with_cut("snap = 0.01"), "cut[0].origin", "missing"),
        (with_cut("travel = [0.01, 0.0, 0.0]"), "cut[0].blade", "need a blade"),
        (with_cut(&format!("{PATCH}\nstart = 0.1")), "cut[0].start", "only with a blade"),
        (with_cut(&format!("{PATCH}\nevent_travel = 0.001")), "cut[0].event_travel", "only with a blade"),
        (with_cut(&format!("{blade}\ntravel = [0.015, 0.0, 0.0]\nstart = 0.0\nend = 0.1\nevent_travel = 0.0")), "cut[0].event_travel", "positive"),
        (with_cut(&format!("{blade}\ntravel = [0.015, 0.0, 0.0]\nstart = 0.0\nend = 0.1\nevent_travel = inf")), "cut[0].event_travel", "finite"),
        (with_cut("surface = \"no_such.stl\""), "cut[0].surface", "no such file"),
        (with_cut("surface = \"incision.obj\""), "cut[0].surface", ".stl or .msh"),
        (with_cut(blade), "cut[0].travel", "missing"),
        (with_cut(&format!("{blade}\ntravel = [0.015, 0.0, 0.0]\nend = 0.5")), "cut[0].start", "missing"),
        (with_cut(&format!("{blade}\ntravel = [0.015, 0.0, 0.0]\nstart = 0.5\nend = 0.5")), "cut[0].end", "later than start"),
        (with_cut(&format!("{blade}\ntravel = [0.015, 0.0, 0.0]\nstart = 0.5\nend = 0.1")), "cut[0].end", "later than start"),
        (with_cut(&format!("{blade}\ntravel = [0.015, 0.0, inf]\nstart = 0.0\nend = 0.1")), "cut[0].travel", "finite"),
        (with_cut(&format!("{blade}\ntravel = [0.0, 0.08, 0.0]\nstart = 0.0\nend = 0.1")), "cut[0].travel", "sweeps no area"),
        (with_cut("blade = [[0.0, 0.0, 0.1], [0.0, 0.0, 0.1]]\ntravel = [0.015, 0.0, 0.0]\nstart = 0.0\nend = 0.1"), "cut[0].blade", "zero length"),
        (with_cut(&format!("{blade}\ntravel = [0.015, 0.0, 0.0]\nstart = 0.0\nend = 0.1\npath = [[[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]]]\ntimes = [0.0]")), "cut[0].path", "not both"),
        (with_cut(&format!("{blade}\npath = [[[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]], [[0.01, -0.01, 0.1], [0.01, 0.07, 0.1]]]")), "cut[0].times", "missing"),
        (with_cut(&format!("{blade}\npath = [[[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]], [[0.01, -0.01, 0.1], [0.01, 0.07, 0.1]]]\ntimes = [0.1]")), "cut[0].times", "has 1 entries but path has 2"),
        (with_cut(&format!("{blade}\npath = [[[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]], [[0.01, -0.01, 0.1], [0.01, 0.07, 0.1]]]\ntimes = [0.3, 0.2]")), "cut[0].times", "must increase"),
        (with_cut(&format!("{blade}\npath = [[[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]], [[0.01, -0.01, 0.1], [0.01, 0.07, 0.1]]]\ntimes = [0.1, nan]")), "cut[0].times", "finite"),
        (with_cut(&format!("{blade}\npath = [[[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]], [[0.01, -0.01, 0.1], [0.01, 0.07, 0.1]]]\ntimes = [0.1, 0.2]\nstart = 0.1")), "cut[0].start", "only with travel"),
        (with_cut(&format!("{blade}\npath = [[[0.0, 0.0, 0.1], [0.0, 0.07, 0.1]], [[0.01, -0.01, 0.1], [0.01, 0.07, 0.1]]]\ntimes = [0.1, 0.2]")), "cut[0].path", "first keyframe"),
    ]);
}

#[test]
fn cut_kinds_run_or_are_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let blade = "blade = [[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]]";
    let far = "origin = [0.0, 0.0, 0.1875]\nu = [0.015, 0.0, 0.0]\nv = [0.0, 0.06, 0.0]";
    let stl = dir.path().join("incision.stl");
    std::fs::write(&stl, "solid s\nendsolid s\n").unwrap();
    let dynamic = |cut: &str| {
        with_cut(cut).replace(
            "type = \"static\"",
            "type = \"dynamic\"\ndt = 0.01\nsteps = 2",
        )
    };
    let empty = dir.path().join("empty.stl");
    std::fs::write(&empty, "").unwrap();
    let garbage = dir.path().join("garbage.stl");
    std::fs::write(&garbage, "not an stl at all").unwrap();
    let nan = dir.path().join("nan.stl");
    std::fs::write(
        &nan,
        "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0.1\nvertex NaN 0 0.1\nvertex 0 1 0.1\nendloop\nendfacet\nendsolid s\n",
    )
    .unwrap();
    assert_refused(&[
        (
            with_cut(&format!("surface = \"{}\"", stl.display())),
            "cut[0].surface",
            "no triangles",
        ),
        (
            with_cut(&format!("surface = \"{}\"", empty.display())),
            "cut[0].surface",
            "the file is empty",
        ),
        (
            with_cut(&format!("surface = \"{}\"", garbage.display())),
            "cut[0].surface",
            "neither an ASCII STL",
        ),
        (
            with_cut(&format!("surface = \"{}\"", nan.display())),
            "cut[0].surface",
            "a vertex coordinate is not a finite number",
        ),
        // The run ends at 2 × 0.01 s: a blade starting then never cuts.
        (
            dynamic(&format!("{blade}\ntravel = [0.015, 0.0, 0.0]\nstart = 0.02\nend = 0.1")),
            "cut[0].start",
            "when the run has ended (steps × dt = 2 × 0.01 = 0.02 s)",
        ),
        (
            dynamic(&format!("{blade}\npath = [[[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]], [[0.01, -0.01, 0.1], [0.01, 0.07, 0.1]]]\ntimes = [0.5, 0.6]")),
            "cut[0].times",
            "the blade starts at t = 0.5 s, when the run has ended",
        ),
    ]);
    // Each runs: the seed's front extended or tip-enriched, per-cut snaps, a
    // static blade (its completed sweep).
    for cut in [
        format!("{PATCH}\nfront = \"extend\"\nsnap = 0.01\n[[cut]]\n{far}\nsnap = 0.01"),
        format!("{PATCH}\nfront = \"tip\""),
        format!("{PATCH}\ntip_radius = 0.01"),
        format!("{PATCH}\nsnap = 0.01\n[[cut]]\n{far}\nsnap = 0.02"),
        format!("{blade}\ntravel = [0.015, 0.0, 0.0]\nstart = 0.0\nend = 0.1"),
    ] {
        for text in [with_cut(&cut), dynamic(&cut)] {
            // Two element columns: the extended seed front (x = 0.015 on the
            // node layer z = 0.1) ends on their faces, not through the only one.
            let text = text.replace("levels = [[1, 2, 4]]", "levels = [[2, 2, 8]]");
            let (ok, err, _dir) = run_case(&text);
            assert!(ok, "{cut}: {err}");
        }
    }
}

#[test]
fn the_plan_shows_the_options_the_run_uses() {
    let dynamic = |extra: &str| {
        GOOD.replace(
            "type = \"static\"",
            &format!(
                "type = \"dynamic\"\nformulation = \"corotational\"\ndt = 0.01\nsteps = 2\n{extra}"
            ),
        )
    };
    // A blade half-way through the beam during the two steps.
    let blade = |front: &str| {
        dynamic("").replace(
            "[[fix]]",
            &format!("[[cut]]\nblade = [[-0.01, -0.01, 0.1], [-0.01, 0.07, 0.1]]\ntravel = [0.025, 0.0, 0.0]\nstart = 0.0\nend = 0.02\n{front}[[fix]]"),
        )
    };
    for (text, has, lacks) in [
        (
            dynamic("mass = \"consistent\""),
            "[run ] mass (consistent",
            "lumped",
        ),
        (dynamic(""), "[run ] mass (lumped", "consistent"),
        (
            dynamic("linear_solver = \"pcg\""),
            "[run ] numeric factorisation when PCG needs more than 25 iterations",
            "every iteration",
        ),
        (
            dynamic("linear_solver = \"warped_pcg\""),
            "warped by the node rotations",
            "every iteration",
        ),
        (
            dynamic("linear_solver = \"lagged\""),
            "[run ] numeric factorisation when an iteration on it leaves more than 0.2 of the residual, or after 12 Newton iterations on one factor",
            "every iteration",
        ),
        (
            dynamic(""),
            "Anderson-accelerated (history 5) after an iteration that reduced the residual by less than 10x",
            "PCG",
        ),
        (
            dynamic(""),
            "lagged factorisation of the exact tangent",
            "PCG",
        ),
        (
            dynamic("linear_solver = \"direct\""),
            "[run ] numeric factorisation every iteration",
            "lagged",
        ),
        (
            GOOD.to_string(),
            "[skip] numeric factorisation every iteration (constant matrix",
            "[run ] mass",
        ),
        (
            blade(""),
            "[run ] cut events: the state carried over (new shifted DOFs start at zero (the field, its rates and both energies unchanged); where a tip front moved, d, v and a projected together",
            "no projection",
        ),
        (
            blade("front = \"extend\"\n"),
            "[run ] cut events: the state carried over (new shifted DOFs start at zero: the field, its rates and both energies unchanged; an extended front projects only where an event drops or recuts enriched DOFs that hold the field (a path that turns)",
            "projected together",
        ),
        (dynamic(""), "[run ] mass", "cut events"),
        // A Tet4 tip_radius ramps the blending elements from 2.5 median
        // edges on (`cut::RAMP_SPAN`; this mesh's: about 0.045 m).
        (
            with_cut(&format!("{PATCH}\ntip_radius = 0.01")),
            "tip_radius < 2.5 h (h = ",
            "blending elements ramped",
        ),
        (
            with_cut(&format!("{PATCH}\ntip_radius = 0.2")),
            "tip_radius >= 2.5 h (h = ",
            "not ramped",
        ),
        (with_cut(PATCH), "the scene has [[cut]])", "tip_radius"),
        (blade(""), "[run ] cut events (at every step the cut grows)", "event_travel"),
        (
            blade("event_travel = 0.002\n"),
            "[run ] cut events (once a blade's edge has moved its event_travel (0.002 m) since the last event",
            "every step the cut grows",
        ),
    ] {
        let (out, _dir) = run_output(&text);
        let stdout = succeeded(&out);
        let plan: String = stdout
            .lines()
            .filter(|l| l.starts_with("  ["))
            .collect::<Vec<_>>()
            .join("\n");
        assert!(plan.contains(has), "plan lacks {has:?}:\n{plan}");
        assert!(!plan.contains(lacks), "plan has {lacks:?}:\n{plan}");
    }
}

#[test]
fn a_missing_case_file_names_the_os_error() {
    let out = Command::new(bin())
        .args(["run", "/no/such/case.toml"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("/no/such/case.toml: cannot read: No such file"),
        "{err}"
    );
}

#[test]
fn a_dynamic_run_writes_a_series_that_reads_back() {
    let text = GOOD.replace(
        "type = \"static\"",
        "type = \"dynamic\"\ndt = 0.01\nsteps = 7\noutput_every = 3",
    );
    let (ok, err, dir) = run_case(&text);
    assert!(ok, "{err}");
    let out = dir.path().join("out");
    // Frames: the initial state, steps 3 and 6, and the last step.
    let series = xfem_cut::io::read_pvd(&out.join("result.pvd")).unwrap();
    let times: Vec<f64> = series.iter().map(|(t, _)| *t).collect();
    assert_eq!(times.len(), 4, "{times:?}");
    assert!((times[3] - 0.07).abs() < 1e-12, "{times:?}");
    let last = xfem_cut::io::read_vtu(&out.join(&series[3].1)).unwrap();
    let result = xfem_cut::io::read_vtu(&out.join("result.vtu")).unwrap();
    assert_eq!(last, result, "the last frame is the result");
    let first = xfem_cut::io::read_vtu(&out.join(&series[0].1)).unwrap();
    assert!(
        first.point_data["u"].1.iter().all(|&u| u == 0.0),
        "starts at rest"
    );
    let (points, disp) = xfem_cut::io::read_probes_csv(&out.join("probes.csv")).unwrap();
    assert_eq!(points.len(), 2);
    assert_eq!(points[1], nalgebra::Point3::new(0.03, 0.06, 0.2));
    assert!(disp[1].x > 0.0, "gravity in +x moves the tip in +x");
}

/// Runs into one folder keep no earlier run's outputs that would pass for
/// theirs: a shorter series removes the frames beyond its own, a static run
/// without probes the series, its frames and `probes.csv`; other files
/// stay.
#[test]
fn a_run_into_a_used_folder_leaves_none_of_the_earlier_runs_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let run = |text: &str| {
        let case = dir.path().join("case.toml");
        std::fs::write(&case, text).unwrap();
        let o = Command::new(bin())
            .arg("run")
            .arg(&case)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).to_string()
    };
    let dynamic = |steps: usize| {
        GOOD.replace(
            "type = \"static\"",
            &format!("type = \"dynamic\"\ndt = 0.01\nsteps = {steps}\noutput_every = 1"),
        )
    };
    let frames = || -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(out.join("frames"))
            .map(|d| {
                d.map(|e| e.unwrap().file_name().to_string_lossy().to_string())
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        names
    };
    run(&dynamic(3));
    assert_eq!(frames().len(), 4);
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    std::fs::write(out.join("frames/keep.txt"), "mine").unwrap();
    let stdout = run(&dynamic(1));
    assert_eq!(
        frames(),
        ["keep.txt", "result_00000.vtu", "result_00001.vtu"],
        "{stdout}"
    );
    assert!(
        stdout.contains("removed 2 file(s) an earlier run left in"),
        "{stdout}"
    );
    assert_eq!(
        xfem_cut::io::read_pvd(&out.join("result.pvd"))
            .unwrap()
            .len(),
        2
    );
    // Static, no probes: no series, no probes.
    let stdout = run(&GOOD.replace(
        "[[probe]]\npoints = [[0.0, 0.03, 0.2], [0.03, 0.06, 0.2]]\n",
        "",
    ));
    assert!(!out.join("result.pvd").exists(), "{stdout}");
    assert!(!out.join("probes.csv").exists(), "{stdout}");
    assert_eq!(frames(), ["keep.txt"]);
    assert!(out.join("notes.txt").exists() && out.join("result.vtu").exists());
    // Without the file of its own, the emptied folder goes too.
    std::fs::remove_file(out.join("frames/keep.txt")).unwrap();
    run(&dynamic(1));
    run(GOOD);
    assert!(!out.join("frames").exists());
    assert!(out.join("probes.csv").exists());
}

/// Step n of a run ends at n·dt to the last bit, not at dt summed n times
/// (20 steps of 5 ms summed: 0.10000000000000002 s, in the series' frame
/// times, the probes' and the sweeps' step times).
#[test]
fn a_run_steps_on_multiples_of_its_time_step() {
    let text = GOOD.replace(
        "type = \"static\"",
        "type = \"dynamic\"\ndt = 0.005\nsteps = 20\noutput_every = 10",
    );
    let (ok, err, dir) = run_case(&text);
    assert!(ok, "{err}");
    let series = xfem_cut::io::read_pvd(&dir.path().join("out").join("result.pvd")).unwrap();
    let times: Vec<f64> = series.iter().map(|(t, _)| *t).collect();
    assert_eq!(times, [0.0, 10.0 * 0.005, 20.0 * 0.005]);
}

#[test]
fn the_plan_names_the_mesh_given_by_the_mesh_option() {
    let text = GOOD
        .replace(
            "[[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]",
            "[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]",
        )
        .replace("[[0.0, 0.03, 0.2], [0.03, 0.06, 0.2]]", "[[0.5, 0.5, 1.0]]");
    let mesh =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/gmsh_cube_tet4_binary.msh");
    let (out, _dir) = run_on_mesh(&text, &mesh);
    let stdout = succeeded(&out);
    let line = stdout.lines().find(|l| l.contains("] mesh")).unwrap();
    assert!(
        line.contains("tet4 gmsh file")
            && line.contains("gmsh_cube_tet4_binary.msh")
            && !line.contains("structured"),
        "{line}"
    );
}

/// A Tet10 scene on a gmsh file of 4-node tetrahedra (the case's own mesh
/// list, or `--mesh`) says in its plan that the elements were made 10-node
/// ones; on the file's own 10-node elements it does not.
#[test]
fn the_plan_says_when_a_tet4_file_is_made_tet10() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let scene = |mesh: &str| {
        GOOD.replace(
            "box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]\nlevels = [[1, 2, 4]]",
            &format!("mesh = [{:?}]\nelement = \"tet10\"", fixtures.join(mesh)),
        )
        .replace("[[0.0, 0.03, 0.2], [0.03, 0.06, 0.2]]", "[[0.5, 0.5, 1.0]]")
    };
    let said = "its 4-node tetrahedra made 10-node ones";
    for (mesh, promoted) in [
        ("gmsh_cube_tet4_binary.msh", true),
        ("gmsh_cube_tet10_binary.msh", false),
    ] {
        let (out, _dir) = run_output(&scene(mesh));
        let stdout = succeeded(&out);
        let line = stdout.lines().find(|l| l.contains("] mesh")).unwrap();
        assert!(line.contains("tet10 gmsh file"), "{line}");
        assert_eq!(line.contains(said), promoted, "{mesh}: {line}");
    }
    // The same through --mesh.
    let (out, _dir) = run_on_mesh(
        &scene("gmsh_cube_tet10_binary.msh"),
        &fixtures.join("gmsh_cube_tet4_binary.msh"),
    );
    let stdout = succeeded(&out);
    let line = stdout.lines().find(|l| l.contains("] mesh")).unwrap();
    assert!(
        line.contains("given by --mesh") && line.contains(said),
        "{line}"
    );
}

/// A blade's run prints its steps' cost while the blade cuts apart from the
/// others (the sweep's events make its steps dearer: what a user weighs),
/// and the factor its last model took.
#[test]
fn a_sweep_prints_its_steps_while_cutting_apart_from_the_others() {
    let (out, _dir) = run_shipped("cut_progressive");
    let stdout = succeeded(&out);
    let line = |start: &str| {
        stdout
            .lines()
            .find(|l| l.starts_with(start))
            .unwrap_or_else(|| panic!("no line starting {start:?}: {stdout}"))
            .to_string()
    };
    // [0.1, 0.6] s at dt = 0.01 s: the 50 steps ending in (0.1, 0.6], of 300.
    let cutting = line("per step while the blades cut (t in (0.1, 0.6] s): 50 steps: ");
    let other = line("per step before and after: 250 steps: ");
    let factorisations = |l: &str| -> f64 {
        l.split(", ")
            .find_map(|p| p.strip_suffix(" factorisations a step"))
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{l}"))
    };
    // A linear scene refactorises at its events only.
    assert!(
        factorisations(&cutting) > 0.5 && factorisations(&other) < 0.1,
        "{cutting}\n{other}"
    );
    assert!(line("factor (the sweep's last): whole (").contains("AMD"));
}

/// A run that ends while its blade still cuts says so, and times its steps
/// until then (the blade starts at 0: no steps before it, none after).
#[test]
fn a_sweep_the_run_ends_before_its_end_says_so() {
    let text = GOOD.replace("levels = [[1, 2, 4]]", "levels = [[2, 2, 8]]").replace(
        "type = \"static\"",
        "type = \"dynamic\"\ndt = 0.01\nsteps = 3\n[[cut]]\nblade = [[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]]\ntravel = [0.015, 0.0, 0.0]\nstart = 0.0\nend = 0.1",
    );
    let (out, _dir) = run_output(&text);
    let stdout = succeeded(&out);
    assert!(
        stdout.contains(
            "sweep 0.0000 → 0.1000 s (the run ends at 0.0300 s, with the blades still cutting"
        ),
        "{stdout}"
    );
    assert!(
        stdout.contains("per step while the blades cut (t in (0, 0.03] s): 3 steps: "),
        "{stdout}"
    );
    assert!(!stdout.contains("per step before"), "{stdout}");
    assert!(!stdout.contains("per step after"), "{stdout}");
}

/// A blade's `path` may start with the blade itself (times and keyframes one
/// to one) or leave it out (the blade is the keyframe at times[0]): both read
/// as the same keyframes.
#[test]
fn a_blade_path_may_leave_out_the_blade_as_its_first_keyframe() {
    use xfem_cut::scene::{CutGeometry, Scene};
    let blade = "blade = [[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]]";
    let later =
        "[[0.01, -0.01, 0.1], [0.01, 0.07, 0.1]], [[0.015, -0.01, 0.1], [0.015, 0.07, 0.12]]";
    let keyframes = |path: &str| {
        let text = with_cut(&format!(
            "{blade}\npath = [{path}]\ntimes = [0.1, 0.2, 0.4]"
        ));
        let scene = Scene::parse(&text, Path::new("case.toml")).unwrap();
        match &scene.cuts[0].geometry {
            CutGeometry::Blade { keyframes, .. } => keyframes.clone(),
            _ => panic!("a blade"),
        }
    };
    let with = keyframes(&format!("[[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]], {later}"));
    let without = keyframes(later);
    assert_eq!(with.len(), 3);
    assert_eq!(with, without);
    assert_eq!(with[0].0, 0.1);
    assert_eq!(with[0].1[1].y, 0.07);
}

/// `XFEM_THREADS` runs the factorisation and the element loops on that many
/// threads: the same probes (to round-off), the run says so; a bad value is
/// refused naming the variable.
#[test]
fn xfem_threads_runs_on_more_threads_with_the_same_answer() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("case.toml");
    std::fs::write(&case, with_cut(PATCH).replace("[[1, 2, 4]]", "[[2, 4, 9]]")).unwrap();
    let run = |threads: &str, out: &str| {
        let o = Command::new(bin())
            .env("XFEM_THREADS", threads)
            .args(["run", case.to_str().unwrap(), "--out"])
            .arg(dir.path().join(out))
            .output()
            .unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).to_string(),
            String::from_utf8_lossy(&o.stderr).to_string(),
        )
    };
    let probes = |out: &str| -> Vec<f64> {
        std::fs::read_to_string(dir.path().join(out).join("probes.csv"))
            .unwrap()
            .lines()
            .skip(1)
            .flat_map(|l| {
                l.split(',')
                    .skip(3)
                    .map(|v| v.parse::<f64>().unwrap())
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    let (ok1, out1, err1) = run("1", "one");
    let (ok2, out2, err2) = run("2", "two");
    assert!(ok1 && ok2, "{err1} {err2}");
    assert!(!out1.contains("threads:"));
    assert!(out2.contains("threads: 2"), "{out2}");
    let (a, b) = (probes("one"), probes("two"));
    let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() <= 1e-12 * scale, "{x} vs {y}");
    }
    let (ok, _, err) = run("two", "bad");
    assert!(!ok);
    assert!(
        err.contains("XFEM_THREADS") && err.contains("\"two\""),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1);
}

/// A blade's run says what its precompute really is (the cut is set up at
/// the start and at each event, not before the run) and the steps' times
/// apart from the events, beside the sweep.
#[test]
fn a_blade_run_reports_its_steps_apart_from_its_events() {
    let cut = "blade = [[0.0, -0.01, 0.1], [0.0, 0.07, 0.1]]\ntravel = [0.015, 0.0, 0.0]\nstart = 0.0\nend = 0.02";
    let text = with_cut(cut)
        .replace(
            "type = \"static\"",
            "type = \"dynamic\"\ndt = 0.01\nsteps = 4",
        )
        .replace("levels = [[1, 2, 4]]", "levels = [[1, 2, 8]]");
    let (out, _dir) = run_output(&text);
    let stdout = succeeded(&out);
    let line = |start: &str| {
        stdout
            .lines()
            .find(|l| l.starts_with(start))
            .unwrap_or_else(|| panic!("no line {start:?} in:\n{stdout}"))
            .to_string()
    };
    assert!(
        line("precompute:").contains("at each cut event"),
        "{stdout}"
    );
    // The plan: the element data and the pattern are not made once.
    assert!(
        line("  [run ] element data").contains("each cut event changes"),
        "{stdout}"
    );
    assert!(
        line("  [run ] sparsity pattern").contains("each cut event that changes the pattern"),
        "{stdout}"
    );
    let steps = line("per step (Newton solve, events apart): median ");
    let ms: Vec<f64> = steps
        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter_map(|w| w.parse().ok())
        .collect();
    assert_eq!(ms.len(), 2, "{steps}");
    assert!(ms[0] > 0.0 && ms[0] <= ms[1], "{steps}");
    assert!(line("sweep ").contains("cut events"), "{stdout}");
}

/// Bad command-line arguments: one line naming the argument and the value,
/// exit 2 (clap's usage hint is not repeated); `--help` still prints help.
#[test]
fn bad_arguments_give_one_line_naming_them() {
    let case = cases().join("gravity.toml");
    for (args, words) in [
        (
            vec!["run", case.to_str().unwrap(), "--level", "abc"],
            "'abc'",
        ),
        (vec!["run"], "<CASE>"),
        (vec!["bogus"], "'bogus'"),
        (
            vec!["run", case.to_str().unwrap(), "--frobnicate"],
            "'--frobnicate'",
        ),
    ] {
        let out = Command::new(bin()).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(
            err.trim_end().lines().count(),
            1,
            "{args:?}: not one line: {err}"
        );
        assert!(err.contains(words), "{args:?}: {err}");
    }
    let help = Command::new(bin()).arg("--help").output().unwrap();
    assert!(help.status.success());
    assert!(String::from_utf8_lossy(&help.stdout).contains("Usage: xfem-cut"));
}

/// [`GOOD`] on the Tet10 gmsh mesh `mesh` (the cylinder fixtures: radius
/// 0.03, height 0.1, its bottom fixed), with these probe points.
fn on_mesh(mesh: &str, probes: &str) -> String {
    GOOD.replace(
        "box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]\nlevels = [[1, 2, 4]]",
        &format!("mesh = [\"{mesh}\"]\nelement = \"tet10\""),
    )
    .replace("[[0.0, 0.03, 0.2], [0.03, 0.06, 0.2]]", probes)
}

/// A Tet10 mesh of a curved body (gmsh's order 2 puts the mid-nodes of the
/// cylinder's boundary edges on the cylinder) solves as its straight-sided
/// twin (the same mesh written with `Mesh.SecondOrderLinear = 1`),
/// corotational, a tilted cut's front inside elements; the plan says what
/// the reader moved. Before the reader put the mid-nodes at their edges'
/// midpoints, elements were straight-sided everywhere but in the
/// corotational local displacements Rᵀ(x + d) − x, which read the curved
/// mid-nodes: the top's probes moved by 3 % and Newton took 5–8 iterations
/// a load step instead of 2–3.
#[test]
fn a_curved_tet10_mesh_solves_as_its_straight_sided_twin() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let run = |name: &str| {
        let text = on_mesh(
            &fixtures.join(name).display().to_string(),
            "[[0.0, 0.0, 0.1], [0.02, 0.0, 0.1], [-0.02, 0.0, 0.1], [0.0, 0.0, 0.0537]]",
        )
        .replace(
            "[[fix]]",
            "[[cut]]\norigin = [-0.05, -0.05, 0.0537]\nu = [0.061, 0.0, 0.02]\nv = [0.0, 0.1, 0.0]\n[[fix]]",
        )
        .replace(
            "type = \"static\"",
            "type = \"static\"\nformulation = \"corotational\"",
        );
        let (out, dir) = run_output(&text);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let (_, u) = xfem_cut::io::read_probes_csv(&dir.path().join("out/probes.csv")).unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout).to_string();
        let mesh_line = stdout
            .lines()
            .find(|l| l.contains("] mesh"))
            .unwrap()
            .to_string();
        (u, mesh_line)
    };
    let (curved, curved_plan) = run("gmsh_cylinder_tet10_curved.msh");
    let (straight, straight_plan) = run("gmsh_cylinder_tet10_straight.msh");
    assert!(
        curved_plan.contains("mid-nodes off their edges") && curved_plan.contains("straight-sided"),
        "{curved_plan}"
    );
    assert!(!straight_plan.contains("mid-nodes"), "{straight_plan}");
    let scale = straight.iter().map(|u| u.norm()).fold(0.0, f64::max);
    let worst = curved
        .iter()
        .zip(&straight)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(scale > 1e-3, "the top moves: {scale}");
    assert!(
        worst <= 1e-10 * scale,
        "curved against straight: {worst:e} of {scale:e}"
    );
}

/// A gmsh file with a node no tetrahedron uses (here a point of its own,
/// as a surface saved in the same file leaves) solves as the file without
/// it, and the plan says so. Before, the node kept DOFs no element held:
/// "the system matrix is not positive definite".
#[test]
fn a_node_no_tetrahedron_uses_is_left_out() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let text = std::fs::read_to_string(fixtures.join("gmsh_cylinder_tet10_straight.msh")).unwrap();
    let orphan = text.replacen(
        "$Nodes\n9 211 1 211\n",
        "$Nodes\n10 212 1 212\n0 1 0 1\n212\n0.5 0.5 0.5\n",
        1,
    );
    assert_ne!(orphan, text);
    let dir = tempfile::tempdir().unwrap();
    let run = |mesh: &str| {
        std::fs::write(
            dir.path().join(mesh),
            if mesh == "orphan.msh" { &orphan } else { &text },
        )
        .unwrap();
        let case = dir.path().join(format!("{mesh}.toml"));
        let out = dir.path().join(format!("{mesh}.out"));
        std::fs::write(&case, on_mesh(mesh, "[[0.0, 0.0, 0.1], [0.02, 0.0, 0.05]]")).unwrap();
        let run = Command::new(bin())
            .arg("run")
            .arg(&case)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "{mesh}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        let stdout = String::from_utf8_lossy(&run.stdout).to_string();
        let line = stdout
            .lines()
            .find(|l| l.contains("] mesh"))
            .unwrap()
            .to_string();
        (
            std::fs::read_to_string(out.join("probes.csv")).unwrap(),
            line,
        )
    };
    let (with, with_plan) = run("orphan.msh");
    let (without, without_plan) = run("plain.msh");
    assert_eq!(with, without);
    assert!(
        with_plan.contains("1 node no tetrahedron uses left out"),
        "{with_plan}"
    );
    assert!(!without_plan.contains("left out"), "{without_plan}");
}

/// `converge` on a case the reference pipeline does not know (a temp case
/// named after none of refs/make_refs.py's) ends with one line naming the
/// case file and where references come from, and a non-zero exit, before it
/// solves anything.
#[test]
fn converge_without_a_reference_says_where_references_come_from() {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("no_reference_case.toml");
    std::fs::write(
        &case,
        GOOD.replace("name = \"tiny\"", "name = \"no_reference_case\""),
    )
    .unwrap();
    let out = Command::new(bin())
        .args(["converge", case.to_str().unwrap(), "--csv"])
        .arg(dir.path().join("rows.csv"))
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("no_reference_case.toml"), "{err}");
    assert!(err.contains("refs/make_refs.py"), "{err}");
    assert!(!dir.path().join("rows.csv").exists());
}
