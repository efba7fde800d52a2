//! The quick families of the stress suite must pass (the slow ones, dt and
//! 10⁴ undamped steps, run in `make report`; the 10⁴-step damped cut beam is
//! in tests/xfem.rs).

use xfem_cut::study::stress::run_suite;

fn all_pass(family: &str, at_least: usize) {
    let rows = run_suite(family, |_| {});
    assert!(rows.len() >= at_least, "{family}: only {} rows", rows.len());
    for r in &rows {
        assert!(
            r.pass,
            "{} | {}: {} (criterion: {})",
            r.test, r.setting, r.measured, r.criterion
        );
    }
}

/// Cuts 0 … 1e-12 … 1e-2 h from a node layer, snapped and not, Tet4 and Tet10: finite, and
/// the field moves by no more than the geometry does (≤ 3δ relative).
#[test]
fn cuts_near_node_layers_change_the_result_only_as_much_as_the_geometry() {
    all_pass("near-node", 18);
}

#[test]
fn freed_fragments_fall_and_tumble_rigidly() {
    all_pass("fragment", 4);
}

#[test]
fn twists_of_90_and_180_degrees_converge() {
    all_pass("rotation", 2);
}

#[test]
fn inverted_elements_keep_proper_rotations_and_finite_states() {
    all_pass("inverted", 2);
}

#[test]
fn nearly_incompressible_material_solves_accurately() {
    all_pass("poisson", 10);
}

/// Crack fronts (tip enrichment, topological and geometric) 1e-3 … 1e-12 h
/// beside a node line, a face plane and interior faces, Tet4 and Tet10:
/// finite, relative residual ≤ 1e-8, the front's nodes tip-enriched,
/// condition estimates reported.
#[test]
fn fronts_near_nodes_edges_and_faces_solve_accurately() {
    all_pass("front-near", 48);
}
