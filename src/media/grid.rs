//! Voxel grids of medium properties, and Mitsuba 3's `.vol` grid files.
//!
//! A grid holds `res.x × res.y × res.z` voxels of one or three channels,
//! over the unit cube of its own space; it is read trilinearly between
//! voxel centres ((i + ½)/res). Past the outermost centres it either keeps
//! the edge values (Mitsuba's `gridvolume`, clamped) or fades to zero, as
//! if surrounded by empty voxels (pbrt-v4's `SampledGrid`).

use crate::color::Rgb;
use crate::error::{Error, Result};
use glam::Vec3;
use std::path::Path;

/// The most voxels a grid file may declare (a 2048³ grid of one float is
/// 32 GiB; this is 2 GiB): a larger header is refused before allocating.
pub const MAX_VOXELS: u64 = 1 << 29;

/// What a grid is read as past its outermost voxel centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GridEdge {
    /// The edge voxels' values (Mitsuba).
    #[default]
    Clamp,
    /// Zero outside the grid, so values fade over the last half voxel
    /// (pbrt-v4).
    Zero,
}

/// A voxel grid over the unit cube.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelGrid {
    /// Voxels along x, y and z.
    pub res: [usize; 3],
    /// Values per voxel: 1 (a density) or 3 (a colour).
    pub channels: usize,
    /// The values, x fastest, then y, then z, channels innermost.
    pub data: Vec<f32>,
    /// The box the file says the grid spans (Mitsuba's `use_grid_bbox`).
    pub file_bounds: (Vec3, Vec3),
    /// How the grid is read past its outermost voxel centres.
    pub edge: GridEdge,
    /// The box of the unit cube outside which the grid reads 0, if any: a
    /// NanoVDB grid's active box, to which pbrt-v4 clips its medium.
    pub support: Option<(Vec3, Vec3)>,
}

impl VoxelGrid {
    /// A grid of the given values (checked: `data` holds every voxel).
    pub fn new(res: [usize; 3], channels: usize, data: Vec<f32>) -> std::result::Result<VoxelGrid, String> {
        if res.contains(&0) || !(channels == 1 || channels == 3) {
            return Err(format!(
                "a grid needs at least one voxel and 1 or 3 channels, not {res:?} voxels of {channels}"
            ));
        }
        if data.len() != res[0] * res[1] * res[2] * channels {
            return Err(format!(
                "a {}×{}×{} grid of {channels} channels needs {} values, not {}",
                res[0],
                res[1],
                res[2],
                res[0] * res[1] * res[2] * channels,
                data.len()
            ));
        }
        Ok(VoxelGrid {
            res,
            channels,
            data,
            file_bounds: (Vec3::ZERO, Vec3::ONE),
            edge: GridEdge::Clamp,
            support: None,
        })
    }

    /// Reads a Mitsuba `.vol` file: the bytes `VOL`, version 3, encoding
    /// 1 (32-bit float), the resolution, the channel count and the
    /// bounding box, then the values (all little-endian).
    pub fn parse_mitsuba_vol(bytes: &[u8]) -> std::result::Result<VoxelGrid, String> {
        if bytes.len() < 48 || &bytes[..3] != b"VOL" {
            return Err("not a Mitsuba volume file (it does not start with \"VOL\" and a 48-byte header)".into());
        }
        if bytes[3] != 3 {
            return Err(format!(
                "volume file version {} is unsupported (trazo reads version 3)",
                bytes[3]
            ));
        }
        let int = |at: usize| i32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
        let float = |at: usize| f32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
        if int(4) != 1 {
            return Err(format!(
                "volume encoding {} is unsupported (trazo reads 1, 32-bit floats)",
                int(4)
            ));
        }
        let (x, y, z, c) = (int(8), int(12), int(16), int(20));
        if x <= 0 || y <= 0 || z <= 0 || !(c == 1 || c == 3) {
            return Err(format!(
                "the header declares {x}×{y}×{z} voxels of {c} channels (trazo reads positive sizes and 1 or 3 channels)"
            ));
        }
        let count = x as u64 * y as u64 * z as u64 * c as u64;
        if count > MAX_VOXELS {
            return Err(format!(
                "the header declares {count} values, more than the {MAX_VOXELS} trazo reads"
            ));
        }
        let needed = 48 + count as usize * 4;
        if bytes.len() < needed {
            return Err(format!(
                "the file ends after {} bytes; its header declares {count} values ({needed} bytes)",
                bytes.len()
            ));
        }
        let data: Vec<f32> = bytes[48..needed]
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes")))
            .collect();
        let mut grid = VoxelGrid::new([x as usize, y as usize, z as usize], c as usize, data)?;
        let min = Vec3::new(float(24), float(28), float(32));
        let max = Vec3::new(float(36), float(40), float(44));
        if min.is_finite() && max.is_finite() && min.cmplt(max).all() {
            grid.file_bounds = (min, max);
        }
        Ok(grid)
    }

    /// Reads a Mitsuba `.vol` file from disk.
    pub fn load_mitsuba_vol(path: &Path) -> Result<VoxelGrid> {
        let limit = 48 + MAX_VOXELS * 4;
        let bytes = crate::files::read_limited(path, limit).map_err(|e| Error::file(path, e))?;
        VoxelGrid::parse_mitsuba_vol(&bytes).map_err(|e| Error::file(path, e))
    }

    /// Replaces NaN, infinite and negative values by 0; returns how many
    /// there were.
    pub fn sanitize(&mut self) -> usize {
        let mut bad = 0;
        for v in &mut self.data {
            if !v.is_finite() || *v < 0.0 {
                *v = 0.0;
                bad += 1;
            }
        }
        bad
    }

    /// The value of voxel (x, y, z).
    #[inline]
    fn voxel(&self, x: usize, y: usize, z: usize) -> Rgb {
        let i = ((z * self.res[1] + y) * self.res[0] + x) * self.channels;
        if self.channels == 1 {
            Rgb::splat(self.data[i])
        } else {
            Rgb::new(self.data[i], self.data[i + 1], self.data[i + 2])
        }
    }

    /// The trilinear value at `p` in the unit cube (outside it: see
    /// [`GridEdge`]).
    #[inline]
    pub fn lookup(&self, p: Vec3) -> Rgb {
        if let Some((lo, hi)) = self.support {
            if p.cmplt(lo).any() || p.cmpgt(hi).any() {
                return Rgb::ZERO;
            }
        }
        let zero_edge = self.edge == GridEdge::Zero;
        // Per axis: the two voxel indices either side of `p` (None: outside
        // a zero-edged grid) and the weight of the second.
        let mut index = [[None::<usize>; 2]; 3];
        let mut frac = [0f32; 3];
        for a in 0..3 {
            let n = self.res[a] as i64;
            let x = p[a] * n as f32 - 0.5;
            if zero_edge {
                let x = x.clamp(-1.0, n as f32);
                let i = crate::math::floor(x) as i64;
                frac[a] = x - i as f32;
                for (k, slot) in index[a].iter_mut().enumerate() {
                    let j = i + k as i64;
                    *slot = (0..n).contains(&j).then_some(j as usize);
                }
            } else {
                let x = x.clamp(0.0, (n - 1) as f32);
                let i = (crate::math::floor(x) as i64).min(n - 1);
                frac[a] = x - i as f32;
                index[a] = [Some(i as usize), Some((i + 1).min(n - 1) as usize)];
            }
        }
        let at = |x: Option<usize>, y: Option<usize>, z: Option<usize>| match (x, y, z) {
            (Some(x), Some(y), Some(z)) => self.voxel(x, y, z),
            _ => Rgb::ZERO,
        };
        let lerp = |a: Rgb, b: Rgb, t: f32| a + (b - a) * t;
        let [[x0, x1], [y0, y1], [z0, z1]] = index;
        let [fx, fy, fz] = frac;
        let c00 = lerp(at(x0, y0, z0), at(x1, y0, z0), fx);
        let c10 = lerp(at(x0, y1, z0), at(x1, y1, z0), fx);
        let c01 = lerp(at(x0, y0, z1), at(x1, y0, z1), fx);
        let c11 = lerp(at(x0, y1, z1), at(x1, y1, z1), fx);
        lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz)
    }

    /// The largest value of each channel (a bound on every trilinear value).
    pub fn max(&self) -> Rgb {
        let mut m = Rgb::ZERO;
        for z in 0..self.res[2] {
            for y in 0..self.res[1] {
                for x in 0..self.res[0] {
                    m = m.max(self.voxel(x, y, z));
                }
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vol_bytes(res: [i32; 3], channels: i32, values: &[f32]) -> Vec<u8> {
        let mut b = b"VOL\x03".to_vec();
        for v in [1, res[0], res[1], res[2], channels] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        for v in [0.0f32, 0.0, 0.0, 1.0, 1.0, 1.0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        for v in values {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b
    }

    #[test]
    fn reads_a_vol_file_and_interpolates_between_voxel_centres() {
        // 2×1×1: 0 at the left voxel's centre (x = 1/4), 4 at the right's (3/4).
        let g = VoxelGrid::parse_mitsuba_vol(&vol_bytes([2, 1, 1], 1, &[0.0, 4.0])).unwrap();
        assert_eq!(g.res, [2, 1, 1]);
        assert_eq!(g.lookup(Vec3::new(0.25, 0.5, 0.5)).x, 0.0);
        assert_eq!(g.lookup(Vec3::new(0.5, 0.5, 0.5)).x, 2.0);
        assert_eq!(g.lookup(Vec3::new(0.75, 0.1, 0.9)).x, 4.0);
        // Clamped at the edges and outside.
        assert_eq!(g.lookup(Vec3::new(0.0, 0.5, 0.5)).x, 0.0);
        assert_eq!(g.lookup(Vec3::new(7.0, -3.0, 0.5)).x, 4.0);
        assert_eq!(g.max(), Rgb::splat(4.0));
        // Zero-edged (pbrt-v4): fades to 0 over the last half voxel.
        let mut z = g.clone();
        z.edge = GridEdge::Zero;
        assert_eq!(z.lookup(Vec3::new(0.5, 0.5, 0.5)).x, 2.0);
        assert_eq!(z.lookup(Vec3::new(0.875, 0.5, 0.5)).x, 3.0);
        // At the cube's face, half way between the last centre and zero.
        assert_eq!(z.lookup(Vec3::new(1.0, 0.5, 0.5)).x, 2.0);
        assert_eq!(z.lookup(Vec3::new(1.5, 0.5, 0.5)).x, 0.0);
        // A quarter voxel out of the one-voxel-thick y axis: ¾ of the value.
        assert_eq!(z.lookup(Vec3::new(0.75, 0.25, 0.5)).x, 3.0);
        // Three channels.
        let g = VoxelGrid::parse_mitsuba_vol(&vol_bytes([1, 1, 1], 3, &[0.1, 0.2, 0.3])).unwrap();
        assert_eq!(g.lookup(Vec3::splat(0.5)), Rgb::new(0.1, 0.2, 0.3));
    }

    #[test]
    fn refuses_bad_headers_before_allocating() {
        assert!(VoxelGrid::parse_mitsuba_vol(b"VOX").is_err());
        let short = vol_bytes([2, 2, 2], 1, &[1.0; 7]);
        assert!(VoxelGrid::parse_mitsuba_vol(&short).unwrap_err().contains("ends after"));
        let huge = vol_bytes([100_000, 100_000, 100_000], 1, &[]);
        assert!(VoxelGrid::parse_mitsuba_vol(&huge).unwrap_err().contains("more than"));
        let negative = vol_bytes([-1, 2, 2], 1, &[]);
        assert!(VoxelGrid::parse_mitsuba_vol(&negative).is_err());
        let channels = vol_bytes([1, 1, 1], 2, &[1.0, 1.0]);
        assert!(VoxelGrid::parse_mitsuba_vol(&channels).is_err());
        let mut version = vol_bytes([1, 1, 1], 1, &[1.0]);
        version[3] = 2;
        assert!(VoxelGrid::parse_mitsuba_vol(&version).unwrap_err().contains("version"));
    }
}
