//! Whole-pipeline tests through the library: closed-form shading,
//! refraction, BVH against brute force, determinism, robustness to scale.

use trazo::accel::aggregate::{Aggregate, MeshInstance, MeshObject, ShapeInstance};
use trazo::geometry::shape::{Cuboid, Disk, Rectangle, Shape, Sphere};
use trazo::geometry::{Ray, Transform, TriangleMesh};
use trazo::material::optics::{fresnel_dielectric, refract};
use trazo::render::{RenderOptions, render};
use trazo::sampling::{Pcg32, SamplerKind};
use trazo::scene::builtin::cornell_box;
use trazo::scene::desc::*;
use trazo::settings::IntegratorKind;
use trazo::{Rgb, Vec3};

fn point_light(position: Vec3, intensity: f32) -> LightDesc {
    LightDesc {
        kind: LightKind::Point {
            position,
            intensity: Rgb::splat(intensity),
            falloff: true,
        },
        locs: Locs::default(),
    }
}

fn render_desc(desc: &SceneDesc, threads: Option<usize>) -> trazo::film::Film {
    let scene = trazo::scene::build(desc).unwrap();
    render(
        &scene,
        &RenderOptions {
            threads,
            ..RenderOptions::default()
        },
    )
    .unwrap()
    .film
}

/// One sphere under one point light, seen through pixel centres: each
/// pixel must equal the Phong formula evaluated by hand.
#[test]
fn phong_shading_matches_the_formula_at_known_pixels() {
    let (kd, ks, s) = (Rgb::new(0.8, 0.5, 0.2), 0.3f32, 20.0f32);
    let light_pos = Vec3::new(0.5, 0.5, 4.0);
    let intensity = 10.0;
    let ambient = Rgb::splat(0.05);
    let mut d = SceneDesc::default();
    d.settings.width = 65;
    d.settings.height = 65;
    d.settings.spp = 1;
    d.settings.sampler = SamplerKind::Center;
    d.settings.integrator = IntegratorKind::Whitted;
    d.camera.from = Vec3::new(0.0, 0.0, 5.0);
    d.camera.projection = ProjectionDesc::Perspective { fov: 30.0 };
    d.ambient = ambient;
    d.materials.push(MaterialDesc::classic(
        "phong",
        ClassicDesc {
            diffuse: ColorSource::Rgb(kd),
            specular: ColorSource::Rgb(Rgb::splat(ks)),
            shininess: s,
            ..ClassicDesc::default()
        },
    ));
    d.lights.push(point_light(light_pos, intensity));
    d.shapes.push(ShapeDesc::new(
        ShapeKind::Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        },
        Some("phong"),
    ));
    let scene = trazo::scene::build(&d).unwrap();
    let image = trazo::render::render_image(&scene).unwrap();

    for (px, py) in [(32u32, 32u32), (40, 28), (25, 37), (32, 20)] {
        let ray = scene
            .camera
            .generate_ray(trazo::Vec2::new(px as f32 + 0.5, py as f32 + 0.5), trazo::Vec2::ZERO);
        // Ray–unit sphere by the textbook quadratic, in f64.
        let (o, dir) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
        let b = o.dot(dir);
        let c = o.length_squared() - 1.0;
        let t = -b - (b * b - c).sqrt();
        let p = (o + dir * t).as_vec3();
        let n = p.normalize();
        let v = -ray.dir;
        let to_light = light_pos - p;
        let l = to_light.normalize();
        let r = 2.0 * n.dot(l) * n - l;
        let e = intensity / to_light.length_squared() * n.dot(l).max(0.0);
        let brdf = kd / std::f32::consts::PI
            + Rgb::splat(ks * (s + 2.0) / (2.0 * std::f32::consts::PI) * r.dot(v).max(0.0).powf(s));
        let expect = brdf * e + ambient * kd;
        let got = image.get(px, py);
        assert!(
            (got - expect).abs().max_element() < 1e-4 * expect.max_element().max(1.0),
            "pixel ({px},{py}): got {got}, expected {expect}"
        );
    }
    // A pixel that misses the sphere shows the black background.
    assert_eq!(image.get(0, 0), Rgb::ZERO);
}

fn lit_floor_scene(blocker: Option<MaterialDesc>) -> SceneDesc {
    let mut d = SceneDesc::default();
    d.settings.width = 9;
    d.settings.height = 9;
    d.settings.spp = 1;
    d.settings.sampler = SamplerKind::Center;
    d.settings.integrator = IntegratorKind::Whitted;
    d.camera = CameraDesc {
        projection: ProjectionDesc::Orthographic { size: 0.5 },
        from: Vec3::new(0.0, 5.0, 0.0),
        to: Vec3::ZERO,
        up: Vec3::Z,
        ..CameraDesc::default()
    };
    d.materials.push(MaterialDesc::new("floor"));
    d.lights.push(point_light(Vec3::new(0.0, 4.0, 0.0), 16.0));
    d.shapes.push(ShapeDesc::new(
        ShapeKind::Rectangle {
            corner: Vec3::new(-1.0, 0.0, 1.0),
            edge_u: Vec3::new(2.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, -2.0),
        },
        Some("floor"),
    ));
    if let Some(m) = blocker {
        let name = m.name.clone();
        d.materials.push(m);
        // A thin horizontal slab between the light and the floor, wider
        // than what the camera sees of the floor... but not in the camera's
        // way: the camera looks down from above it, so place the camera
        // below the slab.
        d.camera.from = Vec3::new(0.0, 1.0, 0.0);
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Cuboid {
                min: Vec3::new(-3.0, 2.0, -3.0),
                max: Vec3::new(3.0, 2.2, 3.0),
            },
            Some(&name),
        ));
    }
    d
}

/// Shadow rays: an opaque slab blocks the light; a glass slab lets
/// `kt·(1 − F)` through at each of its two faces (F = 0.04 at normal
/// incidence for η = 1.5), as documented for the Whitted integrator.
#[test]
fn shadow_rays_through_opaque_and_transparent_occluders() {
    let centre = |d: &SceneDesc| {
        trazo::render::render_image(&trazo::scene::build(d).unwrap())
            .unwrap()
            .get(4, 4)
    };
    let lit = centre(&lit_floor_scene(None));
    // Diffuse 0.5, E = 16/4² → L = 0.5/π.
    assert!((lit.x - 0.5 / std::f32::consts::PI).abs() < 1e-5, "{lit}");
    assert_eq!(centre(&lit_floor_scene(Some(MaterialDesc::new("wall")))), Rgb::ZERO);
    let glass = MaterialDesc::classic(
        "glass",
        ClassicDesc {
            diffuse: ColorSource::Rgb(Rgb::ZERO),
            transmission: Rgb::new(1.0, 0.5, 0.25),
            ior: 1.5,
            ..ClassicDesc::default()
        },
    );
    let through = centre(&lit_floor_scene(Some(glass)));
    let f = fresnel_dielectric(1.0, 1.5);
    let expect = lit * Rgb::new(1.0, 0.25, 0.0625) * (1.0 - f) * (1.0 - f);
    assert!((through - expect).abs().max_element() < 1e-5, "{through} vs {expect}");
}

/// A ray through a glass slab leaves parallel to how it entered, shifted
/// sideways by t·sin(θᵢ − θₜ)/cos θₜ (Snell's law at both faces).
#[test]
fn refraction_through_a_slab_follows_snell() {
    let eta = 1.5f32;
    let thickness = 0.5f32;
    let g = Aggregate::build(
        vec![],
        vec![ShapeInstance {
            shape: Shape::Cuboid(Cuboid {
                min: Vec3::new(-10.0, -thickness, -10.0),
                max: Vec3::new(10.0, 0.0, 10.0),
            }),
            motion: None,
            transform: None,
            material: 0,
            light: None,
            flip_normals: false,
        }],
        vec![],
        vec![],
    );
    for deg in [0.0f32, 20.0, 45.0, 70.0] {
        let th = deg.to_radians();
        let d_in = Vec3::new(th.sin(), -th.cos(), 0.0);
        let r = Ray::new(Vec3::new(0.0, 1.0, 0.0), d_in);
        let h1 = g.surface(&r, &g.intersect(&r).unwrap());
        let (t1, _) = refract(-d_in, h1.ns, eta).unwrap();
        let inside = h1.spawn_ray(t1);
        let h2 = g.surface(&inside, &g.intersect(&inside).unwrap());
        assert!((h2.p.y + thickness).abs() < 1e-5);
        let (out, _) = refract(-t1, h2.ns, eta).unwrap();
        assert!((out - d_in).length() < 1e-5, "{deg}°: exit {out} vs entry {d_in}");
        let th_t = (th.sin() / eta).asin();
        let shift = thickness * (th - th_t).sin() / th_t.cos();
        // Distance between the exit ray and the undeviated line.
        let undeviated = h1.p + d_in * (thickness / th.cos());
        let offset = (h2.p - undeviated) - d_in * (h2.p - undeviated).dot(d_in);
        assert!(
            (offset.length() - shift).abs() < 1e-4,
            "{deg}°: {} vs {shift}",
            offset.length()
        );
    }
}

/// Light entering a 45° glass prism square to one face meets the
/// hypotenuse at 45°, beyond the critical angle asin(1/1.5) ≈ 41.8°: it is
/// totally reflected and leaves through the other face turned by 90°.
#[test]
fn total_internal_reflection_in_a_prism() {
    // Right prism: legs along +x and +y, hypotenuse from (1,0) to (0,1), extruded in z.
    let tri = |a: Vec3, b: Vec3, c: Vec3| [a, b, c];
    let (p0, p1, p2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
    let z0 = Vec3::new(0.0, 0.0, -1.0);
    let z1 = Vec3::new(0.0, 0.0, 1.0);
    let faces = vec![
        tri(p0 + z0, p2 + z0, p1 + z0),
        tri(p0 + z1, p1 + z1, p2 + z1),
        // bottom leg (y = 0), facing −y
        tri(p0 + z0, p1 + z0, p1 + z1),
        tri(p0 + z0, p1 + z1, p0 + z1),
        // left leg (x = 0), facing −x
        tri(p0 + z0, p0 + z1, p2 + z1),
        tri(p0 + z0, p2 + z1, p2 + z0),
        // hypotenuse, facing (1, 1)
        tri(p1 + z0, p2 + z0, p2 + z1),
        tri(p1 + z0, p2 + z1, p1 + z1),
    ];
    let mut mesh = TriangleMesh::default();
    for f in faces {
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(f);
        mesh.indices.push([base, base + 1, base + 2]);
    }
    let g = Aggregate::build(
        vec![mesh],
        vec![],
        vec![MeshObject {
            mesh: 0,
            material: 0,
            light: None,
        }],
        vec![],
    );
    let eta = 1.5;
    // Enter the bottom face going up.
    let mut ray = Ray::new(Vec3::new(0.3, -1.0, 0.0), Vec3::Y);
    let h = g.surface(&ray, &g.intersect(&ray).unwrap());
    assert!(h.ng.dot(-Vec3::Y) > 0.99);
    let (d, _) = refract(-ray.dir, h.ng, eta).unwrap();
    assert!((d - Vec3::Y).length() < 1e-6, "normal incidence does not bend");
    ray = h.spawn_ray(d);
    let h = g.surface(&ray, &g.intersect(&ray).unwrap());
    let cos_i = h.ng.dot(-ray.dir);
    assert!(refract(-ray.dir, h.ng, eta).is_none(), "must be totally reflected");
    assert_eq!(fresnel_dielectric(cos_i, eta), 1.0);
    let reflected = trazo::material::optics::reflect(-ray.dir, -h.ng);
    assert!((reflected - -Vec3::X).length() < 1e-5, "{reflected}");
    ray = h.spawn_ray(reflected);
    let h = g.surface(&ray, &g.intersect(&ray).unwrap());
    let (out, _) = refract(-ray.dir, h.ng, eta).unwrap();
    assert!((out - -Vec3::X).length() < 1e-5);
    // Reflected at (0.3, 0.7), it leaves the left face at height 0.7.
    assert!((h.p.x).abs() < 1e-5 && (h.p.y - 0.7).abs() < 1e-5, "{}", h.p);
}

/// Whitted's furnace: with kt = 1 every ray split by Fresnel ends in the
/// background, so a glass sphere in a uniform background is invisible up
/// to the energy cut off at the depth limit.
#[test]
fn glass_sphere_in_a_uniform_background_disappears() {
    let mut d = SceneDesc::default();
    d.settings.width = 16;
    d.settings.height = 16;
    d.settings.spp = 1;
    d.settings.max_depth = 24;
    d.settings.integrator = IntegratorKind::Whitted;
    d.background = BackgroundDesc::Constant(Rgb::splat(0.7));
    d.materials.push(MaterialDesc::classic(
        "glass",
        ClassicDesc {
            diffuse: ColorSource::Rgb(Rgb::ZERO),
            transmission: Rgb::ONE,
            ior: 1.5,
            ..ClassicDesc::default()
        },
    ));
    d.shapes.push(ShapeDesc::new(
        ShapeKind::Sphere {
            center: Vec3::ZERO,
            radius: 1.5,
        },
        Some("glass"),
    ));
    let img = render_desc(&d, None).to_image();
    for p in &img.pixels {
        assert!((*p - Rgb::splat(0.7)).abs().max_element() < 2e-3, "{p}");
    }
}

/// pbrt-v4's `maxcomponentvalue`: each sample is scaled so that its
/// largest component, once exposed, is at most the limit; hue is kept.
#[test]
fn the_largest_component_of_a_sample_is_limited_after_exposure() {
    let mut d = SceneDesc::default();
    d.settings.width = 4;
    d.settings.height = 4;
    d.settings.spp = 2;
    d.background = BackgroundDesc::Constant(Rgb::new(4.0, 2.0, 1.0));
    let free = render_desc(&d, None).to_image();
    assert!(
        free.pixels
            .iter()
            .all(|p| (*p - Rgb::new(4.0, 2.0, 1.0)).abs().max_element() < 1e-5)
    );
    d.settings.max_component_value = 1.0;
    d.settings.exposure = 1.0; // ×2: the film keeps at most 1/2
    let limited = render_desc(&d, None).to_image();
    for p in &limited.pixels {
        assert!((*p - Rgb::new(0.5, 0.25, 0.125)).abs().max_element() < 1e-6, "{p}");
    }
    d.settings.max_component_value = 0.0;
    let Err(e) = trazo::scene::build(&d) else {
        panic!("a zero limit is refused")
    };
    let e = e.to_string();
    assert!(e.contains("max_component_value") && e.contains("positive"), "{e}");
}

/// An output colour space: a coloured background seen directly comes out
/// as the space's matrix times its sRGB colour, after the white balance
/// (whose white becomes the space's), from TOML and from a pbrt-v4
/// `ColorSpace` before `Film`.
#[test]
fn output_colour_spaces_convert_the_finished_image() {
    use trazo::color::space::ColorSpace;
    let c = Rgb::new(0.5, 0.2, 0.1);
    for (space, kelvin) in [("rec2020", 0.0f32), ("aces2065-1", 0.0), ("dci-p3", 4000.0)] {
        let text = format!(
            "[render]\nwidth = 4\nheight = 4\nspp = 2\nwhite_balance = {kelvin}\ncolor_space = \"{space}\"\n\
             [world]\nbackground = [0.5, 0.2, 0.1]\n"
        );
        let d = trazo::scene::native::parse(&text, std::path::Path::new("cs.toml")).unwrap();
        let image = render_desc(&d, None).to_image();
        let cs = ColorSpace::from_pbrt_name(space).unwrap();
        let want = trazo::color::white_balance::output_transform(cs, kelvin).unwrap() * c;
        assert!((want - c).abs().max_element() > 0.01, "{space}: {want}");
        for p in &image.pixels {
            assert!(
                (*p - want).abs().max_element() < 1e-6,
                "{space}, {kelvin} K: {p} vs {want}"
            );
        }
    }
    let pbrt = "ColorSpace \"aces2065-1\"\nFilm \"rgb\"\nWorldBegin\n";
    let d = trazo::scene::pbrt::parse(pbrt, std::path::Path::new("cs.pbrt")).unwrap();
    assert_eq!(d.settings.color_space, ColorSpace::Aces2065_1);
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    let bad = "[render]\ncolor_space = \"p3\"\n";
    let Err(e) = trazo::scene::native::parse(bad, std::path::Path::new("cs.toml")) else {
        panic!("an unknown colour space is refused")
    };
    assert!(e.to_string().contains("color_space"), "{e}");
}

/// pbrt-v4's `whitebalance`: a grey background seen directly comes out as
/// the balance matrix times its colour, through TOML and the pbrt-v4
/// reader; a temperature outside the range is refused.
#[test]
fn white_balance_applies_the_balance_matrix_to_the_image() {
    let grey = Rgb::new(0.5, 0.5, 0.5);
    for kelvin in [3000.0f32, 6504.0, 12000.0] {
        let text =
            format!("[render]\nwidth = 4\nheight = 4\nspp = 2\nwhite_balance = {kelvin}\n[world]\nbackground = 0.5\n");
        let d = trazo::scene::native::parse(&text, std::path::Path::new("wb.toml")).unwrap();
        let image = render_desc(&d, None).to_image();
        let want = trazo::color::white_balance::white_balance(kelvin).unwrap() * grey;
        for p in &image.pixels {
            assert!((*p - want).abs().max_element() < 1e-6, "{kelvin} K: {p} vs {want}");
        }
        if kelvin == 3000.0 {
            assert!(
                want.z > 1.5 * want.x,
                "a warm illuminant's balance turns grey blue: {want}"
            );
        }
    }
    let pbrt = "Film \"rgb\" \"float whitebalance\" 5000\nWorldBegin\n";
    let d = trazo::scene::pbrt::parse(pbrt, std::path::Path::new("wb.pbrt")).unwrap();
    assert_eq!(d.settings.white_balance, 5000.0);
    assert!(
        !d.warnings.iter().any(|w| w.contains("whitebalance")),
        "{:?}",
        d.warnings
    );
    let bad = "Film \"rgb\" \"float whitebalance\" -10\nWorldBegin\n";
    let Err(e) = trazo::scene::pbrt::parse(bad, std::path::Path::new("wb.pbrt")) else {
        panic!("a negative temperature is refused")
    };
    let e = e.to_string();
    assert!(
        e.contains("wb.pbrt:1:12") && e.contains("white_balance") && e.contains("1000 to 25000 K"),
        "{e}"
    );
}

fn random_aggregate(seed: u64) -> Aggregate {
    let mut r = Pcg32::new(seed, 0);
    let mut v = || r.next_f32();
    let mut shapes = Vec::new();
    for i in 0..60 {
        let c = Vec3::new(v(), v(), v()) * 20.0 - 10.0;
        let shape = match i % 4 {
            0 => Shape::Sphere(Sphere::new(c, 0.2 + v())),
            1 => Shape::Cuboid(Cuboid {
                min: c,
                max: c + Vec3::new(v(), v(), v()) + 0.1,
            }),
            2 => Shape::Rectangle(Rectangle::new(
                c,
                Vec3::new(v(), v(), v()) * 2.0 - 1.0,
                Vec3::new(v(), v(), v()) * 2.0 - 1.0,
            )),
            _ => Shape::Disk(Disk {
                center: c,
                normal: (Vec3::new(v(), v(), v()) - 0.5).normalize(),
                radius: 0.3 + v(),
                uv: trazo::geometry::DiskUv::AngleRadius,
            }),
        };
        let transform = if i % 3 == 0 {
            Some(
                Transform::scale(Vec3::new(0.5 + v(), 0.5 + v(), 0.5 + v()))
                    .unwrap()
                    .then(&Transform::shear(v() - 0.5, 0.0, 0.0, v() - 0.5, 0.0, 0.0).unwrap())
                    .then(&Transform::rotate(Vec3::new(v(), v(), v()) + 0.1, v() * 360.0).unwrap()),
            )
        } else {
            None
        };
        shapes.push(ShapeInstance {
            shape,
            motion: None,
            transform,
            material: 0,
            light: None,
            flip_normals: false,
        });
    }
    let soup = |n: usize, v: &mut dyn FnMut() -> f32| {
        let mut m = TriangleMesh::default();
        for t in 0..n {
            let c = Vec3::new(v(), v(), v()) * 16.0 - 8.0;
            for _ in 0..3 {
                m.positions.push(c + Vec3::new(v(), v(), v()) * 2.0 - 1.0);
            }
            m.indices.push([3 * t as u32, 3 * t as u32 + 1, 3 * t as u32 + 2]);
        }
        m
    };
    // A large world-space mesh (traced through its own tree of triangle
    // blocks), a small one (single triangles in the top-level tree), and a
    // small and a large instanced one (the same two kinds of tree).
    let world = soup(300, &mut v);
    let shared = soup(40, &mut v);
    let small_world = soup(30, &mut v);
    let large_shared = soup(260, &mut v);
    let instances = (0..8)
        .map(|k| MeshInstance {
            mesh: if k < 5 { 1 } else { 3 },
            motion: None,
            transform: Transform::rotate(Vec3::new(v(), v(), v()) + 0.1, v() * 360.0)
                .unwrap()
                .then(&Transform::translate(Vec3::new(v(), v(), v()) * 10.0 - 5.0)),
            material: 0,
            light: None,
            flip_normals: false,
        })
        .collect();
    Aggregate::build(
        vec![world, shared, small_world, large_shared],
        shapes,
        vec![
            MeshObject {
                mesh: 0,
                material: 0,
                light: None,
            },
            MeshObject {
                mesh: 2,
                material: 0,
                light: None,
            },
        ],
        instances,
    )
}

/// Nearest hit by testing every primitive, using only public data.
fn brute_force_t(g: &Aggregate, ray: &Ray) -> Option<f32> {
    let mut best: Option<f32> = None;
    let mut r = *ray;
    let mut take = |t: f32, r: &mut Ray| {
        r.t_max = t;
        best = Some(t);
    };
    for s in &g.shapes {
        let local = s.transform.map_or(r, |t| t.inv_ray(&r));
        if let Some(t) = s.shape.intersect(&local) {
            take(t, &mut r);
        }
    }
    for o in &g.mesh_objects {
        let m = &g.meshes[o.mesh as usize];
        for i in 0..m.len() {
            if let Some(h) = m.intersect(i, &r) {
                take(h.t, &mut r);
            }
        }
    }
    for inst in &g.instances {
        let m = &g.meshes[inst.mesh as usize];
        for i in 0..m.len() {
            if let Some(h) = m.intersect(i, &inst.transform.inv_ray(&r)) {
                take(h.t, &mut r);
            }
        }
    }
    best
}

#[test]
fn bvh_agrees_with_brute_force_on_random_scenes() {
    for seed in 1..4 {
        let g = random_aggregate(seed);
        let mut r = Pcg32::new(seed * 77, 1);
        let mut hits = 0;
        for _ in 0..3000 {
            let o = Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 30.0 - 15.0;
            let d = Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 2.0 - 1.0;
            let ray = Ray::new(o, d);
            let expect = brute_force_t(&g, &ray);
            let got = g.intersect(&ray).map(|h| h.t);
            // Large meshes are traced four triangles at a time, whose edge
            // functions round differently from the one-triangle test's
            // (without fused multiply-adds): t may differ in the last bits.
            match (got, expect) {
                (Some(a), Some(b)) => assert!((a - b).abs() <= 4.0 * f32::EPSILON * b, "ray {ray:?}: {a} vs {b}"),
                _ => assert_eq!(got, expect, "ray {ray:?}"),
            }
            // The surface found (barycentrics included) is where the ray is.
            if let Some(h) = g.intersect(&ray) {
                let p = g.surface(&ray, &h).p;
                let at = ray.origin + ray.dir * h.t;
                assert!(
                    (p - at).length() <= 1e-4 * (1.0 + at.length()),
                    "ray {ray:?}: {p} vs {at}"
                );
            }
            assert_eq!(g.occluded(&ray), expect.is_some());
            hits += expect.is_some() as u32;
        }
        assert!(hits > 200, "the test must exercise hits ({hits})");
    }
}

/// A room-sized scene: ten rectangles (some transformed, which are baked
/// into world space) and two small meshes of `triangles`, few enough to be
/// single triangles in the top-level tree's blocks where the processor
/// allows.
fn small_planar_aggregate(seed: u64, triangles: [usize; 2]) -> Aggregate {
    let mut r = Pcg32::new(seed, 3);
    let mut v = || r.next_f32();
    let mut shapes = Vec::new();
    for i in 0..10 {
        let c = Vec3::new(v(), v(), v()) * 4.0 - 2.0;
        let transform = (i % 3 == 0).then(|| {
            Transform::rotate(Vec3::new(v(), v(), v()) + 0.1, v() * 360.0)
                .unwrap()
                .then(&Transform::scale(Vec3::new(0.5 + v(), 0.5 + v(), 0.5 + v())).unwrap())
        });
        shapes.push(ShapeInstance {
            shape: Shape::Rectangle(Rectangle::new(
                c,
                Vec3::new(v(), v(), v()) * 2.0 - 1.0,
                Vec3::new(v(), v(), v()) * 2.0 - 1.0,
            )),
            motion: None,
            transform,
            material: 0,
            light: None,
            flip_normals: false,
        });
    }
    let mut mesh = |n: usize| {
        let mut m = TriangleMesh::default();
        let centre = Vec3::new(v(), v(), v()) * 3.0 - 1.5;
        for t in 0..n {
            for _ in 0..3 {
                m.positions.push(centre + Vec3::new(v(), v(), v()) - 0.5);
            }
            m.indices.push([3 * t as u32, 3 * t as u32 + 1, 3 * t as u32 + 2]);
        }
        m
    };
    let meshes = vec![mesh(triangles[0]), mesh(triangles[1])];
    let objects = (0..2)
        .map(|mesh| MeshObject {
            mesh,
            material: 0,
            light: None,
        })
        .collect();
    Aggregate::build(meshes, shapes, objects, Vec::new())
}

/// Small scenes of rectangles and triangles, whose tree's leaves hold them
/// in blocks of eight (on x86-64 with AVX), find what testing every
/// primitive one by one finds.
#[test]
fn small_scenes_agree_with_brute_force() {
    for (seed, triangles) in [(1, [12, 20]), (2, [12, 20]), (3, [12, 20]), (4, [48, 60])] {
        let g = small_planar_aggregate(seed, triangles);
        if cfg!(target_arch = "x86_64") && std::arch::is_x86_feature_detected!("avx") {
            assert!(g.stats().leaf_blocks > 0, "the leaves hold blocks");
        }
        let mut r = Pcg32::new(seed * 91, 5);
        let mut hits = 0;
        for i in 0..4000 {
            let o = Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 8.0 - 4.0;
            let target = Vec3::new(r.next_f32(), r.next_f32(), r.next_f32()) * 3.0 - 1.5;
            let d = target - o;
            let t_max = if i % 5 == 0 { 0.7 } else { f32::INFINITY };
            let ray = Ray::with_interval(o, d, 1e-4, t_max);
            let expect = brute_force_t(&g, &ray);
            let got = g.intersect(&ray);
            // Blocks of triangles compute their edge functions without
            // fused multiply-adds, as the mesh trees' blocks do. Their
            // rounding error is relative to the coordinates (about 1 here),
            // not to the distance, which for a ray starting near a
            // triangle is small.
            match (got.map(|h| h.t), expect) {
                (Some(a), Some(b)) => assert!(
                    (a - b).abs() <= 4.0 * f32::EPSILON * b.max(1.0),
                    "ray {ray:?}: {a} vs {b}"
                ),
                (a, b) => assert_eq!(a, b, "ray {ray:?}"),
            }
            if let Some(h) = got {
                let p = g.surface(&ray, &h).p;
                let at = ray.origin + ray.dir * h.t;
                assert!(
                    (p - at).length() <= 1e-4 * (1.0 + at.length()),
                    "ray {ray:?}: {p} vs {at}"
                );
                hits += 1;
            }
            assert_eq!(g.occluded(&ray), expect.is_some(), "ray {ray:?}");
        }
        assert!(hits > 500, "the test must exercise hits ({hits})");
        // A zero direction meets nothing.
        let still = Ray::with_interval(Vec3::new(0.1, 0.2, 0.3), Vec3::ZERO, 0.0, f32::INFINITY);
        assert!(g.intersect(&still).is_none() && !g.occluded(&still));
    }
}

/// The Cornell box's room (walls, light and two boxes' faces: eighteen
/// rectangles) is a tree of one leaf of blocks, each of which a ray tests
/// (with AVX, where a block test costs what a node visit does); thirty
/// rectangles far apart get nodes, which skip nearly all of them.
#[test]
fn a_room_is_a_tree_of_one_leaf() {
    let rectangles = |spacing: f32| {
        let shapes = (0..30)
            .map(|i| ShapeInstance {
                shape: Shape::Rectangle(Rectangle::new(
                    Vec3::new((i % 5) as f32, (i / 5) as f32, (i % 3) as f32) * spacing,
                    Vec3::new(1.0, 0.0, 0.2),
                    Vec3::new(0.0, 1.0, 0.3),
                )),
                motion: None,
                transform: None,
                material: 0,
                light: None,
                flip_normals: false,
            })
            .collect();
        Aggregate::build(Vec::new(), shapes, Vec::new(), Vec::new())
    };
    if cfg!(target_arch = "x86_64") && std::arch::is_x86_feature_detected!("avx") {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/crosscheck/scenes/cornell-box.xml");
        let room = trazo::scene::build(&trazo::scene::load(&path, &[]).unwrap()).unwrap();
        let stats = room.geometry.stats();
        assert_eq!((stats.primitives, stats.nodes, stats.leaf_blocks), (18, 0, 3));
    }
    assert!(rectangles(30.0).stats().nodes > 0);
}

#[test]
fn same_seed_gives_identical_images_for_any_thread_count() {
    let mut d = cornell_box();
    d.settings.width = 40;
    d.settings.height = 40;
    d.settings.spp = 5;
    d.settings.seed = 42;
    let one = render_desc(&d, Some(1));
    let two = render_desc(&d, Some(2));
    let three = render_desc(&d, Some(3));
    assert_eq!(one, two);
    assert_eq!(one, three);
    d.settings.seed = 43;
    assert_ne!(render_desc(&d, Some(2)), one, "another seed gives another image");
}

/// The Sobol sampler keeps the determinism of the others, and converges to
/// the same image as the stratified sampler: the per-pixel differences of
/// two independent renders are what their estimated variances explain, and
/// so is the difference of the image means (a bias would show there).
#[test]
fn sobol_renders_are_deterministic_and_agree_with_stratified() {
    let mut d = cornell_box();
    d.settings.width = 24;
    d.settings.height = 24;
    d.settings.spp = 16;
    d.settings.seed = 5;
    d.settings.sampler = SamplerKind::Sobol;
    let one = render_desc(&d, Some(1));
    assert_eq!(one, render_desc(&d, Some(2)), "same image for 1 and 2 threads");

    d.settings.spp = 256;
    let sobol = render_desc(&d, Some(2));
    d.settings.sampler = SamplerKind::Stratified;
    d.settings.seed = 6;
    let stratified = render_desc(&d, Some(2));
    let (mut chi2, mut n, mut diff_sum, mut var_sum) = (0.0, 0usize, 0.0, 0.0);
    for (a, b) in sobol.pixels.iter().zip(&stratified.pixels) {
        let (ya, yb) = (
            trazo::color::luminance(a.value()) as f64,
            trazo::color::luminance(b.value()) as f64,
        );
        let var = a.variance_of_mean() + b.variance_of_mean();
        diff_sum += ya - yb;
        var_sum += var;
        if var > 0.0 {
            chi2 += (ya - yb).powi(2) / var;
            n += 1;
        } else {
            assert!((ya - yb).abs() < 1e-5, "noiseless pixels agree: {ya} vs {yb}");
        }
    }
    // The sample variance overestimates the variance of a stratified or
    // Sobol mean, so the normalised squared difference is at most about 1
    // on average; a biased sampler would push it far above.
    assert!(n > 400, "the test must cover noisy pixels ({n})");
    let per_pixel = chi2 / n as f64;
    assert!(per_pixel < 1.5, "mean normalised squared difference {per_pixel}");
    let z = diff_sum / var_sum.sqrt();
    assert!(z.abs() < 4.0, "image means differ by {z} standard errors");
    let e = trazo::film::metrics::relative_mse(&sobol.to_image(), &stratified.to_image()).unwrap();
    assert!(e < 0.01, "relative MSE {e}");
}

/// The Cornell box scaled by 10⁻³ and 10³ renders the same image: ray
/// offsets follow the scale, so there is no self-intersection acne at
/// small scales and no light leaking at large ones.
#[test]
fn images_do_not_depend_on_scene_scale() {
    let base = {
        let mut d = cornell_box();
        d.settings.width = 48;
        d.settings.height = 48;
        d.settings.spp = 4;
        d
    };
    let reference = render_desc(&base, None).to_image();
    for scale in [1e-3f32, 1e3] {
        let mut d = base.clone();
        d.camera.from *= scale;
        d.camera.to *= scale;
        for s in &mut d.shapes {
            s.transform.push(TransformOp::Scale(Vec3::splat(scale)));
        }
        let img = render_desc(&d, None).to_image();
        let mut worst = 0.0f32;
        let mut sum = 0.0f64;
        for (a, b) in img.pixels.iter().zip(&reference.pixels) {
            let e = (*a - *b).abs().max_element();
            worst = worst.max(e);
            sum += e as f64;
        }
        let mean = sum / img.pixels.len() as f64;
        assert!(mean < 1e-3, "scale {scale}: mean difference {mean}");
        // Pixels on silhouettes may flip between objects, nowhere else.
        let flipped = img
            .pixels
            .iter()
            .zip(&reference.pixels)
            .filter(|(a, b)| (**a - **b).abs().max_element() > 0.05)
            .count();
        assert!(flipped <= 3, "scale {scale}: {flipped} pixels differ (worst {worst})");
    }
}

/// Instancing: one mesh stored once, placed many times, renders like the
/// same mesh copied into world space.
#[test]
fn instances_render_like_copies() {
    let mesh = MeshDesc {
        name: "ball".into(),
        source: MeshSource::UvSphere {
            segments: 24,
            rings: 12,
        },
        locs: Locs::default(),
    };
    let mut d = SceneDesc::default();
    d.settings.width = 48;
    d.settings.height = 32;
    d.settings.spp = 2;
    d.camera.from = Vec3::new(0.0, 0.0, 8.0);
    d.lights.push(point_light(Vec3::new(2.0, 5.0, 6.0), 60.0));
    let placements = [
        Vec3::new(-2.0, 0.0, 0.0),
        Vec3::new(0.0, 0.5, -1.0),
        Vec3::new(2.0, -0.3, 0.5),
    ];
    let mut instanced = d.clone();
    instanced.meshes.push(mesh.clone());
    let mut copies = d.clone();
    for (i, p) in placements.iter().enumerate() {
        instanced
            .shapes
            .push(ShapeDesc::new(ShapeKind::Mesh("ball".into()), None).with(TransformOp::Translate(*p)));
        let mut m = mesh.clone();
        m.name = format!("ball{i}");
        copies.meshes.push(m);
        copies
            .shapes
            .push(ShapeDesc::new(ShapeKind::Mesh(format!("ball{i}")), None).with(TransformOp::Translate(*p)));
    }
    let si = trazo::scene::build(&instanced).unwrap();
    assert_eq!(si.geometry.instances.len(), 3);
    assert_eq!(si.geometry.meshes.len(), 1, "the mesh is stored once");
    let sc = trazo::scene::build(&copies).unwrap();
    assert_eq!(sc.geometry.mesh_objects.len(), 3);
    let a = trazo::render::render_image(&si).unwrap();
    let b = trazo::render::render_image(&sc).unwrap();
    let differing = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(x, y)| (**x - **y).abs().max_element() > 1e-3)
        .count();
    assert!(differing <= 2, "{differing} pixels differ");
    assert!(a.mean().x > 0.01);
}

/// A scene of about a million triangles loads, builds and renders.
#[test]
fn a_million_triangles_render() {
    let mut d = SceneDesc::default();
    d.settings.width = 24;
    d.settings.height = 24;
    d.settings.spp = 1;
    d.lights.push(point_light(Vec3::new(0.0, 3.0, 5.0), 30.0));
    d.meshes.push(MeshDesc {
        name: "sphere".into(),
        source: MeshSource::UvSphere {
            segments: 1000,
            rings: 501,
        },
        locs: Locs::default(),
    });
    d.shapes.push(ShapeDesc::new(ShapeKind::Mesh("sphere".into()), None));
    let scene = trazo::scene::build(&d).unwrap();
    assert!(scene.geometry.stats().triangles >= 1_000_000);
    let img = trazo::render::render_image(&scene).unwrap();
    assert!(img.get(12, 12).x > 0.0 && img.get(0, 0) == Rgb::ZERO);
}

/// Robust ray offsetting (pbrt-v4 §6.8): a ray spawned from a hit point
/// away from the surface never meets that surface again, and one spawned
/// into a closed surface meets its far side, not the point it left — for
/// scenes from 10⁻⁴ to 10⁵ units across and far from the origin.
#[test]
fn spawned_rays_never_hit_the_surface_they_leave_at_any_scale() {
    use trazo::sampling::warp::sample_sphere_uniform;
    let shapes = [
        ShapeKind::Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        },
        ShapeKind::Rectangle {
            corner: Vec3::new(-1.0, -1.0, 0.0),
            edge_u: Vec3::new(2.0, 0.3, 0.1),
            edge_v: Vec3::new(0.2, 2.0, -0.4),
        },
        ShapeKind::Cuboid {
            min: Vec3::splat(-1.0),
            max: Vec3::new(1.0, 0.5, 0.8),
        },
        ShapeKind::InlineMesh(MeshSource::UvSphere {
            segments: 24,
            rings: 12,
        }),
    ];
    let mut rng = Pcg32::new(7, 1);
    let mut rand2 = || trazo::Vec2::new(rng.next_f32(), rng.next_f32());
    for kind in &shapes {
        for scale in [1e-4f32, 1.0, 1e5] {
            for offset in [0.0f32, 1e3] {
                let mut d = SceneDesc::default();
                let shift = Vec3::new(offset, -0.5 * offset, 2.0 * offset) * scale;
                d.shapes.push(
                    ShapeDesc::new(kind.clone(), None)
                        .with(TransformOp::Rotate {
                            axis: Vec3::new(1.0, 2.0, 3.0),
                            degrees: 37.0,
                        })
                        .with(TransformOp::Scale(Vec3::splat(scale)))
                        .with(TransformOp::Translate(shift)),
                );
                let scene = trazo::scene::build(&d).unwrap();
                let closed = !matches!(kind, ShapeKind::Rectangle { .. });
                let mut hits = 0;
                for _ in 0..2000 {
                    // A ray from outside toward a random point near the shape.
                    let from = shift + sample_sphere_uniform(rand2()) * 10.0 * scale;
                    let to = shift + sample_sphere_uniform(rand2()) * 0.5 * scale;
                    let Some(hit) = scene.intersect(&Ray::new(from, (to - from).normalize())) else {
                        continue;
                    };
                    hits += 1;
                    let w = sample_sphere_uniform(rand2());
                    let leaving = if hit.ng.dot(from - hit.p) > 0.0 {
                        hit.ng
                    } else {
                        -hit.ng
                    };
                    let away = if w.dot(leaving) > 0.0 { w } else { -w };
                    // Every shape here is convex: once left, it is never met again.
                    if let Some(again) = scene.intersect(&hit.spawn_ray(away)) {
                        panic!(
                            "{kind:?} at scale {scale}, offset {offset}: the outgoing ray met the surface again at t = {}",
                            again.t
                        );
                    }
                    if closed && away.dot(leaving) > 0.2 {
                        // Into the shape: the way out, not the point it left.
                        // Near an edge of a box the way out may be another face
                        // within the rounding error of the start (its faces are
                        // rectangles, whose error bounds are looser than the
                        // box's own were); the surface the ray started on is
                        // never met again.
                        if let Some(inside) = scene.intersect(&hit.spawn_ray(-away)) {
                            assert!(
                                (inside.p - hit.p).length() > 4.0 * hit.p_error.length() || inside.ng.dot(hit.ng) < 0.9,
                                "{kind:?} at scale {scale}, offset {offset}: the ray into the shape hit its start (t = {})",
                                inside.t
                            );
                        } else {
                            panic!("{kind:?} at scale {scale}, offset {offset}: the ray into the shape escaped");
                        }
                    }
                }
                assert!(hits > 200, "{kind:?} at scale {scale}: only {hits} rays hit");
            }
        }
    }
}

fn small_box(spp: u32) -> trazo::scene::Scene {
    small_box_filtered(spp, trazo::settings::Filter::default())
}

fn small_box_filtered(spp: u32, filter: trazo::settings::Filter) -> trazo::scene::Scene {
    let mut d = cornell_box();
    d.settings.width = 24;
    d.settings.height = 20;
    d.settings.spp = spp;
    d.settings.filter = filter;
    trazo::scene::build(&d).unwrap()
}

/// With a filter wider than a pixel, samples are splatted into their
/// neighbours: the image is still the same for any number of threads and
/// for a render resumed from a pass boundary, and it converges to the
/// image that filter importance sampling gives (the same expectation).
#[test]
fn splatted_filters_stay_deterministic_and_agree_with_importance_sampling() {
    use trazo::render::{Control, render_controlled};
    use trazo::settings::Filter;
    let gaussian = Filter::Gaussian {
        stddev: 0.5,
        radius: 2.0,
    };
    let scene = small_box_filtered(12, gaussian);
    let by_threads: Vec<_> = [1, 2, 3]
        .map(|t| {
            render(
                &scene,
                &RenderOptions {
                    threads: Some(t),
                    tile_size: 8,
                    ..RenderOptions::default()
                },
            )
            .unwrap()
            .film
        })
        .into_iter()
        .collect();
    assert!(by_threads[0] == by_threads[1] && by_threads[0] == by_threads[2]);
    // Resume from the film after the passes of 1, 2 and 4 samples.
    let passes = films_by_pass(&scene, false);
    let (spp, film) = passes[2].clone();
    assert_eq!(spp, 4);
    let stats = trazo::render::RenderStats {
        spp,
        samples: spp as u64 * 24 * 20,
        ..Default::default()
    };
    let mut control = Control {
        resume: Some((film, stats)),
        ..Control::default()
    };
    let resumed = render_controlled(&scene, &RenderOptions::default(), &mut control).unwrap();
    assert!(resumed.film == passes.last().unwrap().1);
    // Splatting and filter importance sampling estimate the same image: at
    // many samples their means over the image agree to within the noise.
    let mean = |f: &trazo::film::Film| {
        let n = f.pixels.len() as f64;
        f.pixels
            .iter()
            .map(|p| trazo::color::luminance(p.value()) as f64)
            .sum::<f64>()
            / n
    };
    let splatted = render(&small_box_filtered(256, gaussian), &RenderOptions::default())
        .unwrap()
        .film;
    let mut fis_scene = small_box_filtered(256, gaussian);
    fis_scene.settings.filter = Filter::Box { radius: 0.5 };
    let (a, b) = (
        mean(&splatted),
        mean(&render(&fis_scene, &RenderOptions::default()).unwrap().film),
    );
    assert!((a - b).abs() < 0.02 * b, "{a} vs {b}");
}

/// The film after every pass of an uninterrupted render, by samples per pixel.
fn films_by_pass(scene: &trazo::scene::Scene, aovs: bool) -> Vec<(u32, trazo::film::Film)> {
    use trazo::render::{Control, render_controlled};
    let mut films = Vec::new();
    let mut save = |f: &trazo::film::Film, st: &trazo::render::RenderStats, _: &[u8]| films.push((st.spp, f.clone()));
    let options = RenderOptions {
        aovs,
        ..RenderOptions::default()
    };
    let mut control = Control {
        checkpoint_every: Some(std::time::Duration::ZERO),
        on_checkpoint: Some(&mut save),
        ..Control::default()
    };
    let out = render_controlled(scene, &options, &mut control).unwrap();
    assert_eq!(out.stopped, None);
    drop(control);
    films.push((out.stats.spp, out.film));
    films
}

/// A render interrupted at a pass boundary, saved to a checkpoint's bytes and
/// resumed on another number of threads ends with the same film, bit for
/// bit, as one that never stopped.
#[test]
fn a_resumed_render_equals_an_uninterrupted_one() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use trazo::render::checkpoint::Checkpoint;
    use trazo::render::{Control, Stop, render_controlled};
    let scene = small_box(37);
    let reference = films_by_pass(&scene, true);
    assert_eq!(
        reference.iter().map(|f| f.0).collect::<Vec<_>>(),
        [1, 2, 4, 8, 16, 32, 37]
    );
    for stop_at in [1u32, 8, 32] {
        let cancel = AtomicBool::new(false);
        let mut saved = None;
        let mut save = |f: &trazo::film::Film, st: &trazo::render::RenderStats, _: &[u8]| {
            if st.spp >= stop_at {
                saved = Some((f.clone(), st.clone()));
                cancel.store(true, Ordering::Relaxed);
            }
        };
        let options = RenderOptions {
            aovs: true,
            threads: Some(2),
            ..RenderOptions::default()
        };
        let mut control = Control {
            cancel: Some(&cancel),
            checkpoint_every: Some(std::time::Duration::ZERO),
            on_checkpoint: Some(&mut save),
            ..Control::default()
        };
        let partial = render_controlled(&scene, &options, &mut control).unwrap();
        drop(control);
        assert_eq!(partial.stopped, Some(Stop::Interrupted));
        assert_eq!(partial.stats.spp, stop_at);
        // The interrupted film is exactly the uninterrupted one after as many passes.
        let same_pass = &reference.iter().find(|f| f.0 == stop_at).unwrap().1;
        assert!(partial.film == *same_pass, "stopped at {stop_at}");
        let (film, stats) = saved.unwrap();
        let checkpoint = Checkpoint {
            job: vec![("scene".into(), "box".into())],
            target_spp: 37,
            film,
            stats,
            state: Vec::new(),
        };
        let back = Checkpoint::from_bytes(&checkpoint.to_bytes()).unwrap();
        let options = RenderOptions {
            aovs: true,
            threads: Some(1),
            ..RenderOptions::default()
        };
        let mut control = Control {
            resume: Some((back.film, back.stats)),
            ..Control::default()
        };
        let resumed = render_controlled(&scene, &options, &mut control).unwrap();
        assert_eq!(resumed.stopped, None);
        assert_eq!(resumed.stats.spp, 37);
        assert_eq!(resumed.stats.samples, 37 * 24 * 20);
        assert!(resumed.film == reference.last().unwrap().1, "resumed from {stop_at}");
    }
    // A film that is not at a pass boundary cannot be resumed.
    let (_, film) = reference[2].clone();
    let stats = trazo::render::RenderStats {
        spp: 3,
        ..Default::default()
    };
    let mut control = Control {
        resume: Some((film, stats)),
        ..Control::default()
    };
    let options = RenderOptions {
        aovs: true,
        ..RenderOptions::default()
    };
    assert!(render_controlled(&scene, &options, &mut control).is_err());
}

/// Cancelling in the middle of a pass, from another thread, leaves the film
/// of the passes completed before it: never a half pass.
#[test]
fn an_interrupt_mid_pass_keeps_whole_passes() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use trazo::render::{Control, Stop, render_controlled};
    let mut d = cornell_box();
    d.settings.width = 64;
    d.settings.height = 64;
    d.settings.spp = 4096;
    let scene = trazo::scene::build(&d).unwrap();
    let cancel = AtomicBool::new(false);
    let first_pass_done = AtomicBool::new(false);
    let started = std::time::Instant::now();
    let out = std::thread::scope(|s| {
        s.spawn(|| {
            while !first_pass_done.load(Ordering::Relaxed) {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
            cancel.store(true, Ordering::Relaxed);
        });
        let mut done = |_: &trazo::film::Film, _: &trazo::render::RenderStats, _: &[u8]| {
            first_pass_done.store(true, Ordering::Relaxed);
        };
        let mut control = Control {
            cancel: Some(&cancel),
            checkpoint_every: Some(std::time::Duration::ZERO),
            on_checkpoint: Some(&mut done),
            ..Control::default()
        };
        render_controlled(&scene, &RenderOptions::default(), &mut control).unwrap()
    });
    assert!(
        started.elapsed().as_secs_f64() < 10.0,
        "the interrupt was not obeyed promptly"
    );
    assert_eq!(out.stopped, Some(Stop::Interrupted));
    let spp = out.stats.spp;
    assert!(
        spp < 4096 && trazo::render::pass_schedule(4096).iter().any(|p| p.1 == spp),
        "{spp}"
    );
    assert_eq!(out.stats.samples, spp as u64 * 64 * 64);
    assert!(out.film.pixels.iter().all(|p| p.sum().weight == spp as f64), "{spp}");
}

/// The render loop hands an integrator's lanes a tile's samples in order
/// across pixels, so that passes of fewer samples a pixel than lanes (the
/// schedule's first, of 1, 1, 2 and 4) keep them full; each estimate lands
/// in its own pixel, and every sample is traced once.
#[test]
fn lanes_take_samples_across_pixels_and_each_lands_in_its_own() {
    use std::sync::atomic::{AtomicU64, Ordering};
    use trazo::integrator::{Integrator, LANES, RayStats};
    use trazo::sampling::Sampler;
    #[derive(Default)]
    struct Directions {
        groups: AtomicU64,
        partial: AtomicU64,
        traced: AtomicU64,
    }
    impl Integrator for Directions {
        // The ray's direction: the image is the camera's field of
        // directions, which grows along x and falls along y.
        fn radiance(&self, _: &trazo::scene::Scene, ray: &Ray, _: &mut Sampler, _: &mut RayStats) -> Rgb {
            Rgb::new(ray.dir.x, ray.dir.y, 1.0)
        }
        fn radiance_lanes(
            &self,
            scene: &trazo::scene::Scene,
            rays: &[Ray; LANES],
            samplers: &mut [Sampler; LANES],
            live: u32,
            stats: &mut RayStats,
        ) -> [Rgb; LANES] {
            self.groups.fetch_add(1, Ordering::Relaxed);
            self.partial.fetch_add(u64::from(live != 0xff), Ordering::Relaxed);
            self.traced.fetch_add(live.count_ones().into(), Ordering::Relaxed);
            std::array::from_fn(|i| {
                if live & (1 << i) != 0 {
                    self.radiance(scene, &rays[i], &mut samplers[i], stats)
                } else {
                    Rgb::ZERO
                }
            })
        }
    }
    // 24 × 20 pixels in tiles of 16 × 16, 16 × 4, 8 × 16 and 8 × 4: every
    // tile's samples of a pass fill whole groups of eight.
    let spp = 11;
    let scene = small_box_filtered(spp, trazo::settings::Filter::Box { radius: 0.5 });
    let lanes = Directions::default();
    let out = trazo::render::render_with(&scene, &lanes, &RenderOptions::default()).unwrap();
    let samples = 24 * 20 * spp as u64;
    assert_eq!(lanes.traced.load(Ordering::Relaxed), samples);
    assert_eq!(lanes.groups.load(Ordering::Relaxed), samples / 8);
    assert_eq!(lanes.partial.load(Ordering::Relaxed), 0);
    let image = out.film.to_image();
    for y in 0..20 {
        for x in 0..24 {
            let p = image.get(x, y);
            assert!(out.film.pixels[(y * 24 + x) as usize].sum().weight == spp as f64);
            if x > 0 {
                assert!(p.x > image.get(x - 1, y).x, "pixel ({x}, {y})");
            }
            if y > 0 {
                assert!(p.y < image.get(x, y - 1).y, "pixel ({x}, {y})");
            }
        }
    }
}

/// An integrator that returns NaN or infinity for some samples: they are
/// counted, dropped before the film, and the first few are reported with
/// their pixel and sample index.
#[test]
fn non_finite_samples_are_dropped_counted_and_located() {
    struct Faulty;
    impl trazo::integrator::Integrator for Faulty {
        fn radiance(
            &self,
            _: &trazo::scene::Scene,
            ray: &Ray,
            sampler: &mut trazo::sampling::Sampler,
            _: &mut trazo::integrator::RayStats,
        ) -> Rgb {
            let u = sampler.next_1d();
            if ray.dir.x > 0.2 && u < 0.25 {
                Rgb::new(f32::NAN, 1.0, 1.0)
            } else if ray.dir.x < -0.2 && u < 0.25 {
                Rgb::splat(f32::INFINITY)
            } else {
                Rgb::splat(0.5)
            }
        }
    }
    let scene = small_box(16);
    let out = trazo::render::render_with(&scene, &Faulty, &RenderOptions::default()).unwrap();
    let st = &out.stats;
    assert!(st.invalid_samples > 100, "{}", st.invalid_samples);
    assert_eq!(st.invalid_examples.len(), trazo::render::MAX_INVALID_EXAMPLES);
    for e in &st.invalid_examples {
        assert!(!e.value.is_finite());
        assert!(e.x < 24 && e.y < 20 && e.index < 16);
    }
    let total: f64 = out.film.pixels.iter().map(|p| p.sum().weight).sum();
    assert_eq!(total as u64 + st.invalid_samples, st.samples);
    assert!(out.film.pixels.iter().all(|p| p.sum().rgb.is_finite()));
    assert!(
        out.film
            .to_image()
            .pixels
            .iter()
            .all(|p| *p == Rgb::splat(0.5) || *p == Rgb::ZERO)
    );
}

/// The memory estimate bounds what the geometry really holds once built,
/// without overstating it more than the build's temporaries explain: for a
/// large mesh (its own tree over blocks of triangles) and for many small
/// ones (each triangle a top-level primitive, which costs more).
#[test]
fn the_geometry_estimate_bounds_the_built_bvh_and_meshes() {
    let grid = |side: u32, x: f32| {
        let row = side + 1;
        let positions = (0..row * row)
            .map(|k| Vec3::new(x + (k % row) as f32, ((k * 7) % 5) as f32 * 0.1, (k / row) as f32))
            .collect();
        let indices = (0..side * side)
            .flat_map(|q| {
                let a = q / side * row + q % side;
                [[a, a + 1, a + row + 1], [a, a + row + 1, a + row]]
            })
            .collect();
        TriangleMesh {
            positions,
            normals: vec![],
            uvs: vec![],
            indices,
            attributes: Vec::new(),
        }
    };
    let mut large = SceneDesc::default();
    large.shapes.push(ShapeDesc::new(
        ShapeKind::InlineMesh(MeshSource::UvSphere {
            segments: 300,
            rings: 200,
        }),
        None,
    ));
    let mut small = SceneDesc::default();
    for k in 0..400 {
        small.shapes.push(ShapeDesc::new(
            ShapeKind::InlineMesh(MeshSource::Inline(grid(5, k as f32 * 6.0))),
            None,
        ));
    }
    // The sphere's 600 triangles at its poles are degenerate and dropped.
    // The top-level tree's build temporaries (bounds, references, the
    // binary tree before it is collapsed) are larger beside what it keeps
    // than a mesh tree's, so small meshes' estimate may exceed what stays
    // held by more.
    let cases = [(large, 1, 119_400, 301 * 201, 3.0), (small, 400, 50, 36, 3.5)];
    for (d, meshes, triangles, vertices, most) in cases {
        let scene = trazo::scene::build(&d).unwrap();
        let g = scene.geometry.stats();
        assert_eq!(g.triangles, meshes * triangles);
        let held = (g.bvh_bytes + g.mesh_bytes) as u64;
        let estimate = meshes as u64 * trazo::scene::memory::mesh_bytes(triangles as u64, vertices);
        assert!(
            estimate >= held && estimate as f64 <= most * held as f64,
            "{meshes} meshes of {triangles} triangles: estimate {estimate} for {held} bytes held"
        );
        let limits = trazo::scene::BuildLimits {
            max_memory: Some(estimate / 2),
            aovs: false,
        };
        let e = trazo::scene::build_limited(&d, &limits).unwrap_err().to_string();
        assert!(e.contains("more than the memory limit"), "{e}");
    }
}

/// `hide_emitters` (Mitsuba's): what the camera sees directly of emitters
/// and of the environment is black under every integrator, and the light
/// they cast is unchanged: a view of only an emitting rectangle and the sky
/// renders black (and not without the setting), and a view of only a floor
/// lit by them renders the same bits with and without it.
#[test]
fn hidden_emitters_are_black_to_the_camera_and_light_the_scene_as_before() {
    // Black, so that what it reflects of the sky does not show.
    let mut lamp = MaterialDesc::with_kind(
        "lamp",
        MaterialKindDesc::Diffuse {
            reflectance: ColorSource::Rgb(Rgb::ZERO),
        },
    );
    lamp.emission = ColorSource::Rgb(Rgb::new(4.0, 3.0, 2.0));
    let floor = MaterialDesc::with_kind(
        "floor",
        MaterialKindDesc::Diffuse {
            reflectance: ColorSource::Rgb(Rgb::splat(0.6)),
        },
    );
    let base = |look_down: bool| {
        let mut d = SceneDesc::default();
        d.settings.width = 12;
        d.settings.height = 10;
        d.settings.spp = 4;
        d.settings.max_depth = 4;
        d.background = BackgroundDesc::Constant(Rgb::new(0.2, 0.3, 0.5));
        d.materials.push(lamp.clone());
        d.materials.push(floor.clone());
        // A lamp facing the camera (+z) and, below the view, a large floor.
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Rectangle {
                corner: Vec3::new(-0.5, 1.5, 0.0),
                edge_u: Vec3::new(1.0, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 1.0, 0.0),
            },
            Some("lamp"),
        ));
        d.shapes.push(ShapeDesc::new(
            ShapeKind::Rectangle {
                corner: Vec3::new(-10.0, -3.0, 10.0),
                edge_u: Vec3::new(20.0, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, -20.0),
            },
            Some("floor"),
        ));
        // For Whitted's tracer, which lights by point lights only.
        d.lights.push(point_light(Vec3::new(1.0, 0.0, 3.0), 5.0));
        if look_down {
            d.camera.from = Vec3::new(0.0, -1.0, 4.0);
            d.camera.to = Vec3::new(0.0, -3.0, 4.0 - 0.3);
            d.camera.up = Vec3::Z;
            d.camera.projection = ProjectionDesc::Perspective { fov: 30.0 };
        } else {
            // Only the lamp and the sky above the floor's horizon.
            d.camera.from = Vec3::new(0.0, 0.3, 5.0);
            d.camera.to = Vec3::new(0.0, 2.5, 0.0);
        }
        d
    };
    for integrator in [
        IntegratorKind::Path,
        IntegratorKind::VolPath,
        IntegratorKind::Whitted,
        IntegratorKind::Photon,
        IntegratorKind::Sppm,
        IntegratorKind::Light,
    ] {
        let name = integrator.name();
        let render_with = |look_down: bool, hide: bool| {
            let mut d = base(look_down);
            d.settings.integrator = integrator;
            d.settings.hide_emitters = hide;
            d.settings.photon.photons = 2_000;
            d.settings.photon.sppm_photons = 500;
            if integrator == IntegratorKind::Light {
                // The sky carries most of the power, so few paths start
                // on the lamp.
                d.settings.spp = 64;
            }
            render_desc(&d, Some(1)).to_image()
        };
        let (hidden, shown) = (render_with(false, true), render_with(false, false));
        assert!(hidden.pixels.iter().all(|p| *p == Rgb::ZERO), "{name}: something shows");
        if integrator == IntegratorKind::Light {
            // The light tracer never sees the sky directly, and the lamp
            // only where some of its few paths start there.
            assert!(
                shown.mean().max_element() > 0.0,
                "{name}: nothing shows without the setting"
            );
        } else {
            assert!(
                shown.pixels.iter().all(|p| p.max_element() > 0.0),
                "{name}: the view is not all emitters"
            );
            assert!(
                shown.mean().max_element() > 0.05,
                "{name}: nothing shows without the setting"
            );
        }
        let (hidden, shown) = (render_with(true, true), render_with(true, false));
        assert!(shown.mean().max_element() > 0.01, "{name}: the floor is dark");
        assert_eq!(
            hidden, shown,
            "{name}: hiding the emitters changed the light on the floor"
        );
    }
}

/// Ambient occlusion against its closed form: on a floor under a parallel
/// ceiling at height h, a cosine-distributed direction at angle θ meets the
/// ceiling within distance d when cos θ > h/d, which has cosine-weighted
/// measure 1 − (h/d)²; so every pixel that sees the floor is (h/d)² in
/// expectation. The image mean is within 4.5 standard errors of a
/// Bernoulli mean of that many samples, for two distances.
#[test]
fn ambient_occlusion_under_a_ceiling_matches_its_closed_form() {
    let h = 0.5f32;
    for d_max in [1.0f32, 0.7] {
        let mut d = SceneDesc::default();
        d.settings.width = 16;
        d.settings.height = 16;
        d.settings.spp = 64;
        d.settings.integrator = IntegratorKind::AmbientOcclusion;
        d.settings.ao_distance = d_max;
        d.materials.push(MaterialDesc::new("grey"));
        for y in [0.0, h] {
            d.shapes.push(ShapeDesc::new(
                ShapeKind::Rectangle {
                    corner: Vec3::new(-10.0, y, 10.0),
                    edge_u: Vec3::new(20.0, 0.0, 0.0),
                    edge_v: Vec3::new(0.0, 0.0, -20.0),
                },
                Some("grey"),
            ));
        }
        // Between the two, looking down at the floor.
        d.camera.from = Vec3::new(0.0, 0.25, 0.0);
        d.camera.to = Vec3::new(0.0, 0.0, -0.3);
        d.camera.projection = ProjectionDesc::Perspective { fov: 30.0 };
        let img = render_desc(&d, None).to_image();
        let expected = (h / d_max) as f64 * (h / d_max) as f64;
        let n = (16 * 16 * 64) as f64;
        let sigma = (expected * (1.0 - expected) / n).sqrt();
        let mean = img.mean().x as f64;
        assert!(
            (mean - expected).abs() < 4.5 * sigma,
            "distance {d_max}: {mean} vs (h/d)² = {expected} ± {sigma}"
        );
        assert!(img.pixels.iter().all(|p| p.x == p.y && p.y == p.z));
    }
}

/// A crop window renders that part of the full image: with a one-pixel
/// box filter its pixels are the full image's, to the bit (they draw the
/// full image's pixels' random numbers), and the window comes out at its
/// own size.
#[test]
fn a_crop_window_is_that_part_of_the_full_image() {
    let mut d = trazo::scene::builtin::cornell_box();
    d.settings.width = 40;
    d.settings.height = 30;
    d.settings.spp = 4;
    d.settings.filter = trazo::settings::Filter::Box { radius: 0.5 };
    let full = render(&trazo::scene::build(&d).unwrap(), &RenderOptions::default())
        .unwrap()
        .film
        .to_image();
    let mut c = d.clone();
    c.settings.crop = Some(trazo::settings::Crop {
        full_width: 40,
        full_height: 30,
        x: 7,
        y: 11,
    });
    (c.settings.width, c.settings.height) = (20, 13);
    let crop = render(&trazo::scene::build(&c).unwrap(), &RenderOptions::default())
        .unwrap()
        .film
        .to_image();
    assert_eq!((crop.width, crop.height), (20, 13));
    for y in 0..13 {
        for x in 0..20 {
            assert_eq!(crop.get(x, y), full.get(x + 7, y + 11), "pixel ({x}, {y})");
        }
    }
    // A window that does not fit is refused, naming the camera.
    c.settings.width = 40;
    let e = trazo::scene::build(&c)
        .expect_err("a window beyond the image")
        .to_string();
    assert!(e.contains("crop window"), "{e}");
}

/// Diffuse transmission (pbrt-v4's `diffusetransmission`): under a sky of
/// radiance 1 and above a black half-space, a sheet of reflectance R and
/// transmittance T seen from below shows T (the sky's light, transmitted
/// diffusely) and seen from above shows 1·R reflected; a sphere with
/// R + T = 1 vanishes in a white furnace. Through TOML and through the
/// pbrt-v4 reader (with its `scale`).
#[test]
fn diffuse_transmission_transmits_and_reflects_its_shares() {
    let scene = |from: &str, background: &str| {
        format!(
            r#"
[render]
width = 8
height = 8
spp = 64
max_depth = 3

[camera]
from = {from}
to = [0, 0, 0]
fov = 20

[world]
background = {background}

[[material]]
name = "sheet"
type = "diffusetransmission"
reflectance = [0.2, 0.3, 0.1]
transmittance = [0.6, 0.4, 0.7]

[[shape]]
type = "disk"
radius = 1000
normal = [0, 1, 0]
material = "sheet"
"#
        )
    };
    // The image's mean and the standard error of each channel's mean.
    let mean = |text: &str| {
        let d = trazo::scene::native::parse(text, std::path::Path::new("dt.toml")).unwrap();
        let f = render_desc(&d, None);
        let n = f.pixels.len() as f32;
        let m = f.pixels.iter().fold(Rgb::ZERO, |a, p| a + p.value()) / n;
        let var: f64 = f.pixels.iter().map(|p| p.variance_of_mean()).sum::<f64>() / (n as f64 * n as f64);
        (m, var.sqrt() as f32)
    };
    // A background of 1 above and 0 below: the world background is
    // constant, so light from below is cut by a second, black disk.
    let below = scene("[0, -5, 0.01]", "1").replace(
        "material = \"sheet\"\n",
        "material = \"sheet\"\n\n[[material]]\nname = \"black\"\ntype = \"diffuse\"\nreflectance = 0\n\n[[shape]]\ntype = \"disk\"\ncenter = [0, -50, 0]\nradius = 1000\nmaterial = \"black\"\n",
    );
    // The camera sits between the sheet and the black disk: it sees the
    // sheet's underside, lit through the sheet by the sky (T) and from below
    // by nothing.
    let (m, e) = mean(&below);
    assert!(
        (m - Rgb::new(0.6, 0.4, 0.7)).abs().max_element() < 4.5 * e + 1e-5,
        "seen from below: {m} ± {e}"
    );
    let above = scene("[0, 5, 0.01]", "1").replace(
        "material = \"sheet\"\n",
        "material = \"sheet\"\n\n[[material]]\nname = \"black\"\ntype = \"diffuse\"\nreflectance = 0\n\n[[shape]]\ntype = \"disk\"\ncenter = [0, -50, 0]\nradius = 1000\nmaterial = \"black\"\n",
    );
    let (m, e) = mean(&above);
    assert!(
        (m - Rgb::new(0.2, 0.3, 0.1)).abs().max_element() < 4.5 * e + 1e-5,
        "seen from above: {m} ± {e}"
    );

    // pbrt-v4: scale 2 doubles both (clamped to 1); a closed sphere of
    // R + T = 1 in a white furnace renders 1. (The sky is found by BSDF
    // sampling alone, whose per-channel weights are heavy-tailed here: 256
    // samples a pixel make its estimated standard error trustworthy.)
    let pbrt = r#"Integrator "path" "integer maxdepth" 64
Sampler "independent" "integer pixelsamples" 256
Film "rgb" "integer xresolution" 8 "integer yresolution" 8
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 30
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
Material "diffusetransmission" "rgb reflectance" [0.15 0.3 0.05] "rgb transmittance" [0.35 0.2 0.45] "float scale" 2
Shape "sphere" "float radius" 1
"#;
    let d = trazo::scene::pbrt::parse(pbrt, std::path::Path::new("dt.pbrt")).unwrap();
    assert!(
        !d.warnings.iter().any(|w| w.contains("diffusetransmission")),
        "{:?}",
        d.warnings
    );
    let mut d = d;
    d.settings.rr_depth = 64;
    let f = render_desc(&d, None);
    for p in &f.pixels {
        let v = p.value();
        let sigma = p.variance_of_mean().sqrt() as f32;
        assert!(
            (v - Rgb::ONE).abs().max_element() <= 5.0 * sigma + 1e-3,
            "{v} ± {sigma}"
        );
    }
}

/// Filters with negative lobes, splatted, ring at a hard edge as their
/// closed forms say: a lamp filling the left half of the image, seen
/// straight on, makes each pixel near the edge the share of the filter's
/// integral that falls on the lamp, F(e − c) = ∫ from −r to e − c of f over
/// ∫f, for the pixel centre c and the edge e at the image's middle: above 1
/// a pixel and a half inside the lamp and below 0 a pixel and a half
/// outside for Lanczos' sinc and for Catmull–Rom's cubic, which the
/// Gaussian never is. The profiles are written here again from their
/// papers, not taken from the renderer. Tolerance: 4.5 standard errors of
/// the mean over 8 seeds, and 2·10⁻⁴ for the splat's weights, tabulated at
/// 64 phases a pixel and interpolated.
#[test]
fn filters_with_negative_lobes_ring_at_an_edge_as_their_closed_forms_say() {
    use std::f64::consts::PI;
    let sinc = |x: f64| if x.abs() < 1e-9 { 1.0 } else { (PI * x).sin() / (PI * x) };
    let lanczos = |x: f64| if x.abs() <= 3.0 { sinc(x) * sinc(x / 3.0) } else { 0.0 };
    // Mitchell and Netravali 1988, eq. 8, with B = 0, C = 1/2.
    let catmull_rom = |x: f64| {
        let x = x.abs();
        if x <= 1.0 {
            1.5 * x.powi(3) - 2.5 * x * x + 1.0
        } else if x <= 2.0 {
            -0.5 * x.powi(3) + 2.5 * x * x - 4.0 * x + 2.0
        } else {
            0.0
        }
    };
    let share = |f: &dyn Fn(f64) -> f64, radius: f64, t: f64| {
        let n = 200_000;
        let dx = 2.0 * radius / n as f64;
        let (mut below, mut all) = (0.0, 0.0);
        for i in 0..n {
            let x = -radius + (i as f64 + 0.5) * dx;
            all += f(x) * dx;
            if x < t {
                below += f(x) * dx;
            }
        }
        below / all
    };
    let render_edge = |filter: &str, seed: u32| {
        let d = trazo::scene::native::parse(
            &format!(
                r#"
[render]
width = 16
height = 4
spp = 256
max_depth = 1
filter = "{filter}"
seed = {seed}

[camera]
from = [0, 0, 1]
to = [0, 0, 0]
fov = 90

[[material]]
name = "lamp"
type = "diffuse"
reflectance = 0
emission = 1

[[shape]]
type = "rectangle"
corner = [-100, -100, 0]
edge_u = [100, 0, 0]
edge_v = [0, 200, 0]
material = "lamp"
"#
            ),
            std::path::Path::new("edge.toml"),
        )
        .unwrap();
        render_desc(&d, None)
    };
    type Profile<'a> = (&'a str, &'a dyn Fn(f64) -> f64, f64);
    let profiles: [Profile; 2] = [("lanczos", &lanczos, 3.0), ("catmullrom", &catmull_rom, 2.0)];
    for (name, f, radius) in profiles {
        let films: Vec<_> = (0..8).map(|seed| render_edge(name, seed)).collect();
        for x in 5..11u32 {
            let c = x as f64 + 0.5;
            let expected = share(f, radius, 8.0 - c);
            // The row's pixels are alike: their mean over the rows and seeds.
            let values: Vec<f64> = films
                .iter()
                .map(|film| {
                    (0..4)
                        .map(|y| film.pixels[(y * 16 + x) as usize].value().x as f64)
                        .sum::<f64>()
                        / 4.0
                })
                .collect();
            let mean = values.iter().sum::<f64>() / values.len() as f64;
            let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (values.len() - 1) as f64;
            let se = (var / values.len() as f64).sqrt();
            assert!(
                (mean - expected).abs() <= 4.5 * se + 2e-4,
                "{name}: pixel {x} is {mean} ± {se}, the closed form {expected}"
            );
            if x == 6 {
                assert!(expected > 1.01, "{name}: overshoot {expected}");
            }
            if x == 9 {
                assert!(expected < -0.01, "{name}: undershoot {expected}");
            }
        }
    }
    // The Gaussian stays within [0, 1].
    let gaussian = render_edge("gaussian", 0);
    assert!(
        gaussian
            .pixels
            .iter()
            .all(|p| (-1e-6..=1.0 + 1e-6).contains(&p.value().x)),
        "a Gaussian filter does not ring"
    );
}
