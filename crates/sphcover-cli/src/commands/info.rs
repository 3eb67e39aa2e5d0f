//! `sphcover info`: what a geometry file holds.

use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;
use sphcover_core::io::{self, FileInfo, NonFinitePolicy, ReadOptions};
use sphcover_core::{Aabb, DVec3};

use crate::args::InfoArgs;
use crate::memory_limit::MemoryLimit;
use crate::report::Reporter;

/// A normal counts as unit length when its length is within this of 1 (files store normals
/// in float or with few decimals, so exact unit length cannot be asked for).
const UNIT_TOLERANCE: f64 = 1e-3;

/// What `info` reports about one file: a point set or mesh, or a volume.
#[derive(Debug, Serialize)]
#[serde(untagged)]
enum Report {
    Geometry(Summary),
    Volume(VolumeSummary),
}

/// Everything `info` reports about a volume (CT image).
#[derive(Debug, Serialize)]
struct VolumeSummary {
    file: String,
    format: String,
    datatype: String,
    dims: [usize; 3],
    frames: u64,
    voxels: usize,
    voxel_size: [f64; 3],
    affine_source: String,
    world_bounding_box: BoxSummary,
    scaling: Option<(f64, f64)>,
    value_range: Option<(f64, f64)>,
    non_finite_voxels: u64,
    description: String,
}

/// Everything `info` reports about a point set or mesh.
#[derive(Debug, Serialize)]
struct Summary {
    file: String,
    format: String,
    file_size: u64,
    elements: Vec<ElementSummary>,
    comments: Vec<String>,
    points: usize,
    triangles: usize,
    polygons: u64,
    skipped_polygons: u64,
    bounding_box: Option<BoxSummary>,
    normals: Option<NormalSummary>,
    confidence: Option<RangeSummary>,
    values: Option<RangeSummary>,
    radii: Option<RangeSummary>,
    /// Per-vertex colours: how many distinct ones.
    distinct_colors: Option<usize>,
    mesh: Option<MeshSummary>,
    non_finite_vertices: u64,
    non_finite_values: u64,
}

#[derive(Debug, Serialize)]
struct ElementSummary {
    name: String,
    count: u64,
    properties: Vec<String>,
}

#[derive(Debug, Serialize)]
struct BoxSummary {
    min: [f64; 3],
    max: [f64; 3],
    extent: [f64; 3],
    diagonal: f64,
}

impl BoxSummary {
    fn of(bbox: &Aabb) -> BoxSummary {
        BoxSummary {
            min: bbox.min.to_array(),
            max: bbox.max.to_array(),
            extent: bbox.extent().to_array(),
            diagonal: bbox.diagonal(),
        }
    }
}

#[derive(Debug, Serialize)]
struct NormalSummary {
    unit_length: usize,
    zero_length: usize,
    other_length: usize,
    non_finite: usize,
    min_length: f64,
    max_length: f64,
}

#[derive(Debug, Serialize)]
struct RangeSummary {
    min: f64,
    max: f64,
    non_finite: usize,
}

#[derive(Debug, Serialize)]
struct MeshSummary {
    edges: usize,
    boundary_edges: usize,
    non_manifold_edges: usize,
    degenerate_triangles: usize,
    unreferenced_vertices: usize,
    closed: bool,
}

/// Runs `sphcover info`: every file is reported, and the first unreadable one ends the run
/// with its error after the others have been reported.
pub fn run(args: &InfoArgs, reporter: &Reporter) -> anyhow::Result<()> {
    let limit = args.memory.limit();
    let mut first_error = None;
    let mut out = String::new();
    for path in &args.files {
        let stage = reporter.stage(&format!("read {}", path.display()));
        let bar = reporter.progress(None, &format!("reading {}", path.display()));
        let result = if io::is_volume_path(path) {
            summarise_volume(path, &limit).map(Report::Volume)
        } else {
            summarise(path, &limit).map(Report::Geometry)
        };
        bar.finish_and_clear();
        stage.finish();
        match result {
            Ok(summary) => {
                if args.json {
                    out.push_str(&serde_json::to_string_pretty(&summary)?);
                    out.push('\n');
                } else {
                    out.push_str(&match &summary {
                        Report::Geometry(g) => render_text(g),
                        Report::Volume(v) => render_volume_text(v),
                    });
                }
            }
            Err(e) => {
                if first_error.is_none() {
                    first_error = Some(e);
                } else {
                    reporter.error(&e);
                }
            }
        }
    }
    print!("{out}");
    first_error.map_or(Ok(()), Err)
}

fn summarise(path: &Path, limit: &MemoryLimit) -> anyhow::Result<Summary> {
    let options = limit.apply(ReadOptions {
        non_finite: NonFinitePolicy::Keep,
        ..ReadOptions::default()
    });
    let geometry = io::read_geometry(path, &options).map_err(|e| limit.explain(e))?;
    let points = &geometry.points;
    let bbox = Aabb::from_points(&points.positions);
    let info: &FileInfo = &geometry.info;
    Ok(Summary {
        file: path.display().to_string(),
        format: info.variant.clone(),
        file_size: info.file_size,
        elements: info
            .elements
            .iter()
            .map(|e| ElementSummary {
                name: e.name.clone(),
                count: e.count,
                properties: e
                    .properties
                    .iter()
                    .map(|p| format!("{} {}", p.type_name, p.name))
                    .collect(),
            })
            .collect(),
        comments: info.comments.clone(),
        points: points.len(),
        triangles: geometry.triangles.len(),
        polygons: info.polygons,
        skipped_polygons: info.skipped_polygons,
        bounding_box: (!bbox.is_empty()).then(|| BoxSummary::of(&bbox)),
        normals: points.normals.as_deref().map(summarise_normals),
        confidence: points.confidence.as_deref().and_then(summarise_range),
        values: points.values.as_deref().and_then(summarise_range),
        radii: geometry.radii.as_deref().and_then(summarise_range),
        distinct_colors: points.colors.as_deref().map(|c| {
            c.iter()
                .copied()
                .collect::<std::collections::HashSet<_>>()
                .len()
        }),
        mesh: (!geometry.triangles.is_empty())
            .then(|| summarise_mesh(points.len(), &geometry.triangles, &points.positions)),
        non_finite_vertices: info.non_finite.vertices,
        non_finite_values: info.non_finite.coordinates,
    })
}

fn summarise_volume(path: &Path, limit: &MemoryLimit) -> anyhow::Result<VolumeSummary> {
    let options = limit.apply(ReadOptions {
        non_finite: NonFinitePolicy::Keep,
        ..ReadOptions::default()
    });
    let (volume, info) = io::read_volume(path, &options).map_err(|e| limit.explain(e))?;
    let dims = volume.dims();
    let mut bbox = Aabb::EMPTY;
    for corner in 0..8 {
        let ijk = [0, 1, 2].map(|a| if corner >> a & 1 == 1 { dims[a] - 1 } else { 0 });
        bbox.add(volume.voxel_centre(ijk));
    }
    Ok(VolumeSummary {
        file: path.display().to_string(),
        format: info.format_description(),
        datatype: info.datatype_name().to_owned(),
        dims,
        frames: info.frames(),
        voxels: volume.len(),
        voxel_size: volume.voxel_size().to_array(),
        affine_source: info.axes_source(),
        world_bounding_box: BoxSummary::of(&bbox),
        scaling: info.scaling(),
        value_range: volume.value_range(),
        non_finite_voxels: info.non_finite_voxels(),
        description: info.description(),
    })
}

fn render_volume_text(v: &VolumeSummary) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "{}", v.file);
    let _ = writeln!(o, "  format        {} ({})", v.format, v.datatype);
    let _ = writeln!(
        o,
        "  voxels        {} x {} x {} = {}{}",
        v.dims[0],
        v.dims[1],
        v.dims[2],
        v.voxels,
        if v.frames > 1 {
            format!(" (first of {} frames)", v.frames)
        } else {
            String::new()
        }
    );
    let _ = writeln!(
        o,
        "  voxel size    {} (world axes from {})",
        fmt_vec(v.voxel_size),
        v.affine_source
    );
    let b = &v.world_bounding_box;
    let _ = writeln!(
        o,
        "  voxel centres {} .. {}",
        fmt_vec(b.min),
        fmt_vec(b.max)
    );
    if let Some((slope, inter)) = v.scaling {
        let _ = writeln!(
            o,
            "  scaling       value = {} * stored + {}",
            fmt_num(slope),
            fmt_num(inter)
        );
    }
    match v.value_range {
        Some((lo, hi)) => {
            let _ = writeln!(o, "  values        {} .. {}", fmt_num(lo), fmt_num(hi));
        }
        None => {
            let _ = writeln!(o, "  values        none finite");
        }
    }
    let _ = writeln!(
        o,
        "  non-finite    {}",
        if v.non_finite_voxels == 0 {
            "none".to_owned()
        } else {
            format!("{} voxels", v.non_finite_voxels)
        }
    );
    if !v.description.is_empty() {
        let _ = writeln!(o, "  description   {}", v.description);
    }
    o
}

fn summarise_normals(normals: &[DVec3]) -> NormalSummary {
    let mut s = NormalSummary {
        unit_length: 0,
        zero_length: 0,
        other_length: 0,
        non_finite: 0,
        min_length: f64::INFINITY,
        max_length: 0.0,
    };
    for n in normals {
        if !n.is_finite() {
            s.non_finite += 1;
            continue;
        }
        let len = n.length();
        s.min_length = s.min_length.min(len);
        s.max_length = s.max_length.max(len);
        if len == 0.0 {
            s.zero_length += 1;
        } else if (len - 1.0).abs() <= UNIT_TOLERANCE {
            s.unit_length += 1;
        } else {
            s.other_length += 1;
        }
    }
    if s.min_length > s.max_length {
        s.min_length = 0.0;
    }
    s
}

fn summarise_range(values: &[f64]) -> Option<RangeSummary> {
    let finite = values.iter().copied().filter(|v| v.is_finite());
    let (min, max) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    Some(RangeSummary {
        min: if min <= max { min } else { f64::NAN },
        max: if min <= max { max } else { f64::NAN },
        non_finite: values.iter().filter(|v| !v.is_finite()).count(),
    })
}

/// Edge counts by sorting the three edges of every triangle: a closed 2-manifold has every
/// edge in exactly two triangles.
fn summarise_mesh(vertices: usize, triangles: &[[u32; 3]], positions: &[DVec3]) -> MeshSummary {
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(triangles.len() * 3);
    let mut used = vec![false; vertices];
    let mut degenerate = 0;
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b)));
            used[a as usize] = true;
        }
        let [a, b, c] = t.map(|v| positions[v as usize]);
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || (b - a).cross(c - a) == DVec3::ZERO {
            degenerate += 1;
        }
    }
    edges.sort_unstable();
    let (mut unique, mut boundary, mut non_manifold) = (0, 0, 0);
    let mut i = 0;
    while i < edges.len() {
        let mut j = i + 1;
        while j < edges.len() && edges[j] == edges[i] {
            j += 1;
        }
        unique += 1;
        match j - i {
            1 => boundary += 1,
            2 => {}
            _ => non_manifold += 1,
        }
        i = j;
    }
    MeshSummary {
        edges: unique,
        boundary_edges: boundary,
        non_manifold_edges: non_manifold,
        degenerate_triangles: degenerate,
        unreferenced_vertices: used.iter().filter(|u| !**u).count(),
        closed: boundary == 0 && non_manifold == 0,
    }
}

fn render_text(s: &Summary) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "{}", s.file);
    let _ = writeln!(o, "  format        {} ({} bytes)", s.format, s.file_size);
    for e in &s.elements {
        let _ = writeln!(
            o,
            "  element       {} {}: {}",
            e.name,
            e.count,
            e.properties.join(", ")
        );
    }
    for c in &s.comments {
        let _ = writeln!(o, "  comment       {c}");
    }
    let _ = writeln!(o, "  points        {}", s.points);
    if s.triangles > 0 || s.polygons > 0 {
        let _ = writeln!(
            o,
            "  triangles     {} (from {} polygons{})",
            s.triangles,
            s.polygons,
            if s.skipped_polygons > 0 {
                format!(", {} with fewer than 3 corners skipped", s.skipped_polygons)
            } else {
                String::new()
            }
        );
    }
    match &s.bounding_box {
        Some(b) => {
            let _ = writeln!(
                o,
                "  bounding box  {} .. {}",
                fmt_vec(b.min),
                fmt_vec(b.max)
            );
            let _ = writeln!(
                o,
                "  extent        {} (diagonal {})",
                fmt_vec(b.extent),
                fmt_num(b.diagonal)
            );
        }
        None => {
            let _ = writeln!(o, "  bounding box  none (no finite point)");
        }
    }
    match &s.normals {
        Some(n) => {
            let verdict = if n.unit_length == s.points {
                "all unit length".to_owned()
            } else {
                format!(
                    "{} unit length, {} zero, {} of other length, {} not finite",
                    n.unit_length, n.zero_length, n.other_length, n.non_finite
                )
            };
            let _ = writeln!(
                o,
                "  normals       yes: {verdict} (lengths {} .. {})",
                fmt_num(n.min_length),
                fmt_num(n.max_length)
            );
        }
        None => {
            let _ = writeln!(o, "  normals       no");
        }
    }
    for (name, r) in [
        ("confidence", &s.confidence),
        ("values", &s.values),
        ("radii", &s.radii),
    ] {
        if let Some(r) = r {
            let _ = writeln!(
                o,
                "  {name:<13} {} .. {}{}",
                fmt_num(r.min),
                fmt_num(r.max),
                if r.non_finite > 0 {
                    format!(" ({} not finite)", r.non_finite)
                } else {
                    String::new()
                }
            );
        }
    }
    if let Some(n) = s.distinct_colors {
        let _ = writeln!(o, "  colours       {n} distinct");
    }
    if let Some(m) = &s.mesh {
        let _ = writeln!(
            o,
            "  mesh          {} edges, {} boundary, {} non-manifold, {} degenerate triangles, {} unreferenced vertices: {}",
            m.edges,
            m.boundary_edges,
            m.non_manifold_edges,
            m.degenerate_triangles,
            m.unreferenced_vertices,
            if m.closed { "closed" } else { "open" }
        );
    }
    let _ = writeln!(
        o,
        "  non-finite    {}",
        if s.non_finite_vertices == 0 {
            "none".to_owned()
        } else {
            format!(
                "{} vertices with {} non-finite values",
                s.non_finite_vertices, s.non_finite_values
            )
        }
    );
    o
}

/// Six decimals in the usual range, scientific notation for very large or small magnitudes.
fn fmt_num(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || (1e-3..1e7).contains(&a) || !a.is_finite() {
        format!("{x:.6}")
    } else {
        format!("{x:.6e}")
    }
}

fn fmt_vec(v: [f64; 3]) -> String {
    format!("({}, {}, {})", fmt_num(v[0]), fmt_num(v[1]), fmt_num(v[2]))
}
