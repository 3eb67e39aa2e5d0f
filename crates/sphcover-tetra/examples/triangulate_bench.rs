//! Times the dual complex of an adaptive octree cover of a torus.
//!
//! `cargo run --release -p sphcover-tetra --example triangulate_bench -- N [shrink]` builds the
//! smallest octree cover with at least `N` supports, triangulates it (radius shrink
//! `shrink`, default 0.75), filters the dual complex, builds the `TetMesh`, and prints the
//! times, the counts, the process CPU time, the peak resident memory (VmHWM) after the filter
//! and at the end, and checksums of the dual complex's tetrahedra (to compare versions).

#[path = "common/octree_torus.rs"]
mod octree_torus;

use std::time::Instant;

use octree_torus::octree_torus_cover_of_size;
use sphcover_core::this_process::{peak_resident_bytes, process_cpu_seconds};
use sphcover_tetra::{RegularTriangulation, TetMesh, TriangulationParams, dual_complex_of};

/// FNV-1a over the vertex indices: a fingerprint to compare the output of two versions.
fn checksum(tets: impl Iterator<Item = [u32; 4]>) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for t in tets {
        for v in t {
            h = (h ^ v as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

/// The tetrahedra as sorted vertex quadruples, sorted: independent of slot order.
fn canonical_tets(tets: &[[u32; 4]]) -> Vec<[u32; 4]> {
    let mut all: Vec<[u32; 4]> = tets
        .iter()
        .map(|t| {
            let mut s = *t;
            s.sort_unstable();
            s
        })
        .collect();
    all.sort_unstable();
    all
}

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(100_000);
    let shrink: f64 = args.next().and_then(|a| a.parse().ok()).unwrap_or(0.75);
    let (depth, band, centres, radii) = octree_torus_cover_of_size(n);
    let base_memory = peak_resident_bytes().unwrap_or(0);
    println!(
        "octree torus cover: depth {depth}, band {band:.3}, {} supports, shrink {shrink}",
        centres.len()
    );
    let points: Vec<[f64; 3]> = centres.iter().map(|c| c.to_array()).collect();
    let weights: Vec<f64> = radii.iter().map(|r| (r * shrink) * (r * shrink)).collect();
    let c0 = process_cpu_seconds().unwrap_or(0.0);
    let t0 = Instant::now();
    let tri = RegularTriangulation::new(&points, &weights, &TriangulationParams::default())
        .expect("triangulation");
    let t1 = Instant::now();
    let c1 = process_cpu_seconds().unwrap_or(0.0);
    let dc = dual_complex_of(&tri);
    let t2 = Instant::now();
    let c2 = process_cpu_seconds().unwrap_or(0.0);
    let s = tri.stats();
    println!(
        "triangulation: {:.3} s ({} vertices, {} hidden, {} finite tets, {:.1} walk steps/point, {:.1} conflict tets/point, {} deferred to one-by-one insertion)",
        (t1 - t0).as_secs_f64(),
        s.vertices,
        s.hidden,
        s.finite_tets,
        s.walk_steps as f64 / s.points as f64,
        s.conflict_tets as f64 / s.points as f64,
        s.deferred
    );
    println!(
        "filter: {:.3} s ({} dual tets)",
        (t2 - t1).as_secs_f64(),
        dc.tets.len()
    );
    println!(
        "triangulate + filter: {:.3} s wall, {:.2} s CPU (triangulation {:.2} s CPU, filter {:.2} s CPU)",
        (t2 - t0).as_secs_f64(),
        c2 - c0,
        c1 - c0,
        c2 - c1
    );
    if let Some(peak) = peak_resident_bytes() {
        println!(
            "peak memory after the filter {:.1} MB ({:.0} bytes per sphere above the cover itself)",
            peak as f64 / 1e6,
            (peak - base_memory) as f64 / centres.len() as f64
        );
    }
    println!(
        "dual tets checksum: {:016x} in slot order, {:016x} as a sorted set",
        checksum(dc.tets.iter().copied()),
        checksum(canonical_tets(&dc.tets).into_iter())
    );
    drop(tri);
    let t3 = Instant::now();
    let mesh = TetMesh::from_dual_complex(&dc);
    println!(
        "tet mesh: {:.3} s ({} vertices, {} edges, {} tets)",
        t3.elapsed().as_secs_f64(),
        mesh.vertices.len(),
        mesh.edges.len(),
        mesh.tets.len()
    );
    println!(
        "tet mesh CPU: {:.2} s",
        process_cpu_seconds().unwrap_or(0.0) - c2
    );
    if let Some(peak) = peak_resident_bytes() {
        println!(
            "peak memory with the tet mesh {:.1} MB ({:.0} bytes per sphere above the cover itself)",
            peak as f64 / 1e6,
            (peak - base_memory) as f64 / centres.len() as f64
        );
    }
}
