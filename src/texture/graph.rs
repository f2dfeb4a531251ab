//! Textures made of other textures: products, blends, checks and dots of
//! textures, procedural noise, and the 2-D mappings that place a texture
//! by the point rather than by the surface's (u, v). They follow pbrt-v4's
//! texture classes (`textures.h`; Physically Based Rendering, 4th ed.,
//! ch. 10), evaluated without ray differentials: at a point, not filtered
//! over a pixel's footprint, which supersampling does instead.
//!
//! The nodes live in the scene's [`TextureStore`]; a [`Texture::Node`]
//! names one, and a node's inputs are [`Texture`]s again, so textures stay
//! small and `Copy`. A node may only name nodes made before it, so the
//! graph has no cycles, and its depth is bounded ([`MAX_TEXTURE_DEPTH`]).

use super::noise::{fbm, noise_2d, turbulence};
use super::{TexCoord, Texture, TextureStore};
use crate::color::{Rgb, luminance};
use glam::{Affine3A, Vec2, Vec3};
use std::f32::consts::PI;

/// How deep textures may nest (a texture of a texture of …): evaluation
/// recurses through the nesting.
pub const MAX_TEXTURE_DEPTH: usize = 64;

/// Where a 2-D texture is read: (s, t) from the surface's (u, v) or from
/// the point (pbrt-v4's `TextureMapping2D`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mapping2D {
    /// (s, t) = scale·(u, v) + offset.
    Uv {
        /// Multiplies (u, v).
        scale: Vec2,
        /// Added after scaling.
        offset: Vec2,
    },
    /// (s, t) = u·u_axis + v·v_axis + offset: any affine map of (u, v),
    /// rotations and shears included (Mitsuba's `to_uv`, glTF's
    /// `KHR_texture_transform`).
    UvAffine {
        /// Where (1, 0) goes, less the offset.
        u_axis: Vec2,
        /// Where (0, 1) goes, less the offset.
        v_axis: Vec2,
        /// Where (0, 0) goes.
        offset: Vec2,
    },
    /// (θ/π, φ/2π) of the point's direction from the texture space's
    /// origin (θ from +z, φ from +x toward +y).
    Spherical {
        /// World to texture space.
        to_texture: Affine3A,
    },
    /// ((π + φ)/2π, z) around the texture space's z axis.
    Cylindrical {
        /// World to texture space.
        to_texture: Affine3A,
    },
    /// (s, t) = offset + (p·s_axis, p·t_axis) in texture space.
    Planar {
        /// World to texture space.
        to_texture: Affine3A,
        /// The direction along which s grows.
        s_axis: Vec3,
        /// The direction along which t grows.
        t_axis: Vec3,
        /// Added to (s, t).
        offset: Vec2,
    },
}

impl Mapping2D {
    /// The (s, t) of a look-up.
    pub fn map(&self, tc: &TexCoord) -> Vec2 {
        match *self {
            Mapping2D::Uv { scale, offset } => tc.uv * scale + offset,
            Mapping2D::UvAffine { u_axis, v_axis, offset } => tc.uv.x * u_axis + tc.uv.y * v_axis + offset,
            Mapping2D::Spherical { to_texture } => {
                let d = to_texture.transform_point3(tc.p).normalize_or_zero();
                let mut phi = d.y.atan2(d.x);
                if phi < 0.0 {
                    phi += 2.0 * PI;
                }
                Vec2::new(d.z.clamp(-1.0, 1.0).acos() / PI, phi / (2.0 * PI))
            }
            Mapping2D::Cylindrical { to_texture } => {
                let q = to_texture.transform_point3(tc.p);
                Vec2::new((PI + q.y.atan2(q.x)) / (2.0 * PI), q.z)
            }
            Mapping2D::Planar {
                to_texture,
                s_axis,
                t_axis,
                offset,
            } => {
                let q = to_texture.transform_point3(tc.p);
                offset + Vec2::new(q.dot(s_axis), q.dot(t_axis))
            }
        }
    }
}

/// The procedural patterns of noise (pbrt-v4's `fbm`, `wrinkled`, `windy`
/// and `marble`), read at the point in texture space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NoisePattern {
    /// Fractional Brownian motion: a grey value, mean 0.
    Fbm {
        /// Octaves summed.
        octaves: u32,
        /// Each octave's weight relative to the one before (`roughness`).
        omega: f32,
    },
    /// Turbulence (|noise| summed): a grey value.
    Wrinkled {
        /// Octaves summed.
        octaves: u32,
        /// Each octave's weight relative to the one before.
        omega: f32,
    },
    /// Waves whose height a slower noise modulates: a grey value.
    Windy,
    /// Veins of grey-blue marble: sin(y + variation·fbm) through a colour
    /// spline.
    Marble {
        /// Octaves of the fbm.
        octaves: u32,
        /// Each octave's weight relative to the one before.
        omega: f32,
        /// Multiplies the point before anything else.
        scale: f32,
        /// How far the fbm bends the veins.
        variation: f32,
    },
}

/// pbrt-v4's marble colours: the control points of the cubic Bézier
/// segments that `t` runs through.
const MARBLE_COLORS: [[f32; 3]; 9] = [
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.5, 0.5, 0.5],
    [0.6, 0.59, 0.58],
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.2, 0.2, 0.33],
    [0.58, 0.58, 0.6],
];

/// The marble colour at t ∈ [0, 1]: one of six cubic Bézier segments over
/// [`MARBLE_COLORS`], by de Casteljau's construction, times 1.5.
fn marble_color(t: f32) -> Rgb {
    let segments = MARBLE_COLORS.len() - 3;
    let t = t.clamp(0.0, 1.0) * segments as f32;
    let first = (t as usize).min(segments - 1);
    let u = t - first as f32;
    let c: [Rgb; 4] = std::array::from_fn(|k| Rgb::from(MARBLE_COLORS[first + k]));
    let a = [c[0].lerp(c[1], u), c[1].lerp(c[2], u), c[2].lerp(c[3], u)];
    let b = [a[0].lerp(a[1], u), a[1].lerp(a[2], u)];
    1.5 * b[0].lerp(b[1], u)
}

impl NoisePattern {
    /// The pattern of pbrt-v4's class `class` (`fbm`, `wrinkled`, `windy`
    /// or `marble`, whose scale and variation `marble` reads), or `None`.
    pub fn named<E>(
        class: &str,
        octaves: u32,
        omega: f32,
        marble: impl FnOnce() -> Result<(f32, f32), E>,
    ) -> Result<Option<NoisePattern>, E> {
        Ok(Some(match class {
            "fbm" => NoisePattern::Fbm { octaves, omega },
            "wrinkled" => NoisePattern::Wrinkled { octaves, omega },
            "windy" => NoisePattern::Windy,
            "marble" => {
                let (scale, variation) = marble()?;
                NoisePattern::Marble {
                    octaves,
                    omega,
                    scale,
                    variation,
                }
            }
            _ => return Ok(None),
        }))
    }

    /// The pattern at `q` in texture space.
    pub fn eval(&self, q: Vec3) -> Rgb {
        match *self {
            NoisePattern::Fbm { octaves, omega } => Rgb::splat(fbm(q, omega, octaves)),
            NoisePattern::Wrinkled { octaves, omega } => Rgb::splat(turbulence(q, omega, octaves)),
            NoisePattern::Windy => {
                let strength = fbm(0.1 * q, 0.5, 3);
                let height = fbm(q, 0.5, 6);
                Rgb::splat(strength.abs() * height)
            }
            NoisePattern::Marble {
                octaves,
                omega,
                scale,
                variation,
            } => {
                let q = q * scale;
                let marble = q.y + variation * fbm(q, omega, octaves);
                marble_color(0.5 + 0.5 * marble.sin())
            }
        }
    }

    /// The pattern's mean over space: fbm and windy average 0; turbulence
    /// about 0.2 an octave (pbrt-v4's own estimate); marble its spline over
    /// the phase of the sine.
    pub fn average(&self) -> Rgb {
        match *self {
            NoisePattern::Fbm { .. } | NoisePattern::Windy => Rgb::ZERO,
            NoisePattern::Wrinkled { octaves, omega } => {
                Rgb::splat(0.2 * (0..=octaves).map(|i| omega.powi(i as i32)).sum::<f32>())
            }
            NoisePattern::Marble { .. } => {
                const N: usize = 64;
                (0..N)
                    .map(|k| marble_color(0.5 + 0.5 * (2.0 * PI * (k as f32 + 0.5) / N as f32).sin()))
                    .sum::<Rgb>()
                    / N as f32
            }
        }
    }
}

/// Whether (s, t) lies in one of pbrt-v4's polka dots: cells of side 1
/// centred on the integers, half of them (by noise) holding a dot of radius
/// 0.35 jittered by noise within the cell.
fn inside_polka_dot(st: Vec2) -> bool {
    let cell = (st + 0.5).floor();
    if noise_2d(cell.x + 0.5, cell.y + 0.5) <= 0.0 {
        return false;
    }
    const RADIUS: f32 = 0.35;
    let max_shift = 0.5 - RADIUS;
    let centre = Vec2::new(
        cell.x + max_shift * noise_2d(cell.x + 1.5, cell.y + 2.8),
        cell.y + max_shift * noise_2d(cell.x + 4.5, cell.y + 9.8),
    );
    (st - centre).length_squared() < RADIUS * RADIUS
}

/// Whether ⌊x⌋ + ⌊y⌋ (+ ⌊z⌋) is even, for checks.
fn even_cell(q: &[f32]) -> bool {
    q.iter().map(|x| x.floor() as i64).sum::<i64>().rem_euclid(2) == 0
}

/// A texture made of other textures, or a procedural one. Its inputs are
/// `T`: [`Texture`]s in a scene, colours or texture names
/// ([`crate::scene::desc::ColorSource`]) in a scene description.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TextureNode<T = Texture> {
    /// `tex` × `scale`, channel by channel (pbrt-v4's `scale`).
    Scale {
        /// The texture scaled.
        tex: T,
        /// The factor (a grey float texture, or a colour).
        scale: T,
    },
    /// (1 − a)·`first` + a·`second`, a the first channel of `amount`.
    Mix {
        /// Where the amount is 0.
        first: T,
        /// Where the amount is 1.
        second: T,
        /// The amount.
        amount: T,
    },
    /// a·`first` + (1 − a)·`second`, a = |n·dir| for the shading normal n
    /// (pbrt-v4's `directionmix`).
    DirectionMix {
        /// Where the normal is along `dir`.
        first: T,
        /// Where it is perpendicular to it.
        second: T,
        /// Unit direction in world space.
        dir: Vec3,
    },
    /// Checks of two textures over a 2-D mapping: `even` where ⌊s⌋ + ⌊t⌋
    /// is even.
    Checkerboard {
        /// Where ⌊s⌋ + ⌊t⌋ is even.
        even: T,
        /// Elsewhere.
        odd: T,
        /// How (s, t) is found.
        mapping: Mapping2D,
    },
    /// Solid checks of two textures: unit cubes of texture space.
    SolidCheckerboard {
        /// Where ⌊x⌋ + ⌊y⌋ + ⌊z⌋ is even.
        even: T,
        /// Elsewhere.
        odd: T,
        /// World to texture space.
        to_texture: Affine3A,
    },
    /// pbrt-v4's polka dots over a 2-D mapping.
    Dots {
        /// Inside the dots.
        inside: T,
        /// Between them.
        outside: T,
        /// How (s, t) is found.
        mapping: Mapping2D,
    },
    /// Bilinear interpolation of four colours over (s, t) (extrapolated
    /// outside the unit square).
    Bilerp {
        /// The colours at (s, t) = (0, 0), (1, 0), (0, 1) and (1, 1).
        corners: [Rgb; 4],
        /// How (s, t) is found.
        mapping: Mapping2D,
    },
    /// A noise pattern at the point in texture space.
    Noise {
        /// Which pattern.
        pattern: NoisePattern,
        /// World to texture space.
        to_texture: Affine3A,
    },
    /// max(0, 1 − `tex`), channel by channel (an image's `invert`).
    Invert(T),
    /// One channel of `tex` (0, 1 or 2) in all three: a glTF
    /// metallic-roughness image holds roughness in green, metalness in
    /// blue.
    Channel {
        /// The texture read.
        tex: T,
        /// Which channel.
        channel: u8,
    },
    /// 1 where the first channel of `tex` is at least `cutoff`, else 0:
    /// glTF's alpha mask (`alphaMode` MASK), which cuts after filtering.
    Cutoff {
        /// The texture read.
        tex: T,
        /// The least value that counts as 1.
        cutoff: f32,
    },
    /// `tex` read at (u, v) = the mapping's (s, t): an image or checks
    /// placed by the point.
    Mapped {
        /// The texture read.
        tex: T,
        /// How its (u, v) is found.
        mapping: Mapping2D,
    },
}

impl<T> TextureNode<T> {
    /// The inputs, with the keys that name them in a scene file.
    pub fn inputs(&self) -> Vec<(&'static str, &T)> {
        match self {
            TextureNode::Scale { tex, scale } => vec![("texture", tex), ("scale", scale)],
            TextureNode::Mix { first, second, amount } => {
                vec![("first", first), ("second", second), ("amount", amount)]
            }
            TextureNode::DirectionMix { first, second, .. } => vec![("first", first), ("second", second)],
            TextureNode::Checkerboard { even, odd, .. } | TextureNode::SolidCheckerboard { even, odd, .. } => {
                vec![("even", even), ("odd", odd)]
            }
            TextureNode::Dots { inside, outside, .. } => vec![("inside", inside), ("outside", outside)],
            TextureNode::Invert(tex)
            | TextureNode::Mapped { tex, .. }
            | TextureNode::Channel { tex, .. }
            | TextureNode::Cutoff { tex, .. } => vec![("texture", tex)],
            TextureNode::Bilerp { .. } | TextureNode::Noise { .. } => vec![],
        }
    }

    /// The same node with each input replaced by `f` of it.
    pub fn map<U>(&self, mut f: impl FnMut(&T) -> U) -> TextureNode<U> {
        match self {
            TextureNode::Scale { tex, scale } => TextureNode::Scale {
                tex: f(tex),
                scale: f(scale),
            },
            TextureNode::Mix { first, second, amount } => TextureNode::Mix {
                first: f(first),
                second: f(second),
                amount: f(amount),
            },
            TextureNode::DirectionMix { first, second, dir } => TextureNode::DirectionMix {
                first: f(first),
                second: f(second),
                dir: *dir,
            },
            TextureNode::Checkerboard { even, odd, mapping } => TextureNode::Checkerboard {
                even: f(even),
                odd: f(odd),
                mapping: *mapping,
            },
            TextureNode::SolidCheckerboard { even, odd, to_texture } => TextureNode::SolidCheckerboard {
                even: f(even),
                odd: f(odd),
                to_texture: *to_texture,
            },
            TextureNode::Dots {
                inside,
                outside,
                mapping,
            } => TextureNode::Dots {
                inside: f(inside),
                outside: f(outside),
                mapping: *mapping,
            },
            TextureNode::Bilerp { corners, mapping } => TextureNode::Bilerp {
                corners: *corners,
                mapping: *mapping,
            },
            TextureNode::Noise { pattern, to_texture } => TextureNode::Noise {
                pattern: *pattern,
                to_texture: *to_texture,
            },
            TextureNode::Invert(tex) => TextureNode::Invert(f(tex)),
            TextureNode::Channel { tex, channel } => TextureNode::Channel {
                tex: f(tex),
                channel: *channel,
            },
            TextureNode::Cutoff { tex, cutoff } => TextureNode::Cutoff {
                tex: f(tex),
                cutoff: *cutoff,
            },
            TextureNode::Mapped { tex, mapping } => TextureNode::Mapped {
                tex: f(tex),
                mapping: *mapping,
            },
        }
    }

    /// The node's mean colour, roughly, from its inputs' means `mean`.
    pub fn average_by(&self, mean: impl Fn(&T) -> Rgb) -> Rgb {
        match self {
            TextureNode::Scale { tex, scale } => mean(tex) * mean(scale),
            TextureNode::Mix { first, second, amount } => {
                let a = mean(amount).x;
                (1.0 - a) * mean(first) + a * mean(second)
            }
            TextureNode::DirectionMix { first, second, .. } => 0.5 * (mean(first) + mean(second)),
            TextureNode::Checkerboard { even, odd, .. } | TextureNode::SolidCheckerboard { even, odd, .. } => {
                0.5 * (mean(even) + mean(odd))
            }
            TextureNode::Dots { inside, outside, .. } => {
                // Half the cells hold a dot of radius 0.35.
                let covered = 0.5 * PI * 0.35 * 0.35;
                covered * mean(inside) + (1.0 - covered) * mean(outside)
            }
            TextureNode::Bilerp { corners, .. } => corners.iter().sum::<Rgb>() / 4.0,
            TextureNode::Noise { pattern, .. } => pattern.average(),
            TextureNode::Invert(tex) => (Rgb::ONE - mean(tex)).max(Rgb::ZERO),
            TextureNode::Channel { tex, channel } => Rgb::splat(mean(tex)[(*channel).min(2) as usize]),
            // (The mean's own cut: a typical value, not the covered share.)
            TextureNode::Cutoff { tex, cutoff } => Rgb::splat(if mean(tex).x >= *cutoff { 1.0 } else { 0.0 }),
            TextureNode::Mapped { tex, .. } => mean(tex),
        }
    }
}

impl TextureNode {
    /// The node's colour at `tc`.
    pub fn eval(&self, store: &TextureStore, tc: &TexCoord) -> Rgb {
        match *self {
            TextureNode::Scale { tex, scale } => {
                let s = scale.eval(store, tc);
                if s == Rgb::ZERO {
                    Rgb::ZERO
                } else {
                    tex.eval(store, tc) * s
                }
            }
            TextureNode::Mix { first, second, amount } => {
                let a = amount.eval(store, tc).x;
                // Each side is read only where it counts, as pbrt-v4 does.
                let x = if a != 1.0 { first.eval(store, tc) } else { Rgb::ZERO };
                let y = if a != 0.0 { second.eval(store, tc) } else { Rgb::ZERO };
                (1.0 - a) * x + a * y
            }
            TextureNode::DirectionMix { first, second, dir } => {
                let a = tc.n.dot(dir).abs();
                let x = if a != 0.0 { first.eval(store, tc) } else { Rgb::ZERO };
                let y = if a != 1.0 { second.eval(store, tc) } else { Rgb::ZERO };
                a * x + (1.0 - a) * y
            }
            TextureNode::Checkerboard { even, odd, mapping } => {
                let st = mapping.map(tc);
                if even_cell(&[st.x, st.y]) {
                    even.eval(store, tc)
                } else {
                    odd.eval(store, tc)
                }
            }
            TextureNode::SolidCheckerboard { even, odd, to_texture } => {
                let q = to_texture.transform_point3(tc.p);
                if even_cell(&[q.x, q.y, q.z]) {
                    even.eval(store, tc)
                } else {
                    odd.eval(store, tc)
                }
            }
            TextureNode::Dots {
                inside,
                outside,
                mapping,
            } => {
                if inside_polka_dot(mapping.map(tc)) {
                    inside.eval(store, tc)
                } else {
                    outside.eval(store, tc)
                }
            }
            TextureNode::Bilerp { corners, mapping } => {
                let st = mapping.map(tc);
                let (s, t) = (st.x, st.y);
                (1.0 - s) * (1.0 - t) * corners[0]
                    + s * (1.0 - t) * corners[1]
                    + (1.0 - s) * t * corners[2]
                    + s * t * corners[3]
            }
            TextureNode::Noise { pattern, to_texture } => pattern.eval(to_texture.transform_point3(tc.p)),
            TextureNode::Invert(tex) => (Rgb::ONE - tex.eval(store, tc)).max(Rgb::ZERO),
            TextureNode::Channel { tex, channel } => Rgb::splat(tex.eval(store, tc)[channel.min(2) as usize]),
            TextureNode::Cutoff { tex, cutoff } => Rgb::splat(if tex.eval(store, tc).x >= cutoff { 1.0 } else { 0.0 }),
            TextureNode::Mapped { tex, mapping } => {
                let mut moved = *tc;
                moved.uv = mapping.map(tc);
                tex.eval(store, &moved)
            }
        }
    }

    /// The derivatives of the node's luminance along u and v, by forward
    /// differences of pbrt-v4's step (0.0005 in u or v, the point moved
    /// along ∂p/∂u or ∂p/∂v with it), as pbrt-v4 differentiates a
    /// displacement texture where it has no differentials.
    pub fn luminance_gradient(&self, store: &TextureStore, tc: &TexCoord) -> Vec2 {
        const STEP: f32 = 0.0005;
        let at = |du: f32, dv: f32| {
            let mut moved = *tc;
            moved.uv += Vec2::new(du, dv);
            moved.p += du * tc.dpdu + dv * tc.dpdv;
            luminance(self.eval(store, &moved))
        };
        let here = at(0.0, 0.0);
        Vec2::new(at(STEP, 0.0) - here, at(0.0, STEP) - here) / STEP
    }

    /// The node's mean colour, roughly: of its inputs' means.
    pub fn average(&self, store: &TextureStore) -> Rgb {
        self.average_by(|t| t.average(store))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(u: f32, v: f32, p: Vec3) -> TexCoord {
        TexCoord::new(Vec2::new(u, v), p)
    }

    /// (s, t, s·t) over (u, v): red along u, green along v.
    fn ramp(store: &mut TextureStore) -> Texture {
        store
            .push(TextureNode::Bilerp {
                corners: [Rgb::ZERO, Rgb::X, Rgb::Y, Rgb::ONE],
                mapping: Mapping2D::Uv {
                    scale: Vec2::ONE,
                    offset: Vec2::ZERO,
                },
            })
            .unwrap()
    }

    #[test]
    fn products_blends_and_inversions_follow_their_formulas() {
        let mut store = TextureStore::default();
        let a = Texture::Constant(Rgb::new(0.2, 0.4, 0.8));
        let b = Texture::Constant(Rgb::new(1.0, 0.5, 0.0));
        let half = Texture::Constant(Rgb::splat(0.25));
        let scaled = store.push(TextureNode::Scale { tex: a, scale: half }).unwrap();
        let mixed = store
            .push(TextureNode::Mix {
                first: a,
                second: b,
                amount: half,
            })
            .unwrap();
        let inverted = store.push(TextureNode::Invert(b)).unwrap();
        let nested = store
            .push(TextureNode::Mix {
                first: scaled,
                second: inverted,
                amount: Texture::Constant(Rgb::ONE),
            })
            .unwrap();
        let tc = at(0.3, 0.3, Vec3::ZERO);
        assert_eq!(scaled.eval(&store, &tc), Rgb::new(0.05, 0.1, 0.2));
        assert!(
            (mixed.eval(&store, &tc) - Rgb::new(0.4, 0.425, 0.6))
                .abs()
                .max_element()
                < 1e-6
        );
        assert_eq!(inverted.eval(&store, &tc), Rgb::new(0.0, 0.5, 1.0));
        assert_eq!(nested.eval(&store, &tc), Rgb::new(0.0, 0.5, 1.0));
        assert!((mixed.average(&store) - mixed.eval(&store, &tc)).abs().max_element() < 1e-6);
    }

    #[test]
    fn direction_mix_weighs_by_the_normal() {
        let mut store = TextureStore::default();
        let t = store
            .push(TextureNode::DirectionMix {
                first: Texture::Constant(Rgb::ONE),
                second: Texture::Constant(Rgb::ZERO),
                dir: Vec3::Y,
            })
            .unwrap();
        let mut tc = at(0.0, 0.0, Vec3::ZERO);
        tc.n = Vec3::new(0.0, -0.6, 0.8);
        assert!((t.eval(&store, &tc) - Rgb::splat(0.6)).abs().max_element() < 1e-6);
    }

    #[test]
    fn checks_of_textures_and_bilinear_corners() {
        let mut store = TextureStore::default();
        let ramp = ramp(&mut store);
        let tc = at(0.25, 0.75, Vec3::ZERO);
        assert!(
            (ramp.eval(&store, &tc) - Rgb::new(0.25, 0.75, 0.1875))
                .abs()
                .max_element()
                < 1e-6
        );
        let checks = store
            .push(TextureNode::Checkerboard {
                even: ramp,
                odd: Texture::Constant(Rgb::splat(7.0)),
                mapping: Mapping2D::Uv {
                    scale: Vec2::splat(2.0),
                    offset: Vec2::ZERO,
                },
            })
            .unwrap();
        // (0.25, 0.75)·2 = (0.5, 1.5): ⌊⌋ sum 1, odd.
        assert_eq!(checks.eval(&store, &tc), Rgb::splat(7.0));
        assert_eq!(
            checks.eval(&store, &at(0.75, 0.75, Vec3::ZERO)),
            Rgb::new(0.75, 0.75, 0.5625)
        );
        let solid = store
            .push(TextureNode::SolidCheckerboard {
                even: Texture::Constant(Rgb::ONE),
                odd: Texture::Constant(Rgb::ZERO),
                to_texture: Affine3A::from_scale(Vec3::splat(2.0)),
            })
            .unwrap();
        assert_eq!(solid.eval(&store, &at(0.0, 0.0, Vec3::splat(0.25))), Rgb::ONE);
        assert_eq!(
            solid.eval(&store, &at(0.0, 0.0, Vec3::new(0.75, 0.25, 0.25))),
            Rgb::ZERO
        );
    }

    #[test]
    fn mappings_place_the_texture_by_the_point() {
        let id = Affine3A::IDENTITY;
        let tc = |p: Vec3| at(9.0, 9.0, p);
        let st = Mapping2D::Spherical { to_texture: id }.map(&tc(Vec3::new(0.0, 2.0, 0.0)));
        assert!((st - Vec2::new(0.5, 0.25)).abs().max_element() < 1e-6, "{st}");
        let st = Mapping2D::Cylindrical { to_texture: id }.map(&tc(Vec3::new(-1.0, 0.0, 3.0)));
        assert!((st - Vec2::new(1.0, 3.0)).abs().max_element() < 1e-6, "{st}");
        let st = Mapping2D::Planar {
            to_texture: Affine3A::from_translation(Vec3::X),
            s_axis: Vec3::X,
            t_axis: Vec3::Z,
            offset: Vec2::new(0.5, 0.0),
        }
        .map(&tc(Vec3::new(1.0, 5.0, 2.0)));
        assert_eq!(st, Vec2::new(2.5, 2.0));
        let mut store = TextureStore::default();
        let flat = ramp(&mut store);
        let placed = store
            .push(TextureNode::Mapped {
                tex: flat,
                mapping: Mapping2D::Cylindrical { to_texture: id },
            })
            .unwrap();
        let v = placed.eval(&store, &tc(Vec3::new(-1.0, 0.0, 0.5)));
        assert!((v - Rgb::new(1.0, 0.5, 0.5)).abs().max_element() < 1e-6, "{v}");
    }

    #[test]
    fn dots_cover_about_a_fifth_of_the_plane() {
        // Half the cells hold a dot of radius 0.35: π·0.35²/2 ≈ 0.19.
        let (mut inside, n) = (0, 200 * 200);
        for i in 0..200 {
            for j in 0..200 {
                inside += inside_polka_dot(Vec2::new(i as f32 * 0.237, j as f32 * 0.191)) as u32;
            }
        }
        let f = inside as f32 / n as f32;
        assert!((0.12..0.27).contains(&f), "{f}");
    }

    #[test]
    fn marble_runs_through_its_spline() {
        // Both ends of t are the spline's first and last control points.
        assert!(
            (marble_color(0.0) - 1.5 * Rgb::new(0.58, 0.58, 0.6))
                .abs()
                .max_element()
                < 1e-6
        );
        assert!(
            (marble_color(1.0) - 1.5 * Rgb::new(0.58, 0.58, 0.6))
                .abs()
                .max_element()
                < 1e-6
        );
        // Midway through the fifth segment (control points 4–7).
        let c = [MARBLE_COLORS[4], MARBLE_COLORS[5], MARBLE_COLORS[6], MARBLE_COLORS[7]].map(Rgb::from);
        let bezier = 0.125 * c[0] + 0.375 * c[1] + 0.375 * c[2] + 0.125 * c[3];
        assert!((marble_color(4.5 / 6.0) - 1.5 * bezier).abs().max_element() < 1e-6);
    }

    #[test]
    fn noise_textures_read_the_point_in_texture_space() {
        let mut store = TextureStore::default();
        let pattern = NoisePattern::Fbm { octaves: 4, omega: 0.5 };
        let moved = store
            .push(TextureNode::Noise {
                pattern,
                to_texture: Affine3A::from_translation(Vec3::new(0.5, 0.25, 0.0)),
            })
            .unwrap();
        let p = Vec3::new(0.1, 0.2, 0.3);
        let expected = fbm(p + Vec3::new(0.5, 0.25, 0.0), 0.5, 4);
        assert_eq!(moved.eval(&store, &at(0.0, 0.0, p)), Rgb::splat(expected));
        // Its derivative along u follows ∂p/∂u.
        let mut tc = at(0.0, 0.0, p);
        tc.dpdu = Vec3::X;
        let g = moved.luminance_gradient(&store, &tc);
        let h = 1e-3;
        let numeric = (fbm(p + Vec3::new(0.5 + h, 0.25, 0.0), 0.5, 4) - fbm(p + Vec3::new(0.5 - h, 0.25, 0.0), 0.5, 4))
            / (2.0 * h);
        assert!((g.x - numeric).abs() < 0.05 * numeric.abs().max(1.0), "{g} {numeric}");
        assert_eq!(g.y, 0.0);
    }

    #[test]
    fn nesting_is_bounded() {
        let mut store = TextureStore::default();
        let mut t = Texture::Constant(Rgb::ONE);
        for _ in 0..MAX_TEXTURE_DEPTH {
            t = store.push(TextureNode::Invert(t)).expect("within the bound");
        }
        assert!(store.push(TextureNode::Invert(t)).is_none());
    }
}
