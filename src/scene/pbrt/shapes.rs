//! `Shape` (pbrt-v4 shapes.cpp, `Shape::Create` and each shape's
//! `Create`): parameters, defaults and checks.

use super::params::{FloatValue, ParamList};
use super::{Emission, Parser, PendingShape};
use crate::color::Rgb;
use crate::error::{Error, Result, SourceLoc};
use crate::geometry::TriangleMesh;
use crate::geometry::quadric::Quadric;
use crate::geometry::subdivision::{MAX_SUBDIVISION_LEVELS, loop_subdivide};
use crate::scene::desc::*;
use glam::{Vec2, Vec3};
use std::path::Path;

/// The mesh attribute that holds the per-triangle radiance of pbrt-v4's
/// `power` on a mesh of unequal triangles.
const PBRT_POWER_ATTRIBUTE: &str = "face_pbrt_power_radiance";

impl Parser {
    /// Converts one `Shape` with the current graphics state.
    /// A `plymesh`'s mesh, displaced where it names a float texture
    /// `displacement`, its edges first cut shorter than `edgelength` (1),
    /// as pbrt-v4's `TriQuadMesh::Displace` (done when the scene is built).
    fn displaced(&mut self, p: &ParamList, source: MeshSource, locs: &mut Locs) -> Result<MeshSource> {
        let height = match p.float_or_texture("displacement")? {
            None => {
                // Read, so that it is not reported as unused: pbrt-v4
                // ignores it without a displacement.
                p.float("edgelength", 1.0)?;
                return Ok(source);
            }
            Some((FloatValue::Num(_), prm)) => {
                return Err(prm.err("a displacement must be a float texture (\"texture displacement\" \"name\")"));
            }
            Some((FloatValue::Texture(t), prm)) => match self.float_texture_descs.get(&t) {
                Some((name, _)) => name.clone(),
                None => {
                    return Err(prm.err(format!(
                        "no float texture named \"{t}\"{}",
                        suggest(&t, self.float_textures.iter().map(String::as_str))
                    )));
                }
            },
        };
        let edge_length = match p.float_opt("edgelength")? {
            Some((e, prm)) => {
                if !(e > 0.0 && e.is_finite()) {
                    return Err(prm.err(format!("must be a positive length, got {e}")));
                }
                locs.keys.push(("edge_length".into(), prm.loc.clone()));
                e
            }
            None => 1.0,
        };
        Ok(MeshSource::Displaced {
            mesh: Box::new(source),
            height,
            edge_length,
            power: None,
        })
    }

    pub(super) fn shape(&mut self, kind: &str, p: &ParamList, loc: SourceLoc, dir_rel: &Path) -> Result<()> {
        let mut locs = Locs::at(Some(loc.clone()));
        locs.keys.push(("transform".into(), loc.clone()));
        let what = format!("Shape \"{kind}\"");
        // A bilinearmesh of bent patches is a shape per patch: those after
        // the first.
        let mut extra_patches = Vec::new();
        let (mut shape, analytic) = match kind {
            "sphere" => {
                let r = p.float_opt("radius")?;
                let radius = r.as_ref().map_or(1.0, |(v, _)| *v);
                if let Some((_, prm)) = &r {
                    locs.keys.push(("radius".into(), prm.loc.clone()));
                }
                let zmin = p.float("zmin", -radius)?;
                let zmax = p.float("zmax", radius)?;
                let phimax = p.float("phimax", 360.0)?;
                if zmin > -radius || zmax < radius || phimax < 360.0 {
                    let q = Quadric::sphere(radius, zmin, zmax, phimax)
                        .map_err(|e| Error::scene(Some(loc.clone()), "zmin", format!("{what}: {e}")))?;
                    (ShapeKind::Quadric(q), true)
                } else {
                    (
                        ShapeKind::Sphere {
                            center: Vec3::ZERO,
                            radius,
                        },
                        true,
                    )
                }
            }
            "disk" => {
                let r = p.float_opt("radius")?;
                let radius = r.as_ref().map_or(1.0, |(v, _)| *v);
                if let Some((_, prm)) = &r {
                    locs.keys.push(("radius".into(), prm.loc.clone()));
                }
                let height = p.float("height", 0.0)?;
                let inner = p.float("innerradius", 0.0)?;
                let phimax = p.float("phimax", 360.0)?;
                if inner != 0.0 || phimax < 360.0 {
                    let q = Quadric::annulus(height, inner, radius, phimax)
                        .map_err(|e| Error::scene(Some(loc.clone()), "innerradius", format!("{what}: {e}")))?;
                    (ShapeKind::Quadric(q), true)
                } else {
                    (
                        ShapeKind::Disk {
                            center: Vec3::new(0.0, 0.0, height),
                            normal: Vec3::Z,
                            radius,
                            uv: crate::geometry::DiskUv::AngleRadius,
                        },
                        true,
                    )
                }
            }
            "cylinder" => {
                let r = p.float_opt("radius")?;
                let radius = r.as_ref().map_or(1.0, |(v, _)| *v);
                if let Some((_, prm)) = &r {
                    locs.keys.push(("radius".into(), prm.loc.clone()));
                }
                let zmin = p.float_opt("zmin")?;
                let zmax = p.float_opt("zmax")?;
                for (key, z) in [("p0", &zmin), ("p1", &zmax)] {
                    if let Some((_, prm)) = z {
                        locs.keys.push((key.into(), prm.loc.clone()));
                    }
                }
                let (z0, z1) = (zmin.map_or(-1.0, |(v, _)| v), zmax.map_or(1.0, |(v, _)| v));
                let phimax = p.float("phimax", 360.0)?;
                if phimax < 360.0 {
                    let q = Quadric::cylinder(radius, z0, z1, phimax)
                        .map_err(|e| Error::scene(Some(loc.clone()), "phimax", format!("{what}: {e}")))?;
                    (ShapeKind::Quadric(q), true)
                } else {
                    (
                        ShapeKind::Cylinder {
                            p0: Vec3::new(0.0, 0.0, z0),
                            p1: Vec3::new(0.0, 0.0, z1),
                            radius,
                        },
                        true,
                    )
                }
            }
            // pbrt-v3's quadrics (pbrt-v4 dropped them), with its defaults.
            "cone" | "paraboloid" | "hyperboloid" => {
                let phimax = p.float("phimax", 360.0)?;
                let q = match kind {
                    "cone" => Quadric::cone(p.float("radius", 1.0)?, p.float("height", 1.0)?, phimax),
                    "paraboloid" => Quadric::paraboloid(
                        p.float("radius", 1.0)?,
                        p.float("zmin", 0.0)?,
                        p.float("zmax", 1.0)?,
                        phimax,
                    ),
                    _ => Quadric::hyperboloid(p.point3("p1", Vec3::ZERO)?, p.point3("p2", Vec3::ONE)?, phimax),
                }
                .map_err(|e| Error::scene(Some(loc.clone()), kind, format!("{what}: {e}")))?;
                (ShapeKind::Quadric(q), true)
            }
            "trianglemesh" => {
                let mesh = self.mesh(p, &loc, "trianglemesh", 3, &mut locs)?;
                (ShapeKind::InlineMesh(MeshSource::Inline(mesh)), false)
            }
            "bilinearmesh" => {
                let mesh = self.mesh(p, &loc, "bilinearmesh", 4, &mut locs)?;
                // Each patch v00 v10 v01 v11 is the triangle pair
                // [v00 v10 v11], [v00 v11 v01] of `mesh`. Flat patches
                // stay those triangles; where one is bent, every patch of
                // the mesh is an exact bilinear patch.
                let patches: Vec<[u32; 4]> = mesh
                    .indices
                    .chunks_exact(2)
                    .map(|f| [f[0][0], f[0][1], f[1][2], f[0][2]])
                    .collect();
                let corners = |c: &[u32; 4]| c.map(|i| mesh.positions[i as usize]);
                if patches.iter().all(|c| is_planar(corners(c))) {
                    (ShapeKind::InlineMesh(MeshSource::Inline(mesh)), false)
                } else {
                    if !mesh.normals.is_empty() {
                        self.unsupported(
                            &loc,
                            "\"normal N\" of a bilinearmesh with non-planar patches",
                            "the patches shade with their true normals",
                        );
                    }
                    let mut kinds = patches.iter().map(|c| {
                        let [p00, p10, p01, p11] = corners(c);
                        let patch = crate::geometry::bilinear::BilinearPatch::new(p00, p10, p01, p11);
                        ShapeKind::Bilinear(if mesh.uvs.is_empty() {
                            patch
                        } else {
                            patch.with_uvs(c.map(|i| mesh.uvs[i as usize]))
                        })
                    });
                    let first = kinds.next().expect("a bilinearmesh has a patch");
                    extra_patches = kinds.collect();
                    (first, false)
                }
            }
            "plymesh" => {
                let Some((file, prm)) = p.string("filename")? else {
                    return Err(Error::scene(
                        Some(loc),
                        "filename",
                        "plymesh needs a \"string filename\"",
                    ));
                };
                locs.keys.push(("file".into(), prm.loc.clone()));
                let path = self.resolve(dir_rel, &file);
                // An emitter's `power` needs its triangles' areas now.
                let powered = self.gs.area_light.as_ref().is_some_and(|e| e.power.is_some());
                let source = if crate::files::is_gzip_name(&path) || powered {
                    // pbrt-v4 reads gzip-compressed PLY files; trazo
                    // decompresses and reads them now, the others when the
                    // scene is built.
                    let at = prm.loc.clone();
                    let mesh = self.gzip_ply(&self.top_dir.join(&path), &at, crate::files::MAX_PLY_BYTES)?;
                    MeshSource::Inline(mesh)
                } else {
                    MeshSource::File(path)
                };
                (ShapeKind::InlineMesh(self.displaced(p, source, &mut locs)?), false)
            }
            "loopsubdiv" => {
                let levels = match p.int_opt("levels")? {
                    Some((l, prm)) if !(0..=i64::from(MAX_SUBDIVISION_LEVELS)).contains(&l) => {
                        return Err(prm.err(format!(
                            "{l} is not a number of subdivision levels (0 to {MAX_SUBDIVISION_LEVELS}; each level makes 4 times the triangles)"
                        )));
                    }
                    Some((l, _)) => l as u32,
                    None => 3,
                };
                let control = self.mesh(p, &loc, "loopsubdiv", 3, &mut locs)?;
                for (key, given) in [("N", !control.normals.is_empty()), ("uv", !control.uvs.is_empty())] {
                    if let Some(prm) = p.find(key).filter(|_| given) {
                        let l = prm.loc.clone();
                        self.unsupported(
                            &l,
                            format!("\"{}\" of loopsubdiv", prm.written),
                            "the subdivided surface takes its limit normals and no texture coordinates (as in pbrt-v4)",
                        );
                    }
                }
                let mesh = loop_subdivide(&control.positions, &control.indices, levels)
                    .map_err(|e| Error::scene(Some(loc.clone()), "levels", format!("Shape \"loopsubdiv\": {e}")))?;
                // pbrt-v4's limit normal (the cross product of its tangents
                // over its one-ring order) faces away from the side the
                // control faces wind counter-clockwise on, and its
                // triangles take their side from that normal: wound the
                // other way, trazo's triangles face the same side.
                let mesh = mesh.flipped();
                (ShapeKind::InlineMesh(MeshSource::Inline(mesh)), false)
            }
            _ => {
                // curve (pbrt-v4's Curve::Create): Bézier segments, each
                // split into 2^splitdepth pieces.
                use crate::geometry::curve::{Curve, CurveKind, bezier_segments};
                let Some((points, pp)) = p.vec3s("P", &["point3"])? else {
                    return Err(Error::scene(
                        Some(loc.clone()),
                        "P",
                        "a curve needs its control points \"point3 P\"",
                    ));
                };
                let pp_loc = pp.loc.clone();
                let width = p.float("width", 1.0)?;
                let (w0, w1) = (p.float("width0", width)?, p.float("width1", width)?);
                if !(w0 >= 0.0 && w1 >= 0.0 && w0.is_finite() && w1.is_finite() && w0.max(w1) > 0.0) {
                    return Err(Error::scene(
                        Some(loc.clone()),
                        "width",
                        format!("{what}: widths must be finite, not negative and not both zero, got {w0} and {w1}"),
                    ));
                }
                let degree = p.int_opt("degree")?.map_or(3, |(d, _)| d);
                let basis = p.string("basis")?.map_or("bezier".to_string(), |(b, _)| b);
                if basis != "bezier" && basis != "bspline" {
                    return Err(Error::scene(
                        Some(loc.clone()),
                        "basis",
                        format!("{what}: basis \"{basis}\" (pbrt-v4 knows \"bezier\" and \"bspline\")"),
                    ));
                }
                let segments = bezier_segments(&points, basis == "bspline", degree.clamp(0, 16) as usize)
                    .map_err(|e| Error::scene(Some(pp_loc), "P", format!("{what}: {e}")))?;
                let kind = match p.string("type")? {
                    None => CurveKind::Flat,
                    Some((t, prm)) => CurveKind::named(&t).ok_or_else(|| {
                        prm.err(format!(
                            "unknown curve type \"{t}\" (pbrt-v4 knows \"flat\", \"cylinder\" and \"ribbon\")"
                        ))
                    })?,
                };
                let normals = match p.vec3s("N", &["normal", "normal3"])? {
                    Some((n, prm)) if kind == CurveKind::Ribbon => {
                        if n.len() != segments.len() + 1 {
                            return Err(prm.err(format!(
                                "a ribbon of {} segments needs {} normals, got {}",
                                segments.len(),
                                segments.len() + 1,
                                n.len()
                            )));
                        }
                        Some(n)
                    }
                    Some((_, prm)) => {
                        let l = prm.loc.clone();
                        self.unsupported(
                            &l,
                            "\"normal N\" of a curve that is not a ribbon",
                            "ignored, as in pbrt-v4",
                        );
                        None
                    }
                    None if kind == CurveKind::Ribbon => {
                        return Err(Error::scene(
                            Some(loc.clone()),
                            "N",
                            "a ribbon curve needs normals \"normal N\" at its segments' ends",
                        ));
                    }
                    None => None,
                };
                let split_depth = p.int_opt("splitdepth")?.map_or(3, |(d, _)| d).clamp(0, 10) as u32;
                let n = segments.len() as f32;
                let mut pieces = segments.iter().enumerate().flat_map(|(i, cp)| {
                    let lerp = |t: f32| w0 + (w1 - w0) * t;
                    let ends = normals.as_ref().map(|n| [n[i], n[i + 1]]);
                    Curve::pieces(
                        *cp,
                        lerp(i as f32 / n),
                        lerp((i + 1) as f32 / n),
                        kind,
                        ends,
                        split_depth,
                    )
                });
                let first = pieces.next().expect("a curve has a segment");
                extra_patches = pieces.map(ShapeKind::Curve).collect();
                (ShapeKind::Curve(first), true)
            }
        };
        let mut emission = self.gs.area_light.clone();
        if let Some(e) = emission.as_mut() {
            self.apply_power(e, &mut shape, &what)?;
        }
        if emission.is_some() && self.current_object.is_some() {
            emission = None;
            self.unsupported(
                &loc,
                format!("AreaLightSource on {what} inside ObjectBegin"),
                "area lights are not instanced (pbrt-v4 does not support them either); the shape does not emit",
            );
        }
        // pbrt-v4's alpha: a number below 1 or a float texture.
        let alpha = match p.float_or_texture("alpha")? {
            None => None,
            Some((FloatValue::Num(a), _)) => (a < 1.0).then(|| ColorSource::Rgb(Rgb::splat(a.max(0.0)))),
            Some((FloatValue::Texture(t), prm)) => match self.float_texture_descs.get(&t) {
                Some((name, _)) => Some(ColorSource::Texture(name.clone())),
                None => {
                    return Err(prm.err(format!(
                        "no float texture named \"{t}\"{}",
                        suggest(&t, self.float_textures.iter().map(String::as_str))
                    )));
                }
            },
        };
        let desc = ShapeDesc {
            kind: shape,
            transform: vec![TransformOp::Matrix(self.gs.ctm)],
            material: None,
            flip_normals: false,
            media: self.current_media(),
            motion: self.motion(),
            locs,
        };
        for kind in std::iter::once(None).chain(extra_patches.into_iter().map(Some)) {
            let mut desc = desc.clone();
            if let Some(kind) = kind {
                desc.kind = kind;
            }
            self.add_shape(PendingShape {
                desc,
                analytic,
                reverse: self.gs.reverse_orientation,
                mat: self.gs.material.clone(),
                emission: emission.clone(),
                alpha: alpha.clone(),
            });
        }
        Ok(())
    }

    /// pbrt-v4's area light `power` (DiffuseAreaLight::Create): the
    /// radiance scaled by power / (k · π · sides · area), with the area as
    /// pbrt-v4's shapes report it — in object space for spheres, disks,
    /// cylinders and quadrics, in world space for triangles and patches —
    /// and k the mean luminance of the light's image (1 without one).
    /// pbrt-v4 makes each triangle of a mesh a light of that power, so a
    /// mesh of unequal triangles gets a per-triangle radiance (a mesh
    /// attribute its emission reads; with an image, a per-triangle factor
    /// that scales the image). An image light's other shapes get their own
    /// copy of the image's texture, tinted by its factor.
    fn apply_power(&mut self, e: &mut Emission, shape: &mut ShapeKind, what: &str) -> Result<()> {
        let Some((power, at)) = e.power.take() else {
            return Ok(());
        };
        let image_luminance = match &e.image {
            Some(name) => Some(self.image_mean_luminance(name)?),
            None => None,
        };
        let ctm = self.gs.ctm;
        let world = |p: Vec3| ctm.transform_point3(p);
        if let ShapeKind::InlineMesh(MeshSource::Displaced { power: slot, .. }) = shape {
            // Its triangles are known once the build has displaced it:
            // each gets its radiance from its area there.
            let sides = if e.two_sided { 2.0 } else { 1.0 };
            let per_area = image_luminance.unwrap_or(1.0) * std::f32::consts::PI * sides;
            let image = e.image.take();
            let radiance = if image.is_some() { Rgb::ONE } else { e.radiance };
            *slot = Some(crate::scene::desc::TrianglePower {
                power,
                per_area,
                radiance,
                attribute: PBRT_POWER_ATTRIBUTE.into(),
            });
            // (Its typical radiance: that of a triangle of unit area.)
            let typical = radiance * (power / per_area);
            return self.per_triangle_emission(e, image, &at, what, typical);
        }
        let area = match &*shape {
            ShapeKind::Sphere { radius, .. } => 4.0 * std::f32::consts::PI * radius * radius,
            ShapeKind::Disk { radius, .. } => std::f32::consts::PI * radius * radius,
            ShapeKind::Cylinder { p0, p1, radius } => 2.0 * std::f32::consts::PI * radius * (*p1 - *p0).length(),
            ShapeKind::Quadric(q) => q.area(),
            ShapeKind::Bilinear(b) => {
                let [p00, p10, p01, p11] = b.p.map(|p| world(p.as_vec3()));
                crate::geometry::bilinear::BilinearPatch::new(p00, p10, p01, p11).area()
            }
            ShapeKind::InlineMesh(MeshSource::Inline(mesh)) => {
                let areas: Vec<f32> = (0..mesh.indices.len())
                    .map(|i| {
                        let [a, b, c] = mesh.vertices(i).map(world);
                        0.5 * (b - a).cross(c - a).length()
                    })
                    .collect();
                let mean = areas.iter().sum::<f32>() / areas.len().max(1) as f32;
                if areas.iter().any(|a| (a - mean).abs() > 1e-3 * mean) {
                    // Each triangle's own factor power/(k·π·sides·A): its
                    // radiance L times that, or with an image the image
                    // scaled by it.
                    let sides = if e.two_sided { 2.0 } else { 1.0 };
                    let k = image_luminance.unwrap_or(1.0);
                    let factor = |a: f32| {
                        let k_e = k * std::f32::consts::PI * sides * a;
                        if k_e > 0.0 && k_e.is_finite() {
                            power / k_e
                        } else {
                            0.0 // a degenerate triangle, never hit
                        }
                    };
                    let image = e.image.take();
                    let per_face = |a: f32| match image {
                        None => e.radiance * factor(a),
                        Some(_) => Rgb::splat(factor(a)),
                    };
                    let ShapeKind::InlineMesh(MeshSource::Inline(mesh)) = shape else {
                        unreachable!("matched above")
                    };
                    mesh.attributes.push(crate::geometry::mesh::MeshAttribute {
                        name: PBRT_POWER_ATTRIBUTE.into(),
                        per_face: true,
                        channels: 3,
                        values: areas.iter().flat_map(|&a| per_face(a).to_array()).collect(),
                    });
                    let typical = per_face(mean);
                    self.per_triangle_emission(e, image, &at, what, typical)?;
                    return Ok(());
                }
                mean
            }
            _ => {
                self.unsupported(
                    &at,
                    format!("\"power\" of an area light on {what}"),
                    "the given L and scale are used",
                );
                return Ok(());
            }
        };
        let sides = if e.two_sided { 2.0 } else { 1.0 };
        let k_e = image_luminance.unwrap_or(1.0) * std::f32::consts::PI * sides * area;
        if !(k_e > 0.0 && k_e.is_finite()) {
            return Ok(());
        }
        let factor = power / k_e;
        match e.image.take() {
            None => e.radiance *= factor,
            Some(name) => {
                let mut texture = self
                    .desc
                    .textures
                    .iter()
                    .rev()
                    .find(|t| t.name == name)
                    .expect("an area light's image texture was made with it")
                    .clone();
                if let TextureKind::Image { tint, .. } = &mut texture.kind {
                    *tint *= factor;
                }
                let typical = self.texture_colors.get(&name).copied().unwrap_or(Rgb::ONE) * factor;
                texture.name = format!("{name} with power {}", self.desc.textures.len());
                self.push_texture(&texture.name, &at, texture.locs.clone(), (texture.kind, typical))?;
                e.image = Some(texture.name);
            }
        }
        Ok(())
    }

    /// Makes the emission of an area light whose triangles each carry
    /// their own radiance or factor in the mesh attribute
    /// [`PBRT_POWER_ATTRIBUTE`] read it: the attribute itself, or with
    /// `image` the image scaled by it. `typical` is a typical value.
    fn per_triangle_emission(
        &mut self,
        e: &mut Emission,
        image: Option<String>,
        at: &SourceLoc,
        what: &str,
        typical: Rgb,
    ) -> Result<()> {
        let name = format!("radiance of {what} with power {}", self.desc.textures.len());
        let kind = TextureKind::MeshAttribute {
            name: PBRT_POWER_ATTRIBUTE.into(),
        };
        self.push_texture(&name, at, Locs::at(Some(at.clone())), (kind, typical))?;
        e.image = Some(match image {
            None => name,
            Some(image) => {
                let typical = self.texture_colors.get(&image).copied().unwrap_or(Rgb::ONE) * typical;
                let scaled = format!("{image} with power {}", self.desc.textures.len());
                let kind = TextureKind::Node(crate::texture::TextureNode::Scale {
                    tex: ColorSource::Texture(image),
                    scale: ColorSource::Texture(name),
                });
                self.push_texture(&scaled, at, Locs::at(Some(at.clone())), (kind, typical))?;
                scaled
            }
        });
        Ok(())
    }

    /// The mean luminance of the pixels of an area light's image texture
    /// `name` (pbrt-v4's k_e): the image is read now, once, and kept in
    /// the texture so that the build does not read it again.
    fn image_mean_luminance(&mut self, name: &str) -> Result<f32> {
        let top_dir = self.top_dir.clone();
        let texture = self
            .desc
            .textures
            .iter_mut()
            .rev()
            .find(|t| t.name == name)
            .expect("an area light's image texture was made with it");
        let file_loc = texture.locs.key("file");
        let TextureKind::Image { source, encoding, .. } = &mut texture.kind else {
            unreachable!("an area light's image is an image texture")
        };
        let mut note = None;
        if let ImageSource::EmissionFile(path) = source {
            let (image, unsupported) = crate::texture::ImageTexture::load_colors(
                &top_dir.join(&*path),
                *encoding,
                crate::texture::ImageColors::Emission,
            )
            .map_err(|e| Error::scene(file_loc.clone(), "string filename", crate::scene::build::reason_of(e)))?;
            *source = ImageSource::Data(std::sync::Arc::new(image));
            note = unsupported;
        }
        let ImageSource::Data(image) = source else {
            unreachable!("an area light's image is a file")
        };
        let sum: f64 = image
            .pixels
            .iter()
            .filter(|c| c.is_finite())
            .map(|&c| f64::from(crate::color::luminance(c.max(Rgb::ZERO))))
            .sum();
        let mean = (sum / image.pixels.len().max(1) as f64) as f32;
        if let Some(note) = note {
            let at = file_loc.map(|l| format!("{l}: ")).unwrap_or_default();
            self.desc.warnings.push(format!("{at}{note}"));
        }
        Ok(mean)
    }

    /// The triangles of a gzip-compressed PLY file, decompressed through
    /// the bounded read of every file: `limit` bounds the file and its
    /// decompressed bytes. Its warnings join the scene's.
    pub(super) fn gzip_ply(&mut self, full: &Path, at: &SourceLoc, limit: u64) -> Result<TriangleMesh> {
        let fail = |reason: String| Error::scene(Some(at.clone()), "string filename", reason);
        let bytes = crate::files::read_limited_gz(full, limit)
            .map_err(|e| fail(format!("cannot read mesh {}: {e}", full.display())))?;
        // Positions in the mesh are in its decompressed bytes.
        let ply = crate::scene::ply::parse_ply(&bytes, full).map_err(|e| match e {
            Error::File { path, message } => fail(format!("{}: {message}", path.display())),
            other => fail(other.to_string()),
        })?;
        self.desc.warnings.extend(ply.warnings);
        Ok(ply.mesh)
    }

    /// The mesh of a `trianglemesh` or a `loopsubdiv`'s control mesh
    /// (`corners` = 3), or of a `bilinearmesh` (`corners` = 4, each patch
    /// v00 v10 v01 v11 split into two triangles); `kind` names the shape in
    /// messages.
    fn mesh(
        &mut self,
        p: &ParamList,
        loc: &SourceLoc,
        kind: &str,
        corners: usize,
        locs: &mut Locs,
    ) -> Result<TriangleMesh> {
        let Some((positions, pp)) = p.vec3s("P", &["point3"])? else {
            return Err(Error::scene(
                Some(loc.clone()),
                "P",
                format!("{kind} needs vertex positions \"point3 P\""),
            ));
        };
        let n = positions.len();
        let p_loc = pp.loc.clone();
        let indices: Vec<u32> = match p.ints("indices")? {
            Some((idx, prm)) => {
                locs.keys.push(("indices".into(), prm.loc.clone()));
                if idx.len() % corners != 0 {
                    return Err(prm.err(format!(
                        "needs {corners} indices per {}, found {} indices",
                        if corners == 3 { "triangle" } else { "patch" },
                        idx.len()
                    )));
                }
                if let Some(&bad) = idx.iter().find(|&&i| i < 0 || i as usize >= n) {
                    return Err(prm.err(format!(
                        "index {bad} is out of range: \"point3 P\" has {n} points (indices 0 to {})",
                        n as i64 - 1
                    )));
                }
                idx.into_iter().map(|i| i as u32).collect()
            }
            // pbrt-v4 allows leaving out the indices of a single triangle
            // or patch.
            None if n == corners => (0..corners as u32).collect(),
            None => {
                return Err(Error::scene(
                    Some(p_loc),
                    "indices",
                    format!("{kind} needs \"integer indices\" (only a mesh of exactly {corners} points may omit them)"),
                ));
            }
        };
        let normals = match p.vec3s("N", &["normal3"])? {
            Some((nv, prm)) if nv.len() != n => {
                return Err(prm.err(format!("{} normals given for {n} points; need one per point", nv.len())));
            }
            Some((nv, _)) => nv,
            None => Vec::new(),
        };
        let uvs: Vec<Vec2> = match p.vec2s("uv")? {
            Some((uv, prm)) if uv.len() != n => {
                return Err(prm.err(format!(
                    "{} texture coordinates given for {n} points; need one per point",
                    uv.len()
                )));
            }
            Some((uv, _)) => uv,
            None => Vec::new(),
        };
        if let Some(prm) = p.find("S") {
            let l = prm.loc.clone();
            self.unsupported(&l, format!("\"{}\" of {kind}", prm.written), "tangents are ignored");
        }
        if let Some(prm) = p.find("faceIndices") {
            let l = prm.loc.clone();
            self.unsupported(&l, format!("\"{}\" of {kind}", prm.written), "face indices are ignored");
        }
        let faces: Vec<[u32; 3]> = if corners == 3 {
            indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
        } else {
            let mut faces = Vec::with_capacity(indices.len() / 2);
            for c in indices.chunks_exact(4) {
                let [a, b, cc, d] = [c[0], c[1], c[2], c[3]];
                // The patch's corners in order around it are v00 v10 v11 v01.
                faces.push([a, b, d]);
                faces.push([a, d, cc]);
            }
            faces
        };
        Ok(TriangleMesh {
            positions,
            normals,
            uvs,
            indices: faces,
            attributes: Vec::new(),
        })
    }
}

/// Whether a bilinear patch v00 v10 v01 v11 lies in a plane.
fn is_planar([p00, p10, p01, p11]: [Vec3; 4]) -> bool {
    let n = (p10 - p00).cross(p01 - p00);
    let scale = (p10 - p00).length().max((p01 - p00).length()).max((p11 - p00).length());
    match n.try_normalize() {
        Some(n) => (p11 - p00).dot(n).abs() <= 1e-4 * scale,
        // Degenerate corners: any fourth point is in some plane with them.
        None => true,
    }
}
