//! Comparison with the reference dual complexes in `fixtures/tetra/` (CGAL's regular
//! triangulation filtered by orthocentre power ≤ 0; see the README there).
mod common;
use common::*;
use sphcover_tetra::{DualComplexParams, dual_complex, predicates::orient3d};

fn run(name: &str, shrink: f64, reference: &str) {
    let (c, r) = read_spheres(&format!("{name}.spheres.txt"));
    let params = DualComplexParams {
        shrink,
        ..Default::default()
    };
    let dc = dual_complex(&c, &r, &params).unwrap();
    for t in &dc.tets {
        let p = t.map(|i| c[i as usize].to_array());
        assert_eq!(orient3d(&p[0], &p[1], &p[2], &p[3]), 1);
    }
    let ours = canonical(&dc.tets);
    let theirs = read_tets(reference);
    let same = ours == theirs;
    let missing = theirs
        .iter()
        .filter(|t| ours.binary_search(t).is_err())
        .count();
    let extra = ours
        .iter()
        .filter(|t| theirs.binary_search(t).is_err())
        .count();
    println!(
        "{name} x{shrink}: ours {} theirs {} identical {same} missing {missing} extra {extra}; hidden {}",
        ours.len(),
        theirs.len(),
        dc.triangulation.hidden
    );
    let (vo, vt) = (total_volume(&c, &ours), total_volume(&c, &theirs));
    println!(
        "volume {vo} vs {vt}; euler {} vs {}",
        euler_of_tets(&ours),
        euler_of_tets(&theirs)
    );
    assert!(same, "{name}: {missing} missing, {extra} extra");
}

#[test]
fn random_3k_identical() {
    run("random_3k", 1.0, "random_3k.tets.txt");
}

#[test]
fn grid_10_identical() {
    run("grid_10", 1.0, "grid_10.tets.txt");
}

#[test]
fn octree_torus_identical() {
    run("octree_torus_d6", 1.0, "octree_torus_d6.tets.txt");
}

#[test]
fn octree_torus_shrunk_identical() {
    run("octree_torus_d6", 0.75, "octree_torus_d6_s075.tets.txt");
}
