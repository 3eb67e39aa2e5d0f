//! The NIfTI-1/2 reader on small files written by the tests themselves: both byte orders,
//! every supported datatype, gzip or not, sform/qform/pixdim, scaling, 4D, and malformed
//! files (truncated, absurd dimensions, bad fields), each refused with the file and a byte
//! offset.
#![cfg(feature = "nifti")]

use std::io::Write;
use std::path::{Path, PathBuf};

use sphcover_core::io::{
    AffineSource, IoError, Location, ReadOptions, SampleType, VolumeInfo, parse_nifti, read_nifti,
    read_volume,
};
use sphcover_core::{DVec3, VoxelValues};

/// A NIfTI header under construction; `bytes()` lays it out.
#[derive(Clone)]
struct Header {
    version: u8,
    big: bool,
    datatype: i16,
    bitpix: i16,
    dim: [i64; 8],
    pixdim: [f64; 8],
    vox_offset: f64,
    slope: f64,
    inter: f64,
    qform_code: i32,
    sform_code: i32,
    quatern: [f64; 3],
    qoffset: [f64; 3],
    srow: [[f64; 4]; 3],
    magic_pair: bool,
}

impl Header {
    fn new(version: u8, big: bool, dt: SampleType, dims: &[i64]) -> Header {
        let mut dim = [1i64; 8];
        dim[0] = dims.len() as i64;
        dim[1..=dims.len()].copy_from_slice(dims);
        Header {
            version,
            big,
            datatype: dt.nifti_code(),
            bitpix: 8 * dt.size() as i16,
            dim,
            pixdim: [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0],
            vox_offset: if version == 1 { 352.0 } else { 544.0 },
            slope: 0.0,
            inter: 0.0,
            qform_code: 0,
            sform_code: 0,
            quatern: [0.0; 3],
            qoffset: [0.0; 3],
            srow: [[0.0; 4]; 3],
            magic_pair: false,
        }
    }

    fn bytes(&self) -> Vec<u8> {
        let size = if self.version == 1 { 348 } else { 540 };
        let mut b = vec![0u8; (self.vox_offset as usize).max(size + 4)];
        let big = self.big;
        let mut put = |at: usize, raw: &[u8]| {
            let mut raw = raw.to_vec();
            if big {
                raw.reverse();
            }
            b[at..at + raw.len()].copy_from_slice(&raw);
        };
        put(0, &(size as i32).to_le_bytes());
        if self.version == 1 {
            put(70, &self.datatype.to_le_bytes());
            put(72, &self.bitpix.to_le_bytes());
            for i in 0..8 {
                put(40 + 2 * i, &(self.dim[i] as i16).to_le_bytes());
                put(76 + 4 * i, &(self.pixdim[i] as f32).to_le_bytes());
            }
            put(108, &(self.vox_offset as f32).to_le_bytes());
            put(112, &(self.slope as f32).to_le_bytes());
            put(116, &(self.inter as f32).to_le_bytes());
            put(252, &(self.qform_code as i16).to_le_bytes());
            put(254, &(self.sform_code as i16).to_le_bytes());
            for i in 0..3 {
                put(256 + 4 * i, &(self.quatern[i] as f32).to_le_bytes());
                put(268 + 4 * i, &(self.qoffset[i] as f32).to_le_bytes());
                for c in 0..4 {
                    put(
                        280 + 16 * i + 4 * c,
                        &(self.srow[i][c] as f32).to_le_bytes(),
                    );
                }
            }
        } else {
            put(12, &self.datatype.to_le_bytes());
            put(14, &self.bitpix.to_le_bytes());
            for i in 0..8 {
                put(16 + 8 * i, &self.dim[i].to_le_bytes());
                put(104 + 8 * i, &self.pixdim[i].to_le_bytes());
            }
            put(168, &(self.vox_offset as i64).to_le_bytes());
            put(176, &self.slope.to_le_bytes());
            put(184, &self.inter.to_le_bytes());
            put(344, &self.qform_code.to_le_bytes());
            put(348, &self.sform_code.to_le_bytes());
            for i in 0..3 {
                put(352 + 8 * i, &self.quatern[i].to_le_bytes());
                put(376 + 8 * i, &self.qoffset[i].to_le_bytes());
                for c in 0..4 {
                    put(400 + 32 * i + 8 * c, &self.srow[i][c].to_le_bytes());
                }
            }
        }
        // Magic strings are byte strings: no swapping.
        if self.version == 1 {
            let m: &[u8; 4] = if self.magic_pair { b"ni1\0" } else { b"n+1\0" };
            b[344..348].copy_from_slice(m);
        } else {
            let m: &[u8; 8] = if self.magic_pair {
                b"ni2\0\r\n\x1a\n"
            } else {
                b"n+2\0\r\n\x1a\n"
            };
            b[4..12].copy_from_slice(m);
        }
        b
    }
}

/// Encodes `values` (as f64) in the datatype and byte order.
fn encode(dt: SampleType, big: bool, values: &[f64]) -> Vec<u8> {
    let mut out = Vec::new();
    for &v in values {
        let mut raw = match dt {
            SampleType::U8 => vec![v as u8],
            SampleType::I8 => (v as i8).to_le_bytes().to_vec(),
            SampleType::I16 => (v as i16).to_le_bytes().to_vec(),
            SampleType::U16 => (v as u16).to_le_bytes().to_vec(),
            SampleType::I32 => (v as i32).to_le_bytes().to_vec(),
            SampleType::U32 => (v as u32).to_le_bytes().to_vec(),
            SampleType::F32 => (v as f32).to_le_bytes().to_vec(),
            SampleType::F64 => v.to_le_bytes().to_vec(),
        };
        if big {
            raw.reverse();
        }
        out.extend(raw);
    }
    out
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn sample_values(dt: SampleType, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let i = i as f64;
            match dt {
                SampleType::U8 => (i * 7.0) % 256.0,
                SampleType::I8 => (i * 7.0) % 200.0 - 100.0,
                SampleType::I16 => i * 97.0 - 1000.0,
                SampleType::U16 => i * 1013.0,
                SampleType::I32 => i * 1_000_003.0 - 5e7,
                SampleType::U32 => i * 60_000_007.0,
                SampleType::F32 => (i * 0.37 - 2.0) as f32 as f64,
                SampleType::F64 => i * 0.123_456_789 - 1.5,
            }
        })
        .collect()
}

const ALL: [SampleType; 8] = [
    SampleType::U8,
    SampleType::I8,
    SampleType::I16,
    SampleType::U16,
    SampleType::I32,
    SampleType::U32,
    SampleType::F32,
    SampleType::F64,
];

#[test]
fn every_datatype_both_orders_both_versions_plain_and_gzip() {
    let dir = tempfile::tempdir().unwrap();
    let dims = [3i64, 4, 5];
    for version in [1u8, 2] {
        for big in [false, true] {
            for dt in ALL {
                let values = sample_values(dt, 60);
                let mut h = Header::new(version, big, dt, &dims);
                h.pixdim[1..4].copy_from_slice(&[0.5, 0.25, 2.0]);
                let mut file = h.bytes();
                file.extend(encode(dt, big, &values));
                for gz in [false, true] {
                    let bytes = if gz { gzip(&file) } else { file.clone() };
                    let name = format!(
                        "v{version}_{big}_{}_{gz}.nii{}",
                        dt.name(),
                        if gz { ".gz" } else { "" }
                    );
                    let path = write(dir.path(), &name, &bytes);
                    let (vol, info) = read_nifti(&path, &ReadOptions::default())
                        .unwrap_or_else(|e| panic!("{name}: {e}"));
                    assert_eq!(info.version, version);
                    assert_eq!(info.big_endian, big);
                    assert_eq!(info.gzip, gz);
                    assert_eq!(info.datatype, dt);
                    assert_eq!(info.dims, [3, 4, 5]);
                    assert_eq!(info.frames, 1);
                    assert_eq!(info.affine_source, AffineSource::Pixdim);
                    assert_eq!(info.voxel_size, DVec3::new(0.5, 0.25, 2.0));
                    assert_eq!(info.scaling, None);
                    let narrow = !matches!(dt, SampleType::I32 | SampleType::U32 | SampleType::F64);
                    assert_eq!(
                        matches!(vol.values(), VoxelValues::F32(_)),
                        narrow,
                        "{name}"
                    );
                    for (i, &v) in values.iter().enumerate() {
                        assert_eq!(vol.value(i), v, "{name} voxel {i}");
                    }
                    assert_eq!(vol.voxel_centre([2, 3, 4]), DVec3::new(1.0, 0.75, 8.0));
                    // The in-memory parser agrees.
                    let (again, _) = parse_nifti(&bytes, &path, &ReadOptions::default()).unwrap();
                    assert_eq!(again, vol);
                }
            }
        }
    }
}

#[test]
fn sform_wins_over_qform_which_wins_over_pixdim() {
    let dir = tempfile::tempdir().unwrap();
    let dt = SampleType::I16;
    let values = sample_values(dt, 8);
    for version in [1u8, 2] {
        let mut h = Header::new(version, false, dt, &[2, 2, 2]);
        h.pixdim = [-1.0, 2.0, 3.0, 4.0, 1.0, 1.0, 1.0, 1.0];
        // qform: 90° about z (quaternion (cos45°, 0, 0, sin45°)), qfac −1 from pixdim[0].
        h.qform_code = 1;
        h.quatern = [0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2];
        h.qoffset = [10.0, 20.0, 30.0];
        let mut file = h.bytes();
        file.extend(encode(dt, false, &values));
        let path = write(dir.path(), &format!("q{version}.nii"), &file);
        let (vol, VolumeInfo::Nifti(info)) = read_volume(&path, &ReadOptions::default()).unwrap()
        else {
            panic!("a .nii file must read as NIfTI")
        };
        assert_eq!(info.affine_source, AffineSource::Qform);
        // Voxel (1, 0, 0) moves 2 along +y; (0, 1, 0) moves 3 along −x; (0, 0, 1) moves −4 in z.
        let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-6;
        assert!(close(
            vol.voxel_centre([1, 0, 0]),
            DVec3::new(10.0, 22.0, 30.0)
        ));
        assert!(close(
            vol.voxel_centre([0, 1, 0]),
            DVec3::new(7.0, 20.0, 30.0)
        ));
        assert!(close(
            vol.voxel_centre([0, 0, 1]),
            DVec3::new(10.0, 20.0, 26.0)
        ));

        h.sform_code = 2;
        h.srow = [
            [0.0, 1.5, 0.0, -1.0],
            [2.5, 0.0, 0.0, -2.0],
            [0.0, 0.0, 0.5, 3.0],
        ];
        let mut file = h.bytes();
        file.extend(encode(dt, false, &values));
        let path = write(dir.path(), &format!("s{version}.nii"), &file);
        let (vol, VolumeInfo::Nifti(info)) = read_volume(&path, &ReadOptions::default()).unwrap()
        else {
            panic!("a .nii file must read as NIfTI")
        };
        assert_eq!(info.affine_source, AffineSource::Sform);
        assert!(close(
            vol.voxel_centre([1, 1, 1]),
            DVec3::new(0.5, 0.5, 3.5)
        ));
        assert!(close(info.voxel_size, DVec3::new(2.5, 1.5, 0.5)));
    }
}

#[test]
fn scaling_applies_unless_slope_is_zero() {
    let dir = tempfile::tempdir().unwrap();
    let dt = SampleType::I16;
    let values = [0.0, 1.0, 100.0, -5.0];
    for version in [1u8, 2] {
        for (slope, inter, expect) in [(0.0, 7.0, None), (2.0, -1024.0, Some((2.0, -1024.0)))] {
            let mut h = Header::new(version, true, dt, &[2, 2]);
            h.slope = slope;
            h.inter = inter;
            let mut file = h.bytes();
            file.extend(encode(dt, true, &values));
            let path = write(dir.path(), "scaled.nii", &file);
            let (vol, info) = read_nifti(&path, &ReadOptions::default()).unwrap();
            assert_eq!(info.scaling, expect);
            assert_eq!(info.dims, [2, 2, 1]);
            for (i, v) in values.iter().enumerate() {
                let want = match expect {
                    Some((s, b)) => v * s + b,
                    None => *v,
                };
                assert_eq!(vol.value(i), want);
            }
        }
    }
}

#[test]
fn four_d_volumes_keep_the_first_frame_and_extensions_are_skipped() {
    let dir = tempfile::tempdir().unwrap();
    let dt = SampleType::F32;
    let values: Vec<f64> = (0..24).map(f64::from).collect();
    let mut h = Header::new(1, false, dt, &[2, 3, 2, 2]);
    h.vox_offset = 352.0 + 32.0; // an extension block before the data
    let mut file = h.bytes();
    file.extend(encode(dt, false, &values));
    for gz in [false, true] {
        let bytes = if gz { gzip(&file) } else { file.clone() };
        let path = write(dir.path(), "4d.nii.gz", &bytes);
        let (vol, info) = read_nifti(&path, &ReadOptions::default()).unwrap();
        assert_eq!(info.frames, 2);
        assert_eq!(info.vox_offset, 384);
        assert_eq!(vol.len(), 12);
        assert_eq!(vol.value(11), 11.0);
    }
}

/// The error's location when it is a content error.
fn location(e: &IoError) -> Location {
    match e {
        IoError::Malformed { at, .. } => *at,
        other => panic!("not a content error: {other}"),
    }
}

#[test]
fn malformed_files_are_refused_with_file_and_offset() {
    let dir = tempfile::tempdir().unwrap();
    let dt = SampleType::I16;
    let good = |version| {
        let h = Header::new(version, false, dt, &[4, 4, 4]);
        let mut f = h.bytes();
        f.extend(encode(dt, false, &sample_values(dt, 64)));
        f
    };
    let check = |name: &str, bytes: &[u8], at: u64, needle: &str| {
        for gz in [false, true] {
            let data = if gz { gzip(bytes) } else { bytes.to_vec() };
            let path = write(dir.path(), name, &data);
            let err = read_nifti(&path, &ReadOptions::default()).expect_err(name);
            let msg = err.to_string();
            assert!(msg.contains(name), "{msg}");
            assert!(msg.contains(needle), "{name}: {msg}");
            assert_eq!(location(&err), Location::Byte(at), "{name}: {msg}");
            assert!(err.is_bad_input());
        }
    };
    // Truncated data: the first missing voxel and where the file ends.
    let full = good(1);
    check(
        "short.nii",
        &full[..352 + 100],
        452,
        "int16 voxel 50 truncated",
    );
    check(
        "short2.nii",
        &good(2)[..544 + 3],
        547,
        "int16 voxel 1 truncated",
    );
    check("hdr.nii", &full[..200], 200, "inside the 348-byte");
    // Header fields.
    let mut h = Header::new(1, false, dt, &[4, 4, 4]);
    h.dim[0] = 9;
    check("dim0.nii", &h.bytes(), 40, "dim[0] = 9");
    let mut h = Header::new(1, false, dt, &[4, 0, 4]);
    h.dim[0] = 3;
    check("dim2.nii", &h.bytes(), 44, "dim[2] = 0");
    let mut h = Header::new(1, false, dt, &[4, 4, 4]);
    h.datatype = 128; // RGB
    check("rgb.nii", &h.bytes(), 70, "datatype 128");
    let mut h = Header::new(1, false, dt, &[4, 4, 4]);
    h.vox_offset = 100.0;
    let mut b = h.bytes();
    b.resize(400, 0);
    check("off.nii", &b, 108, "vox_offset");
    let mut h = Header::new(1, false, dt, &[4, 4, 4]);
    h.pixdim[2] = 0.0;
    let mut b = h.bytes();
    b.extend(encode(dt, false, &sample_values(dt, 64)));
    check("pix.nii", &b, 84, "pixdim[2]");
    let mut h = Header::new(1, false, dt, &[4, 4, 4]);
    h.sform_code = 1; // all-zero rows
    let mut b = h.bytes();
    b.extend(encode(dt, false, &sample_values(dt, 64)));
    check("sform.nii", &b, 280, "srow");
    let mut h = Header::new(1, false, dt, &[4, 4, 4]);
    h.magic_pair = true;
    check("pair.nii", &h.bytes(), 344, "two-file");
    let mut b = full.clone();
    b[344..348].copy_from_slice(b"abcd");
    check("magic.nii", &b, 344, "magic");
    let mut b = full.clone();
    b[0..4].copy_from_slice(&1234i32.to_le_bytes());
    check("size.nii", &b, 0, "sizeof_hdr is 1234");
}

#[test]
fn absurd_dimensions_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let dt = SampleType::F64;
    // 32767³ doubles (2.8e14 bytes) declared by a tiny file, plain and gzip.
    let h = Header::new(1, false, dt, &[32767, 32767, 32767]);
    let bytes = h.bytes();
    let path = write(dir.path(), "huge.nii", &bytes);
    let err = read_nifti(&path, &ReadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("truncated"), "{err}");
    let path = write(dir.path(), "huge.nii.gz", &gzip(&bytes));
    let err = read_nifti(&path, &ReadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("more than a"), "{err}");
    assert_eq!(location(&err), Location::Byte(42));
    // NIfTI-2: dimensions whose byte count overflows 64 bits.
    let h = Header::new(2, true, dt, &[1 << 40, 1 << 40, 1 << 40]);
    let path = write(dir.path(), "overflow.nii", &h.bytes());
    let err = read_nifti(&path, &ReadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("overflow"), "{err}");
}

#[test]
fn empty_corrupt_and_missing_files() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "empty.nii", &[]);
    assert!(
        read_nifti(&path, &ReadOptions::default())
            .unwrap_err()
            .to_string()
            .contains("empty file")
    );
    let h = Header::new(1, false, SampleType::U8, &[4, 4, 4]);
    let mut f = h.bytes();
    f.extend([7u8; 64]);
    let mut gz = gzip(&f);
    let n = gz.len();
    gz.truncate(n - 12); // cut the trailer and some of the stream
    let path = write(dir.path(), "cut.nii.gz", &gz);
    let err = read_nifti(&path, &ReadOptions::default()).unwrap_err();
    assert!(matches!(err, IoError::Malformed { .. }), "{err}");
    let missing = dir.path().join("missing.nii");
    assert!(matches!(
        read_nifti(&missing, &ReadOptions::default()),
        Err(IoError::Read { .. })
    ));
}
