//! Geometry of intersecting pairs of supports (thesis eq. 4.33–4.36), computed once per graph.
//!
//! The method is described on [`PairGeometry`].

use sphcover_core::{LengthMismatch, SphereIntersectionGraph};
use std::f64::consts::PI;

use glam::DVec3;
use rayon::prelude::*;

use crate::error::OpsError;

/// Rows handled by one parallel task: fixed, so that the split never depends on the pool.
pub(crate) const ROWS_PER_TASK: usize = 4096;

/// One parallel task of [`PairGeometry::build`]: its first row, its rows' entries of `φ`, and
/// its rows' per-support sums `[S, Σφ, thesis m, moment m]`.
type RowTask<'a> = (usize, &'a mut [f64], &'a mut [[f64; 4]]);

/// Geometry of one ordered pair `(i, j)` of supports.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PairTerms {
    /// `d = ‖c_j − c_i‖`.
    pub distance: f64,
    /// `l_i`: signed distance from `c_i` to the radical plane, towards `c_j`.
    pub plane_offset: f64,
    /// `ρ²`: squared radius of the intersection disk.
    pub disk_radius_sq: f64,
    /// `D_ij = π ρ²`.
    pub disk_area: f64,
    /// `A_ij = 2π r_i (r_i − l_i)`: area of the part of the sphere `∂s_i` inside `s_j`.
    pub cap_area: f64,
    /// `φ_ij = D_ij / d`.
    pub phi: f64,
}

impl PairTerms {
    /// The terms of the pair `(c_i, r_i)`, `(c_j, r_j)`; all zero when the spheres have no
    /// intersection circle (nested, coincident or disjoint balls).
    #[inline]
    pub fn new(c_i: DVec3, r_i: f64, c_j: DVec3, r_j: f64) -> PairTerms {
        let d = (c_j - c_i).length();
        let sum = r_i + r_j;
        let diff = r_i - r_j;
        if !(d > diff.abs() && d < sum) {
            return PairTerms {
                distance: d,
                ..PairTerms::default()
            };
        }
        let d2 = d * d;
        let disk_radius_sq = ((sum * sum - d2) * (d2 - diff * diff) / (4.0 * d2)).max(0.0);
        let cap_height = ((sum - d) * (d - diff) / (2.0 * d)).max(0.0);
        let disk_area = PI * disk_radius_sq;
        PairTerms {
            distance: d,
            plane_offset: r_i - cap_height,
            disk_radius_sq,
            disk_area,
            cap_area: 2.0 * PI * r_i * cap_height,
            phi: disk_area / d,
        }
    }
}

/// Which mass `m_i` normalises the operators `M⁻¹(…)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MassKind {
    /// The thesis mass `m_i = r_i S_i / 3` (eq. 4.19–4.21). Inconsistent: the Laplacian of
    /// `|x|²` comes out at about 3–5 instead of 6 on regular grids, whatever `h`.
    #[default]
    Thesis,
    /// The moment-matched mass `m_i = (1/6) Σ_j φ_ij ‖c_j − c_i‖²`, which makes the symmetric
    /// Laplacian exact on `|x|²` wherever the stencil is balanced (`Σ_j φ_ij (c_j − c_i) = 0`),
    /// as on regular grids.
    MomentMatched,
}

/// Pair geometry of a cover over its sphere intersection graph, stored in compressed sparse
/// rows aligned with [`SphereIntersectionGraph::neighbour_array`]: entry `k` of
/// [`PairGeometry::phi`] belongs to the pair `(i, neighbour_array()[k])` for the row `i` with
/// `offsets()[i] ≤ k < offsets()[i + 1]`.
///
/// It is also the symmetric weight matrix `W = [φ_ij]`, and applies the stiffness
/// `L_W = W − diag(W·1)` (symmetric, negative semi-definite) and the Laplacian
/// `Lap = M⁻¹ L_W` for either [`MassKind`].
///
/// For supports `i`, `j` with `d = ‖c_j − c_i‖` and `|r_i − r_j| < d < r_i + r_j`, the two
/// spheres meet in a circle lying in the radical plane:
///
/// ```text
/// l_i  = (d² + r_i² − r_j²) / (2d)    signed distance from c_i to the radical plane
/// ρ²   = r_i² − l_i²                  radius² of the intersection disk (symmetric)
/// D_ij = π ρ²                         intersection-disk area (symmetric)
/// A_ij = 2π r_i (r_i − l_i)           area of the cap of ∂s_i inside s_j
/// S_i  = Σ_j A_ij                     normaliser (eq. 4.19)
/// φ_ij = D_ij / d                     symmetric edge weight (eq. 4.20)
/// m_i  = r_i S_i / 3                  thesis mass: the ball's volume when the caps tile ∂s_i
/// ```
///
/// Pairs where one ball contains the other (`d ≤ |r_i − r_j|`, including `d = 0`), and pairs
/// whose balls do not meet (possible when the graph was built with a shrink factor above 1),
/// have no intersection circle and get `φ = 0`, `A = 0`. A support without any usable pair has
/// zero mass and, by convention, zero operators (never NaN).
///
/// ρ² and `r_i − l_i` are evaluated in factored forms,
/// `ρ² = ((r_i + r_j)² − d²)(d² − (r_i − r_j)²) / (4d²)` and
/// `r_i − l_i = (r_i + r_j − d)(r_j − r_i + d) / (2d)`, which avoid the cancellation of
/// `r_i² − l_i²` for nearly tangent or nearly nested balls, and make `φ_ij` and `φ_ji` the same
/// floating-point number: every operand of ρ² is symmetric in `i`, `j` bit for bit.
#[derive(Clone, Debug, PartialEq)]
pub struct PairGeometry {
    centres: Vec<DVec3>,
    radii: Vec<f64>,
    offsets: Vec<u32>,
    neighbours: Vec<u32>,
    phi: Vec<f64>,
    cap_sum: Vec<f64>,
    weight_sum: Vec<f64>,
    thesis_mass: Vec<f64>,
    moment_mass: Vec<f64>,
    usable_pairs: usize,
}

impl PairGeometry {
    /// Computes the pair geometry of the balls `(centres[i], radii[i])` over `graph`, in
    /// parallel; the result is identical for any thread count.
    ///
    /// Centres must be finite, radii finite and non-negative, the graph built on as many
    /// supports as there are centres.
    pub fn build(
        centres: &[DVec3],
        radii: &[f64],
        graph: &SphereIntersectionGraph,
    ) -> Result<PairGeometry, OpsError> {
        let n = centres.len();
        if radii.len() != n {
            return Err(OpsError::LengthMismatch(LengthMismatch {
                array: "radii",
                expected: n,
                found: radii.len(),
            }));
        }
        if graph.len() != n {
            return Err(OpsError::GraphMismatch {
                graph: graph.len(),
                supports: n,
            });
        }
        if let Some(index) = centres.iter().position(|c| !c.is_finite()) {
            return Err(OpsError::NonFiniteCentre {
                index,
                centre: centres[index],
            });
        }
        if let Some(index) = radii.iter().position(|r| !(r.is_finite() && *r >= 0.0)) {
            return Err(OpsError::InvalidRadius {
                index,
                radius: radii[index],
            });
        }
        let offsets = graph.offsets().to_vec();
        let neighbours = graph.neighbour_array().to_vec();
        if let Some(k) = neighbours.iter().position(|&j| j as usize >= n) {
            let row = offsets.partition_point(|&o| o as usize <= k) - 1;
            return Err(OpsError::InvalidGraph {
                row,
                neighbour: neighbours[k],
            });
        }

        let mut phi = vec![0.0; neighbours.len()];
        let mut per_support = vec![[0.0f64; 4]; n];
        // Split the entry array along row boundaries so that each task owns its rows' entries.
        let mut tasks: Vec<RowTask<'_>> = Vec::new();
        {
            let mut phi_rest: &mut [f64] = &mut phi;
            let mut rows_rest: &mut [[f64; 4]] = &mut per_support;
            let mut row = 0;
            while row < n {
                let end = (row + ROWS_PER_TASK).min(n);
                let entries = (offsets[end] - offsets[row]) as usize;
                let (phi_here, phi_next) = phi_rest.split_at_mut(entries);
                let (rows_here, rows_next) = rows_rest.split_at_mut(end - row);
                tasks.push((row, phi_here, rows_here));
                phi_rest = phi_next;
                rows_rest = rows_next;
                row = end;
            }
        }
        let usable_pairs: usize = tasks
            .into_par_iter()
            .map(|(first_row, phi_out, rows_out)| {
                let base = offsets[first_row] as usize;
                let mut usable = 0;
                for (local, sums) in rows_out.iter_mut().enumerate() {
                    let i = first_row + local;
                    let (ci, ri) = (centres[i], radii[i]);
                    let (mut s, mut w, mut moment) = (0.0, 0.0, 0.0);
                    for k in offsets[i] as usize..offsets[i + 1] as usize {
                        let j = neighbours[k] as usize;
                        let t = PairTerms::new(ci, ri, centres[j], radii[j]);
                        phi_out[k - base] = t.phi;
                        usable += usize::from(t.phi > 0.0);
                        s += t.cap_area;
                        w += t.phi;
                        moment += t.phi * t.distance * t.distance;
                    }
                    *sums = [s, w, ri * s / 3.0, moment / 6.0];
                }
                usable
            })
            .sum();

        Ok(PairGeometry {
            centres: centres.to_vec(),
            radii: radii.to_vec(),
            offsets,
            neighbours,
            phi,
            cap_sum: per_support.iter().map(|s| s[0]).collect(),
            weight_sum: per_support.iter().map(|s| s[1]).collect(),
            thesis_mass: per_support.iter().map(|s| s[2]).collect(),
            moment_mass: per_support.iter().map(|s| s[3]).collect(),
            usable_pairs,
        })
    }

    /// Number of supports: the rows of the graph the geometry was built over.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// True when there is no support.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Support centres.
    pub fn centres(&self) -> &[DVec3] {
        &self.centres
    }

    /// Support radii.
    pub fn radii(&self) -> &[f64] {
        &self.radii
    }

    /// Row offsets, as in the graph.
    pub fn offsets(&self) -> &[u32] {
        &self.offsets
    }

    /// All neighbour rows concatenated, as in the graph.
    pub fn neighbour_array(&self) -> &[u32] {
        &self.neighbours
    }

    /// Neighbours of support `i` (panics when out of range, like slice indexing).
    pub fn neighbours(&self, i: usize) -> &[u32] {
        &self.neighbours[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    /// `φ` of every directed entry, aligned with [`PairGeometry::neighbour_array`].
    pub fn phi(&self) -> &[f64] {
        &self.phi
    }

    /// `φ_ij` for the neighbours of `i`, aligned with [`PairGeometry::neighbours`].
    pub fn phi_row(&self, i: usize) -> &[f64] {
        &self.phi[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    /// The full terms (`l`, `ρ²`, `D`, `A`, `φ`) of directed entry `k`, recomputed from the
    /// centres and radii; `row` must be the row holding `k`.
    pub fn terms(&self, row: usize, k: usize) -> PairTerms {
        let j = self.neighbours[k] as usize;
        PairTerms::new(
            self.centres[row],
            self.radii[row],
            self.centres[j],
            self.radii[j],
        )
    }

    /// `S_i = Σ_j A_ij` per support (eq. 4.19).
    pub fn cap_sum(&self) -> &[f64] {
        &self.cap_sum
    }

    /// Row sums `Σ_j φ_ij` of `W`: the diagonal of `−L_W`.
    pub fn weight_sum(&self) -> &[f64] {
        &self.weight_sum
    }

    /// The mass `m_i` of the given kind; zero exactly for supports without usable pairs.
    pub fn mass(&self, kind: MassKind) -> &[f64] {
        match kind {
            MassKind::Thesis => &self.thesis_mass,
            MassKind::MomentMatched => &self.moment_mass,
        }
    }

    /// Number of directed entries with `φ > 0` (each usable pair counts twice).
    pub fn usable_entries(&self) -> usize {
        self.usable_pairs
    }

    /// Number of directed entries stored (the graph's, usable or not).
    pub fn stored_entries(&self) -> usize {
        self.neighbours.len()
    }

    /// `y = L_W x = (W − diag(W·1)) x`, i.e. `y_i = Σ_j φ_ij (x_j − x_i)`, in parallel over
    /// fixed row blocks; bit-identical for any thread count, and exactly zero for constant `x`.
    ///
    /// Panics when `x` or `y` is not of length [`PairGeometry::len`].
    pub fn apply_stiffness(&self, x: &[f64], y: &mut [f64]) {
        assert_eq!(x.len(), self.len(), "x has the wrong length");
        assert_eq!(y.len(), self.len(), "y has the wrong length");
        y.par_chunks_mut(ROWS_PER_TASK)
            .enumerate()
            .for_each(|(block, out)| {
                let first = block * ROWS_PER_TASK;
                for (local, yi) in out.iter_mut().enumerate() {
                    *yi = self.stiffness_row(first + local, x);
                }
            });
    }

    /// `Σ_j φ_ij (x_j − x_i)` for one row, with four independent partial sums in a fixed order
    /// so that the latency of the additions does not bound the loop.
    #[inline]
    pub(crate) fn stiffness_row(&self, i: usize, x: &[f64]) -> f64 {
        let start = self.offsets[i] as usize;
        let end = self.offsets[i + 1] as usize;
        let phi = &self.phi[start..end];
        let nb = &self.neighbours[start..end];
        let xi = x[i];
        let mut acc = [0.0f64; 4];
        let mut chunks_phi = phi.chunks_exact(4);
        let mut chunks_nb = nb.chunks_exact(4);
        for (p, j) in (&mut chunks_phi).zip(&mut chunks_nb) {
            for l in 0..4 {
                acc[l] += p[l] * (x[j[l] as usize] - xi);
            }
        }
        for (p, j) in chunks_phi.remainder().iter().zip(chunks_nb.remainder()) {
            acc[0] += p * (x[*j as usize] - xi);
        }
        (acc[0] + acc[1]) + (acc[2] + acc[3])
    }

    /// `y = M⁻¹ L_W x` (the thesis Laplacian for [`MassKind::Thesis`]); rows of zero mass give
    /// zero. Same determinism as [`PairGeometry::apply_stiffness`].
    pub fn apply_laplacian(&self, mass: MassKind, x: &[f64], y: &mut [f64]) {
        self.apply_stiffness(x, y);
        let m = self.mass(mass);
        y.par_iter_mut()
            .zip(m.par_iter())
            .for_each(|(yi, &mi)| *yi = if mi > 0.0 { *yi / mi } else { 0.0 });
    }
}
