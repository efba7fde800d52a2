//! Equality with FEniCSx on the same pre-cut gmsh meshes (`make refs-test` builds them):
//! our Tet4 = FEniCSx P1 and our Tet10 = FEniCSx P2 to 1e-10 relative, for every beam case.

use std::path::Path;
use xfem_cut::mesh::ElementKind;
use xfem_cut::run::solve_scene;
use xfem_cut::scene::Scene;
use xfem_cut::study::reference::{out_dir, read_reference, same_mesh_difference};

const CASES: [(&str, &str); 6] = [
    ("gravity", "beam_crack"),
    ("stretch", "beam_crack"),
    ("bend", "beam_crack"),
    ("stretch_face", "beam_crack"),
    ("bend_face", "beam_crack"),
    ("slice", "slice_precut"),
];

fn need(path: &Path) {
    assert!(
        path.exists(),
        "{} is missing: run `make refs-test` (or `make test`, which runs it)",
        path.display()
    );
}

#[test]
fn linear_solves_on_precut_meshes_equal_fenicsx() {
    let cases_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let mut worst: f64 = 0.0;
    for (case, family) in CASES {
        for level in ["L0", "L1"] {
            let msh = out_dir().join(format!("meshes/{family}/{level}.msh"));
            need(&msh);
            for (element, file) in [
                (ElementKind::Tet4, "p1.vtu"),
                (ElementKind::Tet10, "p2.vtu"),
            ] {
                let vtu = out_dir().join(format!("{case}/{family}_{level}/{file}"));
                need(&vtu);
                let mut scene = Scene::load(&cases_dir.join(format!("{case}.toml"))).unwrap();
                // The crack is in the mesh: solve it as plain FEM.
                scene.cuts.clear();
                scene.element = element;
                let ours = solve_scene(&scene, 0, Some(&msh), false).unwrap();
                let reference = read_reference(&vtu).unwrap();
                let diff = same_mesh_difference(&ours.model.mesh, &ours.d, &reference).unwrap();
                println!(
                    "{case} {level} {}: relative difference {diff:.2e}",
                    element.name()
                );
                assert!(
                    diff <= 1e-10,
                    "{case} {level} {}: differs from FEniCSx by {diff:e}",
                    element.name()
                );
                worst = worst.max(diff);
            }
        }
    }
    println!("largest relative difference to FEniCSx: {worst:.2e}");
}

#[test]
fn corotational_solve_equals_scikit_fem() {
    let cases_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    // The large-deformation cases on the pre-cut meshes, Tet4 against P1 and
    // Tet10 against P2, on the reference's load path (steps, scale, tolerance
    // from its json): L0 always (`make refs-test`), P1 on L1–L2 and P2 on L1
    // where `make refs` built them.
    let mut compared = Vec::new();
    for (case, degree, level) in [
        ("stretch_face", 1, "L0"),
        ("bend_face", 1, "L0"),
        ("stretch_face", 2, "L0"),
        ("bend_face", 2, "L0"),
        ("stretch_face", 1, "L1"),
        ("bend_face", 1, "L1"),
        ("stretch_face", 1, "L2"),
        ("bend_face", 1, "L2"),
        ("stretch_face", 2, "L1"),
        ("bend_face", 2, "L1"),
    ] {
        let msh = out_dir().join(format!("meshes/beam_crack/{level}.msh"));
        let vtu = out_dir().join(format!("{case}/beam_crack_{level}/corot_p{degree}.vtu"));
        if level != "L0" && !vtu.exists() {
            continue;
        }
        need(&msh);
        need(&vtu);
        let info: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(vtu.with_extension("json")).unwrap())
                .unwrap();
        let scale = info["scale"].as_f64().unwrap_or(1.0);
        let steps = info["load_steps"].as_u64().unwrap() as usize;
        let tolerance = info["tolerance"].as_f64().unwrap_or(1e-11);
        let mut scene = Scene::load(&cases_dir.join(format!("{case}.toml"))).unwrap();
        scene.cuts.clear();
        scene.formulation = xfem_cut::model::Formulation::Corotational;
        if degree == 2 {
            scene.element = xfem_cut::mesh::ElementKind::Tet10;
        }
        for fix in &mut scene.fixes {
            fix.displacement = fix.displacement.map(|u| u * scale);
        }
        scene.gravity = scene.gravity.map(|g| g * scale);
        // The reference's path: its load steps, Newton (exact tangent, as the
        // reference) to its tolerance with backtracking.
        scene.analysis = xfem_cut::scene::Analysis::Static(xfem_cut::statics::StaticOptions {
            load_steps: steps,
            tolerance,
            max_iterations: 300,
            exact_tangent: true,
            ..Default::default()
        });
        let ours = solve_scene(&scene, 0, Some(&msh), false).unwrap();
        let reference = read_reference(&vtu).unwrap();
        let diff = same_mesh_difference(&ours.model.mesh, &ours.d, &reference).unwrap();
        println!(
            "{case} {level} P{degree} (load x{scale}) corotational vs scikit-fem: {diff:.2e}, Newton iterations {:?}",
            ours.iterations
        );
        assert!(
            diff <= 1e-8,
            "{case} {level} P{degree}: differs from scikit-fem by {diff:e}"
        );
        compared.push(format!("{case} {level} P{degree}"));
    }
    println!("compared with scikit-fem: {}", compared.join(", "));
}
