//! Blocks of eight primitives of one kind, tested against a ray in eight
//! vector lanes: what the leaves of a scene's top-level tree hold
//! ([`Aggregate`](super::Aggregate)). Each kind is laid out as structure of arrays (Embree's
//! "triangle8" layout) and tested without a branch that depends on the
//! primitive: spheres (the refined quadratic of [`Sphere::intersect`],
//! the same bits), rectangles (the operations of
//! [`Rectangle::intersect`] in the same order) and triangles (the
//! watertight test of [`Triangle4`](crate::geometry::triangle::Triangle4)).
//! The other way round, a [`RayPacket`] tests one sphere or rectangle of
//! a block against up to eight rays in lanes, with the same arithmetic
//! per lane: how the path tracer's lanes go through a tree of one leaf.
//!
//! The lane code is built for AVX. Blocks exist only where the processor
//! has it ([`Blocks::new`] says so once); elsewhere the tree holds the
//! same primitives one by one.

#[cfg(target_arch = "x86_64")]
pub(crate) use avx::*;

#[cfg(target_arch = "x86_64")]
mod avx {
    use crate::geometry::bounds::gamma;
    use crate::geometry::lanes::{F8, LANES, Lanes, M8, avx_available};
    use crate::geometry::real::Real;
    use crate::geometry::shape::{SphereRay, sphere_distance};
    use crate::geometry::triangle::TriangleRay;
    use crate::geometry::{Ray, Rectangle, Sphere};
    use glam::Vec3;

    /// Eight rectangles: `[corner, normal, dual_u, dual_v][axis]`, and the
    /// caller's numbers. An empty lane holds NaN, which every comparison
    /// rejects.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Rectangle8 {
        pub(crate) v: [[Lanes; 3]; 4],
        pub(crate) ids: [u32; LANES],
    }

    /// Eight triangles: `v[vertex][axis]`, and the caller's numbers. An
    /// empty lane holds NaN vertices.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Triangle8 {
        pub(crate) v: [[Lanes; 3]; 3],
        pub(crate) ids: [u32; LANES],
    }

    /// Packs `points[k][axis]` of up to eight primitives into lanes.
    pub(crate) fn pack<const K: usize>(items: &[[Vec3; K]]) -> [[Lanes; 3]; K] {
        let mut v = [[Lanes([f32::NAN; LANES]); 3]; K];
        for (lane, points) in items.iter().enumerate() {
            for (k, p) in points.iter().enumerate() {
                for axis in 0..3 {
                    v[k][axis].0[lane] = p[axis];
                }
            }
        }
        v
    }

    pub(crate) fn pack_ids<T>(chunk: &[&(T, u32)]) -> [u32; LANES] {
        let mut ids = [u32::MAX; LANES];
        for (lane, (_, id)) in chunk.iter().enumerate() {
            ids[lane] = *id;
        }
        ids
    }

    /// `[x, y, z]` loaded.
    #[inline]
    #[target_feature(enable = "avx")]
    pub(crate) fn load3(v: &[Lanes; 3]) -> [F8; 3] {
        [F8::load(&v[0]), F8::load(&v[1]), F8::load(&v[2])]
    }

    /// `a · b` in the order of glam's `Vec3::dot`.
    #[inline]
    #[target_feature(enable = "avx")]
    pub(crate) fn dot(a: [F8; 3], b: [F8; 3]) -> F8 {
        a[0].mul(b[0]).add(a[1].mul(b[1])).add(a[2].mul(b[2]))
    }

    impl Rectangle8 {
        /// Bit per lane the ray meets within `(ray.t_min, t_max]`, and the
        /// lanes' distances: [`Rectangle::intersect`] on eight lanes.
        #[inline]
        #[target_feature(enable = "avx")]
        pub(crate) fn intersect(&self, ray: &Ray, t_max: f32) -> (u32, F8) {
            let corner = load3(&self.v[0]);
            let frame = [corner, load3(&self.v[1]), load3(&self.v[2]), load3(&self.v[3])];
            let (origin, dir, t_min) = ray.read_by_field();
            let o = [F8::splat(origin.x), F8::splat(origin.y), F8::splat(origin.z)];
            let d = [F8::splat(dir.x), F8::splat(dir.y), F8::splat(dir.z)];
            let (valid, t) = rectangle_lanes(frame, o, d, F8::splat(t_min), F8::splat(t_max.min(f32::MAX)));
            (valid.bits(), t)
        }
    }

    /// [`Rectangle::intersect`] on eight lanes, rectangles
    /// `[corner, normal, dual_u, dual_v]` against rays `o + t·d`: whether
    /// each lane's hit lies within `(t_min, t_max]`, and its distance.
    /// Either the rectangles or the rays may be the same in every lane.
    /// The one-rectangle test's conditions, denominator not zero and t
    /// finite, take two comparisons: t is ±∞ or NaN where the denominator
    /// is zero, `t > t_min` is false for −∞ and NaN, and `t <= t_max` with
    /// t_max at most the largest float (the callers' part) is false for
    /// +∞.
    #[inline]
    #[target_feature(enable = "avx")]
    pub(crate) fn rectangle_lanes(frame: [[F8; 3]; 4], o: [F8; 3], d: [F8; 3], t_min: F8, t_max: F8) -> (M8, F8) {
        let [corner, n, dual_u, dual_v] = frame;
        let denom = dot(n, d);
        let q = [corner[0].sub(o[0]), corner[1].sub(o[1]), corner[2].sub(o[2])];
        let t = dot(n, q).div(denom);
        // The point `o + d·t` relative to the corner.
        let r = [
            o[0].add(d[0].mul(t)).sub(corner[0]),
            o[1].add(d[1].mul(t)).sub(corner[1]),
            o[2].add(d[2].mul(t)).sub(corner[2]),
        ];
        let u = dot(dual_u, r);
        let v = dot(dual_v, r);
        let (zero, one) = (F8::splat(0.0), F8::splat(1.0));
        let valid = t
            .gt(t_min)
            .and(t.le(t_max))
            .and(u.ge(zero))
            .and(u.le(one))
            .and(v.ge(zero))
            .and(v.le(one));
        (valid, t)
    }

    /// The edge functions and their sum per lane, from which a hit lane's
    /// barycentrics follow.
    pub(crate) struct Edges {
        e: [F8; 3],
        det: F8,
    }

    impl Edges {
        #[inline]
        #[target_feature(enable = "avx")]
        pub(crate) fn barycentrics(&self, lane: usize) -> [f32; 3] {
            let inv_det = 1.0 / self.det.to_array()[lane];
            [
                self.e[0].to_array()[lane] * inv_det,
                self.e[1].to_array()[lane] * inv_det,
                self.e[2].to_array()[lane] * inv_det,
            ]
        }
    }

    /// What the triangle test needs of a ray, in lanes, made once per ray:
    /// the axis permutation and shear of [`TriangleRay`], the permuted
    /// origin and the interval's start.
    pub(crate) struct RayLanes {
        axes: [usize; 3],
        origin: [F8; 3],
        shear: [F8; 3],
        t_min: F8,
    }

    impl RayLanes {
        #[inline]
        #[target_feature(enable = "avx")]
        pub(crate) fn new(ray: &Ray, pre: &TriangleRay) -> RayLanes {
            let axes = [pre.kx, pre.ky, pre.kz];
            let (origin, _, t_min) = ray.read_by_field();
            RayLanes {
                axes,
                origin: [
                    F8::splat(origin[pre.kx]),
                    F8::splat(origin[pre.ky]),
                    F8::splat(origin[pre.kz]),
                ],
                shear: [F8::splat(pre.sx), F8::splat(pre.sy), F8::splat(pre.sz)],
                t_min: F8::splat(t_min),
            }
        }

        /// A vertex's lanes translated to the ray origin, permuted and
        /// sheared (z scaled for the distance).
        #[inline]
        #[target_feature(enable = "avx")]
        pub(crate) fn vertex(&self, v: &[Lanes; 3]) -> (F8, F8, F8) {
            let [kx, ky, kz] = self.axes;
            let z = F8::load(&v[kz]).sub(self.origin[2]);
            (
                F8::load(&v[kx]).sub(self.origin[0]).add(self.shear[0].mul(z)),
                F8::load(&v[ky]).sub(self.origin[1]).add(self.shear[1].mul(z)),
                z.mul(self.shear[2]),
            )
        }
    }

    /// `a·b − c·d` in f32.
    #[inline]
    #[target_feature(enable = "avx")]
    pub(crate) fn difference_of_products(a: F8, b: F8, c: F8, d: F8) -> F8 {
        a.mul(b).sub(c.mul(d))
    }

    /// The largest of three magnitudes.
    #[inline]
    #[target_feature(enable = "avx")]
    pub(crate) fn max_abs(a: F8, b: F8, c: F8) -> F8 {
        a.abs().max(b.abs()).max(c.abs())
    }

    impl Triangle8 {
        /// Bit per lane the ray meets within `(ray.t_min, t_max]`, the
        /// lanes' distances and their edge functions: the watertight test
        /// of `Triangle4` on eight lanes.
        #[inline]
        #[target_feature(enable = "avx")]
        pub(crate) fn intersect(&self, ray: &RayLanes, t_max: F8) -> (u32, F8, Edges) {
            // Translate to the origin, permute so that |d.z| is largest,
            // shear the direction onto +z; z is scaled for the distance only.
            let (x0, y0, z0) = ray.vertex(&self.v[0]);
            let (x1, y1, z1) = ray.vertex(&self.v[1]);
            let (x2, y2, z2) = ray.vertex(&self.v[2]);
            let mut e = [
                difference_of_products(x1, y2, y1, x2),
                difference_of_products(x2, y0, y2, x0),
                difference_of_products(x0, y1, y0, x1),
            ];
            let zero = F8::splat(0.0);
            if e[0].eq(zero).or(e[1].eq(zero)).or(e[2].eq(zero)).bits() != 0 {
                // An edge function that rounds to zero gets its exact sign
                // in double precision (Woop et al. 2013, section 4).
                let exact = |ax: F8, by: F8, ay: F8, bx: F8| {
                    let (ax, by, ay, bx) = (ax.to_array(), by.to_array(), ay.to_array(), bx.to_array());
                    F8::from_array(std::array::from_fn(|i| {
                        (ax[i] as f64 * by[i] as f64 - ay[i] as f64 * bx[i] as f64) as f32
                    }))
                };
                e = [exact(x1, y2, y1, x2), exact(x2, y0, y2, x0), exact(x0, y1, y0, x1)];
            }
            let [e0, e1, e2] = e;
            let negative = e0.lt(zero).or(e1.lt(zero)).or(e2.lt(zero));
            let positive = e0.gt(zero).or(e1.gt(zero)).or(e2.gt(zero));
            let det = e0.add(e1).add(e2);
            let inside = det.ne(zero).and_not(negative.and(positive));
            let edges = Edges { e, det };
            // Most blocks lie off the ray: stop before the distances.
            if inside.bits() == 0 {
                return (0, zero, edges);
            }
            let t = e0.mul(z0).add(e1.mul(z1)).add(e2.mul(z2)).div(det);
            // Reject hits whose t is not certainly positive given rounding
            // (pbrt-v4, section 6.8.4), as the one-triangle test does.
            let max_zt = max_abs(z0, z1, z2);
            let max_xt = max_abs(x0, x1, x2);
            let max_yt = max_abs(y0, y1, y2);
            let delta_z = F8::splat(gamma(3)).mul(max_zt);
            let delta_x = F8::splat(gamma(5)).mul(max_xt.add(max_zt));
            let delta_y = F8::splat(gamma(5)).mul(max_yt.add(max_zt));
            let delta_e = F8::splat(2.0).mul(
                F8::splat(gamma(2))
                    .mul(max_xt)
                    .mul(max_yt)
                    .add(delta_y.mul(max_xt))
                    .add(delta_x.mul(max_yt)),
            );
            let max_e = max_abs(e0, e1, e2);
            let delta_t = F8::splat(3.0)
                .mul(
                    F8::splat(gamma(3))
                        .mul(max_e)
                        .mul(max_zt)
                        .add(delta_e.mul(max_zt))
                        .add(delta_z.mul(max_e)),
                )
                .div(det.abs());
            let valid = inside.and(t.gt(ray.t_min)).and(t.le(t_max)).and(t.gt(delta_t));
            (valid.bits(), t, edges)
        }
    }

    /// The lanes a block uses: its numbers up to the first unused one.
    #[inline]
    fn lanes_used(ids: &[u32; LANES]) -> u32 {
        ids.iter().take_while(|&&id| id != u32::MAX).count() as u32
    }

    /// The lane with the smallest distance among the set bits of `mask`
    /// that is at most `*t_max`, which it then becomes.
    #[inline]
    pub(crate) fn nearest_lane(mut mask: u32, t: &[f32; LANES], t_max: &mut f32) -> Option<usize> {
        let mut best = None;
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            if t[lane] <= *t_max {
                *t_max = t[lane];
                best = Some(lane);
            }
        }
        best
    }

    /// Eight spheres: centres `c[axis]` and radii in lanes, and the
    /// caller's numbers. An empty lane has a NaN radius, which no ray
    /// meets.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Sphere8 {
        c: [Lanes; 3],
        r: Lanes,
        pub(crate) ids: [u32; LANES],
    }

    impl Sphere8 {
        /// Up to eight spheres with the caller's numbers.
        pub(crate) fn new(members: &[(Sphere, u32)]) -> Sphere8 {
            assert!(members.len() <= LANES, "a block holds at most eight spheres");
            let mut block = Sphere8 {
                c: [Lanes([0.0; LANES]); 3],
                r: Lanes([f32::NAN; LANES]),
                ids: [u32::MAX; LANES],
            };
            for (lane, (s, id)) in members.iter().enumerate() {
                for axis in 0..3 {
                    block.c[axis].0[lane] = s.center[axis];
                }
                block.r.0[lane] = s.radius;
                block.ids[lane] = *id;
            }
            block
        }

        /// The lanes' distances and a bit per lane the ray meets within
        /// its interval: [`Sphere::intersect`] on eight lanes.
        #[inline]
        #[target_feature(enable = "avx")]
        fn intersect(&self, ray: &SphereRay<f32>) -> ([f32; LANES], u32) {
            let lanes = ray.splat(F8::splat(0.0));
            let [cx, cy, cz] = load3(&self.c);
            let (t, hit) = sphere_distance(&lanes, cx, cy, cz, F8::load(&self.r));
            (t.to_array(), hit.bits())
        }
    }

    /// Up to eight rays in lanes, tested together against one primitive
    /// at a time (a packet: the lanes of the path tracer, whose rays a tree
    /// of one leaf sends through the same primitives). Each lane's
    /// nearest distance so far is kept by the caller (`t_max`), so that
    /// the lane's ray can also be tested by itself. A lane computes the
    /// bits the one-ray test of the same primitive computes, so a packet
    /// finds what the rays find one by one. A lane without a ray has a
    /// NaN interval, which no test accepts.
    pub(crate) struct RayPacket {
        /// The rays as the sphere test takes them; its `t_max` is set
        /// before each test, and its `t_min` is NaN also where |d|² is 0
        /// (such a ray meets no sphere).
        sphere: SphereRay<F8>,
        /// The intervals' starts, NaN in lanes without a ray.
        t_min: F8,
    }

    /// Rays in a [`RayPacket`].
    pub(crate) const PACKET: usize = LANES;

    /// Lanes of a packet that a primitive becomes the nearest hit of, and
    /// their distances.
    pub(crate) type PacketHit = (u32, [f32; LANES]);

    impl RayPacket {
        /// The rays of `rays` whose bits are set in `live`.
        #[inline]
        #[target_feature(enable = "avx")]
        pub(crate) fn new(rays: &[Ray; LANES], live: u32) -> RayPacket {
            let mut o = [[0.0f32; LANES]; 3];
            let mut d = [[0.0f32; LANES]; 3];
            let mut t_min = [f32::NAN; LANES];
            for i in crate::geometry::simd::lanes(live) {
                let (origin, dir, start) = rays[i].read_by_field();
                for axis in 0..3 {
                    o[axis][i] = origin[axis];
                    d[axis][i] = dir[axis];
                }
                t_min[i] = start;
            }
            let [dx, dy, dz] = [F8::from_array(d[0]), F8::from_array(d[1]), F8::from_array(d[2])];
            // What `SphereRay::new` makes of each lane's ray, in the same
            // order of operations: |d|² and its reciprocal, and no
            // interval where |d|² is 0 (also in lanes without a ray).
            let a = dx * dx + dy * dy + dz * dz;
            let zero = a.eq(F8::splat(0.0));
            let one = F8::splat(1.0);
            let t_min = F8::from_array(t_min);
            RayPacket {
                sphere: SphereRay {
                    o: [F8::from_array(o[0]), F8::from_array(o[1]), F8::from_array(o[2])],
                    d: [dx, dy, dz],
                    a: F8::select(zero, one, a),
                    inv_a: F8::select(zero, one, one / a),
                    t_min: F8::select(zero, F8::splat(f32::NAN), t_min),
                    t_max: F8::splat(f32::NAN),
                },
                t_min,
            }
        }

        /// The sphere of centre `c` and radius `r` against every lane, as
        /// `Sphere::intersect` against each ray with its interval so far
        /// (`t_max`, which the lanes it becomes the nearest hit of take).
        #[inline]
        #[target_feature(enable = "avx")]
        pub(crate) fn sphere(&mut self, c: [f32; 3], r: f32, t_max: &mut [f32; LANES]) -> PacketHit {
            let before = F8::from_array(*t_max);
            self.sphere.t_max = before;
            let (t, hit) = sphere_distance(
                &self.sphere,
                F8::splat(c[0]),
                F8::splat(c[1]),
                F8::splat(c[2]),
                F8::splat(r),
            );
            F8::select(hit, t, before).store_unaligned(t_max);
            (hit.bits(), t.to_array())
        }

        /// The spheres of `block` against every lane, `found(lanes, t, id)`
        /// told of each sphere that becomes the nearest hit of some lanes:
        /// what [`Blocks::spheres`] finds for each ray (within a block
        /// the first of equally near spheres, as there).
        #[inline]
        #[target_feature(enable = "avx")]
        fn sphere_block(
            &mut self,
            block: &Sphere8,
            t_max: &mut [f32; LANES],
            found: &mut impl FnMut(u32, &[f32; LANES], u32),
        ) {
            // Every lane of the block is tested against the interval the
            // block began with.
            let mut nearest = F8::from_array(*t_max);
            self.sphere.t_max = nearest;
            // Lanes no sphere of the block has been taken by yet.
            let mut fresh = F8::splat(0.0).eq(F8::splat(0.0));
            for (k, &id) in block.ids.iter().enumerate() {
                if id == u32::MAX {
                    break;
                }
                let [cx, cy, cz] = std::array::from_fn(|axis| F8::splat(block.c[axis].0[k]));
                let (t, hit) = sphere_distance(&self.sphere, cx, cy, cz, F8::splat(block.r.0[k]));
                let take = hit.and(t.lt(nearest).or(fresh));
                let bits = take.bits();
                if bits != 0 {
                    nearest = F8::select(take, t, nearest);
                    fresh = fresh.and_not(take);
                    found(bits, &t.to_array(), id);
                }
            }
            nearest.store_unaligned(t_max);
        }

        /// The rectangles of `block` against every lane, `found` told as in
        /// [`RayPacket::sphere_block`]: what [`Blocks::rectangles`] finds
        /// for each ray (the last of equally near rectangles, as there).
        #[inline]
        #[target_feature(enable = "avx")]
        fn rectangle_block(
            &mut self,
            block: &Rectangle8,
            t_max: &mut [f32; LANES],
            found: &mut impl FnMut(u32, &[f32; LANES], u32),
        ) {
            let mut nearest = F8::from_array(*t_max);
            for (k, &id) in block.ids.iter().enumerate() {
                if id == u32::MAX {
                    break;
                }
                let splat = |j: usize| -> [F8; 3] { std::array::from_fn(|axis| F8::splat(block.v[j][axis].0[k])) };
                let frame = [splat(0), splat(1), splat(2), splat(3)];
                let (valid, t) = rectangle_lanes(
                    frame,
                    self.sphere.o,
                    self.sphere.d,
                    self.t_min,
                    nearest.min(F8::splat(f32::MAX)),
                );
                let bits = valid.bits();
                if bits != 0 {
                    nearest = F8::select(valid, t, nearest);
                    found(bits, &t.to_array(), id);
                }
            }
            nearest.store_unaligned(t_max);
        }
    }

    /// The blocks of one scene's tree, by kind. Built only where the
    /// processor has AVX, which every test then relies on.
    #[derive(Clone, Debug)]
    pub(crate) struct Blocks {
        spheres: Vec<Sphere8>,
        rectangles: Vec<Rectangle8>,
        triangles: Vec<Triangle8>,
    }

    /// The nearest (or, for shadow rays, some) primitive of a block that a
    /// ray meets: its number, distance and (triangles) barycentrics.
    pub(crate) type BlockHit = (u32, f32, [f32; 3]);

    /// Consecutive blocks of one kind: the first's number and how many.
    pub(crate) type BlockRange = (u32, u32);

    impl Blocks {
        /// No blocks yet; `None` where the processor lacks AVX.
        pub(crate) fn new() -> Option<Blocks> {
            avx_available().then(|| Blocks {
                spheres: Vec::new(),
                rectangles: Vec::new(),
                triangles: Vec::new(),
            })
        }

        /// Adds a block of up to eight spheres; returns its number.
        pub(crate) fn push_spheres(&mut self, members: &[(Sphere, u32)]) -> u32 {
            self.spheres.push(Sphere8::new(members));
            (self.spheres.len() - 1) as u32
        }

        /// Adds a block of up to eight rectangles; returns its number.
        pub(crate) fn push_rectangles(&mut self, members: &[(Rectangle, u32)]) -> u32 {
            assert!(members.len() <= LANES, "a block holds at most eight rectangles");
            let frames: Vec<[Vec3; 4]> = members.iter().map(|(r, _)| r.test_frame()).collect();
            let refs: Vec<&(Rectangle, u32)> = members.iter().collect();
            self.rectangles.push(Rectangle8 {
                v: pack(&frames),
                ids: pack_ids(&refs),
            });
            (self.rectangles.len() - 1) as u32
        }

        /// Adds a block of up to eight triangles; returns its number.
        pub(crate) fn push_triangles(&mut self, members: &[([Vec3; 3], u32)]) -> u32 {
            assert!(members.len() <= LANES, "a block holds at most eight triangles");
            let vertices: Vec<[Vec3; 3]> = members.iter().map(|(t, _)| *t).collect();
            let refs: Vec<&([Vec3; 3], u32)> = members.iter().collect();
            self.triangles.push(Triangle8 {
                v: pack(&vertices),
                ids: pack_ids(&refs),
            });
            (self.triangles.len() - 1) as u32
        }

        /// Number of blocks.
        pub(crate) fn len(&self) -> usize {
            self.spheres.len() + self.rectangles.len() + self.triangles.len()
        }

        /// Bytes held by the blocks.
        pub(crate) fn memory_bytes(&self) -> usize {
            self.spheres.len() * std::mem::size_of::<Sphere8>()
                + self.rectangles.len() * std::mem::size_of::<Rectangle8>()
                + self.triangles.len() * std::mem::size_of::<Triangle8>()
        }

        /// The `count` sphere blocks from `first` against `ray`, in order
        /// (each bounding the next by its nearest hit, as a traversal does):
        /// with `any_hit` the first lane hit, else the nearest.
        #[inline]
        #[allow(unsafe_code)]
        pub(crate) fn spheres(&self, (first, count): BlockRange, ray: &Ray, any_hit: bool) -> Option<BlockHit> {
            let mut one = SphereRay::new(ray)?;
            let mut found = None;
            for b in &self.spheres[first as usize..(first + count) as usize] {
                // SAFETY: blocks exist only where the processor has AVX.
                let (t, mut mask) = unsafe { b.intersect(&one) };
                let mut best: Option<(usize, f32)> = None;
                while mask != 0 {
                    let lane = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    if best.is_none_or(|(_, t_best)| t[lane] < t_best) {
                        best = Some((lane, t[lane]));
                        if any_hit {
                            break;
                        }
                    }
                }
                if let Some((lane, t)) = best {
                    found = Some((b.ids[lane], t, [0.0; 3]));
                    if any_hit {
                        break;
                    }
                    one.t_max = t;
                }
            }
            found
        }

        /// Primitives in sphere block `b` (the lanes it uses).
        #[inline]
        pub(crate) fn sphere_count(&self, b: u32) -> u32 {
            lanes_used(&self.spheres[b as usize].ids)
        }

        /// Primitives in rectangle block `b`.
        #[inline]
        pub(crate) fn rectangle_count(&self, b: u32) -> u32 {
            lanes_used(&self.rectangles[b as usize].ids)
        }

        /// Sphere block `b` against the rays of `packet`, `found(lanes, t,
        /// id)` told of each sphere that becomes the nearest hit of some
        /// lanes.
        #[inline]
        #[allow(unsafe_code)]
        pub(crate) fn spheres_packet(
            &self,
            b: u32,
            packet: &mut RayPacket,
            t_max: &mut [f32; LANES],
            mut found: impl FnMut(u32, &[f32; LANES], u32),
        ) {
            // SAFETY: blocks exist only where the processor has AVX.
            unsafe { packet.sphere_block(&self.spheres[b as usize], t_max, &mut found) };
        }

        /// Rectangle block `b` against the rays of `packet`, `found` told
        /// as in [`Blocks::spheres_packet`].
        #[inline]
        #[allow(unsafe_code)]
        pub(crate) fn rectangles_packet(
            &self,
            b: u32,
            packet: &mut RayPacket,
            t_max: &mut [f32; LANES],
            mut found: impl FnMut(u32, &[f32; LANES], u32),
        ) {
            // SAFETY: blocks exist only where the processor has AVX.
            unsafe { packet.rectangle_block(&self.rectangles[b as usize], t_max, &mut found) };
        }

        /// The `count` rectangle blocks from `first` against `ray`: with
        /// `any_hit` some lane hit, else the nearest.
        #[inline]
        #[allow(unsafe_code)]
        pub(crate) fn rectangles(&self, (first, count): BlockRange, ray: &Ray, any_hit: bool) -> Option<BlockHit> {
            let blocks = &self.rectangles[first as usize..(first + count) as usize];
            // SAFETY: blocks exist only where the processor has AVX.
            unsafe { Rectangle8::nearest(blocks, ray, any_hit) }
        }

        /// The `count` triangle blocks from `first` against `ray`, whose
        /// set-up for the triangle test is `pre`: with `any_hit` some lane
        /// hit, else the nearest.
        #[inline]
        #[allow(unsafe_code)]
        pub(crate) fn triangles(
            &self,
            (first, count): BlockRange,
            ray: &Ray,
            pre: &TriangleRay,
            any_hit: bool,
        ) -> Option<BlockHit> {
            let blocks = &self.triangles[first as usize..(first + count) as usize];
            // SAFETY: blocks exist only where the processor has AVX.
            unsafe { Triangle8::nearest(blocks, ray, pre, any_hit) }
        }
    }

    impl Rectangle8 {
        /// The nearest lane of `blocks` that `ray` meets within its
        /// interval (with `any_hit`, the first block's nearest), with its
        /// number and distance. The ray's lanes are made once.
        #[inline]
        #[target_feature(enable = "avx")]
        fn nearest(blocks: &[Rectangle8], ray: &Ray, any_hit: bool) -> Option<BlockHit> {
            let mut t_max = ray.t_max;
            let mut found = None;
            for b in blocks {
                let (mask, t) = b.intersect(ray, t_max);
                if let Some(lane) = nearest_lane(mask, &t.to_array(), &mut t_max) {
                    found = Some((b.ids[lane], t_max, [0.0; 3]));
                    if any_hit {
                        break;
                    }
                }
            }
            found
        }
    }

    impl Triangle8 {
        /// The nearest lane of `blocks` that `ray` meets within its
        /// interval (with `any_hit`, the first block's nearest), with its
        /// number, distance and barycentrics.
        #[inline]
        #[target_feature(enable = "avx")]
        fn nearest(blocks: &[Triangle8], ray: &Ray, pre: &TriangleRay, any_hit: bool) -> Option<BlockHit> {
            let lanes = RayLanes::new(ray, pre);
            let mut t_max = ray.t_max;
            let mut found = None;
            for b in blocks {
                let (mask, t, edges) = b.intersect(&lanes, F8::splat(t_max));
                if let Some(lane) = nearest_lane(mask, &t.to_array(), &mut t_max) {
                    found = Some((b.ids[lane], t_max, edges.barycentrics(lane)));
                    if any_hit {
                        break;
                    }
                }
            }
            found
        }
    }
}

/// Where the processor is not x86-64 there are no blocks: the lane code is
/// written for AVX, and the tree holds every primitive by itself.
#[cfg(not(target_arch = "x86_64"))]
mod portable {
    use crate::geometry::triangle::TriangleRay;
    use crate::geometry::{Ray, Rectangle, Sphere};
    use glam::Vec3;

    /// Never built here.
    #[derive(Clone, Debug)]
    pub(crate) struct Blocks(std::convert::Infallible);

    /// See the x86-64 definition.
    pub(crate) type BlockHit = (u32, f32, [f32; 3]);

    /// See the x86-64 definition.
    pub(crate) type BlockRange = (u32, u32);

    impl Blocks {
        pub(crate) fn new() -> Option<Blocks> {
            None
        }
        pub(crate) fn push_spheres(&mut self, _: &[(Sphere, u32)]) -> u32 {
            match self.0 {}
        }
        pub(crate) fn push_rectangles(&mut self, _: &[(Rectangle, u32)]) -> u32 {
            match self.0 {}
        }
        pub(crate) fn push_triangles(&mut self, _: &[([Vec3; 3], u32)]) -> u32 {
            match self.0 {}
        }
        pub(crate) fn len(&self) -> usize {
            match self.0 {}
        }
        pub(crate) fn memory_bytes(&self) -> usize {
            match self.0 {}
        }
        pub(crate) fn spheres(&self, _: BlockRange, _: &Ray, _: bool) -> Option<BlockHit> {
            match self.0 {}
        }
        pub(crate) fn rectangles(&self, _: BlockRange, _: &Ray, _: bool) -> Option<BlockHit> {
            match self.0 {}
        }
        pub(crate) fn triangles(&self, _: BlockRange, _: &Ray, _: &TriangleRay, _: bool) -> Option<BlockHit> {
            match self.0 {}
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
pub(crate) use portable::*;
