//! The function a polygonisation meshes: one cover's partition-of-unity function, or the
//! functions of the tiles of a tiled reconstruction, each used inside its own box.
//!
//! The search, the extraction and the seed projection only ask for values, gradients and
//! blends at batches of points, so a piecewise function is one more way of answering them:
//! each point is answered by the piece whose box holds it. A grid vertex is evaluated once,
//! by one piece, so the cells on both sides of a seam read the same values and the mesh is
//! closed across it.

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::{Aabb, PuEvaluator, ValueGradient};

use super::PolygoniseError;

/// One piece: a cover's function and, optionally, one value per support to blend at the
/// vertices.
#[derive(Clone, Copy)]
pub struct FieldPiece<'e> {
    /// The piece's function.
    pub eval: &'e PuEvaluator<'e>,
    /// One value per support of the piece's cover, blended at the vertices.
    pub blend: Option<&'e [f64]>,
}

impl std::fmt::Debug for FieldPiece<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FieldPiece")
            .field("supports", &self.eval.cover().len())
            .field("blend", &self.blend.is_some())
            .finish()
    }
}

/// A function defined piecewise on a box split by axis-aligned planes: piece `ix + nx (iy +
/// ny iz)` answers in the box between the planes `ix − 1` and `ix` of `splits[0]` (and so on
/// for y and z), the outermost boxes reaching to infinity. A point on a plane belongs to the
/// box above it.
#[derive(Debug)]
pub struct PiecewiseFunction<'e> {
    pieces: Vec<FieldPiece<'e>>,
    splits: [Vec<f64>; 3],
}

impl<'e> PiecewiseFunction<'e> {
    /// The function of one cover everywhere.
    pub fn single(piece: FieldPiece<'e>) -> Result<PiecewiseFunction<'e>, PolygoniseError> {
        PiecewiseFunction::new(vec![piece], [Vec::new(), Vec::new(), Vec::new()])
    }

    /// The pieces, in the order described on the type, and the split planes along each axis,
    /// finite and in ascending order (equal planes bound a box that holds no point); there
    /// must be `Π (splits[a].len() + 1)` pieces.
    pub fn new(
        pieces: Vec<FieldPiece<'e>>,
        splits: [Vec<f64>; 3],
    ) -> Result<PiecewiseFunction<'e>, PolygoniseError> {
        let boxes: usize = splits.iter().map(|s| s.len() + 1).product();
        let ascending = splits
            .iter()
            .all(|s| s.iter().all(|x| x.is_finite()) && s.windows(2).all(|w| w[0] <= w[1]));
        if boxes != pieces.len() || !ascending {
            return Err(PolygoniseError::PieceLayout {
                pieces: pieces.len(),
                boxes,
            });
        }
        for piece in &pieces {
            if let Some(values) = piece.blend
                && values.len() != piece.eval.cover().len()
            {
                return Err(PolygoniseError::BlendLengthMismatch {
                    expected: piece.eval.cover().len(),
                    found: values.len(),
                });
            }
        }
        if pieces.iter().all(|p| p.eval.cover().is_empty()) {
            return Err(PolygoniseError::EmptyCover);
        }
        Ok(PiecewiseFunction { pieces, splits })
    }

    /// Whether every piece carries values to blend.
    pub(super) fn blends(&self) -> bool {
        self.pieces.iter().all(|p| p.blend.is_some())
    }

    /// The piece answering at `p`.
    fn piece_of(&self, p: DVec3) -> usize {
        let [sx, sy, sz] = &self.splits;
        let along = |s: &Vec<f64>, x: f64| s.partition_point(|&plane| plane <= x);
        along(sx, p.x) + (sx.len() + 1) * (along(sy, p.y) + (sy.len() + 1) * along(sz, p.z))
    }

    /// `query(piece, its points)` for the points of each piece, in input order.
    fn by_piece<R: Clone + Send>(
        &self,
        points: &[DVec3],
        query: impl Fn(&FieldPiece<'e>, &[DVec3]) -> Vec<R>,
    ) -> Vec<R> {
        if let [only] = &self.pieces[..] {
            return query(only, points);
        }
        let owner: Vec<u32> = points
            .par_iter()
            .map(|&p| self.piece_of(p) as u32)
            .collect();
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        order.par_sort_by_key(|&i| owner[i as usize]);
        let mut out: Vec<Option<R>> = vec![None; points.len()];
        for group in order.chunk_by(|&a, &b| owner[a as usize] == owner[b as usize]) {
            let piece = &self.pieces[owner[group[0] as usize] as usize];
            let at: Vec<DVec3> = group.iter().map(|&i| points[i as usize]).collect();
            for (&i, r) in group.iter().zip(query(piece, &at)) {
                out[i as usize] = Some(r);
            }
        }
        out.into_iter().flatten().collect()
    }

    /// `f` at every point, `None` where it is undefined.
    pub(super) fn values(&self, points: &[DVec3]) -> Vec<Option<f64>> {
        self.by_piece(points, |piece, at| piece.eval.values(at))
    }

    /// `f` and `∇f` at every point.
    pub(super) fn values_gradients(&self, points: &[DVec3]) -> Vec<Option<ValueGradient>> {
        self.by_piece(points, |piece, at| piece.eval.values_gradients(at))
    }

    /// `f`, `∇f` and the blend at every point, when every piece blends.
    pub(super) fn values_gradients_blends(
        &self,
        points: &[DVec3],
    ) -> Option<Vec<Option<(ValueGradient, f64)>>> {
        self.blends().then(|| {
            self.by_piece(points, |piece, at| {
                // Lengths were checked when the pieces were given.
                let values = piece.blend.unwrap_or_default();
                piece
                    .eval
                    .values_gradients_blends(at, values)
                    .unwrap_or_else(|_| vec![None; at.len()])
            })
        })
    }

    /// The blend at every point (0 where no weight is positive), when every piece blends.
    pub(super) fn blend(&self, points: &[DVec3]) -> Option<Vec<f64>> {
        self.blends().then(|| {
            self.by_piece(points, |piece, at| {
                let values = piece.blend.unwrap_or_default();
                piece.eval.blend(at, values).map_or_else(
                    |_| vec![0.0; at.len()],
                    |b| b.into_iter().map(|v| v.unwrap_or(0.0)).collect(),
                )
            })
        })
    }

    /// The box where some piece's function can be defined (its expanded balls).
    pub(super) fn defined_box(&self) -> Aabb {
        let mut defined = Aabb::EMPTY;
        for piece in &self.pieces {
            let cover = piece.eval.cover();
            let sigma = piece.eval.sigma();
            for (&c, &r) in cover.centres().iter().zip(cover.radii()) {
                defined.add(c - DVec3::splat(r * sigma));
                defined.add(c + DVec3::splat(r * sigma));
            }
        }
        defined
    }

    /// The smallest support radius of every piece.
    pub(super) fn smallest_radius(&self) -> f64 {
        self.pieces
            .iter()
            .flat_map(|p| p.eval.cover().radii().iter().copied())
            .fold(f64::INFINITY, f64::min)
    }
}
