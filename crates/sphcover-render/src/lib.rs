//! A software rasteriser for previews on machines without a display: triangle meshes
//! shaded flat or smooth, point clouds as splats, sphere sets as balls, optionally coloured
//! by a per-vertex value through the viridis colour map with a labelled colour bar, and the
//! picture written as PNG. It needs neither a GPU nor a window, so tests, servers and batch
//! jobs can look at geometry too.
//!
//! ```
//! use sphcover_render::{Background, DVec3, RenderOptions, Scene, render};
//!
//! // A regular tetrahedron around the origin, drawn from the default isometric view.
//! let positions = [
//!     DVec3::new(1.0, 1.0, 1.0),
//!     DVec3::new(1.0, -1.0, -1.0),
//!     DVec3::new(-1.0, 1.0, -1.0),
//!     DVec3::new(-1.0, -1.0, 1.0),
//! ];
//! let triangles = [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]];
//! let scene = Scene {
//!     positions: &positions,
//!     triangles: &triangles,
//!     normals: None,
//!     radii: None,
//!     scalars: None,
//!     colors: None,
//! };
//! let options = RenderOptions {
//!     width: 64,
//!     height: 48,
//!     background: Background::Colour([255, 255, 255]),
//!     ..RenderOptions::default()
//! };
//! let rendered = render(&scene, &options)?;
//! let image = &rendered.image;
//! assert_eq!((image.width, image.height), (64, 48));
//! // The camera is fitted to the geometry, so the solid covers the centre of the picture
//! // and leaves the corners to the background.
//! let centre = image.get(32, 24);
//! assert_ne!(centre, [255, 255, 255, 255]);
//! assert!(centre[0] < 240 && centre[3] == 255, "{centre:?}");
//! assert_eq!(image.get(0, 0), [255, 255, 255, 255]);
//!
//! let mut png = Vec::new();
//! image.write_png(&mut png)?;
//! assert!(png.starts_with(b"\x89PNG"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! [`render`] draws a [`Scene`] (borrowed vertex and triangle arrays) with [`RenderOptions`]
//! into the [`Image`] of a [`Rendered`]. [`Rendered::camera`] is the view the picture was
//! drawn with, for callers that place their own marks over it, and [`colour_bar_label`]
//! prints a value as the colour bar does.
//!
//! The input types are plain structs built with struct literals: [`RenderOptions`] with
//! `..RenderOptions::default()` for the fields left alone, like the `Params` structs of the
//! other sphcover crates. They are deliberately not `#[non_exhaustive]`, which would forbid
//! that syntax outside this crate: the `sphcover render` command names every field, so an
//! option added later is a compile error there until the command decides how to set it. The
//! types only the renderer builds, [`Rendered`] and [`RenderError`], are `#[non_exhaustive]`,
//! so that new statistics or refusals do not break their readers.
//!
//! The image is drawn in horizontal bands, one rayon task per band; within a band every
//! primitive is drawn in index order with a strict depth test and every sample is shaded
//! and averaged by the same arithmetic whatever the thread count, so the same input and
//! options always give the same bytes.
#![deny(missing_docs)]

mod camera;
mod colour_bar;
mod colour_map;
mod image;
mod raster;
mod shading;

use rayon::prelude::*;

pub use camera::{Camera, Projected, Projection, UpAxis, ViewAngles, Viewport};
pub use colour_bar::label as colour_bar_label;
pub use glam::DVec3;
pub use image::Image;

use colour_bar::ColourBar;
use colour_map::{ColourScale, linear_to_srgb, srgb_to_linear};
use raster::{Band, Bins, EMPTY, Fixed, INVALID, Setup, Splat, to_fixed};

/// Largest image side, in pixels.
pub const MAX_SIDE: usize = 16_384;
/// Largest supersampling factor per axis.
pub const MAX_SUPERSAMPLE: usize = 4;
/// Output rows per band (one rayon task each).
const BAND_PIXELS: usize = 16;
/// Smallest and largest automatic point diameter, in pixels.
const AUTO_DIAMETER: (f64, f64) = (1.0, 24.0);
/// Surface colour when no scalar colours the geometry: a light, slightly cool grey (sRGB).
const SURFACE_SRGB: [f64; 3] = [0.80, 0.81, 0.84];
/// Entries of the linear-to-sRGB output table.
const ENCODE_LEN: usize = 4096;

/// What to draw: vertices with optional attributes, and triangles over them. Without
/// triangles the vertices are drawn as splats.
#[derive(Clone, Copy, Debug)]
pub struct Scene<'a> {
    /// Vertex positions.
    pub positions: &'a [DVec3],
    /// Triangles as vertex indices; empty for a point cloud.
    pub triangles: &'a [[u32; 3]],
    /// Per-vertex normals (any length, any orientation).
    pub normals: Option<&'a [DVec3]>,
    /// Per-vertex ball radii: a sphere set, drawn as balls of these radii.
    pub radii: Option<&'a [f64]>,
    /// Per-vertex values to colour by.
    pub scalars: Option<&'a [f64]>,
    /// Per-vertex sRGB colours (a scan's own), drawn when there are no `scalars`.
    pub colors: Option<&'a [[u8; 3]]>,
}

/// How triangle normals are chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shading {
    /// One normal per triangle: shows the facets.
    Flat,
    /// Normals interpolated from the vertices: the file's normals, or area-weighted
    /// averages of the face normals when the file has none.
    Smooth,
}

/// What is behind the geometry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Background {
    /// An opaque sRGB colour.
    Colour([u8; 3]),
    /// Nothing: the PNG gets an alpha channel.
    Transparent,
}

/// Everything about the picture except the scene. Set the fields you need in a struct
/// literal and take the rest from `..RenderOptions::default()`.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Direction of view.
    pub view: ViewAngles,
    /// World axis drawn upwards.
    pub up: UpAxis,
    /// Orthographic or perspective.
    pub projection: Projection,
    /// Samples per pixel along each axis (2 gives 2×2 anti-aliasing).
    pub supersample: usize,
    /// Flat or smooth triangles.
    pub shading: Shading,
    /// Splat diameter in pixels for point clouds; `None` picks one from the point density.
    pub point_diameter: Option<f64>,
    /// Background.
    pub background: Background,
    /// Values mapped to the ends of the colour map; `None` uses the range of the values.
    pub colour_range: Option<(f64, f64)>,
    /// Draw a labelled colour bar when colouring by a scalar (if the image is large enough).
    pub colour_bar: bool,
}

impl Default for RenderOptions {
    fn default() -> RenderOptions {
        RenderOptions {
            width: 1200,
            height: 900,
            view: ViewAngles {
                azimuth: 45.0,
                elevation: 35.264_389_682_754_654,
            },
            up: UpAxis::Y,
            projection: Projection::Orthographic,
            supersample: 2,
            shading: Shading::Smooth,
            point_diameter: None,
            background: Background::Colour([255, 255, 255]),
            colour_range: None,
            colour_bar: true,
        }
    }
}

/// Why a scene could not be drawn.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// The image size is out of range.
    #[error("image size {width}x{height}: each side must be between 1 and {MAX_SIDE} pixels")]
    Size {
        /// Requested width.
        width: usize,
        /// Requested height.
        height: usize,
    },
    /// The supersampling factor is out of range.
    #[error("supersampling {0}: must be between 1 and {MAX_SUPERSAMPLE}")]
    Supersample(usize),
    /// The point diameter is not a positive number.
    #[error("point size {0}: must be a positive number of pixels")]
    PointDiameter(f64),
    /// No vertex can be placed in the image.
    #[error("nothing to draw: no vertex has finite coordinates")]
    Empty,
    /// An attribute array or a triangle does not match the vertices.
    #[error("inconsistent scene: {0}")]
    Inconsistent(String),
    /// Colouring by a scalar of which no value is finite.
    #[error("the values to colour by are all NaN or infinite")]
    NoFiniteValue,
    /// The colour range is not two finite numbers in order.
    #[error("colour range {0}..{1}: needs two finite numbers, the first not above the second")]
    ColourRange(f64, f64),
    /// More primitives than 32-bit identifiers reach.
    #[error("{0} primitives are more than the renderer's 32-bit identifiers reach")]
    TooMany(usize),
}

/// A rendered picture and what was drawn.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct Rendered {
    /// The picture.
    pub image: Image,
    /// Triangles drawn (with area, in front of the camera, spanning a row of samples).
    pub triangles: usize,
    /// Points drawn as splats.
    pub splats: usize,
    /// Splat diameter used, in pixels (point clouds without radii).
    pub point_diameter: Option<f64>,
    /// Values at the ends of the colour map, when colouring by a scalar.
    pub colour_range: Option<(f64, f64)>,
    /// Whether the colour bar fit in the image.
    pub colour_bar: bool,
    /// The camera the picture was drawn with: [`Camera::project`] places further points in
    /// it, in output pixels.
    pub camera: Camera,
}

/// Everything the bands share.
struct Frame<'a> {
    scene: Scene<'a>,
    camera: Camera,
    light: DVec3,
    ss: usize,
    width_s: usize,
    height_s: usize,
    fixed: Vec<Fixed>,
    keys: Vec<f64>,
    /// 1/distance per vertex (perspective-correct interpolation); empty for orthographic.
    inv_distance: Vec<f64>,
    normals: Option<Vec<DVec3>>,
    splats: Vec<Splat>,
    scale: Option<ColourScale>,
    /// The scene's colours in linear light, when they are drawn.
    colors: Option<Vec<[f32; 3]>>,
    surface: [f32; 3],
    background: [f32; 3],
    transparent: bool,
    encode: Vec<u8>,
}

/// Draws a scene.
pub fn render(scene: &Scene<'_>, options: &RenderOptions) -> Result<Rendered, RenderError> {
    check(scene, options)?;
    let (width, height, ss) = (options.width, options.height, options.supersample);
    let scale = match scene.scalars {
        None => None,
        Some(values) => {
            let (low, high) = match options.colour_range {
                Some(range) => range,
                None => ColourScale::range_of(values).ok_or(RenderError::NoFiniteValue)?,
            };
            Some(ColourScale::new(low, high))
        }
    };
    let bar = match &scale {
        Some(s) if options.colour_bar => ColourBar::layout(width, height, s),
        _ => None,
    };
    let viewport = Viewport {
        x: 0.0,
        y: 0.0,
        width: (width - bar.as_ref().map_or(0, |b| b.strip_width)) as f64,
        height: height as f64,
    };
    let mesh = !scene.triangles.is_empty();
    let ball_radii = if mesh { None } else { scene.radii };
    let camera = Camera::fit(
        scene.positions,
        ball_radii,
        options.view,
        options.up,
        options.projection,
        viewport,
    )
    .ok_or(RenderError::Empty)?;
    let light = shading::light_direction(camera.toward_viewer, camera.right, camera.up);

    let projected: Vec<Projected> = scene
        .positions
        .par_iter()
        .map(|&p| camera.project(p))
        .collect();
    let sf = ss as f64;
    let usable = |i: usize| {
        let q = &projected[i];
        scene.positions[i].is_finite() && camera.in_front(q.distance)
    };
    let fixed: Vec<Fixed> = (0..projected.len())
        .into_par_iter()
        .map(|i| {
            if usable(i) {
                to_fixed(projected[i].x * sf, projected[i].y * sf)
            } else {
                INVALID
            }
        })
        .collect();
    let keys: Vec<f64> = projected
        .par_iter()
        .map(|q| camera.depth_key(q.distance))
        .collect();
    let inv_distance = if camera.is_perspective() {
        projected.par_iter().map(|q| 1.0 / q.distance).collect()
    } else {
        Vec::new()
    };

    let normals = match (mesh, options.shading, scene.normals) {
        (true, Shading::Flat, _) => None,
        (true, Shading::Smooth, Some(n)) => Some(n.to_vec()),
        (true, Shading::Smooth, None) => Some(sphcover_core::vertex_normals(
            scene.positions,
            scene.triangles,
        )),
        (false, _, n) => n.map(<[DVec3]>::to_vec),
    };

    let mut point_diameter = None;
    let splats = if mesh {
        Vec::new()
    } else {
        let diameter = match (scene.radii, options.point_diameter) {
            (Some(_), _) => None,
            (None, Some(d)) => Some(d),
            (None, None) => Some(auto_diameter(&projected, &fixed)),
        };
        point_diameter = diameter;
        (0..projected.len())
            .into_par_iter()
            .map(|i| {
                let q = projected[i];
                let (pixels, depth_radius) = match (scene.radii, diameter) {
                    (Some(r), _) => (r[i].abs() * camera.pixels_per_unit(q.distance), r[i].abs()),
                    (None, Some(d)) => (0.5 * d, 0.5 * d / camera.pixels_per_unit(q.distance)),
                    (None, None) => (0.0, 0.0),
                };
                let radius = if fixed[i] == INVALID || !pixels.is_finite() {
                    0.0
                } else {
                    pixels * sf
                };
                Splat {
                    x: q.x * sf,
                    y: q.y * sf,
                    radius,
                    distance: q.distance,
                    depth_radius,
                }
            })
            .collect()
    };

    let (background, transparent) = match options.background {
        Background::Colour(c) => (
            c.map(|v| srgb_to_linear(f64::from(v) / 255.0) as f32),
            false,
        ),
        Background::Transparent => ([0.0; 3], true),
    };
    let frame = Frame {
        scene: *scene,
        camera,
        light,
        ss,
        width_s: width * ss,
        height_s: height * ss,
        fixed,
        keys,
        inv_distance,
        normals,
        splats,
        colors: scene.colors.filter(|_| scale.is_none()).map(|colors| {
            colors
                .par_iter()
                .map(|c| c.map(|v| srgb_to_linear(f64::from(v) / 255.0) as f32))
                .collect()
        }),
        scale,
        surface: SURFACE_SRGB.map(|c| srgb_to_linear(c) as f32),
        background,
        transparent,
        encode: (0..ENCODE_LEN)
            .map(|i| (linear_to_srgb(i as f64 / (ENCODE_LEN - 1) as f64) * 255.0).round() as u8)
            .collect(),
    };

    let band_rows = BAND_PIXELS * ss;
    let setups = |t: usize| {
        let [a, b, c] = scene.triangles[t];
        Setup::new([
            frame.fixed[a as usize],
            frame.fixed[b as usize],
            frame.fixed[c as usize],
        ])
    };
    let bins = if mesh {
        Bins::build(scene.triangles.len(), band_rows, frame.height_s, |t| {
            setups(t).map(|s| {
                let b = s.sample_box();
                (b[1], b[3])
            })
        })
    } else {
        Bins::build(frame.splats.len(), band_rows, frame.height_s, |k| {
            frame.splats[k].rows()
        })
    };
    let drawn = bins.drawn;

    let mut image = Image::new(width, height, [0, 0, 0, 0]);
    image
        .rgba
        .par_chunks_mut(4 * width * BAND_PIXELS)
        .enumerate()
        .for_each(|(b, pixels)| {
            let rows = band_rows.min(frame.height_s - b * band_rows);
            let mut band = Band::new(b * band_rows, rows, frame.width_s);
            for &k in bins.band(b) {
                if mesh {
                    if let Some(setup) = setups(k as usize) {
                        let [a, bb, c] = scene.triangles[k as usize];
                        let keys = [
                            frame.keys[a as usize],
                            frame.keys[bb as usize],
                            frame.keys[c as usize],
                        ];
                        band.triangle(k, &setup, keys);
                    }
                } else {
                    band.splat(k, &frame.splats[k as usize], |d| frame.camera.depth_key(d));
                }
            }
            frame.resolve(&band, pixels, mesh);
        });

    if let Some(bar) = &bar {
        let ink = match options.background {
            Background::Colour(c)
                if 0.2126 * f64::from(c[0])
                    + 0.7152 * f64::from(c[1])
                    + 0.0722 * f64::from(c[2])
                    < 110.0 =>
            {
                [235, 235, 235]
            }
            _ => [30, 30, 30],
        };
        bar.draw(&mut image, ink);
    }
    Ok(Rendered {
        image,
        triangles: if mesh { drawn } else { 0 },
        splats: if mesh { 0 } else { drawn },
        point_diameter,
        colour_range: frame.scale.as_ref().map(|s| (s.low, s.high)),
        colour_bar: bar.is_some(),
        camera: frame.camera,
    })
}

/// Refuses options and scenes the renderer cannot draw.
fn check(scene: &Scene<'_>, options: &RenderOptions) -> Result<(), RenderError> {
    let (w, h) = (options.width, options.height);
    if !(1..=MAX_SIDE).contains(&w) || !(1..=MAX_SIDE).contains(&h) {
        return Err(RenderError::Size {
            width: w,
            height: h,
        });
    }
    if !(1..=MAX_SUPERSAMPLE).contains(&options.supersample) {
        return Err(RenderError::Supersample(options.supersample));
    }
    if let Some(d) = options.point_diameter
        && !(d.is_finite() && d > 0.0)
    {
        return Err(RenderError::PointDiameter(d));
    }
    if let Some((lo, hi)) = options.colour_range
        && !(lo.is_finite() && hi.is_finite() && lo <= hi)
    {
        return Err(RenderError::ColourRange(lo, hi));
    }
    let n = scene.positions.len();
    if n == 0 {
        return Err(RenderError::Empty);
    }
    for (name, len) in [
        ("normals", scene.normals.map(<[_]>::len)),
        ("radii", scene.radii.map(<[_]>::len)),
        ("values", scene.scalars.map(<[_]>::len)),
        ("colours", scene.colors.map(<[_]>::len)),
    ] {
        if let Some(len) = len
            && len != n
        {
            return Err(RenderError::Inconsistent(format!(
                "{len} {name} for {n} vertices"
            )));
        }
    }
    let primitives = if scene.triangles.is_empty() {
        n
    } else {
        scene.triangles.len()
    };
    if primitives >= EMPTY as usize {
        return Err(RenderError::TooMany(primitives));
    }
    if let Some(t) = scene
        .triangles
        .par_iter()
        .position_first(|t| t.iter().any(|&v| v as usize >= n))
    {
        return Err(RenderError::Inconsistent(format!(
            "triangle {t} refers to a vertex beyond the {n} vertices"
        )));
    }
    Ok(())
}

/// A splat diameter that closes the gaps between neighbouring points of a scanned surface:
/// points spread evenly over a closed surface whose silhouette fills their image box lie
/// about √(π·area/n) pixels apart; scans are not even, so the splats are made half as
/// large again.
fn auto_diameter(projected: &[Projected], fixed: &[Fixed]) -> f64 {
    let inside: Vec<usize> = (0..projected.len())
        .filter(|&i| fixed[i] != INVALID)
        .collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &i in &inside {
        let q = projected[i];
        lo = [lo[0].min(q.x), lo[1].min(q.y)];
        hi = [hi[0].max(q.x), hi[1].max(q.y)];
    }
    let area = ((hi[0] - lo[0]).max(1.0)) * ((hi[1] - lo[1]).max(1.0));
    let d = 1.5 * (std::f64::consts::PI * area / inside.len().max(1) as f64).sqrt();
    if d.is_finite() {
        d.clamp(AUTO_DIAMETER.0, AUTO_DIAMETER.1)
    } else {
        AUTO_DIAMETER.0
    }
}

impl Frame<'_> {
    /// Shades the samples of a band and averages them into its output pixels. Each
    /// primitive seen in a pixel is shaded once, at the mean of its samples there, and
    /// weighted by their number: shading varies slowly across a pixel, and interior pixels
    /// (one primitive for all samples) then cost one shading instead of ss².
    fn resolve(&self, band: &Band, pixels: &mut [u8], mesh: bool) {
        let ss = self.ss;
        let width = self.width_s / ss;
        let out_rows = band.rows / ss;
        let samples = (ss * ss) as f32;
        // (primitive, samples, sum of sample x, sum of sample y)
        let mut seen: Vec<(u32, u32, usize, usize)> = Vec::with_capacity(ss * ss);
        for y in 0..out_rows {
            for x in 0..width {
                seen.clear();
                for sy in 0..ss {
                    let j = y * ss + sy;
                    for sx in 0..ss {
                        let i = x * ss + sx;
                        let id = band.id[j * band.width + i];
                        if id == EMPTY {
                            continue;
                        }
                        match seen.iter_mut().find(|s| s.0 == id) {
                            Some(s) => {
                                s.1 += 1;
                                s.2 += i;
                                s.3 += band.y0 + j;
                            }
                            None => seen.push((id, 1, i, band.y0 + j)),
                        }
                    }
                }
                let mut sum = [0.0f32; 3];
                let mut hits = 0u32;
                for &(id, n, sx, sy) in &seen {
                    let (cx, cy) = (
                        sx as f64 / f64::from(n) + 0.5,
                        sy as f64 / f64::from(n) + 0.5,
                    );
                    let c = if mesh {
                        self.shade_triangle(id as usize, cx, cy)
                    } else {
                        self.shade_splat(id as usize, cx, cy)
                    };
                    for k in 0..3 {
                        sum[k] += c[k] * n as f32;
                    }
                    hits += n;
                }
                let out = &mut pixels[4 * (y * width + x)..4 * (y * width + x) + 4];
                let (rgb, alpha) = if self.transparent {
                    if hits == 0 {
                        ([0.0; 3], 0.0)
                    } else {
                        (sum.map(|s| s / hits as f32), hits as f32 / samples)
                    }
                } else {
                    let empty = (ss * ss) as u32 - hits;
                    let mut rgb = [0.0; 3];
                    for k in 0..3 {
                        rgb[k] = (sum[k] + empty as f32 * self.background[k]) / samples;
                    }
                    (rgb, 1.0)
                };
                for k in 0..3 {
                    out[k] = self.encode_linear(rgb[k]);
                }
                out[3] = (alpha * 255.0).round() as u8;
            }
        }
    }

    #[inline]
    fn encode_linear(&self, c: f32) -> u8 {
        let i = (c.clamp(0.0, 1.0) * (ENCODE_LEN - 1) as f32).round() as usize;
        self.encode[i]
    }

    /// Colour of a triangle at a position in samples, linear light.
    fn shade_triangle(&self, t: usize, x: f64, y: f64) -> [f32; 3] {
        let tri = self.scene.triangles[t];
        let corners = tri.map(|v| self.fixed[v as usize]);
        let Some(setup) = Setup::new(corners) else {
            return self.surface;
        };
        let mut w = setup.weights_at_point(to_fixed(x, y));
        if !self.inv_distance.is_empty() {
            // Perspective-correct: weights of 1/distance, renormalised.
            let mut sum = 0.0;
            for k in 0..3 {
                w[k] *= self.inv_distance[tri[k] as usize];
                sum += w[k];
            }
            if sum != 0.0 {
                w = w.map(|x| x / sum);
            }
        }
        let face = || {
            let [a, b, c] = tri.map(|v| self.scene.positions[v as usize]);
            (b - a).cross(c - a).normalize_or_zero()
        };
        let normal = match &self.normals {
            Some(n) => {
                let v = (0..3).fold(DVec3::ZERO, |acc, k| acc + w[k] * n[tri[k] as usize]);
                let v = v.normalize_or_zero();
                if v == DVec3::ZERO { face() } else { v }
            }
            None => face(),
        };
        let base = match (&self.scale, self.scene.scalars, &self.colors) {
            (Some(scale), Some(values), _) => {
                let v = (0..3).fold(0.0, |acc, k| acc + w[k] * values[tri[k] as usize]);
                scale.linear(v)
            }
            // Blended in linear light, as the shading is.
            (_, _, Some(colors)) => (0..3).fold([0.0; 3], |acc, k| {
                let c = colors[tri[k] as usize];
                std::array::from_fn(|j| acc[j] + w[k] as f32 * c[j])
            }),
            _ => self.surface,
        };
        let light = shading::lambert(normal, self.light) as f32;
        base.map(|c| c * light)
    }

    /// Colour of a splat at a position in samples, linear light: lit by the point's normal
    /// when it has one, else as the sphere it stands for.
    fn shade_splat(&self, k: usize, x: f64, y: f64) -> [f32; 3] {
        let splat = &self.splats[k];
        let (dx, dy) = splat.offset_at_point(x, y);
        let given = self
            .normals
            .as_ref()
            .filter(|_| self.scene.radii.is_none())
            .map(|n| n[k].normalize_or_zero())
            .filter(|n| *n != DVec3::ZERO && n.is_finite());
        let normal = given.unwrap_or_else(|| {
            let c = &self.camera;
            let q = (dx * dx + dy * dy).min(1.0);
            (dx * c.right - dy * c.up + (1.0 - q).sqrt() * c.toward_viewer).normalize_or_zero()
        });
        let base = match (&self.scale, self.scene.scalars, &self.colors) {
            (Some(scale), Some(values), _) => scale.linear(values[k]),
            (_, _, Some(colors)) => colors[k],
            _ => self.surface,
        };
        let light = shading::lambert(normal, self.light) as f32;
        base.map(|c| c * light)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UV sphere of radius `r` with poles on ±y and equator vertices on ±x and ±z.
    fn uv_sphere(r: f64, stacks: usize, slices: usize) -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let mesh = sphcover_core::synthetic::uv_sphere(r, stacks, slices);
        (mesh.vertices, mesh.triangles)
    }

    fn coverage(image: &Image) -> f64 {
        image
            .rgba
            .chunks_exact(4)
            .map(|p| p[3] as f64 / 255.0)
            .sum()
    }

    fn options() -> RenderOptions {
        RenderOptions {
            width: 200,
            height: 160,
            view: ViewAngles::parse("front").unwrap(),
            background: Background::Transparent,
            ..RenderOptions::default()
        }
    }

    #[test]
    fn a_sphere_covers_its_disc() {
        let (positions, triangles) = uv_sphere(2.0, 48, 96);
        let scene = Scene {
            positions: &positions,
            triangles: &triangles,
            normals: None,
            radii: None,
            scalars: None,
            colors: None,
        };
        let out = render(&scene, &options()).unwrap();
        let r = 0.5 * 160.0 * (1.0 - 2.0 * camera::MARGIN);
        let disc = std::f64::consts::PI * r * r;
        let covered = coverage(&out.image);
        assert!((covered - disc).abs() < 0.01 * disc, "{covered} vs {disc}");
        assert!(out.triangles > triangles.len() / 2 && out.triangles <= triangles.len());
    }

    #[test]
    fn vertex_colours_are_drawn_unless_values_are() {
        // Red on the left half of the sphere, blue on the right, seen from the front (+z).
        let (positions, triangles) = uv_sphere(1.0, 24, 48);
        let colors: Vec<[u8; 3]> = positions
            .iter()
            .map(|p| {
                if p.x < 0.0 {
                    [230, 20, 20]
                } else {
                    [20, 20, 230]
                }
            })
            .collect();
        let scene = Scene {
            positions: &positions,
            triangles: &triangles,
            normals: None,
            radii: None,
            scalars: None,
            colors: Some(&colors),
        };
        let front = RenderOptions {
            view: ViewAngles::parse("front").unwrap(),
            ..options()
        };
        let image = render(&scene, &front).unwrap().image;
        let (w, h) = (image.width, image.height);
        let [r, g, b, _] = image.get(w / 2 - w / 8, h / 2);
        assert!(r > 2 * b && r > 2 * g, "left {r} {g} {b}");
        let [r, g, b, _] = image.get(w / 2 + w / 8, h / 2);
        assert!(b > 2 * r && b > 2 * g, "right {r} {g} {b}");
        let points = Scene {
            triangles: &[],
            ..scene
        };
        let [r, _, b, _] = render(&points, &front)
            .unwrap()
            .image
            .get(w / 2 - w / 8, h / 2);
        assert!(r > 2 * b, "splat {r} {b}");

        let x: Vec<f64> = positions.iter().map(|p| p.x).collect();
        let by_value = Scene {
            scalars: Some(&x),
            ..scene
        };
        let plain = Scene {
            colors: None,
            ..by_value
        };
        assert_eq!(
            render(&by_value, &front).unwrap().image,
            render(&plain, &front).unwrap().image
        );
        let short = Scene {
            colors: Some(&colors[1..]),
            ..scene
        };
        assert!(matches!(
            render(&short, &front),
            Err(RenderError::Inconsistent(_))
        ));
    }

    #[test]
    fn output_does_not_depend_on_the_thread_count() {
        let (positions, triangles) = uv_sphere(1.0, 20, 40);
        let scalars: Vec<f64> = positions.iter().map(|p| p.x * p.y).collect();
        let scene = Scene {
            positions: &positions,
            triangles: &triangles,
            normals: None,
            radii: None,
            scalars: Some(&scalars),
            colors: None,
        };
        let opts = RenderOptions {
            view: ViewAngles::parse("iso").unwrap(),
            projection: Projection::Perspective { fov_deg: 35.0 },
            ..options()
        };
        let run = |threads: usize| {
            sphcover_core::on_threads(threads, || render(&scene, &opts).unwrap().image)
        };
        let one = run(1);
        assert_eq!(one, run(3));
        let points = Scene {
            triangles: &[],
            ..scene
        };
        let run_points = |threads: usize| {
            sphcover_core::on_threads(threads, || render(&points, &opts).unwrap().image)
        };
        assert_eq!(run_points(1), run_points(4));
    }

    #[test]
    fn balls_are_drawn_at_their_radius() {
        // Two balls side by side; the fit makes the pair span the viewport width.
        let positions = [DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0)];
        let radii = [1.0, 1.0];
        let scene = Scene {
            positions: &positions,
            triangles: &[],
            normals: None,
            radii: Some(&radii),
            scalars: None,
            colors: None,
        };
        let opts = RenderOptions {
            width: 200,
            height: 200,
            ..options()
        };
        let out = render(&scene, &opts).unwrap();
        let r = 0.25 * 200.0 * (1.0 - 2.0 * camera::MARGIN);
        let discs = 2.0 * std::f64::consts::PI * r * r;
        let covered = coverage(&out.image);
        assert!(
            (covered - discs).abs() < 0.02 * discs,
            "{covered} vs {discs}"
        );
    }

    #[test]
    fn bad_scenes_and_options_are_refused() {
        let positions = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let scene = Scene {
            positions: &positions,
            triangles: &[[0, 1, 3]],
            normals: None,
            radii: None,
            scalars: None,
            colors: None,
        };
        assert!(matches!(
            render(&scene, &options()),
            Err(RenderError::Inconsistent(_))
        ));
        let scene = Scene {
            triangles: &[[0, 1, 2]],
            ..scene
        };
        for bad in [
            RenderOptions {
                width: 0,
                ..options()
            },
            RenderOptions {
                supersample: 9,
                ..options()
            },
            RenderOptions {
                point_diameter: Some(f64::NAN),
                ..options()
            },
            RenderOptions {
                colour_range: Some((2.0, 1.0)),
                ..options()
            },
        ] {
            assert!(render(&scene, &bad).is_err(), "{bad:?}");
        }
        let nan = [f64::NAN; 3];
        let coloured = Scene {
            scalars: Some(&nan),
            ..scene
        };
        assert_eq!(
            render(&coloured, &options()).unwrap_err(),
            RenderError::NoFiniteValue
        );
        let empty = Scene {
            positions: &[DVec3::NAN],
            triangles: &[],
            ..scene
        };
        assert_eq!(render(&empty, &options()).unwrap_err(), RenderError::Empty);
    }
}
