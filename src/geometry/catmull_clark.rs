//! Catmull–Clark subdivision surfaces (Catmull and Clark 1978, "Recursively
//! generated B-spline surfaces on arbitrary topological meshes"): `levels`
//! rounds of refinement of a control mesh of polygons, each round making
//! every n-gon n quads, then every vertex moved to its limit position
//! (Halstead, Kass and DeRose 1993, "Efficient, fair interpolation using
//! Catmull–Clark surfaces", for the limit mask of a vertex of a quad mesh),
//! and the quads split into triangles. On a regular grid of quads the
//! surface is the uniform bicubic B-spline of the control points.
//!
//! Boundary edges (one face) keep the surface on the boundary curve, the
//! cubic B-spline of the boundary's points, as in Pixar's and OpenSubdiv's
//! rules. A vertex whose faces do not form one fan or a fan bounded by two
//! boundary edges (an edge of three or more faces) has no rule: it stays
//! where it is.

use std::collections::{BTreeMap, HashMap};

use glam::Vec3;

use super::TriangleMesh;
use super::subdivision::{MAX_SUBDIVISION_LEVELS, MAX_SUBDIVISION_TRIANGLES};

/// The faces of a polygon mesh, each a list of vertex indices.
type Faces = Vec<Vec<u32>>;

/// Each edge (its ends in increasing order) with the faces it borders, in
/// order (so that the new points are numbered the same in every run).
fn edges_of(faces: &Faces) -> BTreeMap<(u32, u32), Vec<u32>> {
    let mut edges: BTreeMap<(u32, u32), Vec<u32>> = BTreeMap::new();
    for (f, face) in faces.iter().enumerate() {
        for (i, &a) in face.iter().enumerate() {
            let b = face[(i + 1) % face.len()];
            edges.entry((a.min(b), a.max(b))).or_default().push(f as u32);
        }
    }
    edges
}

/// What a vertex touches: its faces, its edges' other ends, and its
/// boundary edges' other ends.
#[derive(Default, Clone)]
struct Ring {
    faces: Vec<u32>,
    neighbours: Vec<u32>,
    boundary: Vec<u32>,
    /// An edge of three or more faces meets the vertex.
    non_manifold: bool,
}

impl Ring {
    /// Vertex `p`'s new position by `interior` (a vertex inside the
    /// surface) or by `boundary` (given its two boundary neighbours); `p`
    /// itself where neither rule applies.
    fn place(&self, p: Vec3, interior: impl FnOnce() -> Vec3, boundary: impl FnOnce(u32, u32) -> Vec3) -> Vec3 {
        if self.non_manifold || self.faces.is_empty() {
            return p;
        }
        match self.boundary[..] {
            [] => interior(),
            [a, b] => boundary(a, b),
            _ => p,
        }
    }
}

fn rings_of(points: usize, faces: &Faces, edges: &BTreeMap<(u32, u32), Vec<u32>>) -> Vec<Ring> {
    let mut rings = vec![Ring::default(); points];
    for (f, face) in faces.iter().enumerate() {
        for &v in face {
            rings[v as usize].faces.push(f as u32);
        }
    }
    for (&(a, b), around) in edges {
        for (v, w) in [(a, b), (b, a)] {
            let r = &mut rings[v as usize];
            r.neighbours.push(w);
            match around.len() {
                1 => r.boundary.push(w),
                2 => {}
                _ => r.non_manifold = true,
            }
        }
    }
    rings
}

/// One round of refinement: a point per face (its centroid), per edge and
/// per vertex, and each n-gon made n quads.
fn refine(points: &[Vec3], faces: &Faces) -> (Vec<Vec3>, Faces) {
    let edges = edges_of(faces);
    let rings = rings_of(points.len(), faces, &edges);
    let face_points: Vec<Vec3> = faces
        .iter()
        .map(|f| f.iter().map(|&v| points[v as usize]).sum::<Vec3>() / f.len() as f32)
        .collect();
    // New points: the vertices, then the faces, then the edges.
    let mut out: Vec<Vec3> = (0..points.len())
        .map(|v| {
            let (r, p) = (&rings[v], points[v]);
            r.place(
                p,
                || {
                    // (F + 2R + (n − 3)P)/n: F the mean of the faces'
                    // points, R of the edges' midpoints.
                    let n = r.neighbours.len() as f32;
                    let f = r.faces.iter().map(|&f| face_points[f as usize]).sum::<Vec3>() / r.faces.len() as f32;
                    let m = r
                        .neighbours
                        .iter()
                        .map(|&w| 0.5 * (p + points[w as usize]))
                        .sum::<Vec3>()
                        / n;
                    (f + 2.0 * m + (n - 3.0) * p) / n
                },
                |a, b| (points[a as usize] + 6.0 * p + points[b as usize]) / 8.0,
            )
        })
        .collect();
    let face_base = out.len() as u32;
    out.extend(&face_points);
    let mut edge_index = HashMap::with_capacity(edges.len());
    for (&(a, b), around) in &edges {
        let mid = 0.5 * (points[a as usize] + points[b as usize]);
        let p = match around.as_slice() {
            [f, g] => 0.5 * mid + 0.25 * (face_points[*f as usize] + face_points[*g as usize]),
            _ => mid,
        };
        edge_index.insert((a, b), out.len() as u32);
        out.push(p);
    }
    let edge = |a: u32, b: u32| edge_index[&(a.min(b), a.max(b))];
    let mut quads = Vec::with_capacity(faces.iter().map(Vec::len).sum());
    for (f, face) in faces.iter().enumerate() {
        let n = face.len();
        for i in 0..n {
            let (prev, v, next) = (face[(i + n - 1) % n], face[i], face[(i + 1) % n]);
            quads.push(vec![v, edge(v, next), face_base + f as u32, edge(prev, v)]);
        }
    }
    (out, quads)
}

/// The limit position of each vertex of a mesh of quads: for an interior
/// vertex of n faces (n² P + 4 Σ eᵢ + Σ fᵢ) / (n (n + 5)), eᵢ its edges'
/// other ends and fᵢ its faces' opposite corners; on the boundary, the
/// cubic B-spline curve's (P₋ + 4 P + P₊) / 6.
fn limit_points(points: &[Vec3], quads: &Faces) -> Vec<Vec3> {
    let edges = edges_of(quads);
    let rings = rings_of(points.len(), quads, &edges);
    (0..points.len())
        .map(|v| {
            let (r, p) = (&rings[v], points[v]);
            r.place(
                p,
                || {
                    let n = r.faces.len() as f32;
                    let e: Vec3 = r.neighbours.iter().map(|&w| points[w as usize]).sum();
                    let f: Vec3 = r
                        .faces
                        .iter()
                        .map(|&f| {
                            let q = &quads[f as usize];
                            let at = q.iter().position(|&w| w == v as u32).expect("the face has the vertex");
                            points[q[(at + 2) % 4] as usize]
                        })
                        .sum();
                    (n * n * p + 4.0 * e + f) / (n * (n + 5.0))
                },
                |a, b| (points[a as usize] + 4.0 * p + points[b as usize]) / 6.0,
            )
        })
        .collect()
}

/// The triangles of `levels` (at least 1) rounds of Catmull–Clark
/// subdivision of the control mesh (`positions`, polygon `faces` of at
/// least three vertices each), with every vertex on the limit surface and
/// the area-weighted normals of its faces. Fails, before allocating, when
/// the result would exceed [`MAX_SUBDIVISION_TRIANGLES`], and on faces
/// that name missing points or have fewer than three.
pub fn catmull_clark(positions: &[Vec3], faces: &[Vec<u32>], levels: u32) -> Result<TriangleMesh, String> {
    if !(1..=MAX_SUBDIVISION_LEVELS).contains(&levels) {
        return Err(format!(
            "{levels} subdivision levels: 1 to {MAX_SUBDIVISION_LEVELS} (each level makes 4 times the faces)"
        ));
    }
    if let Some((i, f)) = faces.iter().enumerate().find(|(_, f)| f.len() < 3) {
        return Err(format!("face {i} has {} vertices; a face needs at least 3", f.len()));
    }
    if let Some(bad) = faces.iter().flatten().find(|&&i| i as usize >= positions.len()) {
        return Err(format!(
            "index {bad} is out of range: the control mesh has {} points",
            positions.len()
        ));
    }
    // The first round makes an n-gon n quads, each later one 4 of each.
    let quads: u64 = faces.iter().map(|f| f.len() as u64).sum();
    let made = quads.saturating_mul(2).saturating_mul(1u64 << (2 * (levels - 1)));
    if made > MAX_SUBDIVISION_TRIANGLES {
        return Err(format!(
            "{} faces subdivided {levels} times make {made} triangles, more than the {MAX_SUBDIVISION_TRIANGLES} allowed",
            faces.len()
        ));
    }
    let mut points = positions.to_vec();
    let mut faces: Faces = faces.to_vec();
    for _ in 0..levels {
        (points, faces) = refine(&points, &faces);
    }
    let limit = limit_points(&points, &faces);
    let indices: Vec<[u32; 3]> = faces
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    let mut normals = vec![Vec3::ZERO; limit.len()];
    for &[a, b, c] in &indices {
        let [pa, pb, pc] = [a, b, c].map(|i| limit[i as usize]);
        let n = (pb - pa).cross(pc - pa);
        for i in [a, b, c] {
            normals[i as usize] += n;
        }
    }
    let normals = normals.into_iter().map(|n| n.normalize_or_zero()).collect();
    Ok(TriangleMesh {
        positions: limit,
        normals,
        uvs: Vec::new(),
        indices,
        attributes: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    /// The cube of corners ±1, six quads facing out.
    fn cube() -> (Vec<Vec3>, Faces) {
        let p: Vec<Vec3> = (0..8)
            .map(|i| {
                Vec3::new(
                    if i & 1 != 0 { 1.0 } else { -1.0 },
                    if i & 2 != 0 { 1.0 } else { -1.0 },
                    if i & 4 != 0 { 1.0 } else { -1.0 },
                )
            })
            .collect();
        let faces = vec![
            vec![0, 2, 3, 1],
            vec![4, 5, 7, 6],
            vec![0, 1, 5, 4],
            vec![2, 6, 7, 3],
            vec![0, 4, 6, 2],
            vec![1, 3, 7, 5],
        ];
        (p, faces)
    }

    /// On a regular grid of quads the limit surface is the uniform bicubic
    /// B-spline: the limit point of an interior control vertex is the
    /// tensor product of the weights (1, 4, 1)/6 over its 3 × 3
    /// neighbours, whatever the number of levels.
    #[test]
    fn a_regular_grid_gives_the_bicubic_b_spline() {
        let mut rng = Pcg32::new(9, 4);
        let n = 7;
        let p: Vec<Vec3> = (0..n * n)
            .map(|k| Vec3::new((k % n) as f32, (k / n) as f32, rng.next_f32()))
            .collect();
        let mut faces = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = (j * n + i) as u32;
                faces.push(vec![v, v + 1, v + 1 + n as u32, v + n as u32]);
            }
        }
        let w = [1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0];
        for levels in 1..=3 {
            let mesh = catmull_clark(&p, &faces, levels).unwrap();
            // The original vertices keep their numbers through refinement.
            for (i, j) in [(3, 3), (2, 4), (4, 2)] {
                let mut expected = Vec3::ZERO;
                for (b, wb) in w.iter().enumerate() {
                    for (a, wa) in w.iter().enumerate() {
                        expected += wa * wb * p[(j + b - 1) * n + (i + a - 1)];
                    }
                }
                let got = mesh.positions[j * n + i];
                assert!(
                    (got - expected).length() < 1e-5,
                    "levels {levels}: {got} against {expected}"
                );
            }
        }
    }

    /// The cube's corners go to (±½, ±½, ±½) (its limit mask at a vertex
    /// of three faces), the surface stays closed (every edge of two
    /// triangles) and inside the cube.
    #[test]
    fn a_cube_becomes_a_closed_rounded_box() {
        let (p, faces) = cube();
        for levels in 1..=3 {
            let mesh = catmull_clark(&p, &faces, levels).unwrap();
            assert_eq!(mesh.indices.len(), 6 * 4usize.pow(levels) * 2);
            for c in 0..8 {
                assert!(
                    (mesh.positions[c].abs() - Vec3::splat(0.5)).length() < 1e-5,
                    "corner {c}: {}",
                    mesh.positions[c]
                );
            }
            assert!(mesh.positions.iter().all(|q| q.abs().max_element() <= 1.0));
            let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
            for t in &mesh.indices {
                for i in 0..3 {
                    let (a, b) = (t[i], t[(i + 1) % 3]);
                    *edges.entry((a.min(b), a.max(b))).or_default() += 1;
                }
            }
            assert!(edges.values().all(|&k| k == 2), "the surface is closed");
            // Normals point out.
            assert!(mesh.positions.iter().zip(&mesh.normals).all(|(q, n)| q.dot(*n) > 0.0));
        }
    }

    /// A flat open grid of triangles and a pentagon stays flat, and its
    /// boundary stays on the boundary's B-spline curve (a corner of two
    /// boundary edges moves to (P₋ + 4P + P₊)/6).
    #[test]
    fn open_flat_meshes_stay_flat_and_keep_their_boundary() {
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(3.0, 1.5, 0.0),
            Vec3::new(1.0, 3.0, 0.0),
            Vec3::new(-1.0, 1.5, 0.0),
            Vec3::new(1.0, -2.0, 0.0),
        ];
        let faces = vec![vec![0, 1, 2, 3, 4], vec![0, 5, 1]];
        let mesh = catmull_clark(&p, &faces, 2).unwrap();
        assert!(mesh.positions.iter().all(|q| q.z == 0.0));
        // Vertex 3 lies on the boundary between 2 and 4.
        let expected = (p[2] + 4.0 * p[3] + p[4]) / 6.0;
        assert!((mesh.positions[3] - expected).length() < 1e-5, "{}", mesh.positions[3]);
    }

    #[test]
    fn bad_control_meshes_are_errors() {
        let (p, faces) = cube();
        assert!(catmull_clark(&p, &faces, 0).unwrap_err().contains("levels"));
        assert!(catmull_clark(&p, &faces, 13).unwrap_err().contains("levels"));
        assert!(catmull_clark(&p, &[vec![0, 1]], 1).unwrap_err().contains("at least 3"));
        assert!(
            catmull_clark(&p, &[vec![0, 1, 8]], 1)
                .unwrap_err()
                .contains("out of range")
        );
        assert!(catmull_clark(&p, &faces, 12).unwrap_err().contains("more than"));
    }
}
