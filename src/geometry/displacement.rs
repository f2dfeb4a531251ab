//! Displacement of triangle meshes by a height function, as pbrt-v4
//! displaces `plymesh` shapes (`TriQuadMesh::Displace`): triangles are cut
//! at the midpoint of their longest edge until every edge is shorter than
//! a bound, each vertex moves along its normal by the height there, and
//! the mesh takes new smooth normals.

use super::mesh::TriangleMesh;
use glam::{Vec2, Vec3};
use std::collections::HashMap;

/// Why a mesh cannot be displaced.
#[derive(Clone, Debug, PartialEq)]
pub enum DisplacementError {
    /// The height function reads (u, v), which the mesh does not have
    /// (pbrt-v4 requires them too).
    NoUvs,
    /// The edge bound is not a positive finite length.
    BadEdgeLength(f32),
    /// Refining to the bound would make more than `limit` triangles.
    TooManyTriangles {
        /// The bound on the number of triangles.
        limit: usize,
    },
}

impl std::fmt::Display for DisplacementError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DisplacementError::NoUvs => write!(f, "a displaced mesh needs texture coordinates (uv)"),
            DisplacementError::BadEdgeLength(e) => {
                write!(f, "the edge length must be positive and finite, got {e}")
            }
            DisplacementError::TooManyTriangles { limit } => write!(
                f,
                "refining the mesh to that edge length would make more than {limit} triangles"
            ),
        }
    }
}

/// `mesh` cut until every edge, measured by `distance` (pbrt-v4 measures
/// in render space, after the shape's transform), is shorter than
/// `max_edge`; then each vertex p moved to p + h·n, with h = `height(p,
/// uv)` and n its normal (the mesh's own, or smooth normals as pbrt-v4
/// computes them), and the result given smooth normals. Midpoints take
/// the mean of their edge's positions, uvs and per-vertex attributes and
/// the normalised sum of its normals; a cut triangle's parts keep its
/// per-face attributes. Edges shared by two triangles are cut once, so
/// the mesh stays watertight. Fails rather than make more than
/// `max_triangles` triangles.
pub fn displace(
    mesh: &TriangleMesh,
    distance: impl Fn(Vec3, Vec3) -> f32,
    max_edge: f32,
    height: impl Fn(Vec3, Vec2) -> f32,
    max_triangles: usize,
) -> Result<TriangleMesh, DisplacementError> {
    if mesh.uvs.len() != mesh.positions.len() {
        return Err(DisplacementError::NoUvs);
    }
    if !(max_edge > 0.0 && max_edge.is_finite()) {
        return Err(DisplacementError::BadEdgeLength(max_edge));
    }
    // No triangle with edges below the bound is larger than the
    // equilateral one: a lower bound on the count, checked before any
    // allocation.
    let largest = 3f64.sqrt() / 4.0 * (max_edge as f64).powi(2);
    let area: f64 = mesh
        .indices
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
            // The area by `distance`'s metric: Heron's formula on its
            // lengths.
            let (x, y, z) = (distance(a, b) as f64, distance(b, c) as f64, distance(c, a) as f64);
            let s = 0.5 * (x + y + z);
            (s * (s - x) * (s - y) * (s - z)).max(0.0).sqrt()
        })
        .sum();
    let too_many = DisplacementError::TooManyTriangles { limit: max_triangles };
    // NaN (an infinite vertex) fails too.
    let fits = area / largest <= max_triangles as f64;
    if !fits {
        return Err(too_many);
    }

    let mut out = mesh.clone();
    if out.normals.is_empty() {
        out.normals = pbrt_vertex_normals(&out.positions, &out.indices);
    }
    let per_face: Vec<usize> = (0..out.attributes.len())
        .filter(|&a| out.attributes[a].per_face)
        .collect();
    let mut face_values: Vec<Vec<f32>> = per_face.iter().map(|_| Vec::new()).collect();
    let mut indices = Vec::with_capacity(mesh.indices.len());
    let mut split: HashMap<(u32, u32), u32> = HashMap::new();
    // Triangles still to cut, with the face they came from; an explicit
    // stack: the depth grows with the ratio of edge to bound.
    let mut stack: Vec<([u32; 3], usize)> = Vec::new();
    for (face, &tri) in mesh.indices.iter().enumerate() {
        stack.push((tri, face));
        while let Some((t, face)) = stack.pop() {
            let p = t.map(|i| out.positions[i as usize]);
            let d = [distance(p[0], p[1]), distance(p[1], p[2]), distance(p[2], p[0])];
            // NaN lengths (an infinite vertex) end the cutting too.
            if !(d[0] >= max_edge || d[1] >= max_edge || d[2] >= max_edge) {
                if indices.len() == max_triangles {
                    return Err(too_many);
                }
                indices.push(t);
                for (k, &a) in per_face.iter().enumerate() {
                    let attr = &mesh.attributes[a];
                    face_values[k].extend_from_slice(&attr.values[face * attr.channels..(face + 1) * attr.channels]);
                }
                continue;
            }
            // Rotate so that the longest edge runs from v[0] to v[1].
            let v = if d[0] > d[1] {
                if d[0] > d[2] { t } else { [t[2], t[0], t[1]] }
            } else if d[1] > d[2] {
                [t[1], t[2], t[0]]
            } else {
                [t[2], t[0], t[1]]
            };
            let key = (v[0].min(v[1]), v[0].max(v[1]));
            let mid = match split.get(&key) {
                Some(&m) => m,
                None => {
                    let m = add_midpoint(&mut out, v[0], v[1]);
                    split.insert(key, m);
                    m
                }
            };
            stack.push(([mid, v[1], v[2]], face));
            stack.push(([v[0], mid, v[2]], face));
        }
    }
    for (k, &a) in per_face.iter().enumerate() {
        out.attributes[a].values = std::mem::take(&mut face_values[k]);
    }
    out.indices = indices;

    for i in 0..out.positions.len() {
        let h = height(out.positions[i], out.uvs[i]);
        out.positions[i] += h * out.normals[i];
    }
    out.normals = pbrt_vertex_normals(&out.positions, &out.indices);
    Ok(out)
}

/// A new vertex halfway along the edge from `a` to `b`; its index.
fn add_midpoint(mesh: &mut TriangleMesh, a: u32, b: u32) -> u32 {
    let (a, b) = (a as usize, b as usize);
    let m = mesh.positions.len() as u32;
    mesh.positions.push(0.5 * (mesh.positions[a] + mesh.positions[b]));
    let n = mesh.normals[a] + mesh.normals[b];
    mesh.normals.push(n.try_normalize().unwrap_or(n));
    mesh.uvs.push(0.5 * (mesh.uvs[a] + mesh.uvs[b]));
    for attr in mesh.attributes.iter_mut().filter(|attr| !attr.per_face) {
        let c = attr.channels;
        for k in 0..c {
            let mean = 0.5 * (attr.values[a * c + k] + attr.values[b * c + k]);
            attr.values.push(mean);
        }
    }
    m
}

/// Vertex normals as pbrt-v4's `TriQuadMesh::ComputeNormals`: the sum of
/// the unit normals of the triangles around the vertex, unweighted,
/// normalised (zero where no triangle with an area touches the vertex).
fn pbrt_vertex_normals(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec3> {
    let mut sums = vec![Vec3::ZERO; positions.len()];
    for t in indices {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        if let Some(n) = (b - a).cross(c - b).try_normalize() {
            for &i in t {
                sums[i as usize] += n;
            }
        }
    }
    sums.into_iter().map(Vec3::normalize_or_zero).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square in the xy-plane, facing +z, with uvs = (x, y).
    fn square() -> TriangleMesh {
        TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        }
    }

    fn euclid(a: Vec3, b: Vec3) -> f32 {
        a.distance(b)
    }

    /// Every edge ends below the bound; the cut mesh covers the same area,
    /// shares its midpoints (watertight: every inner edge has two
    /// triangles), and a constant height lifts it along +z.
    #[test]
    fn refined_meshes_keep_their_surface_and_stay_watertight() {
        for max_edge in [0.9f32, 0.3, 0.1] {
            let m = displace(&square(), euclid, max_edge, |_, _| 0.25, 1 << 20).unwrap();
            assert!(m.validate().is_ok());
            let mut edges: HashMap<(u32, u32), usize> = HashMap::new();
            let mut area = 0.0;
            for t in &m.indices {
                let p = t.map(|i| m.positions[i as usize]);
                for k in 0..3 {
                    assert!(p[k].distance(p[(k + 1) % 3]) < max_edge, "{max_edge}");
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    *edges.entry((a.min(b), a.max(b))).or_default() += 1;
                }
                area += 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
            }
            assert!((area - 1.0).abs() < 1e-5, "{max_edge}: area {area}");
            // Border edges (on the square's sides) have one triangle, the
            // others two.
            for (&(a, b), &count) in &edges {
                let (pa, pb) = (m.positions[a as usize], m.positions[b as usize]);
                let on_border = [0, 1]
                    .iter()
                    .any(|&k| (pa[k] == 0.0 && pb[k] == 0.0) || (pa[k] == 1.0 && pb[k] == 1.0));
                assert_eq!(count, if on_border { 1 } else { 2 }, "{max_edge}: edge {pa} {pb}");
            }
            assert!(m.positions.iter().all(|p| p.z == 0.25));
            assert!(m.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
            // uvs are interpolated linearly: they stay the xy position.
            for (p, uv) in m.positions.iter().zip(&m.uvs) {
                assert!((p.truncate() - *uv).length() < 1e-6);
            }
        }
    }

    /// The height is read at each vertex's own (u, v): a ramp h = u tilts
    /// the square, and its normals turn with it.
    #[test]
    fn heights_follow_the_texture_coordinates() {
        let m = displace(&square(), euclid, 0.2, |_, uv| 0.5 * uv.x, 1 << 20).unwrap();
        for (p, uv) in m.positions.iter().zip(&m.uvs) {
            assert!((p.z - 0.5 * uv.x).abs() < 1e-6);
        }
        let tilted = Vec3::new(-0.5, 0.0, 1.0).normalize();
        assert!(m.normals.iter().all(|n| (*n - tilted).length() < 1e-5));
    }

    /// The edge length is measured by the caller's metric (pbrt-v4's render
    /// space): doubling every distance takes more triangles.
    #[test]
    fn edges_are_measured_where_the_caller_says() {
        let near = displace(&square(), euclid, 0.5, |_, _| 0.0, 1 << 20).unwrap();
        let far = displace(&square(), |a, b| 2.0 * a.distance(b), 0.5, |_, _| 0.0, 1 << 20).unwrap();
        assert!(far.len() >= 3 * near.len(), "{} vs {}", far.len(), near.len());
    }

    /// Meshes without uvs, absurd edge lengths and refinements past the
    /// limit are errors, the last before anything is allocated.
    #[test]
    fn bad_input_is_refused() {
        let mut no_uv = square();
        no_uv.uvs.clear();
        assert_eq!(
            displace(&no_uv, euclid, 0.5, |_, _| 0.0, 100).unwrap_err(),
            DisplacementError::NoUvs
        );
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert!(matches!(
                displace(&square(), euclid, bad, |_, _| 0.0, 100),
                Err(DisplacementError::BadEdgeLength(_))
            ));
        }
        let e = displace(&square(), euclid, 1e-6, |_, _| 0.0, 1 << 20).unwrap_err();
        assert_eq!(e, DisplacementError::TooManyTriangles { limit: 1 << 20 });
        assert!(e.to_string().contains("more than 1048576 triangles"));
    }
}
