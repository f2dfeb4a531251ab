//! Bidirectional path tracing (Veach 1997, chapter 10; Lafortune and
//! Willems 1993): for each pixel sample a subpath from the camera and one
//! from a light, and every way of joining them into a full path.
//!
//! A camera subpath `z₀ z₁ … z_{t−1}` starts on the lens; a light subpath
//! `y₀ y₁ … y_{s−1}` on a light chosen in proportion to its power. The
//! strategy (s, t) uses the first s light vertices and the first t camera
//! vertices:
//!
//! | strategy | path | what it is |
//! |---|---|---|
//! | s = 0 | the camera subpath reaches an emitter | the path tracer without next-event estimation |
//! | s = 1 | a light point sampled for `z_{t−1}` | next-event estimation |
//! | t = 1 | `y_{s−1}` connected to the lens | light tracing, splatted where it lands |
//! | s, t ≥ 2 | `y_{s−1}` joined to `z_{t−1}` by a shadow ray | the bidirectional connections |
//!
//! Every path of length k can be made by k + 1 strategies with different
//! densities; each contribution is weighted by the power heuristic over
//! all of them (Veach 1997, eq. 10.9), computed as pbrt does from the
//! ratios of each vertex's density as sampled from either side (pdfFwd,
//! pdfRev, per unit area), so that no strategy's full density is formed.
//! The weights of the strategies that make one path sum to one, so the
//! estimate is unbiased whatever the weights are.
//!
//! Conventions are pbrt-v4's `BDPTIntegrator`: no Russian roulette in the
//! subpaths; a delta bounce's density is one per unit solid angle (as
//! Georgiev's VCM counts it, so that the segment's cos/d² stays in the
//! weights), and no strategy joins at a delta vertex;
//! the strategy (1, 1), a light point seen by the lens, is not used (the
//! camera subpath's s = 0 finds it); the geometry term uses shading
//! normals, with the adjoint BSDF's correction for them on light subpaths
//! (Veach 1997, eq. 5.21). Lights at infinity (environment, directional)
//! shine from a disk of the scene's bounding radius, as their emitted rays
//! do. Contributions land where their path crosses the image: in the
//! camera sample's pixel (spread by the filter as light tracing's splats
//! are), or, for t = 1, where the connection reaches the film. An
//! iteration traces one camera subpath and one light subpath per pixel.

pub mod vcm;

use super::adjoint_shading_factor;
use super::light::SplatImage;
use super::state::{StateReader, StateWriter};
use super::{Progressive, Work};
use crate::accel::aggregate::EmitterRef;
use crate::color::Rgb;
use crate::color::spectrum::WavelengthSample;
use crate::film::Film;
use crate::geometry::interaction::SHADOW_EPSILON;
use crate::geometry::{Ray, SurfaceHit};
use crate::light::{Light, ShadowTarget};
use crate::material::{Bsdf, MaterialKind, ShadingFrame, TransportMode};
use crate::media::Phase;
use crate::sampling::Uniforms;
use crate::sampling::warp::{pdf_cone_uniform, pdf_sphere_uniform};
use crate::scene::Scene;
use crate::texture::TexCoord;
use glam::{DVec3, Vec2, Vec3};
use std::f32::consts::PI;
use std::sync::atomic::AtomicBool;

/// Separates bidirectional path tracing's random numbers from the others'.
const STREAM: u64 = 0x6264_7074;

/// The streams of a sample's numbers (see [`Uniforms::start_stream`]):
/// the camera subpath's, the light subpath's, the connections'.
pub(crate) const CAMERA_STREAM: u32 = 0;
pub(crate) const LIGHT_STREAM: u32 = 1;
pub(crate) const CONNECTION_STREAM: u32 = 2;
/// How many streams a sample draws from.
pub(crate) const STREAMS: u32 = 3;

/// What a path vertex lies on.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    /// The lens (or the orthographic view plane).
    Camera,
    /// A light: `p` is its point, or for a light at infinity the unit
    /// direction from the scene toward it.
    Light { light: u32, infinite: bool, delta: bool },
    /// A surface.
    Surface,
    /// A scattering point in a participating medium.
    Medium,
}

/// A vertex of a subpath (`'s`: the scene its BSDF reads).
#[derive(Clone, Copy, Debug)]
struct Vertex<'s> {
    kind: Kind,
    /// Position (for a light at infinity, the direction toward it).
    p: Vec3,
    /// Geometric normal of a surface or an area light (zero elsewhere).
    ng: Vec3,
    /// The shading normal the BSDF's frame uses (the normal for an area
    /// light).
    ns: Vec3,
    /// Throughput of the subpath up to here (for lights: emission over
    /// the density of the point).
    beta: Rgb,
    /// Whether the vertex scattered by a delta lobe.
    delta: bool,
    /// Whether a connection can end here: a light that is not a
    /// direction, the camera, a surface with a non-delta lobe.
    connectible: bool,
    /// Density of this vertex sampled from its subpath's side, and from
    /// the other side, per unit area (per solid angle for lights at
    /// infinity).
    pdf_fwd: f32,
    pdf_rev: f32,
    /// For surfaces: the hit, its BSDF and shading frame, and the unit
    /// direction toward the previous vertex of its subpath.
    hit: Option<SurfaceHit>,
    bsdf: Option<(Bsdf<'s>, ShadingFrame)>,
    wo: Vec3,
    /// Radiance for camera subpaths, importance for light subpaths.
    mode: TransportMode,
    /// The time its subpath is traced at (where the camera moves, the
    /// camera vertex is where the camera is then).
    time: f32,
    /// The medium the subpath reached the vertex through (for the camera
    /// and lights, the one they sit in).
    medium: Option<u32>,
    /// For medium vertices, the medium's phase function.
    phase: Option<Phase>,
    /// Whether its BSDF depends on the sample's wavelength (a dispersive
    /// glass): a path through it is weighted by the wavelength's weight.
    disperses: bool,
}

impl<'s> Vertex<'s> {
    fn endpoint(kind: Kind, p: Vec3, n: Vec3, beta: Rgb, pdf_fwd: f32) -> Vertex<'s> {
        Vertex {
            kind,
            p,
            ng: n,
            ns: n,
            beta,
            delta: false,
            connectible: !matches!(
                kind,
                Kind::Light {
                    infinite: true,
                    delta: true,
                    ..
                }
            ),
            pdf_fwd,
            pdf_rev: 0.0,
            hit: None,
            bsdf: None,
            wo: Vec3::ZERO,
            mode: TransportMode::Radiance,
            time: 0.0,
            medium: None,
            phase: None,
            disperses: false,
        }
    }

    /// Whether vertex merging can happen here: at a surface that did not
    /// scatter by a delta lobe (photons are kept on surfaces only, not
    /// in media).
    fn merges(&self) -> bool {
        self.kind == Kind::Surface && !self.delta
    }

    /// The cosine a segment along unit direction `w` has at this vertex in
    /// the geometry term: with the shading normal on surfaces, none (1) in
    /// a medium.
    fn cos_toward(&self, w: Vec3) -> f32 {
        if self.kind == Kind::Medium {
            1.0
        } else {
            self.ns.dot(w).abs()
        }
    }

    fn is_infinite_light(&self) -> bool {
        matches!(self.kind, Kind::Light { infinite: true, .. })
    }

    fn is_delta_light(&self) -> bool {
        matches!(self.kind, Kind::Light { delta: true, .. })
    }

    /// Whether densities arriving here are per unit area of a surface
    /// (surfaces and area lights), which carries a cosine.
    fn on_surface(&self) -> bool {
        self.ng != Vec3::ZERO
    }

    /// Unit direction from this vertex toward `to`, and the squared
    /// distance (infinite toward a light at infinity).
    fn toward(&self, to: &Vertex) -> (Vec3, f32) {
        if to.is_infinite_light() {
            return (to.p, f32::INFINITY);
        }
        if self.is_infinite_light() {
            return (-self.p, f32::INFINITY);
        }
        let d = to.p - self.p;
        let d2 = d.length_squared();
        (d / d2.sqrt(), d2)
    }
}

/// A density in the weights' ratios: the zero a delta bounce stores
/// stands for a Dirac factor that every strategy able to make the path
/// shares, so it counts as one (pbrt-v4's `remap0`).
fn remap(pdf: f32) -> f32 {
    if pdf != 0.0 { pdf } else { 1.0 }
}

fn sq(x: f32) -> f32 {
    x * x
}

/// Whether the vertex before light-subpath vertex `i` scattered by a
/// delta lobe (for the light's own vertex: whether the light is a delta
/// one), which rules out a connection between the two.
fn delta_before(light: &[Vertex], i: usize) -> bool {
    if i > 0 {
        light[i - 1].delta
    } else {
        light[0].is_delta_light()
    }
}

/// How many surfaces that are not there a segment or a walk may cross
/// (a bound against a ray caught among coincident surfaces).
const MAX_CROSSINGS: usize = 256;

/// What a segment of a subpath through a medium ended in.
enum Flight {
    /// It reached the segment's end.
    Crossed,
    /// It scattered at this point.
    Scattered(Vec3),
    /// Nothing is left to carry.
    Ended,
}

/// The mean of the three channels.
#[inline]
fn mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) * (1.0 / 3.0)
}

/// Whether a surface of material `m` is not there: a boundary of a
/// medium that light crosses unchanged (Mitsuba's `null`, pbrt-v4's
/// `interface`).
fn is_null(m: &crate::material::Material) -> bool {
    matches!(m.kind, MaterialKind::Thin { eta, .. } if eta == 1.0)
}

/// The medium that lies outside every surface bounding a medium, where
/// lights at infinity shine from: the camera's, changed at every such
/// surface a ray from the camera through the image's centre crosses on
/// its way out of the scene.
fn outer_medium(scene: &Scene) -> Option<u32> {
    let (w, h) = (scene.settings.width as f32, scene.settings.height as f32);
    let mut ray = scene.camera.generate_ray(Vec2::new(0.5 * w, 0.5 * h), Vec2::splat(0.5));
    let mut medium = scene.camera_medium;
    for _ in 0..MAX_CROSSINGS {
        let Some(hit) = scene.intersect(&ray) else { break };
        if let Some(interface) = scene.material_media[hit.material as usize] {
            medium = interface.toward(ray.dir, hit.ng);
        }
        ray = hit.spawn_ray(ray.dir);
    }
    medium
}

/// The BSDF at a surface vertex, in its shading frame, for a sample of
/// wavelength `nm` (drawn where the scene disperses light), and whether it
/// depends on it.
fn surface_bsdf<'s>(scene: &'s Scene, hit: &SurfaceHit, wo: Vec3, nm: Option<f32>) -> (Bsdf<'s>, ShadingFrame, bool) {
    let m = &scene.materials[hit.material as usize];
    let tc = TexCoord::at(hit);
    let frame = m.shading_frame(&scene.textures, hit, wo);
    match nm.filter(|_| m.dispersion().is_some()) {
        Some(nm) => (scene.material_bsdf_at(hit.material, &tc, nm), frame, true),
        None => (m.bsdf(&scene.textures, &tc), frame, false),
    }
}

/// The BSDF of surface vertex `v` from its previous vertex toward unit
/// direction `wi`, with a normal map's factor and, on light subpaths, the
/// adjoint correction for shading normals; the geometry term's shading
/// cosine at `v` is applied by the caller.
fn vertex_f(v: &Vertex, wi_world: Vec3) -> Rgb {
    if let Some(phase) = &v.phase {
        return Rgb::splat(phase.eval(v.wo, wi_world));
    }
    let (Some(hit), Some((bsdf, frame))) = (&v.hit, &v.bsdf) else {
        return Rgb::ZERO;
    };
    let (wo, wi) = (frame.to_local(v.wo), frame.to_local(wi_world));
    // The geometric normal decides reflection or transmission.
    let front_o = hit.ng.dot(v.wo) > 0.0;
    let front_i = hit.ng.dot(wi_world) > 0.0;
    if (front_i == front_o) != (wi.z * wo.z > 0.0) || wi.z == 0.0 {
        return Rgb::ZERO;
    }
    match v.mode {
        TransportMode::Radiance => bsdf.eval(wo, wi, v.mode) * frame.factor(wi_world),
        TransportMode::Importance => {
            bsdf.eval(wo, wi, v.mode)
                * (frame.factor(v.wo) * adjoint_shading_factor(hit.ng, v.wo, wo.z, wi_world, wi.z))
        }
    }
}

/// The densities with which light `light` emits from point `p` of normal
/// `n` (zero for points and lights at infinity) in unit direction `w`
/// (where the light travels): per unit area of the point, and per solid
/// angle of the direction, as [`Light::sample_le`] draws them.
fn pdf_le(scene: &Scene, bounds: (Vec3, f32), light: u32, p: Vec3, n: Vec3, w: Vec3) -> (f32, f32) {
    let disk = 1.0 / (PI * bounds.1 * bounds.1);
    match &scene.lights[light as usize] {
        Light::Point { .. } => (1.0, pdf_sphere_uniform()),
        Light::Spot {
            direction, cos_outer, ..
        } => (
            1.0,
            if direction.dot(w) >= *cos_outer {
                pdf_cone_uniform(*cos_outer)
            } else {
                0.0
            },
        ),
        Light::Projector(proj) => (1.0, proj.pdf_emission(w)),
        Light::Goniometric(g) => (1.0, g.pdf_emission(w)),
        Light::Directional { .. } => (disk, 1.0),
        // A distance function or an implicit surface: its light subpaths
        // start on lines drawn through it, at a density per unit area that
        // is the line's rather than the point's but uniform by area on
        // average ([`crate::light::sample_on_lines`]); MIS weighs its
        // points by that average, 1/A (A its area by Crofton's formula),
        // which keeps every strategy's weights a function of the path
        // alone, so that they still sum to one, while each contribution is
        // divided by the density its sample actually had.
        Light::Area {
            cone: Some(_),
            area,
            two_sided,
            ..
        } => {
            let cos = crate::light::emitting_cosine(n, w, *two_sided);
            let sides = if *two_sided { 2.0 } else { 1.0 };
            (
                if area.total > 0.0 { 1.0 / area.total } else { 0.0 },
                if cos > 0.0 { cos / (sides * PI) } else { 0.0 },
            )
        }
        Light::Area {
            emitter,
            area,
            two_sided,
            ..
        } => {
            let cos = crate::light::emitting_cosine(n, w, *two_sided);
            let sides = if *two_sided { 2.0 } else { 1.0 };
            (
                scene.geometry.emitter_pdf_area(*emitter, area, p, n),
                if cos > 0.0 { cos / (sides * PI) } else { 0.0 },
            )
        }
        Light::Environment => (disk, scene.background.pdf(-w)),
    }
}

/// The longest paths, in segments, whose strategies get images of their
/// own ([`crate::settings::RenderSettings::bdpt_strategies`]): two images
/// for each of the 19 strategies up to 5 segments, as many as memory
/// comfortably holds at film sizes.
pub const MAX_STRATEGY_SEGMENTS: u32 = 5;

/// The index of strategy (s, t), a path of k = s + t − 1 segments, among
/// those with their own image, in order of k then s: one for k = 1 ((0, 2);
/// (1, 1) is not used), k + 1 for each longer k.
fn strategy_index(s: usize, t: usize) -> usize {
    let k = s + t - 1;
    if k == 1 { 0 } else { (k - 1) * (k + 2) / 2 - 1 + s }
}

/// The bidirectional path tracer: its settings and the image of its
/// iterations (and of each strategy's, when asked for).
pub struct Bdpt {
    max_depth: u32,
    image: SplatImage,
    /// Per strategy up to [`MAX_STRATEGY_SEGMENTS`] (`strategy_index`),
    /// the sums of its weighted and of its unweighted contributions.
    strategies: Option<Vec<[Vec<DVec3>; 2]>>,
}

impl Bdpt {
    /// Nothing traced yet; `aovs` asks for the auxiliary sums.
    pub fn new(scene: &Scene, aovs: bool) -> Bdpt {
        let s = &scene.settings;
        let pixels = s.width as usize * s.height as usize;
        let longest = s.max_depth.min(MAX_STRATEGY_SEGMENTS) as usize;
        Bdpt {
            max_depth: s.max_depth,
            image: SplatImage::new(scene, aovs),
            strategies: (s.bdpt_strategies && longest > 0).then(|| {
                let count = strategy_index(0, longest + 2);
                (0..count)
                    .map(|_| [vec![DVec3::ZERO; pixels], vec![DVec3::ZERO; pixels]])
                    .collect()
            }),
        }
    }
}

impl Progressive for Bdpt {
    /// One camera subpath and one light subpath per pixel.
    fn iterate(&mut self, scene: &Scene, cancel: Option<&AtomicBool>) -> Option<Work> {
        let tracer = Tracer::new(scene, self.max_depth);
        let width = scene.settings.width;
        let per_strategy = self.strategies.is_some();
        let strategies = &mut self.strategies;
        let rays = self.image.iterate(
            scene,
            STREAM,
            cancel,
            |i, rng, target, work: &mut Subpaths, out, rays| {
                let (x, y) = (i % width, i / width);
                let raster = Vec2::new(x as f32 + rng.next_f32(), y as f32 + rng.next_f32());
                // Contributions at the camera sample's raster position are
                // summed into one splat.
                let mut sum = Rgb::ZERO;
                tracer.sample(raster, rng, work, rays, |s, t, at, l, unweighted| {
                    match at {
                        Some(r) => target.add_splat(r, l, &mut out.image),
                        None => sum += l,
                    }
                    if per_strategy && s + t - 1 <= MAX_STRATEGY_SEGMENTS as usize {
                        let image = 2 * strategy_index(s, t) as u32;
                        let at = at.unwrap_or(raster);
                        target.splat_with(at, l, |px, v| out.extra.push((image, px, v)));
                        target.splat_with(at, unweighted, |px, v| out.extra.push((image + 1, px, v)));
                    }
                });
                if sum != Rgb::ZERO {
                    target.add_splat(raster, sum, &mut out.image);
                }
            },
            &mut |image, px, l| {
                if let Some(s) = strategies.as_mut() {
                    s[image as usize / 2][image as usize % 2][px as usize] += l.as_dvec3();
                }
            },
        )?;
        Some(Work {
            rays,
            ..Work::default()
        })
    }

    fn film(&self) -> Film {
        self.image.film()
    }

    /// Each strategy's image up to [`MAX_STRATEGY_SEGMENTS`], weighted
    /// and unweighted, named as pbrt-v4 names them
    /// (`bdpt_d{bounces}_s{s}_t{t}`, `…_unweighted`): the weighted images
    /// of all strategies sum to the image (for paths of that length); the
    /// unweighted images of one path length each estimate the light of
    /// those paths, by one strategy alone.
    fn extra_images(&self) -> Vec<(String, Film)> {
        let Some(strategies) = &self.strategies else {
            return Vec::new();
        };
        let mut out = Vec::new();
        let longest = self.max_depth.min(MAX_STRATEGY_SEGMENTS) as usize;
        for k in 1..=longest {
            for s in 0..=k {
                let t = k + 1 - s;
                if s == 1 && t == 1 {
                    continue;
                }
                let [weighted, unweighted] = &strategies[strategy_index(s, t)];
                let name = format!("bdpt_d{:02}_s{s:02}_t{t:02}", k - 1);
                out.push((name.clone(), self.image.film_of(weighted)));
                out.push((format!("{name}_unweighted"), self.image.film_of(unweighted)));
            }
        }
        out
    }

    /// The image's sums and, when recorded, each strategy's.
    fn state(&self) -> Vec<u8> {
        let mut w = StateWriter::default();
        self.image.write_state(&mut w);
        let strategies = self.strategies.as_deref().unwrap_or_default();
        w.u64(strategies.len() as u64);
        for pair in strategies {
            for image in pair {
                w.dvec3s(image);
            }
        }
        w.0
    }

    fn restore(&mut self, _scene: &Scene, state: &[u8]) -> Result<(), String> {
        let mut r = StateReader::new(state);
        self.image.read_state(&mut r)?;
        let count = self.strategies.as_ref().map_or(0, Vec::len);
        if r.count(16)? != count {
            return Err("the saved state and the render disagree on the strategies' images".into());
        }
        if let Some(strategies) = &mut self.strategies {
            for pair in strategies.iter_mut() {
                for image in pair.iter_mut() {
                    let n = image.len();
                    *image = r.dvec3s(n)?;
                }
            }
        }
        r.finish()
    }
}

/// The two subpaths of a sample.
#[derive(Default)]
pub(crate) struct Subpaths<'s> {
    camera: Vec<Vertex<'s>>,
    light: Vec<Vertex<'s>>,
    /// The light subpath's vertices kept for merging (vertex connection
    /// and merging).
    stored: Vec<vcm::LightVertex>,
    /// Light the camera subpath's flights gathered from emitting media:
    /// (t, light) for the strategy (0, t) whose last segment it lay on.
    glow: Vec<(usize, Rgb)>,
    /// The sample's wavelength, where the scene disperses light.
    wavelength: Option<WavelengthSample>,
}

/// What [`Tracer::mis_weight`] changes in the subpaths, to be put back.
struct Saved<'s> {
    /// (index, pdf_rev, delta) of the vertices whose values change.
    light_changed: [Option<(usize, f32, bool)>; 2],
    camera_changed: [Option<(usize, f32, bool)>; 2],
    /// The first vertex of the light (true) or camera subpath, which the
    /// strategy's sampled vertex replaced.
    replaced: Option<(bool, Vertex<'s>)>,
    /// Whether the sampled light vertex was pushed onto an empty subpath.
    pushed: bool,
}

impl<'s> Saved<'s> {
    fn restore(self, light: &mut Vec<Vertex<'s>>, camera: &mut [Vertex<'s>]) {
        for (i, pdf_rev, delta) in self.light_changed.into_iter().flatten() {
            (light[i].pdf_rev, light[i].delta) = (pdf_rev, delta);
        }
        for (i, pdf_rev, delta) in self.camera_changed.into_iter().flatten() {
            (camera[i].pdf_rev, camera[i].delta) = (pdf_rev, delta);
        }
        match self.replaced {
            Some((true, v)) => light[0] = v,
            Some((false, v)) => camera[0] = v,
            None => {}
        }
        if self.pushed {
            light.pop();
        }
    }
}

/// What a sample needs of the scene.
pub(crate) struct Tracer<'s> {
    scene: &'s Scene,
    bounds: (Vec3, f32),
    max_depth: u32,
    /// Vertex merging's factor η = π r² N (Georgiev et al. 2012, eq. 11:
    /// the density of merging at a vertex is that of reaching it from
    /// both sides times η, for N light paths merged within radius r);
    /// zero where paths are only connected (BDPT, MLT).
    merge_eta: f32,
    /// Whether the sample's wavelength is the first number of its light
    /// subpath's stream (vertex connection and merging, whose light
    /// subpaths are traced again without their camera subpaths when a
    /// render resumes) rather than of the camera's.
    wavelength_from_light: bool,
    /// Whether subpaths and connections go through participating media
    /// (the scene has some; VCM merges on surfaces only).
    media: bool,
    /// The medium of what lies outside every surface that bounds a medium,
    /// where lights at infinity shine from (see [`outer_medium`]).
    outer_medium: Option<u32>,
}

impl<'s> Tracer<'s> {
    /// The subpaths and connections of the scene for `max_depth` segments.
    pub(crate) fn new(scene: &'s Scene, max_depth: u32) -> Tracer<'s> {
        let media = !scene.media.is_empty();
        Tracer {
            scene,
            bounds: crate::light::scene_bounding_sphere(scene),
            max_depth,
            merge_eta: 0.0,
            wavelength_from_light: false,
            media,
            outer_medium: if media { outer_medium(scene) } else { None },
        }
    }

    /// The tracer of vertex connection and merging: the weights count
    /// merging at every vertex where it can happen, with factor `eta`
    /// (π r² times the light paths merged).
    pub(crate) fn merging(mut self, eta: f32) -> Tracer<'s> {
        self.merge_eta = eta;
        self.wavelength_from_light = true;
        self
    }

    /// The sample through raster position `raster` (drawn from `rng`'s
    /// camera stream): both subpaths, then every strategy (s, t), each
    /// contribution handed to `each(s, t, at, weighted, unweighted)`, `at`
    /// the raster position it lands on where that is not `raster`
    /// (t = 1).
    // Out of line: inlined into the iteration's per-pixel closure, the
    // whole sample made that closure slower (measured in the commit).
    #[inline(never)]
    pub(crate) fn sample<R: Uniforms>(
        &self,
        raster: Vec2,
        rng: &mut R,
        work: &mut Subpaths<'s>,
        rays: &mut u64,
        mut each: impl FnMut(usize, usize, Option<Vec2>, Rgb, Rgb),
    ) {
        let scene = self.scene;
        let u_lens = Vec2::new(rng.next_f32(), rng.next_f32());
        let time = scene.camera.time_from(|| rng.next_f32());
        let wavelength = if self.wavelength_from_light {
            rng.start_stream(LIGHT_STREAM);
            let w = self.draw_wavelength(rng);
            rng.start_stream(CAMERA_STREAM);
            w
        } else {
            self.draw_wavelength(rng)
        };
        work.wavelength = wavelength;
        let nm = wavelength.map(|w| w.nm);
        let camera_vertices = self.max_depth as usize + 1;
        work.glow.clear();
        self.camera_subpath(
            raster,
            u_lens,
            time,
            camera_vertices,
            rng,
            &mut work.camera,
            Some(&mut work.glow),
            rays,
            nm,
        );
        rng.start_stream(LIGHT_STREAM);
        let light_vertices = if self.max_depth < 2 { 0 } else { self.max_depth as usize };
        self.light_subpath(rng, time, light_vertices, &mut work.light, rays, nm);
        rng.start_stream(CONNECTION_STREAM);
        let (nc, nl) = (work.camera.len(), work.light.len());
        // Emission of media, found only by the camera's flights: weight 1.
        for &(t, l) in &work.glow {
            let l = l * Self::spectral(wavelength, work, 0, t);
            if l.is_finite() && l != Rgb::ZERO {
                each(0, t, None, l, l);
            }
        }
        for t in 1..=nc {
            // s = 1 samples its own light vertex: it needs none from the
            // light subpath.
            for s in 0..=nl.max(1) {
                let segments = s + t - 1;
                if (s == 1 && t == 1) || segments == 0 || segments > self.max_depth as usize {
                    continue;
                }
                if !scene.settings.shows_emission(segments as u32) && s + t == 2 {
                    continue;
                }
                if let Some((unweighted, w, at)) = self.connect(s, t, work, rng, rays) {
                    let unweighted = unweighted * Self::spectral(wavelength, work, s, t);
                    let l = unweighted * w;
                    if l.is_finite() && l != Rgb::ZERO {
                        each(s, t, at, l, unweighted);
                    }
                }
            }
        }
    }

    /// Strategy (s, t) alone, for paths of `segments` segments (s + t =
    /// segments + 1), as multiplexed Metropolis light transport draws it
    /// (Hachisuka et al. 2014): the camera subpath of exactly t vertices
    /// through a raster position drawn over the whole image, the light
    /// subpath of exactly s, the connection. The first number of the
    /// camera stream chooses the strategy among the `segments + 1`
    /// (uniformly, so the contribution is multiplied by their number);
    /// paths of one segment (an emitter seen directly) have only (0, 2).
    /// The raster position where the contribution lands, and the
    /// contribution; `None` where the strategy makes no path.
    pub(crate) fn strategy<R: Uniforms>(
        &self,
        segments: usize,
        rng: &mut R,
        work: &mut Subpaths<'s>,
        rays: &mut u64,
    ) -> Option<(Vec2, Rgb)> {
        let scene = self.scene;
        rng.start_stream(CAMERA_STREAM);
        let (s, t, strategies) = if segments <= 1 {
            (0, 2, 1)
        } else {
            let n = segments + 1;
            let s = ((rng.next_f32() * n as f32) as usize).min(n - 1);
            (s, n - s, n)
        };
        let (width, height) = (scene.settings.width as f32, scene.settings.height as f32);
        let raster = Vec2::new(rng.next_f32() * width, rng.next_f32() * height);
        let u_lens = Vec2::new(rng.next_f32(), rng.next_f32());
        let time = scene.camera.time_from(|| rng.next_f32());
        let wavelength = self.draw_wavelength(rng);
        let nm = wavelength.map(|w| w.nm);
        work.glow.clear();
        self.camera_subpath(
            raster,
            u_lens,
            time,
            t,
            rng,
            &mut work.camera,
            Some(&mut work.glow),
            rays,
            nm,
        );
        // Emission of media on the camera subpath's last segment is this
        // length's (0, t) too.
        let glow: Rgb = if s == 0 {
            let l: Rgb = work.glow.iter().filter(|(g, _)| *g == t).map(|(_, l)| *l).sum();
            l * Self::spectral(wavelength, work, 0, t)
        } else {
            Rgb::ZERO
        };
        if work.camera.len() != t {
            let l = glow * strategies as f32;
            return (l.is_finite() && l != Rgb::ZERO).then_some((raster, l));
        }
        rng.start_stream(LIGHT_STREAM);
        self.light_subpath(rng, time, if s >= 2 { s } else { 0 }, &mut work.light, rays, nm);
        if s >= 2 && work.light.len() != s {
            return None;
        }
        rng.start_stream(CONNECTION_STREAM);
        if segments <= 1 && !scene.settings.shows_emission(1) {
            return None;
        }
        let (l, at) = match self.connect(s, t, work, rng, rays) {
            Some((unweighted, w, at)) => (unweighted * Self::spectral(wavelength, work, s, t) * w + glow, at),
            None => (glow, None),
        };
        let l = l * strategies as f32;
        (l.is_finite() && l != Rgb::ZERO).then(|| (at.unwrap_or(raster), l))
    }

    /// One wavelength for both subpaths of a sample, where the scene has a
    /// dispersive glass (pbrt-v4 samples a spectral path's wavelengths
    /// once for both subpaths). A merge joins a camera subpath with a
    /// light vertex of another sample, each weighted by its own
    /// wavelength where it disperses, as photon mapping joins them.
    pub(super) fn draw_wavelength<R: Uniforms>(&self, rng: &mut R) -> Option<WavelengthSample> {
        self.scene
            .any_dispersive
            .then(|| crate::color::spectrum::sample_visible_wavelength(rng.next_f32()))
    }

    /// The weight of the sample's wavelength for the path that strategy
    /// (s, t) makes of the first s light and t camera vertices: its
    /// [`WavelengthSample::weight`] where one of them disperses, 1
    /// elsewhere (such a path does not depend on the wavelength).
    fn spectral(wavelength: Option<WavelengthSample>, work: &Subpaths, s: usize, t: usize) -> Rgb {
        let Some(w) = wavelength else {
            return Rgb::ONE;
        };
        let light = &work.light[..s.min(work.light.len())];
        let camera = &work.camera[..t.min(work.camera.len())];
        if light.iter().chain(camera).any(|v| v.disperses) {
            w.weight
        } else {
            Rgb::ONE
        }
    }

    /// The camera subpath through raster position `raster`, traced at `time`.
    #[allow(clippy::too_many_arguments)]
    fn camera_subpath<R: Uniforms>(
        &self,
        raster: Vec2,
        u_lens: Vec2,
        time: f32,
        max_vertices: usize,
        rng: &mut R,
        path: &mut Vec<Vertex<'s>>,
        glow: Option<&mut Vec<(usize, Rgb)>>,
        rays: &mut u64,
        nm: Option<f32>,
    ) {
        path.clear();
        let camera = &self.scene.camera;
        let ray = camera.moved(camera.generate_ray(raster, u_lens).at_time(time));
        let lens = camera.lens_point(&ray);
        let mut endpoint = Vertex::endpoint(Kind::Camera, lens, Vec3::ZERO, Rgb::ONE, 1.0);
        endpoint.time = time;
        endpoint.medium = if self.media { self.scene.camera_medium } else { None };
        let medium = endpoint.medium;
        path.push(endpoint);
        let pdf_dir = camera.pdf_dir_at(ray.dir, time);
        self.walk(
            ray,
            Rgb::ONE,
            pdf_dir,
            medium,
            TransportMode::Radiance,
            max_vertices,
            rng,
            path,
            glow,
            rays,
            nm,
        );
    }

    /// The light subpath of up to `max_vertices` vertices: a light chosen
    /// by power, a point and direction on it ([`Light::sample_le`]), then
    /// the walk, traced at `time`.
    #[allow(clippy::too_many_arguments)]
    fn light_subpath<R: Uniforms>(
        &self,
        rng: &mut R,
        time: f32,
        max_vertices: usize,
        path: &mut Vec<Vertex<'s>>,
        rays: &mut u64,
        nm: Option<f32>,
    ) {
        path.clear();
        let scene = self.scene;
        if scene.lights.is_empty() || scene.light_distribution.is_empty() || max_vertices == 0 {
            return;
        }
        let Some((emitted, light, pmf)) =
            crate::light::sample_scene_emission(scene, &scene.light_distribution, self.bounds, rng)
        else {
            return;
        };
        let light = light as u32;
        let w = emitted.ray.dir;
        let beta = emitted.weight / pmf;
        let infinite = matches!(
            scene.lights[light as usize],
            Light::Environment | Light::Directional { .. }
        );
        let delta = scene.lights[light as usize].is_delta();
        let kind = Kind::Light { light, infinite, delta };
        let (p, n) = match (&emitted.surface, infinite) {
            (Some(point), _) => (point.p, point.n),
            (None, true) => (-w, Vec3::ZERO),
            (None, false) => (emitted.ray.origin, Vec3::ZERO),
        };
        let (pdf_pos, pdf_dir) = pdf_le(scene, self.bounds, light, p, n, w);
        let mut start = Vertex::endpoint(kind, p, n, Rgb::ZERO, pmf * pdf_pos);
        start.mode = TransportMode::Importance;
        start.time = time;
        if infinite {
            start.pdf_fwd = self.pdf_light_origin(&start, &start);
        }
        if self.media {
            start.medium = if infinite {
                self.outer_medium
            } else {
                self.medium_around(emitted.ray.origin, w, time)
            };
            // Light from infinity does not cross a medium without end
            // (the camera's rays that leave through one find no sky
            // either).
            if let Some(m) = start.medium.map(|m| &scene.media[m as usize]) {
                if infinite && m.bounds.is_none() && m.majorant().max_element() > 0.0 {
                    return;
                }
            }
        }
        let medium = start.medium;
        path.push(start);
        self.walk(
            emitted.ray.at_time(time),
            beta,
            pdf_dir,
            medium,
            TransportMode::Importance,
            max_vertices,
            rng,
            path,
            None,
            rays,
            nm,
        );
        // The first surface of a path from infinity was found by a point
        // on the disk the light shines from.
        if infinite && path.len() > 1 {
            let cos = if path[1].on_surface() {
                path[1].ng.dot(w).abs()
            } else {
                1.0
            };
            path[1].pdf_fwd = pdf_pos * cos;
        }
    }

    /// Strategy (s, t) of the sample's subpaths: the unweighted
    /// contribution, its weight, and for t = 1 the raster position it
    /// lands on; `None` where the strategy makes no path.
    fn connect<R: Uniforms>(
        &self,
        s: usize,
        t: usize,
        work: &mut Subpaths<'s>,
        rng: &mut R,
        rays: &mut u64,
    ) -> Option<(Rgb, f32, Option<Vec2>)> {
        let scene = self.scene;
        let mut sampled = None;
        let mut raster = None;
        let l = if s == 0 {
            let pt = &work.camera[t - 1];
            match pt.kind {
                Kind::Light { infinite: true, .. } => pt.beta * scene.background.eval(pt.p),
                Kind::Surface => {
                    let hit = pt.hit.as_ref()?;
                    let m = &scene.materials[hit.material as usize];
                    if !(m.is_emissive() && m.emits_toward(hit, pt.wo)) {
                        return None;
                    }
                    pt.beta * m.emission_at(&scene.textures, &TexCoord::at(hit))
                }
                _ => return None,
            }
        } else if t == 1 {
            let qs = &work.light[s - 1];
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            if !qs.connectible || !matches!(qs.kind, Kind::Surface | Kind::Medium) {
                return None;
            }
            let c = scene.camera.sample_wi_at(qs.p, u, qs.time)?;
            let l = qs.beta * vertex_f(qs, c.wi) * (qs.cos_toward(c.wi) * c.weight);
            if l == Rgb::ZERO {
                return None;
            }
            *rays += 1;
            let tr = self.transmittance(qs, ShadowTarget::Point(qs.p + c.wi * c.dist), c.wi, rng);
            if tr == Rgb::ZERO {
                return None;
            }
            let mut camera = Vertex::endpoint(Kind::Camera, c.origin, Vec3::ZERO, Rgb::splat(c.weight), 0.0);
            camera.mode = TransportMode::Radiance;
            camera.time = qs.time;
            sampled = Some(camera);
            raster = Some(c.raster);
            l * tr
        } else if s == 1 {
            let pt = &work.camera[t - 1];
            let (u_light, u_pick) = (rng.next_f32(), rng.next_f32());
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            if !pt.connectible || !matches!(pt.kind, Kind::Surface | Kind::Medium) {
                return None;
            }
            let (vertex, wi, li, shadow) = self.sample_light_vertex(pt, u_light, u_pick, u, rng)?;
            let l = pt.beta * vertex_f(pt, wi) * li * pt.cos_toward(wi);
            if l == Rgb::ZERO {
                return None;
            }
            *rays += 1;
            let tr = self.transmittance(pt, shadow, wi, rng);
            if tr == Rgb::ZERO {
                return None;
            }
            sampled = Some(vertex);
            l * tr
        } else {
            let (qs, pt) = (&work.light[s - 1], &work.camera[t - 1]);
            let inner = |v: &Vertex| v.connectible && matches!(v.kind, Kind::Surface | Kind::Medium);
            if !inner(qs) || !inner(pt) {
                return None;
            }
            let (w, d2) = pt.toward(qs);
            let g = pt.cos_toward(w) * qs.cos_toward(w) / d2;
            let l = qs.beta * vertex_f(qs, -w) * vertex_f(pt, w) * pt.beta * g;
            if l == Rgb::ZERO || !l.is_finite() {
                return None;
            }
            *rays += 1;
            let end = qs.hit.as_ref().map_or(qs.p, |h| h.spawn_ray(-w).origin);
            let tr = self.transmittance(pt, ShadowTarget::Point(end), w, rng);
            if tr == Rgb::ZERO {
                return None;
            }
            l * tr
        };
        if l == Rgb::ZERO {
            return None;
        }
        Some((l, self.mis_weight(work, s, t, sampled), raster))
    }

    /// A light point for camera vertex `pt` (strategy s = 1): a light
    /// chosen by power as light subpaths choose it; an area light's point
    /// drawn as its emitted rays draw it (by area; a distance function's
    /// or an implicit surface's through a line, whose direction takes two
    /// more numbers from `rng`), the other lights' through
    /// [`Light::sample_li`]. The light vertex, the unit direction toward
    /// it, the light arriving along it over the densities, and the shadow
    /// ray's end.
    fn sample_light_vertex<R: Uniforms>(
        &self,
        pt: &Vertex,
        u_light: f32,
        u_pick: f32,
        u: Vec2,
        rng: &mut R,
    ) -> Option<(Vertex<'s>, Vec3, Rgb, ShadowTarget)> {
        let scene = self.scene;
        if scene.light_distribution.is_empty() {
            return None;
        }
        let (index, pmf, _) = scene.light_distribution.sample(u_light);
        if pmf <= 0.0 {
            return None;
        }
        let light = &scene.lights[index];
        let infinite = matches!(light, Light::Environment | Light::Directional { .. });
        let kind = Kind::Light {
            light: index as u32,
            infinite,
            delta: light.is_delta(),
        };
        let (mut vertex, wi, li, target) = match light {
            Light::Area {
                emitter,
                area,
                radiance,
                two_sided,
                cone,
                ..
            } => {
                let (p, n, uv, pdf_area) = match (cone, emitter) {
                    (Some(sphere), EmitterRef::Shape(i)) => {
                        let u_dir = Vec2::new(rng.next_f32(), rng.next_f32());
                        let (hit, pdf_area, _) = crate::light::sample_on_lines(
                            &scene.geometry,
                            *i,
                            *sphere,
                            u_pick,
                            (u, u_dir),
                            radiance.reads_uv(),
                        )?;
                        (hit.p, hit.ng, (hit.uv, hit.attribute), pdf_area)
                    }
                    _ => {
                        let es = scene
                            .geometry
                            .sample_emitter(*emitter, area, u_pick, u, radiance.reads_uv())?;
                        (es.p, es.n, (es.uv, es.attribute), es.pdf_area)
                    }
                };
                let d = pt.p - p;
                let d2 = d.length_squared();
                let cos = crate::light::emitting_cosine(n, d, *two_sided) / d2.sqrt();
                if !(cos > 0.0 && pdf_area > 0.0 && d2 > 0.0) {
                    return None;
                }
                let (uv, attribute) = uv;
                let le = radiance.eval(&scene.textures, &TexCoord::new(uv, p).with_attribute(attribute));
                let vertex = Vertex::endpoint(kind, p, n, le / (pmf * pdf_area), 0.0);
                (
                    vertex,
                    -d / d2.sqrt(),
                    le * (cos / (pmf * pdf_area * d2)),
                    ShadowTarget::Point(p),
                )
            }
            _ => {
                let ls = match light {
                    // The densities BDPT weighs an environment vertex with
                    // are its emission's, which a portal does not window:
                    // its connections are drawn the same way (for other
                    // backgrounds the two are one).
                    Light::Environment => {
                        let (wi, pdf) = scene.background.sample(u)?;
                        crate::light::LightSample {
                            wi,
                            li: scene.background.eval(wi),
                            pdf,
                            is_delta: false,
                            target: ShadowTarget::Infinity,
                        }
                    }
                    _ => light.sample_li(scene, pt.p, u_pick, u, false)?,
                };
                if ls.pdf <= 0.0 {
                    return None;
                }
                let li = ls.li / (ls.pdf * pmf);
                let p = match (infinite, ls.target) {
                    (true, _) => ls.wi,
                    (false, ShadowTarget::Point(p)) => p,
                    (false, ShadowTarget::Infinity) => return None,
                };
                (Vertex::endpoint(kind, p, Vec3::ZERO, li, 0.0), ls.wi, li, ls.target)
            }
        };
        vertex.mode = TransportMode::Importance;
        vertex.pdf_fwd = self.pdf_light_origin(&vertex, pt);
        Some((vertex, wi, li, target))
    }

    /// The power heuristic's weight of strategy (s, t) among all the
    /// strategies that make its path (pbrt-v4's `MISWeight`, with the
    /// ratios squared): each vertex's densities from the two sides are
    /// updated for this connection, then the ratios of the path's density
    /// under each other strategy to this one's are accumulated outward
    /// from the connection. `sampled` is the vertex strategy s = 1 or
    /// t = 1 drew in place of its subpath's first.
    fn mis_weight(&self, work: &mut Subpaths<'s>, s: usize, t: usize, sampled: Option<Vertex<'s>>) -> f32 {
        if s + t == 2 {
            return 1.0;
        }
        let (light, camera) = (&mut work.light, &mut work.camera);
        // What this strategy changes, to be put back.
        let pushed = s == 1 && light.is_empty();
        if pushed {
            light.push(sampled.expect("s = 1 samples its light vertex"));
        }
        // The densities and delta flags this strategy changes, and the
        // subpath endpoint its sampled vertex stands in for.
        let light_changed =
            [s.checked_sub(1), s.checked_sub(2)].map(|i| i.map(|i| (i, light[i].pdf_rev, light[i].delta)));
        let camera_changed =
            [t.checked_sub(1), t.checked_sub(2)].map(|i| i.map(|i| (i, camera[i].pdf_rev, camera[i].delta)));
        let mut replaced = None;
        if let Some(v) = sampled {
            if s == 1 {
                replaced = Some((true, std::mem::replace(&mut light[0], v)));
            } else if t == 1 {
                replaced = Some((false, std::mem::replace(&mut camera[0], v)));
            }
        }
        let saved = Saved {
            light_changed,
            camera_changed,
            replaced,
            pushed,
        };
        // An emitter reached by the camera subpath, as a light vertex.
        let pt_light = if s == 0 { self.as_light(&camera[t - 1]) } else { None };
        if s == 0 && pt_light.is_none() {
            // Emission that no light samples: no other strategy finds it.
            saved.restore(light, camera);
            return 1.0;
        }
        camera[t - 1].delta = false;
        if s > 0 {
            light[s - 1].delta = false;
        }
        camera[t - 1].pdf_rev = if s > 0 {
            self.pdf(&light[s - 1], s.checked_sub(2).map(|i| &light[i]), &camera[t - 1])
        } else {
            self.pdf_light_origin(pt_light.as_ref().unwrap_or(&camera[t - 1]), &camera[t - 2])
        };
        if t >= 2 {
            camera[t - 2].pdf_rev = match (&pt_light, s) {
                (Some(l), 0) => self.pdf_light(l, &camera[t - 2]),
                _ => self.pdf(&camera[t - 1], Some(&light[s - 1]), &camera[t - 2]),
            };
        }
        if s > 0 {
            light[s - 1].pdf_rev = self.pdf(&camera[t - 1], t.checked_sub(2).map(|i| &camera[i]), &light[s - 1]);
        }
        if s >= 2 {
            light[s - 2].pdf_rev = self.pdf(&light[s - 1], Some(&camera[t - 1]), &light[s - 2]);
        }
        let eta = self.merge_eta;
        let mut sum = 0.0f32;
        let mut ratio = 1.0f32;
        for i in (1..t).rev() {
            ratio *= remap(camera[i].pdf_rev) / remap(camera[i].pdf_fwd);
            if !camera[i].delta && !camera[i - 1].delta {
                sum += ratio * ratio;
            }
            // Merging at a surface vertex (not at the emitter an s = 0
            // path ends on).
            if eta > 0.0 && camera[i].merges() && !(s == 0 && i == t - 1) {
                sum += sq(ratio * remap(camera[i].pdf_fwd) * eta);
            }
        }
        ratio = 1.0;
        for i in (0..s).rev() {
            ratio *= remap(light[i].pdf_rev) / remap(light[i].pdf_fwd);
            if !light[i].delta && !delta_before(light, i) {
                sum += ratio * ratio;
            }
            if eta > 0.0 && i > 0 && light[i].merges() {
                sum += sq(ratio * remap(light[i].pdf_fwd) * eta);
            }
        }
        saved.restore(light, camera);
        let w = 1.0 / (1.0 + sum);
        if w.is_finite() { w } else { 0.0 }
    }

    /// Camera vertex `v` on an emitter, as the light vertex a light
    /// subpath would have started there; `None` where no light is there,
    /// or none that light subpaths start from (an emitter sampled by
    /// direction only: no other strategy makes the path).
    fn as_light(&self, v: &Vertex<'s>) -> Option<Vertex<'s>> {
        match v.kind {
            Kind::Light { .. } => Some(*v),
            Kind::Surface => {
                let hit = v.hit.as_ref()?;
                let light = hit.light?;
                let kind = Kind::Light {
                    light,
                    infinite: false,
                    delta: false,
                };
                let mut l = Vertex::endpoint(kind, v.p, hit.ng, v.beta, v.pdf_fwd);
                l.pdf_rev = v.pdf_rev;
                Some(l)
            }
            Kind::Camera | Kind::Medium => None,
        }
    }

    /// Extends `path` from its last vertex along `ray`, which starts in
    /// `medium`, until it has `max_vertices` vertices or ends; `pdf_dir`
    /// is the density of `ray`'s direction at the last vertex. With
    /// `glow`, the light of emitting media along the flights is added to it
    /// per strategy (0, t).
    #[allow(clippy::too_many_arguments)]
    fn walk<R: Uniforms>(
        &self,
        mut ray: Ray,
        mut beta: Rgb,
        mut pdf_dir: f32,
        mut medium: Option<u32>,
        mode: TransportMode,
        max_vertices: usize,
        rng: &mut R,
        path: &mut Vec<Vertex<'s>>,
        mut glow: Option<&mut Vec<(usize, Rgb)>>,
        rays: &mut u64,
        nm: Option<f32>,
    ) {
        let scene = self.scene;
        let mut crossings = 0;
        while path.len() < max_vertices {
            *rays += 1;
            let hit = scene.intersect(&ray);
            if let (true, Some(mi)) = (self.media, medium) {
                let t_end = hit.as_ref().map_or(ray.t_max, |h| h.t);
                // The segment makes paths of as many segments as there
                // are vertices.
                let segments = path.len();
                let gathers = glow.is_some()
                    && segments <= self.max_depth as usize
                    && scene.settings.shows_emission(segments as u32);
                let mut light = Rgb::ZERO;
                let flight = self.fly(mi, &ray, t_end, &mut beta, gathers.then_some(&mut light), rng);
                if let (Some(glow), true) = (glow.as_deref_mut(), light != Rgb::ZERO) {
                    glow.push((segments + 1, light));
                }
                match flight {
                    Flight::Crossed => {}
                    Flight::Ended => return,
                    Flight::Scattered(p) => {
                        if beta == Rgb::ZERO || !beta.is_finite() {
                            return;
                        }
                        let phase = scene.media[mi as usize].phase;
                        let wo = -ray.dir.normalize();
                        let prev = path.len() - 1;
                        let mut v = Vertex::endpoint(Kind::Medium, p, Vec3::ZERO, beta, 0.0);
                        (v.wo, v.mode, v.time, v.medium, v.phase) = (wo, mode, ray.time, medium, Some(phase));
                        v.pdf_fwd = self.convert(pdf_dir, &path[prev], &v);
                        path.push(v);
                        if path.len() >= max_vertices {
                            return;
                        }
                        // Phase functions are sampled exactly: the weight is 1.
                        let ps = phase.sample(wo, Vec2::new(rng.next_f32(), rng.next_f32()));
                        if ps.pdf.is_nan() || ps.pdf <= 0.0 {
                            return;
                        }
                        pdf_dir = ps.pdf;
                        let this = path.len() - 1;
                        path[prev].pdf_rev = self.convert(phase.eval(ps.wi, wo), &path[this], &path[prev]);
                        ray = Ray::new(p, ps.wi).at_time(ray.time);
                        continue;
                    }
                }
            }
            let Some(mut hit) = hit else {
                // A camera subpath that leaves the scene meets the
                // environment, as a vertex on a light at infinity.
                if mode == TransportMode::Radiance {
                    if let Some(env) = scene.environment_light {
                        let kind = Kind::Light {
                            light: env,
                            infinite: true,
                            delta: false,
                        };
                        path.push(Vertex::endpoint(kind, ray.dir.normalize(), Vec3::ZERO, beta, pdf_dir));
                    }
                }
                return;
            };
            scene.choose_any_material(&mut hit, ray.dir);
            let m = &scene.materials[hit.material as usize];
            let tc = TexCoord::at(&hit);
            // A mask's cut-out part lets the path through unchanged, as the
            // path tracer's and the light tracer's paths pass it; among
            // media so does a surface that is not there (a medium's
            // boundary), as the volumetric path tracer's paths pass it.
            if m.cut_out(&scene.textures, &tc, || rng.next_f32()) || (self.media && is_null(m)) {
                if self.media {
                    crossings += 1;
                    if crossings > MAX_CROSSINGS {
                        return;
                    }
                    if let Some(interface) = scene.material_media[hit.material as usize] {
                        medium = interface.toward(ray.dir, hit.ng);
                    }
                }
                ray = hit.spawn_ray(ray.dir);
                continue;
            }
            let wo_world = -ray.dir.normalize();
            let ng_wo = hit.ng.dot(wo_world);
            let (bsdf, frame, disperses) = surface_bsdf(scene, &hit, wo_world, nm);
            if ng_wo == 0.0 || (!m.two_sided && !bsdf.transmits() && !hit.is_front(wo_world)) {
                return; // the back of a one-sided surface is black
            }
            let prev = path.len() - 1;
            let interface = scene.material_media[hit.material as usize];
            let mut v = Vertex {
                kind: Kind::Surface,
                p: hit.p,
                ng: hit.ng,
                ns: frame.n,
                beta,
                delta: false,
                connectible: bsdf.has_smooth(),
                pdf_fwd: 0.0,
                pdf_rev: 0.0,
                time: hit.time,
                hit: Some(hit),
                bsdf: Some((bsdf, frame)),
                wo: wo_world,
                mode,
                medium,
                phase: None,
                disperses,
            };
            v.pdf_fwd = self.convert(pdf_dir, &path[prev], &v);
            path.push(v);
            if path.len() >= max_vertices {
                return;
            }
            let wo = frame.to_local(wo_world);
            let (u_lobe, u) = (rng.next_f32(), Vec2::new(rng.next_f32(), rng.next_f32()));
            let Some(bs) = bsdf.sample(wo, u_lobe, u, mode) else {
                return;
            };
            if bs.pdf <= 0.0 || bs.f == Rgb::ZERO || bs.wi.z == 0.0 || wo.z == 0.0 {
                return;
            }
            let wi_world = frame.to_world(bs.wi);
            let reflection = bs.wi.z * wo.z > 0.0;
            if (hit.ng.dot(wi_world) > 0.0) != ((ng_wo > 0.0) == reflection) {
                return; // the shading normal sent the path through the surface
            }
            let factor = match mode {
                TransportMode::Radiance => frame.factor(wi_world),
                TransportMode::Importance => {
                    frame.factor(wo_world) * adjoint_shading_factor(hit.ng, wo_world, wo.z, wi_world, bs.wi.z)
                }
            };
            beta *= bs.f * (factor * bs.wi.z.abs() / bs.pdf);
            if beta == Rgb::ZERO || !beta.is_finite() {
                return;
            }
            let this = path.len() - 1;
            if bs.delta {
                // A Dirac density, taken as one per unit solid angle, so
                // that its conversion to area (cos/d² at the vertex it
                // reaches) still enters the ratios, as Georgiev's
                // implementation of VCM counts it; taken as one per unit
                // area (pbrt-v4's remap of a zero), every path through a
                // delta vertex is weighed without the geometry of the
                // segment beyond it.
                path[this].delta = true;
                pdf_dir = 1.0;
                path[prev].pdf_rev = self.convert(1.0, &path[this], &path[prev]);
            } else {
                pdf_dir = bs.pdf;
                let pdf_back = bsdf.pdf(bs.wi, wo);
                path[prev].pdf_rev = self.convert(pdf_back, &path[this], &path[prev]);
            }
            if let (true, Some(interface)) = (self.media, interface) {
                medium = interface.toward(wi_world, hit.ng);
            }
            ray = hit.spawn_ray(wi_world);
        }
    }

    /// A free flight along `ray` up to its parameter `t_end` in medium
    /// `medium`, by spectral tracking (Kutz et al. 2017) against one grey
    /// majorant σ̄ (the largest channel's), so that the tentative
    /// collisions have one density in every channel: at each, the path
    /// scatters or goes on (a null collision) with probabilities P in
    /// proportion to the throughput either would carry, averaged over the
    /// channels, and `beta` is weighed by σs/(σ̄·P) or σn/(σ̄·P).
    /// Absorption is folded into those weights, as the volumetric path
    /// tracer folds it. Unbiased in every channel. With `glow`, the
    /// medium's emission is added to it: β·σa·Le/σ̄ at each tentative
    /// collision (the null-scattering estimate of ∫ T σa Le dt).
    fn fly<R: Uniforms>(
        &self,
        medium: u32,
        ray: &Ray,
        t_end: f32,
        beta: &mut Rgb,
        mut glow: Option<&mut Rgb>,
        rng: &mut R,
    ) -> Flight {
        let m = &self.scene.media[medium as usize];
        let len = ray.dir.length();
        let (dir, origin) = (ray.dir / len, ray.at(ray.t_min));
        let Some((t0, t1)) = m.segment(origin, dir, (t_end - ray.t_min) * len) else {
            return Flight::Crossed;
        };
        let sigma_bar = m.majorant().max_element();
        if sigma_bar.is_nan() || sigma_bar <= 0.0 {
            return Flight::Crossed;
        }
        let mut t = t0;
        loop {
            t -= (1.0 - rng.next_f32()).ln() / sigma_bar;
            if t.is_nan() || t >= t1 {
                return Flight::Crossed;
            }
            let p = origin + dir * t;
            let mp = m.point(p);
            if let (Some(glow), true) = (glow.as_deref_mut(), mp.le != Rgb::ZERO) {
                *glow += *beta * mp.sigma_a * mp.le / sigma_bar;
            }
            let sigma_n = (Rgb::splat(sigma_bar) - mp.sigma_a - mp.sigma_s).max(Rgb::ZERO);
            let (w_scatter, w_null) = (mean(*beta * mp.sigma_s), mean(*beta * sigma_n));
            if (w_scatter + w_null).is_nan() || w_scatter + w_null <= 0.0 {
                return Flight::Ended;
            }
            let p_scatter = w_scatter / (w_scatter + w_null);
            if rng.next_f32() < p_scatter {
                *beta *= mp.sigma_s / (sigma_bar * p_scatter);
                return Flight::Scattered(p);
            }
            *beta *= sigma_n / (sigma_bar * (1.0 - p_scatter));
        }
    }

    /// The transmittance from vertex `from` to `target` (unit direction
    /// `dir` from it): zero where a surface is in the way, except, among
    /// media, surfaces that are not there, which the segment crosses into
    /// the medium behind them. Through a medium whose σt is constant the
    /// exact exp(−σt·d); otherwise ratio tracking against the grey
    /// majorant (the product of σn/σ̄ over tentative collisions; Novák et
    /// al. 2014), unbiased per channel.
    fn transmittance<R: Uniforms>(&self, from: &Vertex, target: ShadowTarget, dir: Vec3, rng: &mut R) -> Rgb {
        let scene = self.scene;
        let mut ray = match (&from.hit, target) {
            (Some(h), ShadowTarget::Point(q)) => h.spawn_ray_to(q),
            (Some(h), ShadowTarget::Infinity) => h.spawn_ray(dir),
            (None, ShadowTarget::Point(q)) => {
                Ray::with_interval(from.p, q - from.p, 0.0, SHADOW_EPSILON).at_time(from.time)
            }
            (None, ShadowTarget::Infinity) => Ray::new(from.p, dir).at_time(from.time),
        };
        if !self.media {
            return if scene.occluded(&ray) { Rgb::ZERO } else { Rgb::ONE };
        }
        let mut medium = match (
            &from.hit,
            &from
                .hit
                .as_ref()
                .and_then(|h| scene.material_media[h.material as usize]),
        ) {
            (Some(h), Some(interface)) => interface.toward(dir, h.ng),
            _ => from.medium,
        };
        let mut tr = Rgb::ONE;
        for _ in 0..MAX_CROSSINGS {
            let hit = scene.intersect(&ray);
            if let Some(mi) = medium {
                let t_end = hit.as_ref().map_or(ray.t_max, |h| h.t);
                tr *= self.segment_transmittance(mi, &ray, t_end, rng);
                if tr == Rgb::ZERO || !tr.is_finite() {
                    return Rgb::ZERO;
                }
            }
            let Some(h) = hit else {
                return tr;
            };
            if !is_null(&scene.materials[h.material as usize]) {
                return Rgb::ZERO;
            }
            if let Some(interface) = scene.material_media[h.material as usize] {
                medium = interface.toward(dir, h.ng);
            }
            ray = match target {
                ShadowTarget::Point(q) => h.spawn_ray_to(q),
                ShadowTarget::Infinity => h.spawn_ray(dir),
            };
        }
        Rgb::ZERO
    }

    /// The transmittance of medium `medium` along `ray` up to its
    /// parameter `t_end` (see [`Tracer::transmittance`]).
    fn segment_transmittance<R: Uniforms>(&self, medium: u32, ray: &Ray, t_end: f32, rng: &mut R) -> Rgb {
        let m = &self.scene.media[medium as usize];
        let len = ray.dir.length();
        let (dir, origin) = (ray.dir / len, ray.at(ray.t_min));
        let Some((t0, t1)) = m.segment(origin, dir, (t_end - ray.t_min) * len) else {
            return Rgb::ONE;
        };
        if let Some(sigma_t) = m.constant_extinction() {
            return crate::media::transmittance(t1 - t0, sigma_t);
        }
        let sigma_bar = m.majorant().max_element();
        if sigma_bar.is_nan() || sigma_bar <= 0.0 {
            return Rgb::ONE;
        }
        let mut tr = Rgb::ONE;
        let mut t = t0;
        loop {
            t -= (1.0 - rng.next_f32()).ln() / sigma_bar;
            if t.is_nan() || t >= t1 {
                return tr;
            }
            let mp = m.point(origin + dir * t);
            tr *= (Rgb::splat(sigma_bar) - mp.sigma_a - mp.sigma_s).max(Rgb::ZERO) / sigma_bar;
            // Russian roulette on a faint estimate (as pbrt-v4's).
            if tr.max_element() < 0.05 {
                if rng.next_f32() < 0.75 {
                    return Rgb::ZERO;
                }
                tr /= 0.25;
            }
        }
    }

    /// The medium at point `p` of a light: the side that a ray from `p`
    /// along `w` comes from at the first surface it meets that bounds a
    /// medium; where it meets none, the outer medium. (Lights do not name
    /// their medium; pbrt-v4's take the one current where they are made.)
    fn medium_around(&self, p: Vec3, w: Vec3, time: f32) -> Option<u32> {
        let scene = self.scene;
        let eps = 1e-4 * (1.0 + p.abs().max_element());
        let mut ray = Ray::with_interval(p, w, eps, f32::INFINITY).at_time(time);
        for _ in 0..MAX_CROSSINGS {
            let Some(hit) = scene.intersect(&ray) else { break };
            if let Some(interface) = scene.material_media[hit.material as usize] {
                return interface.toward(-w, hit.ng);
            }
            ray = hit.spawn_ray(w);
        }
        self.outer_medium
    }

    /// A density per solid angle at `from` as a density per unit area at
    /// `to` (per solid angle for a light at infinity; an orthographic
    /// camera's density is already per unit area of its view plane).
    fn convert(&self, pdf: f32, from: &Vertex, to: &Vertex) -> f32 {
        if to.is_infinite_light() {
            return pdf;
        }
        let (w, d2) = from.toward(to);
        let cos = if to.on_surface() { to.ng.dot(w).abs() } else { 1.0 };
        if from.kind == Kind::Camera && self.scene.camera.is_orthographic() {
            return pdf * cos;
        }
        if from.is_infinite_light() {
            return pdf * cos;
        }
        if d2 == 0.0 || !d2.is_finite() {
            return 0.0;
        }
        pdf * cos / d2
    }

    /// The density with which `v`, reached from `prev`, samples `next`,
    /// per unit area of `next`.
    fn pdf(&self, v: &Vertex, prev: Option<&Vertex>, next: &Vertex) -> f32 {
        match v.kind {
            Kind::Light { .. } => self.pdf_light(v, next),
            Kind::Camera => {
                let (w, _) = v.toward(next);
                self.convert(self.scene.camera.pdf_dir_at(w, v.time), v, next)
            }
            Kind::Medium => {
                let (Some(phase), Some(prev)) = (&v.phase, prev) else {
                    return 0.0;
                };
                let (wp, _) = v.toward(prev);
                let (wn, _) = v.toward(next);
                self.convert(phase.eval(wp, wn), v, next)
            }
            Kind::Surface => {
                let (Some((bsdf, frame)), Some(prev)) = (&v.bsdf, prev) else {
                    return 0.0;
                };
                let (wp, _) = v.toward(prev);
                let (wn, _) = v.toward(next);
                let pdf = bsdf.pdf(frame.to_local(wp), frame.to_local(wn));
                self.convert(pdf, v, next)
            }
        }
    }

    /// The density with which light vertex `v` emits toward `to`, per
    /// unit area of `to`.
    fn pdf_light(&self, v: &Vertex, to: &Vertex) -> f32 {
        let Kind::Light { light, infinite, .. } = v.kind else {
            return 0.0;
        };
        if infinite {
            // The disk the light's rays leave from, seen along them.
            let cos = if to.on_surface() { to.ng.dot(v.p).abs() } else { 1.0 };
            return cos / (PI * self.bounds.1 * self.bounds.1);
        }
        let (w, d2) = v.toward(to);
        let (_, pdf_dir) = pdf_le(self.scene, self.bounds, light, v.p, v.ng, w);
        let cos = if to.on_surface() { to.ng.dot(w).abs() } else { 1.0 };
        if d2 == 0.0 { 0.0 } else { pdf_dir * cos / d2 }
    }

    /// The density with which a light subpath starts at light vertex `v`
    /// (the light's choice times its point's density; for a light at
    /// infinity, of its direction), seen from `to`.
    fn pdf_light_origin(&self, v: &Vertex, to: &Vertex) -> f32 {
        let Kind::Light { light, infinite, .. } = v.kind else {
            return 0.0;
        };
        let scene = self.scene;
        let pmf = scene.light_distribution.pmf(light as usize);
        if infinite {
            return match &scene.lights[light as usize] {
                Light::Environment => pmf * scene.background.pdf(v.p),
                _ => pmf,
            };
        }
        let (w, _) = v.toward(to);
        let (pdf_pos, _) = pdf_le(scene, self.bounds, light, v.p, v.ng, w);
        pmf * pdf_pos
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::rng::Pcg32;

    /// The camera subpaths of `scene` that reach an emitter are full paths
    /// x₀ (on the light) … x_k (the lens); each is split every way into a
    /// light subpath x₀ … x_{s−1} and a camera subpath x_k … x_s, their
    /// vertices' densities from either side computed afresh, and the
    /// weights [`Tracer::mis_weight`] gives the strategies that can make
    /// the path (no connection at a delta or non-connectible vertex) must
    /// sum to one. Returns how many paths were checked.
    ///
    /// With `eta` > 0 the strategies are vertex connection and merging's:
    /// merges at every vertex with a non-delta lobe join the connections,
    /// the merged light vertex lying exactly at the camera's.
    fn weights_sum_to_one<'s>(scene: &'s Scene, trials: u32, eta: f32) -> (u32, u32) {
        let tracer = Tracer::new(scene, 8).merging(eta);
        let mut rng = Pcg32::new(11, 3);
        let mut path = Vec::new();
        let mut rays = 0;
        let (mut checked, mut through_media) = (0, 0);
        let (w, h) = (scene.settings.width as f32, scene.settings.height as f32);
        for _ in 0..trials {
            let raster = Vec2::new(rng.next_f32() * w, rng.next_f32() * h);
            let lens = Vec2::new(rng.next_f32(), rng.next_f32());
            tracer.camera_subpath(raster, lens, 0.0, 9, &mut rng, &mut path, None, &mut rays, None);
            for t in 3..=path.len() {
                let Some(light_end) = tracer.as_light(&path[t - 1]) else {
                    continue;
                };
                if !matches!(path[t - 1].kind, Kind::Surface) {
                    continue;
                }
                // x₀ … x_k, x₀ on the light and x_k the lens.
                let mut x: Vec<Vertex> = path[..t].iter().rev().copied().collect();
                let k = x.len() - 1;
                let as_light_vertex = |i: usize, x: &[Vertex<'s>]| if i == 0 { light_end } else { x[i] };
                let mut from_light = vec![0.0f32; k + 1];
                let mut from_camera = vec![0.0f32; k + 1];
                from_light[0] = tracer.pdf_light_origin(&light_end, &x[1]);
                from_light[1] = tracer.pdf_light(&light_end, &x[1]);
                // Through a delta bounce, a unit density per solid angle.
                for i in 2..=k {
                    let prev = as_light_vertex(i - 2, &x);
                    from_light[i] = match x[i - 1].delta {
                        true => tracer.convert(1.0, &x[i - 1], &x[i]),
                        false => tracer.pdf(&x[i - 1], Some(&prev), &x[i]),
                    };
                }
                from_camera[k - 1] = tracer.pdf(&x[k], None, &x[k - 1]);
                for i in (0..k - 1).rev() {
                    from_camera[i] = match x[i + 1].delta {
                        true => tracer.convert(1.0, &x[i + 1], &as_light_vertex(i, &x)),
                        false => tracer.pdf(&x[i + 1], Some(&x[i + 2]), &x[i]),
                    };
                }
                let mut sum = 0.0f64;
                for s in 0..=k {
                    let t = k + 1 - s;
                    let valid = |i: usize| {
                        let v = if i == 0 { &light_end } else { &x[i] };
                        v.connectible && !v.delta
                    };
                    if s > 0 && !(valid(s - 1) && valid(s)) {
                        continue;
                    }
                    let light: Vec<Vertex> = (0..s)
                        .map(|i| {
                            let mut v = as_light_vertex(i, &x);
                            v.mode = TransportMode::Importance;
                            (v.pdf_fwd, v.pdf_rev) = (from_light[i], from_camera[i]);
                            v
                        })
                        .collect();
                    let camera: Vec<Vertex> = (s..=k)
                        .rev()
                        .map(|i| {
                            let mut v = x[i];
                            (v.pdf_fwd, v.pdf_rev) = (from_camera[i], from_light[i]);
                            v
                        })
                        .collect();
                    let sampled = match (s, t) {
                        (1, _) => Some(light[0]),
                        (_, 1) => Some(camera[0]),
                        _ => None,
                    };
                    let mut work = Subpaths {
                        camera,
                        light,
                        stored: Vec::new(),
                        glow: Vec::new(),
                        wavelength: None,
                    };
                    sum += tracer.mis_weight(&mut work, s, t, sampled) as f64;
                }
                // Merges at x_i: the light subpath x₀ … x_i, the camera
                // subpath x_k … x_i.
                for i in 1..k {
                    if eta == 0.0 || !x[i].merges() || !x[i].connectible {
                        continue;
                    }
                    let light: Vec<Vertex> = (0..=i)
                        .map(|j| {
                            let mut v = as_light_vertex(j, &x);
                            v.mode = TransportMode::Importance;
                            (v.pdf_fwd, v.pdf_rev) = (from_light[j], from_camera[j]);
                            if j > 0 {
                                v.wo = v.toward(&as_light_vertex(j - 1, &x)).0;
                            }
                            v
                        })
                        .collect();
                    let mut stored = Vec::new();
                    tracer.light_vertices(&light, None, &mut stored);
                    let y = stored.last().expect("x_i has a non-delta lobe");
                    let camera: Vec<Vertex> = (i..=k)
                        .rev()
                        .map(|j| {
                            let mut v = x[j];
                            (v.pdf_fwd, v.pdf_rev) = (from_camera[j], from_light[j]);
                            v
                        })
                        .collect();
                    let (_, frame) = x[i].bsdf.unwrap();
                    let site = tracer.merge_site(&camera, camera.len()).unwrap();
                    let w = tracer.merge_weight(&camera, &site, y, frame.to_local(light[i].wo));
                    sum += w as f64;
                }
                assert!((sum - 1.0).abs() < 1e-3, "path of {k} segments: weights sum to {sum}");
                checked += 1;
                through_media += u32::from(x.iter().any(|v| v.kind == Kind::Medium));
                x.clear();
            }
        }
        (checked, through_media)
    }

    /// The Cornell box in chromatic fog (the camera in it) with a ball of
    /// a denser medium with no surface.
    fn foggy_cornell_box() -> Scene {
        let mut foggy = crate::scene::builtin::cornell_box();
        let medium = |name: &str, sigma_t: Rgb, g: f32| crate::scene::desc::MediumDesc {
            name: name.into(),
            sigma_t: crate::scene::desc::FieldDesc::Constant(sigma_t),
            albedo: crate::scene::desc::FieldDesc::Constant(Rgb::splat(0.8)),
            emission: None,
            scale: Rgb::ONE,
            g,
            locs: Default::default(),
        };
        foggy.media.push(medium("fog", Rgb::new(0.3, 0.5, 0.7), 0.0));
        foggy.media.push(medium("milk", Rgb::splat(3.0), 0.4));
        foggy.camera_medium = Some("fog".into());
        foggy.materials.push(crate::scene::desc::MaterialDesc::with_kind(
            "boundary",
            crate::scene::desc::MaterialKindDesc::NULL,
        ));
        let mut ball = crate::scene::desc::ShapeDesc::new(
            crate::scene::desc::ShapeKind::Sphere {
                center: Vec3::new(0.3, -0.5, 0.2),
                radius: 0.35,
            },
            Some("boundary"),
        );
        ball.media = Some(crate::scene::desc::MediumInterfaceDesc {
            inside: Some("milk".into()),
            outside: Some("fog".into()),
        });
        foggy.shapes.push(ball);
        foggy.settings.integrator = crate::settings::IntegratorKind::Bdpt;
        crate::scene::build(&foggy).unwrap()
    }

    #[test]
    fn weights_of_the_strategies_of_a_path_sum_to_one() {
        let cornell = crate::scene::build(&crate::scene::builtin::cornell_box()).unwrap();
        let (n, _) = weights_sum_to_one(&cornell, 5000, 0.0);
        assert!(n > 50, "only {n} paths reached the light");
        // Glass (delta lobes) and a sphere light.
        let caustic = crate::scene::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/caustic.toml"),
            &[],
        )
        .unwrap();
        let caustic = crate::scene::build(&caustic).unwrap();
        let (n, _) = weights_sum_to_one(&caustic, 200_000, 0.0);
        assert!(n > 50, "only {n} paths reached the light");
        // Medium vertices.
        let foggy = foggy_cornell_box();
        let tracer = Tracer::new(&foggy, 8);
        assert!(tracer.media);
        let (n, through_media) = weights_sum_to_one(&foggy, 20_000, 0.0);
        assert!(
            n > 50 && through_media > n / 4,
            "{n} paths reached the light, {through_media} through media"
        );
    }

    /// Vertex connection and merging: connections and merges together,
    /// for merging factors η from much smaller to much larger than the
    /// densities' products.
    #[test]
    fn weights_with_merging_sum_to_one() {
        let cornell = crate::scene::build(&crate::scene::builtin::cornell_box()).unwrap();
        let caustic = crate::scene::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/caustic.toml"),
            &[],
        )
        .unwrap();
        let caustic = crate::scene::build(&caustic).unwrap();
        let foggy = foggy_cornell_box();
        for eta in [1e-4, 1.0, 1e3] {
            let (n, _) = weights_sum_to_one(&cornell, 2000, eta);
            assert!(n > 20, "only {n} paths reached the light");
            let (n, _) = weights_sum_to_one(&caustic, 100_000, eta);
            assert!(n > 20, "only {n} paths reached the light");
            // Merging on surfaces only, among medium vertices.
            let (n, through_media) = weights_sum_to_one(&foggy, 20_000, eta);
            assert!(
                n > 20 && through_media > n / 4,
                "{n} paths, {through_media} through media"
            );
        }
    }
}
