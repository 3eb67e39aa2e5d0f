//! `sphcover tetra`: the tetrahedral mesh of a cover (thesis §3.5), built as the dual complex
//! of the union of balls on an exact regular triangulation.

use sphcover_core::io::{self, SphereSet};
use sphcover_tetra::{DualComplexParams, TetMesh, dual_complex, write_tet_mesh};

use crate::args::TetraArgs;
use crate::exit::BadInput;
use crate::report::Reporter;

/// Runs `sphcover tetra`.
pub fn run(args: &TetraArgs, reporter: &Reporter) -> anyhow::Result<()> {
    if !(args.shrink.is_finite() && args.shrink > 0.0) {
        return Err(BadInput(format!(
            "--shrink {} must be a positive number",
            args.shrink
        ))
        .into());
    }

    let stage = reporter.stage("read spheres");
    let spheres = read_spheres(args, reporter)?;
    stage.finish();
    reporter.detail(&format!("  {} spheres", spheres.centres.len()));

    let stage = reporter.stage("regular triangulation");
    let bar = reporter.progress(None, "triangulating");
    let params = DualComplexParams {
        shrink: args.shrink,
        seed: args.seed,
    };
    let complex = dual_complex(&spheres.centres, &spheres.radii, &params)
        .map_err(|e| BadInput(format!("{}: {e}", args.spheres.display())))?;
    bar.finish_and_clear();
    stage.finish();

    let stage = reporter.stage("edges and rings");
    let mesh = TetMesh::from_dual_complex(&complex);
    stage.finish();

    let stage = reporter.stage("write");
    write_tet_mesh(
        &args.output,
        &mesh,
        &spheres.centres,
        &spheres.radii,
        std::slice::from_ref(&args.spheres),
    )?;
    stage.finish();

    let t = &complex.triangulation;
    reporter.summary(&format!(
        "{} spheres: {} vertices, {} hidden, {} duplicate centres; dual complex: {} tetrahedra, {} edges, {} triangles, Euler characteristic {} -> {}",
        t.points,
        mesh.vertices.len(),
        t.hidden,
        t.duplicates,
        mesh.tets.len(),
        mesh.edges.len(),
        mesh.num_triangles(),
        mesh.euler_characteristic(),
        args.output.display()
    ));
    Ok(())
}

/// Reads the sphere set, dropping non-finite spheres with a warning when asked to.
fn read_spheres(args: &TetraArgs, reporter: &Reporter) -> anyhow::Result<SphereSet> {
    let limit = args.memory.limit();
    let geometry = io::read_geometry(&args.spheres, &args.read.read_options(&limit))
        .map_err(|e| limit.explain(e))?;
    let dropped = geometry.info.non_finite.dropped_vertices;
    if dropped > 0 {
        reporter.warn(&format!(
            "{}: dropped {dropped} spheres with non-finite values",
            args.spheres.display()
        ));
    }
    let Some(radii) = geometry.radii else {
        return Err(io::IoError::NoRadius {
            path: args.spheres.clone(),
        }
        .into());
    };
    Ok(SphereSet {
        centres: geometry.points.positions,
        radii,
    })
}
