//! Reading scattered samples with values (`--value-property`) for `cover` and `skeleton`.

use std::path::Path;

use sphcover_core::DVec3;
use sphcover_core::io::{self, ReadOptions};

use crate::exit::BadInput;
use crate::memory_limit::MemoryLimit;
use crate::report::Reporter;

/// The positions of the vertices of the PLY point file `input` and their scalar `property`,
/// read under the memory `limit`; bad input (exit 2) for a volume or a file without that
/// property.
pub fn read_value_samples(
    input: &Path,
    property: &str,
    options: &ReadOptions,
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
        io::read_geometry_with_vertex_property(input, property, &limit.apply(options.clone()))
            .map_err(|e| limit.explain(e))?;
    stage.finish();
    let Some(values) = values else {
        return Err(BadInput(format!(
            "{name}: no scalar vertex property named `{property}` (only PLY files declare named properties)"
        ))
        .into());
    };
    Ok((geometry.points.positions, values))
}
