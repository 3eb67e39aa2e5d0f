//! The dual complex of a cover: the tetrahedra of the regular triangulation of the support
//! centres (weights `r²`) whose orthocentre has non-positive power (thesis §3.5).
//!
//! The method is described on [`dual_complex()`].

use rayon::prelude::*;
use sphcover_core::DVec3;

use crate::error::TetraError;
use crate::predicates::{Point, orthocentre_power_sign};
use crate::regular::{
    INFINITE_VERTEX, NO_TET, RegularTriangulation, TriangulationParams, TriangulationStats,
    VertexStatus,
};

/// Options of [`dual_complex`].
#[derive(Clone, Debug)]
pub struct DualComplexParams {
    /// Radius shrink `σ_t`: triangulate with radii `σ_t·r` (thesis §3.5.2). `1.0` disables it.
    pub shrink: f64,
    /// Seed of the triangulation's insertion order and walk.
    pub seed: u64,
}

impl Default for DualComplexParams {
    fn default() -> Self {
        Self {
            shrink: 0.75,
            seed: TriangulationParams::default().seed,
        }
    }
}

/// The tetrahedra of the dual complex of a cover.
#[derive(Clone, Debug)]
pub struct DualComplex {
    /// Tetrahedra as support indices, positively oriented ([`crate::predicates::orient3d`]
    /// of the centres is positive), in the triangulation's slot order.
    pub tets: Vec<[u32; 4]>,
    /// For each tetrahedron, the index in `tets` of the neighbour across the face opposite
    /// vertex `i`, or [`NO_TET`] when that face is on the boundary of the complex.
    pub neighbours: Vec<[u32; 4]>,
    /// Per support: what became of it in the triangulation (hidden supports have no power
    /// cell and appear in no tetrahedron).
    pub status: Vec<VertexStatus>,
    /// Counters of the triangulation.
    pub triangulation: TriangulationStats,
}

impl DualComplex {
    /// Per support: `true` when it is not a vertex of the triangulation (hidden or a
    /// duplicated centre).
    pub fn hidden(&self) -> Vec<bool> {
        self.status
            .iter()
            .map(|s| *s != VertexStatus::Vertex)
            .collect()
    }
}

/// Builds the dual complex of the cover `(centres, radii)` with the radius shrink and seed of
/// `params`.
///
/// Thesis definition: lift each ball to a 4D ball of the same centre and radius; four
/// supports form a tetrahedron when their 4D spheres share a point inside no other 4D sphere.
/// The shared points are `(x*, ±u)` with `x*` the orthocentre and `u² = −power(x*)`, and
/// "inside no other sphere" is the emptiness of the regular triangulation. So the
/// tetrahedra are the finite cells of the regular triangulation with `power(x*) ≤ 0`.
///
/// Boundary case: we keep `power(x*) = 0` (the four balls meet in a single point), as the
/// reference construction does (CGAL's regular triangulation filtered by `power ≤ 0`); the
/// sign is decided exactly.
///
/// The radius shrink `σ_t` (thesis §3.5.2, default 0.75) triangulates with radii `σ_t·r`:
/// fewer supports are hidden and tetrahedra near the boundary are less skinny; vertices stay
/// at the true centres.
///
/// Errors: an invalid shrink, mismatched lengths, a negative or non-finite radius, and those
/// of [`RegularTriangulation::new`] (non-finite centres, magnitudes spanning more than the
/// exact predicates support, centres that do not span 3D). Scaling the centres and radii by a
/// power of two changes nothing in the result.
pub fn dual_complex(
    centres: &[DVec3],
    radii: &[f64],
    params: &DualComplexParams,
) -> Result<DualComplex, TetraError> {
    Ok(dual_complex_of(&cover_triangulation(
        centres, radii, params,
    )?))
}

/// The regular triangulation of the cover `(centres, radii)` with the radius shrink and seed
/// of `params`, after checking them.
pub(crate) fn cover_triangulation(
    centres: &[DVec3],
    radii: &[f64],
    params: &DualComplexParams,
) -> Result<RegularTriangulation, TetraError> {
    if !(params.shrink.is_finite() && params.shrink > 0.0) {
        return Err(TetraError::InvalidShrink(params.shrink));
    }
    if centres.len() != radii.len() {
        return Err(TetraError::LengthMismatch {
            points: centres.len(),
            weights: radii.len(),
        });
    }
    if let Some(i) = radii.iter().position(|r| !(r.is_finite() && *r >= 0.0)) {
        return Err(TetraError::InvalidWeight { index: i });
    }
    let points: Vec<Point> = centres.iter().map(|c| c.to_array()).collect();
    // From the radii rather than from weights: the weights are formed after the scaling into
    // the exact range, so radii whose squares under- or overflow in these units still work.
    RegularTriangulation::from_spheres(
        &points,
        radii,
        params.shrink,
        &TriangulationParams {
            seed: params.seed,
            ..Default::default()
        },
    )
}

/// The dual complex of an existing triangulation: its finite tetrahedra whose orthocentre has
/// non-positive power with respect to the triangulation's own weights.
///
/// The sign is decided on the triangulation's scaled copy of its input, where the degree-8
/// orthocentre polynomial is exact (module `regular::domain`); in the caller's units it could
/// underflow for tiny inputs.
pub fn dual_complex_of(tri: &RegularTriangulation) -> DualComplex {
    complex_of(tri, |cell| {
        let p = cell.map(|v| tri.point(v));
        let w = cell.map(|v| tri.scaled_weight(v));
        orthocentre_power_sign(p, w) <= 0
    })
}

/// The finite tetrahedra of `tri` that `kept` accepts (given their vertices), in slot order,
/// with their adjacency within the complex.
pub(crate) fn complex_of(
    tri: &RegularTriangulation,
    kept: impl Fn([u32; 4]) -> bool + Sync,
) -> DualComplex {
    let slots = tri.num_slots();

    // Decide each slot independently (deterministic whatever the thread count), 64 slots to
    // a word; a kept slot's index in the complex is the number of kept slots before it.
    let kept = |t: u32| {
        let cell = tri.tet(t);
        if cell[0] >= INFINITE_VERTEX - 1 || cell.contains(&INFINITE_VERTEX) {
            return false;
        }
        kept(cell)
    };
    let keep: Vec<u64> = (0..slots.div_ceil(64) as u32)
        .into_par_iter()
        .with_min_len(64)
        .map(|word| {
            let first = 64 * word;
            let last = (first + 64).min(slots as u32);
            (first..last).fold(0u64, |bits, t| bits | (u64::from(kept(t)) << (t - first)))
        })
        .collect();
    let mut before = Vec::with_capacity(keep.len() + 1);
    let mut count = 0u32;
    for bits in &keep {
        before.push(count);
        count += bits.count_ones();
    }
    // The complex's index of slot `t`, or NO_TET when it is not kept.
    let index = |t: u32| {
        let (word, bit) = ((t / 64) as usize, t % 64);
        let bits = keep[word];
        if bits >> bit & 1 == 0 {
            return NO_TET;
        }
        before[word] + (bits & ((1u64 << bit) - 1)).count_ones()
    };
    let kept_slots = || {
        keep.iter().enumerate().flat_map(|(word, &bits)| {
            (0..64u32)
                .filter(move |&bit| bits >> bit & 1 == 1)
                .map(move |bit| 64 * word as u32 + bit)
        })
    };
    let mut tets = Vec::with_capacity(count as usize);
    tets.extend(kept_slots().map(|t| tri.tet(t)));
    let mut neighbours = Vec::with_capacity(count as usize);
    neighbours.extend(kept_slots().map(|t| tri.neighbours(t).map(index)));
    DualComplex {
        tets,
        neighbours,
        status: tri.vertex_status().to_vec(),
        triangulation: tri.stats().clone(),
    }
}
