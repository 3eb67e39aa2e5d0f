//! The weighted point sets of `tetra-bench`, generated deterministically, and their binary
//! file format (what the CGAL peer reads).
//!
//! * [`random_spheres`]: `n` centres uniform in the unit cube, weights uniform in
//!   `[0, (f·s)²]` with `s = n^(-1/3)` the mean spacing and `f` = [`RANDOM_RADIUS`] = 0.5 by
//!   default: weights matter, and some points are hidden (redundant) (0.2% at `f = 0.5`);
//! * [`octree_spheres`]: the graded octree cover of a torus of the `sphcover-tetra`
//!   benchmark (`crates/sphcover-tetra/examples/common/octree_torus.rs`, included as a
//!   source file), weighted as `dual_complex` weights a cover with its
//!   default shrink: `(0.75·r)²`. Its centres lie on a dyadic grid and equal cells are
//!   co-spherical: the set is full of exact ties.
//!
//! ```
//! use sphcover_benches::sphere_sets::{SphereSetKind, read_spheres, write_spheres};
//!
//! let set = SphereSetKind::Random.generate(1000, 1, 0.5);
//! assert_eq!((set.points.len(), set.weights.len()), (1000, 1000));
//! let path = std::env::temp_dir().join(format!("sphere-sets-doc-{}.bin", std::process::id()));
//! write_spheres(&path, &set)?;
//! let back = read_spheres(&path)?;
//! std::fs::remove_file(&path)?;
//! assert_eq!((back.points, back.weights), (set.points, set.weights));
//! # Ok::<(), std::io::Error>(())
//! ```

use std::io::{BufWriter, Read, Write};
use std::path::Path;

use sphcover_core::random::SplitMix64;

/// Which set to generate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SphereSetKind {
    /// Uniform centres in the unit cube, random weights ([`random_spheres`]).
    Random,
    /// The octree cover of a torus ([`octree_spheres`]).
    Octree,
}

impl SphereSetKind {
    /// The kind named `random` or `octree`.
    pub fn from_name(name: &str) -> Option<SphereSetKind> {
        match name.trim() {
            "random" => Some(SphereSetKind::Random),
            "octree" => Some(SphereSetKind::Octree),
            _ => None,
        }
    }

    /// Its name, as `from_name` takes it.
    pub fn name(self) -> &'static str {
        match self {
            SphereSetKind::Random => "random",
            SphereSetKind::Octree => "octree",
        }
    }

    /// The set of this kind for `n` (exactly `n` spheres for `random`, about `n` for
    /// `octree`); `seed` and `random_radius` (see [`random_spheres`]) matter for `random`
    /// only.
    pub fn generate(self, n: usize, seed: u64, random_radius: f64) -> SphereSet {
        match self {
            SphereSetKind::Random => random_spheres(n, seed, random_radius),
            SphereSetKind::Octree => octree_spheres(n),
        }
    }
}

/// Centres and weights (squared radii), and how they were made.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SphereSet {
    /// Centres.
    pub points: Vec<[f64; 3]>,
    /// Weights, one per centre.
    pub weights: Vec<f64>,
    /// One line on the generator's parameters.
    pub description: String,
}

impl SphereSet {
    /// Number of spheres.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when there is no sphere.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// A uniform `f64` in `[0, 1)` with 53 random bits.
fn unit(rng: &mut SplitMix64) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The default largest radius of the random set, in mean spacings.
pub const RANDOM_RADIUS: f64 = 0.5;

/// `n` centres uniform in the unit cube, weights uniform in `[0, (radius·s)²]`,
/// `s = n^(-1/3)`; per sphere x, y, z, then the weight, from one `SplitMix64` stream seeded
/// with `seed`.
pub fn random_spheres(n: usize, seed: u64, radius: f64) -> SphereSet {
    let mut rng = SplitMix64::new(seed);
    let s = (n.max(1) as f64).powf(-1.0 / 3.0);
    let max_weight = (radius * s) * (radius * s);
    let mut points = Vec::with_capacity(n);
    let mut weights = Vec::with_capacity(n);
    for _ in 0..n {
        let p = [unit(&mut rng), unit(&mut rng), unit(&mut rng)];
        points.push(p);
        weights.push(max_weight * unit(&mut rng));
    }
    SphereSet {
        points,
        weights,
        description: format!(
            "uniform in the unit cube, weights in [0, {max_weight:.3e}], seed {seed}"
        ),
    }
}

// The generator of the `sphcover-tetra` example and criterion bench, shared as a source file
// (an example cannot be imported).
#[path = "../../crates/sphcover-tetra/examples/common/octree_torus.rs"]
mod octree_torus;
pub use octree_torus::{octree_torus_cover, octree_torus_cover_of_size};

/// The radius shrink of `sphcover_tetra::DualComplexParams::default()`.
pub const OCTREE_SHRINK: f64 = 0.75;

/// The octree cover of about `n` supports, weighted as `sphcover_tetra::dual_complex`
/// weights it with the default shrink: `s = 0.75·r`, weight `s·s`.
pub fn octree_spheres(n: usize) -> SphereSet {
    let (depth, band, centres, radii) = octree_torus_cover_of_size(n);
    SphereSet {
        points: centres.iter().map(|c| c.to_array()).collect(),
        weights: radii
            .iter()
            .map(|&r| {
                let s = r * OCTREE_SHRINK;
                s * s
            })
            .collect(),
        description: format!(
            "octree cover of a torus, depth {depth}, band {band:.3}, weights (0.75·r)²"
        ),
    }
}

/// Writes the spheres as little-endian `f64` quadruples x, y, z, w (32 bytes each).
pub fn write_spheres(path: &Path, set: &SphereSet) -> std::io::Result<()> {
    let mut out = BufWriter::new(std::fs::File::create(path)?);
    for (p, w) in set.points.iter().zip(&set.weights) {
        for x in [p[0], p[1], p[2], *w] {
            out.write_all(&x.to_le_bytes())?;
        }
    }
    out.flush()
}

/// Reads a file of [`write_spheres`], sphere by sphere into vectors of the exact size (no
/// whole-file buffer: a measurement of peak memory after it sees only the set).
pub fn read_spheres(path: &Path) -> std::io::Result<SphereSet> {
    let (mut input, n) = crate::open_records(path, 32, "spheres")?;
    let mut points = Vec::with_capacity(n);
    let mut weights = Vec::with_capacity(n);
    let mut buf = [0u8; 32];
    for _ in 0..n {
        input.read_exact(&mut buf)?;
        let x = |i: usize| f64::from_le_bytes(buf[8 * i..8 * i + 8].try_into().expect("8 bytes"));
        points.push([x(0), x(1), x(2)]);
        weights.push(x(3));
    }
    Ok(SphereSet {
        points,
        weights,
        description: format!("read from {}", path.display()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_sets_are_deterministic_and_in_range() {
        let a = random_spheres(500, 7, RANDOM_RADIUS);
        assert_eq!(a, random_spheres(500, 7, RANDOM_RADIUS));
        assert_ne!(a.points, random_spheres(500, 8, RANDOM_RADIUS).points);
        let max_w = 0.25 * 500f64.powf(-2.0 / 3.0);
        assert!(a.points.iter().flatten().all(|x| (0.0..1.0).contains(x)));
        assert!(a.weights.iter().all(|w| (0.0..=max_w).contains(w)));
    }

    #[test]
    fn octree_covers_have_about_the_size_asked() {
        let set = octree_spheres(20_000);
        let n = set.len() as f64;
        assert!((n / 20_000.0 - 1.0).abs() < 0.1, "{n}");
        // Centres of cells of depth ≤ 12 lie on a dyadic grid: multiples of 2^-13.
        assert!(
            set.points
                .iter()
                .flatten()
                .all(|x| (x * 8192.0).fract() == 0.0)
        );
    }
}
