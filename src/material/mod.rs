//! Materials: how surfaces reflect, transmit and emit light.
//!
//! The classical material record of the ray-tracing course: diffuse and
//! specular colour, Phong exponent, mirror reflectivity, transmission with
//! an index of refraction, and emission.
//!
//! ```toml
//! [[material]]
//! name = "glass"
//! diffuse = [0, 0, 0]
//! specular = [0.2, 0.2, 0.2]
//! shininess = 200
//! transmission = [1, 1, 1]
//! ior = 1.5
//! ```

pub mod optics;
pub mod phong;

use crate::color::Rgb;
use crate::texture::{ImageTexture, TexCoord, Texture};

/// A surface material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Diffuse colour kd (albedo of the Lambertian part).
    pub diffuse: Texture,
    /// Specular colour ks of the Phong lobe.
    pub specular: Texture,
    /// Phong exponent s: larger is a tighter highlight.
    pub shininess: f32,
    /// Weight kr of the mirror-reflected ray.
    pub reflectivity: Rgb,
    /// Weight kt of light passing through (refracted, Fresnel-weighted).
    pub transmission: Rgb,
    /// Index of refraction of the material's inside (1 = no bending).
    pub ior: f32,
    /// Emitted radiance, from the front side.
    pub emission: Rgb,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            diffuse: Texture::Constant(Rgb::splat(0.5)),
            specular: Texture::Constant(Rgb::ZERO),
            shininess: 0.0,
            reflectivity: Rgb::ZERO,
            transmission: Rgb::ZERO,
            ior: 1.0,
            emission: Rgb::ZERO,
        }
    }
}

impl Material {
    /// A plain diffuse material.
    pub fn diffuse(color: Rgb) -> Material {
        Material {
            diffuse: Texture::Constant(color),
            ..Default::default()
        }
    }

    /// Diffuse colour at a point.
    #[inline]
    pub fn kd(&self, images: &[ImageTexture], tc: &TexCoord) -> Rgb {
        self.diffuse.eval(images, tc)
    }

    /// Specular colour at a point.
    #[inline]
    pub fn ks(&self, images: &[ImageTexture], tc: &TexCoord) -> Rgb {
        self.specular.eval(images, tc)
    }

    /// Whether light passes through the surface.
    #[inline]
    pub fn is_transmissive(&self) -> bool {
        self.transmission != Rgb::ZERO
    }

    /// Whether the surface emits.
    #[inline]
    pub fn is_emissive(&self) -> bool {
        self.emission != Rgb::ZERO
    }
}
