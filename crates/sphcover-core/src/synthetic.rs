//! Deterministic synthetic covers, for tests and benchmarks.
//!
//! Three families, from easy to realistic:
//!
//! * [`regular_grid`]: supports on a cubic lattice of spacing `h` with radius `ρ·h`, the setting
//!   in which the thesis operators are analysed (thesis §4; consistency is measured there).
//! * [`jittered_grid`]: the same with seeded random displacements of the centres and radii.
//! * [`adaptive_surface_cover`]: an octree refined near an analytic surface, 2:1 balanced, with
//!   a support at every leaf centre and radius `0.75 ×` the leaf diagonal: the shape of the
//!   initial covers of thesis §3.4.1, with radii spanning as many octaves as refinement levels.
//!   It produces a million supports in about half a second.
//!
//! Randomness comes from `rand_pcg::Pcg64` seeded by the caller, so the same parameters give
//! the same cover on every platform and for any thread count.
//!
//! Beside the covers, the plain shapes that tests, examples and benchmarks sample:
//! [`fibonacci_sphere`] (evenly spread directions), [`uv_sphere`] (a closed triangle mesh),
//! [`thin_wall`] (both faces of a wall) and [`voxel_subsamples`] (the points at which a
//! voxel's partial volume is measured); and, for
//! the tests of the volume readers' limits, `gzip_with_zeros` (a decompression bomb).

use crate::ParameterError;
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use thiserror::Error;

use crate::geometry::Aabb;

/// Largest octree depth of [`adaptive_surface_cover`]: cell coordinates are packed in 21 bits
/// per axis.
pub const MAX_OCTREE_DEPTH: u32 = 20;

/// Largest number of supports a generator will produce (indices are `u32`).
const MAX_SUPPORTS: u64 = u32::MAX as u64;

/// A synthetic cover: support `i` is the ball `(centres[i], radii[i])`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SyntheticCover {
    /// Support centres.
    pub centres: Vec<DVec3>,
    /// Support radii, one per centre.
    pub radii: Vec<f64>,
}

impl SyntheticCover {
    /// Number of supports.
    pub fn len(&self) -> usize {
        self.centres.len()
    }

    /// True when the cover has no support.
    pub fn is_empty(&self) -> bool {
        self.centres.is_empty()
    }
}

/// Why a synthetic cover could not be generated.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum SyntheticError {
    /// A parameter is out of its documented range.
    #[error(transparent)]
    InvalidParameter(#[from] ParameterError),
    /// The domain box is empty or not finite.
    #[error("the domain box is empty or not finite")]
    InvalidDomain,
    /// The parameters ask for more supports than `u32` indices can address.
    #[error("{count} supports exceed the u32 index range")]
    TooManySupports {
        /// Number of supports (or cells) the parameters ask for.
        count: u64,
    },
}

fn check(
    name: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), SyntheticError> {
    if ok {
        Ok(())
    } else {
        Err(SyntheticError::InvalidParameter(ParameterError {
            name,
            value,
            expected,
        }))
    }
}

fn check_domain(domain: &Aabb) -> Result<(), SyntheticError> {
    if domain.is_empty() || !domain.min.is_finite() || !domain.max.is_finite() {
        Err(SyntheticError::InvalidDomain)
    } else {
        Ok(())
    }
}

/// Lattice points `domain.min + h·(a, b, c)` inside the domain, x fastest.
fn lattice(domain: &Aabb, spacing: f64) -> Result<Vec<DVec3>, SyntheticError> {
    check_domain(domain)?;
    check(
        "spacing",
        spacing,
        spacing > 0.0 && spacing.is_finite(),
        "finite and > 0",
    )?;
    // The small tolerance keeps the far face when the extent is a multiple of the spacing up
    // to rounding.
    let steps = (domain.extent() / spacing * (1.0 + 1e-12)).floor();
    let count = (steps + DVec3::ONE).element_product();
    if count > MAX_SUPPORTS as f64 {
        return Err(SyntheticError::TooManySupports {
            count: if count.is_finite() {
                count as u64
            } else {
                u64::MAX
            },
        });
    }
    let n = (steps + DVec3::ONE).as_uvec3();
    let mut points = Vec::with_capacity(count as usize);
    for c in 0..n.z {
        for b in 0..n.y {
            for a in 0..n.x {
                points.push(domain.min + spacing * DVec3::new(a as f64, b as f64, c as f64));
            }
        }
    }
    Ok(points)
}

/// Supports at the lattice points `domain.min + h·(a, b, c)` lying in `domain`, each with
/// radius `radius_factor · h`. The order is x fastest, then y, then z.
///
/// `spacing` and `radius_factor` must be finite and positive; a cover needs
/// `radius_factor > √3/2` for the balls to leave no gap.
pub fn regular_grid(
    domain: Aabb,
    spacing: f64,
    radius_factor: f64,
) -> Result<SyntheticCover, SyntheticError> {
    check(
        "radius_factor",
        radius_factor,
        radius_factor > 0.0 && radius_factor.is_finite(),
        "finite and > 0",
    )?;
    let centres = lattice(&domain, spacing)?;
    let radii = vec![radius_factor * spacing; centres.len()];
    Ok(SyntheticCover { centres, radii })
}

/// A [`regular_grid`] with seeded random perturbations: each centre moves by a uniform offset
/// in `[−jitter·h, jitter·h]³` and each radius is `radius_factor · h · (1 + jitter·u)` with `u`
/// uniform in `[−1, 1]`.
///
/// `jitter` must lie in `[0, 1)`, so radii stay positive.
pub fn jittered_grid(
    domain: Aabb,
    spacing: f64,
    radius_factor: f64,
    jitter: f64,
    seed: u64,
) -> Result<SyntheticCover, SyntheticError> {
    check("jitter", jitter, (0.0..1.0).contains(&jitter), "in [0, 1)")?;
    let mut cover = regular_grid(domain, spacing, radius_factor)?;
    let mut rng = Pcg64::seed_from_u64(seed);
    let amplitude = jitter * spacing;
    for (c, r) in cover.centres.iter_mut().zip(&mut cover.radii) {
        let offset = DVec3::new(
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
            rng.random_range(-1.0..=1.0),
        );
        *c += amplitude * offset;
        *r *= 1.0 + jitter * rng.random_range(-1.0..=1.0);
    }
    Ok(cover)
}

/// `n` directions of a Fibonacci lattice, spread evenly over the unit sphere: point `i` has
/// `z = 1 − (2i + 1)/n` and longitude `i` times the golden angle. On a sphere they are the
/// points and their outward normals at once.
///
/// ```
/// let u = sphcover_core::synthetic::fibonacci_sphere(100);
/// assert_eq!(u.len(), 100);
/// assert!(u.iter().all(|d| (d.length() - 1.0).abs() < 1e-12));
/// ```
pub fn fibonacci_sphere(n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let s = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            DVec3::new(s * a.cos(), s * a.sin(), z)
        })
        .collect()
}

/// Oriented samples of both faces of a flat wall `thickness` thick: the plane `z = 0` with
/// outward normal `−z` and the plane `z = thickness` with `+z`, each on a grid of spacing
/// 0.01 over `[−0.2, 0.2]²`, the two grids offset by 0.003 along `x` and `y` respectively (so
/// no sample lies straight across from another). Returns the points and their normals.
///
/// ```
/// let (points, normals) = sphcover_core::synthetic::thin_wall(0.02);
/// assert_eq!(points.len(), 2 * 41 * 41);
/// assert!(points.iter().zip(&normals).all(|(p, n)| (p.z == 0.0) == (n.z < 0.0)));
/// ```
pub fn thin_wall(thickness: f64) -> (Vec<DVec3>, Vec<DVec3>) {
    let mut points = Vec::new();
    let mut normals = Vec::new();
    for i in -20..=20 {
        for j in -20..=20 {
            let (x, y) = (f64::from(i) * 0.01, f64::from(j) * 0.01);
            points.push(DVec3::new(x + 0.003, y, 0.0));
            normals.push(-DVec3::Z);
            points.push(DVec3::new(x, y + 0.003, thickness));
            normals.push(DVec3::Z);
        }
    }
    (points, normals)
}

/// A closed, outward-wound UV sphere of radius `radius` about the origin with poles on ±y:
/// `stacks` bands of latitude (`≥ 2`) and `slices` vertices per ring (`≥ 3`), equator vertices
/// on ±x and ±z when `stacks` is even and `slices` a multiple of 4.
///
/// ```
/// use sphcover_core::{MeshTopology, synthetic::uv_sphere};
///
/// let mesh = uv_sphere(2.0, 8, 12);
/// assert_eq!(mesh.vertices.len(), 2 + 7 * 12);
/// assert!(MeshTopology::of(&mesh).is_closed_oriented_manifold());
/// ```
pub fn uv_sphere(radius: f64, stacks: usize, slices: usize) -> crate::TriMesh {
    let mut vertices = vec![DVec3::new(0.0, radius, 0.0)];
    for s in 1..stacks {
        let phi = std::f64::consts::PI * s as f64 / stacks as f64;
        for k in 0..slices {
            let theta = std::f64::consts::TAU * k as f64 / slices as f64;
            vertices.push(
                radius * DVec3::new(phi.sin() * theta.cos(), phi.cos(), phi.sin() * theta.sin()),
            );
        }
    }
    vertices.push(DVec3::new(0.0, -radius, 0.0));
    let ring = |s: usize, k: usize| (1 + (s - 1) * slices + k % slices) as u32;
    let south = (vertices.len() - 1) as u32;
    let mut triangles = Vec::new();
    for k in 0..slices {
        triangles.push([0, ring(1, k + 1), ring(1, k)]);
        triangles.push([south, ring(stacks - 1, k), ring(stacks - 1, k + 1)]);
        for s in 1..stacks - 1 {
            triangles.push([ring(s, k), ring(s, k + 1), ring(s + 1, k + 1)]);
            triangles.push([ring(s, k), ring(s + 1, k + 1), ring(s + 1, k)]);
        }
    }
    crate::TriMesh::new(vertices, triangles)
}

/// The 64 points of a 4 × 4 × 4 supersampling of a voxel, as offsets from its centre in voxel
/// units (x fastest): the fraction of them inside a solid is the voxel's partial volume.
pub fn voxel_subsamples() -> impl Iterator<Item = DVec3> {
    (0..64usize).map(|s| {
        DVec3::new(
            (s % 4) as f64 + 0.5,
            ((s / 4) % 4) as f64 + 0.5,
            (s / 16) as f64 + 0.5,
        ) / 4.0
            - 0.5
    })
}

/// An analytic closed surface, given by its signed distance (negative inside).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    /// The sphere `‖p − centre‖ = radius`.
    Sphere {
        /// Centre of the sphere.
        centre: DVec3,
        /// Radius of the sphere.
        radius: f64,
    },
    /// The torus around the axis through `centre` parallel to z: points at distance
    /// `minor_radius` from the circle of radius `major_radius` in the plane `z = centre.z`.
    Torus {
        /// Centre of the torus.
        centre: DVec3,
        /// Radius of the core circle.
        major_radius: f64,
        /// Radius of the tube.
        minor_radius: f64,
    },
}

impl Surface {
    /// Signed Euclidean distance from `p` to the surface, negative inside.
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        match *self {
            Surface::Sphere { centre, radius } => (p - centre).length() - radius,
            Surface::Torus {
                centre,
                major_radius,
                minor_radius,
            } => {
                let q = p - centre;
                let ring = q.truncate().length() - major_radius;
                (ring * ring + q.z * q.z).sqrt() - minor_radius
            }
        }
    }

    fn check(&self) -> Result<(), SyntheticError> {
        match *self {
            Surface::Sphere { centre, radius } => {
                check("centre", f64::NAN, centre.is_finite(), "finite coordinates")?;
                check("radius", radius, radius > 0.0 && radius.is_finite(), "> 0")
            }
            Surface::Torus {
                centre,
                major_radius,
                minor_radius,
            } => {
                check("centre", f64::NAN, centre.is_finite(), "finite coordinates")?;
                check(
                    "major_radius",
                    major_radius,
                    major_radius > 0.0 && major_radius.is_finite(),
                    "> 0",
                )?;
                check(
                    "minor_radius",
                    minor_radius,
                    minor_radius > 0.0 && minor_radius.is_finite(),
                    "> 0",
                )
            }
        }
    }
}

/// Parameters of [`adaptive_surface_cover`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdaptiveCoverParams {
    /// The octree root is the cube centred on this box with edge its longest edge.
    pub domain: Aabb,
    /// The surface the octree is refined around.
    pub surface: Surface,
    /// Every cell shallower than this is refined, wherever it lies.
    pub min_depth: u32,
    /// No cell deeper than this (at most [`MAX_OCTREE_DEPTH`]).
    pub max_depth: u32,
    /// A cell is refined (below `max_depth`) when its centre lies within
    /// `band ×` its half-diagonal of the surface; `band ≥ 1` refines every cell the surface
    /// crosses.
    pub band: f64,
    /// Support radius as a multiple of the leaf diagonal (thesis §3.4.1: 0.75).
    pub radius_factor: f64,
}

impl Default for AdaptiveCoverParams {
    /// A sphere of radius 0.35 in the unit cube `[−0.5, 0.5]³` (the normalised frame of thesis
    /// §3.4.1), refined from depth 2 to depth 7: 149,528 supports.
    fn default() -> Self {
        AdaptiveCoverParams {
            domain: Aabb {
                min: DVec3::splat(-0.5),
                max: DVec3::splat(0.5),
            },
            surface: Surface::Sphere {
                centre: DVec3::ZERO,
                radius: 0.35,
            },
            min_depth: 2,
            max_depth: 7,
            band: 1.0,
            radius_factor: 0.75,
        }
    }
}

/// Bits per axis of a packed cell key.
const KEY_BITS: u32 = 21;
const KEY_MASK: u64 = (1 << KEY_BITS) - 1;

fn pack(a: u64, b: u64, c: u64) -> u64 {
    a | (b << KEY_BITS) | (c << (2 * KEY_BITS))
}

fn unpack(key: u64) -> (u64, u64, u64) {
    (
        key & KEY_MASK,
        (key >> KEY_BITS) & KEY_MASK,
        key >> (2 * KEY_BITS),
    )
}

/// Spreads the low 21 bits of `v` to every third bit (Morton interleaving).
fn spread_bits(v: u64) -> u64 {
    let mut x = v & KEY_MASK;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

fn children(key: u64) -> impl Iterator<Item = u64> {
    let (a, b, c) = unpack(key);
    (0..8u64).map(move |k| pack(2 * a + (k & 1), 2 * b + ((k >> 1) & 1), 2 * c + (k >> 2)))
}

/// An octree refined around `params.surface`, 2:1 balanced across faces, edges and corners,
/// with one support per leaf: centre at the leaf centre, radius `radius_factor ×` the leaf
/// diagonal. Supports come in octree (Morton) order, which keeps neighbours close in memory.
///
/// Counts on the unit cube with the default sphere (radius 0.35), `min_depth` 2, `band` 1:
/// 36,072 supports at `max_depth` 6, 149,528 at 7, 603,856 at 8 and 2,402,296 at 9; a sphere
/// of radius 0.225 gives 998,656 at depth 9. Generating a million supports takes about half
/// a second on two cores.
pub fn adaptive_surface_cover(
    params: &AdaptiveCoverParams,
) -> Result<SyntheticCover, SyntheticError> {
    check_domain(&params.domain)?;
    params.surface.check()?;
    check(
        "max_depth",
        params.max_depth as f64,
        params.max_depth <= MAX_OCTREE_DEPTH,
        "at most MAX_OCTREE_DEPTH",
    )?;
    check(
        "min_depth",
        params.min_depth as f64,
        params.min_depth <= params.max_depth,
        "at most max_depth",
    )?;
    check(
        "band",
        params.band,
        params.band >= 0.0 && params.band.is_finite(),
        "finite and >= 0",
    )?;
    check(
        "radius_factor",
        params.radius_factor,
        params.radius_factor > 0.0 && params.radius_factor.is_finite(),
        "finite and > 0",
    )?;

    let size = params.domain.longest_edge();
    let origin = params.domain.centre() - DVec3::splat(0.5 * size);
    let cell_centre = |key: u64, depth: u32| {
        let (a, b, c) = unpack(key);
        let width = size / (1u64 << depth) as f64;
        origin + width * DVec3::new(a as f64 + 0.5, b as f64 + 0.5, c as f64 + 0.5)
    };
    let half_diagonal = |depth: u32| 0.5 * 3f64.sqrt() * size / (1u64 << depth) as f64;
    let near_surface = |key: u64, depth: u32| {
        params
            .surface
            .signed_distance(cell_centre(key, depth))
            .abs()
            < params.band * half_diagonal(depth)
    };

    // refined[d]: sorted keys of the cells of depth d that have children.
    let max_depth = params.max_depth as usize;
    let mut refined: Vec<Vec<u64>> = vec![Vec::new(); max_depth];
    if max_depth > 0 && (params.min_depth > 0 || near_surface(0, 0)) {
        refined[0].push(0);
    }
    // Every refined cell adds 7 leaves net (8 children replace 1), so the refined count bounds
    // the support count from below: stop before the octree outgrows u32 indices.
    let leaves_at_least =
        |refined: &[Vec<u64>]| 7 * refined.iter().map(|level| level.len() as u64).sum::<u64>() + 1;
    // Uniform refinement to min_depth alone makes 8^min_depth leaves.
    guard_count(1u64 << (3 * params.min_depth.min(21)))?;
    for depth in 1..max_depth {
        let forced = (depth as u32) < params.min_depth;
        let keep = |key: u64| forced || near_surface(key, depth as u32);
        // Count before collecting, so that an octree too large for u32 indices fails before
        // it takes the memory.
        let count = if forced {
            8 * refined[depth - 1].len()
        } else {
            refined[depth - 1]
                .par_iter()
                .map(|&key| children(key).filter(|&child| keep(child)).count())
                .sum()
        };
        guard_count(leaves_at_least(&refined) + 7 * count as u64)?;
        let mut next: Vec<u64> = refined[depth - 1]
            .par_iter()
            .flat_map_iter(|&key| children(key))
            .filter(|&key| keep(key))
            .collect();
        next.par_sort_unstable();
        refined[depth] = next;
    }

    // 2:1 balance: a refined cell at depth d forces refinement of every cell of depth d − 1
    // touching its parent (the parent included). Going deepest first, each level is complete
    // before it forces the next one up, and a leaf can only touch leaves at most one level
    // deeper.
    for depth in (1..max_depth).rev() {
        let limit = 1u64 << (depth - 1);
        let forced: Vec<u64> = refined[depth]
            .par_iter()
            .flat_map_iter(|&key| {
                let (a, b, c) = unpack(key);
                let (pa, pb, pc) = ((a / 2) as i64, (b / 2) as i64, (c / 2) as i64);
                (0..27).filter_map(move |k| {
                    let na = pa + k % 3 - 1;
                    let nb = pb + (k / 3) % 3 - 1;
                    let nc = pc + k / 9 - 1;
                    let inside = |v: i64| v >= 0 && (v as u64) < limit;
                    (inside(na) && inside(nb) && inside(nc))
                        .then(|| pack(na as u64, nb as u64, nc as u64))
                })
            })
            .collect();
        let level = &mut refined[depth - 1];
        level.extend(forced);
        level.par_sort_unstable();
        level.dedup();
        guard_count(leaves_at_least(&refined))?;
    }

    // Leaves: children of refined cells that are not refined themselves, or the root alone.
    let mut leaves: Vec<(u64, u32)> = Vec::new();
    if refined.first().is_none_or(|r| r.is_empty()) {
        leaves.push((0, 0));
    }
    for depth in 1..=max_depth {
        let deeper = refined.get(depth).map(Vec::as_slice).unwrap_or(&[]);
        let level_leaves: Vec<(u64, u32)> = refined[depth - 1]
            .par_iter()
            .flat_map_iter(|&key| children(key))
            .filter(|key| deeper.binary_search(key).is_err())
            .map(|key| (key, depth as u32))
            .collect();
        leaves.extend(level_leaves);
        guard_count(leaves.len() as u64)?;
    }

    // Octree order: Morton code of the leaf's lowest corner at the finest resolution. Leaves
    // do not overlap, so these codes are distinct.
    let mut ordered: Vec<(u64, u64, u32)> = leaves
        .into_par_iter()
        .map(|(key, depth)| {
            let shift = max_depth as u32 - depth;
            let (a, b, c) = unpack(key);
            let morton = spread_bits(a << shift)
                | (spread_bits(b << shift) << 1)
                | (spread_bits(c << shift) << 2);
            (morton, key, depth)
        })
        .collect();
    ordered.par_sort_unstable();

    let diagonal = |depth: u32| 3f64.sqrt() * size / (1u64 << depth) as f64;
    let (centres, radii) = ordered
        .par_iter()
        .map(|&(_, key, depth)| {
            (
                cell_centre(key, depth),
                params.radius_factor * diagonal(depth),
            )
        })
        .unzip();
    Ok(SyntheticCover { centres, radii })
}

fn guard_count(count: u64) -> Result<(), SyntheticError> {
    if count > MAX_SUPPORTS {
        Err(SyntheticError::TooManySupports { count })
    } else {
        Ok(())
    }
}

/// A little-endian NIfTI-1 header (with the 4 extension bytes) declaring `dims` voxels of
/// `datatype` (`bitpix` bits), data from byte 352, unit voxels: the head of the readers'
/// test volumes and decompression bombs.
pub fn nifti_header(dims: [i16; 3], datatype: i16, bitpix: i16) -> Vec<u8> {
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    for (i, d) in [3, dims[0], dims[1], dims[2], 1, 1, 1, 1]
        .iter()
        .enumerate()
    {
        h[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&datatype.to_le_bytes());
    h[72..74].copy_from_slice(&bitpix.to_le_bytes());
    for i in 0..8 {
        h[76 + 4 * i..80 + 4 * i].copy_from_slice(&1.0f32.to_le_bytes());
    }
    h[108..112].copy_from_slice(&352.0f32.to_le_bytes());
    h[344..348].copy_from_slice(b"n+1\0");
    h
}

/// A one-block (256-byte) INRIMAGE-4 header declaring `dims` 16-bit signed voxels.
pub fn inrimage_header(dims: [u64; 3]) -> Vec<u8> {
    let mut h = format!(
        "#INRIMAGE-4#{{\nXDIM={}\nYDIM={}\nZDIM={}\nVDIM=1\nTYPE=signed fixed\nPIXSIZE=16 bits\nCPU=pc\n",
        dims[0], dims[1], dims[2]
    )
    .into_bytes();
    h.resize(256 - 4, b'\n');
    h.extend_from_slice(b"##}\n");
    h
}

/// A gzip file (one member) of `head` followed by `zero_mib` MiB of zero bytes, compressed
/// about 1000:1 (a gigabyte of zeros is about a megabyte of file, as any gzip makes it) and
/// built in milliseconds whatever its size: one MiB of zeros is compressed once, flushed to a
/// byte boundary, and repeated. Each repeat refers only to its own bytes, so the repeats
/// decode alike; the trailer's CRC and size are those of the whole. The decompression bombs
/// of the readers' tests and fuzz targets.
#[cfg(feature = "nifti")]
pub fn gzip_with_zeros(head: &[u8], zero_mib: u64) -> Vec<u8> {
    use flate2::{Compress, Compression, Crc, FlushCompress};
    const MIB: usize = 1 << 20;
    // A fresh raw-DEFLATE compressor per piece, flushed (not finished): no piece refers to
    // bytes before it, and none is marked final.
    let deflate = |data: &[u8]| {
        let mut out = Vec::with_capacity(data.len() / 64 + 1024);
        let mut compress = Compress::new(Compression::best(), false);
        // The output holds any input this small: one call consumes and flushes it all.
        compress
            .compress_vec(data, &mut out, FlushCompress::Sync)
            .expect("DEFLATE into a large enough buffer");
        debug_assert_eq!(compress.total_in(), data.len() as u64);
        out
    };
    // Made once per process: the fuzz targets build a file per input.
    static ZERO_MIB: std::sync::OnceLock<(Vec<u8>, Crc)> = std::sync::OnceLock::new();
    let (zero_piece, zero_crc) = ZERO_MIB.get_or_init(|| {
        let zeros = vec![0u8; MIB];
        let mut crc = Crc::new();
        crc.update(&zeros);
        (deflate(&zeros), crc)
    });

    let mut file = vec![0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 0xff];
    file.extend(deflate(head));
    let mut crc = Crc::new();
    crc.update(head);
    for _ in 0..zero_mib {
        file.extend_from_slice(zero_piece);
        crc.combine(zero_crc);
    }
    // An empty final block with fixed codes: BFINAL = 1, BTYPE = 01, end-of-block.
    file.extend([0x03, 0x00]);
    file.extend(crc.sum().to_le_bytes());
    // ISIZE is the length modulo 2^32, as RFC 1952 says.
    let size = (head.len() as u64).wrapping_add(zero_mib << 20);
    file.extend((size as u32).to_le_bytes());
    file
}
