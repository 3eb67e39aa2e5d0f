//! PLY output: `vertex` with x y z and whichever of nx ny nz, confidence, quality (the
//! values), radius are present, as reals, then `uchar` red green blue when there are
//! colours; then `face` lists of 3 indices when there are triangles.

use std::io::Write;

use crate::io::encode::write_records;
use crate::io::text::{push_real, push_uint};
use crate::io::{Export, PlyEncoding};

/// Most fields a vertex record can have: x y z nx ny nz confidence value radius.
const MAX_FIELDS: usize = 9;

/// Fills `out` with the fields of vertex `i`, returns their number.
#[inline]
fn vertex_fields(e: &Export<'_>, i: usize, out: &mut [f64; MAX_FIELDS]) -> usize {
    let mut n = 0;
    let mut put = |v: f64| {
        out[n] = v;
        n += 1;
    };
    let p = e.positions[i];
    put(p.x);
    put(p.y);
    put(p.z);
    if let Some(normals) = e.normals {
        let v = normals[i];
        put(v.x);
        put(v.y);
        put(v.z);
    }
    for attribute in [e.confidence, e.values, e.radii].into_iter().flatten() {
        put(attribute[i]);
    }
    n
}

pub(crate) fn write(
    w: &mut dyn Write,
    e: &Export<'_>,
    encoding: PlyEncoding,
    double: bool,
) -> std::io::Result<()> {
    let real = if double { "double" } else { "float" };
    // `int` is what most readers expect; `uint` only when indices need the 32nd bit.
    let unsigned = e.positions.len() > i32::MAX as usize;
    let format = match encoding {
        PlyEncoding::BinaryLittleEndian => "binary_little_endian",
        PlyEncoding::BinaryBigEndian => "binary_big_endian",
        PlyEncoding::Ascii => "ascii",
    };
    let mut header = format!(
        "ply\nformat {format} 1.0\ncomment written by sphcover\nelement vertex {}\n",
        e.positions.len()
    );
    let mut names = vec!["x", "y", "z"];
    if e.normals.is_some() {
        names.extend(["nx", "ny", "nz"]);
    }
    for (present, name) in [
        (e.confidence.is_some(), "confidence"),
        // MeshLab's name for a per-vertex scalar: it colours by it and keeps it.
        (e.values.is_some(), "quality"),
        (e.radii.is_some(), "radius"),
    ] {
        if present {
            names.push(name);
        }
    }
    for name in names {
        header.push_str(&format!("property {real} {name}\n"));
    }
    if e.colors.is_some() {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    if !e.triangles.is_empty() {
        header.push_str(&format!(
            "element face {}\nproperty list uchar {} vertex_indices\n",
            e.triangles.len(),
            if unsigned { "uint" } else { "int" }
        ));
    }
    header.push_str("end_header\n");
    w.write_all(header.as_bytes())?;

    match encoding {
        PlyEncoding::Ascii => {
            write_records(w, e.positions.len(), |i, buf| {
                let mut fields = [0.0; MAX_FIELDS];
                let n = vertex_fields(e, i, &mut fields);
                for (k, &v) in fields[..n].iter().enumerate() {
                    if k > 0 {
                        buf.push(b' ');
                    }
                    push_real(buf, v, double);
                }
                if let Some(colors) = e.colors {
                    for c in colors[i] {
                        buf.push(b' ');
                        push_uint(buf, u64::from(c));
                    }
                }
                buf.push(b'\n');
            })?;
            write_records(w, e.triangles.len(), |t, buf| {
                buf.push(b'3');
                for v in e.triangles[t] {
                    buf.push(b' ');
                    push_uint(buf, u64::from(v));
                }
                buf.push(b'\n');
            })
        }
        PlyEncoding::BinaryLittleEndian | PlyEncoding::BinaryBigEndian => {
            let big = encoding == PlyEncoding::BinaryBigEndian;
            write_records(w, e.positions.len(), |i, buf| {
                let mut fields = [0.0; MAX_FIELDS];
                let n = vertex_fields(e, i, &mut fields);
                for &v in &fields[..n] {
                    match (double, big) {
                        (true, false) => buf.extend_from_slice(&v.to_le_bytes()),
                        (true, true) => buf.extend_from_slice(&v.to_be_bytes()),
                        (false, false) => buf.extend_from_slice(&(v as f32).to_le_bytes()),
                        (false, true) => buf.extend_from_slice(&(v as f32).to_be_bytes()),
                    }
                }
                if let Some(colors) = e.colors {
                    buf.extend_from_slice(&colors[i]);
                }
            })?;
            write_records(w, e.triangles.len(), |t, buf| {
                buf.push(3);
                for v in e.triangles[t] {
                    // Indices below 2^31 have the same bytes as `int` and `uint`.
                    if big {
                        buf.extend_from_slice(&v.to_be_bytes());
                    } else {
                        buf.extend_from_slice(&v.to_le_bytes());
                    }
                }
            })
        }
    }
}
