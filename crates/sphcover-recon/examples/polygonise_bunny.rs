//! Times polygonisation of a dense sample of a mesh (the bundled bunny by default).
//!
//! ```text
//! cargo run --release -p sphcover-recon --example polygonise_bunny -- [MESH] [POINTS] [DEPTH] [OUT.ply] [NOISE]
//! ```
//!
//! The mesh's triangles are sampled area-uniformly (deterministically) with their face
//! normals, the sample is normalised to the unit frame, a surface cover is built with the
//! default parameters, and its zero set is polygonised from all samples at
//! `step = box / 2^DEPTH`. NOISE (default 0) moves every sample by Gaussian noise of that
//! standard deviation per axis, as a fraction of the box diagonal, after the normals were
//! taken. Prints the time of each stage and the topology of the result.

use std::path::PathBuf;
use std::time::Instant;

use sphcover_core::io::{ReadOptions, WriteOptions, read_mesh, write_mesh};
use sphcover_core::this_process::process_cpu_seconds;
use sphcover_core::{
    DVec3, MeshTopology, Normalisation, PuEvaluator, SurfaceCoverParams, SurfaceSamples, TriMesh,
    build_surface_cover,
};
use sphcover_recon::{GridStep, PolygoniseParams, polygonise};

/// A uniform value in [0, 1) from an integer (splitmix64), so the sample needs no RNG crate.
fn unit(i: u64) -> f64 {
    let mut z = i.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// `n` points spread area-uniformly over the triangles, with the face normals.
fn sample(mesh: &TriMesh, n: usize) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|v| mesh.vertices[v as usize]);
        total += 0.5 * (b - a).cross(c - a).length();
        cumulative.push(total);
    }
    let mut points = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    for i in 0..n as u64 {
        let target = unit(3 * i) * total;
        let t = cumulative
            .partition_point(|&c| c < target)
            .min(cumulative.len() - 1);
        let [a, b, c] = mesh.triangles[t].map(|v| mesh.vertices[v as usize]);
        let (mut u, mut v) = (unit(3 * i + 1), unit(3 * i + 2));
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        points.push(a + (b - a) * u + (c - a) * v);
        normals.push((b - a).cross(c - a).normalize_or_zero());
    }
    (points, normals)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/bunny_npm.off")
    });
    let n: usize = args.get(1).map_or(Ok(362_000), |s| s.parse())?;
    let depth: u32 = args.get(2).map_or(Ok(9), |s| s.parse())?;

    let mesh = read_mesh(&path, &ReadOptions::default())?;
    let (mut points, normals) = sample(&mesh, n);
    let norm = Normalisation::of_points(&points).ok_or("the mesh has no extent")?;
    norm.points_to_unit(&mut points);
    let noise: f64 = args.get(4).map_or(Ok(0.0), |s| s.parse())?;
    if noise > 0.0 {
        let sigma = noise * sphcover_core::Aabb::from_points(&points).diagonal();
        for (i, p) in points.iter_mut().enumerate() {
            // Box–Muller from two hashed uniforms per axis.
            let g = |k: u64| {
                let (u, v) = (
                    unit(1 << 40 | (6 * i as u64 + 2 * k)),
                    unit(1 << 40 | (6 * i as u64 + 2 * k + 1)),
                );
                (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
            };
            *p += DVec3::new(g(0), g(1), g(2)) * sigma;
        }
    }

    let start = Instant::now();
    let (cover, _) = build_surface_cover(
        &SurfaceSamples::new(&points, &normals),
        &SurfaceCoverParams::default(),
    )?;
    let cover_time = start.elapsed();
    let eval = PuEvaluator::new(&cover, 1.0)?;
    let params = PolygoniseParams {
        step: GridStep::Depth(depth),
        ..PolygoniseParams::default()
    };
    let start = Instant::now();
    let cpu_start = process_cpu_seconds();
    let (mut surface, stats) = polygonise(&eval, &points, &params)?;
    let polygonise_time = start.elapsed();
    let cpu = process_cpu_seconds().zip(cpu_start).map(|(b, a)| b - a);
    let topo = MeshTopology::of(&surface);
    println!(
        "{n} points, {} supports (cover {cover_time:.2?}); depth {depth}: step {:.3e}",
        cover.len(),
        stats.step
    );
    println!(
        "polygonise {polygonise_time:.2?} wall, {} CPU (search {:.2?}, of which f at {} grid vertices {:.2?}; extraction {:.2?}); {} vertices, {} triangles",
        cpu.map_or("?".to_string(), |c| format!("{c:.2}s")),
        stats.search_time,
        stats.grid_evaluations,
        stats.evaluation_time,
        stats.extraction_time,
        surface.vertices.len(),
        surface.triangles.len()
    );
    println!(
        "seeds projected {}, searched {}, dropped {}",
        stats.seeds_projected, stats.seeds_searched, stats.seeds_dropped
    );
    println!(
        "components {}, euler {}, watertight {}, manifold {}, consistently wound {}, multi-sheet cells {}, split vertices {}",
        topo.components,
        topo.euler_characteristic(),
        topo.is_watertight(),
        topo.is_manifold(),
        topo.inconsistent_edges == 0,
        stats.multi_sheet_cells,
        stats.split_vertices
    );
    if let Some(out) = args.get(3) {
        surface.to_input(&norm);
        write_mesh(&PathBuf::from(out), &surface, &WriteOptions::default())?;
    }
    Ok(())
}
