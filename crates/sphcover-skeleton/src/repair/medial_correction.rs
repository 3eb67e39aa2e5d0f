//! Moving sheet vertices to the middle between the part's two faces.
//!
//! On a thick plate the blurred intensity has a flat top, and a quadratic fit within ε of it
//! has almost no curvature across: the ridge (eq. 6.1) is decided by noise and wanders across
//! the plateau (on the reference wedge at 10 % noise, the output lies up to 2 voxels off the
//! middle of its 8-voxel end). The middle is better defined by the faces: along the sheet's
//! across direction `e`, the object surface `f = T` lies at `a` on one side and `b` on the
//! other, and the mid-surface point is `p + (a − b)/2 · e`. Where the faces are not both
//! within reach (a junction, where the other sheet's material continues along `e`), or the
//! shift would exceed a bound, the vertex stays: the correction only re-centres, it never
//! moves a vertex far.
//!
//! Those junction vertices are handled by [`fold_junction_vertices`] instead.

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::TriMesh;

use super::part_surface::PartSurface;

/// Parameters of [`centre_between_faces`]; lengths in voxels.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct CentringParams {
    /// Largest shift of a vertex: the correction re-centres, it never moves a vertex far.
    pub max_shift_voxels: f64,
    /// Step of the march towards the part's faces.
    pub step_voxels: f64,
}

impl Default for CentringParams {
    fn default() -> CentringParams {
        CentringParams {
            max_shift_voxels: 2.0,
            step_voxels: 0.25,
        }
    }
}

/// Parameters of [`fold_junction_vertices`]; lengths in voxels.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct JunctionFoldParams {
    /// Junction vertices go onto the tangent plane of the nearest re-centred vertex within
    /// this distance. Measured (`phantom_table`, seed 1): T-junction p95 away from the rim
    /// 0.41 → 0.40, 0.46 → 0.43, 0.40 → 0.36 at 0, 10, 30 % noise against no folding, no
    /// other phantom worse.
    pub reach_voxels: f64,
    /// Step of the march towards the part's faces.
    pub step_voxels: f64,
}

impl Default for JunctionFoldParams {
    fn default() -> JunctionFoldParams {
        JunctionFoldParams {
            reach_voxels: 4.0,
            step_voxels: 0.25,
        }
    }
}

/// Moves each vertex of `mesh` (normals = across directions) to the midpoint of the two
/// crossings of the part's surface along its normal, when both lie within the surface's
/// largest half-thickness and the shift is at most [`CentringParams::max_shift_voxels`];
/// `voxel` is the length unit of `params` (world units). Returns the number of vertices
/// moved.
pub fn centre_between_faces(
    mesh: &mut TriMesh,
    surface: &PartSurface<'_>,
    params: &CentringParams,
    voxel: f64,
) -> usize {
    let Some(normals) = &mesh.normals else {
        return 0;
    };
    let step = params.step_voxels * voxel;
    let max_shift = params.max_shift_voxels * voxel;
    let moved: Vec<Option<DVec3>> = mesh
        .vertices
        .par_iter()
        .zip(normals)
        .with_min_len(256)
        .map(|(&p, &e)| {
            let a = surface.surface_distance(p, e, step)?;
            let b = surface.surface_distance(p, -e, step)?;
            let shift = 0.5 * (a - b);
            (shift.abs() <= max_shift).then(|| p + shift * e)
        })
        .collect();
    let mut count = 0;
    for (v, m) in mesh.vertices.iter_mut().zip(moved) {
        if let Some(m) = m {
            if m != *v {
                count += 1;
            }
            *v = m;
        }
    }
    count
}

/// Projects each vertex where the part's two faces are not both found along `±e` (a
/// junction: the other plate's material continues there) onto the tangent plane of the
/// nearest vertex where both are (within [`JunctionFoldParams::reach_voxels`]; `voxel` is
/// the length unit of `params`, in world units). Near a T-junction the ridge is a fillet
/// bending from one plate into the other; each of its vertices goes to the plate it is
/// nearest to, which folds the fillet into the corner. Returns the number of vertices moved.
pub fn fold_junction_vertices(
    mesh: &mut TriMesh,
    surface: &PartSurface<'_>,
    params: &JunctionFoldParams,
    voxel: f64,
) -> usize {
    let Some(normals) = &mesh.normals else {
        return 0;
    };
    let step = params.step_voxels * voxel;
    let reach = params.reach_voxels * voxel;
    let junction: Vec<bool> = mesh
        .vertices
        .par_iter()
        .zip(normals)
        .with_min_len(256)
        .map(|(&p, &e)| {
            surface.surface_distance(p, e, step).is_none()
                || surface.surface_distance(p, -e, step).is_none()
        })
        .collect();
    let cell = reach.max(f64::MIN_POSITIVE);
    let key = |p: DVec3| (p / cell).floor().to_array().map(|c| c as i64);
    let mut grid: std::collections::HashMap<[i64; 3], Vec<u32>> = Default::default();
    for (i, p) in mesh.vertices.iter().enumerate() {
        if !junction[i] {
            grid.entry(key(*p)).or_default().push(i as u32);
        }
    }
    let vertices = &mesh.vertices;
    let moved: Vec<Option<DVec3>> = (0..vertices.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|i| {
            if !junction[i] {
                return None;
            }
            let p = vertices[i];
            let [lx, ly, lz] = key(p - DVec3::splat(reach));
            let [hx, hy, hz] = key(p + DVec3::splat(reach));
            let mut best: Option<(f64, u32)> = None;
            for x in lx..=hx {
                for y in ly..=hy {
                    for z in lz..=hz {
                        for &v in grid.get(&[x, y, z]).map(Vec::as_slice).unwrap_or_default() {
                            let d = vertices[v as usize].distance(p);
                            if d <= reach && best.is_none_or(|b| (d, v) < b) {
                                best = Some((d, v));
                            }
                        }
                    }
                }
            }
            let (_, v) = best?;
            let n = normals[v as usize].normalize_or_zero();
            Some(p - (p - vertices[v as usize]).dot(n) * n)
        })
        .collect();
    let mut count = 0;
    for (v, m) in mesh.vertices.iter_mut().zip(moved) {
        if let Some(m) = m {
            count += usize::from(m != *v);
            *v = m;
        }
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use sphcover_core::{Cover, DMat3, Kernel, LocalFunctions, PuEvaluator, QuadraticFunction};

    /// The slab's part at level ½, searched 5 units deep.
    fn part<'a>(eval: &'a PuEvaluator<'a>) -> PartSurface<'a> {
        PartSurface {
            function: eval,
            level: 0.5,
            max_half_thickness: 5.0,
        }
    }

    fn centring(max_shift_voxels: f64) -> CentringParams {
        CentringParams {
            max_shift_voxels,
            step_voxels: 0.01,
        }
    }

    fn fold(reach_voxels: f64) -> JunctionFoldParams {
        JunctionFoldParams {
            reach_voxels,
            step_voxels: 0.01,
        }
    }

    /// One large support whose function is the slab profile `1 − ((z − z0)/w)²`: the
    /// surface at level ½ lies at `z0 ± w/√2`.
    fn slab(z0: f64, w: f64) -> Cover {
        let q = QuadraticFunction {
            a: DMat3::from_diagonal(DVec3::new(0.0, 0.0, -1.0 / (w * w))),
            b: DVec3::new(0.0, 0.0, 2.0 * z0 / (w * w)),
            k: 1.0 - z0 * z0 / (w * w),
        };
        Cover::new(
            vec![DVec3::ZERO],
            vec![100.0],
            LocalFunctions::from_quadratic([q]),
            Kernel::WendlandC2,
        )
        .unwrap()
    }

    proptest! {
        /// A vertex inside a slab, off its middle, moves exactly (up to the march's linear
        /// interpolation of a quadratic) to the middle, along its normal only.
        #[test]
        fn vertices_move_to_the_middle(z0 in -1.0..1.0f64, w in 1.0..3.0f64, off in -0.6..0.6f64,
                                       x in -5.0..5.0f64, flip in any::<bool>()) {
            let cover = slab(z0, w);
            let eval = PuEvaluator::new(&cover, 1.0).unwrap();
            let e = if flip { -DVec3::Z } else { DVec3::Z };
            let mut mesh = TriMesh::new(vec![DVec3::new(x, 0.0, z0 + off * w)], vec![]);
            mesh.normals = Some(vec![e]);
            centre_between_faces(&mut mesh, &part(&eval), &centring(2.0), 1.0);
            let p = mesh.vertices[0];
            prop_assert!((p.z - z0).abs() < 1e-3 * w, "{p} vs {z0}");
            prop_assert!(p.x == x && p.y == 0.0);
        }
    }

    proptest! {
        /// In a slab, a vertex whose across direction lies in the slab's plane finds no face
        /// along it (as at a junction) and is projected onto the tangent plane of the nearest
        /// vertex across the slab (its normal finds both faces), keeping its in-plane
        /// position; that vertex stays. Beyond `reach` nothing moves.
        #[test]
        fn junction_vertices_fold_onto_the_nearest_plate(
            z0 in -1.0..1.0f64, w in 1.0..3.0f64, a in -0.5..0.5f64, b in -0.5..0.5f64,
            dx in -1.0..1.0f64, dy in -1.0..1.0f64,
        ) {
            let cover = slab(z0, w);
            let eval = PuEvaluator::new(&cover, 1.0).unwrap();
            let plate = DVec3::new(0.0, 0.0, z0 + a * w);
            let fillet = DVec3::new(dx, dy, z0 + b * w);
            let make = || {
                let mut mesh = TriMesh::new(vec![plate, fillet], vec![]);
                mesh.normals = Some(vec![DVec3::Z, DVec3::X]);
                mesh
            };
            let mut mesh = make();
            prop_assert_eq!(fold_junction_vertices(&mut mesh, &part(&eval), &fold(4.0), 1.0), usize::from(a != b));
            prop_assert_eq!(mesh.vertices[0], plate);
            let folded = mesh.vertices[1];
            prop_assert!((folded.z - plate.z).abs() < 1e-12);
            prop_assert!(folded.x == dx && folded.y == dy);
            let mut far = make();
            let reach = 0.99 * plate.distance(fillet);
            prop_assert_eq!(fold_junction_vertices(&mut far, &part(&eval), &fold(reach), 1.0), 0);
            prop_assert_eq!(far.vertices[1], fillet);
        }
    }

    #[test]
    fn shifts_beyond_the_bound_are_refused() {
        let cover = slab(0.0, 2.0);
        let eval = PuEvaluator::new(&cover, 1.0).unwrap();
        let mut mesh = TriMesh::new(vec![DVec3::new(0.0, 0.0, 1.0)], vec![]);
        mesh.normals = Some(vec![DVec3::Z]);
        assert_eq!(
            centre_between_faces(&mut mesh, &part(&eval), &centring(0.5), 1.0),
            0
        );
        assert_eq!(mesh.vertices[0].z, 1.0);
        assert_eq!(
            centre_between_faces(&mut mesh, &part(&eval), &centring(2.0), 1.0),
            1
        );
    }
}
