//! Reading speed of PLY point clouds: 10M points with normals in binary little-endian
//! `float` (the common scanner export), and 1M points in ascii.
//!
//! The files are generated in a temporary directory first. Compare the binary figure with
//! `cat FILE > /dev/null` on the same machine: the reader should cost little more than
//! reading the bytes.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{Criterion, SamplingMode, criterion_group, criterion_main};
use sphcover_core::io::{
    PlyEncoding, Precision, ReadOptions, WriteOptions, read_point_cloud, write_point_cloud,
};
use sphcover_core::synthetic::fibonacci_sphere;
use sphcover_core::{DVec3, PointCloud};

/// A deterministic cloud on a wavy sphere, with unit normals.
fn cloud(n: usize) -> PointCloud {
    let positions: Vec<DVec3> = fibonacci_sphere(n)
        .into_iter()
        .map(|u| u * (1.0 + 0.05 * (7.0 * u.y.atan2(u.x)).sin()))
        .collect();
    let normals = positions.iter().map(|p| p.normalize()).collect();
    PointCloud {
        positions,
        normals: Some(normals),
        confidence: None,
        values: None,
        colors: None,
    }
}

fn write(path: &Path, n: usize, encoding: PlyEncoding) {
    let options = WriteOptions {
        ply_encoding: encoding,
        precision: Precision::F32,
        inputs: Vec::new(),
    };
    write_point_cloud(path, &cloud(n), &options).expect("writing the benchmark input");
}

fn read_ply(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let binary = dir.path().join("cloud_10m.ply");
    write(&binary, 10_000_000, PlyEncoding::BinaryLittleEndian);
    let ascii = dir.path().join("cloud_1m_ascii.ply");
    write(&ascii, 1_000_000, PlyEncoding::Ascii);
    let options = ReadOptions::default();

    let mut group = c.benchmark_group("read_ply");
    group
        .sample_size(10)
        .sampling_mode(SamplingMode::Flat)
        .measurement_time(Duration::from_secs(15));
    group.bench_function("binary_le_float_10M_points_with_normals", |b| {
        b.iter_with_large_drop(|| black_box(read_point_cloud(&binary, &options).expect("read")))
    });
    group.bench_function("ascii_1M_points_with_normals", |b| {
        b.iter_with_large_drop(|| black_box(read_point_cloud(&ascii, &options).expect("read")))
    });
    group.finish();
}

criterion_group!(benches, read_ply);
criterion_main!(benches);
