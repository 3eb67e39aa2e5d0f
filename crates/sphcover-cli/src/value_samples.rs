//! Reading scattered samples with values (`--value-property`) for `cover` and `skeleton`.

use std::path::Path;

use sphcover_core::DVec3;
use sphcover_core::io;

use crate::args::InputArgs;
use crate::exit::BadInput;
use crate::memory_limit::MemoryLimit;
use crate::report::Reporter;

/// The positions of the vertices of the PLY point file `input` and their scalar `property`,
/// read under the memory `limit`; bad input (exit 2) for a volume or a file without that
/// property. Samples whose position or value is not finite are refused, or with
/// `--drop-non-finite` dropped with a warning, as vertices are.
pub fn read_value_samples(
    input: &Path,
    property: &str,
    read: &InputArgs,
    limit: &MemoryLimit,
    reporter: &Reporter,
) -> anyhow::Result<(Vec<DVec3>, Vec<f64>)> {
    let name = input.display();
    if io::is_volume_path(input) {
        return Err(BadInput(format!(
            "{name}: --value-property names a vertex property of a PLY point file; a volume carries its values on the grid"
        ))
        .into());
    }
    let stage = reporter.stage("read samples");
    let (geometry, values) =
        io::read_geometry_with_vertex_property(input, property, &read.read_options(limit))
            .map_err(|e| limit.explain(e))?;
    stage.finish();
    let Some(mut values) = values else {
        return Err(BadInput(format!(
            "{name}: no scalar vertex property named `{property}` (only PLY files declare named properties)"
        ))
        .into());
    };
    let mut positions = geometry.points.positions;
    let bad = values.iter().filter(|v| !v.is_finite()).count();
    if bad > 0 {
        if !read.drop_non_finite {
            let first = values.iter().position(|v| !v.is_finite()).unwrap_or(0);
            return Err(BadInput(format!(
                "{name}: vertex {first}: `{property}` is not finite ({bad} sample{} with a NaN or infinite value); --drop-non-finite drops them",
                if bad == 1 { "" } else { "s" }
            ))
            .into());
        }
        let keep: Vec<bool> = values.iter().map(|v| v.is_finite()).collect();
        let mut k = keep.iter();
        positions.retain(|_| *k.next().unwrap_or(&false));
        values.retain(|v| v.is_finite());
        reporter.warn(&format!(
            "{name}: dropped {bad} sample{} whose `{property}` is NaN or infinite",
            if bad == 1 { "" } else { "s" }
        ));
    }
    Ok((positions, values))
}
