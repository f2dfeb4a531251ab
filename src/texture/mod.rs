//! Textures: colours that vary over a surface.
//!
//! ```toml
//! [[texture]]
//! name = "floor"
//! type = "checkerboard"   # or "image", "mix", "marble", … (docs/scene-format.md)
//! even = [0.9, 0.9, 0.9]
//! odd = [0.1, 0.1, 0.1]
//! scale = [8, 8]          # checks per unit of u and v
//! ```

pub mod graph;
pub mod image;
pub mod noise;

pub use self::graph::{MAX_TEXTURE_DEPTH, Mapping2D, NoisePattern, TextureNode};
pub use self::image::{ImageColors, ImageFilter, ImageTexture, WrapMode};

use crate::color::Rgb;
use glam::{Vec2, Vec3};

/// Where a texture is looked up.
#[derive(Clone, Copy, Debug)]
pub struct TexCoord {
    /// Surface coordinates.
    pub uv: Vec2,
    /// World-space position (for solid textures).
    pub p: Vec3,
    /// The value of the mesh attribute the surface's material reads, at
    /// the point (0 where the surface has none).
    pub attribute: Rgb,
    /// The shading normal (zero where none is known), which direction
    /// mixes read.
    pub n: Vec3,
    /// ∂p/∂u (zero where none is known), along which a bump map's
    /// differences of a solid texture move the point.
    pub dpdu: Vec3,
    /// ∂p/∂v, as `dpdu`.
    pub dpdv: Vec3,
}

impl TexCoord {
    /// A look-up at (u, v) and p, where no mesh attribute is known (a
    /// point sampled on a light, say).
    #[inline]
    pub fn new(uv: Vec2, p: Vec3) -> TexCoord {
        TexCoord {
            uv,
            p,
            attribute: Rgb::ZERO,
            n: Vec3::ZERO,
            dpdu: Vec3::ZERO,
            dpdv: Vec3::ZERO,
        }
    }

    /// The same look-up on a surface whose mesh attribute is `attribute`.
    #[inline]
    pub fn with_attribute(self, attribute: Rgb) -> TexCoord {
        TexCoord { attribute, ..self }
    }

    /// Where a surface hit looks up its textures.
    #[inline]
    pub fn at(hit: &crate::geometry::SurfaceHit) -> TexCoord {
        TexCoord {
            uv: hit.uv,
            p: hit.p,
            attribute: hit.attribute,
            n: hit.ns,
            dpdu: hit.dpdu,
            dpdv: hit.dpdv,
        }
    }
}

/// What textures refer to by index: the scene's images and the nodes of
/// textures made of textures.
#[derive(Clone, Debug, Default)]
pub struct TextureStore {
    /// Decoded images.
    pub images: Vec<ImageTexture>,
    /// Nodes, each naming only nodes before it.
    pub nodes: Vec<TextureNode>,
    /// Each node's nesting depth (1 for a node of plain textures).
    depths: Vec<u8>,
}

impl TextureStore {
    /// A store of these images and no nodes.
    pub fn with_images(images: Vec<ImageTexture>) -> TextureStore {
        TextureStore {
            images,
            ..TextureStore::default()
        }
    }

    /// Adds a node and returns the texture that names it; `None` where it
    /// would nest deeper than [`MAX_TEXTURE_DEPTH`].
    pub fn push(&mut self, node: TextureNode) -> Option<Texture> {
        let depth = 1 + node
            .inputs()
            .iter()
            .map(|(_, t)| match **t {
                Texture::Node(i) => self.depths[i as usize] as usize,
                _ => 0,
            })
            .max()
            .unwrap_or(0);
        if depth > MAX_TEXTURE_DEPTH {
            return None;
        }
        self.nodes.push(node);
        self.depths.push(depth as u8);
        Some(Texture::Node(self.nodes.len() as u32 - 1))
    }
}

/// A colour texture. Image data and the nodes of textures made of
/// textures live in the scene's [`TextureStore`] and are referenced by
/// index, so textures stay small and `Copy`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Texture {
    /// The same colour everywhere.
    Constant(Rgb),
    /// Checks in (u, v): `scale` checks per unit of u and of v.
    Checkerboard {
        /// Colour of the checks where ⌊u·su⌋ + ⌊v·sv⌋ is even.
        even: Rgb,
        /// Colour of the other checks.
        odd: Rgb,
        /// Checks per unit of u and v.
        scale: Vec2,
    },
    /// Solid checks: cubes of side 1/`scale` in world space.
    Checkerboard3d {
        /// Colour where ⌊x·s⌋ + ⌊y·s⌋ + ⌊z·s⌋ is even.
        even: Rgb,
        /// The other colour.
        odd: Rgb,
        /// Cubes per unit length.
        scale: f32,
    },
    /// An image mapped by (u, v).
    Image {
        /// Index into the scene's images.
        image: u32,
        /// Repetitions per unit of u and v.
        scale: Vec2,
        /// Offset added to (u, v) after scaling.
        offset: Vec2,
        /// Colour multiplier.
        tint: Rgb,
        /// How the image continues beyond [0, 1]², along u and along v.
        wrap: [WrapMode; 2],
        /// How it is read between texel centres.
        filter: ImageFilter,
    },
    /// A value that a mesh carries per vertex (interpolated) or per face
    /// (Mitsuba's `mesh_attribute` texture), its first three channels (one
    /// channel read as grey); the number is the attribute's name among the
    /// scene's `attribute_names`. Surfaces without it read 0.
    MeshAttribute(u32),
    /// A texture made of textures, or a procedural one: a node of the
    /// scene's [`TextureStore`].
    Node(u32),
}

impl Texture {
    /// Whether the texture reads surface coordinates (u, v): a surface
    /// record needs them only where some texture does, and a sphere's
    /// cost an arc tangent and an arc sine.
    pub fn reads_uv(&self) -> bool {
        // A node may (conservatively).
        matches!(
            self,
            Texture::Checkerboard { .. } | Texture::Image { .. } | Texture::Node(_)
        )
    }

    /// The colour at `tc`. A constant is read in place, without a call:
    /// most materials and emitters have constant colours, and their look-up
    /// sits in the path tracer's inner loop.
    #[inline(always)]
    pub fn eval(&self, store: &TextureStore, tc: &TexCoord) -> Rgb {
        match *self {
            Texture::Constant(c) => c,
            _ => self.eval_varying(store, tc),
        }
    }

    /// [`Texture::eval`] of a texture that varies over the surface.
    fn eval_varying(&self, store: &TextureStore, tc: &TexCoord) -> Rgb {
        match *self {
            Texture::Constant(c) => c,
            Texture::Checkerboard { even, odd, scale } => {
                let q = (tc.uv * scale).floor();
                if (q.x as i64 + q.y as i64).rem_euclid(2) == 0 {
                    even
                } else {
                    odd
                }
            }
            Texture::Checkerboard3d { even, odd, scale } => {
                let q = (tc.p * scale).floor();
                if (q.x as i64 + q.y as i64 + q.z as i64).rem_euclid(2) == 0 {
                    even
                } else {
                    odd
                }
            }
            Texture::Image {
                image,
                scale,
                offset,
                tint,
                wrap,
                filter,
            } => store.images[image as usize].lookup(tc.uv * scale + offset, wrap, filter) * tint,
            Texture::MeshAttribute(_) => tc.attribute,
            Texture::Node(i) => store.nodes[i as usize].eval(store, tc),
        }
    }

    /// The derivatives along u and v of the texture's luminance at `tc`,
    /// for bump maps: an image's are its interpolant's; checks are constant
    /// almost everywhere, as are constants; a mesh attribute gives none; a
    /// node's are forward differences.
    pub fn luminance_gradient(&self, store: &TextureStore, tc: &TexCoord) -> Vec2 {
        match *self {
            Texture::Image {
                image,
                scale,
                offset,
                wrap,
                filter,
                tint,
            } => store.images[image as usize].luminance_gradient(tc.uv * scale + offset, wrap, filter, tint) * scale,
            Texture::Node(i) => store.nodes[i as usize].luminance_gradient(store, tc),
            Texture::Constant(_)
            | Texture::Checkerboard { .. }
            | Texture::Checkerboard3d { .. }
            | Texture::MeshAttribute(_) => Vec2::ZERO,
        }
    }

    /// The texture's average colour: its value for constants, the mean of
    /// the checks or of the image, roughly a node's.
    pub fn average(&self, store: &TextureStore) -> Rgb {
        match *self {
            Texture::Constant(c) => c,
            Texture::Checkerboard { even, odd, .. } | Texture::Checkerboard3d { even, odd, .. } => 0.5 * (even + odd),
            Texture::Image { image, tint, .. } => store.images[image as usize].average() * tint,
            Texture::Node(i) => store.nodes[i as usize].average(store),
            // Unknown before a mesh is hit: the middle of [0, 1].
            Texture::MeshAttribute(_) => Rgb::splat(0.5),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(u: f32, v: f32) -> TexCoord {
        TexCoord::new(Vec2::new(u, v), Vec3::ZERO)
    }

    #[test]
    fn checkerboard_alternates() {
        let t = Texture::Checkerboard {
            even: Rgb::ONE,
            odd: Rgb::ZERO,
            scale: Vec2::splat(2.0),
        };
        assert_eq!(t.eval(&TextureStore::default(), &at(0.1, 0.1)), Rgb::ONE);
        assert_eq!(t.eval(&TextureStore::default(), &at(0.6, 0.1)), Rgb::ZERO);
        assert_eq!(t.eval(&TextureStore::default(), &at(0.6, 0.6)), Rgb::ONE);
        // Negative coordinates continue the pattern.
        assert_eq!(t.eval(&TextureStore::default(), &at(-0.1, 0.1)), Rgb::ZERO);
    }

    #[test]
    fn solid_checkerboard_alternates_in_3d() {
        let t = Texture::Checkerboard3d {
            even: Rgb::ONE,
            odd: Rgb::ZERO,
            scale: 1.0,
        };
        let tc = |p: Vec3| TexCoord::new(Vec2::ZERO, p);
        assert_eq!(t.eval(&TextureStore::default(), &tc(Vec3::splat(0.5))), Rgb::ONE);
        assert_eq!(
            t.eval(&TextureStore::default(), &tc(Vec3::new(1.5, 0.5, 0.5))),
            Rgb::ZERO
        );
        assert_eq!(
            t.eval(&TextureStore::default(), &tc(Vec3::new(1.5, 1.5, 0.5))),
            Rgb::ONE
        );
        assert_eq!(
            t.eval(&TextureStore::default(), &tc(Vec3::new(0.5, 0.5, -0.5))),
            Rgb::ZERO
        );
    }
}
