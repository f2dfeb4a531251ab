//! Loop subdivision surfaces (Loop 1987, "Smooth Subdivision Surfaces
//! Based on Triangles"), as pbrt-v4's `loopsubdiv` shape renders them:
//! `levels` rounds of refinement of the control mesh, then every vertex
//! moved to its limit position and given the limit surface's normal
//! (Hoppe et al. 1994, "Piecewise Smooth Surface Reconstruction", for the
//! limit masks and tangents; pbrt-v4's book, section "Loop Subdivision
//! Surfaces", for the boundary rules).
//!
//! Boundary edges (one face) keep the surface pinned to the boundary
//! curve. A vertex whose faces do not form one fan (an edge with three or
//! more faces, two cones meeting at a point) has no Loop rule; it stays
//! where it is and takes the mean normal of its faces.

use std::collections::HashMap;

use glam::Vec3;

use super::TriangleMesh;

/// The most triangles a subdivision may make (about 1.3 GB of mesh before
/// its tree).
pub const MAX_SUBDIVISION_TRIANGLES: u64 = 1 << 25;

/// The most refinement rounds accepted (each multiplies the faces by 4).
pub const MAX_SUBDIVISION_LEVELS: u32 = 12;

/// The triangles of `levels` rounds of Loop subdivision of the control mesh
/// (`positions`, `faces`), with every vertex on the limit surface and its
/// limit normal; no texture coordinates. Faces that repeat a vertex are
/// dropped. Fails, before allocating, when the result would exceed
/// [`MAX_SUBDIVISION_TRIANGLES`].
pub fn loop_subdivide(positions: &[Vec3], faces: &[[u32; 3]], levels: u32) -> Result<TriangleMesh, String> {
    if levels > MAX_SUBDIVISION_LEVELS {
        return Err(format!(
            "{levels} subdivision levels is too many (at most {MAX_SUBDIVISION_LEVELS}; each level makes 4 times the triangles)"
        ));
    }
    if let Some(bad) = faces.iter().flatten().find(|&&i| i as usize >= positions.len()) {
        return Err(format!(
            "index {bad} is out of range: the control mesh has {} points",
            positions.len()
        ));
    }
    let mut faces: Vec<[u32; 3]> = faces
        .iter()
        .copied()
        .filter(|[a, b, c]| a != b && b != c && c != a)
        .collect();
    let made = (faces.len() as u64).saturating_mul(1u64 << (2 * levels));
    if made > MAX_SUBDIVISION_TRIANGLES {
        return Err(format!(
            "{} triangles subdivided {levels} times make {made} triangles, more than the {MAX_SUBDIVISION_TRIANGLES} allowed",
            faces.len()
        ));
    }
    let mut points = positions.to_vec();
    for _ in 0..levels {
        (points, faces) = refine(&points, &faces);
    }
    let rings = Rings::new(points.len(), &faces);
    let limit: Vec<Vec3> = (0..points.len()).map(|v| rings.limit_point(v, &points)).collect();
    let face_normals = area_weighted_normals(&limit, &faces);
    let normals = (0..limit.len())
        .map(|v| rings.limit_normal(v, &limit, face_normals[v]))
        .collect();
    Ok(TriangleMesh {
        positions: limit,
        normals,
        uvs: Vec::new(),
        indices: faces,
        attributes: Vec::new(),
    })
}

/// Loop's β for an interior vertex of `valence` neighbours: 3/16 for a
/// valence of 3, 3/(8n) otherwise (Warren's simplification).
fn beta(valence: usize) -> f32 {
    if valence == 3 {
        3.0 / 16.0
    } else {
        3.0 / (8.0 * valence as f32)
    }
}

/// The one-ring of every vertex in order around it, and whether it is an
/// interior fan, a boundary fan or neither.
struct Rings {
    /// `ring[start[v]..start[v + 1]]` are vertex `v`'s neighbours in order
    /// (a boundary fan's two boundary neighbours first and last).
    start: Vec<usize>,
    ring: Vec<u32>,
    kind: Vec<RingKind>,
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum RingKind {
    /// The faces close around the vertex.
    Interior,
    /// The faces form one open fan: the vertex is on the boundary.
    Boundary,
    /// No faces, or faces that are not one fan.
    Irregular,
}

impl Rings {
    fn new(vertex_count: usize, faces: &[[u32; 3]]) -> Rings {
        // Each face adds, to the link of each of its corners, the edge
        // between the other two corners. Ordering does not rely on the
        // faces' winding agreeing.
        let mut link_start = vec![0usize; vertex_count + 1];
        for f in faces {
            for &v in f {
                link_start[v as usize + 1] += 1;
            }
        }
        for v in 0..vertex_count {
            link_start[v + 1] += link_start[v];
        }
        let mut fill = link_start.clone();
        let mut links = vec![(0u32, 0u32); link_start[vertex_count]];
        for &[a, b, c] in faces {
            for (v, e) in [(a, (b, c)), (b, (c, a)), (c, (a, b))] {
                links[fill[v as usize]] = e;
                fill[v as usize] += 1;
            }
        }
        let mut start = Vec::with_capacity(vertex_count + 1);
        let mut ring = Vec::with_capacity(links.len());
        let mut kind = Vec::with_capacity(vertex_count);
        let mut scratch = Vec::new();
        start.push(0);
        for v in 0..vertex_count {
            let k = order_link(&links[link_start[v]..link_start[v + 1]], &mut scratch, &mut ring);
            kind.push(k);
            start.push(ring.len());
        }
        Rings { start, ring, kind }
    }

    fn of(&self, v: usize) -> &[u32] {
        &self.ring[self.start[v]..self.start[v + 1]]
    }

    /// The vertex's position after one round of refinement (the "even"
    /// rule).
    fn refined_point(&self, v: usize, points: &[Vec3]) -> Vec3 {
        let ring = self.of(v);
        match self.kind[v] {
            RingKind::Interior => {
                let b = beta(ring.len());
                one_ring_mix(points[v], ring, points, b)
            }
            RingKind::Boundary => boundary_mix(points[v], ring, points, 1.0 / 8.0),
            RingKind::Irregular => points[v],
        }
    }

    /// The vertex's limit position: interior weight γ = 1/(n + 3/(8β)),
    /// boundary weights 3/5, 1/5, 1/5 (pbrt-v4's, not the cubic B-spline
    /// curve's 2/3, 1/6, 1/6).
    fn limit_point(&self, v: usize, points: &[Vec3]) -> Vec3 {
        let ring = self.of(v);
        match self.kind[v] {
            RingKind::Interior => {
                let n = ring.len() as f32;
                let gamma = 1.0 / (n + 3.0 / (8.0 * beta(ring.len())));
                one_ring_mix(points[v], ring, points, gamma)
            }
            RingKind::Boundary => boundary_mix(points[v], ring, points, 1.0 / 5.0),
            RingKind::Irregular => points[v],
        }
    }

    /// The limit surface's normal at vertex `v` of the limit mesh `limit`,
    /// from its two limit tangents, turned to the side of `face_normal`
    /// (the area-weighted normal of its faces, used where the tangents
    /// are degenerate or the vertex has no Loop rule).
    fn limit_normal(&self, v: usize, limit: &[Vec3], face_normal: Vec3) -> Vec3 {
        let ring = self.of(v);
        let p = limit[v];
        let r = |i: usize| limit[ring[i] as usize];
        let k = ring.len();
        let tangents = match self.kind[v] {
            RingKind::Interior => {
                let (mut s, mut t) = (Vec3::ZERO, Vec3::ZERO);
                for i in 0..k {
                    let angle = std::f32::consts::TAU * i as f32 / k as f32;
                    s += angle.cos() * r(i);
                    t += angle.sin() * r(i);
                }
                Some((s, t))
            }
            RingKind::Boundary => {
                let s = r(k - 1) - r(0);
                let t = match k {
                    2 => r(0) + r(1) - 2.0 * p,
                    3 => r(1) - p,
                    4 => -r(0) + 2.0 * r(1) + 2.0 * r(2) - r(3) - 2.0 * p,
                    _ => {
                        let theta = std::f32::consts::PI / (k - 1) as f32;
                        let mut t = theta.sin() * (r(0) + r(k - 1));
                        for (j, &q) in ring.iter().enumerate().take(k - 1).skip(1) {
                            let w = (2.0 * theta.cos() - 2.0) * (j as f32 * theta).sin();
                            t += w * limit[q as usize];
                        }
                        -t
                    }
                };
                Some((s, t))
            }
            RingKind::Irregular => None,
        };
        let fallback = face_normal.try_normalize().unwrap_or(Vec3::Z);
        match tangents.and_then(|(s, t)| s.cross(t).try_normalize()) {
            Some(n) if n.dot(face_normal) < 0.0 => -n,
            Some(n) => n,
            None => fallback,
        }
    }
}

/// Orders a vertex's link edges into one chain, appending its vertices to
/// `ring`: a cycle for an interior vertex, a path (ends first and last)
/// for a boundary vertex. Anything else appends nothing.
fn order_link(edges: &[(u32, u32)], scratch: &mut Vec<(u32, u32)>, ring: &mut Vec<u32>) -> RingKind {
    if edges.is_empty() {
        return RingKind::Irregular;
    }
    // Each link vertex's neighbours in the link, sorted by vertex.
    scratch.clear();
    for &(a, b) in edges {
        if a == b {
            return RingKind::Irregular;
        }
        scratch.push((a, b));
        scratch.push((b, a));
    }
    scratch.sort_unstable();
    let neighbours = |x: u32| -> &[(u32, u32)] {
        let lo = scratch.partition_point(|e| e.0 < x);
        let hi = scratch.partition_point(|e| e.0 <= x);
        &scratch[lo..hi]
    };
    // Every link vertex needs one or two distinct neighbours; exactly zero
    // or two have one (interior or boundary).
    let mut ends = Vec::new();
    let mut count = 0;
    let mut i = 0;
    while i < scratch.len() {
        let x = scratch[i].0;
        let run = neighbours(x);
        match run {
            [_] => ends.push(x),
            [a, b] if a.1 != b.1 => {}
            _ => return RingKind::Irregular,
        }
        count += 1;
        i += run.len();
    }
    let kind = match ends.len() {
        0 => RingKind::Interior,
        2 => RingKind::Boundary,
        _ => return RingKind::Irregular,
    };
    let first = ends.first().copied().unwrap_or(scratch[0].0);
    let begin = ring.len();
    let (mut prev, mut at) = (u32::MAX, first);
    loop {
        ring.push(at);
        let next = neighbours(at).iter().map(|e| e.1).find(|&n| n != prev);
        match next {
            Some(n) if n != first && ring.len() - begin < count => {
                prev = at;
                at = n;
            }
            _ => break,
        }
    }
    if ring.len() - begin != count {
        // Two separate fans meet at this vertex.
        ring.truncate(begin);
        return RingKind::Irregular;
    }
    kind
}

/// (1 − nw) p + w Σ ring.
fn one_ring_mix(p: Vec3, ring: &[u32], points: &[Vec3], w: f32) -> Vec3 {
    let sum: Vec3 = ring.iter().map(|&q| points[q as usize]).sum();
    (1.0 - ring.len() as f32 * w) * p + w * sum
}

/// (1 − 2w) p + w (b₀ + b₁) over the two boundary neighbours.
fn boundary_mix(p: Vec3, ring: &[u32], points: &[Vec3], w: f32) -> Vec3 {
    let b0 = points[ring[0] as usize];
    let b1 = points[ring[ring.len() - 1] as usize];
    (1.0 - 2.0 * w) * p + w * (b0 + b1)
}

/// Each vertex's sum of its faces' normals weighted by area.
fn area_weighted_normals(points: &[Vec3], faces: &[[u32; 3]]) -> Vec<Vec3> {
    let mut sum = vec![Vec3::ZERO; points.len()];
    for &[a, b, c] in faces {
        let [pa, pb, pc] = [a, b, c].map(|i| points[i as usize]);
        let n = (pb - pa).cross(pc - pa);
        for i in [a, b, c] {
            sum[i as usize] += n;
        }
    }
    sum
}

/// One round of Loop refinement: each vertex moved by the even rule, a new
/// vertex on each edge, each face split into four.
fn refine(points: &[Vec3], faces: &[[u32; 3]]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let rings = Rings::new(points.len(), faces);
    let mut out: Vec<Vec3> = (0..points.len()).map(|v| rings.refined_point(v, points)).collect();

    // Edges: their ends, the corners opposite them and how many faces
    // share them.
    struct Edge {
        ends: [u32; 2],
        opposite: [u32; 2],
        faces: u32,
    }
    let mut edge_of: HashMap<(u32, u32), u32> = HashMap::with_capacity(faces.len() * 3 / 2 + 1);
    let mut edges: Vec<Edge> = Vec::with_capacity(faces.len() * 3 / 2 + 1);
    let mut face_edges = Vec::with_capacity(faces.len());
    for f in faces {
        let mut ids = [0u32; 3];
        for (i, id) in ids.iter_mut().enumerate() {
            let (a, b) = (f[i], f[(i + 1) % 3]);
            let opposite = f[(i + 2) % 3];
            let key = (a.min(b), a.max(b));
            *id = *edge_of.entry(key).or_insert_with(|| {
                edges.push(Edge {
                    ends: [a, b],
                    opposite: [opposite, opposite],
                    faces: 0,
                });
                (edges.len() - 1) as u32
            });
            let e = &mut edges[*id as usize];
            if e.faces == 1 {
                e.opposite[1] = opposite;
            }
            e.faces += 1;
        }
        face_edges.push(ids);
    }
    let base = out.len() as u32;
    out.extend(edges.iter().map(|e| {
        let [a, b] = e.ends.map(|i| points[i as usize]);
        if e.faces == 2 {
            let [c, d] = e.opposite.map(|i| points[i as usize]);
            0.375 * (a + b) + 0.125 * (c + d)
        } else {
            // A boundary edge, or one that three or more faces share: the
            // new vertex stays on the edge.
            0.5 * (a + b)
        }
    }));

    let mut refined = Vec::with_capacity(faces.len() * 4);
    for (&[v0, v1, v2], ids) in faces.iter().zip(&face_edges) {
        // m0 on v0v1, m1 on v1v2, m2 on v2v0.
        let [m0, m1, m2] = ids.map(|e| base + e);
        refined.push([v0, m0, m2]);
        refined.push([v1, m1, m0]);
        refined.push([v2, m2, m1]);
        refined.push([m0, m1, m2]);
    }
    (out, refined)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A regular octahedron of radius 1: every vertex of valence 4.
    fn octahedron() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        let f = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        (p, f)
    }

    #[test]
    fn level_zero_moves_each_vertex_to_its_limit() {
        let (p, f) = octahedron();
        let m = loop_subdivide(&p, &f, 0).unwrap();
        assert_eq!(m.indices, f);
        // Valence 4: β = 3/32, γ = 1/(4 + 4) = 1/8. The ring of +x is
        // ±y, ±z, whose sum is 0: the limit is (1 − 4/8) · x = x / 2.
        for (q, l) in p.iter().zip(&m.positions) {
            assert!((*l - 0.5 * *q).length() < 1e-6, "{q} → {l}");
        }
        // By symmetry the limit normal at each vertex points away from the
        // centre.
        for (q, n) in p.iter().zip(&m.normals) {
            assert!((*n - *q).length() < 1e-5, "{q}: {n}");
        }
    }

    #[test]
    fn each_level_quadruples_the_faces_and_keeps_a_closed_mesh_closed() {
        let (p, f) = octahedron();
        for levels in 0..4 {
            let m = loop_subdivide(&p, &f, levels).unwrap();
            assert_eq!(m.indices.len(), 8 << (2 * levels));
            // Euler: V − E + F = 2 with E = 3F/2.
            let v = m.positions.len() as i64;
            let faces = m.indices.len() as i64;
            assert_eq!(v - 3 * faces / 2 + faces, 2);
            m.validate().unwrap();
            let rings = Rings::new(m.positions.len(), &m.indices);
            assert!(rings.kind.iter().all(|&k| k == RingKind::Interior));
        }
    }

    #[test]
    fn refining_further_keeps_each_limit_point() {
        // The limit mask is the refinement rule's dominant eigenvector: a
        // vertex's limit point does not move when the mesh is refined
        // first. Even vertices keep their numbers, so level L's points are
        // the first points of level L + 1 — for interior vertices of
        // valence 3, 4 and 6 (a tetrahedron, an octahedron, refined ones).
        // (pbrt-v4's boundary limit weights, 3/5 and 1/5, are not the
        // boundary curve's own 2/3 and 1/6, so boundaries lack this
        // property in pbrt too; trazo keeps pbrt's weights.)
        let tetrahedron = (
            vec![
                Vec3::new(1.0, 1.0, 1.0),
                Vec3::new(1.0, -1.0, -1.0),
                Vec3::new(-1.0, 1.0, -1.0),
                Vec3::new(-1.0, -1.0, 1.0),
            ],
            vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]],
        );
        for (p, f) in [octahedron(), tetrahedron] {
            for levels in 0..3 {
                let coarse = loop_subdivide(&p, &f, levels).unwrap();
                let fine = loop_subdivide(&p, &f, levels + 1).unwrap();
                for (a, b) in coarse.positions.iter().zip(&fine.positions) {
                    assert!((*a - *b).length() < 1e-5, "level {levels}: {a} then {b}");
                }
            }
        }
        // The octahedron's limit surface is star-shaped about its centre,
        // inside the hull, and its normals point outward (the faces wind
        // counter-clockwise seen from outside).
        let (p, f) = octahedron();
        let m = loop_subdivide(&p, &f, 3).unwrap();
        for (q, n) in m.positions.iter().zip(&m.normals) {
            assert!(q.length() > 0.3 && q.length() < 1.0, "{q}");
            assert!(n.dot(*q) > 0.0);
            assert!((n.length() - 1.0).abs() < 1e-5);
        }
    }

    /// A flat grid of `n` × `n` squares in the plane z = 0, each split into
    /// two triangles.
    fn grid(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                p.push(Vec3::new(i as f32, j as f32, 0.0));
            }
        }
        let at = |i: u32, j: u32| j * (n + 1) + i;
        let mut f = Vec::new();
        for j in 0..n {
            for i in 0..n {
                f.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                f.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        (p, f)
    }

    #[test]
    fn a_flat_grid_stays_flat_with_its_boundary_on_the_square() {
        let (p, f) = grid(4);
        let m = loop_subdivide(&p, &f, 2).unwrap();
        for (q, n) in m.positions.iter().zip(&m.normals) {
            assert!(q.z.abs() < 1e-6);
            assert!((*n - Vec3::Z).length() < 1e-5, "{q}: {n}");
            // Boundary points move only along the boundary, so nothing
            // leaves the square.
            assert!(q.x >= -1e-5 && q.x <= 4.0 + 1e-5 && q.y >= -1e-5 && q.y <= 4.0 + 1e-5);
        }
        // An affine function of position is reproduced by every mask, so
        // the limit of a planar regular region is the plane itself: the
        // centre vertex (valence 6) stays at (2, 2).
        assert!(
            m.positions
                .iter()
                .any(|q| (*q - Vec3::new(2.0, 2.0, 0.0)).length() < 1e-5)
        );
        // A boundary vertex of valence 4 on a straight boundary stays put:
        // 3/5 p + 1/5 (p − e) + 1/5 (p + e) = p.
        assert!(
            m.positions
                .iter()
                .any(|q| (*q - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-5)
        );
    }

    #[test]
    fn boundary_normals_of_a_bent_strip_follow_the_bend() {
        // A single triangle: three boundary vertices of valence 2. Its limit
        // surface is the triangle's plane, normal along its winding.
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let m = loop_subdivide(&p, &[[0, 1, 2]], 3).unwrap();
        for n in &m.normals {
            assert!((*n - Vec3::Z).length() < 1e-5, "{n}");
        }
        let m = loop_subdivide(&p, &[[0, 2, 1]], 3).unwrap();
        for n in &m.normals {
            assert!((*n + Vec3::Z).length() < 1e-5, "{n}");
        }
    }

    #[test]
    fn non_manifold_and_degenerate_input_renders_without_panicking() {
        // Three triangles on one edge, a repeated-corner face, an unused
        // vertex, a bow-tie vertex and a zero-area face.
        let p = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            -Vec3::Y,
            Vec3::Z,
            Vec3::new(5.0, 5.0, 5.0),
            Vec3::new(-1.0, 0.0, 1.0),
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(2.0, 0.0, 0.0),
        ];
        let f = [[0, 1, 2], [1, 0, 3], [0, 1, 4], [2, 2, 1], [0, 6, 7], [0, 1, 8]];
        let m = loop_subdivide(&p, &f, 2).unwrap();
        assert_eq!(m.indices.len(), 5 * 16);
        m.validate().unwrap();
        assert!(m.positions.iter().chain(&m.normals).all(|v| v.is_finite()));
        assert!(m.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4));
    }

    #[test]
    fn too_many_levels_or_triangles_is_an_error_before_any_work() {
        let (p, f) = octahedron();
        let e = loop_subdivide(&p, &f, 40).unwrap_err();
        assert!(e.contains("40 subdivision levels"), "{e}");
        let e = loop_subdivide(&p, &f, 12).unwrap_err();
        assert!(e.contains("more than the"), "{e}");
        let e = loop_subdivide(&p, &[[0, 1, 9]], 1).unwrap_err();
        assert!(e.contains("out of range"), "{e}");
    }
}
