//! Exact Euclidean distance transform on a voxel grid with per-axis spacing (Felzenszwalb
//! and Huttenlocher, "Distance transforms of sampled functions", 2012): three separable
//! passes of the 1D lower envelope of parabolas.

use rayon::prelude::*;

/// Squared distance from each voxel centre to the nearest voxel centre where `background`
/// is true, with axis spacing `spacing` (world units; exact for orthogonal voxel axes).
/// Voxels with no background voxel anywhere get `+∞`. Outside the grid counts as neither.
pub(crate) fn squared_distance_to_background(
    dims: [usize; 3],
    spacing: [f64; 3],
    background: impl Fn(usize) -> bool + Sync,
) -> Vec<f64> {
    let [nx, ny, nz] = dims;
    let n = nx * ny * nz;
    let mut d2: Vec<f64> = (0..n)
        .into_par_iter()
        .map(|i| if background(i) { 0.0 } else { f64::INFINITY })
        .collect();
    // x lines are contiguous.
    d2.par_chunks_mut(nx).for_each_init(
        || Scratch::new(nx),
        |s, line| s.transform_line(line, spacing[0]),
    );
    // y lines live inside one z slab.
    d2.par_chunks_mut(nx * ny).for_each_init(
        || (Scratch::new(ny), vec![0.0; ny]),
        |(s, line), slab| {
            for i in 0..nx {
                for j in 0..ny {
                    line[j] = slab[i + nx * j];
                }
                s.transform_line(line, spacing[1]);
                for j in 0..ny {
                    slab[i + nx * j] = line[j];
                }
            }
        },
    );
    // z lines span the whole array: transform a copy and scatter it back per y row.
    if nz > 1 {
        let stride = nx * ny;
        let lines: Vec<Vec<f64>> = (0..stride)
            .into_par_iter()
            .map_init(
                || Scratch::new(nz),
                |s, col| {
                    let mut line: Vec<f64> = (0..nz).map(|k| d2[col + stride * k]).collect();
                    s.transform_line(&mut line, spacing[2]);
                    line
                },
            )
            .collect();
        for (col, line) in lines.into_iter().enumerate() {
            for (k, v) in line.into_iter().enumerate() {
                d2[col + stride * k] = v;
            }
        }
    }
    d2
}

/// Buffers of the 1D transform, reused across lines.
struct Scratch {
    f: Vec<f64>,
    vertex: Vec<usize>,
    boundary: Vec<f64>,
}

impl Scratch {
    fn new(n: usize) -> Scratch {
        Scratch {
            f: vec![0.0; n],
            vertex: vec![0; n],
            boundary: vec![0.0; n + 1],
        }
    }

    /// Replaces `line[q]` by `min_p (line[p] + ((q − p)·h)²)`.
    fn transform_line(&mut self, line: &mut [f64], h: f64) {
        let n = line.len();
        self.f[..n].copy_from_slice(line);
        let f = &self.f;
        // Parabolas rooted at +∞ never enter the envelope; with none finite the line stays +∞.
        let Some(first) = f[..n].iter().position(|v| v.is_finite()) else {
            return;
        };
        let pos = |q: usize| q as f64 * h;
        let mut k = 0;
        self.vertex[0] = first;
        self.boundary[0] = f64::NEG_INFINITY;
        self.boundary[1] = f64::INFINITY;
        for q in first + 1..n {
            if !f[q].is_finite() {
                continue;
            }
            let v = |k: usize| self.vertex[k];
            let meet = |v: usize| {
                ((f[q] + pos(q) * pos(q)) - (f[v] + pos(v) * pos(v))) / (2.0 * (pos(q) - pos(v)))
            };
            // boundary[0] = −∞ stops the loop at k = 0.
            let mut s = meet(v(k));
            while s <= self.boundary[k] {
                k -= 1;
                s = meet(v(k));
            }
            k += 1;
            self.vertex[k] = q;
            self.boundary[k] = s;
            self.boundary[k + 1] = f64::INFINITY;
        }
        let mut k = 0;
        for (q, out) in line.iter_mut().enumerate() {
            while self.boundary[k + 1] < pos(q) {
                k += 1;
            }
            let v = self.vertex[k];
            let dx = pos(q) - pos(v);
            *out = dx * dx + f[v];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute(dims: [usize; 3], spacing: [f64; 3], bg: &[bool]) -> Vec<f64> {
        let [nx, ny, nz] = dims;
        let mut out = vec![f64::INFINITY; bg.len()];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let me = i + nx * (j + ny * k);
                    for (o, &b) in bg.iter().enumerate() {
                        if b {
                            let (oi, oj, ok) = (o % nx, (o / nx) % ny, o / (nx * ny));
                            let d = [
                                (i as f64 - oi as f64) * spacing[0],
                                (j as f64 - oj as f64) * spacing[1],
                                (k as f64 - ok as f64) * spacing[2],
                            ];
                            out[me] = out[me].min(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                        }
                    }
                }
            }
        }
        out
    }

    proptest! {
        #[test]
        fn matches_brute_force(
            nx in 1usize..7, ny in 1usize..6, nz in 1usize..5,
            sx in 0.3f64..2.0, sy in 0.3f64..2.0, sz in 0.3f64..2.0,
            seed in any::<u64>(), density in 0.0f64..0.5,
        ) {
            let n = nx * ny * nz;
            let bg: Vec<bool> = (0..n)
                .map(|i| {
                    let h = (seed ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15))
                        .wrapping_mul(0xbf58_476d_1ce4_e5b9);
                    ((h >> 11) as f64 / (1u64 << 53) as f64) < density
                })
                .collect();
            let dims = [nx, ny, nz];
            let spacing = [sx, sy, sz];
            let fast = squared_distance_to_background(dims, spacing, |i| bg[i]);
            let slow = brute(dims, spacing, &bg);
            for (a, b) in fast.iter().zip(&slow) {
                prop_assert!(a == b || (a - b).abs() <= 1e-9 * b.max(1.0), "{a} vs {b}");
            }
        }
    }
}
