//! The sampling lattice around a centre voxel: the offsets within `r_max` sorted into shells
//! of equal distance, and the lattice steps of the hull test.
//!
//! It is built once per cover and read by every fit and covering check, so the work per
//! centre is walks over these tables; the fitting, covering and elimination phases add
//! their own methods to it in their own files.

use glam::{DMat3, DVec3};

use super::{VolumeCoverParams, VolumeCoverVariant};
use crate::volume::Volume;

/// A lattice offset from a centre voxel with its position in the frame `d/h`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Offset {
    pub(super) step: [i32; 3],
    pub(super) p: [f64; 3],
}

/// The sampling grid and everything shared by the fits.
pub(super) struct Grid<'a> {
    pub(super) volume: &'a Volume,
    pub(super) dims: [i64; 3],
    lo: f64,
    inv_range: f64,
    pub(super) object: &'a [bool],
    /// `h`: the unit of the fixed frame (the voxel diagonal).
    pub(super) unit: f64,
    /// The voxel→world linear map divided by `h`.
    pub(super) linear: DMat3,
    /// Lattice offsets within `r_max`, by increasing distance.
    pub(super) offsets: Vec<Offset>,
    /// Shells: `(squared distance in frame d/h, end index in offsets)`, increasing.
    pub(super) shells: Vec<(f64, usize)>,
    r_min: f64,
    pub(super) r_max: f64,
    /// Index of the last shell within `r_min`.
    pub(super) first_shell: usize,
    pub(super) tolerance: f64,
    pub(super) min_samples: usize,
    /// Lattice steps for the hull test, shortest first.
    pub(super) steps: Vec<([i32; 3], DVec3)>,
    pub(super) bounding_box: bool,
}

impl<'a> Grid<'a> {
    pub(super) fn new(
        volume: &'a Volume,
        lo: f64,
        hi: f64,
        r_min: f64,
        r_max: f64,
        object: &'a [bool],
        params: &VolumeCoverParams,
    ) -> Grid<'a> {
        let dims = volume.dims().map(|d| d as i64);
        let unit = volume.voxel_diagonal();
        let linear = volume.affine().matrix3 * (1.0 / unit);
        // The box of lattice offsets that can reach r_max: |step_a| ≤ R·‖row a of L⁻¹‖.
        let inv = linear.inverse();
        let reach = r_max / unit;
        let rows = inv.transpose();
        let ext =
            [rows.x_axis, rows.y_axis, rows.z_axis].map(|row| (reach * row.length()).ceil() as i32);
        // A ball's support is open (its weight vanishes on the sphere), so offsets on the
        // sphere of radius r_max, up to rounding, are outside every ball: neither fitted nor
        // covered. r_max is often a voxel distance (the thickness), so they occur.
        let mut offsets = Vec::new();
        let r2 = reach * reach * (1.0 - 1e-9);
        for k in -ext[2]..=ext[2] {
            for j in -ext[1]..=ext[1] {
                for i in -ext[0]..=ext[0] {
                    let p = linear * DVec3::new(i as f64, j as f64, k as f64);
                    if p.length_squared() < r2 {
                        offsets.push(Offset {
                            step: [i, j, k],
                            p: p.to_array(),
                        });
                    }
                }
            }
        }
        let d2 = |o: &Offset| o.p[0] * o.p[0] + o.p[1] * o.p[1] + o.p[2] * o.p[2];
        offsets.sort_by(|a, b| {
            d2(a)
                .total_cmp(&d2(b))
                .then_with(|| a.step[2].cmp(&b.step[2]))
                .then_with(|| a.step[1].cmp(&b.step[1]))
                .then_with(|| a.step[0].cmp(&b.step[0]))
        });
        // Offsets at the same true distance can differ in the last bits of their computed
        // distance (summation order): a shell gathers every offset within a relative 1e-9
        // of its first one, and keeps the largest computed distance.
        let mut shells: Vec<(f64, usize)> = Vec::new();
        let mut shell_start = f64::NEG_INFINITY;
        for (idx, o) in offsets.iter().enumerate() {
            let d = d2(o);
            match shells.last_mut() {
                Some(last) if d <= shell_start * (1.0 + 1e-9) => *last = (d, idx + 1),
                _ => {
                    shell_start = d;
                    shells.push((d, idx + 1));
                }
            }
        }
        let rmin2 = (r_min / unit) * (r_min / unit);
        let first_shell = shells.iter().rposition(|&(d, _)| d <= rmin2).unwrap_or(0);
        let mut steps: Vec<([i32; 3], DVec3)> = Vec::new();
        for k in -2i32..=2 {
            for j in -2i32..=2 {
                for i in -2i32..=2 {
                    let s = [i, j, k];
                    let first_nonzero = s.iter().copied().find(|&c| c != 0);
                    let primitive = gcd(gcd(i.abs(), j.abs()), k.abs()) == 1;
                    if first_nonzero.is_some_and(|c| c > 0) && primitive {
                        steps.push((s, linear * DVec3::new(i as f64, j as f64, k as f64)));
                    }
                }
            }
        }
        steps.sort_by(|a, b| {
            a.1.length_squared()
                .total_cmp(&b.1.length_squared())
                .then_with(|| a.0.cmp(&b.0))
        });
        Grid {
            volume,
            dims,
            lo,
            inv_range: 1.0 / (hi - lo),
            object,
            unit,
            linear,
            offsets,
            shells,
            r_min,
            r_max,
            first_shell,
            tolerance: params.tolerance,
            min_samples: params.min_samples,
            steps,
            bounding_box: params.variant == VolumeCoverVariant::BoundingBoxLinear,
        }
    }

    /// The voxel at `base + step`, if inside the grid.
    #[inline]
    pub(super) fn neighbour(&self, base: [i64; 3], step: [i32; 3]) -> Option<usize> {
        let i = base[0] + i64::from(step[0]);
        let j = base[1] + i64::from(step[1]);
        let k = base[2] + i64::from(step[2]);
        let [nx, ny, nz] = self.dims;
        if i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz {
            return None;
        }
        Some((i + nx * (j + ny * k)) as usize)
    }

    /// The normalised value of a voxel, `None` when not finite.
    #[inline]
    pub(super) fn sample(&self, idx: usize) -> Option<f64> {
        let v = (self.volume.value(idx) - self.lo) * self.inv_range;
        v.is_finite().then_some(v)
    }

    pub(super) fn base(&self, idx: usize) -> [i64; 3] {
        self.volume.ijk(idx).map(|c| c as i64)
    }

    /// The ball radius for shell `s`: halfway to the next shell, within `[r_min, r_max]`.
    pub(super) fn radius_of_shell(&self, s: usize) -> f64 {
        let here = self.shells[s].0.sqrt() * self.unit;
        let r = match self.shells.get(s + 1) {
            Some(&(next, _)) => 0.5 * (here + next.sqrt() * self.unit),
            None => self.r_max,
        };
        let r = if s >= self.first_shell {
            r.max(self.r_min)
        } else {
            r
        };
        r.min(self.r_max).max(here)
    }
}

fn gcd(a: i32, b: i32) -> i32 {
    if b == 0 { a } else { gcd(b, a % b) }
}
