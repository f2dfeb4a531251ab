//! Indexed triangle meshes with optional per-vertex normals and UVs.

use super::bounds::{Aabb, gamma};
use super::ray::Ray;
use super::shape::{AreaSample, LocalSurface};
use super::transform::Transform;
use super::triangle::{TriangleHit, TriangleRay, intersect_triangle, intersect_triangle_with};
use crate::sampling::warp::{orthonormal_basis, sample_triangle_uniform};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// The angle between two unit vectors, accurate near 0 and π too (from the
/// chord between them rather than the arc cosine of their dot product).
fn unit_angle(a: Vec3, b: Vec3) -> f32 {
    if a.dot(b) < 0.0 {
        PI - 2.0 * ((a + b).length() / 2.0).min(1.0).asin()
    } else {
        2.0 * ((a - b).length() / 2.0).min(1.0).asin()
    }
}

/// A triangle mesh. Faces wind counter-clockwise seen from their front side.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex normals: empty, or one per position.
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates: empty, or one per position.
    pub uvs: Vec<Vec2>,
    /// Vertex indices of each triangle.
    pub indices: Vec<[u32; 3]>,
    /// Other values per vertex or per triangle, by name (Mitsuba's mesh
    /// attributes). A scene keeps only the one its material reads, first.
    pub attributes: Vec<MeshAttribute>,
}

/// Values a mesh carries per vertex or per triangle besides its geometry
/// (a PLY file's colours, weights…), named as Mitsuba names them:
/// `vertex_color`, `face_weight`.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshAttribute {
    /// `vertex_…` or `face_…`.
    pub name: String,
    /// Whether there is one value per triangle (else one per vertex).
    pub per_face: bool,
    /// Channels per value (1 to 4).
    pub channels: usize,
    /// The values, `channels` numbers each.
    pub values: Vec<f32>,
}

impl MeshAttribute {
    /// The first three channels of element `i` (one channel as grey).
    #[inline]
    fn get(&self, i: usize) -> Vec3 {
        let v = &self.values[i * self.channels..(i + 1) * self.channels];
        match v {
            [g] => Vec3::splat(*g),
            [a, b] => Vec3::new(*a, *b, 0.0),
            [a, b, c, ..] => Vec3::new(*a, *b, *c),
            [] => Vec3::ZERO,
        }
    }
}

/// Why a mesh is unusable.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshError {
    /// A face refers to a vertex that does not exist.
    IndexOutOfRange {
        /// Face number.
        face: usize,
        /// The bad index.
        index: u32,
        /// Number of vertices.
        vertices: usize,
    },
    /// `normals` or `uvs` has the wrong length.
    AttributeCount {
        /// Which attribute.
        attribute: &'static str,
        /// Its length.
        len: usize,
        /// Number of vertices.
        vertices: usize,
    },
    /// A position is NaN or infinite.
    NonFinite {
        /// Vertex number.
        vertex: usize,
    },
}

impl std::fmt::Display for MeshError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MeshError::IndexOutOfRange { face, index, vertices } => write!(
                f,
                "face {face} uses vertex {index}, but the mesh has {vertices} vertices"
            ),
            MeshError::AttributeCount {
                attribute,
                len,
                vertices,
            } => write!(
                f,
                "{len} {attribute} given for {vertices} vertices (need one per vertex, or none)"
            ),
            MeshError::NonFinite { vertex } => {
                write!(f, "vertex {vertex} has a NaN or infinite coordinate")
            }
        }
    }
}

impl TriangleMesh {
    /// Checks indices and attribute counts.
    pub fn validate(&self) -> Result<(), MeshError> {
        let n = self.positions.len();
        for (attribute, len) in [("normals", self.normals.len()), ("uvs", self.uvs.len())] {
            if len != 0 && len != n {
                return Err(MeshError::AttributeCount {
                    attribute,
                    len,
                    vertices: n,
                });
            }
        }
        for a in &self.attributes {
            let count = if a.per_face { self.indices.len() } else { n };
            if !(1..=4).contains(&a.channels) || a.values.len() != count * a.channels {
                return Err(MeshError::AttributeCount {
                    attribute: if a.per_face {
                        "face attribute values"
                    } else {
                        "vertex attribute values"
                    },
                    len: a.values.len(),
                    vertices: count,
                });
            }
        }
        if let Some(vertex) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::NonFinite { vertex });
        }
        for (face, tri) in self.indices.iter().enumerate() {
            for &index in tri {
                if index as usize >= n {
                    return Err(MeshError::IndexOutOfRange {
                        face,
                        index,
                        vertices: n,
                    });
                }
            }
        }
        Ok(())
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    /// Whether the mesh has no triangles.
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    /// The value of the mesh's first attribute on triangle `i` at
    /// barycentrics `b` (interpolated per vertex, constant per face), or 0.
    #[inline]
    pub fn attribute(&self, i: usize, b: [f32; 3]) -> Vec3 {
        let Some(a) = self.attributes.first() else {
            return Vec3::ZERO;
        };
        if a.per_face {
            a.get(i)
        } else {
            let [ia, ib, ic] = self.indices[i].map(|x| x as usize);
            b[0] * a.get(ia) + b[1] * a.get(ib) + b[2] * a.get(ic)
        }
    }

    /// The three vertex positions of triangle `i`.
    #[inline]
    pub fn vertices(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Bounds of triangle `i`.
    #[inline]
    pub fn triangle_bounds(&self, i: usize) -> Aabb {
        let [a, b, c] = self.vertices(i);
        Aabb::new(a, b).union_point(c)
    }

    /// Bounds of the whole mesh.
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.positions.iter().copied())
    }

    /// Intersects triangle `i`.
    #[inline]
    pub fn intersect(&self, i: usize, ray: &Ray) -> Option<TriangleHit> {
        let [a, b, c] = self.vertices(i);
        intersect_triangle(ray, a, b, c)
    }

    /// [`TriangleMesh::intersect`] with the ray's part of the test
    /// computed once for all the triangles a traversal meets.
    #[inline(always)]
    pub fn intersect_with(&self, i: usize, ray: &Ray, pre: &TriangleRay) -> Option<TriangleHit> {
        let [a, b, c] = self.vertices(i);
        intersect_triangle_with(ray, pre, a, b, c)
    }

    /// Area of triangle `i`.
    pub fn triangle_area(&self, i: usize) -> f32 {
        let [a, b, c] = self.vertices(i);
        0.5 * (b - a).cross(c - a).length()
    }

    /// The surface of triangle `i` at barycentrics `b`.
    pub fn surface(&self, i: usize, b: [f32; 3]) -> LocalSurface {
        let [ia, ib, ic] = self.indices[i].map(|x| x as usize);
        let [p0, p1, p2] = [self.positions[ia], self.positions[ib], self.positions[ic]];
        // The point from barycentrics, not from o + t·d: its error is small
        // and known (pbrt-v4, eq. 6.43).
        let p = b[0] * p0 + b[1] * p1 + b[2] * p2;
        let p_error = gamma(7) * ((b[0] * p0).abs() + (b[1] * p1).abs() + (b[2] * p2).abs());
        let mut n = (p1 - p0).cross(p2 - p0).normalize_or_zero();
        if n == Vec3::ZERO {
            n = Vec3::Z; // degenerate: never hit, but keep the frame finite
        }
        let (uv0, uv1, uv2) = if self.uvs.is_empty() {
            (Vec2::ZERO, Vec2::X, Vec2::ONE)
        } else {
            (self.uvs[ia], self.uvs[ib], self.uvs[ic])
        };
        let uv = b[0] * uv0 + b[1] * uv1 + b[2] * uv2;
        // dp/du from the two edge equations dp = dpdu·du + dpdv·dv.
        let (duv02, duv12) = (uv0 - uv2, uv1 - uv2);
        let (dp02, dp12) = (p0 - p2, p1 - p2);
        let det = duv02.x * duv12.y - duv02.y * duv12.x;
        let (dpdu, dpdv) = if det.abs() < 1e-12 {
            orthonormal_basis(n)
        } else {
            (
                (duv12.y * dp02 - duv02.y * dp12) / det,
                (duv02.x * dp12 - duv12.x * dp02) / det,
            )
        };
        LocalSurface {
            p,
            p_error,
            n,
            uv,
            dpdu,
            dpdv,
        }
    }

    /// Interpolated vertex normal of triangle `i` (unit length), if the
    /// mesh has normals and they do not cancel out.
    pub fn shading_normal(&self, i: usize, b: [f32; 3]) -> Option<Vec3> {
        if self.normals.is_empty() {
            return None;
        }
        let [ia, ib, ic] = self.indices[i].map(|x| x as usize);
        (b[0] * self.normals[ia] + b[1] * self.normals[ib] + b[2] * self.normals[ic]).try_normalize()
    }

    /// A point uniformly distributed on triangle `i`, and the mesh
    /// attribute's value there.
    pub fn sample_triangle(&self, i: usize, u: Vec2) -> (AreaSample, Vec3) {
        let b = sample_triangle_uniform(u);
        let [p0, p1, p2] = self.vertices(i);
        let mut n = (p1 - p0).cross(p2 - p0).normalize_or_zero();
        if let Some(ns) = self.shading_normal(i, b) {
            if ns.dot(n) < 0.0 {
                n = -n;
            }
        }
        let uv = if self.uvs.is_empty() {
            Vec2::new(b[1] + b[2], b[2])
        } else {
            let [ia, ib, ic] = self.indices[i].map(|x| x as usize);
            b[0] * self.uvs[ia] + b[1] * self.uvs[ib] + b[2] * self.uvs[ic]
        };
        let sample = AreaSample {
            p: b[0] * p0 + b[1] * p1 + b[2] * p2,
            n,
            uv,
        };
        (sample, self.attribute(i, b))
    }

    /// The mesh with its vertices and normals transformed (for meshes that
    /// are placed once, whose transform is baked in at load time).
    pub fn transformed(&self, t: &Transform) -> TriangleMesh {
        let flip = t.swaps_handedness();
        TriangleMesh {
            positions: self.positions.iter().map(|&p| t.point(p)).collect(),
            normals: self.normals.iter().map(|&n| t.normal(n).normalize_or_zero()).collect(),
            uvs: self.uvs.clone(),
            attributes: self.attributes.clone(),
            // A mirroring transform reverses winding; swap two indices so
            // that faces keep their front side.
            indices: if flip {
                self.indices.iter().map(|&[a, b, c]| [a, c, b]).collect()
            } else {
                self.indices.clone()
            },
        }
    }

    /// The mesh with its front and back swapped: winding reversed, vertex
    /// normals negated.
    pub fn flipped(mut self) -> TriangleMesh {
        for t in &mut self.indices {
            t.swap(1, 2);
        }
        for n in &mut self.normals {
            *n = -*n;
        }
        self
    }

    /// Gives the mesh smooth vertex normals, replacing any it has: each
    /// triangle adds its unit normal to its corners' normals, weighted by
    /// the corner's interior angle (Thürmer and Wüthrich 1998, "Computing
    /// Vertex Normals from Polygonal Facets", as Mitsuba 3 smooths meshes
    /// that come without normals). A vertex that only degenerate
    /// triangles use gets +x, as in Mitsuba.
    pub fn compute_vertex_normals(&mut self) {
        let mut sums = vec![Vec3::ZERO; self.positions.len()];
        for &tri in &self.indices {
            let p = tri.map(|i| self.positions[i as usize]);
            let Some(n) = (p[1] - p[0]).cross(p[2] - p[0]).try_normalize() else {
                continue;
            };
            for k in 0..3 {
                let e1 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
                let e2 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
                sums[tri[k] as usize] += n * unit_angle(e1, e2);
            }
        }
        self.normals = sums.into_iter().map(|n| n.try_normalize().unwrap_or(Vec3::X)).collect();
    }
    /// A latitude–longitude sphere of `segments` × `rings` quads (two
    /// triangles each, fans at the poles), with normals and UVs. Useful for
    /// stress tests: 1000 × 500 gives about one million triangles.
    pub fn uv_sphere(center: Vec3, radius: f32, segments: u32, rings: u32) -> TriangleMesh {
        let segments = segments.max(3);
        let rings = rings.max(2);
        let mut m = TriangleMesh::default();
        for j in 0..=rings {
            let v = j as f32 / rings as f32;
            let theta = PI * (1.0 - v); // v = 1 at the north pole
            for i in 0..=segments {
                let u = i as f32 / segments as f32;
                let phi = 2.0 * PI * u;
                let n = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
                m.positions.push(center + radius * n);
                m.normals.push(n);
                m.uvs.push(Vec2::new(u, v));
            }
        }
        let row = segments + 1;
        for j in 0..rings {
            for i in 0..segments {
                let a = j * row + i;
                let b = a + 1;
                let c = a + row;
                let d = c + 1;
                // Counter-clockwise seen from outside.
                if j != 0 {
                    m.indices.push([a, c, b]);
                }
                if j != rings - 1 {
                    m.indices.push([b, c, d]);
                }
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> TriangleMesh {
        TriangleMesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(2.0, 0.0, -2.0),
                Vec3::new(0.0, 0.0, -2.0),
            ],
            normals: vec![],
            uvs: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            attributes: Vec::new(),
        }
    }

    #[test]
    fn computed_vertex_normals_weigh_faces_by_corner_angle() {
        let mut m = quad();
        m.compute_vertex_normals();
        assert!(
            m.normals.iter().all(|n| (*n - Vec3::Y).length() < 1e-6),
            "{:?}",
            m.normals
        );
        // Vertex 0 is a 90° corner of a triangle facing +z and a 45° corner
        // of one facing +x: its normal leans twice as far towards +z. The
        // unused vertex 4 gets Mitsuba's fallback.
        let mut m = TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.0, 1.0, 1.0), Vec3::ONE],
            normals: vec![],
            uvs: vec![],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            attributes: Vec::new(),
        };
        m.compute_vertex_normals();
        let expected = Vec3::new(1.0, 0.0, 2.0).normalize();
        assert!((m.normals[0] - expected).length() < 1e-6, "{}", m.normals[0]);
        assert_eq!(m.normals[1], Vec3::Z);
        assert_eq!(m.normals[4], Vec3::X);
    }

    #[test]
    fn validation_catches_bad_indices_and_counts() {
        let mut m = quad();
        assert!(m.validate().is_ok());
        m.indices.push([0, 1, 9]);
        assert!(matches!(m.validate(), Err(MeshError::IndexOutOfRange { index: 9, .. })));
        let mut m = quad();
        m.normals = vec![Vec3::Y];
        assert!(matches!(m.validate(), Err(MeshError::AttributeCount { .. })));
        let mut m = quad();
        m.positions[1].x = f32::NAN;
        assert!(matches!(m.validate(), Err(MeshError::NonFinite { vertex: 1 })));
    }

    #[test]
    fn surface_interpolates_uv_and_faces_front() {
        let m = quad();
        let r = Ray::new(Vec3::new(1.5, 1.0, -0.5), -Vec3::Y);
        let h = m.intersect(0, &r).unwrap();
        let s = m.surface(0, h.b);
        assert!((s.p - Vec3::new(1.5, 0.0, -0.5)).length() < 1e-6);
        assert!((s.n - Vec3::Y).length() < 1e-6); // CCW seen from +y
        assert!((s.uv - Vec2::new(0.75, 0.25)).length() < 1e-6);
        // dp/du points along +x (u grows with x), with length 2 per unit u.
        assert!((s.dpdu - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-5);
    }

    #[test]
    fn interpolated_normals() {
        let mut m = quad();
        m.normals = vec![Vec3::Y, Vec3::Y, Vec3::X, Vec3::X];
        let n = m.shading_normal(0, [0.5, 0.5, 0.0]).unwrap();
        assert!((n - Vec3::Y).length() < 1e-6);
        let n = m.shading_normal(0, [0.0, 0.5, 0.5]).unwrap();
        assert!((n - Vec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-6);
    }

    #[test]
    fn mirroring_keeps_the_front_side() {
        let m = quad();
        let t = Transform::scale(Vec3::new(-1.0, 1.0, 1.0)).unwrap();
        let mm = m.transformed(&t);
        let s = mm.surface(0, [1.0 / 3.0; 3]);
        assert!((s.n - Vec3::Y).length() < 1e-6);
    }

    #[test]
    fn uv_sphere_is_closed_with_outward_faces() {
        let m = TriangleMesh::uv_sphere(Vec3::ZERO, 1.0, 96, 48);
        assert!(m.validate().is_ok());
        assert_eq!(m.len(), 2 * 96 * 48 - 2 * 96);
        // The inscribed polyhedron's area approaches 4π from below.
        let area: f32 = (0..m.len()).map(|i| m.triangle_area(i)).sum();
        assert!(area < 4.0 * PI && area > 4.0 * PI * 0.998, "area {area}");
        for i in 0..m.len() {
            let s = m.surface(i, [1.0 / 3.0; 3]);
            assert!(s.n.dot(s.p) > 0.0, "face {i} points inward");
        }
    }
}
