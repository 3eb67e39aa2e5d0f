//! Command-line arguments.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// Processing of scanned geometry with spherically supported functions.
#[derive(Debug, Parser)]
#[command(name = "sphcover", version, about, long_about = None)]
pub struct Cli {
    #[command(flatten)]
    pub global: GlobalArgs,
    #[command(subcommand)]
    pub command: Command,
}

/// Options every subcommand takes.
#[derive(Debug, Args)]
pub struct GlobalArgs {
    /// Worker threads (default: one per core). Output does not depend on it.
    #[arg(long, global = true, value_name = "N")]
    pub threads: Option<usize>,
    /// Print per-stage timings and counts to stderr.
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub verbose: u8,
    /// Print nothing but errors; no progress bars.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    pub quiet: bool,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Report what a geometry file holds: counts, bounding box, attributes, normals, non-finite values.
    Info(InfoArgs),
    /// Reconstruct a surface mesh from scanned points (oriented or not), robust to noise and outliers.
    Recon(ReconArgs),
    /// Extract the skeletal sheet (mid-surface) of a thin part from a CT volume.
    Skeleton(SkeletonArgs),
    /// Build a spherical cover of oriented scan points or of a CT volume.
    Cover(CoverArgs),
    /// Build the tetrahedral mesh of a cover: the dual complex of its union of balls.
    Tetra(TetraArgs),
    /// Draw a mesh, point cloud or sphere set to a PNG (software rasteriser, no display needed).
    Render(RenderArgs),
}

/// Arguments of `sphcover info`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// Files to inspect (PLY, OBJ, OFF, STL, XYZ/PWN, sphere sets).
    #[arg(required = true, value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// Print the report as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub memory: ReadMemoryArgs,
}

/// Arguments of `sphcover tetra`.
#[derive(Debug, Args)]
pub struct TetraArgs {
    /// A sphere set (`x y z r` text, or PLY with a `radius` vertex property).
    #[arg(value_name = "SPHERES")]
    pub spheres: PathBuf,
    /// Output: `.vtk` (VTK legacy unstructured grid, opens in ParaView), `.vtu` (VTK XML) or `.txt`/`.tets`
    /// (one tetrahedron per line as four ascending support indices, rows sorted).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Radius factor σ_t applied before triangulating (thesis §3.5.2): below 1 it avoids
    /// skinny tetrahedra near the boundary and hides fewer small spheres.
    #[arg(long, default_value_t = 0.75, value_name = "S")]
    pub shrink: f64,
    /// Seed of the insertion order and point-location walks (the mesh does not depend on it).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[command(flatten)]
    pub read: InputArgs,
    #[command(flatten)]
    pub memory: ReadMemoryArgs,
}

/// Reconstruction methods of `sphcover recon`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ReconMethodArg {
    /// Cover, graph cut against outliers, diffusion against noise, polygonisation (default).
    Integrated,
    /// Graph cut on the tetrahedral mesh, marching tetrahedra on the labels (thesis §5.2.2).
    Graphcut,
    /// Cover, diffusion, polygonisation (no graph cut).
    Diffusion,
    /// The plain partition-of-unity function of the cover.
    Pu,
}

/// Arguments of `sphcover recon`.
#[derive(Debug, Args)]
pub struct ReconArgs {
    /// Scanned points: PLY, OBJ, OFF, STL, XYZ/PWN, LAS/LAZ; with normals or without (they are
    /// then estimated); a PLY `confidence` property is used as the scanner's confidence.
    #[arg(value_name = "INPUT")]
    pub input: PathBuf,
    /// Output mesh (PLY keeps the per-vertex confidence as `quality`, which MeshLab shows;
    /// `.vtp`/`.vtu` for ParaView; OBJ, OFF, STL).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Cover tolerance ε, relative to the longest bounding-box edge (default 2.5e-3). A given
    /// ε is used as given (with a warning when it lies below 4× the measured noise).
    #[arg(long, value_name = "E")]
    pub eps: Option<f64>,
    /// How ε follows the scan's noise: auto (at least 4× the measured noise; the default
    /// without --eps), off (ε as given; the default with --eps), or the noise σ relative to
    /// the longest bounding-box edge (at least 4× that).
    #[arg(long, value_name = "auto|off|SIGMA", allow_hyphen_values = true)]
    pub noise: Option<String>,
    /// Pipeline.
    #[arg(long, value_enum, default_value_t = ReconMethodArg::Integrated)]
    pub method: ReconMethodArg,
    /// Graph-cut ratio k of terminal to edge cost (default 28 on the sphere intersection
    /// graph, 5 for --method graphcut).
    #[arg(long, value_name = "K")]
    pub k: Option<f64>,
    /// Remove surface far from every sample: farther than 3 sample spacings, or than D
    /// (relative to the longest bounding-box edge) when given. `--trim off` keeps everything:
    /// a closed surface, extrapolated where the scan is open. Default: cut away the regions
    /// the scanner never saw (surface farther than 3 spacings from every sample, in regions
    /// that reach farther than 6% of the diagonal) along the line 3 spacings from the
    /// samples, and close smaller holes; a scan of one view (normals facing one side) is cut
    /// at one spacing and keeps only pinholes.
    #[arg(long, value_name = "D", num_args = 0..=1, default_missing_value = "auto")]
    pub trim: Option<String>,
    /// Polygonisation grid: step = longest edge / 2^DEPTH (default from the point count,
    /// 6..=10).
    #[arg(long, value_name = "DEPTH")]
    pub depth: Option<u32>,
    /// Diffusion: strength of the fit to the samples' normals (relative; 0 ignores the
    /// normals, for very noisy ones).
    #[arg(long, value_name = "MU")]
    pub normal_fit: Option<f64>,
    /// Diffusion: strength of the fit to the samples' positions (relative).
    #[arg(long, value_name = "MU")]
    pub position_fit: Option<f64>,
    /// Neighbours for normal estimation of unoriented input (3 to 500).
    #[arg(
        long,
        visible_alias = "normal-neighbors",
        default_value_t = 12,
        value_name = "N"
    )]
    pub normal_neighbours: usize,
    /// Estimate normals even when the input has them (for unreliable normals).
    #[arg(long)]
    pub estimate_normals: bool,
    /// Keep the vertices on the function's zero set instead of moving them onto quadrics
    /// fitted to the samples near them (the thesis's surface; less accurate on clean scans).
    #[arg(long)]
    pub no_refine: bool,
    /// Keep the tunnels one or two grid cells wide that thin walls can get at the grid's
    /// scale, instead of filling them (see docs/algorithms.md, Surface reconstruction).
    #[arg(long)]
    pub keep_pinholes: bool,
    /// Seed of the random choices (cover expansion order).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Build the cover and its function in N×N×N tiles (or NX,NY,NZ), one after the other,
    /// each from the samples of its box and a halo; the surface is meshed once from the
    /// tiles' functions, without seams. For scans whose cover would not fit in memory.
    #[arg(long, value_name = "N|NX,NY,NZ", value_parser = parse_tiles)]
    pub tiles: Option<[usize; 3]>,
    /// With --tiles: how far beyond its box a tile takes samples, relative to the longest
    /// bounding-box edge (default: a fifth of a tile's width, at most 0.1).
    #[arg(long, value_name = "H", requires = "tiles")]
    pub halo: Option<f64>,
    /// With --tiles: read the scan from its file a block at a time into tile files, and make
    /// every pass over the samples one tile at a time, so that memory holds one tile's
    /// samples and the surface, not the whole scan. Binary PLY, LAS and LAZ are streamed;
    /// other formats are read whole first. Normals the scan lacks are estimated tile by
    /// tile and oriented by those of a subsample of the whole scan.
    #[arg(long, requires = "tiles")]
    pub stream: bool,
    /// With --stream: where the tile files go (a directory made inside it is removed at the
    /// end; default: the output's directory). They take about 1.5-3 times the size of the
    /// scan's points and normals in doubles.
    #[arg(long, value_name = "DIR", requires = "stream")]
    pub scratch: Option<PathBuf>,
    /// Also write the input points with their confidence and outlier label (PLY
    /// properties `confidence` and `quality` = 1 for outliers).
    #[arg(long, value_name = "FILE")]
    pub points_out: Option<PathBuf>,
    /// Also write the final cover (cover PLY, readable by `sphcover tetra` and the library).
    #[arg(long, value_name = "FILE")]
    pub cover_out: Option<PathBuf>,
    /// Also write the report (counts, timings) as JSON.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Memory budget (e.g. 2G, 500M): before reconstructing, predict the peak from the
    /// point count and depth; over budget, use the finest coarser depth that fits (without
    /// --depth), or refuse with the estimate (exit 2). Once the cover's graph is built the
    /// peak is predicted again (a cover refined to the sampling, as thin walls and sharp edges
    /// make it, can need several times the first estimate), against this budget or, without
    /// it, the default limit: over it, the run stops with the cover's size and the remedies.
    /// Reading the points is held to it too (default: 60% of the machine's memory).
    #[arg(long, value_name = "SIZE", value_parser = sphcover_core::io::parse_byte_size)]
    pub max_memory: Option<u64>,
    #[command(flatten)]
    pub read: InputArgs,
}

/// `--tiles N` or `--tiles NX,NY,NZ`.
fn parse_tiles(text: &str) -> Result<[usize; 3], String> {
    let counts: Vec<usize> = text
        .split(',')
        .map(|n| n.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{text}: give N or NX,NY,NZ, whole numbers of tiles"))?;
    let tiles = match counts[..] {
        [n] => [n; 3],
        [x, y, z] => [x, y, z],
        _ => return Err(format!("{text}: give N or NX,NY,NZ tiles")),
    };
    if tiles.contains(&0) {
        return Err(format!("{text}: at least one tile along each axis"));
    }
    Ok(tiles)
}

/// Arguments of `sphcover cover`.
#[derive(Debug, Args)]
pub struct CoverArgs {
    /// Oriented points (PLY, OBJ, OFF, STL, XYZ/PWN with normals) for a surface cover, or a
    /// NIfTI volume (`.nii`, `.nii.gz`) for a volume cover.
    #[arg(value_name = "INPUT")]
    pub input: PathBuf,
    /// Output cover file (PLY: centres, radii and local-function coefficients).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Error tolerance ε. Surfaces: the largest |g| of a support's fit over its points, in
    /// units of the longest bounding-box edge (default 2.5e-3). Volumes: the RMS fit error
    /// as a fraction of the value range (default 0.05).
    #[arg(long, value_name = "E")]
    pub eps: Option<f64>,
    /// Volumes: the object is where the value exceeds T, in the file's own units (HU for
    /// CT). Default: the midpoint of the value range.
    #[arg(long, value_name = "T")]
    pub threshold: Option<f64>,
    /// Volumes: linear local functions over the whole bounding box (thesis §6.2.3) instead of
    /// quadratics over the object.
    #[arg(long)]
    pub linear: bool,
    /// Scattered samples with values: the points of a PLY INPUT are volume samples off any
    /// grid, and NAME is the scalar vertex property holding their values (e.g. `intensity`).
    /// Builds a volume cover (quadratic fits, RMS tolerance, --threshold) instead of a surface
    /// cover; no normals needed.
    #[arg(long, value_name = "NAME")]
    pub value_property: Option<String>,
    /// Volumes: the order in which uncovered object points become centres.
    #[arg(long, value_enum, default_value_t = CoverCentreOrder::Random)]
    pub centre_order: CoverCentreOrder,
    /// Volumes: which redundant supports are removed after covering.
    #[arg(long, value_enum, default_value_t = CoverElimination::Corners)]
    pub elimination: CoverElimination,
    /// Seed of the random choices (expansion order, centre choice).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Write the PLY as ascii instead of binary little-endian.
    #[arg(long)]
    pub ascii: bool,
    #[command(flatten)]
    pub read: InputArgs,
    #[command(flatten)]
    pub memory: ReadMemoryArgs,
}

/// `sphcover cover --centre-order`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum CoverCentreOrder {
    /// Uniformly random among the uncovered points, from the seed (thesis §3.4.2).
    Random,
    /// Deepest inside the object first (quadratic variant only).
    Deepest,
    /// Greedy set cover: the support covering the most uncovered points next (one fit per
    /// object point: 5–20× slower, fewest supports).
    Greedy,
}

/// `sphcover cover --elimination`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum CoverElimination {
    /// Keep every support of the covering loop (the thesis' cover).
    Off,
    /// Remove supports whose object voxels all lie in other supports; points between voxel
    /// centres may then fall outside every ball.
    Centres,
    /// As `centres`, and the corners of the object voxels' cells stay covered too: no new
    /// gap in the cover.
    Corners,
}

/// How `sphcover skeleton` finds the sheet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SkeletonMethod {
    /// Ridges of the spherical cover's function on its tetrahedral mesh (thesis §6): a
    /// triangle mesh.
    Ridge,
    /// Baseline: Gaussian smoothing and non-maximum suppression on the voxel grid: points.
    Nms,
}

/// Which material of a CT `sphcover skeleton` takes the sheet of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum MaterialArg {
    /// On a CT in Hounsfield units, the first thin material of bone and tissue; otherwise
    /// two classes.
    Auto,
    /// Bone: above the soft-tissue level + 190 HU (226 HU at +36 HU).
    Bone,
    /// Tissue: above the midpoint of air and soft tissue (the skin).
    Tissue,
    /// No materials: two classes, values as they are.
    Off,
}

/// Arguments of `sphcover skeleton`.
#[derive(Debug, Args)]
pub struct SkeletonArgs {
    /// A CT volume (`.nii`, `.nii.gz`, `.inr`, `.inr.gz`) of a thin part, brighter than the
    /// background, on axis-aligned axes with voxels at most 8:1 (beyond 1.75:1 resampled along
    /// the coarse axes first); or, with `--value-property`, a PLY file of scattered samples
    /// with values.
    #[arg(value_name = "CT")]
    pub input: PathBuf,
    /// Output: the sheet as a triangle mesh (PLY, VTK XML .vtu/.vtp, OBJ, OFF, STL) in world coordinates; with
    /// `--method nms`, a point set (PLY, XYZ).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// The object is where the value exceeds T, in the file's own units (HU for CT).
    /// Default: on a CT in Hounsfield units, the threshold of the material (see
    /// --material); otherwise halfway between the median of the values below Otsu's split
    /// of the volume smoothed by one voxel and the upper quartile of those above it. On a
    /// CT a given T is windowed as a material's is (unless --material off).
    #[arg(long, value_name = "T")]
    pub threshold: Option<f64>,
    /// On a CT in Hounsfield units (recognised by its air and soft-tissue peaks), the
    /// material whose mid-surface is wanted; its values are clamped to a window around its
    /// threshold and smoothed, so that the sheet follows the middle of the material whatever
    /// lies inside it (e.g. the diploë of a skull). `auto` takes the first thin one.
    #[arg(long, value_enum, default_value_t = MaterialArg::Auto)]
    pub material: MaterialArg,
    /// Ridge method: support expansion σ for the derivatives (default 4, thesis §6.2.2).
    /// NMS method: the Gaussian's standard deviation in voxels (default 1).
    #[arg(long, value_name = "S")]
    pub sigma: Option<f64>,
    /// Fit tolerance ε of the cover as a fraction of the value range (default: from the
    /// noise level and the contrast).
    #[arg(long, value_name = "E")]
    pub eps: Option<f64>,
    /// How to find the sheet.
    #[arg(long, value_enum, default_value_t = SkeletonMethod::Ridge)]
    pub method: SkeletonMethod,
    /// Scattered samples with values: the points of a PLY INPUT are samples off any grid
    /// (e.g. a resampled or irregular CT), and NAME is the scalar vertex property holding
    /// their values. Lengths in voxels become multiples of the median distance between
    /// nearest samples.
    #[arg(long, value_name = "NAME")]
    pub value_property: Option<String>,
    /// Seed of the random choices (cover centres, triangulation order).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Also write the report (threshold, stage counts, per-stage seconds) as JSON (ridge
    /// method).
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Memory budget (e.g. 2G, 500M): refuse up front (exit 2), from the volume's header
    /// before reading its voxels, with the estimate when the predicted peak for its size
    /// exceeds it (ridge method). Reading the input is held to it too (default: 60% of the
    /// machine's memory).
    #[arg(long, value_name = "SIZE", value_parser = sphcover_core::io::parse_byte_size)]
    pub max_memory: Option<u64>,
    /// Write the PLY as ascii instead of binary little-endian.
    #[arg(long)]
    pub ascii: bool,
    #[command(flatten)]
    pub read: InputArgs,
}

/// Arguments of `sphcover render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// A mesh or point cloud (PLY, OBJ, OFF, STL, XYZ/PWN, LAS), or a sphere set or cover
    /// file (drawn as balls). A file with faces is drawn as a surface, one without as points.
    #[arg(value_name = "MESH_OR_POINTS")]
    pub input: PathBuf,
    /// Output image (`.png`).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// Direction of view: front, back, left, right, top, bottom, iso, or AZ,EL in degrees
    /// (azimuth around the up axis from the front towards the right, elevation above the
    /// horizon).
    #[arg(
        long,
        default_value = "iso",
        value_name = "VIEW",
        allow_hyphen_values = true
    )]
    pub view: String,
    /// World axis drawn upwards: x, y or z [default: y; z for LAS].
    #[arg(long, value_name = "AXIS")]
    pub up: Option<String>,
    /// Image size in pixels.
    #[arg(long, default_value = "1200x900", value_name = "WxH")]
    pub size: String,
    /// Colour by a per-vertex scalar (viridis): any scalar PLY vertex property (confidence,
    /// quality, an outlier label…), or value, radius, x, y, z for any format.
    #[arg(long, visible_alias = "color-by", value_name = "PROPERTY")]
    pub colour_by: Option<String>,
    /// Values at the ends of the colour map [default: the range of the values].
    #[arg(long, value_name = "LO,HI", allow_hyphen_values = true)]
    pub range: Option<String>,
    /// Leave out the colour bar drawn with --colour-by.
    #[arg(long, visible_alias = "no-color-bar")]
    pub no_colour_bar: bool,
    /// Draw the surface grey even when the file has vertex colours (PLY red green blue, LAS
    /// RGB), which are drawn otherwise unless --colour-by is given.
    #[arg(long, visible_alias = "ignore-colors")]
    pub ignore_colours: bool,
    /// Splat diameter of points, in pixels [default: from the point density].
    #[arg(long, value_name = "PX", allow_negative_numbers = true)]
    pub point_size: Option<f64>,
    /// Background: white, black, grey, transparent or #RRGGBB.
    #[arg(long, default_value = "white", value_name = "COLOUR")]
    pub background: String,
    /// Perspective projection with this vertical field of view (default orthographic).
    #[arg(
        long,
        value_name = "DEGREES",
        num_args = 0..=1,
        default_missing_value = "35",
        allow_negative_numbers = true
    )]
    pub perspective: Option<f64>,
    /// One normal per triangle instead of normals interpolated from the vertices.
    #[arg(long)]
    pub flat: bool,
    /// Samples per pixel along each axis, for anti-aliasing (1 to 4).
    #[arg(long, default_value_t = 2, value_name = "N")]
    pub supersample: usize,
    #[command(flatten)]
    pub read: InputArgs,
    #[command(flatten)]
    pub memory: ReadMemoryArgs,
}

/// How input files are read.
#[derive(Debug, Args)]
pub struct InputArgs {
    /// Drop vertices with NaN or infinite coordinates (with a warning) instead of refusing
    /// the file; in a volume, such voxels become background (its lowest finite value).
    #[arg(long)]
    pub drop_non_finite: bool,
}

/// The memory limit of the readers, for commands without a memory budget of their own.
#[derive(Debug, Args)]
pub struct ReadMemoryArgs {
    /// Most memory the data an input declares may take (e.g. 2G, 500M): a file declaring
    /// more is refused from its header, before anything is read (exit 2). Default: 60% of the
    /// machine's memory.
    #[arg(long, value_name = "SIZE", value_parser = sphcover_core::io::parse_byte_size)]
    pub max_memory: Option<u64>,
}

impl ReadMemoryArgs {
    /// The limit these flags ask for.
    pub fn limit(&self) -> crate::memory_limit::MemoryLimit {
        crate::memory_limit::MemoryLimit::from_flag(self.max_memory)
    }
}

impl InputArgs {
    /// The readers' options these flags ask for, under the run's memory `limit`.
    pub fn read_options(
        &self,
        limit: &crate::memory_limit::MemoryLimit,
    ) -> sphcover_core::io::ReadOptions {
        use sphcover_core::io::{NonFinitePolicy, ReadOptions};
        limit.apply(ReadOptions {
            non_finite: if self.drop_non_finite {
                NonFinitePolicy::Drop
            } else {
                NonFinitePolicy::Refuse
            },
            ..ReadOptions::default()
        })
    }
}
