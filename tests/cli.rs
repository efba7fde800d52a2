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

/// Runs `xfem-cut run` on `text` written to a temp case file.
fn run_case(text: &str) -> (bool, String, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let case = dir.path().join("case.toml");
    std::fs::write(&case, text).unwrap();
    let out = Command::new(bin())
        .arg("run")
        .arg(&case)
        .arg("--out")
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
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
        (GOOD.replace("[[probe]]\npoints = [[0.0, 0.03, 0.2], [0.03, 0.06, 0.2]]", "[[probe]]\npoints = [[1.0, 0.03, 0.2]]"), "probe 0"),
        (GOOD.replace("density = 1070.0", "density = 1070.0\n[[cut]]\norigin = [0.0, 0.0, 0.1]\nu = [0.0, 0.0, 0.0]\nv = [0.0, 0.06, 0.0]"), "cut[0].v"),
        ("name = \"x\"\n[body\n".to_string(), "syntax"),
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
        err.contains("not positive definite") || err.contains("floats free"),
        "{err}"
    );
}

#[test]
fn shipped_uncut_cases_run() {
    for name in ["gravity_uncut", "stretch_face_uncut", "slice_uncut"] {
        let dir = tempfile::tempdir().unwrap();
        let out = Command::new(bin())
            .arg("run")
            .arg(cases().join(format!("{name}.toml")))
            .arg("--out")
            .arg(dir.path())
            .output()
            .unwrap();
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
