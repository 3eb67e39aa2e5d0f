use super::*;
use crate::pipeline::{reconstruct, reconstruct_streamed};
use sphcover_core::{MeshTopology, StopRequest};
use sphcover_evaluation::{torus, torus_signed_distance};

fn scratch(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("sphcover-streamed-{name}-{}", std::process::id()))
}

fn tilted_torus(n: usize) -> (PointCloud, impl Fn(DVec3) -> f64) {
    let tilt = glam::DMat3::from_rotation_x(0.4) * glam::DMat3::from_rotation_y(0.3);
    let mut cloud = torus(0.3, 0.12, n);
    for p in &mut cloud.positions {
        *p = tilt * *p;
    }
    for n in cloud.normals.as_mut().into_iter().flatten() {
        *n = tilt * *n;
    }
    (cloud, move |p: DVec3| {
        torus_signed_distance(0.3, 0.12, tilt.transpose() * p)
    })
}

fn streamed(cloud: &dyn PointBlocks, tiling: &Tiling, dir: &Path) -> StreamedReconstruction {
    reconstruct_streamed(
        cloud,
        &SequentialStreamedTiles,
        &ReconParams::default(),
        tiling,
        dir,
        &|_| {},
        &StopRequest::new(),
    )
    .unwrap()
}

/// Asserts that `mesh` is one closed torus whose worst vertex (by `truth`) is within 1.5
/// times the single run's.
fn assert_a_torus_like(
    mesh: &TriMesh,
    single: &TriMesh,
    truth: &impl Fn(DVec3) -> f64,
    tiles: [usize; 3],
) {
    let topology = MeshTopology::of(mesh);
    assert!(
        topology.is_closed_oriented_manifold(),
        "{tiles:?}: {topology:?}"
    );
    assert_eq!(
        (topology.components, topology.euler_characteristic()),
        (1, 0),
        "{tiles:?}"
    );
    let worst = |m: &TriMesh| {
        m.vertices
            .iter()
            .map(|&v| truth(v).abs())
            .fold(0.0, f64::max)
    };
    let (error, single_error) = (worst(mesh), worst(single));
    assert!(
        error < 1.5 * single_error + 1e-3,
        "{tiles:?}: worst vertex {error:.2e} against the single run's {single_error:.2e}"
    );
}

fn area(m: &TriMesh) -> f64 {
    m.triangles
        .iter()
        .map(|t| sphcover_core::triangle_area(m, t))
        .sum()
}

#[test]
fn streamed_tiles_join_into_one_closed_surface_as_accurate_as_the_single_run() {
    let (cloud, truth) = tilted_torus(12_000);
    let single = reconstruct(&cloud, &ReconParams::default(), &|_| {}).unwrap();
    let dir = scratch("torus");
    for tiles in [[2, 2, 2], [3, 1, 2], [1, 4, 1]] {
        let tiling = Tiling { tiles, halo: 0.1 };
        let result = streamed(&cloud, &tiling, &dir);
        assert_a_torus_like(&result.mesh, &single.mesh, &truth, tiles);
        let own: usize = result.stats.tiles.iter().map(|t| t.own_samples).sum();
        assert_eq!(own, cloud.len(), "{tiles:?}");
        let ratio = area(&result.mesh) / area(&single.mesh);
        assert!((ratio - 1.0).abs() < 0.01, "{tiles:?}: area ratio {ratio}");
        let spacing = result.stats.scan.spacing / single.stats.scan.spacing;
        assert!(
            (spacing - 1.0).abs() < 0.05,
            "{tiles:?}: spacing ratio {spacing}"
        );
    }
    // Every tile directory went with its run.
    let left = std::fs::read_dir(&dir).unwrap().count();
    assert_eq!(left, 0);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_file_streams_to_the_surface_of_the_same_points_in_memory_at_any_thread_count() {
    let (cloud, _) = tilted_torus(6000);
    let dir = scratch("file");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("torus.ply");
    io::write_point_cloud(&path, &cloud, &io::WriteOptions::default()).unwrap();
    let file = ScanFile {
        block: 1000,
        ..ScanFile::new(&path)
    };
    let tiling = Tiling::cubes(2);
    let in_memory = streamed(&cloud, &tiling, &dir);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| streamed(&file, &tiling, &dir))
    };
    let (one, three) = (run(1), run(3));
    assert_eq!(one.mesh, in_memory.mesh);
    assert_eq!(one.mesh, three.mesh);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn outliers_far_and_near_are_left_out() {
    let (mut cloud, truth) = tilted_torus(8000);
    // Uniform outliers in the box (5%), and two far away along +x.
    let mut s = 7u64;
    let mut next = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    for _ in 0..400 {
        cloud
            .positions
            .push(DVec3::new(next(), next(), next()) * 1.0);
        cloud.normals.as_mut().unwrap().push(DVec3::Z);
    }
    cloud
        .positions
        .extend([DVec3::new(5.0, 0.1, 0.0), DVec3::new(5.2, -0.1, 0.1)]);
    cloud.normals.as_mut().unwrap().extend([DVec3::X; 2]);
    let dir = scratch("outliers");
    let result = streamed(&cloud, &Tiling::cubes(2), &dir);
    let topology = MeshTopology::of(&result.mesh);
    assert_eq!(
        (topology.components, topology.euler_characteristic()),
        (1, 0)
    );
    assert!(result.stats.scan.isolated_count >= 2);
    let error = result
        .mesh
        .vertices
        .iter()
        .map(|&v| truth(v).abs())
        .fold(0.0, f64::max);
    assert!(error < 0.02, "worst vertex {error:.3e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn scans_without_normals_get_them_oriented_across_tiles() {
    let (mut cloud, truth) = tilted_torus(12_000);
    cloud.normals = None;
    let single = reconstruct(&cloud, &ReconParams::default(), &|_| {}).unwrap();
    let dir = scratch("no-normals");
    for tiles in [[2, 2, 2], [1, 4, 1]] {
        let result = streamed(&cloud, &Tiling { tiles, halo: 0.1 }, &dir);
        assert!(result.stats.normals_estimated);
        assert_a_torus_like(&result.mesh, &single.mesh, &truth, tiles);
    }
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Tasks run in reverse order, each through bytes as another process would get and return
/// them.
struct ThroughBytes;

impl StreamedTileRunner for ThroughBytes {
    fn run(
        &self,
        tasks: &[StreamedTile],
        params: &ReconParams,
    ) -> Result<Vec<StreamedTileProduct>, ReconError> {
        let mut out = vec![None; tasks.len()];
        for (t, task) in tasks.iter().enumerate().rev() {
            let sent = StreamedTile::from_bytes(&task.to_bytes())?;
            let product = streamed_tile_function(&sent, params)?;
            out[t] = Some(StreamedTileProduct::from_bytes(&product.to_bytes())?);
        }
        Ok(out.into_iter().flatten().collect())
    }
}

#[test]
fn any_runner_gives_the_sequential_runs_surface() {
    let (cloud, _) = tilted_torus(5000);
    let dir = scratch("runner");
    let tiling = Tiling {
        tiles: [2, 1, 3],
        halo: 0.1,
    };
    let here = streamed(&cloud, &tiling, &dir);
    let there = reconstruct_streamed(
        &cloud,
        &ThroughBytes,
        &ReconParams::default(),
        &tiling,
        &dir,
        &|_| {},
        &StopRequest::new(),
    )
    .unwrap();
    assert_eq!(here.mesh, there.mesh);
    assert_eq!(here.stats.supports, there.stats.supports);
    std::fs::remove_dir_all(&dir).unwrap();
}
