//! Visibility: which primitive is nearest at each sample, by z-buffer over horizontal bands.
//!
//! Triangles are rasterised with exact integer edge functions on vertices snapped to 1/256
//! of a sample, and a sample on an edge shared by two triangles goes to exactly one of them
//! (the "owner" rule below), so meshes show neither cracks nor double hits. Each band is
//! drawn by one task, with its primitives in index order and a strict depth test, so the
//! result is the same whatever the number of threads.

use rayon::prelude::*;

/// Fixed-point steps per sample.
pub(crate) const SUBPIXEL: i64 = 256;

/// Largest fixed-point coordinate magnitude kept: edge functions of such coordinates stay
/// far inside `i64` (differences below 2^30, products below 2^60).
const FIXED_LIMIT: f64 = (1u64 << 29) as f64;

/// "No primitive here".
pub(crate) const EMPTY: u32 = u32::MAX;

/// A vertex in fixed-point sample coordinates (x right, y down), or [`INVALID`].
pub(crate) type Fixed = [i64; 2];

/// A vertex that cannot be drawn (non-finite, behind the camera or absurdly far off).
pub(crate) const INVALID: Fixed = [i64::MIN, i64::MIN];

/// Snaps a position in samples to the fixed-point grid.
pub(crate) fn to_fixed(x: f64, y: f64) -> Fixed {
    let (fx, fy) = (x * SUBPIXEL as f64, y * SUBPIXEL as f64);
    if fx.abs() < FIXED_LIMIT && fy.abs() < FIXED_LIMIT {
        [fx.round() as i64, fy.round() as i64]
    } else {
        INVALID
    }
}

/// Twice the signed area of (a, b, p); positive when p lies left of a→b in a y-down frame
/// seen as y-up, i.e. on the interior side of a positively oriented triangle.
#[inline(always)]
fn edge(a: Fixed, b: Fixed, p: Fixed) -> i64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Whether samples exactly on edge a→b belong to the triangle. The reverse edge b→a (the
/// same edge seen from the neighbouring triangle) gets the opposite answer, so each such
/// sample is drawn once.
#[inline(always)]
fn owns(a: Fixed, b: Fixed) -> bool {
    let dy = b[1] - a[1];
    dy > 0 || (dy == 0 && b[0] - a[0] < 0)
}

/// Fixed-point centre of sample (i, j).
#[inline(always)]
fn sample_centre(i: i64, j: i64) -> Fixed {
    [i * SUBPIXEL + SUBPIXEL / 2, j * SUBPIXEL + SUBPIXEL / 2]
}

/// A triangle ready to rasterise: positively oriented, non-degenerate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Setup {
    v: [Fixed; 3],
    /// `corners[k]` is the corner of the input triangle that vertex `k` of the setup is.
    corners: [usize; 3],
    /// Twice the area, in fixed-point units squared; positive.
    area: i64,
}

impl Setup {
    /// The setup of a triangle with the given fixed-point corners; `None` when a corner is
    /// invalid or the triangle has no area.
    pub fn new(corners: [Fixed; 3]) -> Option<Setup> {
        if corners.contains(&INVALID) {
            return None;
        }
        let mut v = corners;
        let mut order = [0, 1, 2];
        let mut area = edge(v[0], v[1], v[2]);
        if area == 0 {
            return None;
        }
        if area < 0 {
            v.swap(1, 2);
            order.swap(1, 2);
            area = -area;
        }
        Some(Setup {
            v,
            corners: order,
            area,
        })
    }

    /// Inclusive sample bounds (i0, j0, i1, j1) of the samples whose centres the triangle's
    /// bounding box holds.
    pub fn sample_box(&self) -> [i64; 4] {
        let (mut lo, mut hi) = (self.v[0], self.v[0]);
        for p in &self.v[1..] {
            lo = [lo[0].min(p[0]), lo[1].min(p[1])];
            hi = [hi[0].max(p[0]), hi[1].max(p[1])];
        }
        let first = |c: i64| (c - SUBPIXEL / 2 + SUBPIXEL - 1).div_euclid(SUBPIXEL);
        let last = |c: i64| (c - SUBPIXEL / 2).div_euclid(SUBPIXEL);
        [first(lo[0]), first(lo[1]), last(hi[0]), last(hi[1])]
    }

    /// The edge functions at a sample and whether it is covered, evaluated directly (the
    /// oracle of the incremental loop).
    #[cfg(test)]
    fn edges_at(&self, i: i64, j: i64) -> ([i64; 3], bool) {
        let p = sample_centre(i, j);
        let [a, b, c] = self.v;
        let e = [edge(b, c, p), edge(c, a, p), edge(a, b, p)];
        let bias = [owns(b, c), owns(c, a), owns(a, b)];
        let inside = (0..3).all(|k| e[k] > 0 || (e[k] == 0 && bias[k]));
        (e, inside)
    }

    /// Barycentric weights of the input triangle's corners at sample (i, j).
    #[cfg(test)]
    pub fn weights_at(&self, i: i64, j: i64) -> [f64; 3] {
        self.weights_at_point(sample_centre(i, j))
    }

    /// Barycentric weights of the input triangle's corners at a fixed-point position.
    #[inline]
    pub fn weights_at_point(&self, p: Fixed) -> [f64; 3] {
        let [a, b, c] = self.v;
        let e = [edge(b, c, p), edge(c, a, p), edge(a, b, p)];
        let inv = 1.0 / self.area as f64;
        let mut w = [0.0; 3];
        for k in 0..3 {
            w[self.corners[k]] = e[k] as f64 * inv;
        }
        w
    }

    /// Calls `visit(i, j, weights)` for every covered sample inside the inclusive sample
    /// bounds `clip`, rows in order, with the weights of the setup's own vertex order.
    #[inline]
    fn for_each_covered(&self, clip: [i64; 4], mut visit: impl FnMut(usize, usize, [f64; 3])) {
        let b = self.sample_box();
        let (i0, j0) = (b[0].max(clip[0]), b[1].max(clip[1]));
        let (i1, j1) = (b[2].min(clip[2]), b[3].min(clip[3]));
        if i0 > i1 || j0 > j1 {
            return;
        }
        let [va, vb, vc] = self.v;
        let pairs = [(vb, vc), (vc, va), (va, vb)];
        // One step right changes a→b's edge function by −Δy·SUBPIXEL: exact in integers.
        let step = pairs.map(|(a, b)| -(b[1] - a[1]) * SUBPIXEL);
        let bias = pairs.map(|(a, b)| i64::from(owns(a, b)));
        let inv = 1.0 / self.area as f64;
        for j in j0..=j1 {
            let p = sample_centre(i0, j);
            let mut e = pairs.map(|(a, b)| edge(a, b, p));
            for i in i0..=i1 {
                if e[0] + bias[0] > 0 && e[1] + bias[1] > 0 && e[2] + bias[2] > 0 {
                    visit(
                        i as usize,
                        j as usize,
                        [e[0] as f64 * inv, e[1] as f64 * inv, e[2] as f64 * inv],
                    );
                }
                for k in 0..3 {
                    e[k] += step[k];
                }
            }
        }
    }

    /// Depth keys in the setup's vertex order, from keys in the input corner order.
    #[inline]
    fn reorder(&self, keys: [f64; 3]) -> [f64; 3] {
        self.corners.map(|c| keys[c])
    }
}

/// A disc drawn for a point: a small sphere facing the camera, so overlapping splats
/// intersect like the balls they stand for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Splat {
    /// Centre, in samples.
    pub x: f64,
    /// Centre, in samples.
    pub y: f64,
    /// Radius, in samples; zero for a point that is not drawn.
    pub radius: f64,
    /// Distance of the centre from the camera.
    pub distance: f64,
    /// Radius of the sphere in distance units.
    pub depth_radius: f64,
}

impl Splat {
    /// Inclusive sample rows the splat may cover; `None` for a splat not drawn.
    pub fn rows(&self) -> Option<(i64, i64)> {
        // Also refuses a NaN radius.
        if self.radius.is_nan() || self.radius <= 0.0 {
            return None;
        }
        let first = (self.y - self.radius - 0.5).ceil();
        let last = (self.y + self.radius - 0.5).floor();
        (first <= last && first.is_finite() && last.is_finite())
            .then_some((first as i64, last as i64))
    }

    /// The offset of a sample centre from the splat's centre, in radii (inside the disc
    /// when its length is at most 1).
    #[inline]
    pub fn offset_at(&self, i: usize, j: usize) -> (f64, f64) {
        self.offset_at_point(i as f64 + 0.5, j as f64 + 0.5)
    }

    /// The offset of a position in samples from the splat's centre, in radii.
    #[inline]
    pub fn offset_at_point(&self, x: f64, y: f64) -> (f64, f64) {
        ((x - self.x) / self.radius, (y - self.y) / self.radius)
    }
}

/// Primitives sorted into bands: the primitives touching band `b`, in index order.
#[derive(Clone, Debug, Default)]
pub(crate) struct Bins {
    starts: Vec<usize>,
    items: Vec<u32>,
    /// Primitives that touch at least one band.
    pub drawn: usize,
}

impl Bins {
    /// Bins `count` primitives whose inclusive sample-row ranges `rows(k)` gives (`None` for
    /// a primitive not drawn) into bands of `band_rows` rows covering `height` rows.
    pub fn build(
        count: usize,
        band_rows: usize,
        height: usize,
        rows: impl Fn(usize) -> Option<(i64, i64)> + Sync,
    ) -> Bins {
        let bands = height.div_ceil(band_rows);
        let last_row = height as i64 - 1;
        let ranges: Vec<Option<(u32, u32)>> = (0..count)
            .into_par_iter()
            .map(|k| {
                let (r0, r1) = rows(k)?;
                let (r0, r1) = (r0.max(0), r1.min(last_row));
                (r0 <= r1).then(|| {
                    (
                        (r0 as usize / band_rows) as u32,
                        (r1 as usize / band_rows) as u32,
                    )
                })
            })
            .collect();
        let mut starts = vec![0usize; bands + 1];
        for &(b0, b1) in ranges.iter().flatten() {
            for b in b0..=b1 {
                starts[b as usize + 1] += 1;
            }
        }
        for b in 0..bands {
            starts[b + 1] += starts[b];
        }
        let drawn = ranges.iter().flatten().count();
        let mut fill = starts.clone();
        let mut items = vec![0u32; starts[bands]];
        for (k, range) in ranges.iter().enumerate() {
            if let Some((b0, b1)) = *range {
                for b in b0..=b1 {
                    items[fill[b as usize]] = k as u32;
                    fill[b as usize] += 1;
                }
            }
        }
        Bins {
            starts,
            items,
            drawn,
        }
    }

    /// The primitives touching band `b`.
    pub fn band(&self, b: usize) -> &[u32] {
        match (self.starts.get(b), self.starts.get(b + 1)) {
            (Some(&s), Some(&e)) => &self.items[s..e],
            _ => &[],
        }
    }
}

/// Depth and primitive of each sample of one band.
#[derive(Debug)]
pub(crate) struct Band {
    /// First sample row.
    pub y0: usize,
    /// Rows.
    pub rows: usize,
    /// Samples per row.
    pub width: usize,
    /// Depth key of the nearest primitive so far (+∞ where none).
    pub key: Vec<f64>,
    /// Nearest primitive ([`EMPTY`] where none).
    pub id: Vec<u32>,
}

impl Band {
    /// An empty band.
    pub fn new(y0: usize, rows: usize, width: usize) -> Band {
        Band {
            y0,
            rows,
            width,
            key: vec![f64::INFINITY; rows * width],
            id: vec![EMPTY; rows * width],
        }
    }

    fn clip(&self) -> [i64; 4] {
        [
            0,
            self.y0 as i64,
            self.width as i64 - 1,
            (self.y0 + self.rows) as i64 - 1,
        ]
    }

    #[inline(always)]
    fn test(&mut self, i: usize, j: usize, key: f64, id: u32) {
        let s = (j - self.y0) * self.width + i;
        if key < self.key[s] {
            self.key[s] = key;
            self.id[s] = id;
        }
    }

    /// Draws a triangle with per-corner depth keys (input corner order).
    pub fn triangle(&mut self, id: u32, setup: &Setup, keys: [f64; 3]) {
        let k = setup.reorder(keys);
        let clip = self.clip();
        setup.for_each_covered(clip, |i, j, w| {
            let key = w[0] * k[0] + w[1] * k[1] + w[2] * k[2];
            self.test(i, j, key, id);
        });
    }

    /// Draws a splat; `depth_key` maps a distance to the depth-test key.
    pub fn splat(&mut self, id: u32, splat: &Splat, depth_key: impl Fn(f64) -> f64) {
        let Some((r0, r1)) = splat.rows() else { return };
        let clip = self.clip();
        let (j0, j1) = (r0.max(clip[1]), r1.min(clip[3]));
        let i0 = ((splat.x - splat.radius - 0.5).ceil() as i64).max(0);
        let i1 = ((splat.x + splat.radius - 0.5).floor() as i64).min(clip[2]);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let (dx, dy) = splat.offset_at(i as usize, j as usize);
                let q = dx * dx + dy * dy;
                if q <= 1.0 {
                    let distance = splat.distance - splat.depth_radius * (1.0 - q).sqrt();
                    self.test(i as usize, j as usize, depth_key(distance), id);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const W: usize = 23;
    const H: usize = 19;

    fn fixed_triangle() -> impl Strategy<Value = ([Fixed; 3], [f64; 3])> {
        let corner = (
            -600i64..(W as i64 * 256 + 600),
            -600i64..(H as i64 * 256 + 600),
        )
            .prop_map(|(x, y)| [x, y]);
        (
            [corner.clone(), corner.clone(), corner],
            prop::array::uniform3(-10.0..10.0f64),
        )
    }

    /// Draws through the bins and bands, as the renderer does.
    fn banded(tris: &[([Fixed; 3], [f64; 3])], band_rows: usize) -> Vec<u32> {
        let setups: Vec<Option<Setup>> = tris.iter().map(|t| Setup::new(t.0)).collect();
        let bins = Bins::build(tris.len(), band_rows, H, |k| {
            setups[k].map(|s| {
                let b = s.sample_box();
                (b[1], b[3])
            })
        });
        let mut out = Vec::new();
        for b in 0..H.div_ceil(band_rows) {
            let rows = band_rows.min(H - b * band_rows);
            let mut band = Band::new(b * band_rows, rows, W);
            for &k in bins.band(b) {
                if let Some(s) = &setups[k as usize] {
                    band.triangle(k, s, tris[k as usize].1);
                }
            }
            out.extend(band.id);
        }
        out
    }

    /// The oracle: every sample against every triangle, edge functions evaluated directly.
    fn brute_force(tris: &[([Fixed; 3], [f64; 3])]) -> Vec<u32> {
        let mut out = vec![EMPTY; W * H];
        for j in 0..H {
            for i in 0..W {
                let mut best = f64::INFINITY;
                for (k, (corners, keys)) in tris.iter().enumerate() {
                    let Some(s) = Setup::new(*corners) else {
                        continue;
                    };
                    let (e, inside) = s.edges_at(i as i64, j as i64);
                    if inside {
                        // The same arithmetic as the renderer, so that depth ties agree.
                        let z = s.reorder(*keys);
                        let w = e.map(|e| e as f64 * (1.0 / s.area as f64));
                        let key = w[0] * z[0] + w[1] * z[1] + w[2] * z[2];
                        if key < best {
                            best = key;
                            out[j * W + i] = k as u32;
                        }
                    }
                }
            }
        }
        out
    }

    proptest! {
        /// Binned, incremental rasterisation equals the per-sample brute force.
        #[test]
        fn banded_rasteriser_matches_brute_force(
            tris in prop::collection::vec(fixed_triangle(), 1..12),
            band_rows in 1usize..8,
        ) {
            prop_assert_eq!(banded(&tris, band_rows), brute_force(&tris));
        }

        /// A jittered grid of triangles over a rectangle covers each sample inside it exactly
        /// once and no sample outside: no cracks, no double hits, even where edges pass
        /// exactly through sample centres.
        #[test]
        fn meshes_are_watertight(
            jitter in prop::collection::vec((-1i64..=1, -1i64..=1), 36),
            diagonals in prop::collection::vec(any::<bool>(), 25),
        ) {
            // 6×6 vertices over samples [2, 20) × [2, 17); the outer border lies between
            // sample centres and interior vertices move by half a sample, little enough
            // that every cell stays convex (so both diagonals split it without overlap).
            let (x0, y0, x1, y1) = (2 * 256, 2 * 256, 20 * 256, 17 * 256);
            let vertex = |a: usize, b: usize| -> Fixed {
                let x = x0 + (x1 - x0) * a as i64 / 5;
                let y = y0 + (y1 - y0) * b as i64 / 5;
                let (dx, dy) = jitter[b * 6 + a];
                let inner = |k: usize| k > 0 && k < 5;
                [
                    if inner(a) { x + dx * 128 } else { x },
                    if inner(b) { y + dy * 128 } else { y },
                ]
            };
            let mut count = vec![0u32; W * H];
            for b in 0..5 {
                for a in 0..5 {
                    let (p, q, r, s) = (vertex(a, b), vertex(a + 1, b), vertex(a + 1, b + 1), vertex(a, b + 1));
                    let halves = if diagonals[b * 5 + a] { [[p, q, r], [p, r, s]] } else { [[p, q, s], [q, r, s]] };
                    for (h, corners) in halves.into_iter().enumerate() {
                        // Alternate windings: the rasteriser must not care.
                        let corners = if h == 0 { corners } else { [corners[0], corners[2], corners[1]] };
                        if let Some(setup) = Setup::new(corners) {
                            setup.for_each_covered([0, 0, W as i64 - 1, H as i64 - 1], |i, j, _| count[j * W + i] += 1);
                        }
                    }
                }
            }
            for j in 0..H {
                for i in 0..W {
                    let inside = (2..20).contains(&i) && (2..17).contains(&j);
                    prop_assert_eq!(count[j * W + i], u32::from(inside), "sample {} {}", i, j);
                }
            }
        }

        /// Weights sum to 1 and reproduce the sample position.
        #[test]
        fn weights_are_barycentric(t in fixed_triangle(), i in 0i64..23, j in 0i64..19) {
            if let Some(s) = Setup::new(t.0) {
                let w = s.weights_at(i, j);
                prop_assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-9);
                let p = sample_centre(i, j);
                for axis in 0..2 {
                    let x: f64 = (0..3).map(|k| w[k] * t.0[k][axis] as f64).sum();
                    prop_assert!((x - p[axis] as f64).abs() < 1e-6 * (1.0 + p[axis].abs() as f64));
                }
            }
        }
    }

    #[test]
    fn splats_cover_their_disc_and_keep_the_nearest() {
        let mut band = Band::new(0, 40, 40);
        let near = Splat {
            x: 20.0,
            y: 20.0,
            radius: 10.0,
            distance: 1.0,
            depth_radius: 0.5,
        };
        let far = Splat {
            x: 25.0,
            distance: 2.0,
            ..near
        };
        band.splat(0, &near, |d| d);
        band.splat(1, &far, |d| d);
        let covered = band.id.iter().filter(|&&id| id == 0).count() as f64;
        let disc = std::f64::consts::PI * 100.0;
        assert!((covered - disc).abs() < 0.05 * disc, "{covered} vs {disc}");
        assert_eq!(band.id[20 * 40 + 20], 0);
        assert_eq!(band.id[20 * 40 + 33], 1);
        assert!(band.id[20 * 40 + 35] == EMPTY || band.id[20 * 40 + 35] == 1);
    }
}
