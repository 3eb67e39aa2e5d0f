//! Diffusion of local functions (thesis §5.2.3): smooth the linear functions of a surface
//! cover over its sphere intersection graph while keeping them fitted to the samples.
//!
//! The method is described on [`diffuse()`].

use rayon::prelude::*;
use sphcover_core::{
    Cover, CoverError, DVec3, Face, FaceSelection, LengthMismatch, LocalFunctions, ParameterError,
    PointIndex, SupportLists, SupportSamples, face_to_fit,
};
use sphcover_ops::{CgError, CgParams, CgScratch, PairGeometry, SymmetricOperator};
use std::time::{Duration, Instant};
use thiserror::Error;

use crate::angle::angle_between;

/// How the Poisson step of each round is solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoissonStep {
    /// One Jacobi sweep per round, as the thesis does.
    ThesisJacobi,
    /// Conjugate gradients to the tolerance of [`DiffusionParams::cg`] (beyond the thesis).
    Converged,
}

/// How the fitting weights are scaled against the smoothing (see [`diffuse`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FittingScale {
    /// `t_i = μ W_i / W̄`: dimensionless, the same at every support size and sampling density.
    Relative,
    /// The thesis form `t_i = λ W_i / a_i²`, with λ in the units of the unit frame.
    Thesis,
}

/// Parameters of [`diffuse`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffusionParams {
    /// Rounds of gradient smoothing and Poisson update (thesis: 5).
    pub rounds: usize,
    /// Fitting strength of the normals (`μ_n` or `λ_n`, by [`DiffusionParams::scale`]); 0
    /// ignores the samples' normals (thesis Fig. 5.32, for very noisy normals).
    pub normal_fit: f64,
    /// Exponent `q` of the normal-coherence gate: the normal fitting strength used is
    /// `normal_fit · ĉ^q`, with `ĉ` the median over the fitted supports of `‖N_i‖ / W_i`
    /// (1 when the samples' normals in a support agree, less when they scatter; see [`diffuse`]).
    /// 0 uses `normal_fit` as given.
    pub normal_coherence_exponent: f64,
    /// The gate never takes the normal strength below `min(normal_fit, normal_fit_floor)`:
    /// a fifth of the normals flipped (coherence 0.57) still needs some normal fit (module
    /// docs).
    pub normal_fit_floor: f64,
    /// Fitting strength of the positions (`μ_p` or `λ_p`).
    pub position_fit: f64,
    /// Exponent `p` of the confidence gate of [`FittingScale::Relative`]: both strengths of
    /// support `i` are multiplied by `(W_i / K_i)^p`, the mean confidence of its samples
    /// (see [`diffuse`]). 0 leaves them as they are.
    pub confidence_power: f64,
    /// Interpretation of the two strengths.
    pub scale: FittingScale,
    /// Use the anisotropic weights `ψ_ij` (else `ψ = 1`).
    pub anisotropic: bool,
    /// The layer gate `h` (beyond the thesis): with `Some(h)`, every edge weight is also
    /// multiplied by `1 / (1 + (d_ij / h)⁴)`, `d_ij` the farther of the two supports' planes
    /// from the other's (see [`diffuse`]), so supports on two layers of surface a depth jump
    /// apart are not smoothed into one. `None` couples every edge; the reconstruction then
    /// sets `h` for a scan of one view ([`crate::ONE_VIEW_LAYER_GAP`]).
    pub layer_gap: Option<f64>,
    /// The Poisson step.
    pub poisson: PoissonStep,
    /// Conjugate-gradient settings of [`PoissonStep::Converged`].
    pub cg: CgParams,
}

impl Default for DiffusionParams {
    /// Two rounds (the thesis has 5; with the strong fit and the vertex refinement of the
    /// pipeline, 1, 2 and 3 rounds give the same scores on every case of the 100K-bunny
    /// benchmark within 0.0004% of the diagonal, and each round is a full Poisson solve
    /// (`docs/benchmarks.md`, *Stages at 362K*); one round leaves the 2K-point noisy sphere in
    /// 3 pieces without the graph cut, and a sphere with a fifth of its normals flipped 0.064
    /// radii off), relative fitting μ_n = 64 gated by the normal coherence with exponent 32
    /// down to 1, μ_p = 8, both gated by the mean confidence (power 1), anisotropic, converged
    /// Poisson step to a relative residual of 1e-6 ([`diffuse`]: how these were chosen).
    fn default() -> Self {
        DiffusionParams {
            rounds: 2,
            normal_fit: 64.0,
            normal_coherence_exponent: 32.0,
            normal_fit_floor: 1.0,
            position_fit: 8.0,
            confidence_power: 1.0,
            scale: FittingScale::Relative,
            anisotropic: true,
            layer_gap: None,
            poisson: PoissonStep::Converged,
            cg: CgParams {
                relative_tolerance: 1e-6,
                max_iterations: 2_000,
                ..CgParams::default()
            },
        }
    }
}

/// Errors of the diffusion.
#[derive(Debug, Error)]
pub enum DiffusionError {
    /// The cover does not hold linear local functions.
    #[error("diffusion needs a cover of linear local functions")]
    NotLinear,
    /// Arrays of different lengths.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
    /// A parameter is out of range.
    #[error(transparent)]
    InvalidParameter(#[from] ParameterError),
    /// The cover could not be evaluated or updated.
    #[error(transparent)]
    Cover(#[from] CoverError),
    /// The Poisson solve failed.
    #[error("Poisson step of diffusion round {round}: {source}")]
    Poisson {
        /// The round (from 0).
        round: usize,
        /// The solver's error.
        source: CgError,
    },
}

/// Per-support sums over the samples in the support (see [`diffuse`]), gathered once.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FittingTerms {
    /// `W_i = Σ_k σ_k w_i(p_k)`.
    pub weight: Vec<f64>,
    /// `N_i = Σ_k σ_k w_i(p_k) ñ_k`, with `ñ_k = −n_k / ‖n_k‖` (the convention of `α`).
    pub normal_sum: Vec<DVec3>,
    /// `P_i = Σ_k σ_k w_i(p_k) (p_k − c_i)`.
    pub offset_sum: Vec<DVec3>,
    /// `K_i = Σ_k w_i(p_k)`: the kernel weight without the confidences, so that `W_i / K_i`
    /// is the mean confidence of the support's samples.
    pub kernel_sum: Vec<f64>,
}

impl FittingTerms {
    /// Gathers the sums of every support of the incidences' cover over its samples `points`
    /// (with outward `normals` and a `confidence` σ_k each; `incidence` was gathered from a
    /// point index over exactly `points`), in parallel. Samples with a zero or
    /// non-finite normal contribute to `W` and `P` but not to `N`. A support that holds two
    /// opposite faces of a thin part sums over the face of its nearest sample only (as the
    /// cover's fit does; see [`sphcover_core::may_hold_opposite_faces`]), else the fitting
    /// terms pull its plane between the faces; `faces` says which samples make a face.
    pub fn gather(
        cover: &Cover,
        index: &PointIndex,
        incidence: &SupportSamples,
        points: &[DVec3],
        normals: &[DVec3],
        confidence: &[f64],
        faces: FaceSelection,
    ) -> Result<FittingTerms, DiffusionError> {
        for (array, found) in [("normals", normals.len()), ("confidence", confidence.len())] {
            if found != points.len() {
                return Err(DiffusionError::LengthMismatch(LengthMismatch {
                    array,
                    expected: points.len(),
                    found,
                }));
            }
        }
        if index.input_len() != points.len() || !incidence.fits(cover, index) {
            return Err(DiffusionError::LengthMismatch(LengthMismatch {
                array: "point index",
                expected: points.len(),
                found: index.input_len(),
            }));
        }
        let kernel = cover.kernel();
        // The samples' normals and confidences in the index's slot order, so the per-support
        // loops read them as contiguously as the positions instead of at random (the input
        // order of a scan can be anything). Only where the values are read from changes: the
        // sums still run over each support's slots in tree order.
        let slot_points = index.slot_points();
        let (slot_normals, slot_confidence): (Vec<DVec3>, Vec<f64>) = index
            .order()
            .par_iter()
            .map(|&k| (normals[k as usize], confidence[k as usize]))
            .unzip();
        let sums: Vec<FittingSums> = cover
            .centres()
            .par_iter()
            .zip(cover.radii().par_iter())
            .enumerate()
            .map(|(i, (&c, &r))| {
                // The sums over the samples of `face`, or over all.
                let sums = |face: Option<Face>| {
                    let mut sum = FittingSums::default();
                    incidence.for_each_slot_within(cover, index, i, |s, _| {
                        let n = slot_normals[s];
                        if face.is_none_or(|face| face.holds(n)) {
                            let p = slot_points[s];
                            sum.add(p - c, n, kernel.weight(p, c, r), slot_confidence[s]);
                        }
                    });
                    sum
                };
                let all = sums(None);
                let face = face_to_fit(all.weight, -all.normal, faces, |visit| {
                    incidence.for_each_slot_within(cover, index, i, |s, d2| {
                        let w = kernel.weight(slot_points[s], c, r) * slot_confidence[s];
                        visit(slot_normals[s], d2, w);
                    });
                });
                match face {
                    Some(face) => sums(Some(face)),
                    None => all,
                }
            })
            .collect();
        Ok(FittingTerms {
            weight: sums.iter().map(|s| s.weight).collect(),
            normal_sum: sums.iter().map(|s| s.normal).collect(),
            offset_sum: sums.iter().map(|s| s.offset).collect(),
            kernel_sum: sums.iter().map(|s| s.kernel).collect(),
        })
    }

    fn len(&self) -> usize {
        self.weight.len()
    }

    /// `W_i / K_i`, the kernel-weighted mean confidence of support `i`'s samples (0 without
    /// samples).
    fn mean_confidence(&self, i: usize) -> f64 {
        let k = self.kernel_sum[i];
        if k > 0.0 {
            (self.weight[i] / k).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// Median over the supports with `W_i > 0` of `‖N_i‖ / W_i`: the mean resultant length
    /// of the samples' unit normals, weighted as the fit weighs them (0 when there is none).
    pub fn median_normal_coherence(&self) -> f64 {
        let mut coherence: Vec<f64> = self
            .weight
            .iter()
            .zip(&self.normal_sum)
            .filter(|(w, _)| **w > 0.0)
            .map(|(w, n)| (n.length() / w).min(1.0))
            .filter(|c| c.is_finite())
            .collect();
        if coherence.is_empty() {
            return 0.0;
        }
        let mid = coherence.len() / 2;
        let (_, median, _) = coherence.select_nth_unstable_by(mid, f64::total_cmp);
        *median
    }
}

/// One support's terms of [`FittingTerms`] while they are summed.
#[derive(Clone, Copy, Default)]
struct FittingSums {
    weight: f64,
    normal: DVec3,
    offset: DVec3,
    kernel: f64,
}

impl FittingSums {
    /// Adds a sample at `offset` from the centre with outward `normal`, kernel weight
    /// `kernel_weight` and `confidence`.
    fn add(&mut self, offset: DVec3, normal: DVec3, kernel_weight: f64, confidence: f64) {
        self.kernel += kernel_weight;
        let w = confidence * kernel_weight;
        if w > 0.0 {
            self.weight += w;
            let len = normal.length();
            if len > 0.0 && len.is_finite() {
                self.normal -= (w / len) * normal;
            }
            self.offset += w * offset;
        }
    }
}

/// What [`diffuse`] did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DiffusionStats {
    /// Rounds run.
    pub rounds: usize,
    /// Conjugate-gradient iterations per round ([`PoissonStep::Converged`]).
    pub cg_iterations: Vec<usize>,
    /// Relative residual of the last Poisson solve.
    pub final_residual: f64,
    /// Supports that hold samples (`W_i > 0`).
    pub fitted_supports: usize,
    /// Median over the fitted supports of the normal coherence `‖N_i‖ / W_i` (0 when no
    /// support holds a sample with a normal).
    pub normal_coherence: f64,
    /// The normal fitting strength used (after the coherence gate).
    pub normal_fit: f64,
    /// Wall time.
    pub time: Duration,
}

/// Diffuses the linear local functions of `cover` (thesis §5.2.3; method below). `pairs` is
/// the pair geometry of the cover over its sphere intersection graph, `terms` the samples'
/// sums and `at_centres` the support lists gathered at its centres
/// ([`sphcover_core::PuEvaluator::support_lists`]: the balls do not change, so every round
/// evaluates its gradients over them); the cover's functions are replaced.
///
/// Each round:
///
/// 1. `v_i = ∇f(c_i)`, the analytic gradient of the partition-of-unity function.
/// 2. Gradients are smoothed with the anisotropic weights `ψ_ij = 1 / (1 + θ_ij²)` (θ the
///    angle between `v_i` and `v_j`, eq. 5.24) and pulled towards the samples' normals
///    (eq. 5.25–5.32):
///    `v̂_i = (S_i + t_i n̄_i) / (1 + t_i)` with `S_i = Σ_j φ_ij ψ_ij v_j / Σ_j φ_ij ψ_ij`
///    and `n̄_i` the confidence- and kernel-weighted mean of the samples' normals in the
///    convention of `α` (pointing inwards). This is the thesis update
///    `(a·(1/m_i)Σ φψ v_j + λ_n Σ σ w ñ) / (a² + λ_n Σ σ w)` divided through by `a²`, with
///    `a = (1/m_i) Σ φψ` and `t_i = λ_n W_i / a²`, `W_i = Σ_k σ_k w_i(p_k)`.
/// 3. The constants solve the Poisson equation `Lap f(c_i) = Div v̂` with the fitting term
///    `Σ_k σ_k w_i(p_k) (β_i + v̂_i·(p_k − c_i))² → min` (eq. 5.23, 5.33–5.38). The thesis does
///    one Jacobi sweep per round ([`PoissonStep::ThesisJacobi`]):
///    `β_i = (Σ_j φψ (β_j + v̂_j·(c_i − c_j)) / Σ_j φψ + t'_i b_i) / (1 + t'_i)` with
///    `b_i = −v̂_i·P_i / W_i`, `P_i = Σ_k σ_k w_i(p_k)(p_k − c_i)`. Solved to convergence
///    ([`PoissonStep::Converged`], the default) it is the symmetric positive-definite system
///    `Σ_j φψ_ij (β_i − β_j − e_ij) + t'_i (Σ_j φψ_ij)(β_i − b_i) = 0` with the central flux
///    `e_ij = ½(v̂_i + v̂_j)·(c_i − c_j)`, solved by preconditioned conjugate gradients.
///
/// **Fitting strength.** In the thesis form `t_i = λ W_i / a_i²` depends on the support
/// size through `a_i ∝ r_i⁻²`, so one `λ` gives supports of different sizes fitting weights
/// spread over orders of magnitude (the thesis sets λ "sufficiently large" for a unit box).
/// [`FittingScale::Relative`] (the default) makes the weight dimensionless,
/// `t_i = μ W_i / W̄` with `W̄` the mean of `W` over the supports holding samples, so the
/// same `μ` means the same balance of smoothing and fitting at every scale and density.
/// [`FittingScale::Thesis`] keeps the thesis form for fidelity.
///
/// **Gates (beyond the thesis).** Smoothing the gradients over the graph averages each
/// support with neighbours a support radius away, a fixed length that does not shrink with
/// the sampling: on a clean scan it only costs accuracy (the 100K-point bunny: Chamfer 0.0113%
/// of the diagonal with μ_n = 1, μ_p = 4, against 0.0064% for the undiffused function). So the
/// fit is strong by default and two measurements of the scan weaken it where the samples are
/// not to be trusted:
///
/// - *Normal coherence*: `ĉ`, the median over the fitted supports of `‖N_i‖ / W_i` (the mean
///   resultant length of the samples' normals), is 0.995 for exact normals on the bunny,
///   0.954 for normals rotated by up to 30° and 0.843 for up to 60°. The normal strength used
///   is `max(μ_n ĉ^q, 1)` (q = 32: ×0.85, ×0.22, ×0.004), so noisy normals are smoothed
///   and the positions carry the shape, but never less than 1. The floor keeps some normal
///   fit where the normals are wrong but unbiased: with a fifth of a 600-point sphere's
///   normals flipped (ĉ = 0.57) the largest vertex error (depth 6) is 8.5% of the radius
///   with no floor, 6.6%, 6.1% and 5.8% with floors 0.5, 0.75 and 1; on the 100K bunny
///   with normals rotated by up to 60°, normal strengths 0.27 (no floor), 0.5, 0.75 and 1
///   give Chamfer 0.0106, 0.0108, 0.0113, 0.0117 and Hausdorff-99 0.0477,
///   0.0458, 0.0449, 0.0454 (% of the diagonal).
/// - *Mean confidence*: both strengths of support `i` are multiplied by `W_i / K_i`, the mean
///   confidence of its samples. Surface supports score about 0.65, supports around the
///   outliers that the graph cut and the isolation test miss about 0.16. Without this gate
///   a position strength μ_p = 16 already lets 5% uniform outliers of the 100K bunny form
///   floating sheets; with it 64 does not. μ_p stays at 8 because the 2K-point noisy sphere
///   with 2% outliers (none isolated at that density) splits into 3 components from μ_p = 12
///   on without the graph cut.
///
/// **Layer gate (beyond the thesis).** Both smoothings average a support with every
/// neighbour its ball meets, and the angle gate `ψ` does not part two parallel layers of
/// surface: a plate floating before a wall, seen from the front by one view, has supports on
/// the plate and on the wall whose balls meet across the gap, with the same gradient. Their
/// average puts the zero set between the layers, and the wall beside the plates was lost (the
/// single-view `plates` scene: 10.7% of the samples farther than two nearest-neighbour
/// distances from the output). With [`DiffusionParams::layer_gap`] `h`, the edge `ij` is
/// weighted by `1 / (1 + (d_ij / h)⁴)` as well, `d_ij` the larger of the distances from each
/// support's initial zero plane to the foot of the other's centre on its own plane: about the
/// gap between two layers, and a few ε between neighbours on one smooth surface (each plane
/// fits its samples within ε inside its ball).
///
/// The per-support sample sums `W_i`, `N_i = Σ σ w ñ`, `P_i` do not change between rounds,
/// so they are gathered once ([`FittingTerms::gather`]). Every sum runs over a fixed order
/// (graph rows, tree order of the point index), so the result does not depend on the number
/// of threads.
pub fn diffuse(
    cover: &mut Cover,
    pairs: &PairGeometry,
    terms: &FittingTerms,
    at_centres: &SupportLists,
    params: &DiffusionParams,
) -> Result<DiffusionStats, DiffusionError> {
    let start = Instant::now();
    let n = cover.len();
    for (array, found) in [
        ("pair geometry", pairs.len()),
        ("fitting terms", terms.len()),
    ] {
        if found != n {
            return Err(DiffusionError::LengthMismatch(LengthMismatch {
                array,
                expected: n,
                found,
            }));
        }
    }
    for (name, value) in [
        ("normal_fit", params.normal_fit),
        (
            "normal_coherence_exponent",
            params.normal_coherence_exponent,
        ),
        ("normal_fit_floor", params.normal_fit_floor),
        ("position_fit", params.position_fit),
        ("confidence_power", params.confidence_power),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(DiffusionError::InvalidParameter(ParameterError::new(
                name,
                value,
                "a finite, non-negative number",
            )));
        }
    }
    let LocalFunctions::Linear { alpha, beta } = cover.funcs().clone() else {
        return Err(DiffusionError::NotLinear);
    };
    let (mut alpha, mut beta) = (alpha, beta);
    let mut stats = DiffusionStats {
        fitted_supports: terms.weight.iter().filter(|&&w| w > 0.0).count(),
        ..DiffusionStats::default()
    };
    let mean_weight = {
        let total: f64 = terms.weight.iter().sum();
        if stats.fitted_supports > 0 {
            total / stats.fitted_supports as f64
        } else {
            1.0
        }
    };
    stats.normal_coherence = terms.median_normal_coherence();
    let normal_fit = if params.normal_coherence_exponent > 0.0 {
        let gated = params.normal_fit
            * stats
                .normal_coherence
                .powf(params.normal_coherence_exponent);
        gated.max(params.normal_fit.min(params.normal_fit_floor))
    } else {
        params.normal_fit
    };
    stats.normal_fit = normal_fit;
    let mut scratch = CgScratch::new();
    let mut weights = vec![0.0; pairs.stored_entries()];
    let layer_gates = params
        .layer_gap
        .map(|h| layer_gates(pairs, cover.centres(), &alpha, &beta, h));
    for round in 0..params.rounds {
        // 1. Gradients of the current function at the centres.
        let gradients: Vec<DVec3> = at_centres
            .values_gradients(cover, cover.centres())?
            .into_iter()
            .zip(&alpha)
            .map(|(vg, &a)| vg.map_or(a, |vg| vg.gradient))
            .collect();

        // 2. Edge weights φψ, smoothed and fitted gradients.
        edge_weights(pairs, &gradients, params.anisotropic, &mut weights);
        if let Some(gates) = &layer_gates {
            weights.par_iter_mut().zip(gates).for_each(|(w, g)| *w *= g);
        }
        // A pair without a positive weight (coincident centres give φ no value) counts as
        // absent: 0, which the row sums add without a branch per entry.
        weights.par_iter_mut().for_each(|w| {
            if w.is_nan() || *w <= 0.0 {
                *w = 0.0;
            }
        });
        let fit = |i: usize, strength: f64, weight_sum: f64| -> f64 {
            let w = terms.weight[i];
            if w <= 0.0 || strength == 0.0 {
                return 0.0;
            }
            match params.scale {
                FittingScale::Relative => {
                    strength * w / mean_weight
                        * terms.mean_confidence(i).powf(params.confidence_power)
                }
                FittingScale::Thesis => {
                    let m = pairs.mass(sphcover_ops::MassKind::Thesis)[i];
                    let a = if m > 0.0 { weight_sum / m } else { 0.0 };
                    if a > 0.0 {
                        strength * w / (a * a)
                    } else {
                        f64::INFINITY
                    }
                }
            }
        };
        let smoothed: Vec<DVec3> = (0..n)
            .into_par_iter()
            .map(|i| {
                let (sum, total) = row_sum(pairs, &weights, i, |j| gradients[j]);
                let t = fit(i, normal_fit, total);
                let target = terms.normal_sum[i] / terms.weight[i].max(f64::MIN_POSITIVE);
                blend(total, sum, t, target, gradients[i])
            })
            .collect();
        alpha.clone_from(&smoothed);

        // 3. Constants.
        let centres = cover.centres();
        let data_target = |i: usize| {
            let w = terms.weight[i];
            if w > 0.0 {
                -smoothed[i].dot(terms.offset_sum[i]) / w
            } else {
                0.0
            }
        };
        match params.poisson {
            PoissonStep::ThesisJacobi => {
                beta = (0..n)
                    .into_par_iter()
                    .map(|i| {
                        let (sum, total) = row_sum(pairs, &weights, i, |j| {
                            beta[j] + smoothed[j].dot(centres[i] - centres[j])
                        });
                        let t = fit(i, params.position_fit, total);
                        blend(total, sum, t, data_target(i), beta[i])
                    })
                    .collect();
            }
            PoissonStep::Converged => {
                let system = ScreenedStiffness::new(pairs, &weights, |i, total| {
                    // A tiny screening towards the current value keeps components without
                    // samples (and isolated supports) well posed.
                    let t = fit(i, params.position_fit, total);
                    if t.is_finite() {
                        t * total + 1e-9 * total.max(1.0)
                    } else {
                        1.0
                    }
                });
                let rhs: Vec<f64> = (0..n)
                    .into_par_iter()
                    .map(|i| {
                        let (flux, total) = row_sum(pairs, &weights, i, |j| {
                            0.5 * (smoothed[i] + smoothed[j]).dot(centres[i] - centres[j])
                        });
                        let t = fit(i, params.position_fit, total);
                        let screen = system.screening[i];
                        if t.is_finite() {
                            flux + t * total * data_target(i) + (screen - t * total) * beta[i]
                        } else {
                            data_target(i)
                        }
                    })
                    .collect();
                let info = sphcover_ops::conjugate_gradient(
                    &system,
                    &rhs,
                    &mut beta,
                    &params.cg,
                    &mut scratch,
                )
                .map_err(|source| DiffusionError::Poisson { round, source })?;
                stats.cg_iterations.push(info.iterations);
                stats.final_residual = info.relative_residual;
            }
        }
        cover.set_funcs(LocalFunctions::Linear {
            alpha: alpha.clone(),
            beta: beta.clone(),
        })?;
        stats.rounds += 1;
    }
    stats.time = start.elapsed();
    Ok(stats)
}

/// `φ_ij ψ_ij` for every stored entry, `ψ_ij = 1 / (1 + θ_ij²)`.
fn edge_weights(pairs: &PairGeometry, gradients: &[DVec3], anisotropic: bool, out: &mut [f64]) {
    crate::csr::fill_entries(pairs.offsets(), out, |row, k| {
        let phi = pairs.phi()[k];
        if anisotropic {
            let theta = angle_between(
                gradients[row],
                gradients[pairs.neighbour_array()[k] as usize],
            );
            phi / (1.0 + theta * theta)
        } else {
            phi
        }
    });
}

/// The layer gate `1 / (1 + (d_ij / h)⁴)` of every stored entry (see [`diffuse`]), from the
/// linear functions `α·(x − c) + β` the supports start with.
fn layer_gates(
    pairs: &PairGeometry,
    centres: &[DVec3],
    alpha: &[DVec3],
    beta: &[f64],
    h: f64,
) -> Vec<f64> {
    // The foot of each centre on its support's zero plane (the centre itself without one).
    let feet: Vec<DVec3> = (0..centres.len())
        .map(|i| {
            let a2 = alpha[i].length_squared();
            if a2 > 0.0 {
                centres[i] - beta[i] / a2 * alpha[i]
            } else {
                centres[i]
            }
        })
        .collect();
    let from_plane = |i: usize, p: DVec3| {
        let a = alpha[i].length();
        if a > 0.0 {
            (beta[i] + alpha[i].dot(p - centres[i])).abs() / a
        } else {
            0.0
        }
    };
    let mut gates = vec![0.0; pairs.stored_entries()];
    crate::csr::fill_entries(pairs.offsets(), &mut gates, |i, k| {
        let j = pairs.neighbour_array()[k] as usize;
        let d = from_plane(i, feet[j]).max(from_plane(j, feet[i])) / h;
        1.0 / (1.0 + (d * d) * (d * d))
    });
    gates
}

/// `(Σ_j w_ij value(j), Σ_j w_ij)` over row `i`, in row order. The weights are 0 or
/// positive, and a 0 with a finite value adds nothing to either sum (its term is `±0`, and
/// sums that start at `+0` never become `−0`), so every entry is added: the same bits as
/// skipping the zeros, without a branch per entry.
fn row_sum<T>(
    pairs: &PairGeometry,
    weights: &[f64],
    i: usize,
    value: impl Fn(usize) -> T,
) -> (T, f64)
where
    T: std::ops::Mul<f64, Output = T> + std::ops::Add<Output = T> + Default,
{
    let range = pairs.offsets()[i] as usize..pairs.offsets()[i + 1] as usize;
    let mut sum = T::default();
    let mut total = 0.0;
    // The row's weights and neighbours as slices of one length: no bound check per entry.
    let neighbours = &pairs.neighbour_array()[range.clone()];
    for (&w, &j) in weights[range].iter().zip(neighbours) {
        sum = sum + value(j as usize) * w;
        total += w;
    }
    (sum, total)
}

/// `(sum/total + t·target) / (1 + t)`, the fitted mean; the target alone when `t` is
/// infinite, `keep` when there is neither neighbour nor data.
fn blend<T>(total: f64, sum: T, t: f64, target: T, keep: T) -> T
where
    T: std::ops::Mul<f64, Output = T> + std::ops::Add<Output = T> + Copy,
{
    if t.is_infinite() {
        return target;
    }
    if total > 0.0 {
        (sum * (1.0 / total) + target * t) * (1.0 / (1.0 + t))
    } else if t > 0.0 {
        target
    } else {
        keep
    }
}

/// `A = diag(s) − L_ψ`, i.e. `(A x)_i = s_i x_i + Σ_j w_ij (x_i − x_j)`: symmetric positive
/// definite when every screening `s_i > 0`.
struct ScreenedStiffness<'a> {
    pairs: &'a PairGeometry,
    weights: &'a [f64],
    screening: Vec<f64>,
    degree: Vec<f64>,
}

impl<'a> ScreenedStiffness<'a> {
    fn new(
        pairs: &'a PairGeometry,
        weights: &'a [f64],
        screening: impl Fn(usize, f64) -> f64 + Sync,
    ) -> ScreenedStiffness<'a> {
        let degree: Vec<f64> = (0..pairs.len())
            .into_par_iter()
            .map(|i| row_sum(pairs, weights, i, |_| 0.0).1)
            .collect();
        let screening = degree
            .par_iter()
            .enumerate()
            .map(|(i, &d)| screening(i, d))
            .collect();
        ScreenedStiffness {
            pairs,
            weights,
            screening,
            degree,
        }
    }
}

impl SymmetricOperator for ScreenedStiffness<'_> {
    fn dim(&self) -> usize {
        self.pairs.len()
    }

    fn apply(&self, x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(1024).enumerate().for_each(|(block, out)| {
            for (local, yi) in out.iter_mut().enumerate() {
                let i = block * 1024 + local;
                let (neigh, _) = row_sum(self.pairs, self.weights, i, |j| x[j]);
                *yi = (self.screening[i] + self.degree[i]) * x[i] - neigh;
            }
        });
    }

    fn diagonal(&self, diag: &mut [f64]) {
        for (i, d) in diag.iter_mut().enumerate() {
            *d = self.screening[i] + self.degree[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sphcover_core::SphereIntersectionGraph;

    proptest::proptest! {
        /// The layer gate is symmetric and in (0, 1]: 1 between supports whose planes are
        /// one plane, `1 / (1 + (g / h)⁴)` between supports on two parallel planes `g` apart,
        /// whatever the supports' centres, radii and gradient lengths.
        #[test]
        fn the_layer_gate_parts_two_planes_and_keeps_one(
            // x, y, the centre's offset from its layer, radius, gradient length, upper layer.
            supports in proptest::collection::vec(
                (
                    0.0f64..1.0,
                    0.0f64..1.0,
                    -0.05f64..0.05,
                    0.2f64..0.4,
                    0.5f64..4.0,
                    proptest::bool::ANY,
                ),
                2..40,
            ),
            gap in 0.01f64..0.2,
            h in 0.005f64..0.1,
        ) {
            let layer = |upper: bool| if upper { gap } else { 0.0 };
            let centres: Vec<DVec3> = supports
                .iter()
                .map(|&(x, y, dz, _, _, upper)| DVec3::new(x, y, layer(upper) + dz))
                .collect();
            let radii: Vec<f64> = supports.iter().map(|s| s.3).collect();
            // Each support's zero plane is its layer: α·(x − c) + β = 0 at z = layer.
            let alpha: Vec<DVec3> = supports.iter().map(|s| DVec3::new(0.0, 0.0, s.4)).collect();
            let beta: Vec<f64> = supports
                .iter()
                .zip(&centres)
                .map(|(s, c)| -s.4 * (layer(s.5) - c.z))
                .collect();
            let graph = SphereIntersectionGraph::build(&centres, &radii, 1.0).unwrap();
            let pairs = PairGeometry::build(&centres, &radii, &graph).unwrap();
            let gates = layer_gates(&pairs, &centres, &alpha, &beta, h);
            let apart = 1.0 / (1.0 + (gap / h).powi(4));
            let offsets = pairs.offsets();
            for i in 0..centres.len() {
                for k in offsets[i] as usize..offsets[i + 1] as usize {
                    let j = pairs.neighbour_array()[k] as usize;
                    let g = gates[k];
                    proptest::prop_assert!(g > 0.0 && g <= 1.0);
                    let expected = if supports[i].5 == supports[j].5 { 1.0 } else { apart };
                    proptest::prop_assert!((g - expected).abs() <= 1e-9, "{} vs {}", g, expected);
                    let back = (offsets[j] as usize..offsets[j + 1] as usize)
                        .find(|&m| pairs.neighbour_array()[m] as usize == i);
                    if let Some(m) = back {
                        proptest::prop_assert_eq!(gates[m], g);
                    }
                }
            }
        }

        /// A row sum over every entry, the zero weights included, has the bits of the sum
        /// over the positive weights alone, for scalar and vector values.
        #[test]
        fn zero_weights_add_nothing_to_a_row_sum(
            points in proptest::collection::vec(
                (0.0f64..1.0, 0.0f64..1.0, 0.0f64..1.0, -5.0f64..5.0, proptest::bool::ANY),
                2..30,
            ),
        ) {
            let centres: Vec<DVec3> = points.iter().map(|p| DVec3::new(p.0, p.1, p.2)).collect();
            let radii = vec![0.4; centres.len()];
            let graph = SphereIntersectionGraph::build(&centres, &radii, 1.0).unwrap();
            let pairs = PairGeometry::build(&centres, &radii, &graph).unwrap();
            // Entries to a support marked `false` weigh 0, the others their φ.
            let weights: Vec<f64> = pairs
                .neighbour_array()
                .iter()
                .zip(pairs.phi())
                .map(|(&j, &phi)| if points[j as usize].4 { phi } else { 0.0 })
                .collect();
            let value = |j: usize| points[j].3;
            let vector = |j: usize| centres[j] * points[j].3;
            for i in 0..centres.len() {
                let range = pairs.offsets()[i] as usize..pairs.offsets()[i + 1] as usize;
                let (mut sum, mut vsum, mut total) = (0.0, DVec3::ZERO, 0.0);
                for k in range {
                    let (w, j) = (weights[k], pairs.neighbour_array()[k] as usize);
                    if w > 0.0 {
                        sum += value(j) * w;
                        vsum += vector(j) * w;
                        total += w;
                    }
                }
                let (s, t) = row_sum(&pairs, &weights, i, value);
                let (v, _) = row_sum(&pairs, &weights, i, vector);
                proptest::prop_assert_eq!((s.to_bits(), t.to_bits()), (sum.to_bits(), total.to_bits()));
                proptest::prop_assert_eq!(v.to_array().map(f64::to_bits), vsum.to_array().map(f64::to_bits));
            }
        }
    }
}
