//! The sheet across plates on slices thicker than the pixels, against the centroid of the
//! measured slices: pieces standing off the plates collapsed, the rest moved onto it.
//!
//! The methods are described on [`collapse_off_plate_triangles()`] and
//! [`centre_on_slice_centroids()`].

use glam::DVec3;
use rayon::prelude::*;
use sphcover_core::{TriMesh, Volume};

use super::collapse::collapse_in_order;
use super::retain_triangles;

/// Parameters of [`collapse_off_plate_triangles`] and [`centre_on_slice_centroids`]; lengths
/// in slices but for `max_off_plate_pixels`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct SliceCentroidParams {
    /// A vertex is moved only where the sheet's normal makes at most this cosine's angle with
    /// the slice axis (0.5: 60°); steeper sheets run along the columns.
    pub min_axis_cosine: f64,
    /// Longest run of slices above the threshold that a column may cross the part in; longer
    /// runs are parts standing along the slice axis (a web, a junction).
    pub max_run_slices: usize,
    /// Largest move of a vertex.
    pub max_shift_slices: f64,
    /// Triangles whose centroid lies farther than this (in-slice pixels) along the slice
    /// axis from the plate their column crosses are collapsed from the sheet's free edges
    /// (and so are those over columns that read air).
    pub max_off_plate_pixels: f64,
}

impl Default for SliceCentroidParams {
    /// Measured on the generated phantoms on 5:1 slices (seed 1, noise 0, 10 and 30 %;
    /// `docs/benchmarks.md`), the moves alone (before the collapses were added): mean
    /// coverage 0.908 and spurious share 0.069 (0.890 and 0.076 with no vertex moved). With
    /// the collapses, 0.907 and 0.041; a bound of 1.2 or 2 pixels gave 0.906 and 0.038,
    /// 0.907 and 0.050 (with the object mask smoothed on such grids as now: 0.927 and 0.026
    /// for 1.5 pixels, 0.926 and 0.023 for 1.2, 0.927 and 0.033 for 2; with the triangles
    /// over air collapsed as well, 0.927 and 0.023 for 1.5). A largest move of 0.3 slices
    /// gave 0.905; of 1 slice 0.918, by moving misplaced pieces of the T-junction onto its
    /// plates, but on the head CT's 4.8 mm slices 71 vault holes over 20 mm instead of 42
    /// (the largest 101 mm instead of 52): half a slice is more than the interpolant's bias,
    /// a whole one relocates pieces of sheet. Runs of at most 1 or 2 slices gave 0.895 and 0.907, 4 the same as 3 (3
    /// takes a plate 6 pixels thick tilted 25° on slices 3 pixels thick, 2 does not);
    /// cosines of 0.3 and 0.7 gave 0.909 and 0.906.
    fn default() -> SliceCentroidParams {
        SliceCentroidParams {
            min_axis_cosine: 0.5,
            max_run_slices: 3,
            max_shift_slices: 0.5,
            max_off_plate_pixels: 1.5,
        }
    }
}

/// The slices as the scanner measured them, before the pipeline resampled them along their
/// axis, with the part's threshold and background on their scale.
#[derive(Clone, Copy, Debug)]
pub struct ThickSlices<'a> {
    /// The volume as read (windowed to the material on a CT, as the pipeline's threshold
    /// is).
    pub volume: &'a Volume,
    /// The voxel axis across the slices (0, 1 or 2).
    pub axis: usize,
    /// The part is where the values exceed this.
    pub threshold: f64,
    /// The level of what surrounds the part.
    pub background: f64,
}

/// Binomial weights of a column's neighbours along each of the two in-slice axes: the
/// centroid of one column carries the noise of its slices; the weighted mean of 5 × 5
/// columns (256 in all) carries about a quarter of it, and a plane's centroids, linear
/// across the columns, keep their mean. On the phantoms on 3:1 slices (seed 1, noise 0, 10
/// and 30 %) the mean of the rows' 95th-percentile distance was 0.21 voxels with no vertex
/// moved, 0.27 with single columns, 0.20 with 3 × 3 and 0.18 with 5 × 5; on 5:1 slices the
/// mean spurious share 0.076, 0.068, 0.059 and 0.060 (the moves alone).
const NEIGHBOUR_WEIGHTS: [(i64, f64); 5] = [(-2, 1.0), (-1, 4.0), (0, 6.0), (1, 4.0), (2, 1.0)];

/// Least total weight of the neighbours (of 256) whose centroids count: a column at the
/// part's edge, with fewer neighbours crossing it, is not averaged into a lopsided mean.
const MIN_NEIGHBOUR_WEIGHT: f64 = 192.0;

impl ThickSlices<'_> {
    /// The voxel axes along the slices, in order.
    fn in_slice_axes(&self) -> [usize; 2] {
        match self.axis {
            0 => [1, 2],
            1 => [0, 2],
            _ => [0, 1],
        }
    }

    /// The slices' thickness in pixels (their spacing over the finer in-slice edge).
    pub(crate) fn slice_pixels(&self) -> f64 {
        let size = self.volume.voxel_size().to_array();
        let [p, q] = self.in_slice_axes();
        size[self.axis] / size[p].min(size[q])
    }

    /// Unit vector along the slice axis (world coordinates).
    pub(crate) fn axis_direction(&self) -> DVec3 {
        self.volume.affine().matrix3.col(self.axis).normalize()
    }

    /// The value of column `(a, b)` (along the in-slice axes) at slice `k`.
    fn at(&self, [a, b]: [usize; 2], k: usize) -> f64 {
        let mut ijk = [0; 3];
        let [p, q] = self.in_slice_axes();
        (ijk[p], ijk[q], ijk[self.axis]) = (a, b, k);
        self.volume.value(self.volume.index(ijk[0], ijk[1], ijk[2]))
    }

    /// Whether column `column` is above the threshold at slice `k`.
    fn inside(&self, column: [usize; 2], k: usize) -> bool {
        self.at(column, k) > self.threshold
    }

    /// The first and last slice of the run above the threshold through slice `k` (which
    /// must be in it) of column `column`.
    fn run_through(&self, column: [usize; 2], k: usize) -> (usize, usize) {
        let n = self.volume.dims()[self.axis];
        let first = (0..k)
            .rev()
            .find(|&j| !self.inside(column, j))
            .map_or(0, |j| j + 1);
        let last = (k + 1..n)
            .find(|&j| !self.inside(column, j))
            .map_or(n - 1, |j| j - 1);
        (first, last)
    }

    /// The centroid (slice coordinate) of the part where column `column` crosses it at
    /// slice coordinate `w`: over the run of slices above the threshold that holds one of
    /// the two slices around `w` (the higher), and the slice on either side (where a plate
    /// thinner than a slice leaves part of itself), the mean slice weighted by the values
    /// above the background. `None` when neither slice is above the threshold, the run
    /// reaches the grid's end or is longer than `max_run` slices.
    fn column_centroid(&self, column: [usize; 2], w: f64, max_run: usize) -> Option<f64> {
        let n = self.volume.dims()[self.axis];
        let below = w.floor().clamp(0.0, (n - 1) as f64) as usize;
        let above = (below + 1).min(n - 1);
        let start = [below, above]
            .into_iter()
            .filter(|&k| self.inside(column, k))
            .max_by(|&x, &y| self.at(column, x).total_cmp(&self.at(column, y)))?;
        let (first, last) = self.run_through(column, start);
        if first == 0 || last + 1 == n || last - first + 1 > max_run {
            return None;
        }
        let (mut total, mut moment) = (0.0, 0.0);
        for k in first - 1..=last + 1 {
            let weight = (self.at(column, k) - self.background).max(0.0);
            total += weight;
            moment += weight * k as f64;
        }
        (total > 0.0).then(|| moment / total)
    }

    /// The weighted mean ([`NEIGHBOUR_WEIGHTS`]) of the centroids of `column` (at `w`) and of
    /// its neighbours (at the column's centroid) within a slice of its own, `None` without
    /// the column's own or with less than [`MIN_NEIGHBOUR_WEIGHT`] of them. The neighbours
    /// look for the part where the column found it, so that a vertex moved there finds the
    /// same columns again.
    fn smoothed_centroid(&self, column: [usize; 2], w: f64, max_run: usize) -> Option<f64> {
        let own = self.column_centroid(column, w, max_run)?;
        let dims = self.volume.dims();
        let [p, q] = self.in_slice_axes();
        let (mut total, mut sum) = (0.0, 0.0);
        for (da, wa) in NEIGHBOUR_WEIGHTS {
            for (db, wb) in NEIGHBOUR_WEIGHTS {
                let (a, b) = (column[0] as i64 + da, column[1] as i64 + db);
                if a < 0 || b < 0 || a >= dims[p] as i64 || b >= dims[q] as i64 {
                    continue;
                }
                if let Some(c) = self.column_centroid([a as usize, b as usize], own, max_run)
                    && (c - own).abs() <= 1.0
                {
                    total += wa * wb;
                    sum += wa * wb * c;
                }
            }
        }
        (total >= MIN_NEIGHBOUR_WEIGHT).then(|| sum / total)
    }

    /// What `column` crosses within [`OFF_PLATE_REACH_SLICES`] of slice coordinate `w`:
    /// among its runs of slices above the threshold there, the smoothed centroid of the one
    /// nearest `w`; air where no slice there reaches [`AIR_BELOW`] of the way from the
    /// background to the threshold; unknown where a run is longer than `max_run` slices (a
    /// part standing along the axis, whose sheet may lie anywhere along the column), or no
    /// run has a smoothed centroid, or a slice is faint but not air.
    fn crossing(&self, column: [usize; 2], w: f64, max_run: usize) -> Crossing {
        let last_slice = (self.volume.dims()[self.axis] - 1) as f64;
        let lo = (w - OFF_PLATE_REACH_SLICES).ceil().clamp(0.0, last_slice) as usize;
        let hi = (w + OFF_PLATE_REACH_SLICES).floor().clamp(0.0, last_slice) as usize;
        let mut nearest: Option<f64> = None;
        let mut k = lo;
        while k <= hi {
            if !self.inside(column, k) {
                k += 1;
                continue;
            }
            let (first, last) = self.run_through(column, k);
            if last - first + 1 > max_run {
                return Crossing::Unknown;
            }
            if let Some(c) = self.smoothed_centroid(column, k as f64, max_run)
                && nearest.is_none_or(|b| (c - w).abs() < (b - w).abs())
            {
                nearest = Some(c);
            }
            k = last + 1;
        }
        let faint = self.background + AIR_BELOW * (self.threshold - self.background);
        match nearest {
            Some(c) => Crossing::Plate(c),
            None if (lo..=hi).all(|k| self.at(column, k) <= faint) => Crossing::Air,
            None => Crossing::Unknown,
        }
    }
}

/// A column reads air where none of its slices near the sheet reaches this share of the way
/// from the background to the threshold. A plate thinner than a slice can read below the
/// threshold at its thin end, where the resampled grid still holds it: on the generated
/// wedge on 5:1 slices at 30 % noise, counting every column below the threshold as air
/// collapsed pieces of its thin end (coverage 0.921 → 0.919 with seed 1), and 0.5 left
/// most pieces over the perforated plates' holes (spurious share 0.088 → 0.087 on the hole
/// plate, against 0.047 with 0.75).
const AIR_BELOW: f64 = 0.75;

/// What a column of thick slices crosses near a point ([`ThickSlices::crossing`]).
enum Crossing {
    /// A plate, with this smoothed centroid (slice coordinate).
    Plate(f64),
    /// Nothing near the threshold.
    Air,
    /// The part, but no plate whose centroid is known.
    Unknown,
}

/// How far along the slice axis (slices) [`collapse_off_plate_triangles`] looks for the
/// plate a triangle's column crosses: the skirts the slices' interpolant hangs from a
/// plate's rim reach a slice below it. 1.5 and 3 gave the same 5:1 table as 2.
const OFF_PLATE_REACH_SLICES: f64 = 2.0;

/// Collapses the triangles of the sheet that stand off the plates of thick slices: a
/// triangle whose centroid lies more than `max_off_plate_pixels` along the slice axis from
/// the smoothed centroid of the plate its column (the nearest) crosses within two slices
/// (see [`centre_on_slice_centroids`]) is removed, and so is one whose column reads air
/// within those two slices, first of all, then the others farthest first, as far as
/// elementary collapses from the free edges reach (the sheet keeps its components and Euler
/// characteristic). Columns crossing the part in more than `max_run_slices` slices within
/// that reach judge nothing. Returns the triangles removed.
///
/// Across slices thicker than a plate the interpolated grid's ridge also runs along the
/// slice axis where the plate ends or bends away from the slices: skirts hang from the
/// rims of the generated spherical cap and curved plate on 5:1 slices (spurious share 0.12
/// and 0.07 noise-free), fins stand on noisy plates, and on the head CT's 4.8 mm slices
/// small patches overlap the vault where it runs along the slices, whose outlines passed
/// for 42 holes over 20 mm. Their columns cross the plate a slice or more from them. The
/// bound is in pixels, the tolerance the sheet is held to: 1.5 pixels (0.3 slices on 5:1
/// slices, 0.5 on 3:1) left the 3:1 table's coverage as it was; 0.3 slices on 3:1 slices
/// cost the wedge and the perforated plate at 30 % noise 0.006 and 0.010 of coverage.
///
/// Noise grows flaps of sheet over the holes of perforated plates and past their rims, over
/// columns that cross no plate at all: on the generated hole plate on 5:1 slices at 30 %
/// noise they were most of its spurious share (0.088 → 0.047 once collapsed, seed 1).
pub fn collapse_off_plate_triangles(
    sheet: &mut TriMesh,
    slices: &ThickSlices<'_>,
    params: &SliceCentroidParams,
) -> usize {
    let to_voxel = slices.volume.affine().inverse();
    let dims = slices.volume.dims();
    let [p, q] = slices.in_slice_axes();
    let max_off = params.max_off_plate_pixels / slices.slice_pixels();
    let off: Vec<f64> = sheet
        .triangles
        .par_iter()
        .map(|t| {
            let centroid = t.iter().map(|&i| sheet.vertices[i as usize]).sum::<DVec3>() / 3.0;
            let g = to_voxel.transform_point3(centroid).to_array();
            let (a, b, w) = (g[p].round(), g[q].round(), g[slices.axis]);
            if a < 0.0 || b < 0.0 || a as usize >= dims[p] || b as usize >= dims[q] {
                return 0.0;
            }
            match slices.crossing([a as usize, b as usize], w, params.max_run_slices) {
                Crossing::Plate(c) => (c - w).abs(),
                Crossing::Air => f64::INFINITY,
                Crossing::Unknown => 0.0,
            }
        })
        .collect();
    let removable: Vec<bool> = off.iter().map(|&d| d > max_off).collect();
    let farthest_first: Vec<f64> = off.iter().map(|&d| -d).collect();
    let removed = collapse_in_order(sheet, &removable, &farthest_first);
    retain_triangles(&mut sheet.triangles, |t| !removed[t]);
    removed.iter().filter(|&&r| r).count()
}

/// Moves the sheet's vertices along the slice axis of `slices` to the centroid of the part
/// across the slices there; returns how many moved. Only the coordinate along the slice
/// axis changes.
///
/// A scanner's thick slice holds the mean of the part over the slice's extent. Resampled
/// along their axis (Catmull–Rom, [`crate::resample_volume`]), slices thicker than a plate
/// peak near the slice holding most of it, and so does the ridge of the cover's function:
/// for a plate 4.2 voxels thick (PSF σ 0.8 voxel) on slices 5 voxels thick, the
/// interpolant's maximum lies 0.8 voxels from the plate's mid-plane on average over the
/// plate's offsets against the slices, and up to 1.3 (a one-dimensional computation). The
/// slices' values sum to the plate's profile integrated over the column, and their first
/// moment nearly to its first moment (each slice puts its share at its centre), so the
/// centroid of the values above the background lies within 0.17 voxels of the mid-plane
/// (0.5 for a plate 3 voxels thick, 0.3 for 8). At a vertex whose normal is within
/// `min_axis_cosine` of the slice axis, the four columns of slices around it give their
/// centroids, each the weighted mean of its own and its 24 neighbours' (where those cross
/// the same plate), interpolated bilinearly; the vertex moves there along the axis when
/// every column gives one and the move is at most `max_shift_slices`. Elsewhere (sheets
/// along the slice axis, junctions, rims past the part's edge) it stays.
///
/// Normals are the sums of the incident triangles' normals, each turned to agree with the
/// sum so far, so that patches of either orientation count alike.
pub fn centre_on_slice_centroids(
    sheet: &mut TriMesh,
    slices: &ThickSlices<'_>,
    params: &SliceCentroidParams,
) -> usize {
    let affine = slices.volume.affine();
    let to_voxel = affine.inverse();
    let axis = slices.axis_direction();
    let dims = slices.volume.dims();
    let [p, q] = slices.in_slice_axes();
    let normals = unoriented_normals(sheet);
    let moved: Vec<Option<DVec3>> = sheet
        .vertices
        .par_iter()
        .zip(&normals)
        .map(|(&x, &normal)| {
            if normal.dot(axis).abs() < params.min_axis_cosine {
                return None;
            }
            let mut g = to_voxel.transform_point3(x).to_array();
            let (a, b, w) = (g[p].floor(), g[q].floor(), g[slices.axis]);
            if a < 0.0 || b < 0.0 || a as usize + 1 >= dims[p] || b as usize + 1 >= dims[q] {
                return None;
            }
            let (fa, fb) = (g[p] - a, g[q] - b);
            let mut centroid = 0.0;
            for (da, wa) in [(0, 1.0 - fa), (1, fa)] {
                for (db, wb) in [(0, 1.0 - fb), (1, fb)] {
                    let column = [a as usize + da, b as usize + db];
                    centroid +=
                        wa * wb * slices.smoothed_centroid(column, w, params.max_run_slices)?;
                }
            }
            if (centroid - w).abs() > params.max_shift_slices {
                return None;
            }
            g[slices.axis] = centroid;
            Some(affine.transform_point3(DVec3::from_array(g)))
        })
        .collect();
    let mut count = 0;
    for (x, new) in sheet.vertices.iter_mut().zip(moved) {
        if let Some(new) = new {
            *x = new;
            count += 1;
        }
    }
    count
}

/// Unit vertex normals from the incident triangles, each triangle's normal turned to agree
/// with the vertex's sum so far; zero where the triangles have no area.
fn unoriented_normals(sheet: &TriMesh) -> Vec<DVec3> {
    let mut normals = vec![DVec3::ZERO; sheet.vertices.len()];
    for t in &sheet.triangles {
        let [a, b, c] = t.map(|i| sheet.vertices[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in t {
            let sum = &mut normals[i as usize];
            *sum += if sum.dot(n) < 0.0 { -n } else { n };
        }
    }
    normals
        .into_iter()
        .map(|n| n.try_normalize().unwrap_or(DVec3::ZERO))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use sphcover_core::{MeshTopology, VoxelValues};

    /// The share of a plate of `thickness` pixels (mid-plane `normal·x = c`, pixels 1 apart,
    /// PSF σ 0.8 pixel) at `x`.
    fn plate_profile(normal: DVec3, c: f64, thickness: f64, x: DVec3) -> f64 {
        let u = normal.dot(x) - c;
        let s = 0.8 * std::f64::consts::SQRT_2;
        0.5 * (erf((u + 0.5 * thickness) / s) - erf((u - 0.5 * thickness) / s))
    }

    /// The error function (Abramowitz and Stegun 7.1.26, error below 1.5e-7).
    fn erf(x: f64) -> f64 {
        let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
        let poly = t
            * (0.254_829_592
                + t * (-0.284_496_736
                    + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
        (1.0 - poly * (-x * x).exp()).copysign(x)
    }

    /// The plate on slices `slice` pixels thick along z (each the mean of the plate over its
    /// extent), 24 × 24 pixels and 50 pixels deep; values 0 (air) to 1 (plate).
    fn thick_plate(normal: DVec3, c: f64, thickness: f64, slice: usize) -> Volume {
        thick_plate_over(normal, c, thickness, slice, |_| 1.0)
    }

    /// [`thick_plate`] with the values of the columns at pixel `x` scaled by `share(x)`.
    fn thick_plate_over(
        normal: DVec3,
        c: f64,
        thickness: f64,
        slice: usize,
        share: impl Fn(usize) -> f64,
    ) -> Volume {
        let dims = [24, 24, 50 / slice];
        let mut values = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let mean = (0..slice * 8)
                        .map(|s| {
                            let z = (k * slice) as f64 + (s as f64 + 0.5) / 8.0 - 0.5;
                            plate_profile(normal, c, thickness, DVec3::new(i as f64, j as f64, z))
                        })
                        .sum::<f64>()
                        / (slice * 8) as f64;
                    values.push((share(i) * mean) as f32);
                }
            }
        }
        // Slice k covers z from k·slice − 0.5 to (k + 1)·slice − 0.5: its centre is the
        // world z of its voxel centre.
        let origin = DVec3::new(0.0, 0.0, 0.5 * (slice as f64 - 1.0));
        let size = DVec3::new(1.0, 1.0, slice as f64);
        Volume::axis_aligned(dims, VoxelValues::F32(values), size, origin).unwrap()
    }

    /// A sheet of 1-pixel squares over `[4, 19]²` in x and y, at height `z(x, y)`.
    fn sheet_over(z: impl Fn(f64, f64) -> f64) -> TriMesh {
        let mut sheet = crate::repair::grid(15, 15);
        for v in &mut sheet.vertices {
            let (x, y) = (4.0 + v.x, 4.0 + v.y);
            *v = DVec3::new(x, y, z(x, y));
        }
        sheet
    }

    fn slices(volume: &Volume) -> ThickSlices<'_> {
        ThickSlices {
            volume,
            axis: 2,
            threshold: 0.3,
            background: 0.0,
        }
    }

    /// The normal of a plane tilted `tilt` off the slices towards `azimuth`.
    fn tilted(tilt: f64, azimuth: f64) -> DVec3 {
        DVec3::new(
            tilt.sin() * azimuth.cos(),
            tilt.sin() * azimuth.sin(),
            tilt.cos(),
        )
    }

    /// The height of the plane `normal·x = c` over `(x, y)`.
    fn height(normal: DVec3, c: f64, x: f64, y: f64) -> f64 {
        (c - normal.x * x - normal.y * y) / normal.z
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]

        /// A plate 4–8 pixels thick, tilted up to 30° off slices 3–5 pixels thick, with the
        /// sheet placed anywhere within 0.3 slices of its mid-plane (as far as the slices'
        /// interpolant puts it) and a little rough:
        /// every vertex moves
        /// along z alone, to within 0.4 pixels of the mid-plane, and a second pass leaves
        /// it there.
        #[test]
        fn vertices_move_along_the_slices_onto_the_mid_plane(
            thickness in 4.0..8.0f64,
            tilt in 0.0..30f64,
            azimuth in 0.0..std::f64::consts::TAU,
            centre_height in 22.0..27.0f64,
            slice in 3usize..=5,
            offset in -0.3..0.3f64,
            jitter in prop::collection::vec(-0.05..0.05f64, 256),
        ) {
            let normal = tilted(tilt.to_radians(), azimuth);
            let c = normal.dot(DVec3::new(11.5, 11.5, centre_height));
            let volume = thick_plate(normal, c, thickness, slice);
            let mut sheet = sheet_over(|x, y| height(normal, c, x, y));
            for (v, j) in sheet.vertices.iter_mut().zip(&jitter) {
                v.z += (offset + j) * slice as f64;
            }
            let before = sheet.vertices.clone();
            // Slices 3 pixels thick hold a plate 8 pixels thick tilted 30° in up to 5.
            let params = SliceCentroidParams {
                max_run_slices: 6,
                ..SliceCentroidParams::default()
            };
            let moved = centre_on_slice_centroids(&mut sheet, &slices(&volume), &params);
            prop_assert_eq!(moved, sheet.vertices.len());
            for (old, new) in before.iter().zip(&sheet.vertices) {
                prop_assert!(old.truncate().distance(new.truncate()) < 1e-9);
                let off = normal.dot(*new) - c;
                prop_assert!(off.abs() < 0.4, "{:?} is {:.3} pixels off", new, off);
            }
            let once = sheet.vertices.clone();
            centre_on_slice_centroids(&mut sheet, &slices(&volume), &params);
            for (a, b) in once.iter().zip(&sheet.vertices) {
                prop_assert!(a.distance(*b) < 1e-9);
            }
        }
    }

    /// Where the slices' interpolant puts a flat plate 4 pixels thick whose mid-plane lies
    /// 1.5 pixels above a slice's centre (5-pixel slices), the sheet follows the centroid;
    /// the sheet's vertices standing along the slice axis (a web) stay.
    #[test]
    fn a_plate_between_slice_centres_is_found_and_a_web_stays() {
        let normal = DVec3::Z;
        let c = 14.0 + 1.5;
        let volume = thick_plate(normal, c, 4.0, 5);
        let mut sheet = sheet_over(|_, _| 14.0);
        let params = SliceCentroidParams::default();
        let moved = centre_on_slice_centroids(&mut sheet, &slices(&volume), &params);
        assert_eq!(moved, sheet.vertices.len());
        for v in &sheet.vertices {
            assert!((v.z - c).abs() < 0.25, "{v:?}");
        }

        // A web: the same squares stood up in the plane x = 10.
        let mut web = sheet_over(|_, _| 0.0);
        for v in &mut web.vertices {
            *v = DVec3::new(10.0, v.y, v.x + 6.0);
        }
        let before = web.vertices.clone();
        assert_eq!(
            centre_on_slice_centroids(&mut web, &slices(&volume), &params),
            0
        );
        assert_eq!(web.vertices, before);
    }

    /// A sheet farther from the centroid than `max_shift_slices` stays where it is.
    #[test]
    fn moves_are_at_most_max_shift_slices() {
        let volume = thick_plate(DVec3::Z, 17.0, 4.0, 5);
        let params = SliceCentroidParams::default();
        for (z, moved) in [(17.0 + 2.4, true), (17.0 + 2.6, false)] {
            let mut sheet = sheet_over(|_, _| z);
            let count = centre_on_slice_centroids(&mut sheet, &slices(&volume), &params);
            assert_eq!(count, if moved { sheet.vertices.len() } else { 0 }, "{z}");
        }
    }

    /// The flat sheet of [`sheet_over`] with a fin hanging from its row `y = 11` down
    /// `depth` pixels in two strips (the fin's triangles last).
    fn sheet_with_fin(z: f64, depth: f64) -> (TriMesh, usize) {
        let mut sheet = sheet_over(|_, _| z);
        let n = 16u32;
        let first_fin = sheet.triangles.len();
        let rows: Vec<Vec<u32>> = (1..=2)
            .map(|r| {
                (0..n)
                    .map(|i| {
                        sheet.vertices.push(DVec3::new(
                            4.0 + i as f64,
                            11.0,
                            z - depth * r as f64 / 2.0,
                        ));
                        (sheet.vertices.len() - 1) as u32
                    })
                    .collect()
            })
            .collect();
        let top: Vec<u32> = (0..n).map(|i| 7 * n + i).collect();
        for (upper, lower) in [(&top, &rows[0]), (&rows[0], &rows[1])] {
            for i in 0..(n - 1) as usize {
                sheet.triangles.push([upper[i], upper[i + 1], lower[i + 1]]);
                sheet.triangles.push([upper[i], lower[i + 1], lower[i]]);
            }
        }
        (sheet, first_fin)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]

        /// Whatever stands off the plate, only triangles off it go, and the sheet keeps its
        /// components and Euler characteristic.
        #[test]
        fn off_plate_collapses_keep_the_topology(
            depth in 1.0..12.0f64,
            heights in prop::collection::vec(-4.0..4.0f64, 256),
        ) {
            let volume = thick_plate(DVec3::Z, 22.0, 4.0, 5);
            let (mut sheet, _) = sheet_with_fin(22.0, depth);
            for (v, h) in sheet.vertices.iter_mut().zip(&heights) {
                v.z += h;
            }
            let before = MeshTopology::of(&sheet);
            let params = SliceCentroidParams::default();
            collapse_off_plate_triangles(&mut sheet, &slices(&volume), &params);
            let after = MeshTopology::of(&sheet);
            prop_assert_eq!(after.components, before.components);
            prop_assert_eq!(after.euler_characteristic(), before.euler_characteristic());
        }
    }

    /// A fin hanging 6 pixels below a plate on 5-pixel slices is collapsed up to where it
    /// comes within 1.5 pixels of the plate; the sheet on the plate stays whole.
    #[test]
    fn a_fin_off_the_plate_is_collapsed() {
        let volume = thick_plate(DVec3::Z, 22.0, 4.0, 5);
        let (mut sheet, first_fin) = sheet_with_fin(22.0, 6.0);
        let plate = sheet.triangles[..first_fin].to_vec();
        let params = SliceCentroidParams::default();
        let removed = collapse_off_plate_triangles(&mut sheet, &slices(&volume), &params);
        assert_eq!(sheet.triangles[..first_fin], plate[..]);
        // The lower strip (centroids 4–5 pixels down) and the lower triangles of the upper
        // one (2 pixels down) go; the upper ones (1 pixel down) stay.
        assert_eq!(removed, 45);
        let mut still = sheet.clone();
        let params = SliceCentroidParams {
            max_off_plate_pixels: 10.0,
            ..params
        };
        assert_eq!(
            collapse_off_plate_triangles(&mut still, &slices(&volume), &params),
            0
        );
    }

    /// The sheet runs on past a plate that ends at x = 11.5: over air (columns at 0) the
    /// triangles whose centroids' columns lie past the edge are collapsed, and the sheet
    /// stays one disk; where the plate goes on faint (at 0.35 of its values: a peak of 0.26,
    /// between `AIR_BELOW` of the threshold and the threshold) nothing is.
    #[test]
    fn a_sheet_past_the_plate_over_air_is_collapsed() {
        let params = SliceCentroidParams::default();
        for (beyond, collapsed) in [(0.0, true), (0.35, false)] {
            let edge = |x: usize| if x < 12 { 1.0 } else { beyond };
            let volume = thick_plate_over(DVec3::Z, 22.0, 4.0, 5, edge);
            let mut sheet = sheet_over(|_, _| 22.0);
            let past_edge = |sheet: &TriMesh| {
                let x = |t: &[u32; 3]| t.iter().map(|&v| sheet.vertices[v as usize].x).sum::<f64>();
                sheet.triangles.iter().filter(|t| x(t) / 3.0 > 11.5).count()
            };
            let before = past_edge(&sheet);
            let over_plate = sheet.triangles.len() - before;
            let removed = collapse_off_plate_triangles(&mut sheet, &slices(&volume), &params);
            if collapsed {
                assert_eq!((removed, past_edge(&sheet)), (before, 0));
                assert_eq!(sheet.triangles.len(), over_plate);
                let topology = MeshTopology::of(&sheet);
                assert_eq!(
                    (topology.components, topology.euler_characteristic()),
                    (1, 1)
                );
            } else {
                assert_eq!(removed, 0);
            }
        }
    }

    /// A column that crosses the part in more slices than `max_run_slices` (a part standing
    /// along the slice axis, not a plate across it) moves no vertex.
    #[test]
    fn long_runs_along_the_slices_are_left_alone() {
        let volume = thick_plate(DVec3::Z, 15.0, 12.0, 3);
        let mut sheet = sheet_over(|_, _| 15.0);
        let mut params = SliceCentroidParams::default();
        assert_eq!(
            centre_on_slice_centroids(&mut sheet, &slices(&volume), &params),
            0
        );
        params.max_run_slices = 5;
        assert_eq!(
            centre_on_slice_centroids(&mut sheet, &slices(&volume), &params),
            sheet.vertices.len()
        );
    }
}
