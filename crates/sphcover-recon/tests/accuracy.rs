//! Accuracy of the default reconstruction on analytic shapes: clean scans must not be
//! smoothed away, while noisy normals and uniform outliers stay harmless.
//!
//! Clean and outlier scans are sampled from the bundled bunny (`fixtures/real/bunny00.off`,
//! the benchmark's ground truth), whose detail is what over-smoothing loses; the error of a
//! mesh vertex is its distance to the mesh. Noisy normals are tried on a torus, where the
//! distance is exact. The clean bound sits between what the defaults reach and what the
//! weakly fitted setting (μ_n = 1, μ_p = 4, no gates) reaches, so a return to over-smoothing
//! fails it; the refined vertices (the default) must beat the zero set.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::path::PathBuf;

use sphcover_core::io::{ReadOptions, read_mesh};
use sphcover_core::{DVec3, MeshTopology, PointCloud, TriMesh};
use sphcover_evaluation::surface_sampling::SurfaceSampler;
use sphcover_evaluation::torus_signed_distance;
use sphcover_evaluation::triangle_bvh::TriangleBvh;
use sphcover_recon::{DiffusionParams, ReconParams, reconstruct};

const MAJOR: f64 = 1.0;
const MINOR: f64 = 0.2;

fn bunny() -> TriMesh {
    bundled_mesh("bunny00.off")
}

/// A mesh of `fixtures/real/`.
fn bundled_mesh(name: &str) -> TriMesh {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/real")
        .join(name);
    read_mesh(&path, &ReadOptions::default()).expect("bundled mesh")
}

/// The distance of each vertex of `mesh` to `truth`.
fn vertex_distances(mesh: &TriMesh, truth: &TriMesh) -> Vec<f64> {
    let bvh = TriangleBvh::new(truth).expect("bvh");
    mesh.vertices
        .iter()
        .map(|&v| {
            bvh.closest_point(v)
                .expect("closest")
                .distance_squared
                .sqrt()
        })
        .collect()
}

/// `n` area-uniform samples of `mesh` with its face normals.
fn mesh_scan(mesh: &TriMesh, n: usize, seed: u64) -> PointCloud {
    let sampler = SurfaceSampler::new(mesh).expect("sampler");
    let samples = sampler.samples(n, &mut Pcg64::seed_from_u64(seed));
    let mut cloud = PointCloud::from_positions(samples.iter().map(|s| s.position).collect());
    cloud.normals = Some(samples.iter().map(|s| s.normal).collect());
    cloud
}

/// Mean and largest distance of the reconstruction's vertices to `truth`, relative to its
/// bounding-box diagonal, and the reconstruction's components (watertightness asserted).
fn mesh_score(cloud: &PointCloud, params: &ReconParams, truth: &TriMesh) -> (f64, f64, usize) {
    let rec = reconstruct(cloud, params, &|_| {}).expect("reconstruction");
    assert!(
        rec.stats.watertight,
        "not watertight: {} components, {} isolated samples, {} outliers",
        rec.stats.components, rec.stats.scan.isolated_count, rec.stats.outliers
    );
    let diagonal = sphcover_core::Aabb::from_points(&truth.vertices).diagonal();
    let d: Vec<f64> = vertex_distances(&rec.mesh, truth)
        .into_iter()
        .map(|d| d / diagonal)
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let max = d.iter().copied().fold(0.0, f64::max);
    (mean, max, rec.stats.components)
}

/// `n` area-uniform samples of the torus with outward unit normals.
fn torus_scan(n: usize, seed: u64) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut points = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    while points.len() < n {
        let u: f64 = rng.random::<f64>() * std::f64::consts::TAU;
        let v: f64 = rng.random::<f64>() * std::f64::consts::TAU;
        // The area element is ∝ (R + r cos v): rejection keeps the sampling area-uniform.
        if rng.random::<f64>() * (MAJOR + MINOR) > MAJOR + MINOR * v.cos() {
            continue;
        }
        let normal = DVec3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
        let centre = DVec3::new(MAJOR * u.cos(), MAJOR * u.sin(), 0.0);
        points.push(centre + MINOR * normal);
        normals.push(normal);
    }
    (points, normals)
}

/// Rotates `n` by an angle uniform in `[0, max_angle]` about a random axis orthogonal to it.
fn tilt(n: DVec3, max_angle: f64, rng: &mut Pcg64) -> DVec3 {
    let helper = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let a = n.cross(helper).normalize();
    let b = n.cross(a);
    let phi: f64 = rng.random::<f64>() * std::f64::consts::TAU;
    let axis = a * phi.cos() + b * phi.sin();
    let angle = rng.random::<f64>() * max_angle;
    n * angle.cos() + axis.cross(n) * angle.sin()
}

/// Mean and largest distance of the mesh's vertices to the torus, in units of the box's
/// longest edge (the unit frame), and the mesh's components.
fn score(mesh: &TriMesh) -> (f64, f64, usize) {
    let extent = 2.0 * (MAJOR + MINOR);
    let d: Vec<f64> = mesh
        .vertices
        .iter()
        .map(|&v| torus_signed_distance(MAJOR, MINOR, v).abs() / extent)
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let max = d.iter().copied().fold(0.0, f64::max);
    (mean, max, MeshTopology::of(mesh).components)
}

fn run(cloud: &PointCloud, params: &ReconParams) -> (f64, f64, usize) {
    let rec = reconstruct(cloud, params, &|_| {}).expect("reconstruction");
    assert!(
        rec.stats.watertight,
        "not watertight: {} components, {} triangles",
        rec.stats.components, rec.stats.triangles
    );
    score(&rec.mesh)
}

/// The weakly fitted setting: μ_n = 1, μ_p = 4 and no gates, which smooths clean scans away.
fn weak_fitting() -> ReconParams {
    ReconParams {
        diffusion: DiffusionParams {
            normal_fit: 1.0,
            normal_coherence_exponent: 0.0,
            position_fit: 4.0,
            confidence_power: 0.0,
            ..DiffusionParams::default()
        },
        ..ReconParams::default()
    }
}

#[test]
fn clean_scan_is_not_smoothed_away() {
    let truth = bunny();
    let cloud = mesh_scan(&truth, 30_000, 1);
    // The diffused function's zero set, with the defaults and with weak fitting.
    let zero_set = |params: ReconParams| ReconParams {
        refine: None,
        ..params
    };
    let (mean, max, components) = mesh_score(&cloud, &zero_set(ReconParams::default()), &truth);
    let (weak_mean, weak_max, _) = mesh_score(&cloud, &zero_set(weak_fitting()), &truth);
    // The vertices refined onto the samples.
    let (refined_mean, refined_max, refined_components) =
        mesh_score(&cloud, &ReconParams::default(), &truth);
    eprintln!(
        "clean: mean {mean:.3e} max {max:.3e}; weak fitting {weak_mean:.3e} {weak_max:.3e}; \
         refined {refined_mean:.3e} {refined_max:.3e}"
    );
    assert_eq!((components, refined_components), (1, 1));
    assert!(mean < MEAN_BOUND, "mean vertex error {mean:.3e}");
    assert!(
        weak_mean > MEAN_BOUND,
        "the bound no longer separates: {weak_mean:.3e}"
    );
    assert!(
        refined_mean < REFINED_MEAN_BOUND,
        "refined mean vertex error {refined_mean:.3e}"
    );
}

#[test]
fn noisy_normals_do_not_cost_more_than_weak_fitting() {
    let (points, normals) = torus_scan(20_000, 2);
    let mut rng = Pcg64::seed_from_u64(3);
    let tilted: Vec<DVec3> = normals
        .iter()
        .map(|&n| tilt(n, 60f64.to_radians(), &mut rng))
        .collect();
    let mut cloud = PointCloud::from_positions(points);
    cloud.normals = Some(tilted);
    let (mean, _, components) = run(&cloud, &ReconParams::default());
    let (weak_mean, _, _) = run(&cloud, &weak_fitting());
    eprintln!("normals60: mean {mean:.3e}; weak fitting {weak_mean:.3e}");
    assert_eq!(components, 1);
    assert!(mean <= weak_mean, "{mean:.3e} against {weak_mean:.3e}");
}

#[test]
fn uniform_outliers_stay_out_of_the_strong_fit() {
    let truth = bunny();
    let mut cloud = mesh_scan(&truth, 30_000, 4);
    let clean = mesh_score(&cloud, &ReconParams::default(), &truth);
    // 1% outliers, uniform in the bounding box, with random normals.
    let bbox = sphcover_core::Aabb::from_points(&truth.vertices);
    let mut rng = Pcg64::seed_from_u64(5);
    let normals = cloud.normals.as_mut().expect("normals");
    for _ in 0..300 {
        let u = DVec3::new(rng.random(), rng.random(), rng.random());
        cloud.positions.push(bbox.min + u * bbox.extent());
        let n = DVec3::new(
            rng.random::<f64>() - 0.5,
            rng.random::<f64>() - 0.5,
            rng.random::<f64>() - 0.5,
        );
        normals.push(n.normalize_or(DVec3::Z));
    }
    let (mean, max, components) = mesh_score(&cloud, &ReconParams::default(), &truth);
    eprintln!(
        "outliers1: mean {mean:.3e} max {max:.3e}; clean {:.3e} {:.3e}",
        clean.0, clean.1
    );
    assert_eq!(components, 1);
    assert!(
        mean < 1.5 * clean.0,
        "mean {mean:.3e} against {:.3e}",
        clean.0
    );
    assert!(max < 4.0 * clean.1, "max {max:.3e} against {:.3e}", clean.1);
}

/// Between the defaults' and the weak fitting's mean vertex error on the clean bunny
/// (1.16e-4 and 1.57e-4 with ε = 2.5e-3).
const MEAN_BOUND: f64 = 1.35e-4;
/// Between the refined vertices' and the zero set's mean error on the clean bunny
/// (7.1e-5 and 1.16e-4).
const REFINED_MEAN_BOUND: f64 = 9.5e-5;

#[test]
fn thin_walls_keep_their_surface_through_the_graph_cut() {
    // The generated housing (walls 0.7–2.4 mm, gaps 1.3–1.5 mm), sampled noise-free as in
    // the benchmarks: the cut finds supports on its walls inconsistent, but their samples
    // fit them; zeroing them raised bumps of up to 2.5 mm on the 1.6 mm walls.
    let truth = sphcover_evaluation::thin_walled_part::thin_walled_housing()
        .solid
        .boundary_mesh();
    let cloud = mesh_scan(&truth, 200_000, 3);
    let rec = reconstruct(&cloud, &ReconParams::default(), &|_| {}).expect("reconstruction");
    assert!(rec.stats.watertight && rec.stats.components == 1);
    let mut d = vertex_distances(&rec.mesh, &truth);
    d.sort_by(f64::total_cmp);
    let p99 = d[d.len() * 99 / 100];
    let genus = (2 - rec.stats.euler_characteristic) / 2;
    eprintln!(
        "thin walls: {} inconsistent, {} confirmed; 99th percentile distance {p99:.3} mm, largest {:.3}; genus {genus}",
        rec.stats.inconsistent_supports,
        rec.stats.confirmed_supports,
        d[d.len() - 1]
    );
    assert!(p99 < 0.3, "99th percentile distance {p99:.3} mm");
    // The part's genus is 11. Fitting both faces of the 0.7 mm fins at once made the blend
    // thin them until they broke: genus 60 and more. Fitting a rib's side with its top (the
    // samples within 120° of the face's normal instead of 60°) tilted planes across the gaps
    // between ribs and joined neighbouring tops. On this scan the polygonisation also fills a
    // tunnel one grid vertex wide through a wall (`PolygoniseParams::fill_pinholes`).
    assert_eq!(genus, 11);
}

#[test]
fn noise_outliers_and_holes_together_on_sharp_and_genus_two_shapes() {
    // Noise of 0.3% of the diagonal raises ε; the 5% uniform outliers that the isolation test
    // left in then opened the fandisk's surface (F@1% 0.84 at 100K samples).
    use sphcover_evaluation::recon_metrics::{ReconMetricsParams, score_reconstruction};
    use sphcover_evaluation::scan_simulation::{ScanCase, generate_scan};
    for name in ["fandisk.off", "femur.off"] {
        let truth = bundled_mesh(name);
        for seed in [1, 2] {
            let scan =
                generate_scan(&truth, &ScanCase::Combined030.params(60_000, seed)).expect("scan");
            let rec =
                reconstruct(&scan.cloud, &ReconParams::default(), &|_| {}).expect("reconstruction");
            let params = ReconMetricsParams {
                samples: 50_000,
                ..ReconMetricsParams::default()
            };
            let scores = score_reconstruction(&rec.mesh, &truth, &params).expect("scores");
            let f1 = scores.fscore_at(0.01).expect("F@1%");
            eprintln!(
                "{name} seed {seed}: F@1% {f1:.4}, Chamfer {:.4}%, {} components",
                scores.chamfer, scores.topology.components
            );
            assert!(
                scores.topology.watertight && scores.topology.components == 1,
                "{name} seed {seed}"
            );
            assert!(f1 >= 0.99, "{name} seed {seed}: F@1% {f1:.4}");
        }
    }
}

#[test]
fn holes_in_a_closed_object_are_closed_by_default() {
    // The benchmarks' holes (five of radius 3% of the diagonal) lie within reach of the
    // samples around them: the default keeps the surface across them, closed.
    use sphcover_evaluation::scan_simulation::{ScanCase, generate_scan};
    let truth = bunny();
    let scan = generate_scan(&truth, &ScanCase::Holes.params(30_000, 3)).expect("scan");
    let rec = reconstruct(&scan.cloud, &ReconParams::default(), &|_| {}).expect("reconstruction");
    assert_eq!(rec.stats.unseen_area_fraction, 0.0);
    assert!(rec.stats.watertight && rec.stats.components == 1);
}

#[test]
fn a_single_view_of_plates_before_a_wall_keeps_both_layers_and_their_slits() {
    // Five plates floating before a wall, seen by one camera with a projector: the output
    // holds the wall beside the plates (smoothing the plates' and the wall's supports
    // together left 10.7% of a 100K scan's samples uncovered), invents nothing, and joins
    // no plate to the wall across the shadows.
    use sphcover_evaluation::ground_truth_meshes::plates_before_wall;
    use sphcover_evaluation::invented_surface::{InputPoints, InventedSurfaceParams};
    use sphcover_evaluation::scan_simulation::{ScanCase, generate_scan};
    use sphcover_evaluation::shadow_slits::shadow_slits;
    let truth = plates_before_wall();
    let params = ScanCase::SingleView.params(30_000, 2);
    let scan = generate_scan(&truth, &params).expect("scan");
    let rec = reconstruct(&scan.cloud, &ReconParams::default(), &|_| {}).expect("recon");
    assert!(rec.stats.scan.one_view);
    let points = InputPoints::new(&scan.cloud.positions).expect("points");
    let scores = points
        .score(&rec.mesh, &InventedSurfaceParams::default())
        .expect("score");
    assert!(scores.uncovered_fraction <= 0.01, "{scores:?}");
    assert!(scores.invented_fraction <= 0.02, "{scores:?}");
    let slits = shadow_slits(&truth, &params, &rec.mesh).expect("slits");
    assert!(slits.rows.len() > 100, "{}", slits.rows.len());
    assert_eq!(slits.bridged_off_truth(1, usize::MAX, 2.0), 0);
    // Tiles keep the layers apart as the whole scan does (each is told the scan is one view).
    let tiled = sphcover_recon::reconstruct_tiled(
        &scan.cloud,
        &ReconParams::default(),
        &sphcover_recon::Tiling::cubes(2),
        &|_| {},
    )
    .expect("tiled recon");
    let scores = points
        .score(&tiled.mesh, &InventedSurfaceParams::default())
        .expect("score");
    assert!(scores.uncovered_fraction <= 0.01, "tiled: {scores:?}");
}

#[test]
fn a_single_view_is_not_wrapped_in_invented_surface() {
    // One camera with a projector beside it: the back is unseen and depth jumps cast
    // shadows. By default at most 2% of the output lies farther than 3 nearest-neighbour
    // distances from every sample (with a margin of three sample spacings, not one, and
    // shadows closed as holes, the bunny's and the femur's kept 5.5% and 11%).
    use sphcover_evaluation::invented_surface::{InputPoints, InventedSurfaceParams};
    use sphcover_evaluation::scan_simulation::{ScanCase, generate_scan};
    for (name, truth) in [("bunny", bunny()), ("femur", bundled_mesh("femur.off"))] {
        let scan = generate_scan(&truth, &ScanCase::SingleView.params(30_000, 1)).expect("scan");
        let rec = reconstruct(&scan.cloud, &ReconParams::default(), &|_| {}).expect("recon");
        assert!(rec.stats.scan.one_view, "{name}");
        assert!(rec.stats.unseen_area_fraction > 0.3, "{name}");
        let points = InputPoints::new(&scan.cloud.positions).expect("points");
        let invented = points
            .score(&rec.mesh, &InventedSurfaceParams::default())
            .expect("score");
        assert!(
            invented.invented_fraction <= 0.02,
            "{name}: {:.4}",
            invented.invented_fraction
        );
    }
}
