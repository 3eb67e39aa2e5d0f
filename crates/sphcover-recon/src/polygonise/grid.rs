//! The uniform grid of the polygonisation and the packing of its indices into `u64` keys.
//!
//! Every later phase addresses grid vertices and cells by these keys (the sparse brick map,
//! the active cells, the tube faces), so the grid, the choice of its step and the key layout
//! sit apart from any one of them.

use sphcover_core::ParameterError;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;
use sphcover_core::Aabb;

use super::{GridStep, PiecewiseFunction, PolygoniseError};

/// Cells along an axis stay below this so that three indices pack into a `u64`.
const GRID_LIMIT: i64 = 1 << 21;

pub(super) fn grid_step(
    step: GridStep,
    seeds: &[DVec3],
    field: &PiecewiseFunction<'_>,
) -> Result<f64, PolygoniseError> {
    let h = match step {
        GridStep::Depth(d) => Aabb::from_points(seeds).longest_edge() / f64::from(1u32 << d),
        GridStep::Absolute(s) => s,
        GridStep::SmallestRadius(k) => k * field.smallest_radius(),
    };
    if h.is_finite() && h > 0.0 {
        Ok(h)
    } else {
        // A single seed (or coincident seeds) has a bounding box without extent.
        Err(PolygoniseError::InvalidParameter(ParameterError {
            name: "step",
            value: h,
            expected: "a positive step: give an absolute step when the seeds span no box",
        }))
    }
}

/// The uniform grid: vertex `(i, j, k)` is at `origin + step (i, j, k)`; cell `(i, j, k)` has
/// that vertex as its lowest corner.
#[derive(Debug)]
pub(super) struct Grid {
    origin: DVec3,
    pub(super) step: f64,
    /// Grid vertices along each axis; indices outside `0..dims` are outside every support.
    pub(super) dims: [i64; 3],
}

pub(super) type Index3 = [i64; 3];

impl Grid {
    /// The grid of step `step` over the box where `field` can be defined (the expanded
    /// balls), with one spare cell on every side.
    pub(super) fn around(
        field: &PiecewiseFunction<'_>,
        step: f64,
    ) -> Result<Grid, PolygoniseError> {
        let defined = field.defined_box();
        let extent = defined.longest_edge();
        let cells_per_axis = (extent / step).ceil() + 3.0;
        if cells_per_axis.is_nan() || cells_per_axis >= GRID_LIMIT as f64 {
            return Err(PolygoniseError::GridTooFine { step, extent });
        }
        Ok(Grid {
            origin: defined.min - DVec3::splat(step),
            step,
            dims: (defined.extent() / step)
                .ceil()
                .as_ivec3()
                .to_array()
                .map(|d| d as i64 + 3),
        })
    }

    pub(super) fn position(&self, v: Index3) -> DVec3 {
        self.origin + DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) * self.step
    }

    pub(super) fn cell_of(&self, p: DVec3) -> Index3 {
        let q = ((p - self.origin) / self.step).floor();
        [q.x, q.y, q.z].map(|c| c.clamp(-1.0, GRID_LIMIT as f64) as i64)
    }

    pub(super) fn in_range(&self, v: Index3) -> bool {
        (0..3).all(|a| v[a] >= 0 && v[a] < self.dims[a])
    }

    /// The cell and its 26 neighbours.
    pub(super) fn block_around(&self, c: Index3) -> impl Iterator<Item = Index3> + '_ {
        (0..27).map(move |n| [c[0] + n % 3 - 1, c[1] + (n / 3) % 3 - 1, c[2] + n / 9 - 1])
    }
}

/// A cell index packed when in range, else a key no cell has.
pub(super) fn pack_clamped(v: Index3) -> u64 {
    if v.iter().all(|&c| (0..GRID_LIMIT).contains(&c)) {
        pack(v)
    } else {
        u64::MAX
    }
}

pub(super) fn unpack_clamped(key: u64) -> Option<Index3> {
    (key != u64::MAX).then(|| unpack(key))
}

pub(super) fn pack(v: Index3) -> u64 {
    (v[0] as u64) | ((v[1] as u64) << 21) | ((v[2] as u64) << 42)
}

pub(super) fn unpack(key: u64) -> Index3 {
    let mask = (1u64 << 21) - 1;
    [key & mask, (key >> 21) & mask, key >> 42].map(|c| c as i64)
}

/// A multiplicative hash of packed grid keys: std's SipHash costs more than the work per
/// key here.
#[derive(Default)]
pub(super) struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        }
    }
    fn write_u64(&mut self, key: u64) {
        let x = (key ^ (key >> 29)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        self.0 = x ^ (x >> 32);
    }
}

pub(super) type KeyMap<V> = HashMap<u64, V, BuildHasherDefault<KeyHasher>>;
