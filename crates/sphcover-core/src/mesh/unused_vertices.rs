//! Removal of the vertices no triangle uses, after triangles were dropped (trimming, small
//! components).

use super::TriMesh;

/// Removes the vertices no triangle refers to, keeping the order of the others and their
/// normals, values and colours; returns how many were removed.
///
/// Triangles referring to a vertex out of range are left as they are (and keep no vertex
/// alive); [`TriMesh::check`] reports them.
pub fn remove_unused_vertices(mesh: &mut TriMesh) -> usize {
    let n = mesh.vertices.len();
    let mut used = vec![false; n];
    for t in &mesh.triangles {
        for &v in t {
            if let Some(u) = used.get_mut(v as usize) {
                *u = true;
            }
        }
    }
    let kept_count = used.iter().filter(|&&u| u).count();
    if kept_count == n {
        return 0;
    }
    let mut remap = vec![u32::MAX; n];
    let mut next = 0u32;
    for (v, &u) in used.iter().enumerate() {
        if u {
            remap[v] = next;
            next += 1;
        }
    }
    retain_used(&mut mesh.vertices, &used);
    if let Some(normals) = &mut mesh.normals
        && normals.len() == n
    {
        retain_used(normals, &used);
    }
    if let Some(values) = &mut mesh.values
        && values.len() == n
    {
        retain_used(values, &used);
    }
    if let Some(colors) = &mut mesh.colors
        && colors.len() == n
    {
        retain_used(colors, &used);
    }
    for t in &mut mesh.triangles {
        for v in t.iter_mut() {
            if let Some(&r) = remap.get(*v as usize) {
                *v = r;
            }
        }
    }
    n - kept_count
}

fn retain_used<T>(values: &mut Vec<T>, used: &[bool]) {
    let mut k = used.iter();
    values.retain(|_| *k.next().unwrap_or(&false));
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn keeps_used_vertices_and_their_attributes_in_order() {
        let mut mesh = TriMesh::new(
            (0..6).map(|i| DVec3::splat(i as f64)).collect(),
            vec![[1, 3, 5], [5, 3, 4]],
        );
        mesh.normals = Some((0..6).map(|i| DVec3::X * i as f64).collect());
        mesh.values = Some((0..6).map(f64::from).collect());
        mesh.colors = Some((0..6).map(|i| [i, 2 * i, 255]).collect());
        assert_eq!(remove_unused_vertices(&mut mesh), 2);
        assert_eq!(mesh.triangles, vec![[0, 1, 3], [3, 1, 2]]);
        let xs: Vec<f64> = mesh.vertices.iter().map(|v| v.x).collect();
        assert_eq!(xs, vec![1.0, 3.0, 4.0, 5.0]);
        assert_eq!(mesh.values.as_deref(), Some(&[1.0, 3.0, 4.0, 5.0][..]));
        assert_eq!(mesh.normals.as_ref().map(|n| n[3].x), Some(5.0));
        assert_eq!(mesh.colors.as_ref().map(|c| c[1]), Some([3, 6, 255]));
        mesh.check().unwrap();
        assert_eq!(remove_unused_vertices(&mut mesh), 0);
    }

    #[test]
    fn out_of_range_indices_do_not_panic() {
        let mut mesh = TriMesh::new(vec![DVec3::ZERO, DVec3::X], vec![[0, 7, 0]]);
        assert_eq!(remove_unused_vertices(&mut mesh), 1);
        assert_eq!(mesh.triangles, vec![[0, 7, 0]]);
        assert_eq!(mesh.vertices.len(), 1);
    }
}
