//! A head-CT phantom in Hounsfield units: the clinical case of the skeleton pipeline, where
//! the thin part (the skull vault and a head-holder arc) is one material among several and
//! not the brightest against air.
//!
//! The anatomy is analytic, in millimetres, around a head centre `c`, and is described along
//! rays from `c` (unit direction `u`): the scalp is an ellipsoid, under it skin (+55 HU, 2 mm),
//! subcutaneous fat (−90 HU, 3 mm) and 1 mm of soft tissue; then the bone of the vault, whose
//! thickness `t(u)` varies from 2 mm at the temples to 8 mm at the back of the head, with
//! cortical tables (1200–1500 HU) around a diploë (400–650 HU) where it is thicker than
//! 3.2 mm; inside, a CSF layer (+8 HU), brain (+26…38 HU) and two ventricles. The vault ends
//! at the skull base, a 7 mm plate (too thick to be a sheet of the vault) with a foramen
//! magnum. Below it, two maxillary sinuses (air in 1.5 mm bone walls); in the forehead, a
//! frontal sinus splits the thickened frontal bone into two tables. Behind the head, on a
//! foam pad (−850 HU), lies a head-holder arc: a 3 mm cylindrical shell of +500 HU, apart
//! from the bone.
//!
//! The image is the partial-volume rendering of the anatomy (4 × 4 × 4 subsamples in voxels
//! where materials meet), blurred by a Gaussian point-spread function (in-plane and along z
//! apart, as a slice profile), plus Gaussian noise, rounded to whole HU as an int16 scanner
//! stores them. Voxel `(i, j, k)` is centred at `(i·pixel, j·pixel, k·slice)`.
//! Everything is deterministic for a given seed.
//!
//! [`HeadCt`] also holds what the skeleton is scored against (see `head_sheet_metrics`):
//! the material on a grid of pixel-sized cubes over the field of view (whatever the slice
//! spacing), the vault's bone thickness there, and samples of the holder's mid-surface.

use std::f64::consts::PI;
use std::path::Path;

use rand::SeedableRng;
use rand_pcg::Pcg64;
use rayon::prelude::*;
use sphcover_core::io::{self, IoError};
use sphcover_core::synthetic::{nifti_header, voxel_subsamples};
use sphcover_core::{DVec3, Volume, VoxelValues};

use crate::thin_phantoms::{blur_axis, gaussian};

/// Semi-axes of the scalp's ellipsoid at anatomy scale 1 (left–right, back–front, up), mm.
const SCALP_SEMI_AXES: DVec3 = DVec3::new(74.0, 92.0, 90.0);
/// Scalp thickness above the outer table (skin 2 + fat 3 + soft tissue 1), mm.
const SCALP: f64 = 6.0;
/// Thickness of the skull base plate, mm.
const BASE_THICKNESS: f64 = 7.0;
/// Thickness of the holder arc, mm.
const HOLDER_THICKNESS: f64 = 3.0;
/// The holder's gap to the back of the scalp (the foam pad) at anatomy scale 1, mm.
const HOLDER_GAP: f64 = 12.0;
/// Half the angle the holder arc spans behind the head.
const HOLDER_HALF_ANGLE: f64 = 65.0 * PI / 180.0;
/// Wall thickness of the maxillary sinuses, mm.
const SINUS_WALL: f64 = 1.5;

/// What a point of the phantom is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Tissue {
    /// Air (outside, and in the sinuses).
    Air,
    /// The foam pad between the head and the holder.
    Foam,
    /// Skin.
    Skin,
    /// Subcutaneous fat.
    Fat,
    /// Muscle and other soft tissue.
    SoftTissue,
    /// Cerebrospinal fluid.
    Csf,
    /// Brain.
    Brain,
    /// Cortical bone of the vault.
    VaultCortical,
    /// Diploë of the vault.
    VaultDiploe,
    /// Bone that is not the vault: skull base, sinus walls, the frontal sinus's tables.
    OtherBone,
    /// The head-holder arc.
    Holder,
}

impl Tissue {
    /// Bone of any kind.
    pub fn is_bone(self) -> bool {
        matches!(
            self,
            Tissue::VaultCortical | Tissue::VaultDiploe | Tissue::OtherBone
        )
    }

    /// Bone of the vault.
    pub fn is_vault(self) -> bool {
        matches!(self, Tissue::VaultCortical | Tissue::VaultDiploe)
    }
}

/// Parameters of [`head_ct_phantom`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeadCtParams {
    /// Voxels along x, y, z.
    pub dims: [usize; 3],
    /// In-plane voxel size (mm).
    pub pixel: f64,
    /// Slice spacing (mm).
    pub slice: f64,
    /// Scale of the head's outline (thicknesses are not scaled): 1 is an adult head about
    /// 148 × 184 mm across; the test phantom is half that.
    pub anatomy_scale: f64,
    /// Standard deviation of the point-spread function in-plane and along z (mm).
    pub psf_mm: [f64; 2],
    /// Noise standard deviation (HU).
    pub noise_hu: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl HeadCtParams {
    /// A clinical head CT: 256 × 256 × 108 voxels of 0.957 × 0.957 × 1.5 mm, a sharp (bone)
    /// reconstruction kernel and its noise (20 HU).
    pub fn clinical() -> HeadCtParams {
        HeadCtParams {
            dims: [256, 256, 108],
            pixel: 0.957,
            slice: 1.5,
            anatomy_scale: 1.0,
            psf_mm: [0.45, 0.6],
            noise_hu: 20.0,
            seed: 1,
        }
    }

    /// A head of half the size on the same voxels (112 × 124 × 54), small enough for tests.
    pub fn small() -> HeadCtParams {
        HeadCtParams {
            dims: [112, 124, 54],
            anatomy_scale: 0.5,
            ..HeadCtParams::clinical()
        }
    }

    /// The same phantom with slices `ratio` times the in-plane voxel size, over the same
    /// field of view (e.g. 3 or 5 for the anisotropic grids of clinical practice); the
    /// slice profile widens with the slice.
    pub fn with_slice_ratio(self, ratio: f64) -> HeadCtParams {
        let extent = (self.dims[2] - 1) as f64 * self.slice;
        let slice = ratio * self.pixel;
        HeadCtParams {
            dims: [
                self.dims[0],
                self.dims[1],
                (extent / slice).floor() as usize + 1,
            ],
            slice,
            psf_mm: [self.psf_mm[0], self.psf_mm[1] * slice / self.slice],
            ..self
        }
    }
}

/// A rendered head-CT phantom with what its skeleton is scored against.
#[derive(Clone, Debug)]
pub struct HeadCt {
    /// The CT image, in HU.
    pub volume: Volume,
    /// The tissue at each centre of the truth grid: cubes of the pixel size over the field of
    /// view (`truth_dims`, x fastest), whatever the slice spacing.
    pub tissue: Vec<Tissue>,
    /// The vault's bone thickness (mm) along the ray through each centre of the truth grid;
    /// `NaN` away from the vault.
    pub vault_thickness: Vec<f32>,
    /// Cubes of the truth grid along x, y, z.
    pub truth_dims: [usize; 3],
    /// Samples of the holder's mid-surface about half a millimetre apart (mm).
    pub holder_mid_surface: Vec<DVec3>,
    /// Height (mm) of the skull base's upper face: the vault lies above it.
    pub skull_base_z: f64,
    /// In-plane voxel size (mm): the "voxel" of the scores.
    pub pixel: f64,
    head: Head,
}

impl HeadCt {
    /// The middle of the vault's bone on the ray from the head's centre along `u`, or `None`
    /// where that ray meets no vault (below the skull base, or at the frontal sinus).
    pub fn vault_mid_point(&self, u: DVec3) -> Option<DVec3> {
        let head = &self.head;
        let u = u.normalize();
        let depth = SCALP + 0.5 * head.vault_thickness(u);
        let p = head.centre + u * (head.scalp_radius(u) - depth);
        (p.z >= head.skull_base_z && head.frontal_thickening(p) <= 0.5).then_some(p)
    }

    /// World position (mm) of centre `idx` of the truth grid.
    pub fn truth_centre(&self, idx: usize) -> DVec3 {
        truth_centre(self.truth_dims, self.pixel, idx)
    }

    /// The tissue at `x` (mm), before partial volume, blur and noise.
    pub fn tissue_at(&self, x: DVec3) -> Tissue {
        self.head.tissue(x).0
    }

    /// The head's centre (mm), from which [`HeadCt::vault_mid_point`] casts its rays.
    pub fn head_centre(&self) -> DVec3 {
        self.head.centre
    }

    /// Writes the image as a NIfTI-1 file of int16 voxels (`.nii`) with the voxel size in
    /// `pixdim` and neither qform nor sform, as a scanner's converter writes a plain series.
    pub fn write_nifti(&self, path: &Path) -> Result<(), IoError> {
        let dims = self.volume.dims().map(|d| d as i16);
        let mut file = nifti_header(dims, 4, 16);
        let size = self.volume.voxel_size();
        for (axis, s) in [size.x, size.y, size.z].into_iter().enumerate() {
            let at = 80 + 4 * axis;
            file[at..at + 4].copy_from_slice(&(s as f32).to_le_bytes());
        }
        // xyzt_units: millimetres.
        file[123] = 2;
        file.reserve(2 * self.volume.len());
        for idx in 0..self.volume.len() {
            file.extend_from_slice(&(self.volume.value(idx) as i16).to_le_bytes());
        }
        io::write_atomic(path, &[], |w| w.write_all(&file))
    }
}

/// The analytic head.
#[derive(Clone, Debug)]
struct Head {
    centre: DVec3,
    scalp: DVec3,
    skull_base_z: f64,
    foramen: (DVec3, f64),
    maxillary: [(DVec3, DVec3); 2],
    frontal_sinus: (DVec3, DVec3),
    ventricles: [(DVec3, DVec3); 2],
    holder_axis: DVec3,
    holder_radius: f64,
    holder_top: f64,
}

/// `|((p − centre) / semi)|`: below 1 inside the ellipsoid.
fn ellipsoid_level(p: DVec3, (centre, semi): (DVec3, DVec3)) -> f64 {
    ((p - centre) / semi).length()
}

impl Head {
    fn new(params: &HeadCtParams) -> Head {
        let s = params.anatomy_scale;
        let scalp = SCALP_SEMI_AXES * s;
        let [nx, ny, nz] = params.dims;
        let top = (nz - 1) as f64 * params.slice;
        let centre = DVec3::new(
            0.5 * (nx - 1) as f64 * params.pixel,
            0.5 * (ny - 1) as f64 * params.pixel + 5.0 * s,
            top - 8.0 * s - scalp.z,
        );
        let skull_base_z = centre.z - 0.38 * scalp.z;
        let below = skull_base_z - 18.0 * s;
        let maxillary = [-1.0, 1.0].map(|side: f64| {
            (
                centre + DVec3::new(side * 22.0 * s, 45.0 * s, below - centre.z),
                DVec3::new(14.0, 17.0, 16.0) * s,
            )
        });
        let frontal_sinus = (
            centre + DVec3::new(0.0, scalp.y - SCALP - 7.0, -0.08 * scalp.z),
            DVec3::new(12.0 * s, 4.0, 8.0 * s),
        );
        let ventricles = [-1.0, 1.0].map(|side: f64| {
            (
                centre + DVec3::new(side * 10.0 * s, -2.0 * s, 5.0 * s),
                DVec3::new(8.0, 22.0, 10.0) * s,
            )
        });
        Head {
            centre,
            scalp,
            skull_base_z,
            foramen: (
                DVec3::new(centre.x, centre.y - 25.0 * s, skull_base_z),
                14.0 * s,
            ),
            maxillary,
            frontal_sinus,
            ventricles,
            holder_axis: DVec3::new(centre.x, centre.y + 10.0 * s, 0.0),
            holder_radius: scalp.y + 10.0 * s + HOLDER_GAP * s + 0.5 * HOLDER_THICKNESS,
            holder_top: centre.z + 20.0 * s,
        }
    }

    /// The scalp's distance from the centre along `u`.
    fn scalp_radius(&self, u: DVec3) -> f64 {
        1.0 / (u / self.scalp).length()
    }

    /// Vault thickness (mm) along `u`: thin at the temples, thick at the back, rippled, within
    /// 2–8 mm.
    fn vault_thickness(&self, u: DVec3) -> f64 {
        let azimuth = u.y.atan2(u.x);
        let elevation = u.z.clamp(-1.0, 1.0).asin();
        let temple = 2.8 * u.x.powi(4) * (1.0 - u.z * u.z);
        let occiput = 2.5 * (-u.y - 0.3).max(0.0);
        let ripple = 1.0 * (4.0 * azimuth).sin() * (3.0 * elevation + 0.5).cos();
        (5.0 - temple + occiput + ripple).clamp(2.0, 8.0)
    }

    /// Extra frontal bone (mm) around the frontal sinus, which splits it into two tables.
    fn frontal_thickening(&self, p: DVec3) -> f64 {
        let (c, semi) = self.frontal_sinus;
        let level = ellipsoid_level(p, (c, semi * DVec3::new(1.6, 3.0, 1.6)));
        if level < 1.0 {
            8.0 * (1.0 - level * level)
        } else {
            0.0
        }
    }

    /// What `p` is made of, and its HU before blur and noise.
    fn tissue(&self, p: DVec3) -> (Tissue, f64) {
        let d = p - self.centre;
        let r = d.length();
        let u = if r > 0.0 { d / r } else { DVec3::Z };
        let rs = self.scalp_radius(u);
        if r > rs {
            return self.outside(p);
        }
        let depth = rs - r;
        if depth < 2.0 {
            return (Tissue::Skin, 55.0);
        }
        if depth < 5.0 {
            return (Tissue::Fat, -90.0);
        }
        if p.z < self.skull_base_z {
            return self.below_base(p, depth);
        }
        if depth < SCALP {
            return (Tissue::SoftTissue, 45.0);
        }
        // The vault, then the brain.
        let t = self.vault_thickness(u) + self.frontal_thickening(p);
        let into_bone = depth - SCALP;
        if into_bone < t {
            if ellipsoid_level(p, self.frontal_sinus) < 1.0 {
                return (Tissue::Air, -1000.0);
            }
            if self.frontal_thickening(p) > 0.5 {
                return (Tissue::OtherBone, cortical_hu(p));
            }
            return vault_bone(p, into_bone, t);
        }
        if into_bone < t + 2.0 {
            return (Tissue::Csf, 8.0);
        }
        if self.ventricles.iter().any(|&e| ellipsoid_level(p, e) < 1.0) {
            return (Tissue::Csf, 6.0);
        }
        let texture = (0.21 * p.x).sin() * (0.17 * p.y + 0.5).sin() * (0.19 * p.z).cos();
        (Tissue::Brain, 32.0 + 6.0 * texture)
    }

    /// The skull base plate, pierced by the foramen magnum.
    fn skull_base(&self, p: DVec3) -> (Tissue, f64) {
        let (c, radius) = self.foramen;
        if (p.x - c.x).hypot(p.y - c.y) < radius {
            (Tissue::Csf, 8.0)
        } else {
            (Tissue::OtherBone, cortical_hu(p))
        }
    }

    /// Below the skull base: soft tissue around the maxillary sinuses.
    fn below_base(&self, p: DVec3, depth: f64) -> (Tissue, f64) {
        for (centre, semi) in self.maxillary {
            let level = ellipsoid_level(p, (centre, semi));
            if level < 1.0 {
                return (Tissue::Air, -1000.0);
            }
            if level < 1.0 + SINUS_WALL / semi.min_element() {
                return (Tissue::OtherBone, cortical_hu(p));
            }
        }
        if self.skull_base_z - p.z < BASE_THICKNESS.min(depth) && depth > SCALP {
            return self.skull_base(p);
        }
        (Tissue::SoftTissue, 45.0)
    }

    /// Outside the scalp: the holder arc, its foam pad, or air.
    fn outside(&self, p: DVec3) -> (Tissue, f64) {
        if p.z > self.holder_top {
            return (Tissue::Air, -1000.0);
        }
        let q = p - self.holder_axis;
        let rho = q.x.hypot(q.y);
        // The angle from straight behind (−y).
        let angle = q.x.atan2(-q.y).abs();
        if angle > HOLDER_HALF_ANGLE {
            return (Tissue::Air, -1000.0);
        }
        let offset = rho - self.holder_radius;
        if offset.abs() < 0.5 * HOLDER_THICKNESS {
            (Tissue::Holder, 500.0)
        } else if offset < 0.0 {
            (Tissue::Foam, -850.0)
        } else {
            (Tissue::Air, -1000.0)
        }
    }

    /// The holder's mid-surface, samples about `step` apart, inside the field of view.
    fn holder_samples(&self, step: f64, z_max: f64) -> Vec<DVec3> {
        let arc = 2.0 * HOLDER_HALF_ANGLE * self.holder_radius;
        let along = (arc / step).ceil() as usize;
        let top = self.holder_top.min(z_max);
        let rows = (top / step).ceil() as usize;
        let mut out = Vec::with_capacity((along + 1) * (rows + 1));
        for row in 0..=rows {
            let z = top * row as f64 / rows as f64;
            for a in 0..=along {
                let angle = -HOLDER_HALF_ANGLE + 2.0 * HOLDER_HALF_ANGLE * a as f64 / along as f64;
                // Straight behind is −y; the angle grows towards +x.
                let dir = DVec3::new(angle.sin(), -angle.cos(), 0.0);
                out.push(self.holder_axis + dir * self.holder_radius + DVec3::Z * z);
            }
        }
        out
    }
}

/// Cortical bone, 1200–1500 HU.
fn cortical_hu(p: DVec3) -> f64 {
    1350.0 + 150.0 * (0.37 * p.x + 0.8).sin() * (0.29 * p.y).cos() * (0.33 * p.z + 0.3).sin()
}

/// The vault at `into_bone` mm under its outer face, of total thickness `t`: cortical
/// tables (1.1 mm outer, 0.9 mm inner) around a trabecular diploë where the bone is thicker
/// than 3.2 mm, cortical throughout where thinner.
fn vault_bone(p: DVec3, into_bone: f64, t: f64) -> (Tissue, f64) {
    if t > 3.2 && into_bone > 1.1 && into_bone < t - 0.9 {
        let trabeculae = (1.9 * p.x).sin() * (2.3 * p.y + 1.0).sin() * (2.1 * p.z).sin();
        (Tissue::VaultDiploe, 525.0 + 125.0 * trabeculae)
    } else {
        (Tissue::VaultCortical, cortical_hu(p))
    }
}

/// Centre of voxel `idx` of a grid of `dims` cubes of edge `pixel` from the origin.
fn truth_centre(dims: [usize; 3], pixel: f64, idx: usize) -> DVec3 {
    let i = idx % dims[0];
    let j = (idx / dims[0]) % dims[1];
    let k = idx / (dims[0] * dims[1]);
    DVec3::new(i as f64, j as f64, k as f64) * pixel
}

/// Renders the head-CT phantom.
pub fn head_ct_phantom(params: &HeadCtParams) -> HeadCt {
    let head = Head::new(params);
    let [nx, ny, nz] = params.dims;
    let spacing = DVec3::new(params.pixel, params.pixel, params.slice);
    let centre_of = |idx: usize| {
        let i = idx % nx;
        let j = (idx / nx) % ny;
        let k = idx / (nx * ny);
        DVec3::new(i as f64, j as f64, k as f64) * spacing
    };
    // Partial volume: voxels whose centre and eight inner corners agree on the tissue take
    // the centre's value; the others average 64 subsamples.
    let rendered: Vec<f64> = (0..nx * ny * nz)
        .into_par_iter()
        .map(|idx| {
            let x = centre_of(idx);
            let (tissue, hu) = head.tissue(x);
            let corners = (0..8).map(|c| {
                DVec3::new(
                    if c & 1 == 0 { -0.375 } else { 0.375 },
                    if c & 2 == 0 { -0.375 } else { 0.375 },
                    if c & 4 == 0 { -0.375 } else { 0.375 },
                )
            });
            let uniform = corners
                .map(|o| head.tissue(x + o * spacing).0)
                .all(|t| t == tissue);
            if uniform {
                hu
            } else {
                voxel_subsamples()
                    .map(|o| head.tissue(x + o * spacing).1)
                    .sum::<f64>()
                    / 64.0
            }
        })
        .collect();
    let mut values = rendered;
    let sigma_voxels = [
        params.psf_mm[0] / params.pixel,
        params.psf_mm[0] / params.pixel,
        params.psf_mm[1] / params.slice,
    ];
    for (axis, sigma) in sigma_voxels.into_iter().enumerate() {
        if sigma > 0.0 {
            values = blur_axis(&values, params.dims, axis, sigma);
        }
    }
    let mut rng = Pcg64::seed_from_u64(params.seed);
    let values: Vec<f32> = values
        .iter()
        .map(|&v| {
            let noisy = v + params.noise_hu * gaussian(&mut rng);
            noisy.round().clamp(-1024.0, 3071.0) as f32
        })
        .collect();
    let volume = Volume::axis_aligned(params.dims, VoxelValues::F32(values), spacing, DVec3::ZERO)
        .expect("the phantom's grid is non-empty with an invertible affine");
    let z_max = (nz - 1) as f64 * params.slice;
    // The truth is sampled on cubes of the pixel size over the same field of view, whatever
    // the slice spacing, so that thick slices are scored against the same anatomy.
    let truth_dims = [nx, ny, (z_max / params.pixel).floor() as usize + 1];
    let truth: Vec<(Tissue, f32)> = (0..truth_dims.iter().product::<usize>())
        .into_par_iter()
        .map(|idx| {
            let x = truth_centre(truth_dims, params.pixel, idx);
            let tissue = head.tissue(x).0;
            let thickness = if tissue.is_vault() {
                let d = x - head.centre;
                head.vault_thickness(d / d.length()) as f32
            } else {
                f32::NAN
            };
            (tissue, thickness)
        })
        .collect();
    HeadCt {
        volume,
        tissue: truth.iter().map(|t| t.0).collect(),
        vault_thickness: truth.iter().map(|t| t.1).collect(),
        truth_dims,
        holder_mid_surface: head.holder_samples(0.5, z_max),
        skull_base_z: head.skull_base_z,
        pixel: params.pixel,
        head,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count(ct: &HeadCt, f: impl Fn(Tissue) -> bool) -> usize {
        ct.tissue.iter().filter(|&&t| f(t)).count()
    }

    #[test]
    fn the_small_head_holds_every_tissue_with_a_thin_vault() {
        let ct = head_ct_phantom(&HeadCtParams::small());
        assert_eq!(ct.volume.dims(), [112, 124, 54]);
        for tissue in [
            Tissue::Air,
            Tissue::Foam,
            Tissue::Skin,
            Tissue::Fat,
            Tissue::SoftTissue,
            Tissue::Csf,
            Tissue::Brain,
            Tissue::VaultCortical,
            Tissue::VaultDiploe,
            Tissue::OtherBone,
            Tissue::Holder,
        ] {
            assert!(count(&ct, |t| t == tissue) > 0, "{tissue:?}");
        }
        let thickness: Vec<f64> = ct
            .vault_thickness
            .iter()
            .filter(|t| t.is_finite())
            .map(|&t| f64::from(t))
            .collect();
        let (lo, hi) = thickness
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), &t| (lo.min(t), hi.max(t)));
        assert!(
            (2.0..2.5).contains(&lo) && hi > 7.0 && hi <= 8.0,
            "{lo} {hi}"
        );
        // Bone is a few percent of the voxels; the head (everything but air and foam) most.
        let bone = count(&ct, Tissue::is_bone) as f64 / ct.tissue.len() as f64;
        assert!(bone > 0.01 && bone < 0.15, "{bone}");
    }

    #[test]
    fn values_are_whole_hounsfield_units_of_the_tissues() {
        let ct = head_ct_phantom(&HeadCtParams::small());
        let mut brain = Vec::new();
        let mut vault = Vec::new();
        for idx in 0..ct.volume.len() {
            let v = ct.volume.value(idx);
            assert_eq!(v, v.round());
            match ct.tissue_at(ct.volume.voxel_centre(ct.volume.ijk(idx))) {
                Tissue::Brain => brain.push(v),
                Tissue::VaultCortical => vault.push(v),
                _ => {}
            }
        }
        let median = |v: &mut Vec<f64>| {
            let mid = v.len() / 2;
            *v.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        let brain = median(&mut brain);
        assert!((brain - 32.0).abs() < 8.0, "{brain}");
        // Blur pulls thin cortical tables towards their neighbours, not below the diploë.
        let vault = median(&mut vault);
        assert!(vault > 600.0 && vault < 1500.0, "{vault}");
        assert_eq!(
            ct.volume.value(0),
            ct.volume.value(0).clamp(-1024.0, -900.0)
        );
    }

    #[test]
    fn anisotropic_versions_keep_the_field_of_view() {
        let p = HeadCtParams::small();
        for ratio in [3.0, 5.0] {
            let q = p.with_slice_ratio(ratio);
            let extent = (q.dims[2] - 1) as f64 * q.slice;
            assert!(extent <= (p.dims[2] - 1) as f64 * p.slice + 1e-9);
            assert!(extent > (p.dims[2] - 1) as f64 * p.slice - q.slice);
            assert!((q.slice / q.pixel - ratio).abs() < 1e-12);
        }
    }

    #[test]
    fn the_holder_lies_apart_from_the_head() {
        let ct = head_ct_phantom(&HeadCtParams::small());
        assert!(count(&ct, |t| t == Tissue::Holder) > 500);
        // Every holder sample is at least the foam's gap away from skin.
        let skin: Vec<DVec3> = ct
            .tissue
            .iter()
            .enumerate()
            .filter(|(_, t)| **t == Tissue::Skin)
            .map(|(idx, _)| ct.truth_centre(idx))
            .collect();
        for h in ct.holder_mid_surface.iter().step_by(97) {
            let nearest = skin.iter().map(|s| s.distance(*h)).fold(f64::MAX, f64::min);
            assert!(nearest > 0.25 * HOLDER_GAP, "{nearest}");
        }
    }
}
