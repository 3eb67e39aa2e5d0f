//! The passes of a streamed run after the tiles' functions: the polygonisation, and the
//! trimming, cleaning and refinement, each reading the samples one tile file at a time.

use rayon::prelude::*;
use sphcover_core::{Aabb, DVec3, MeshTopology, PointIndex, vertex_normals};

use super::Streamed;
use crate::pipeline::components::{
    component_votes, drop_sheets_by_votes, drop_small_components, may_hold_sheets, most_voted,
    vertex_components,
};
use crate::pipeline::spill::TileLabels;
use crate::pipeline::stages::{polygonisation_params_at, record_topology};
use crate::pipeline::tiled::{polygonise_pieces, tile_of, tiles_holding};
use crate::pipeline::{ReconError, Trim};
use crate::polygonise::{trim_and_resolve, trimming_points};
use crate::vertex_refinement::{
    Outcome, RefinementSamples, RefinementScale, apply_moves, check, refinement_moves,
};

/// Surface nets of the tiles' functions, from a seed in every lattice cell that holds
/// confident samples; trimmed by the next stage (which reads the samples), or only its fans
/// resolved when nothing is trimmed.
pub(super) fn polygonise(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let (which, _) = ctx.threshold();
    let seeds = &ctx.seeds[which].points;
    if seeds.is_empty() {
        return Err(ReconError::Empty("every sample is an outlier"));
    }
    ctx.poly = polygonisation_params_at(
        ctx.params,
        ctx.stats.depth,
        &ctx.stats.scan,
        Aabb::from_points(seeds).diagonal(),
    );
    let (mut mesh, mut stats) =
        polygonise_pieces(&ctx.pieces, &ctx.splits, seeds, &ctx.poly, false)?;
    if ctx.params.trim == Trim::Off {
        trim_and_resolve(&mut mesh, None, &ctx.poly, &mut stats);
    }
    ctx.mesh = mesh;
    ctx.stats.polygonise = Some(stats);
    // The functions are not needed any more.
    ctx.pieces = Vec::new();
    Ok(())
}

/// The elements (`centroids` or vertices) each tile owns, by [`tile_of`] in the unit frame.
fn owned_by_tile(splits: &[Vec<f64>; 3], tiles: usize, points: &[DVec3]) -> Vec<Vec<u32>> {
    let mut owned = vec![Vec::new(); tiles];
    for (i, &p) in points.iter().enumerate() {
        owned[tile_of(splits, p)].push(i as u32);
    }
    owned
}

/// The trimming `params` ask for: the distance of each of [`trimming_points`] (centroids or
/// vertices) to the nearest qualifying sample, measured by the tile whose box holds the
/// point from the samples of its box and halo. Where that is farther than the halo (a
/// sample outside the halo could be nearer), the nearest seed of the whole scan is taken
/// when nearer: the distance is then right to within the seeds' lattice, which only the
/// reach of far regions reads.
pub(super) fn trim(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let Some(points) = trimming_points(&ctx.mesh, &ctx.poly) else {
        return Ok(());
    };
    let owned = owned_by_tile(&ctx.splits, ctx.tiling.count(), &points);
    let (which, threshold) = ctx.threshold();
    let mut distance2 = vec![f64::INFINITY; points.len()];
    for (t, owned) in owned.iter().enumerate() {
        if owned.is_empty() {
            continue;
        }
        let (samples, _) = ctx.tile_samples(t)?;
        let Some(labels) = ctx.files().directory().read_labels(t)? else {
            continue;
        };
        let seeds: Vec<DVec3> = qualifying(&samples.points, &labels, threshold).collect();
        if seeds.is_empty() {
            continue;
        }
        let index = PointIndex::new(&seeds)?;
        let found: Vec<f64> = owned
            .par_iter()
            .map_init(Vec::new, |near, &i| {
                index.nearest_k_with_distances(points[i as usize], 1, near);
                near.first().map_or(f64::INFINITY, |&(d2, _)| d2)
            })
            .collect();
        for (&i, d2) in owned.iter().zip(found) {
            distance2[i as usize] = d2;
        }
    }
    let halo2 = ctx.halo() * ctx.halo();
    let far: Vec<usize> = (0..points.len())
        .filter(|&i| distance2[i] > halo2)
        .collect();
    if !far.is_empty() {
        let index = PointIndex::new(&ctx.seeds[which].points)?;
        let mut near = Vec::new();
        for i in far {
            index.nearest_k_with_distances(points[i], 1, &mut near);
            if let Some(&(d2, _)) = near.first() {
                distance2[i] = distance2[i].min(d2);
            }
        }
    }
    let mut stats = ctx.stats.polygonise.take().unwrap_or_default();
    trim_and_resolve(&mut ctx.mesh, Some(&distance2), &ctx.poly, &mut stats);
    ctx.stats.unseen_area_fraction = stats.unseen_area_fraction;
    ctx.stats.polygonise = Some(stats);
    Ok(())
}

/// The samples of a tile that seed the surface at `threshold`.
fn qualifying<'a>(
    points: &'a [DVec3],
    labels: &'a TileLabels,
    threshold: f64,
) -> impl Iterator<Item = DVec3> + 'a {
    points
        .iter()
        .zip(labels.confidence.iter().zip(&labels.outliers))
        .filter(move |&(_, (&c, &o))| !o && c >= threshold)
        .map(|(&p, _)| p)
}

/// What the cleaning and the refinement of a single run need from the samples, tile by tile:
/// the samples' votes for the components they lie nearest to (every 4th of a tile's own, not
/// isolated, against the vertices of its box and halo), and the move of each vertex onto
/// the samples (by the tile whose box holds it). Small components go first, unsupported
/// sheets after the moves.
pub(super) fn clean_and_refine(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    if ctx.mesh.values.as_ref().map(Vec::len) != Some(ctx.mesh.vertices.len()) {
        ctx.mesh.values = None;
    }
    let mut mesh = std::mem::take(&mut ctx.mesh);
    let small = drop_small_components(&mut mesh, ctx.params, |mesh, topology| {
        let (positions, components) = vertex_components(mesh, topology);
        let near_vertices = vertices_near_tiles(ctx, &positions);
        let mut votes = vec![0usize; topology.components];
        for (t, near) in near_vertices.iter().enumerate() {
            if near.is_empty() {
                continue;
            }
            let (samples, own) = ctx.tile_samples(t)?;
            if let Some(labels) = ctx.files().directory().read_labels(t)? {
                let tile = TileVoters::new(&samples.points, &own, &labels);
                tile.add_votes(near, &positions, &components, &mut votes)?;
            }
        }
        Ok(votes)
    });
    ctx.mesh = mesh;
    let (small, topology) = small?;
    let voting = may_hold_sheets(&topology);
    let (positions, components) = if voting {
        vertex_components(&ctx.mesh, &topology)
    } else {
        (Vec::new(), Vec::new())
    };
    let normals = vertex_normals(&ctx.mesh.vertices, &ctx.mesh.triangles);
    let refine = ctx.params.refine;
    let scale = RefinementScale {
        spacing: ctx.spacing,
        step: 1.0 / f64::from(1u32 << ctx.stats.depth),
        noise_ratio: ctx.stats.eps / ctx.params.cover.eps,
    };
    let tiles = ctx.tiling.count();
    let owned = owned_by_tile(&ctx.splits, tiles, &ctx.mesh.vertices);
    let near_vertices = vertices_near_tiles(ctx, &positions);
    let mut votes = vec![0usize; topology.components];
    let mut moves = vec![Outcome::Unfitted; ctx.mesh.vertices.len()];
    for t in 0..tiles {
        if owned[t].is_empty() && near_vertices[t].is_empty() {
            continue;
        }
        let (samples, own) = ctx.tile_samples(t)?;
        let Some(labels) = ctx.files().directory().read_labels(t)? else {
            continue;
        };
        if !near_vertices[t].is_empty() {
            TileVoters::new(&samples.points, &own, &labels).add_votes(
                &near_vertices[t],
                &positions,
                &components,
                &mut votes,
            )?;
        }
        if let Some(refine) = &refine
            && !owned[t].is_empty()
        {
            let weights: Vec<f64> = labels
                .confidence
                .iter()
                .zip(&labels.outliers)
                .map(|(&c, &o)| if o { 0.0 } else { c })
                .collect();
            let index = PointIndex::new(&samples.points)?;
            let samples = RefinementSamples {
                points: &samples.points,
                normals: &samples.normals,
                weights: &weights,
                index: &index,
            };
            check(&samples, &scale, refine)?;
            let (vertices, vertex_normals): (Vec<DVec3>, Vec<DVec3>) = owned[t]
                .iter()
                .map(|&v| (ctx.mesh.vertices[v as usize], normals[v as usize]))
                .unzip();
            let found = refinement_moves(&vertices, &vertex_normals, &samples, &scale, refine);
            for (&v, m) in owned[t].iter().zip(found) {
                moves[v as usize] = m;
            }
        }
    }
    if refine.is_some() {
        ctx.stats.refinement = Some(apply_moves(&mut ctx.mesh.vertices, &normals, &moves));
    }
    // The object's first triangle: the sheets dropped below keep the others' order.
    let object_first = most_voted(&votes).and_then(|c| {
        topology
            .triangle_component
            .iter()
            .position(|&tc| tc as usize == c)
    });
    let dropped = if voting {
        drop_sheets_by_votes(&mut ctx.mesh, &topology, &votes)?
    } else {
        Vec::new()
    };
    let gone = |c: u32| dropped.get(c as usize).copied().unwrap_or(false);
    ctx.object_triangle = object_first.map(|first| {
        topology.triangle_component[..first]
            .iter()
            .filter(|&&c| !gone(c))
            .count()
    });
    ctx.stats.dropped_components = small + dropped.iter().filter(|&&d| d).count();
    if ctx.mesh.triangles.is_empty() {
        return Err(ReconError::Empty(
            "no surface was found near the confident samples",
        ));
    }
    Ok(())
}

/// The vertices at `positions` that lie in each tile's box and halo.
fn vertices_near_tiles(ctx: &Streamed<'_>, positions: &[DVec3]) -> Vec<Vec<u32>> {
    let mut near = vec![Vec::new(); ctx.tiling.count()];
    for (v, &p) in positions.iter().enumerate() {
        tiles_holding(&ctx.splits, ctx.halo(), p, |t| near[t].push(v as u32));
    }
    near
}

/// The samples of one tile that vote for the components they lie nearest to: every 4th of
/// the tile's own, isolated ones left out.
struct TileVoters<'a> {
    points: &'a [DVec3],
    voters: Vec<usize>,
}

impl<'a> TileVoters<'a> {
    fn new(points: &'a [DVec3], own: &[bool], labels: &TileLabels) -> TileVoters<'a> {
        let voters = (0..own.len())
            .filter(|&s| own[s])
            .step_by(4)
            .filter(|&s| !labels.isolated[s])
            .collect();
        TileVoters { points, voters }
    }

    /// Adds to `votes` the votes for the components of the vertices `near` (indices into
    /// `positions` and `components`).
    fn add_votes(
        &self,
        near: &[u32],
        positions: &[DVec3],
        components: &[u32],
        votes: &mut [usize],
    ) -> Result<(), ReconError> {
        let (tile_positions, tile_components): (Vec<DVec3>, Vec<u32>) = near
            .iter()
            .map(|&v| (positions[v as usize], components[v as usize]))
            .unzip();
        let tile_votes = component_votes(
            &tile_positions,
            &tile_components,
            votes.len(),
            self.points,
            &self.voters,
        )?;
        for (all, v) in votes.iter_mut().zip(tile_votes) {
            *all += v;
        }
        Ok(())
    }
}

/// The surface in input coordinates, and its topology.
pub(super) fn topology(ctx: &mut Streamed<'_>) -> Result<(), ReconError> {
    let topology = MeshTopology::of(&ctx.mesh);
    let open_components = topology.open_component.iter().filter(|&&o| o).count();
    let object = if topology.components > 1 && open_components > 0 {
        ctx.object_triangle
            .and_then(|t| topology.triangle_component.get(t))
            .map(|&c| c as usize)
    } else {
        Some(0).filter(|_| topology.components > 0)
    };
    ctx.mesh.to_input(&ctx.frame);
    record_topology(&mut ctx.stats, &ctx.mesh, &topology, object);
    Ok(())
}
