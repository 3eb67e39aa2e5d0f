//! Builds the surface cover of a mesh sampled uniformly by area, and prints the counts and
//! the stage timings (thesis §3.4.1, Table 5.1: the bunny at 362K points and ε = 2.5e-3).
//!
//! ```text
//! cargo run --release -p sphcover-core --example surface_cover -- MESH.off N_POINTS EPS [SEED]
//! ```
//!
//! The mesh must be closed and consistently oriented (its normals are made to point outward
//! by the sign of its enclosed volume). Points are sampled with a fixed seed, each carrying
//! the normal of its triangle.

use rand::{Rng, SeedableRng};
use sphcover_core::io::{ReadOptions, read_mesh};
use sphcover_core::{
    DVec3, PointCloud, PuEvaluator, SurfaceCoverParams, build_surface_cover_from_cloud,
};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 || args.len() > 4 {
        eprintln!("usage: surface_cover MESH N_POINTS EPS [SEED]");
        return ExitCode::from(2);
    }
    let path = PathBuf::from(&args[0]);
    let (Ok(n), Ok(eps)) = (args[1].parse::<usize>(), args[2].parse::<f64>()) else {
        eprintln!("N_POINTS must be an integer and EPS a number");
        return ExitCode::from(2);
    };
    let seed = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(0u64);
    let mesh = match read_mesh(&path, &ReadOptions::default()) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(1);
        }
    };
    if mesh.triangles.is_empty() {
        eprintln!("{}: no triangles to sample", path.display());
        return ExitCode::from(1);
    }
    let cloud = sample(&mesh.vertices, &mesh.triangles, n, seed);
    println!(
        "{}: {} vertices, {} triangles; sampled {} points (seed {seed})",
        path.display(),
        mesh.vertices.len(),
        mesh.triangles.len(),
        cloud.len()
    );
    let params = SurfaceCoverParams {
        eps,
        // As `sphcover cover` does; NO_SAMPLING_STOP=1 gives the library default.
        sampling_stop: std::env::var_os("NO_SAMPLING_STOP").is_none(),
        ..SurfaceCoverParams::default()
    };
    let threads = rayon::current_num_threads();
    let start = Instant::now();
    let (cover, norm, stats) = match build_surface_cover_from_cloud(&cloud, &params) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(1);
        }
    };
    let elapsed = start.elapsed();
    let t = stats.timings;
    println!(
        "eps {eps}, {threads} threads: {:.3} s",
        elapsed.as_secs_f64()
    );
    println!(
        "  supports: {} before expansion, {} after ({} grown)",
        stats.supports_before_expansion, stats.supports_after_expansion, stats.grown_supports
    );
    println!(
        "  octants per level: {:?}\n  leaves per level:  {:?}\n  grown leaves: {}, empty leaves: {}, balance octants: {}, fits: {} (and {} octants bounded unfitted), over eps: {}, max error {:.3e}",
        stats.octants_per_level,
        stats.leaves_per_level,
        stats.grown_leaves,
        stats.empty_leaves,
        stats.balance_octants,
        stats.fits,
        stats.bounded_octants,
        stats.supports_over_eps,
        stats.max_error
    );
    println!(
        "  stages: index {:.3} s, octree {:.3} s, growth {:.3} s, elimination {:.3} s",
        t.index.as_secs_f64(),
        t.octree.as_secs_f64(),
        t.growth.as_secs_f64(),
        t.elimination.as_secs_f64()
    );
    // Spot check: |f| at a subset of the samples, in unit lengths.
    let eval = match PuEvaluator::new(&cover, 1.0) {
        Ok(e) => e,
        Err(e) => {
            eprintln!("{e}");
            return ExitCode::from(1);
        }
    };
    let step = (cloud.len() / 2000).max(1);
    let worst = cloud
        .positions
        .iter()
        .step_by(step)
        .map(|&p| eval.value(norm.to_unit(p)).map_or(f64::INFINITY, f64::abs))
        .fold(0.0, f64::max);
    println!(
        "  max |f| over every {step}th sample: {worst:.3e} (2 eps = {:.3e})",
        2.0 * eps
    );
    ExitCode::SUCCESS
}

/// `n` points uniform by area, each with its triangle's outward unit normal.
fn sample(vertices: &[DVec3], triangles: &[[u32; 3]], n: usize, seed: u64) -> PointCloud {
    let corners = |t: &[u32; 3]| t.map(|i| vertices[i as usize]);
    let volume: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = corners(t);
            a.dot(b.cross(c))
        })
        .sum();
    let flip = if volume < 0.0 { -1.0 } else { 1.0 };
    let mut cumulative = Vec::with_capacity(triangles.len());
    let mut total = 0.0;
    for t in triangles {
        let [a, b, c] = corners(t);
        total += 0.5 * (b - a).cross(c - a).length();
        cumulative.push(total);
    }
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut positions = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    while positions.len() < n {
        let target = rng.random::<f64>() * total;
        let k = cumulative
            .partition_point(|&c| c <= target)
            .min(triangles.len() - 1);
        let [a, b, c] = corners(&triangles[k]);
        let normal = (b - a).cross(c - a).normalize_or_zero() * flip;
        if normal == DVec3::ZERO {
            continue;
        }
        let (r1, r2) = (rng.random::<f64>().sqrt(), rng.random::<f64>());
        positions.push(a * (1.0 - r1) + b * (r1 * (1.0 - r2)) + c * (r1 * r2));
        normals.push(normal);
    }
    PointCloud {
        positions,
        normals: Some(normals),
        ..PointCloud::default()
    }
}
