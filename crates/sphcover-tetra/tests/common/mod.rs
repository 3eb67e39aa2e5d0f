//! Shared helpers of the integration tests.
#![allow(dead_code)]

use sphcover_core::random::SplitMix64;

/// Uniform random points in the unit cube with weights in `[0, wmax)`.
pub fn random_points(n: usize, wmax: f64, seed: u64) -> (Vec<[f64; 3]>, Vec<f64>) {
    let mut rng = SplitMix64::new(seed);
    let mut u = move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let pts: Vec<[f64; 3]> = (0..n).map(|_| [u(), u(), u()]).collect();
    let w: Vec<f64> = (0..n).map(|_| u() * wmax).collect();
    (pts, w)
}

/// `n` random spheres in the unit cube, with radii around the typical spacing so that
/// tetrahedra both pass and fail the dual complex filter.
pub fn random_cover(n: usize, seed: u64) -> (Vec<sphcover_core::DVec3>, Vec<f64>) {
    let (p, w) = random_points(n, 1.0, seed);
    let c = p
        .iter()
        .map(|x| sphcover_core::DVec3::from_array(*x))
        .collect();
    let spacing = (1.0 / n as f64).cbrt();
    let r = w.iter().map(|x| spacing * (0.4 + 1.2 * x)).collect();
    (c, r)
}

/// Points of an `n³` integer grid (scaled by `h`), all weights `w`.
pub fn grid(n: usize, h: f64, w: f64) -> (Vec<[f64; 3]>, Vec<f64>) {
    let mut pts = Vec::new();
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                pts.push([i as f64 * h, j as f64 * h, k as f64 * h]);
            }
        }
    }
    let ws = vec![w; pts.len()];
    (pts, ws)
}

/// Reads a `x y z r` sphere file from `fixtures/tetra/`.
pub fn read_spheres(name: &str) -> (Vec<sphcover_core::DVec3>, Vec<f64>) {
    let path = format!("{}/../../fixtures/tetra/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut c = Vec::new();
    let mut r = Vec::new();
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect();
        c.push(sphcover_core::DVec3::new(v[0], v[1], v[2]));
        r.push(v[3]);
    }
    (c, r)
}

/// Reads a reference tetrahedron file (sorted rows of ascending indices).
pub fn read_tets(name: &str) -> Vec<[u32; 4]> {
    let path = format!("{}/../../fixtures/tetra/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<u32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3]]
        })
        .collect()
}

/// Tetrahedra with ascending vertices, rows sorted.
pub fn canonical(tets: &[[u32; 4]]) -> Vec<[u32; 4]> {
    let mut v: Vec<[u32; 4]> = tets
        .iter()
        .map(|t| {
            let mut s = *t;
            s.sort_unstable();
            s
        })
        .collect();
    v.sort_unstable();
    v
}

/// `V − E + F − T` of the complex made of `tets` and all their faces.
pub fn euler_of_tets(tets: &[[u32; 4]]) -> i64 {
    let mut verts = std::collections::BTreeSet::new();
    let mut edges = std::collections::BTreeSet::new();
    let mut faces = std::collections::BTreeSet::new();
    for t in canonical(tets) {
        for i in 0..4 {
            verts.insert(t[i]);
            for j in i + 1..4 {
                edges.insert((t[i], t[j]));
                for k in j + 1..4 {
                    faces.insert((t[i], t[j], t[k]));
                }
            }
        }
    }
    verts.len() as i64 - edges.len() as i64 + faces.len() as i64 - tets.len() as i64
}

/// Total unsigned volume of `tets` over `centres`.
pub fn total_volume(centres: &[sphcover_core::DVec3], tets: &[[u32; 4]]) -> f64 {
    tets.iter()
        .map(|t| {
            let [a, b, c, d] = t.map(|i| centres[i as usize]);
            ((b - a).cross(c - a).dot(d - a) / 6.0).abs()
        })
        .sum()
}
