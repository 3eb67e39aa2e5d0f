//! `sphcover render`: a PNG preview of a mesh, a point cloud or a sphere set, drawn by the
//! built-in software rasteriser (no display or GPU needed).

use std::path::Path;

use sphcover_core::io::{self, Format, Geometry};
use sphcover_render::{
    Background, Projection, RenderOptions, Scene, Shading, UpAxis, ViewAngles, colour_bar_label,
    render,
};

use crate::args::RenderArgs;
use crate::exit::BadInput;
use crate::report::Reporter;

/// Runs `sphcover render`.
pub fn run(args: &RenderArgs, reporter: &Reporter) -> anyhow::Result<()> {
    let mut options = parse_options(args)?;

    let stage = reporter.stage("read");
    let (geometry, scalars) = read(args, reporter)?;
    stage.finish();
    if args.up.is_none() && geometry.info.format == Format::Las {
        // LiDAR surveys are z-up by definition of the format.
        options.up = UpAxis::Z;
    }
    let mesh = !geometry.triangles.is_empty();
    let scene = Scene {
        positions: &geometry.points.positions,
        triangles: &geometry.triangles,
        normals: geometry.points.normals.as_deref(),
        radii: geometry.radii.as_deref(),
        scalars: scalars.as_deref(),
        colors: geometry
            .points
            .colors
            .as_deref()
            .filter(|_| !args.ignore_colours),
    };

    let stage = reporter.stage("render");
    let rendered =
        render(&scene, &options).map_err(|e| BadInput(format!("{}: {e}", args.input.display())))?;
    stage.finish();

    let stage = reporter.stage("write");
    let image = &rendered.image;
    io::write_atomic(&args.output, std::slice::from_ref(&args.input), |w| {
        image.write_png(w)
    })?;
    stage.finish();

    reporter.detail(&format!(
        "  drawn: {} triangles, {} splats (the others have no area, lie behind the camera or between sample rows)",
        rendered.triangles, rendered.splats
    ));
    let what = if mesh {
        format!("{} triangles", geometry.triangles.len())
    } else if geometry.radii.is_some() {
        format!("{} balls", geometry.points.len())
    } else {
        format!(
            "{} points as {:.1}-pixel splats",
            geometry.points.len(),
            rendered.point_diameter.unwrap_or(0.0)
        )
    };
    let mut summary = format!(
        "{}: {what}, view {}, {}x{} -> {}",
        args.input.display(),
        args.view,
        options.width,
        options.height,
        args.output.display()
    );
    if let (Some(name), Some((lo, hi))) = (&args.colour_by, rendered.colour_range) {
        summary.push_str(&format!(
            "\ncolour by {name}: {} (dark purple) to {} (yellow), viridis{}",
            colour_bar_label(lo),
            colour_bar_label(hi),
            if rendered.colour_bar {
                ""
            } else {
                "; the image is too small for a colour bar"
            }
        ));
    }
    reporter.summary(&summary);
    Ok(())
}

/// The rendering options the flags ask for.
fn parse_options(args: &RenderArgs) -> anyhow::Result<RenderOptions> {
    let bad = |message: String| anyhow::Error::from(BadInput(message));
    let (width, height) = parse_size(&args.size).map_err(bad)?;
    let view = ViewAngles::parse(&args.view).map_err(bad)?;
    let up = match &args.up {
        Some(text) => UpAxis::parse(text).map_err(bad)?,
        None => UpAxis::Y,
    };
    let projection = match args.perspective {
        None => Projection::Orthographic,
        Some(fov) if fov.is_finite() && fov > 0.0 && fov < 170.0 => {
            Projection::Perspective { fov_deg: fov }
        }
        Some(fov) => {
            return Err(bad(format!(
                "--perspective {fov}: the field of view must lie between 0 and 170 degrees"
            )));
        }
    };
    let background = parse_background(&args.background).map_err(bad)?;
    let colour_range = match &args.range {
        None => None,
        Some(text) => Some(parse_range(text).map_err(bad)?),
    };
    if args.range.is_some() && args.colour_by.is_none() {
        return Err(bad("--range needs --colour-by".into()));
    }
    Ok(RenderOptions {
        width,
        height,
        view,
        up,
        projection,
        supersample: args.supersample,
        shading: if args.flat {
            Shading::Flat
        } else {
            Shading::Smooth
        },
        point_diameter: args.point_size,
        background,
        colour_range,
        colour_bar: !args.no_colour_bar,
    })
}

/// `WxH` in pixels.
fn parse_size(text: &str) -> Result<(usize, usize), String> {
    let bad = || format!("--size {text:?}: expected WIDTHxHEIGHT in pixels, e.g. 1600x1200");
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let w: usize = w.trim().parse().map_err(|_| bad())?;
    let h: usize = h.trim().parse().map_err(|_| bad())?;
    Ok((w, h))
}

/// `LO,HI`.
fn parse_range(text: &str) -> Result<(f64, f64), String> {
    let bad = || format!("--range {text:?}: expected LOW,HIGH (two finite numbers, LOW <= HIGH)");
    let (lo, hi) = text.split_once(',').ok_or_else(bad)?;
    let lo: f64 = lo.trim().parse().map_err(|_| bad())?;
    let hi: f64 = hi.trim().parse().map_err(|_| bad())?;
    if lo.is_finite() && hi.is_finite() && lo <= hi {
        Ok((lo, hi))
    } else {
        Err(bad())
    }
}

/// `white`, `black`, `transparent`, or a hexadecimal colour `#RRGGBB`.
fn parse_background(text: &str) -> Result<Background, String> {
    let named = match text.to_ascii_lowercase().as_str() {
        "white" => Some(Background::Colour([255, 255, 255])),
        "black" => Some(Background::Colour([0, 0, 0])),
        "grey" | "gray" => Some(Background::Colour([128, 128, 128])),
        "transparent" | "none" => Some(Background::Transparent),
        _ => None,
    };
    if let Some(b) = named {
        return Ok(b);
    }
    let hex = text.strip_prefix('#').unwrap_or(text);
    let bad = || {
        format!(
            "--background {text:?}: expected white, black, grey, transparent or a colour #RRGGBB"
        )
    };
    if hex.len() != 6 || !hex.is_ascii() {
        return Err(bad());
    }
    let channel = |k: usize| u8::from_str_radix(&hex[2 * k..2 * k + 2], 16).map_err(|_| bad());
    Ok(Background::Colour([channel(0)?, channel(1)?, channel(2)?]))
}

/// Reads the input and the values to colour by.
fn read(args: &RenderArgs, reporter: &Reporter) -> anyhow::Result<(Geometry, Option<Vec<f64>>)> {
    let limit = args.memory.limit();
    let options = args.read.read_options(&limit);
    let (geometry, scalars) = match &args.colour_by {
        None => (
            io::read_geometry(&args.input, &options).map_err(|e| limit.explain(e))?,
            None,
        ),
        Some(name) => {
            let (geometry, column) =
                io::read_geometry_with_vertex_property(&args.input, name, &options)
                    .map_err(|e| limit.explain(e))?;
            let values = match column {
                Some(values) => values,
                None => builtin_property(&geometry, name)
                    .ok_or_else(|| unknown_property(&args.input, &geometry, name))?,
            };
            (geometry, Some(values))
        }
    };
    let dropped = geometry.info.non_finite.dropped_vertices;
    if dropped > 0 {
        reporter.warn(&format!(
            "{}: dropped {dropped} vertices with non-finite values ({} triangles with them)",
            args.input.display(),
            geometry.info.non_finite.dropped_triangles
        ));
    }
    Ok((geometry, scalars))
}

/// Per-vertex values every format can provide: the reader's attributes and the coordinates.
fn builtin_property(geometry: &Geometry, name: &str) -> Option<Vec<f64>> {
    let points = &geometry.points;
    let axis = |k: usize| Some(points.positions.iter().map(|p| p[k]).collect());
    match name.to_ascii_lowercase().as_str() {
        "confidence" => points.confidence.clone(),
        "quality" | "value" | "values" | "scalar" | "intensity" => points.values.clone(),
        "radius" => geometry.radii.clone(),
        "x" => axis(0),
        "y" => axis(1),
        "z" => axis(2),
        _ => None,
    }
}

/// The error for a property the file does not have, listing those it has.
fn unknown_property(path: &Path, geometry: &Geometry, name: &str) -> anyhow::Error {
    let mut names: Vec<String> = geometry
        .info
        .elements
        .iter()
        .filter(|e| e.name == "vertex" && geometry.info.format == Format::Ply)
        .flat_map(|e| &e.properties)
        .filter(|p| !p.type_name.starts_with("list"))
        .map(|p| p.name.clone())
        .collect();
    for (builtin, present) in [
        ("x", true),
        ("y", true),
        ("z", true),
        ("confidence", geometry.points.confidence.is_some()),
        ("quality", geometry.points.values.is_some()),
        ("radius", geometry.radii.is_some()),
    ] {
        if present && !names.iter().any(|n| n == builtin) {
            names.push(builtin.to_string());
        }
    }
    BadInput(format!(
        "{}: no per-vertex property {name:?} to colour by; the file has: {}",
        path.display(),
        names.join(", ")
    ))
    .into()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_ranges_and_backgrounds_parse() {
        assert_eq!(parse_size("1600x1200"), Ok((1600, 1200)));
        assert_eq!(parse_size("64X48"), Ok((64, 48)));
        for bad in ["", "1600", "x12", "-1x5", "1.5x2"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_range("-1, 2.5"), Ok((-1.0, 2.5)));
        for bad in ["1", "2,1", "nan,1", "a,b"] {
            assert!(parse_range(bad).is_err(), "{bad}");
        }
        assert_eq!(
            parse_background("#FF8000"),
            Ok(Background::Colour([255, 128, 0]))
        );
        assert_eq!(parse_background("none"), Ok(Background::Transparent));
        for bad in ["#12345", "red", "#GG0000", "#ééé"] {
            assert!(parse_background(bad).is_err(), "{bad}");
        }
    }
}
