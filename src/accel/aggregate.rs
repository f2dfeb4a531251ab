//! All of a scene's geometry behind one intersection interface: analytic
//! shapes, world-space triangle meshes and instances of shared meshes, under
//! a two-level BVH.
//!
//! Meshes placed once are stored in world space and their triangles enter
//! the top-level BVH one by one. Meshes placed several times are stored
//! once, in object space, with a BVH of their own; each placement is one
//! top-level primitive holding a transform (instancing). Infinite planes
//! have no bounds and are tested outside the tree. The tree's leaves hold
//! blocks of up to eight spheres, rectangles or single triangles where the
//! processor has AVX; a room of a few dozen rectangles is a tree of one
//! leaf.

#[cfg(target_arch = "x86_64")]
use super::blocks::PACKET;
use super::blocks::{BlockRange, Blocks};
use super::bvh::{ALONE, Bvh, SahCosts};
use super::queries::TriangleBvh;
use super::wide::Bvh4;
use crate::geometry::mesh::TriangleMesh;
use crate::geometry::motion::MotionTransform;
use crate::geometry::shape::{LocalSurface, Rectangle, Shape};
use crate::geometry::triangle::{TriangleRay, intersect_triangle_with};
use crate::geometry::{Aabb, Ray, SurfaceHit, Transform};
use crate::sampling::Distribution1D;
use glam::{Vec2, Vec3};
use std::time::Instant;

/// An analytic shape placed in the scene.
#[derive(Clone, Debug)]
pub struct ShapeInstance {
    /// The shape in its object space.
    pub shape: Shape,
    /// Object-to-world transform; `None` for the identity. For a moving
    /// shape, the transform at the shutter's opening.
    pub transform: Option<Transform>,
    /// The shape's motion while the shutter is open; `None`: it stands
    /// still. Emitters do not move.
    pub motion: Option<Box<MotionTransform>>,
    /// Material index.
    pub material: u32,
    /// Area light index, if the shape emits.
    pub light: Option<u32>,
    /// Whether the front and back sides are swapped.
    pub flip_normals: bool,
}

/// A mesh stored in world space, placed once.
#[derive(Clone, Debug)]
pub struct MeshObject {
    /// Index into the meshes.
    pub mesh: u32,
    /// Material index.
    pub material: u32,
    /// Area light index, if the mesh emits.
    pub light: Option<u32>,
}

/// One placement of a shared object-space mesh.
#[derive(Clone, Debug)]
pub struct MeshInstance {
    /// Index into the meshes.
    pub mesh: u32,
    /// Object-to-world transform (of a moving instance, at the shutter's
    /// opening).
    pub transform: Transform,
    /// The instance's motion while the shutter is open; `None`: it stands
    /// still. Emitters do not move.
    pub motion: Option<Box<MotionTransform>>,
    /// Material index.
    pub material: u32,
    /// Area light index, if the instance emits.
    pub light: Option<u32>,
    /// Whether the front and back sides are swapped.
    pub flip_normals: bool,
}

/// What the top-level BVH holds.
#[derive(Clone, Copy, Debug)]
enum PrimRef {
    Triangle {
        object: u32,
        tri: u32,
        /// Where its vertices are in `Aggregate::triangle_vertices`.
        vertices: u32,
    },
    /// A large world-space mesh object, traced through its own tree.
    Object(u32),
    Shape(u32),
    Instance(u32),
}

/// What a leaf of the top-level tree tests: a primitive by itself, or
/// consecutive blocks of up to eight spheres, rectangles or triangles, each
/// block at once.
#[derive(Clone, Copy, Debug)]
enum LeafItem {
    /// `prims[k]`.
    Prim(u32),
    /// Blocks of world-space spheres, numbered by their shape.
    Spheres(BlockRange),
    /// Blocks of world-space rectangles, numbered by their shape.
    Rectangles(BlockRange),
    /// Blocks of single triangles, numbered by their place in `prims`.
    Triangles(BlockRange),
}

/// The kinds of top-level primitive the tree packs into blocks.
const KIND_SPHERE: u8 = 1;
const KIND_RECTANGLE: u8 = 2;
const KIND_TRIANGLE: u8 = 3;

/// The top level's SAH prices where its leaves hold blocks, as Embree
/// prices its SAH builds: a node visit and a block test (or a primitive
/// tested alone) cost one each. A leaf holds up to four blocks of a kind,
/// so that a room (the Cornell box: three blocks of rectangles) is a tree
/// of one leaf, all of whose blocks a ray tests, with no node to visit.
const BLOCKS_OF_EIGHT: SahCosts = SahCosts {
    traversal: 1.0,
    block: 8,
    leaf_blocks: 4,
};

/// Meshes with at least this many triangles are traced through a tree over
/// blocks of four triangles tested at once (a [`TriangleBvh`]): a world-space
/// one as a single top-level primitive, an instanced one as its bottom
/// level. Smaller world-space meshes (the boxes of a Cornell box) are single
/// triangles in the top-level tree, where blocks measured slower.
pub const BLOCK_TREE_MIN_TRIANGLES: usize = 256;

/// Which primitive a ray hit, and where on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HitPrim {
    /// Triangle `tri` of world-space mesh object `object`.
    Triangle {
        /// Mesh object.
        object: u32,
        /// Triangle within its mesh.
        tri: u32,
        /// Barycentrics.
        b: [f32; 3],
    },
    /// Analytic shape instance.
    Shape(u32),
    /// Triangle `tri` of instance `instance`'s mesh.
    Instance {
        /// Instance.
        instance: u32,
        /// Triangle within the instanced mesh.
        tri: u32,
        /// Barycentrics.
        b: [f32; 3],
    },
}

/// The nearest (or some) intersection found by traversal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter.
    pub t: f32,
    /// What was hit.
    pub prim: HitPrim,
}

/// Figures from the build, for `--verbose`.
#[derive(Clone, Debug, Default)]
pub struct BuildStats {
    /// Wall time of all BVH builds, in seconds.
    pub seconds: f64,
    /// Top-level primitives.
    pub primitives: usize,
    /// Triangles stored (instanced meshes once).
    pub triangles: usize,
    /// Nodes in all BVHs.
    pub nodes: usize,
    /// Bytes held by BVH nodes and primitive references.
    pub bvh_bytes: usize,
    /// Bytes held by mesh data.
    pub mesh_bytes: usize,
    /// Blocks of up to eight spheres, rectangles or triangles in the
    /// leaves of the top-level tree (0 where the processor lacks AVX).
    pub leaf_blocks: usize,
}

/// A point sampled uniformly in the object space of an emitter, mapped to
/// world space, with its density per unit world area.
#[derive(Clone, Copy, Debug)]
pub struct EmitterSample {
    /// World-space point.
    pub p: Vec3,
    /// Unit normal (front side).
    pub n: Vec3,
    /// Density with respect to world-space area.
    pub pdf_area: f32,
    /// Surface coordinates of the point.
    pub uv: Vec2,
    /// The mesh attribute's value at the point (0 where none).
    pub attribute: Vec3,
}

/// Which geometry an area light is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmitterRef {
    /// An analytic shape instance.
    Shape(u32),
    /// A world-space mesh object.
    MeshObject(u32),
    /// A mesh instance.
    Instance(u32),
}

/// The scene's geometry with its acceleration structures.
#[derive(Clone, Debug, Default)]
pub struct Aggregate {
    /// Meshes: world-space ones and shared object-space ones.
    pub meshes: Vec<TriangleMesh>,
    /// Analytic shapes.
    pub shapes: Vec<ShapeInstance>,
    /// World-space mesh placements.
    pub mesh_objects: Vec<MeshObject>,
    /// Instanced mesh placements.
    pub instances: Vec<MeshInstance>,
    /// Per mesh, the bottom-level tree of a small instanced mesh.
    blas: Vec<Option<Bvh4>>,
    /// Per mesh, the bottom-level tree of a large instanced mesh.
    blas_blocks: Vec<Option<TriangleBvh>>,
    /// Per mesh object, its own tree if it is large.
    object_trees: Vec<Option<TriangleBvh>>,
    prims: Vec<PrimRef>,
    /// What the top-level tree's leaves test, which its leaf ranges index.
    items: Vec<LeafItem>,
    /// The blocks that `items` name; `None` where the processor lacks AVX.
    blocks: Option<Blocks>,
    /// The vertices of every `PrimRef::Triangle`, in tree order.
    triangle_vertices: Vec<[Vec3; 3]>,
    unbounded: Vec<u32>,
    bvh: Bvh4,
    /// Where the tree is one leaf with items that rays can be tested
    /// against together (blocks of spheres or rectangles, lone
    /// untransformed spheres), the fewest primitives such an item holds.
    packet_items: Option<u32>,
    /// Whether some shape is an untransformed sphere, whose hits in a
    /// packet [`Aggregate::sphere_surfaces`] makes records of.
    lone_spheres: bool,
    bounds: Aabb,
    stats: BuildStats,
}

impl Aggregate {
    /// Builds the acceleration structures. Meshes used by instances get
    /// their own BVH, and their triangles are reordered to match it.
    pub fn build(
        mut meshes: Vec<TriangleMesh>,
        shapes: Vec<ShapeInstance>,
        mesh_objects: Vec<MeshObject>,
        instances: Vec<MeshInstance>,
    ) -> Aggregate {
        let start = Instant::now();
        let shapes: Vec<ShapeInstance> = shapes.into_iter().map(bake_transform).collect();
        // Bottom level: one BVH per instanced mesh.
        let mut blas: Vec<Option<Bvh>> = vec![None; meshes.len()];
        let mut instanced = vec![false; meshes.len()];
        for inst in &instances {
            instanced[inst.mesh as usize] = true;
        }
        let blas_blocks: Vec<Option<TriangleBvh>> = meshes
            .iter()
            .enumerate()
            .map(|(i, m)| (instanced[i] && m.len() >= BLOCK_TREE_MIN_TRIANGLES).then(|| TriangleBvh::build(m, None)))
            .collect();
        let built: Vec<(usize, Bvh, Vec<u32>)> = {
            use rayon::prelude::*;
            meshes
                .par_iter()
                .enumerate()
                .filter(|(i, _)| instanced[*i] && blas_blocks[*i].is_none())
                .map(|(i, m)| {
                    let bounds: Vec<Aabb> = (0..m.len()).map(|t| m.triangle_bounds(t)).collect();
                    let (bvh, order) = Bvh::build(&bounds);
                    (i, bvh, order)
                })
                .collect()
        };
        for (i, bvh, order) in built {
            let m = &mut meshes[i];
            m.indices = order.iter().map(|&k| m.indices[k as usize]).collect();
            blas[i] = Some(bvh);
        }

        // Top level.
        let mut refs = Vec::new();
        let mut bounds = Vec::new();
        let mut unbounded = Vec::new();
        for (i, s) in shapes.iter().enumerate() {
            match s.shape.bounds() {
                Some(b) => {
                    refs.push(PrimRef::Shape(i as u32));
                    bounds.push(match (&s.motion, &s.transform) {
                        (Some(m), _) => m.bounds(&b),
                        (None, Some(t)) => t.aabb(&b),
                        (None, None) => b,
                    });
                }
                None => unbounded.push(i as u32),
            }
        }
        let object_trees: Vec<Option<TriangleBvh>> = mesh_objects
            .iter()
            .map(|obj| {
                let m = &meshes[obj.mesh as usize];
                (m.len() >= BLOCK_TREE_MIN_TRIANGLES).then(|| TriangleBvh::build(m, None))
            })
            .collect();
        for (o, obj) in mesh_objects.iter().enumerate() {
            let m = &meshes[obj.mesh as usize];
            if object_trees[o].is_some() {
                refs.push(PrimRef::Object(o as u32));
                bounds.push(m.bounds());
                continue;
            }
            for t in 0..m.len() {
                refs.push(PrimRef::Triangle {
                    object: o as u32,
                    tri: t as u32,
                    vertices: 0, // set once the tree has ordered the primitives
                });
                bounds.push(m.triangle_bounds(t));
            }
        }
        for (i, inst) in instances.iter().enumerate() {
            let b = match (&blas[inst.mesh as usize], &blas_blocks[inst.mesh as usize]) {
                (_, Some(_)) => meshes[inst.mesh as usize].bounds(),
                (Some(b), None) => b.bounds(),
                (None, None) => Aabb::EMPTY,
            };
            refs.push(PrimRef::Instance(i as u32));
            bounds.push(match &inst.motion {
                Some(m) => m.bounds(&b),
                None => inst.transform.aabb(&b),
            });
        }
        let scene_bounds = bounds.iter().fold(Aabb::EMPTY, |a, b| a.union(b));
        let mut blocks = Blocks::new();
        let kind = |r: &PrimRef| match *r {
            PrimRef::Shape(i) => match &shapes[i as usize] {
                ShapeInstance {
                    shape: Shape::Sphere(_),
                    transform: None,
                    ..
                } => KIND_SPHERE,
                ShapeInstance {
                    shape: Shape::Rectangle(_),
                    transform: None,
                    ..
                } => KIND_RECTANGLE,
                _ => ALONE,
            },
            PrimRef::Triangle { .. } => KIND_TRIANGLE,
            PrimRef::Object(_) | PrimRef::Instance(_) => ALONE,
        };
        let (bvh, order) = match blocks {
            Some(_) => Bvh::build_kinds(&bounds, |i| kind(&refs[i]), BLOCKS_OF_EIGHT),
            None => Bvh::build(&bounds),
        };
        let mut prims: Vec<PrimRef> = order.iter().map(|&k| refs[k as usize]).collect();
        // The vertices of the top level's single triangles, copied in tree
        // order: a leaf test reads one record instead of following the
        // object, its mesh and the triangle's indices.
        let mut triangle_vertices = Vec::new();
        for p in &mut prims {
            if let PrimRef::Triangle { object, tri, vertices } = p {
                *vertices = triangle_vertices.len() as u32;
                let mesh = &meshes[mesh_objects[*object as usize].mesh as usize];
                triangle_vertices.push(mesh.vertices(*tri as usize));
            }
        }
        // Traversal uses the four-wide trees collapsed from the binary
        // ones: in a room, whose walls make every upper box the whole room,
        // that halves the boxes a ray visits.
        let mut bvh = Bvh4::from_binary(&bvh);
        // Each leaf's primitives of one kind become blocks of eight.
        let mut items = Vec::with_capacity(prims.len());
        let prims_ref = &prims;
        let kind = &kind;
        bvh.remap_leaves(|first, count| {
            let prims = prims_ref;
            let start = items.len() as u32;
            let leaf = first..first + count;
            let Some(blocks) = &mut blocks else {
                items.extend(leaf.map(LeafItem::Prim));
                return (start, count);
            };
            let of_kind = |k: u8| leaf.clone().filter(move |&p| kind(&prims[p as usize]) == k);
            let spheres: Vec<(crate::geometry::Sphere, u32)> = of_kind(KIND_SPHERE)
                .map(|p| match prims[p as usize] {
                    PrimRef::Shape(i) => match shapes[i as usize].shape {
                        Shape::Sphere(s) => (s, i),
                        _ => unreachable!("sphere kind"),
                    },
                    _ => unreachable!("sphere kind"),
                })
                .collect();
            let mut range: Option<BlockRange> = None;
            if spheres.len() == 1 {
                // A sphere alone is tested by itself: a block of one lane
                // costs more than the one sphere's own test, which gives
                // the same bits.
                items.extend(of_kind(KIND_SPHERE).map(LeafItem::Prim));
            } else {
                for chunk in spheres.chunks(8) {
                    let b = blocks.push_spheres(chunk);
                    range = Some(range.map_or((b, 1), |(first, n)| (first, n + 1)));
                }
            }
            if let Some(range) = range {
                items.push(LeafItem::Spheres(range));
            }
            let rectangles: Vec<(Rectangle, u32)> = of_kind(KIND_RECTANGLE)
                .map(|p| match prims[p as usize] {
                    PrimRef::Shape(i) => match shapes[i as usize].shape {
                        Shape::Rectangle(r) => (r, i),
                        _ => unreachable!("rectangle kind"),
                    },
                    _ => unreachable!("rectangle kind"),
                })
                .collect();
            let mut range: Option<BlockRange> = None;
            for chunk in rectangles.chunks(8) {
                let b = blocks.push_rectangles(chunk);
                range = Some(range.map_or((b, 1), |(first, n)| (first, n + 1)));
            }
            if let Some(range) = range {
                items.push(LeafItem::Rectangles(range));
            }
            let triangles: Vec<([Vec3; 3], u32)> = of_kind(KIND_TRIANGLE)
                .map(|p| match prims[p as usize] {
                    PrimRef::Triangle { vertices, .. } => (triangle_vertices[vertices as usize], p),
                    _ => unreachable!("triangle kind"),
                })
                .collect();
            let mut range: Option<BlockRange> = None;
            for chunk in triangles.chunks(8) {
                let b = blocks.push_triangles(chunk);
                range = Some(range.map_or((b, 1), |(first, n)| (first, n + 1)));
            }
            if let Some(range) = range {
                items.push(LeafItem::Triangles(range));
            }
            items.extend(of_kind(ALONE).map(LeafItem::Prim));
            (start, items.len() as u32 - start)
        });
        let blas: Vec<Option<Bvh4>> = blas.iter().map(|b| b.as_ref().map(Bvh4::from_binary)).collect();

        let mut stats = BuildStats {
            seconds: start.elapsed().as_secs_f64(),
            primitives: prims.len(),
            triangles: meshes.iter().map(|m| m.len()).sum(),
            nodes: bvh.node_count(),
            bvh_bytes: bvh.memory_bytes()
                + prims.len() * std::mem::size_of::<PrimRef>()
                + triangle_vertices.len() * std::mem::size_of::<[Vec3; 3]>()
                + items.len() * std::mem::size_of::<LeafItem>()
                + blocks.as_ref().map_or(0, Blocks::memory_bytes),
            mesh_bytes: 0,
            leaf_blocks: blocks.as_ref().map_or(0, Blocks::len),
        };
        for b in blas.iter().flatten() {
            stats.nodes += b.node_count();
            stats.bvh_bytes += b.memory_bytes();
        }
        for t in object_trees.iter().chain(&blas_blocks).flatten() {
            stats.nodes += t.node_count();
            stats.bvh_bytes += t.memory_bytes();
        }
        stats.mesh_bytes = meshes
            .iter()
            .map(|m| m.positions.len() * 12 + m.normals.len() * 12 + m.uvs.len() * 8 + m.indices.len() * 12)
            .sum();
        let mut aggregate = Aggregate {
            meshes,
            shapes,
            mesh_objects,
            instances,
            blas,
            blas_blocks,
            object_trees,
            prims,
            items,
            blocks,
            triangle_vertices,
            unbounded,
            bvh,
            packet_items: None,
            lone_spheres: false,
            bounds: scene_bounds,
            stats,
        };
        aggregate.packet_items = aggregate.smallest_packet_item();
        aggregate.lone_spheres =
            (aggregate.shapes.iter()).any(|s| matches!((&s.shape, &s.transform), (Shape::Sphere(_), None)));
        aggregate
    }

    /// See `Aggregate::packet_items`.
    fn smallest_packet_item(&self) -> Option<u32> {
        #[cfg(target_arch = "x86_64")]
        if let (Some((first, count)), true, Some(blocks)) =
            (self.bvh.root_leaf(), self.unbounded.is_empty(), &self.blocks)
        {
            let range = |(b, n): BlockRange| b..b + n;
            return (first..first + count)
                .flat_map(|k| -> Vec<u32> {
                    match self.items[k as usize] {
                        LeafItem::Spheres(r) => range(r).map(|b| blocks.sphere_count(b)).collect(),
                        LeafItem::Rectangles(r) => range(r).map(|b| blocks.rectangle_count(b)).collect(),
                        LeafItem::Prim(p) => self.lone_sphere(p).map(|_| 1).into_iter().collect(),
                        LeafItem::Triangles(_) => Vec::new(),
                    }
                })
                .min();
        }
        None
    }

    /// Figures from the build.
    pub fn stats(&self) -> &BuildStats {
        &self.stats
    }

    /// Bounds of all bounded geometry.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Calls `on_hit(hit, ray)` for intersections within the ray's interval
    /// as traversal finds them. `on_hit` returns `true` to accept the hit
    /// (it may then shrink `ray.t_max`). With `any_hit`, the first accepted
    /// hit ends the search.
    #[inline(always)]
    fn traverse<F: FnMut(Hit, &mut Ray) -> bool>(&self, ray: &mut Ray, any_hit: bool, mut on_hit: F) -> bool {
        let mut found = false;
        for &i in &self.unbounded {
            if let Some(t) = self.shape_intersect(i, ray) {
                if on_hit(
                    Hit {
                        t,
                        prim: HitPrim::Shape(i),
                    },
                    ray,
                ) {
                    found = true;
                    if any_hit {
                        return true;
                    }
                }
            }
        }
        // A zero direction meets nothing bounded.
        if ray.dir == Vec3::ZERO {
            return found;
        }
        // The triangle test's per-ray set-up, made when the first triangle
        // is met: many rays in a room meet only walls. (`Some(None)`: made,
        // and no triangle test accepts the direction.)
        let mut pre = None;
        found |= self.bvh.traverse_small(
            ray,
            any_hit,
            #[inline(always)]
            |k, ray| self.test_item(k, ray, &mut pre, any_hit, &mut on_hit),
        );
        found
    }

    /// Tests leaf item `k`: a block, or a primitive by itself.
    #[inline(always)]
    fn test_item<F: FnMut(Hit, &mut Ray) -> bool>(
        &self,
        k: u32,
        ray: &mut Ray,
        pre: &mut Option<Option<TriangleRay>>,
        any_hit: bool,
        on_hit: &mut F,
    ) -> bool {
        let blocks = || {
            self.blocks
                .as_ref()
                .expect("blocks are named only where they were built")
        };
        match self.items[k as usize] {
            LeafItem::Prim(p) => self.test_primitive(p, ray, pre, any_hit, on_hit),
            LeafItem::Spheres(b) => match blocks().spheres(b, ray, any_hit) {
                Some((i, t, _)) => on_hit(
                    Hit {
                        t,
                        prim: HitPrim::Shape(i),
                    },
                    ray,
                ),
                None => false,
            },
            LeafItem::Rectangles(b) => match blocks().rectangles(b, ray, any_hit) {
                Some((i, t, _)) => on_hit(
                    Hit {
                        t,
                        prim: HitPrim::Shape(i),
                    },
                    ray,
                ),
                None => false,
            },
            LeafItem::Triangles(b) => {
                let Some(tri_ray) = *pre.get_or_insert_with(|| TriangleRay::new(ray)) else {
                    return false;
                };
                match blocks().triangles(b, ray, &tri_ray, any_hit) {
                    Some((p, t, b)) => match self.prims[p as usize] {
                        PrimRef::Triangle { object, tri, .. } => on_hit(
                            Hit {
                                t,
                                prim: HitPrim::Triangle { object, tri, b },
                            },
                            ray,
                        ),
                        _ => unreachable!("triangle blocks name single triangles"),
                    },
                    None => false,
                }
            }
        }
    }

    /// Tests top-level primitive `k`. Single triangles and shapes, what a
    /// room is made of, are tested inline in the traversal loop; a large
    /// mesh or an instance is a traversal of its own and stays a call, so
    /// that its stack does not weigh on every leaf (as one closure with all
    /// four cases, the test was a call with a 6 KiB frame, and the triangle
    /// and shape tests inside it calls again).
    #[inline(always)]
    fn test_primitive<F: FnMut(Hit, &mut Ray) -> bool>(
        &self,
        k: u32,
        ray: &mut Ray,
        pre: &mut Option<Option<TriangleRay>>,
        any_hit: bool,
        on_hit: &mut F,
    ) -> bool {
        let mut triangle_ray = |ray: &Ray| *pre.get_or_insert_with(|| TriangleRay::new(ray));
        match self.prims[k as usize] {
            PrimRef::Triangle { object, tri, vertices } => {
                let [p0, p1, p2] = self.triangle_vertices[vertices as usize];
                let Some(tri_ray) = triangle_ray(ray) else {
                    return false;
                };
                match intersect_triangle_with(ray, &tri_ray, p0, p1, p2) {
                    Some(h) => on_hit(
                        Hit {
                            t: h.t,
                            prim: HitPrim::Triangle { object, tri, b: h.b },
                        },
                        ray,
                    ),
                    None => false,
                }
            }
            PrimRef::Shape(i) => match self.shape_intersect(i, ray) {
                Some(t) => on_hit(
                    Hit {
                        t,
                        prim: HitPrim::Shape(i),
                    },
                    ray,
                ),
                None => false,
            },
            PrimRef::Object(object) => match triangle_ray(ray) {
                Some(tri_ray) => self.test_object(object, ray, &tri_ray, any_hit, on_hit),
                None => false,
            },
            PrimRef::Instance(i) => self.test_instance(i, ray, any_hit, on_hit),
        }
    }

    /// A large world-space mesh: its own tree over blocks of triangles.
    #[inline(never)]
    fn test_object<F: FnMut(Hit, &mut Ray) -> bool>(
        &self,
        object: u32,
        ray: &mut Ray,
        pre: &TriangleRay,
        any_hit: bool,
        on_hit: &mut F,
    ) -> bool {
        let tree = self.object_trees[object as usize]
            .as_ref()
            .expect("object refs name objects with trees");
        tree.traverse(ray, pre, any_hit, |tri, t, b, ray| {
            on_hit(
                Hit {
                    t,
                    prim: HitPrim::Triangle { object, tri, b },
                },
                ray,
            )
        })
    }

    /// An instance: the ray in the mesh's object space through its tree.
    #[inline(never)]
    fn test_instance<F: FnMut(Hit, &mut Ray) -> bool>(
        &self,
        i: u32,
        ray: &mut Ray,
        any_hit: bool,
        on_hit: &mut F,
    ) -> bool {
        let inst = &self.instances[i as usize];
        let mesh = &self.meshes[inst.mesh as usize];
        // The object-space ray keeps the world ray's parameter.
        let mut obj_ray = match &inst.motion {
            Some(m) => m.at(ray.time).inv_ray(ray),
            None => inst.transform.inv_ray(ray),
        };
        let Some(obj_pre) = TriangleRay::new(&obj_ray) else {
            return false;
        };
        if let Some(tree) = &self.blas_blocks[inst.mesh as usize] {
            let hit = tree.traverse(&mut obj_ray, &obj_pre, any_hit, |tri, t, b, r| {
                on_hit(
                    Hit {
                        t,
                        prim: HitPrim::Instance { instance: i, tri, b },
                    },
                    r,
                )
            });
            ray.t_max = obj_ray.t_max;
            return hit;
        }
        let Some(blas) = &self.blas[inst.mesh as usize] else {
            return false;
        };
        let hit = blas.traverse_small(&mut obj_ray, any_hit, |tri, r| {
            match mesh.intersect_with(tri as usize, r, &obj_pre) {
                Some(h) => on_hit(
                    Hit {
                        t: h.t,
                        prim: HitPrim::Instance {
                            instance: i,
                            tri,
                            b: h.b,
                        },
                    },
                    r,
                ),
                None => false,
            }
        });
        ray.t_max = obj_ray.t_max;
        hit
    }

    #[inline]
    fn shape_intersect(&self, i: u32, ray: &Ray) -> Option<f32> {
        let s = &self.shapes[i as usize];
        match (&s.transform, &s.shape) {
            // Rectangles (walls, area lights: transforms are baked into
            // them) and spheres are the commonest shapes and the cheapest
            // tests, so theirs are inlined; the other shapes' tests stay a
            // call.
            (None, Shape::Rectangle(r)) => r.intersect(ray),
            (None, Shape::Sphere(s)) => s.intersect(ray),
            (None, shape) => shape.intersect(ray),
            (Some(t), shape) => match &s.motion {
                Some(m) => shape.intersect(&m.at(ray.time).inv_ray(ray)),
                None => shape.intersect(&t.inv_ray(ray)),
            },
        }
    }

    /// Where `ray` first meets shape `i` alone (whatever else lies in
    /// the way), with the surface there as a hit on the scene gives it
    /// (surface coordinates if `uv`): how an emitter without an area
    /// density is sampled by direction (see `light::Light::Area`).
    pub fn shape_hit(&self, i: u32, ray: &Ray, uv: bool) -> Option<SurfaceHit> {
        let t = self.shape_intersect(i, ray)?;
        Some(self.surface_with(
            ray,
            &Hit {
                t,
                prim: HitPrim::Shape(i),
            },
            |_| uv,
        ))
    }

    /// The nearest intersection within the ray's interval.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut found = None;
        self.intersect_into(ray, &mut found);
        found
    }

    /// [`Aggregate::intersect`] written into `found`, where the caller
    /// reads it: a returned hit is copied out with wider loads than the
    /// stores that wrote its fields, and the copy waits on them.
    #[inline]
    pub fn intersect_into(&self, ray: &Ray, found: &mut Option<Hit>) {
        *found = None;
        // A tree of one leaf (a room) skips the general traversal, and its
        // stack frame of kilobytes.
        if let (Some(leaf), true) = (self.bvh.root_leaf(), self.unbounded.is_empty()) {
            self.leaf_hit(leaf, ray, false, found);
            return;
        }
        self.intersect_traversed(ray, found)
    }

    /// Whether `count` rays, those of `live`, are better tested together
    /// ([`Aggregate::intersect_together`]): eight rays, a tree of one leaf,
    /// and some item of the leaf holding fewer primitives than there are
    /// rays, which is then tested against all rays at once.
    #[inline]
    pub fn tests_together(&self, count: usize, live: u32) -> bool {
        matches!(self.packet_items, Some(smallest) if count == 8 && live.count_ones() > smallest)
    }

    /// [`Aggregate::intersect_into`] for the rays of `rays` whose bits are
    /// set in `live` (a path tracer's lanes), each hit written to the
    /// same place in `found`, where [`Aggregate::tests_together`]: whether
    /// they were. The leaf's items that hold fewer primitives than there
    /// are rays are tested against all rays at once, in vector lanes, the
    /// others ray by ray (see [`Aggregate::leaf_hit_packet`]). Each ray
    /// finds what it finds by itself.
    #[inline]
    #[allow(unsafe_code)]
    pub fn intersect_together(&self, rays: &[Ray], live: u32, found: &mut [Option<Hit>]) -> bool {
        if !self.tests_together(rays.len(), live) {
            return false;
        }
        #[cfg(target_arch = "x86_64")]
        if let (Some(leaf), Ok(rays), Ok(found)) = (
            self.bvh.root_leaf(),
            <&[Ray; PACKET]>::try_from(rays),
            <&mut [Option<Hit>; PACKET]>::try_from(&mut *found),
        ) {
            // SAFETY: the leaf has blocks, which exist only where the
            // processor has AVX.
            unsafe { self.leaf_hit_packet(leaf, rays, live, found) };
            return true;
        }
        false
    }

    /// [`Aggregate::leaf_hit`]'s nearest hits for a packet of rays (see
    /// [`Aggregate::intersect_together`]): the leaf's items in order, each
    /// block of spheres or rectangles that holds fewer primitives than
    /// there are rays, and each lone untransformed sphere, tested against
    /// all rays at once (a packet test costs about what one ray's test of
    /// a block costs), the others ray by ray.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    #[inline(never)]
    fn leaf_hit_packet(
        &self,
        (first, count): (u32, u32),
        rays: &[Ray; PACKET],
        mut live: u32,
        found: &mut [Option<Hit>; PACKET],
    ) {
        use super::blocks::{BlockHit, RayPacket};
        use crate::geometry::simd::lanes;
        let mut t_max = [f32::NAN; PACKET];
        for i in lanes(live) {
            found[i] = None;
            t_max[i] = rays[i].t_max;
            // A zero direction meets nothing bounded.
            if rays[i].dir == Vec3::ZERO {
                live &= !(1 << i);
            }
        }
        let Some(blocks) = &self.blocks else { return };
        let ray_count = live.count_ones();
        if ray_count == 0 {
            return;
        }
        // Made where a primitive is first tested against all rays.
        let mut packet: Option<RayPacket> = None;
        let as_hit = |(id, t, _): BlockHit| Hit {
            t,
            prim: HitPrim::Shape(id),
        };
        // Each ray's set-up of the triangle test, made where it first
        // meets a triangle.
        let mut pre: [Option<Option<TriangleRay>>; PACKET] = [None; PACKET];
        for k in first..first + count {
            match self.items[k as usize] {
                LeafItem::Spheres(range) => {
                    for step in blocks_in_turn(range, |b| blocks.sphere_count(b) < ray_count) {
                        match step {
                            BlockStep::Packet(b) => {
                                let packet = packet.get_or_insert_with(|| RayPacket::new(rays, live));
                                blocks.spheres_packet(b, packet, &mut t_max, |bits, t, id| {
                                    record_hits(found, bits, t, id)
                                });
                            }
                            BlockStep::OneByOne(run) => one_by_one(rays, live, &mut t_max, found, |_, r| {
                                blocks.spheres(run, r, false).map(as_hit)
                            }),
                        }
                    }
                }
                LeafItem::Rectangles(range) => {
                    for step in blocks_in_turn(range, |b| blocks.rectangle_count(b) < ray_count) {
                        match step {
                            BlockStep::Packet(b) => {
                                let packet = packet.get_or_insert_with(|| RayPacket::new(rays, live));
                                blocks.rectangles_packet(b, packet, &mut t_max, |bits, t, id| {
                                    record_hits(found, bits, t, id)
                                });
                            }
                            BlockStep::OneByOne(run) => one_by_one(rays, live, &mut t_max, found, |_, r| {
                                blocks.rectangles(run, r, false).map(as_hit)
                            }),
                        }
                    }
                }
                item => match (item, ray_count > 1) {
                    (LeafItem::Prim(p), true) if self.lone_sphere(p).is_some() => {
                        let (id, sphere) = self.lone_sphere(p).expect("a sphere");
                        let packet = packet.get_or_insert_with(|| RayPacket::new(rays, live));
                        let (bits, t) = packet.sphere(sphere.center.to_array(), sphere.radius, &mut t_max);
                        record_hits(found, bits, &t, id);
                    }
                    _ => one_by_one(rays, live, &mut t_max, found, |i, r| {
                        let mut hit = None;
                        self.test_item(k, r, &mut pre[i], false, &mut |h: Hit, r: &mut Ray| {
                            r.t_max = h.t;
                            hit = Some(h);
                            true
                        });
                        hit
                    }),
                },
            }
        }
    }

    /// The shape number and sphere of top-level primitive `p` if it is an
    /// untransformed sphere, which [`Aggregate::shape_intersect`] tests
    /// with the sphere's own test.
    #[inline]
    fn lone_sphere(&self, p: u32) -> Option<(u32, crate::geometry::Sphere)> {
        match self.prims[p as usize] {
            PrimRef::Shape(i) => match &self.shapes[i as usize] {
                ShapeInstance {
                    shape: Shape::Sphere(s),
                    transform: None,
                    ..
                } => Some((i, *s)),
                _ => None,
            },
            _ => None,
        }
    }

    /// The nearest (with `any_hit`, some) hit of a tree that is one leaf
    /// (a room: a few blocks of rectangles), without the traversal's stack
    /// frame: what the traversal finds, in the same order.
    /// The hit goes to `best` (left as it is where there is none).
    /// Kept out of line: inlined into the path tracer's loop (which
    /// LLVM does or does not as that loop's other code changes size), its
    /// shadow-ray test made that loop slower on rooms.
    #[inline(never)]
    #[allow(unsafe_code)]
    fn leaf_hit(&self, leaf: (u32, u32), ray: &Ray, any_hit: bool, best: &mut Option<Hit>) {
        #[cfg(target_arch = "x86_64")]
        if self.blocks.is_some() {
            // SAFETY: blocks exist only where the processor has AVX.
            return unsafe { self.leaf_hit_avx(leaf, ray, any_hit, best) };
        }
        self.leaf_items_hit(leaf, ray, any_hit, best)
    }

    /// [`Aggregate::leaf_hit`] built for AVX, so that the block tests are
    /// inlined.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn leaf_hit_avx(&self, leaf: (u32, u32), ray: &Ray, any_hit: bool, best: &mut Option<Hit>) {
        self.leaf_items_hit(leaf, ray, any_hit, best)
    }

    #[inline(always)]
    fn leaf_items_hit(&self, (first, count): (u32, u32), ray: &Ray, any_hit: bool, best: &mut Option<Hit>) {
        // A zero direction meets nothing bounded.
        if ray.dir == Vec3::ZERO {
            return;
        }
        let mut r = ray.copy_by_field();
        let mut pre = None;
        let mut on_hit = |hit: Hit, r: &mut Ray| {
            r.t_max = hit.t;
            *best = Some(hit);
            true
        };
        // A leaf of one item (a room's rectangles, a sphere) is tested
        // without the loop, ahead of which the compiler loads every
        // array an item may read.
        if count == 1 {
            self.test_item(first, &mut r, &mut pre, any_hit, &mut on_hit);
            return;
        }
        for k in first..first + count {
            if self.test_item(k, &mut r, &mut pre, any_hit, &mut on_hit) && any_hit {
                break;
            }
        }
    }

    /// [`Aggregate::intersect`] through the general traversal: built for
    /// AVX where there are blocks (which exist only where the processor
    /// has it), so that the blocks' tests are inlined into it.
    #[inline(never)]
    #[allow(unsafe_code)]
    fn intersect_traversed(&self, ray: &Ray, best: &mut Option<Hit>) {
        #[cfg(target_arch = "x86_64")]
        if self.blocks.is_some() {
            // SAFETY: blocks exist only where the processor has AVX.
            return unsafe { self.intersect_avx(ray, best) };
        }
        self.nearest_hit(ray, best)
    }

    /// [`Aggregate::nearest_hit`] built for AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn intersect_avx(&self, ray: &Ray, best: &mut Option<Hit>) {
        self.nearest_hit(ray, best)
    }

    /// The general traversal for the nearest hit, put in `best` (left as
    /// it is where there is none).
    #[inline(always)]
    fn nearest_hit(&self, ray: &Ray, best: &mut Option<Hit>) {
        let mut r = ray.copy_by_field();
        self.traverse(&mut r, false, |hit, r| {
            r.t_max = hit.t;
            *best = Some(hit);
            true
        });
    }

    /// Whether anything lies on the ray within its interval.
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        if let (Some(leaf), true) = (self.bvh.root_leaf(), self.unbounded.is_empty()) {
            let mut found = None;
            self.leaf_hit(leaf, ray, true, &mut found);
            return found.is_some();
        }
        self.occluded_traversed(ray)
    }

    /// [`Aggregate::occluded`] through the general traversal, built for
    /// AVX where there are blocks, as [`Aggregate::intersect_traversed`].
    #[inline(never)]
    #[allow(unsafe_code)]
    fn occluded_traversed(&self, ray: &Ray) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.blocks.is_some() {
            // SAFETY: blocks exist only where the processor has AVX.
            return unsafe { self.occluded_avx(ray) };
        }
        self.any_hit(ray)
    }

    /// [`Aggregate::any_hit`] built for AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    fn occluded_avx(&self, ray: &Ray) -> bool {
        self.any_hit(ray)
    }

    /// The general traversal for any hit.
    #[inline(always)]
    fn any_hit(&self, ray: &Ray) -> bool {
        let mut r = ray.copy_by_field();
        self.traverse(&mut r, true, |_, _| true)
    }

    /// Material and light of the primitive that was hit.
    #[inline]
    pub fn material_and_light(&self, prim: &HitPrim) -> (u32, Option<u32>) {
        match *prim {
            HitPrim::Triangle { object, .. } => {
                let o = &self.mesh_objects[object as usize];
                (o.material, o.light)
            }
            HitPrim::Shape(i) => {
                let s = &self.shapes[i as usize];
                (s.material, s.light)
            }
            HitPrim::Instance { instance, .. } => {
                let o = &self.instances[instance as usize];
                (o.material, o.light)
            }
        }
    }

    /// The full surface record of a hit found on `ray`.
    pub fn surface(&self, ray: &Ray, hit: &Hit) -> SurfaceHit {
        self.surface_with(ray, hit, |_| true)
    }

    /// [`Aggregate::surface`], with surface coordinates only where
    /// `reads_uv(material)` (elsewhere a sphere's, and its dp/dv, are
    /// zero: they cost an arc tangent, an arc sine and a division).
    #[inline(always)]
    pub fn surface_with(&self, ray: &Ray, hit: &Hit, reads_uv: impl Fn(u32) -> bool) -> SurfaceHit {
        let (material, light) = self.material_and_light(&hit.prim);
        let uv = reads_uv(material);
        // A tangent known in advance (a rectangle's, in world space) spares
        // a square root and a division at the hit.
        let mut tangent = None;
        let mut attribute = Vec3::ZERO;
        let (mut ls, mut ns) = match hit.prim {
            HitPrim::Triangle { object, tri, b } => {
                let mesh = &self.meshes[self.mesh_objects[object as usize].mesh as usize];
                attribute = mesh.attribute(tri as usize, b);
                (mesh.surface(tri as usize, b), mesh.shading_normal(tri as usize, b))
            }
            HitPrim::Shape(i) => {
                let s = &self.shapes[i as usize];
                match (&s.shape, &s.transform) {
                    // A room's walls: the rectangle's record inline, not
                    // behind the call and match of every shape.
                    (Shape::Rectangle(r), None) => {
                        tangent = Some(r.tangent());
                        (r.surface(ray.at(hit.t)), None)
                    }
                    (_, None) => {
                        tangent = s.shape.tangent_at(ray.at(hit.t));
                        let ls = s.shape.surface_at_hit(ray, hit.t, uv);
                        (ls, s.shape.shading_normal(ls.p))
                    }
                    (_, Some(t)) => {
                        let t = &s.motion.as_ref().map_or(*t, |m| m.at(ray.time));
                        let obj_ray = t.inv_ray(ray);
                        let ls = s.shape.surface_at_hit(&obj_ray, hit.t, uv);
                        let ns = s.shape.shading_normal(ls.p).and_then(|n| t.normal(n).try_normalize());
                        (transform_surface(t, ls), ns)
                    }
                }
            }
            HitPrim::Instance { instance, tri, b } => {
                let inst = &self.instances[instance as usize];
                let mesh = &self.meshes[inst.mesh as usize];
                let t = &inst.motion.as_ref().map_or(inst.transform, |m| m.at(ray.time));
                attribute = mesh.attribute(tri as usize, b);
                let ls = transform_surface(t, mesh.surface(tri as usize, b));
                let ns = mesh
                    .shading_normal(tri as usize, b)
                    .and_then(|n| t.normal(n).try_normalize());
                (ls, ns)
            }
        };
        let flip = match hit.prim {
            HitPrim::Shape(i) => self.shapes[i as usize].flip_normals,
            HitPrim::Instance { instance, .. } => self.instances[instance as usize].flip_normals,
            HitPrim::Triangle { .. } => false, // flipped when baked
        };
        if flip {
            ls.n = -ls.n;
            ns = ns.map(|n| -n);
        }
        let mut surface = finish_surface(hit.t, ls, ns, tangent, material, light, attribute);
        surface.time = ray.time;
        surface
    }

    /// [`Aggregate::surface_with`] for the hits `found` of the rays of
    /// `rays` whose bits are set in `live` (a packet, see
    /// [`Aggregate::intersect_together`]) that lie on untransformed
    /// spheres whose materials read no (u, v): their records computed
    /// together, in vector lanes, by the functions that make one sphere's
    /// record (`shape::sphere_normal`, `sphere_at_normal`,
    /// `sphere_tangent`), so that they hold the same bits; written to the
    /// same places of `slots`. The bits of the lanes it wrote; the others
    /// are left to [`Aggregate::surface_with`] (among them a point at a
    /// sphere's centre or pole, which takes its fallbacks).
    ///
    /// # Safety
    /// The processor must have AVX (as it has where rays were tested
    /// together).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    pub(crate) fn sphere_surfaces(
        &self,
        rays: &[Ray; PACKET],
        found: &[Option<Hit>; PACKET],
        live: u32,
        reads_uv: impl Fn(u32) -> bool,
        slots: &mut [Option<SurfaceHit>],
    ) -> u32 {
        use crate::geometry::lanes::F8;
        use crate::geometry::shape::{sphere_at_normal, sphere_normal, sphere_tangent};
        use crate::geometry::simd::{Floats, Vec3s, lanes};
        if !self.lone_spheres {
            return 0;
        }
        // The lanes' rays, distances and spheres, a plain array a number.
        const O: usize = 0; // origin: 0..3
        const D: usize = 3; // direction: 3..6
        const T: usize = 6;
        const C: usize = 7; // centre: 7..10
        const R: usize = 10;
        const FRAME: usize = 11; // the frame's columns: 11..20
        let mut at = [[0.0f32; PACKET]; 20];
        at[R] = [1.0; PACKET];
        let mut spheres = 0u32;
        let mut shapes: [Option<&ShapeInstance>; PACKET] = [None; PACKET];
        for i in lanes(live) {
            let Some(Hit {
                t,
                prim: HitPrim::Shape(id),
            }) = found[i]
            else {
                continue;
            };
            let shape = &self.shapes[id as usize];
            let ShapeInstance {
                shape: Shape::Sphere(sphere),
                transform: None,
                material,
                ..
            } = shape
            else {
                continue;
            };
            if reads_uv(*material) {
                continue;
            }
            spheres |= 1 << i;
            shapes[i] = Some(shape);
            let frame = &sphere.uv_frame;
            let mut put = |k: usize, v: Vec3| (at[k][i], at[k + 1][i], at[k + 2][i]) = (v.x, v.y, v.z);
            put(O, rays[i].origin);
            put(D, rays[i].dir);
            put(C, sphere.center);
            put(FRAME, frame.x_axis);
            put(FRAME + 3, frame.y_axis);
            put(FRAME + 6, frame.z_axis);
            (at[T][i], at[R][i]) = (t, sphere.radius);
        }
        if spheres == 0 {
            return 0;
        }
        // `Ray::at`, `Sphere::tangent_at` and `Sphere::surface` in lanes.
        let lanes3 = |k: usize| Vec3s {
            x: F8::gather(&at[k]),
            y: F8::gather(&at[k + 1]),
            z: F8::gather(&at[k + 2]),
        };
        let p = lanes3(O) + lanes3(D).scale(F8::gather(&at[T]));
        let center = lanes3(C);
        let frame = [lanes3(FRAME), lanes3(FRAME + 3), lanes3(FRAME + 6)];
        let (n, normal) = sphere_normal(center, p);
        let record = sphere_at_normal(center, F8::gather(&at[R]), frame, n);
        let (tangent, defined) = sphere_tangent(center, frame, p);
        let done = spheres & normal & defined;
        let plain = |v: Vec3s<F8>| [v.x.each_lane(), v.y.each_lane(), v.z.each_lane()];
        let [n, tangent, p, p_error, dpdu] = [n, tangent, record.p, record.p_error, record.dpdu].map(plain);
        let lane = |v: &[[f32; PACKET]; 3], i: usize| Vec3::new(v[0][i], v[1][i], v[2][i]);
        for i in lanes(done) {
            let Some(s) = shapes[i] else { continue };
            // As `surface_with` and `finish_surface` complete it: no
            // shading normal, the shape's tangent, no (u, v).
            let ng = if s.flip_normals { -lane(&n, i) } else { lane(&n, i) };
            slots[i] = Some(SurfaceHit {
                t: at[T][i],
                p: lane(&p, i),
                p_error: lane(&p_error, i),
                ng,
                ns: ng,
                uv: Vec2::ZERO,
                tangent: lane(&tangent, i),
                dpdu: lane(&dpdu, i),
                dpdv: Vec3::ZERO,
                material: s.material,
                light: s.light,
                attribute: Vec3::ZERO,
                time: rays[i].time,
            });
        }
        done
    }

    /// The density, per unit world area, with which [`Aggregate::sample_emitter`]
    /// picks the point `p` of the emitter, whose world normal there is `n`.
    pub fn emitter_pdf_area(&self, emitter: EmitterRef, area: &EmitterArea, p: Vec3, n: Vec3) -> f32 {
        let total = area.total.max(f32::MIN_POSITIVE);
        match emitter {
            EmitterRef::Shape(i) => {
                let s = &self.shapes[i as usize];
                match &s.transform {
                    None => s.shape.relative_area_density(p) / total,
                    Some(t) => {
                        let relative = s.shape.relative_area_density(t.inv_point(p));
                        // Area scale |det M|·|M⁻ᵀ n_obj| = |det M| / |Mᵀ n_world|.
                        let mt_n = t.m.transpose().transform_vector3(n).length();
                        let det = glam::Mat3::from_mat4(t.m).determinant().abs();
                        relative * mt_n / (det * total)
                    }
                }
            }
            EmitterRef::MeshObject(_) | EmitterRef::Instance(_) => 1.0 / total,
        }
    }

    /// The corner, edges and front normal of a rectangle emitter whose
    /// transform was baked into it (see [`Aggregate::sample_emitter`]), or
    /// `None` for other emitters.
    pub fn emitter_parallelogram(&self, emitter: EmitterRef) -> Option<([Vec3; 3], Vec3)> {
        let EmitterRef::Shape(i) = emitter else { return None };
        let s = &self.shapes[i as usize];
        match (&s.shape, &s.transform) {
            (Shape::Rectangle(r), None) => {
                let n = if s.flip_normals { -r.normal() } else { r.normal() };
                Some(([r.corner(), r.edge_u(), r.edge_v()], n))
            }
            _ => None,
        }
    }

    /// Precomputes what sampling a point on an emitter needs.
    pub fn emitter_area(&self, emitter: EmitterRef) -> EmitterArea {
        match emitter {
            EmitterRef::Shape(i) => {
                let s = &self.shapes[i as usize];
                EmitterArea {
                    total: s.shape.area(),
                    triangles: None,
                }
            }
            EmitterRef::MeshObject(o) => {
                let m = &self.meshes[self.mesh_objects[o as usize].mesh as usize];
                let areas: Vec<f32> = (0..m.len()).map(|t| m.triangle_area(t)).collect();
                EmitterArea {
                    total: areas.iter().map(|&a| a as f64).sum::<f64>() as f32,
                    triangles: Some(Distribution1D::new(&areas)),
                }
            }
            EmitterRef::Instance(i) => {
                let inst = &self.instances[i as usize];
                let m = &self.meshes[inst.mesh as usize];
                let t = &inst.transform;
                let areas: Vec<f32> = (0..m.len())
                    .map(|k| {
                        let [a, b, c] = m.vertices(k).map(|p| t.point(p));
                        0.5 * (b - a).cross(c - a).length()
                    })
                    .collect();
                EmitterArea {
                    total: areas.iter().map(|&a| a as f64).sum::<f64>() as f32,
                    triangles: Some(Distribution1D::new(&areas)),
                }
            }
        }
    }

    /// A point on an emitter: uniform by area for meshes and untransformed
    /// shapes; for a transformed shape, uniform in object space with the
    /// density corrected by the transform's local area scaling. `uv` asks
    /// for its surface coordinates (a textured emitter); where it does
    /// not, a curved shape's are left zero.
    pub fn sample_emitter(
        &self,
        emitter: EmitterRef,
        area: &EmitterArea,
        u_pick: f32,
        u: Vec2,
        uv: bool,
    ) -> Option<EmitterSample> {
        match emitter {
            EmitterRef::Shape(i) => {
                let s = &self.shapes[i as usize];
                let mut a = s.shape.sample_area(u, uv)?;
                if s.flip_normals {
                    a.n = -a.n;
                }
                let pdf_obj = s.shape.relative_area_density(a.p) / area.total;
                match &s.transform {
                    None => Some(EmitterSample {
                        p: a.p,
                        n: a.n,
                        pdf_area: pdf_obj,
                        uv: a.uv,
                        attribute: Vec3::ZERO,
                    }),
                    Some(t) => {
                        let (n, jac) = normal_and_area_scale(t, a.n);
                        Some(EmitterSample {
                            p: t.point(a.p),
                            n,
                            pdf_area: pdf_obj / jac,
                            uv: a.uv,
                            attribute: Vec3::ZERO,
                        })
                    }
                }
            }
            EmitterRef::MeshObject(o) => {
                let m = &self.meshes[self.mesh_objects[o as usize].mesh as usize];
                let (tri, _, _) = area.triangles.as_ref()?.sample(u_pick);
                let (a, attribute) = m.sample_triangle(tri, u);
                Some(EmitterSample {
                    p: a.p,
                    n: a.n,
                    pdf_area: 1.0 / area.total,
                    uv: a.uv,
                    attribute,
                })
            }
            EmitterRef::Instance(i) => {
                let inst = &self.instances[i as usize];
                let m = &self.meshes[inst.mesh as usize];
                let (tri, _, _) = area.triangles.as_ref()?.sample(u_pick);
                let (a, attribute) = m.sample_triangle(tri, u);
                let (mut n, _) = normal_and_area_scale(&inst.transform, a.n);
                if inst.flip_normals {
                    n = -n;
                }
                Some(EmitterSample {
                    p: inst.transform.point(a.p),
                    n,
                    pdf_area: 1.0 / area.total,
                    uv: a.uv,
                    attribute,
                })
            }
        }
    }
}

/// The same shape with its transform applied, where the transformed shape
/// is a shape of the same kind with the same surface coordinates: a
/// rectangle under any affine map (a parallelogram stays one), a sphere
/// under translation and uniform scaling. Rays then meet it without being
/// carried into object space, and its surface needs no transforming; on the
/// Mitsuba Cornell box, whose walls are transformed rectangles, that was a
/// sixth of the path tracer's time.
fn bake_transform(mut s: ShapeInstance) -> ShapeInstance {
    let (Some(t), None) = (s.transform, &s.motion) else {
        return s;
    };
    match s.shape {
        Shape::Rectangle(r) => {
            s.shape = Shape::Rectangle(crate::geometry::shape::Rectangle::new(
                t.point(r.corner()),
                t.vector(r.edge_u()),
                t.vector(r.edge_v()),
            ));
            // (M a) × (M b) = det M · M⁻ᵀ (a × b): a mirroring map turns the
            // edges' cross product against the transformed normal.
            s.flip_normals ^= t.swaps_handedness();
            s.transform = None;
        }
        Shape::Sphere(sp) => {
            let l = glam::Mat3::from_mat4(t.m);
            let c = l.x_axis.x;
            if c > 0.0 && l == glam::Mat3::from_diagonal(Vec3::splat(c)) {
                s.shape = Shape::Sphere(crate::geometry::shape::Sphere {
                    center: t.point(sp.center),
                    radius: sp.radius * c,
                    uv_frame: sp.uv_frame,
                });
                s.transform = None;
            }
        }
        _ => {}
    }
    s
}

/// Area data of one emitter.
#[derive(Clone, Debug, Default)]
pub struct EmitterArea {
    /// Total area: world-space for meshes and for shapes sampled by
    /// direction (an estimate, `light::crofton_area`), object-space for
    /// other shapes.
    pub total: f32,
    /// Triangle areas, for meshes.
    pub triangles: Option<Distribution1D>,
}

/// The world normal for an object-space unit normal and the factor by
/// which the transform scales areas there: |det M| · |M⁻ᵀ n|.
#[inline]
pub fn normal_and_area_scale(t: &Transform, n_obj: Vec3) -> (Vec3, f32) {
    let nt = t.normal(n_obj);
    let det = glam::Mat3::from_mat4(t.m).determinant().abs();
    let len = nt.length();
    (nt / len, det * len)
}

fn transform_surface(t: &Transform, ls: LocalSurface) -> LocalSurface {
    let (p, p_error) = t.point_with_error(ls.p, ls.p_error);
    LocalSurface {
        p,
        p_error,
        n: t.normal(ls.n).normalize_or_zero(),
        uv: ls.uv,
        dpdu: t.vector(ls.dpdu),
        dpdv: t.vector(ls.dpdv),
    }
}

/// How a block of a packet's leaf is tested.
#[cfg(target_arch = "x86_64")]
enum BlockStep {
    /// Against all rays at once.
    Packet(u32),
    /// Ray by ray, with the blocks after it of the same range.
    OneByOne(BlockRange),
}

/// The blocks of `range` in order: each for which `by_packet(block)`
/// holds by itself, each run of consecutive others together.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn blocks_in_turn((first, count): BlockRange, by_packet: impl Fn(u32) -> bool) -> impl Iterator<Item = BlockStep> {
    let end = first + count;
    let mut b = first;
    std::iter::from_fn(move || {
        if b >= end {
            return None;
        }
        if by_packet(b) {
            b += 1;
            return Some(BlockStep::Packet(b - 1));
        }
        let run_start = b;
        while b < end && !by_packet(b) {
            b += 1;
        }
        Some(BlockStep::OneByOne((run_start, b - run_start)))
    })
}

/// Tests each ray of `rays` whose bit is set in `live` by itself, over
/// its interval so far (`t_max`): `test(lane, ray)` gives its hit, if
/// nearer, which `t_max` and `found` then take.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn one_by_one(
    rays: &[Ray; PACKET],
    live: u32,
    t_max: &mut [f32; PACKET],
    found: &mut [Option<Hit>; PACKET],
    mut test: impl FnMut(usize, &mut Ray) -> Option<Hit>,
) {
    for i in crate::geometry::simd::lanes(live) {
        let mut r = Ray {
            t_max: t_max[i],
            ..rays[i]
        };
        if let Some(h) = test(i, &mut r) {
            t_max[i] = h.t;
            found[i] = Some(h);
        }
    }
}

/// Records, for each lane whose bit is set in `bits`, a hit at its
/// distance in `t` on shape `id`.
#[cfg(target_arch = "x86_64")]
#[inline]
fn record_hits(found: &mut [Option<Hit>; PACKET], bits: u32, t: &[f32; PACKET], id: u32) {
    // The lanes' bits, not a test of each lane: which rays hit is as good
    // as random from block to block.
    for i in crate::geometry::simd::lanes(bits) {
        found[i] = Some(Hit {
            t: t[i],
            prim: HitPrim::Shape(id),
        });
    }
}

/// Completes a surface record: orients the shading normal into the
/// geometric normal's hemisphere and builds a tangent perpendicular to it,
/// unless the shape gave its `tangent` and there is no shading normal.
fn finish_surface(
    t: f32,
    ls: LocalSurface,
    ns: Option<Vec3>,
    tangent: Option<Vec3>,
    material: u32,
    light: Option<u32>,
    attribute: Vec3,
) -> SurfaceHit {
    let ng = ls.n;
    let shading_normal = ns.is_some();
    let ns = match ns {
        Some(n) if n.dot(ng) < 0.0 => -n,
        Some(n) => n,
        None => ng,
    };
    let tangent = match (tangent, shading_normal) {
        (Some(t), false) => t,
        _ => crate::geometry::interaction::unit_tangent(ls.dpdu, ns),
    };
    SurfaceHit {
        t,
        p: ls.p,
        p_error: ls.p_error,
        ng,
        ns,
        uv: ls.uv,
        tangent,
        dpdu: ls.dpdu,
        dpdv: ls.dpdv,
        material,
        light,
        attribute,
        time: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::shape::{Cuboid, Sphere};

    /// Surface records carry a unit tangent perpendicular to the shading
    /// normal, which shading frames use as it is: also for dp/du nearly
    /// along the normal, zero, or huge.
    #[test]
    fn surface_tangents_are_unit_and_perpendicular() {
        let mut rng = crate::sampling::rng::Pcg32::new(4, 4);
        let mut unit = || {
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            crate::sampling::warp::sample_sphere_uniform(u)
        };
        for i in 0..20_000 {
            let (n, other) = (unit(), unit());
            let dpdu = match i % 5 {
                0 => other * 3.0,
                1 => n + other * 1e-4,
                2 => n * 7.0 + other * 1e-7,
                3 => Vec3::ZERO,
                _ => other * 1e30,
            };
            let ls = LocalSurface {
                p: Vec3::ZERO,
                p_error: Vec3::ZERO,
                n,
                uv: Vec2::ZERO,
                dpdu,
                dpdv: n.cross(dpdu),
            };
            let hit = finish_surface(1.0, ls, None, None, 0, None, Vec3::ZERO);
            let t = hit.tangent;
            assert!((t.length() - 1.0).abs() < 1e-5, "{dpdu} at {n}: |t| = {}", t.length());
            assert!(t.dot(hit.ns).abs() < 1e-3, "{dpdu} at {n}: t·n = {}", t.dot(hit.ns));
        }
    }

    /// The blocks of spheres, rectangles and triangles in the top-level
    /// tree's leaves find what testing every primitive by itself finds:
    /// the same nearest primitive at the same distance (to the bit), and
    /// the same answer to shadow rays, in scattered scenes and in dense
    /// ones where leaves hold full blocks, next to shapes tested alone.
    #[test]
    fn leaf_blocks_find_what_every_primitive_finds() {
        use crate::geometry::triangle::intersect_triangle_with;
        let mut rng = crate::sampling::rng::Pcg32::new(25, 3);
        let mut point = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        for (scene, spread) in [(0u32, 4.0f32), (1, 1.0), (2, 0.2)] {
            let mut shapes = Vec::new();
            for k in 0..40 {
                let c = point() * spread;
                let shape = match k % 3 {
                    0 => Shape::Sphere(Sphere::new(c, 0.05 + 0.3 * point().x.abs())),
                    1 => Shape::Rectangle(crate::geometry::shape::Rectangle::new(c, point() * 0.5, point() * 0.5)),
                    _ => Shape::Cuboid(crate::geometry::shape::Cuboid {
                        min: c,
                        max: c + point().abs() * 0.3 + 0.01,
                    }),
                };
                shapes.push(ShapeInstance {
                    shape,
                    transform: None,
                    motion: None,
                    material: k,
                    light: None,
                    flip_normals: false,
                });
            }
            // A huge sphere, as smallpt's walls.
            shapes.push(ShapeInstance {
                shape: Shape::Sphere(Sphere::new(Vec3::new(1e4 + 6.0, 0.0, 0.0), 1e4)),
                transform: None,
                motion: None,
                material: 50,
                light: None,
                flip_normals: false,
            });
            let mut mesh = TriangleMesh::default();
            for t in 0..30u32 {
                let c = point() * spread;
                mesh.positions.extend([c, c + point() * 0.4, c + point() * 0.4]);
                mesh.indices.push([3 * t, 3 * t + 1, 3 * t + 2]);
            }
            let objects = vec![MeshObject {
                mesh: 0,
                material: 60,
                light: None,
            }];
            let g = Aggregate::build(vec![mesh.clone()], shapes.clone(), objects, vec![]);
            #[cfg(target_arch = "x86_64")]
            if crate::geometry::lanes::avx_available() {
                assert!(g.stats().leaf_blocks > 0, "scene {scene}");
            }
            let mut hits = 0;
            for _ in 0..3000 {
                let ray = Ray::new(point() * spread * 1.5, point());
                // Every primitive by itself, keeping the nearest (the
                // first of equal distances).
                let mut best: Option<(f32, HitPrim)> = None;
                let mut r = ray;
                for (i, s) in shapes.iter().enumerate() {
                    if let Some(t) = s.shape.intersect(&r) {
                        if best.is_none_or(|(b, _)| t < b) {
                            best = Some((t, HitPrim::Shape(i as u32)));
                            r.t_max = t;
                        }
                    }
                }
                if let Some(pre) = TriangleRay::new(&ray) {
                    for tri in 0..mesh.len() {
                        let [p0, p1, p2] = mesh.vertices(tri);
                        if let Some(h) = intersect_triangle_with(&r, &pre, p0, p1, p2) {
                            if best.is_none_or(|(b, _)| h.t < b) {
                                best = Some((
                                    h.t,
                                    HitPrim::Triangle {
                                        object: 0,
                                        tri: tri as u32,
                                        b: h.b,
                                    },
                                ));
                                r.t_max = h.t;
                            }
                        }
                    }
                }
                let got = g.intersect(&ray);
                assert_eq!(g.occluded(&ray), best.is_some(), "scene {scene}, ray {ray:?}");
                match (got, best) {
                    (None, None) => {}
                    (Some(h), Some((t, prim))) => {
                        hits += 1;
                        let context = format!("scene {scene}, ray {ray:?}: {h:?} against {prim:?}");
                        match (h.prim, prim) {
                            // Equal distances (a cube's edge) may name either.
                            (HitPrim::Shape(a), HitPrim::Shape(b)) => {
                                assert_eq!(h.t.to_bits(), t.to_bits(), "{context}");
                                assert!(
                                    a == b || matches!(shapes[a as usize].shape, Shape::Cuboid(_)),
                                    "{context}"
                                );
                            }
                            // The blocks run the watertight test of the
                            // mesh trees' blocks (`Triangle4`), whose
                            // rounding differs from the one-triangle test's
                            // by a few units in the last place.
                            (HitPrim::Triangle { tri: a, b: ba, .. }, HitPrim::Triangle { tri: b, b: bb, .. }) => {
                                assert_eq!(a, b, "{context}");
                                assert!((h.t - t).abs() <= 1e-5 * (t + 1.0), "{context}");
                                assert!(ba.iter().zip(bb).all(|(x, y)| (x - y).abs() < 1e-5), "{context}");
                            }
                            _ => panic!("{context}"),
                        }
                    }
                    (got, expected) => panic!("scene {scene}: {got:?} against {expected:?} on {ray:?}"),
                }
            }
            assert!(hits > 300, "scene {scene}: {hits} hits");
        }
    }

    /// Eight rays tested together through a tree of one leaf find, bit for
    /// bit, what each finds by itself: on one sphere, in an empty room (a
    /// block of six rectangles), on smallpt's nine spheres (a block of
    /// eight and one of one), and in a room with two boxes (blocks of
    /// eight, eight and two rectangles) and a triangle;
    /// with lanes left out, a zero direction, bounded intervals, and rays
    /// aimed at the room's corners and edges, where walls are equally
    /// near and the one-ray tests' order decides.
    #[test]
    fn rays_tested_together_find_what_each_finds() {
        let sphere = |c: Vec3, r: f32| ShapeInstance {
            shape: Shape::Sphere(Sphere::new(c, r)),
            transform: None,
            motion: None,
            material: 0,
            light: None,
            flip_normals: false,
        };
        let rectangle = |corner: Vec3, u: Vec3, v: Vec3| ShapeInstance {
            shape: Shape::Rectangle(Rectangle::new(corner, u, v)),
            ..sphere(Vec3::ZERO, 1.0)
        };
        // A box's six faces as rectangles.
        let faces = |min: Vec3, size: Vec3| {
            let (x, y, z) = (Vec3::X * size.x, Vec3::Y * size.y, Vec3::Z * size.z);
            [
                rectangle(min, x, z),
                rectangle(min + y, z, x),
                rectangle(min, y, x),
                rectangle(min + z, x, y),
                rectangle(min, z, y),
                rectangle(min + x, y, z),
            ]
        };
        let mut room: Vec<ShapeInstance> = faces(Vec3::splat(-2.0), Vec3::splat(4.0)).into();
        room.extend(faces(Vec3::new(-1.5, -2.0, -1.0), Vec3::new(1.0, 1.5, 1.0)));
        room.extend(faces(Vec3::new(0.5, -2.0, 0.0), Vec3::new(1.0, 2.5, 1.0)));
        let mut mesh = TriangleMesh::default();
        mesh.positions.extend([
            Vec3::new(-1.0, 1.5, -1.0),
            Vec3::new(1.0, 1.5, -1.0),
            Vec3::new(0.0, 1.5, 1.0),
        ]);
        mesh.indices.push([0, 1, 2]);
        let scenes = [
            (vec![sphere(Vec3::ZERO, 1.0)], vec![], vec![]),
            (faces(Vec3::splat(-2.0), Vec3::splat(4.0)).into(), vec![], vec![]),
            (
                // smallpt's: walls of radius 10⁴ and three balls.
                [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z]
                    .map(|n| sphere(n * (1e4 + 2.0), 1e4))
                    .into_iter()
                    .chain([-1.0, 0.0, 1.0].map(|x| sphere(Vec3::new(x, -1.4, x * 0.5), 0.5)))
                    .collect(),
                vec![],
                vec![],
            ),
            (
                room,
                vec![mesh],
                vec![MeshObject {
                    mesh: 0,
                    material: 1,
                    light: None,
                }],
            ),
        ];
        let mut rng = crate::sampling::rng::Pcg32::new(7, 3);
        let mut masks = crate::sampling::rng::Pcg32::new(8, 5);
        let mut unit = || crate::sampling::warp::sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
        let corners: Vec<Vec3> = (0..8)
            .map(|k: u32| glam::UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1).as_vec3() * 4.0 - 2.0)
            .collect();
        for (scene, (shapes, meshes, objects)) in scenes.into_iter().enumerate() {
            let g = Aggregate::build(meshes, shapes, objects, vec![]);
            #[cfg(target_arch = "x86_64")]
            if crate::geometry::lanes::avx_available() {
                assert!(g.bvh.root_leaf().is_some(), "scene {scene} is one leaf");
                assert!(g.packet_items.is_some(), "scene {scene}");
            }
            let mut together = 0;
            for round in 0..4000 {
                let rays: [Ray; 8] = std::array::from_fn(|i| {
                    let origin = unit() * if scene == 0 { 3.0 } else { 1.9 };
                    let mut ray = match (round + i) % 5 {
                        // Toward a corner or the middle of an edge.
                        0 => Ray::new(origin, corners[(round + i) % 8] - origin),
                        1 => Ray::new(origin, (corners[i] + corners[(i + 1) % 8]) * 0.5 - origin),
                        _ => Ray::new(origin, unit()),
                    };
                    if round % 7 == i {
                        ray.t_max = 0.5 + i as f32 * 0.3;
                    }
                    if round % 11 == i {
                        ray.dir = Vec3::ZERO;
                    }
                    ray
                });
                let live = if round % 3 == 0 {
                    0xff
                } else {
                    (masks.next_u32() & 0xff) | 1
                };
                let mut found = [None; 8];
                if !g.intersect_together(&rays, live, &mut found) {
                    continue;
                }
                together += 1;
                for (i, ray) in rays.iter().enumerate() {
                    if live & (1 << i) != 0 {
                        assert_eq!(
                            found[i],
                            g.intersect(ray),
                            "scene {scene}, round {round}, lane {i}: {ray:?}"
                        );
                    }
                }
            }
            #[cfg(target_arch = "x86_64")]
            if crate::geometry::lanes::avx_available() {
                assert!(together > 1000, "scene {scene}: {together} packets");
            }
        }
    }

    /// The surface records of a packet's hits on spheres, made together in
    /// vector lanes, hold the bits of those made one by one: on spheres
    /// with other frames of surface coordinates, normals flipped, a
    /// material that reads (u, v) (left to the one-by-one records), huge
    /// walls, and hits at the poles.
    #[cfg(target_arch = "x86_64")]
    #[test]
    #[allow(unsafe_code)]
    fn sphere_records_made_together_are_those_made_one_by_one() {
        if !crate::geometry::lanes::avx_available() {
            return;
        }
        let turned = glam::Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.7);
        let sphere = |c: Vec3, r: f32, k: u32| ShapeInstance {
            shape: Shape::Sphere(Sphere {
                uv_frame: if k % 3 == 1 { turned } else { glam::Mat3::IDENTITY },
                ..Sphere::new(c, r)
            }),
            transform: None,
            motion: None,
            material: k % 4,
            light: (k % 5 == 0).then_some(k),
            flip_normals: k % 2 == 1,
        };
        let shapes: Vec<ShapeInstance> = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z]
            .into_iter()
            .map(|n| n * (1e4 + 2.0))
            .chain([-1.0, 0.0, 1.0].map(|x| Vec3::new(x, -1.4, x * 0.5)))
            .enumerate()
            .map(|(k, c)| sphere(c, if k < 6 { 1e4 } else { 0.5 }, k as u32))
            .collect();
        let g = Aggregate::build(vec![], shapes, vec![], vec![]);
        let reads_uv = |m: u32| m == 3;
        let mut rng = crate::sampling::rng::Pcg32::new(9, 1);
        let mut unit = || crate::sampling::warp::sample_sphere_uniform(Vec2::new(rng.next_f32(), rng.next_f32()));
        let (mut together, mut alone) = (0, 0);
        for round in 0..3000 {
            let rays: [Ray; 8] = std::array::from_fn(|i| {
                let origin = unit() * 1.9;
                match (round + i) % 4 {
                    // Toward a ball's pole.
                    0 => Ray::new(origin, Vec3::new(0.0, -0.9, 0.0) - origin),
                    _ => Ray::new(origin, unit()),
                }
            });
            let live = if round % 2 == 0 { 0xff } else { 0b0111_1011 };
            let mut found = [None; 8];
            if !g.intersect_together(&rays, live, &mut found) {
                continue;
            }
            let mut slots = [None; 8];
            // SAFETY: the processor has AVX (checked above).
            let done = unsafe { g.sphere_surfaces(&rays, &found, live, reads_uv, &mut slots) };
            assert_eq!(done & !live, 0);
            for i in 0..8 {
                let Some(hit) = &found[i] else {
                    assert_eq!(done & (1 << i), 0);
                    continue;
                };
                if done & (1 << i) == 0 {
                    alone += 1;
                    continue;
                }
                together += 1;
                let expect = g.surface_with(&rays[i], hit, reads_uv);
                assert_eq!(
                    format!("{:?}", slots[i].expect("a record")),
                    format!("{expect:?}"),
                    "round {round}, lane {i}"
                );
            }
        }
        assert!(together > 10_000 && alone > 1000, "{together} together, {alone} alone");
    }

    /// Rays parallel to a rectangle of a block (a zero denominator: t is
    /// ±∞ or NaN) miss it, in its plane or beside it, with an unbounded
    /// interval or not, as the one-rectangle test has them; and a ray
    /// across hits.
    #[test]
    fn rays_parallel_to_a_rectangle_miss_it() {
        use crate::geometry::shape::Rectangle;
        let floor = Rectangle::new(Vec3::ZERO, Vec3::X, Vec3::Z);
        let wall = Rectangle::new(Vec3::new(0.0, 0.0, 2.0), Vec3::X, Vec3::Y);
        let shapes = [floor, wall]
            .into_iter()
            .map(|r| ShapeInstance {
                shape: Shape::Rectangle(r),
                transform: None,
                motion: None,
                material: 0,
                light: None,
                flip_normals: false,
            })
            .collect();
        let g = Aggregate::build(vec![], shapes, vec![], vec![]);
        #[cfg(target_arch = "x86_64")]
        if crate::geometry::lanes::avx_available() {
            assert_eq!(g.stats().leaf_blocks, 1);
        }
        for t_max in [f32::INFINITY, 10.0] {
            for origin in [
                Vec3::new(-1.0, 0.0, 0.5),
                Vec3::new(-1.0, 0.25, 0.5),
                Vec3::new(-1.0, 0.5, 2.0),
            ] {
                // Along +x, parallel to both: in the floor's plane across
                // it, above it, in the wall's plane across it.
                let ray = Ray::with_interval(origin, Vec3::X, 1e-4, t_max);
                assert!(g.intersect(&ray).is_none() && !g.occluded(&ray), "{origin} {t_max}");
                assert!(floor.intersect(&ray).is_none() && wall.intersect(&ray).is_none());
            }
            // Along +z from above the floor: parallel to it, into the wall.
            let ray = Ray::with_interval(Vec3::new(0.5, 0.25, -1.0), Vec3::Z, 1e-4, t_max);
            let hit = g.intersect(&ray).expect("the wall is hit");
            assert!(matches!(hit.prim, HitPrim::Shape(1)) && hit.t == 3.0, "{hit:?}");
        }
    }

    /// Rays through the diagonal shared by two triangles of a block hit
    /// one of them, as with the one-triangle test.
    #[test]
    fn triangle_blocks_are_watertight() {
        use crate::geometry::triangle::tests::{DIAGONAL_QUAD, assert_diagonal_is_watertight};
        let q = DIAGONAL_QUAD;
        let mesh = TriangleMesh {
            positions: q.to_vec(),
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..TriangleMesh::default()
        };
        let objects = vec![MeshObject {
            mesh: 0,
            material: 0,
            light: None,
        }];
        let g = Aggregate::build(vec![mesh], vec![], objects, vec![]);
        #[cfg(target_arch = "x86_64")]
        if crate::geometry::lanes::avx_available() {
            assert_eq!(g.stats().leaf_blocks, 1);
        }
        assert_diagonal_is_watertight(13, |r| g.intersect(r).is_some());
    }

    fn one_shape(shape: Shape, transform: Transform) -> Aggregate {
        Aggregate::build(
            vec![],
            vec![ShapeInstance {
                shape,
                transform: Some(transform),
                motion: None,
                material: 0,
                light: None,
                flip_normals: false,
            }],
            vec![],
            vec![],
        )
    }

    fn hit(g: &Aggregate, o: Vec3, d: Vec3) -> Option<SurfaceHit> {
        let r = Ray::new(o, d);
        g.intersect(&r).map(|h| g.surface(&r, &h))
    }

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    /// A unit sphere scaled by (2, 1, 1) is the ellipsoid x²/4 + y² + z² = 1,
    /// whose normal at p is along (x/4, y, z).
    #[test]
    fn scaled_sphere_is_an_exact_ellipsoid() {
        let g = one_shape(
            Shape::Sphere(Sphere::new(Vec3::ZERO, 1.0)),
            Transform::scale(Vec3::new(2.0, 1.0, 1.0)).unwrap(),
        );
        let h = hit(&g, Vec3::new(-5.0, 0.0, 0.0), Vec3::X).unwrap();
        assert!((h.t - 3.0).abs() < 1e-5 && close(h.ng, -Vec3::X));
        // Ray along y at x = 1: hits where y = sqrt(1 − 1/4).
        let h = hit(&g, Vec3::new(1.0, -5.0, 0.0), Vec3::Y).unwrap();
        let y = -(0.75f32).sqrt();
        assert!(close(h.p, Vec3::new(1.0, y, 0.0)), "{}", h.p);
        assert!(close(h.ng, Vec3::new(0.25, y, 0.0).normalize()), "{}", h.ng);
        // Unnormalised directions keep t in world units of the direction.
        let h = hit(&g, Vec3::new(-5.0, 0.0, 0.0), Vec3::X * 2.0).unwrap();
        assert!((h.t - 1.5).abs() < 1e-5);
    }

    /// A box sheared by x += y has slanted sides with normal (1, −1, 0)/√2
    /// and a top face that keeps normal +y but moves right.
    #[test]
    fn sheared_box_faces_and_normals() {
        let g = one_shape(
            Shape::Cuboid(Cuboid {
                min: Vec3::splat(-1.0),
                max: Vec3::ONE,
            }),
            Transform::shear(1.0, 0.0, 0.0, 0.0, 0.0, 0.0).unwrap(),
        );
        let h = hit(&g, Vec3::new(1.5, 5.0, 0.0), -Vec3::Y).unwrap();
        assert!((h.t - 4.0).abs() < 1e-5 && close(h.ng, Vec3::Y));
        // Beyond the top face's shifted extent [0, 2] there is only the slanted side.
        assert!(hit(&g, Vec3::new(-0.5, 5.0, 0.5), -Vec3::Y).is_some_and(|h| h.p.y < 1.0 - 1e-3));
        let h = hit(&g, Vec3::new(5.0, 0.5, 0.0), -Vec3::X).unwrap();
        assert!(close(h.p, Vec3::new(1.5, 0.5, 0.0)), "{}", h.p);
        assert!(close(h.ng, Vec3::new(1.0, -1.0, 0.0).normalize()), "{}", h.ng);
    }

    /// A box rotated 45° about y: a ray along −z meets its edge at distance √2.
    #[test]
    fn rotated_box() {
        let g = one_shape(
            Shape::Cuboid(Cuboid {
                min: Vec3::splat(-1.0),
                max: Vec3::ONE,
            }),
            Transform::rotate(Vec3::Y, 45.0).unwrap(),
        );
        let h = hit(&g, Vec3::new(0.0, 0.0, 5.0), -Vec3::Z).unwrap();
        assert!((h.t - (5.0 - 2f32.sqrt())).abs() < 1e-5, "{}", h.t);
        let h = hit(&g, Vec3::new(0.5, 0.0, 5.0), -Vec3::Z).unwrap();
        assert!(close(h.ng, Vec3::new(1.0, 0.0, 1.0).normalize()), "{}", h.ng);
    }

    /// A mirroring transform keeps outward normals outward.
    #[test]
    fn mirrored_sphere_normals_point_out() {
        let g = one_shape(
            Shape::Sphere(Sphere::new(Vec3::new(1.0, 0.0, 0.0), 1.0)),
            Transform::scale(Vec3::new(-1.0, 1.0, 1.0)).unwrap(),
        );
        let h = hit(&g, Vec3::new(-5.0, 0.0, 0.0), Vec3::X).unwrap();
        assert!((h.t - 3.0).abs() < 1e-5 && close(h.ng, -Vec3::X), "{} {}", h.t, h.ng);
    }

    /// Sampled points on a transformed emitter lie on it, and the density
    /// that sampling reports matches `emitter_pdf_area` there; over the
    /// surface the density integrates to 1 (Monte Carlo over the samples:
    /// E[1/pdf] = area).
    #[test]
    fn emitter_sampling_density_is_consistent() {
        let t = Transform::scale(Vec3::new(2.0, 0.5, 1.0))
            .unwrap()
            .then(&Transform::rotate(Vec3::new(1.0, 2.0, 0.5), 30.0).unwrap());
        let g = one_shape(
            Shape::Cuboid(Cuboid {
                min: Vec3::ZERO,
                max: Vec3::ONE,
            }),
            t,
        );
        let e = EmitterRef::Shape(0);
        let area = g.emitter_area(e);
        let mut r = crate::sampling::Pcg32::new(3, 0);
        let n = 20_000;
        let mut inv_pdf_sum = 0.0f64;
        for _ in 0..n {
            let s = g
                .sample_emitter(e, &area, r.next_f32(), Vec2::new(r.next_f32(), r.next_f32()), true)
                .unwrap();
            let back = g.emitter_pdf_area(e, &area, s.p, s.n);
            assert!(
                (back - s.pdf_area).abs() < 1e-4 * s.pdf_area,
                "{back} vs {}",
                s.pdf_area
            );
            inv_pdf_sum += 1.0 / s.pdf_area as f64;
        }
        // World area of the transformed unit cube: faces scaled by the transform.
        let world_area: f64 = [Vec3::X, Vec3::Y, Vec3::Z]
            .iter()
            .map(|&n| 2.0 * normal_and_area_scale(&t, n).1 as f64)
            .sum();
        let est = inv_pdf_sum / n as f64;
        assert!((est - world_area).abs() < 0.01 * world_area, "{est} vs {world_area}");
    }

    /// A bent bilinear patch emitter, plain and transformed: its points are
    /// drawn with pbrt-v4's bilinear density, not uniformly, so estimates
    /// that divide by the density reported (by sampling, and by
    /// `emitter_pdf_area` at the point) integrate a function of the point
    /// over the world surface: here the height², within 4.5 standard errors
    /// (a uniform density, 1 / area, is 2 % off: 15 of them).
    #[test]
    fn bilinear_emitters_report_the_density_they_draw_with() {
        let patch = crate::geometry::bilinear::BilinearPatch::new(
            Vec3::new(-0.6, 1.9, -0.6),
            Vec3::new(0.6, 0.1, -0.6),
            Vec3::new(-0.6, 0.1, 0.6),
            Vec3::new(0.6, 1.9, 0.6),
        );
        let t = Transform::scale(Vec3::new(1.5, 1.0, 0.7))
            .unwrap()
            .then(&Transform::rotate(Vec3::new(1.0, 0.2, 0.3), 40.0).unwrap());
        for transform in [Transform::IDENTITY, t] {
            let g = one_shape(Shape::Bilinear(patch), transform);
            let e = EmitterRef::Shape(0);
            let area = g.emitter_area(e);
            let height2 = |p: Vec3| (p.y as f64) * (p.y as f64);
            // ∫ y² dA over the world surface, by the midpoint rule in (u, v).
            let n = 400;
            let mut integral = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    let (u, v) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                    let (du, dv) = patch.tangents(u, v);
                    let (du, dv) = (transform.vector(du.as_vec3()), transform.vector(dv.as_vec3()));
                    let p = transform.point(patch.point(u, v).as_vec3());
                    integral += height2(p) * du.cross(dv).length() as f64 / (n * n) as f64;
                }
            }
            let mut r = crate::sampling::Pcg32::new(9, 0);
            let samples = 200_000;
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for _ in 0..samples {
                let s = g
                    .sample_emitter(e, &area, r.next_f32(), Vec2::new(r.next_f32(), r.next_f32()), false)
                    .unwrap();
                let back = g.emitter_pdf_area(e, &area, s.p, s.n);
                assert!(
                    (back - s.pdf_area).abs() < 1e-3 * s.pdf_area,
                    "{back} vs {}",
                    s.pdf_area
                );
                let x = height2(s.p) / s.pdf_area as f64;
                sum += x;
                sum2 += x * x;
            }
            let est = sum / samples as f64;
            let se = ((sum2 / samples as f64 - est * est) / samples as f64).sqrt();
            assert!((est - integral).abs() < 4.5 * se, "{est} ± {se} vs {integral}");
        }
    }

    /// A transformed rectangle is stored in world space: a ray meets it
    /// where it meets the transformed parallelogram, with the normal
    /// transformed by M⁻ᵀ (also under a mirroring map), the object-space
    /// surface coordinates, and, as an emitter, density 1 / world area.
    #[test]
    fn transformed_rectangles_are_baked_exactly() {
        let rect = Shape::Rectangle(crate::geometry::shape::Rectangle::new(
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        ));
        for mirror in [1.0, -1.0] {
            let t = Transform::scale(Vec3::new(mirror * 2.0, 0.5, 1.0))
                .unwrap()
                .then(&Transform::rotate(Vec3::new(1.0, 0.0, 0.0), 30.0).unwrap())
                .then(&Transform::translate(Vec3::new(0.0, 0.0, 1.0)));
            let g = one_shape(rect.clone(), t);
            assert!(g.shapes[0].transform.is_none(), "baked");
            // Aim at the image of object point (0.5, 0.25, 0): uv (0.75, 0.625).
            let target = t.point(Vec3::new(0.5, 0.25, 0.0));
            let n_expected = t.normal(Vec3::Z).normalize();
            let o = target + 3.0 * n_expected;
            let h = hit(&g, o, target - o).unwrap();
            assert!(close(h.p, target), "{mirror}: {} vs {target}", h.p);
            assert!(close(h.ng, n_expected), "{mirror}: {} vs {n_expected}", h.ng);
            assert!((h.uv - Vec2::new(0.75, 0.625)).length() < 1e-5, "{mirror}: {}", h.uv);
            let e = EmitterRef::Shape(0);
            let area = g.emitter_area(e);
            let world_area = 4.0 * normal_and_area_scale(&t, Vec3::Z).1;
            assert!((area.total - world_area).abs() < 1e-5 * world_area);
            let s = g.sample_emitter(e, &area, 0.5, Vec2::new(0.3, 0.6), true).unwrap();
            assert!(close(s.n, n_expected) && (s.pdf_area * world_area - 1.0).abs() < 1e-5);
        }
    }
}
