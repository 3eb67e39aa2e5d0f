//! Scans generated a block of points at a time, for scans larger than memory: the defects of
//! [`generate_scan`](crate::scan_simulation::generate_scan) except the virtual scanner, with
//! each block drawn from its own random stream.
//!
//! Block `b` draws from a generator seeded by the scan's seed and `b`, so the scan depends
//! only on its parameters and the block size, and each block can be made alone. It has the
//! distribution of [`generate_scan`](crate::scan_simulation::generate_scan)'s scan, not its
//! points: the outliers are mixed into each block rather than shuffled over the whole scan.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use sphcover_core::{DVec3, PointCloud, TriMesh};

use crate::scan_simulation::{
    ScanError, ScanParams, check_params, gaussian3, random_unit, rotate_about_random_perpendicular,
    surface_defects,
};
use crate::surface_sampling::SurfaceSampler;

/// Generates the scan `params` describe (which must not ask for the virtual scanner) in
/// blocks of `block` surface points (the last one shorter), each with its share of outliers,
/// and hands each block to `visit` in order; returns the number of points. Memory holds one
/// block.
///
/// ```
/// use sphcover_evaluation::ground_truth_meshes::icosphere;
/// use sphcover_evaluation::scan_blocks::generate_scan_in_blocks;
/// use sphcover_evaluation::scan_simulation::ScanCase;
/// use sphcover_core::DVec3;
///
/// let sphere = icosphere(DVec3::ZERO, 1.0, 3);
/// let params = ScanCase::Outliers1.params(10_000, 7);
/// let mut blocks = Vec::new();
/// let total = generate_scan_in_blocks(&sphere, &params, 4000, |b| {
///     blocks.push(b.len());
///     Ok::<(), std::convert::Infallible>(())
/// })
/// .unwrap()
/// .unwrap();
/// assert_eq!(blocks, [4040, 4040, 2020]);
/// assert_eq!(total, 10_100);
/// ```
pub fn generate_scan_in_blocks<E>(
    mesh: &TriMesh,
    params: &ScanParams,
    block: usize,
    mut visit: impl FnMut(PointCloud) -> Result<(), E>,
) -> Result<Result<usize, E>, ScanError> {
    check_params(params)?;
    if params.scanner.is_some() {
        return Err(ScanError::InvalidParameter(sphcover_core::ParameterError {
            name: "scanner",
            value: 1.0,
            expected: "none: the virtual scanner casts its rays over the whole scan at once",
        }));
    }
    let block = block.max(1);
    let sampler = SurfaceSampler::new(mesh)?;
    let bbox = mesh.bounding_box();
    let diagonal = bbox.diagonal();
    let mut rng = Pcg64::seed_from_u64(params.seed);
    let (in_hole, gradient) = surface_defects(mesh, params, &sampler, &mut rng);
    let margin = DVec3::splat(params.outlier_margin * diagonal);
    let (lo, hi) = (bbox.min - margin, bbox.max + margin);
    let sigma = params.noise * diagonal;
    let max_rotation = params.normal_rotation_degrees.to_radians();

    let mut total = 0;
    for (b, first) in (0..params.count).step_by(block).enumerate() {
        let surface = block.min(params.count - first);
        let mut rng =
            Pcg64::seed_from_u64(params.seed ^ (b as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let outliers = (params.outliers * surface as f64).round() as usize;
        let mut positions = Vec::with_capacity(surface + outliers);
        let mut normals = Vec::with_capacity(surface + outliers);
        let max_attempts = surface.saturating_mul(100).saturating_add(1000);
        let mut attempts = 0;
        while positions.len() < surface {
            if attempts == max_attempts {
                return Err(ScanError::RejectionExhausted {
                    accepted: first + positions.len(),
                    wanted: params.count,
                    attempts,
                });
            }
            attempts += 1;
            let s = sampler.sample(&mut rng);
            let keep = gradient
                .as_ref()
                .is_none_or(|g| rng.random::<f64>() < g(s.position));
            if keep && !in_hole(s.position) {
                let mut p = s.position;
                if sigma > 0.0 {
                    p += sigma * gaussian3(&mut rng);
                }
                let mut n = s.normal;
                if max_rotation > 0.0 {
                    let angle = rng.random::<f64>() * max_rotation;
                    n = rotate_about_random_perpendicular(n, angle, &mut rng);
                }
                positions.push(p);
                normals.push(n);
            }
        }
        for _ in 0..outliers {
            let u = DVec3::new(rng.random(), rng.random(), rng.random());
            // Each outlier takes a random place in the block.
            let at = rng.random_range(0..=positions.len());
            positions.insert(at, lo + u * (hi - lo));
            normals.insert(at, random_unit(&mut rng));
        }
        total += positions.len();
        let cloud = PointCloud {
            positions,
            normals: Some(normals),
            ..PointCloud::default()
        };
        if let Err(e) = visit(cloud) {
            return Ok(Err(e));
        }
    }
    Ok(Ok(total))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ground_truth_meshes::icosphere;
    use crate::scan_simulation::ScanCase;

    fn blocks_of(params: &ScanParams, block: usize) -> Vec<PointCloud> {
        let sphere = icosphere(DVec3::ZERO, 1.0, 4);
        let mut blocks = Vec::new();
        generate_scan_in_blocks(&sphere, params, block, |b| {
            blocks.push(b);
            Ok::<(), ()>(())
        })
        .unwrap()
        .unwrap();
        blocks
    }

    #[test]
    fn blocks_are_reproducible_and_lie_on_the_surface_or_are_outliers() {
        let params = ScanCase::Combined.params(20_000, 3);
        let (a, b) = (blocks_of(&params, 5000), blocks_of(&params, 5000));
        assert_eq!(a, b);
        let points: Vec<DVec3> = a.iter().flat_map(|c| c.positions.clone()).collect();
        // 5% outliers, noise 0.25% of the diagonal (2√3 here): the rest lie within 5σ.
        let sigma = 0.0025 * 2.0 * 3f64.sqrt();
        let off = points
            .iter()
            .filter(|p| (p.length() - 1.0).abs() > 5.0 * sigma)
            .count();
        assert!(off <= 1000 && off > 800, "{off} points off the sphere");
        assert_eq!(points.len(), 21_000);
        let other_seed = blocks_of(&ScanCase::Combined.params(20_000, 4), 5000);
        assert_ne!(a, other_seed);
    }

    #[test]
    fn the_virtual_scanner_is_refused() {
        let sphere = icosphere(DVec3::ZERO, 1.0, 2);
        let params = ScanCase::Scanner.params(1000, 0);
        let refused = generate_scan_in_blocks(&sphere, &params, 100, |_| Ok::<(), ()>(()));
        assert!(matches!(refused, Err(ScanError::InvalidParameter(_))));
    }
}
