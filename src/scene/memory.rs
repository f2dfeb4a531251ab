//! How much memory a render will need, estimated before it is allocated,
//! and the limit it is checked against (`--max-memory`).
//!
//! The estimate counts what grows with the input: the film (pixel sums, the
//! copy a pass works on, the checkpoint and output buffers), the auxiliary
//! images, texture images, triangle meshes with their BVH (including
//! the temporaries of the build), and photon maps. [`crate::scene::build_limited`] checks it
//! three times: before anything is loaded (film and the meshes the
//! description holds), after each texture is read, and once all meshes are
//! read, before the BVH is built.

use crate::error::{Error, Result};

/// Bytes per pixel of the film: the exact sums (80), a pass's copy of them
/// (80), the checkpoint buffer (80), the output image (12) and its
/// encoding (12).
pub const FILM_BYTES_PER_PIXEL: u64 = 264;
/// Bytes per pixel of the auxiliary images: the exact sums (128), a pass's
/// copy (128), the checkpoint buffer (128) and three output images (36).
pub const AOV_BYTES_PER_PIXEL: u64 = 420;
/// Bytes per pixel of a G-buffer film's own sums (pbrt-v4's `Film
/// "gbuffer"`): the exact sums (400), a pass's copy (400), the checkpoint
/// buffer (400) and its 22 output channels (88), counted with the auxiliary
/// images.
pub const GBUFFER_BYTES_PER_PIXEL: u64 = 1288;
/// Meshes with at least this many triangles get their own tree over blocks
/// of four triangles; smaller ones are single triangles in the top-level
/// tree (see [`crate::accel::BLOCK_TREE_MIN_TRIANGLES`]), and cost more per
/// triangle.
pub const LARGE_MESH_MIN_TRIANGLES: u64 = crate::accel::BLOCK_TREE_MIN_TRIANGLES as u64;
/// Bytes per triangle of a large mesh with its share of the BVH at the peak
/// of the build: indices, the blocks of four triangles, the tree's nodes and
/// the build's temporaries. Measured with `examples/memory_probe.rs` (the
/// peak resident set of `scene::build` over what the description holds):
/// 106–125 bytes a triangle with its vertices for one mesh of a million
/// triangles, ten of 180 000, 2000 of 512 or 256 of 288; this price with
/// the vertices' gives 152–157.
pub const LARGE_MESH_BYTES_PER_TRIANGLE: u64 = 136;
/// Bytes per triangle of a small mesh, whose triangles are top-level
/// primitives: a reference (16), the vertices copied in tree order (36),
/// bounds, tree nodes and the build's temporaries. Measured as above:
/// 258–336 bytes a triangle with its vertices for meshes of 18 to 242
/// triangles (30 000 to 2000 of them); this price gives 320–356.
pub const SMALL_MESH_BYTES_PER_TRIANGLE: u64 = 300;
/// Bytes per mesh besides its triangles and vertices (its vectors, its
/// object record), which shows for meshes of a few triangles: 100 000
/// two-triangle quads peak at 454 bytes a triangle (estimated 620).
pub const BYTES_PER_MESH: u64 = 512;
/// Bytes per vertex: position, normal and texture coordinates.
pub const BYTES_PER_VERTEX: u64 = 32;
/// Bytes per texel of a decoded texture (linear RGB, f32).
pub const BYTES_PER_TEXEL: u64 = 12;
/// Bytes per texel of an environment map besides its image: the lookup
/// grid of radiance and density nodes (16) and two sampling densities, the
/// full and the compensated one, each with its nodes (4) and the f64
/// cumulative sums and guide tables of its cells (12).
pub const BYTES_PER_ENVIRONMENT_TEXEL: u64 = 48;
/// Photons stored per photon emitted, for the estimate: one at each
/// diffuse bounce until Russian roulette ends the path. Measured about 2 on
/// the Cornell box (394 k stored from 200 k emitted); 4 leaves room for
/// brighter scenes.
pub const STORED_PER_EMITTED: u64 = 4;
/// Bytes per stored photon: the photon (32), its kd-tree split axis (1), and
/// the per-thread lists the map is gathered from (32).
pub const BYTES_PER_PHOTON: u64 = 65;
/// Bytes of one pixel's sums on the film.
pub const PIXEL_SUM_BYTES: u64 = 80;
/// The limit used when the machine's memory cannot be read.
pub const FALLBACK_LIMIT: u64 = 4 << 30;

/// The parts of a render's memory, in bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// Film and output buffers.
    pub film: u64,
    /// Auxiliary images.
    pub aovs: u64,
    /// Triangle meshes and the BVH.
    pub geometry: u64,
    /// Texture and environment images.
    pub textures: u64,
    /// Photon maps (photon mapping and SPPM).
    pub photons: u64,
}

impl MemoryEstimate {
    /// The film's share for a `width`×`height` image, with or without
    /// auxiliary images.
    pub fn for_film(width: u32, height: u32, aovs: bool) -> MemoryEstimate {
        MemoryEstimate::for_filtered_film(width, height, aovs, 0)
    }

    /// [`MemoryEstimate::for_film`] for a filter that splats `margin`
    /// pixels beyond each 16-pixel tile: a pass's copy of the sums then
    /// covers the tiles with their margins, (16 + 2·margin)² / 16² times
    /// the image.
    pub fn for_filtered_film(width: u32, height: u32, aovs: bool, margin: u32) -> MemoryEstimate {
        let pixels = width as u64 * height as u64;
        let side = 16 + 2 * margin as u64;
        let splat_extra = PIXEL_SUM_BYTES * (side * side - 256) / 256;
        MemoryEstimate {
            film: pixels * (FILM_BYTES_PER_PIXEL + splat_extra),
            aovs: if aovs { pixels * AOV_BYTES_PER_PIXEL } else { 0 },
            ..MemoryEstimate::default()
        }
    }

    /// Everything.
    pub fn total(&self) -> u64 {
        self.film
            .saturating_add(self.aovs)
            .saturating_add(self.geometry)
            .saturating_add(self.textures)
            .saturating_add(self.photons)
    }

    /// An error if the total exceeds `limit`, naming each part.
    pub fn check(&self, limit: Option<u64>) -> Result<()> {
        match limit {
            Some(limit) if self.total() > limit => Err(Error::Invalid(format!(
                "the render needs about {} (film {}, auxiliary images {}, geometry {}, textures {}, photon maps {}), more than the memory limit of {}: lower the resolution or the photon counts, or raise the limit with --max-memory",
                format_bytes(self.total()),
                format_bytes(self.film),
                format_bytes(self.aovs),
                format_bytes(self.geometry),
                format_bytes(self.textures),
                format_bytes(self.photons),
                format_bytes(limit)
            ))),
            _ => Ok(()),
        }
    }
}

/// Bytes of the photon maps of `emitted` photons.
pub fn photon_bytes(emitted: u64) -> u64 {
    emitted.saturating_mul(STORED_PER_EMITTED * BYTES_PER_PHOTON)
}

/// Bytes of vertex merging's stored light vertices for `paths` light
/// subpaths of at most `max_depth` segments (each stores its surface
/// vertices but the last; counted as photon maps count stored photons,
/// at most [`STORED_PER_EMITTED`] a path, each held twice while the tree
/// is built).
pub fn light_vertex_bytes(paths: u64, max_depth: u32) -> u64 {
    let per_path = (max_depth.saturating_sub(1) as u64).min(STORED_PER_EMITTED);
    paths.saturating_mul(per_path * 2 * BYTES_PER_LIGHT_VERTEX)
}

/// A stored light vertex of vertex merging, with its kd-tree axis.
pub const BYTES_PER_LIGHT_VERTEX: u64 = 81;

/// Bytes of a mesh of `triangles` triangles and `vertices` vertices, with
/// its BVH.
pub fn mesh_bytes(triangles: u64, vertices: u64) -> u64 {
    let per_triangle = if triangles >= LARGE_MESH_MIN_TRIANGLES {
        LARGE_MESH_BYTES_PER_TRIANGLE
    } else {
        SMALL_MESH_BYTES_PER_TRIANGLE
    };
    triangles
        .saturating_mul(per_triangle)
        .saturating_add(vertices.saturating_mul(BYTES_PER_VERTEX))
        .saturating_add(BYTES_PER_MESH)
}

/// Bytes of `count` analytic shapes and instances in the top-level tree:
/// each costs about what a small mesh's triangle does.
pub fn top_level_bytes(count: u64) -> u64 {
    count.saturating_mul(SMALL_MESH_BYTES_PER_TRIANGLE)
}

/// "1.5 GiB", "512 MiB", "900 KiB", "12 bytes".
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [(&str, u64); 4] = [("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)];
    for (name, size) in UNITS {
        if bytes >= size {
            return format!("{:.1} {name}", bytes as f64 / size as f64);
        }
    }
    format!("{bytes} bytes")
}

/// Parses a size: a number of bytes with an optional unit K, M, G or T
/// (powers of 1024; "KB", "KiB", "MB", "MiB", … mean the same), e.g.
/// `512M`, `4G`, `1.5GiB`, `1000000`.
pub fn parse_size(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .parse()
        .map_err(|_| format!("expected a size such as 512M or 4G, got \"{text}\""))?;
    let unit = unit.trim().to_ascii_uppercase();
    let scale: u64 = match unit.trim_end_matches("IB").trim_end_matches('B') {
        "" => 1,
        "K" => 1 << 10,
        "M" => 1 << 20,
        "G" => 1 << 30,
        "T" => 1 << 40,
        _ => return Err(format!("unknown unit in \"{text}\": use K, M, G or T")),
    };
    let bytes = value * scale as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("\"{text}\" is not a usable size"));
    }
    Ok(bytes as u64)
}

/// The machine's physical memory, where it can be read (Linux:
/// `/proc/meminfo`).
pub fn machine_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The default memory limit: 90% of the machine's memory, or
/// [`FALLBACK_LIMIT`] where it cannot be read.
pub fn default_limit() -> u64 {
    machine_memory().map_or(FALLBACK_LIMIT, |m| m / 10 * 9)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_units() {
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("4G"), Ok(4 << 30));
        assert_eq!(parse_size("4gib"), Ok(4 << 30));
        assert_eq!(parse_size("1.5GB"), Ok(3 << 29));
        assert_eq!(parse_size("1000"), Ok(1000));
        assert_eq!(parse_size(" 2 T "), Ok(2 << 40));
        for bad in ["", "G", "-1G", "4X", "0", "1e99T", "nan"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }

    /// A splatting filter's tile margins are counted: Mitsuba's Gaussian
    /// (margin 2) holds 20² / 16² of the image in a pass's copy.
    #[test]
    fn splat_margins_add_to_the_film() {
        let plain = MemoryEstimate::for_film(100, 100, false).film;
        let splat = MemoryEstimate::for_filtered_film(100, 100, false, 2).film;
        assert_eq!(splat - plain, 100 * 100 * (PIXEL_SUM_BYTES * (400 - 256) / 256));
    }

    #[test]
    fn the_refusal_names_every_part() {
        let e = MemoryEstimate::for_film(1000, 1000, true);
        assert_eq!(e.total(), 1_000_000 * (FILM_BYTES_PER_PIXEL + AOV_BYTES_PER_PIXEL));
        assert!(e.check(Some(e.total())).is_ok());
        assert!(e.check(None).is_ok());
        let msg = e.check(Some(100 << 20)).unwrap_err().to_string();
        assert!(msg.contains("film 251.8 MiB") && msg.contains("100.0 MiB"), "{msg}");
    }

    #[test]
    fn the_default_limit_follows_the_machine() {
        let limit = default_limit();
        match machine_memory() {
            Some(m) => assert!(limit < m && limit > m / 2),
            None => assert_eq!(limit, FALLBACK_LIMIT),
        }
    }
}
