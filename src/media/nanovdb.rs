//! NanoVDB grid files (`.nvdb`; Museth 2021, "NanoVDB: A GPU-Friendly and
//! Portable VDB Data Structure"), the files pbrt-v4's `nanovdb` medium
//! reads: sparse trees of voxels (a root table of 4096³ tiles, internal
//! nodes of 32³ and 16³ children, leaves of 8³ voxels), one or more grids
//! per file, each stored raw or zlib-compressed.
//!
//! trazo reads grids of 32-bit floats (pbrt-v4 reads no other kind) of
//! format version 32, the one OpenVDB and NanoVDB have written since 2021,
//! and turns one into a dense [`VoxelGrid`] over the box of its active
//! voxels, so that the medium code has one kind of grid. Values are those
//! NanoVDB's trilinear sampler (`SampleFromVoxels` of order 1) gives: voxel
//! centres at integer index coordinates, the tree's value (a leaf's, a
//! tile's or the background) at every voxel. The grid reads 0 outside the
//! box of its active voxels, [lo, hi + 1] in index space, which is the
//! world box pbrt-v4 clips the medium to.
//!
//! Every offset in the file is checked against the buffer before it is
//! followed; sizes are checked against limits before anything is
//! allocated.

use super::grid::{GridEdge, MAX_VOXELS, VoxelGrid};
use glam::{DMat3, DMat4, DVec3, Mat4};
use std::collections::HashMap;

/// "NanoVDB0": the magic number of files (and of grids before 32.6).
const MAGIC_V0: u64 = 0x3042_4456_6f6e_614e;
/// "NanoVDB1": the magic number of a grid since 32.6.
const MAGIC_GRID: u64 = 0x3142_4456_6f6e_614e;
/// "NanoVDB2": the magic number of a file since 32.6.
const MAGIC_FILE: u64 = 0x3242_4456_6f6e_614e;
/// The format (major) version trazo reads.
const MAJOR_VERSION: u32 = 32;

// Sizes and offsets of the version-32 layout, for grids of floats.
const FILE_HEADER_SIZE: usize = 16;
const FILE_METADATA_SIZE: usize = 176;
const GRID_DATA_SIZE: usize = 672;
const GRID_MAP: usize = 296;
const GRID_CLASS: usize = 632;
const GRID_TYPE: usize = 636;
const TREE_ROOT_OFFSET: usize = 24;
const TREE_SIZE: usize = 64;
const ROOT_TILE_COUNT: usize = 24;
const ROOT_BACKGROUND: usize = 28;
const ROOT_SIZE: usize = 64;
const ROOT_TILE_SIZE: usize = 32;
const UPPER_VALUE_MASK: usize = 32;
const UPPER_CHILD_MASK: usize = 4128;
const UPPER_TABLE: usize = 8256;
const UPPER_SIZE: usize = 270_400;
const LOWER_VALUE_MASK: usize = 32;
const LOWER_CHILD_MASK: usize = 544;
const LOWER_TABLE: usize = 1088;
const LOWER_SIZE: usize = 33_856;
const LEAF_VALUE_MASK: usize = 16;
const LEAF_VALUES: usize = 96;
const LEAF_SIZE: usize = 2144;

/// The value type of a grid of 32-bit floats.
const TYPE_FLOAT: u32 = 1;
/// The class of a narrow-band level set (signed distances).
pub const CLASS_LEVEL_SET: u32 = 1;
/// The class of a fog volume (densities).
pub const CLASS_FOG_VOLUME: u32 = 2;

/// Largest grid, in bytes, that trazo decompresses or reads (the tree of a
/// grid of [`MAX_VOXELS`] voxels in leaves is about 4.2 bytes a voxel).
pub const MAX_GRID_BYTES: u64 = 5 * MAX_VOXELS;

/// A grid of floats read from a NanoVDB file, its tree checked.
#[derive(Clone, Debug)]
pub struct NanoVdbGrid {
    /// The grid's name (pbrt-v4 looks for "density" and "temperature").
    pub name: String,
    /// Its class ([`CLASS_LEVEL_SET`], [`CLASS_FOG_VOLUME`], 0: unknown…).
    pub class: u32,
    buffer: Vec<u8>,
    /// The root's address in `buffer`.
    root: usize,
    /// Root tiles by key, each the address of its tile.
    tiles: HashMap<u64, usize>,
    background: f32,
    /// Index space to the grid's space: x ↦ matrix·x + translation.
    matrix: DMat3,
    translation: DVec3,
    /// The box of the active voxels and tiles, inclusive, in index space
    /// (`None`: nothing is active).
    active: Option<([i32; 3], [i32; 3])>,
}

/// A block of 8³ voxels: a leaf, or one value throughout (a tile or the
/// background).
#[derive(Clone, Copy, PartialEq)]
enum Block {
    Leaf(usize),
    Value(f32),
}

/// Little-endian reads that fail with a message past the end of `b`.
fn bytes_at<const N: usize>(b: &[u8], at: usize) -> Result<[u8; N], String> {
    at.checked_add(N)
        .and_then(|end| b.get(at..end))
        .map(|s| s.try_into().expect("N bytes"))
        .ok_or_else(|| format!("the data ends before byte {}", at.saturating_add(N)))
}
fn u16_at(b: &[u8], at: usize) -> Result<u16, String> {
    bytes_at(b, at).map(u16::from_le_bytes)
}
fn u32_at(b: &[u8], at: usize) -> Result<u32, String> {
    bytes_at(b, at).map(u32::from_le_bytes)
}
fn u64_at(b: &[u8], at: usize) -> Result<u64, String> {
    bytes_at(b, at).map(u64::from_le_bytes)
}
fn f32_at(b: &[u8], at: usize) -> Result<f32, String> {
    bytes_at(b, at).map(f32::from_le_bytes)
}
fn f64_at(b: &[u8], at: usize) -> Result<f64, String> {
    bytes_at(b, at).map(f64::from_le_bytes)
}

/// The name of a NanoVDB value type, for messages.
fn type_name(t: u32) -> String {
    const NAMES: [&str; 27] = [
        "unknown",
        "float",
        "double",
        "int16",
        "int32",
        "int64",
        "vec3f",
        "vec3d",
        "mask",
        "half",
        "uint32",
        "boolean",
        "rgba8",
        "fp4",
        "fp8",
        "fp16",
        "fpN",
        "vec4f",
        "vec4d",
        "index",
        "onindex",
        "indexmask",
        "onindexmask",
        "pointindex",
        "vec3u8",
        "vec3u16",
        "uint8",
    ];
    NAMES
        .get(t as usize)
        .map_or_else(|| format!("type {t}"), |n| (*n).to_string())
}

/// The root-table key of the 4096³ tile holding index `ijk`.
fn tile_key(ijk: [i32; 3]) -> u64 {
    let [i, j, k] = ijk.map(|c| u64::from(c as u32 >> 12));
    k | (j << 21) | (i << 42)
}

/// The origin of the tile of root-table key `key`.
fn tile_origin(key: u64) -> [i32; 3] {
    let part = |shift: u32| ((((key >> shift) & 0x1f_ffff) as u32) << 12) as i32;
    [part(42), part(21), part(0)]
}

/// Whether bit `n` of the mask at `at` is set.
fn bit(b: &[u8], at: usize, n: usize) -> Result<bool, String> {
    Ok(u32_at(b, at + 4 * (n >> 5))? >> (n & 31) & 1 != 0)
}

/// The grids of a NanoVDB file, by name, with their value type and class:
/// `(name, value type, class, the grid's bytes)`, decompressed; the bytes
/// of grids whose name `wanted` rejects are left out (`None`), unread.
type GridEntry = (String, u32, u32, Option<Vec<u8>>);
fn read_grids(bytes: &[u8], wanted: &dyn Fn(&str) -> bool) -> Result<Vec<GridEntry>, String> {
    let mut grids = Vec::new();
    let mut at = 0;
    // A file is one or more segments: a header, the grids' metadata and
    // names, then the grids' bytes in the same order.
    while at < bytes.len() {
        let magic = u64_at(bytes, at)?;
        if !matches!(magic, MAGIC_V0 | MAGIC_FILE) {
            return Err(if at == 0 {
                "not a NanoVDB file (it does not start with \"NanoVDB\")".into()
            } else {
                format!("byte {at}: a segment does not start with \"NanoVDB\"")
            });
        }
        let version = u32_at(bytes, at + 8)?;
        let (major, minor, patch) = (version >> 21, (version >> 10) & 0x7ff, version & 0x3ff);
        if major != MAJOR_VERSION {
            return Err(format!(
                "NanoVDB format version {major}.{minor}.{patch} is unsupported (trazo reads version {MAJOR_VERSION}, written since 2021)"
            ));
        }
        let count = u16_at(bytes, at + 12)? as usize;
        let codec = u16_at(bytes, at + 14)?;
        at += FILE_HEADER_SIZE;
        let mut metas = Vec::with_capacity(count.min(1024));
        for _ in 0..count {
            let grid_size = u64_at(bytes, at)?;
            let file_size = u64_at(bytes, at + 8)?;
            let value_type = u32_at(bytes, at + 32)?;
            let class = u32_at(bytes, at + 36)?;
            let name_size = u32_at(bytes, at + 136)? as usize;
            let name_at = at + FILE_METADATA_SIZE;
            let name = bytes
                .get(name_at..name_at.saturating_add(name_size))
                .ok_or("the file ends inside a grid's name")?;
            let name = String::from_utf8_lossy(name.split(|&c| c == 0).next().unwrap_or_default()).into_owned();
            metas.push((name, value_type, class, grid_size, file_size));
            at = name_at + name_size;
        }
        for (name, value_type, class, grid_size, file_size) in metas {
            let end = usize::try_from(file_size)
                .ok()
                .and_then(|s| at.checked_add(s))
                .filter(|&e| e <= bytes.len())
                .ok_or_else(|| format!("grid \"{name}\": the file ends inside its {file_size} bytes"))?;
            let stored = &bytes[at..end];
            at = end;
            if !wanted(&name) {
                grids.push((name, value_type, class, None));
                continue;
            }
            if grid_size > MAX_GRID_BYTES {
                return Err(format!(
                    "grid \"{name}\" declares {grid_size} bytes, more than the {MAX_GRID_BYTES} trazo reads"
                ));
            }
            let data = match codec {
                0 => stored.to_vec(),
                1 => inflate_chunks(stored, grid_size).map_err(|e| format!("grid \"{name}\": {e}"))?,
                2 => {
                    return Err(format!(
                        "grid \"{name}\" is compressed with Blosc, which trazo does not read (convert it with `nanovdb_convert` without `--blosc`, or with `--zip`)"
                    ));
                }
                c => return Err(format!("grid \"{name}\": unknown compression codec {c}")),
            };
            if data.len() as u64 != grid_size {
                return Err(format!(
                    "grid \"{name}\" holds {} bytes where its header declares {grid_size}",
                    data.len()
                ));
            }
            grids.push((name, value_type, class, Some(data)));
        }
    }
    Ok(grids)
}

/// Inflates a grid stored with the ZIP codec: chunks of a 64-bit size and
/// that many bytes of zlib data, to at most `limit` bytes.
fn inflate_chunks(mut stored: &[u8], limit: u64) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let mut out = Vec::new();
    while !stored.is_empty() {
        let size = u64_at(stored, 0)?;
        let chunk = usize::try_from(size)
            .ok()
            .and_then(|s| stored.get(8..8usize.checked_add(s)?))
            .ok_or("a compressed chunk runs past the grid's bytes")?;
        let room = limit.saturating_sub(out.len() as u64);
        let before = out.len();
        flate2::read::ZlibDecoder::new(chunk)
            .take(room.saturating_add(1))
            .read_to_end(&mut out)
            .map_err(|e| format!("its compressed data is corrupt ({e})"))?;
        if (out.len() - before) as u64 > room {
            return Err(format!(
                "it inflates to more than the {limit} bytes its header declares"
            ));
        }
        stored = &stored[8 + chunk.len()..];
    }
    Ok(out)
}

/// The names of the grids of a NanoVDB file.
pub fn grid_names(bytes: &[u8]) -> Result<Vec<String>, String> {
    Ok(read_grids(bytes, &|_| false)?.into_iter().map(|g| g.0).collect())
}

impl NanoVdbGrid {
    /// The grid named `name` of NanoVDB file `bytes`: `Ok(None)` if the
    /// file has none of that name; an error if the file is malformed or
    /// the grid does not hold 32-bit floats.
    pub fn from_file(bytes: &[u8], name: &str) -> Result<Option<NanoVdbGrid>, String> {
        let found = read_grids(bytes, &|n| n == name)?
            .into_iter()
            .find_map(|(n, t, c, data)| Some((n, t, c, data?)));
        let Some((name, value_type, class, data)) = found else {
            return Ok(None);
        };
        if value_type != TYPE_FLOAT {
            return Err(format!(
                "grid \"{name}\" holds {} values (trazo reads grids of floats, as pbrt-v4 does)",
                type_name(value_type)
            ));
        }
        NanoVdbGrid::from_buffer(name, class, data).map(Some)
    }

    /// Checks and indexes the bytes of one grid of floats.
    fn from_buffer(name: String, class: u32, buffer: Vec<u8>) -> Result<NanoVdbGrid, String> {
        let err = |e: String| format!("grid \"{name}\": {e}");
        let b = &buffer[..];
        if b.len() < GRID_DATA_SIZE + TREE_SIZE {
            return Err(err(format!("{} bytes are too few for a grid", b.len())));
        }
        if !matches!(u64_at(b, 0).map_err(err)?, MAGIC_V0 | MAGIC_GRID) {
            return Err(err("its data does not start with \"NanoVDB\"".into()));
        }
        if u32_at(b, GRID_TYPE).map_err(err)? != TYPE_FLOAT {
            return Err(err("its data does not hold floats".into()));
        }
        let class = if class == 0 {
            u32_at(b, GRID_CLASS).map_err(err)?
        } else {
            class
        };
        // The map's double-precision matrix (row by row) and translation.
        let m = |k: usize| f64_at(b, GRID_MAP + 88 + 8 * k);
        let t = |k: usize| f64_at(b, GRID_MAP + 232 + 8 * k);
        let rows = [
            DVec3::new(m(0).map_err(err)?, m(1).map_err(err)?, m(2).map_err(err)?),
            DVec3::new(m(3).map_err(err)?, m(4).map_err(err)?, m(5).map_err(err)?),
            DVec3::new(m(6).map_err(err)?, m(7).map_err(err)?, m(8).map_err(err)?),
        ];
        let matrix = DMat3::from_cols(rows[0], rows[1], rows[2]).transpose();
        let translation = DVec3::new(t(0).map_err(err)?, t(1).map_err(err)?, t(2).map_err(err)?);
        if !(matrix.is_finite() && translation.is_finite()) || matrix.determinant().abs() < 1e-300 {
            return Err(err("its index-to-world map is not invertible".into()));
        }
        let tree = GRID_DATA_SIZE;
        let root = tree
            .checked_add(u64_at(b, tree + TREE_ROOT_OFFSET).map_err(err)? as usize)
            .filter(|r| r.checked_add(ROOT_SIZE).is_some_and(|e| e <= b.len()))
            .ok_or_else(|| err("its root lies outside its bytes".into()))?;
        let background = f32_at(b, root + ROOT_BACKGROUND).map_err(err)?;
        let count = u32_at(b, root + ROOT_TILE_COUNT).map_err(err)? as usize;
        if count > (b.len() - root - ROOT_SIZE) / ROOT_TILE_SIZE {
            return Err(err(format!(
                "its root declares {count} tiles, more than its bytes hold"
            )));
        }
        let mut grid = NanoVdbGrid {
            name: name.clone(),
            class,
            buffer: Vec::new(),
            root,
            tiles: HashMap::with_capacity(count),
            background,
            matrix,
            translation,
            active: None,
        };
        let mut active = Bounds::default();
        for k in 0..count {
            let tile = root + ROOT_SIZE + k * ROOT_TILE_SIZE;
            let key = u64_at(b, tile).map_err(err)?;
            let child = u64_at(b, tile + 8).map_err(err)? as i64;
            let state = u32_at(b, tile + 16).map_err(err)?;
            let origin = tile_origin(key);
            if child == 0 {
                if state != 0 {
                    active.add_cube(origin, 4096);
                }
            } else {
                let upper = node(b, root, child, UPPER_SIZE).map_err(|e| err(format!("root tile {k}: {e}")))?;
                check_upper(b, upper, origin, &mut active).map_err(err)?;
            }
            grid.tiles.insert(key, tile);
        }
        grid.active = active.get();
        grid.buffer = buffer;
        Ok(grid)
    }

    /// The value of voxel `ijk` (the tree's: a leaf's, a tile's, or the
    /// background).
    pub fn value(&self, ijk: [i32; 3]) -> f32 {
        match self.block(ijk) {
            Block::Leaf(leaf) => self.leaf_value(leaf, ijk),
            Block::Value(v) => v,
        }
    }

    fn leaf_value(&self, leaf: usize, [x, y, z]: [i32; 3]) -> f32 {
        let n = ((x & 7) << 6 | (y & 7) << 3 | (z & 7)) as usize;
        // In range: the tree was checked when it was read.
        f32_at(&self.buffer, leaf + LEAF_VALUES + 4 * n).unwrap_or(self.background)
    }

    /// The block of 8³ voxels holding `ijk`.
    fn block(&self, ijk: [i32; 3]) -> Block {
        let b = &self.buffer[..];
        let Some(&tile) = self.tiles.get(&tile_key(ijk)) else {
            return Block::Value(self.background);
        };
        // Reads cannot fail (the tree was checked); `background` stands in.
        let value = |at: usize| Block::Value(f32_at(b, at).unwrap_or(self.background));
        let child = u64_at(b, tile + 8).unwrap_or(0) as i64;
        if child == 0 {
            return value(tile + 20);
        }
        let [x, y, z] = ijk.map(|c| c as usize);
        let upper = (self.root as i64 + child) as usize;
        let n = ((x & 4095) >> 7) << 10 | ((y & 4095) >> 7) << 5 | ((z & 4095) >> 7);
        if !bit(b, upper + UPPER_CHILD_MASK, n).unwrap_or(false) {
            return value(upper + UPPER_TABLE + 8 * n);
        }
        let lower = (upper as i64 + u64_at(b, upper + UPPER_TABLE + 8 * n).unwrap_or(0) as i64) as usize;
        let n = ((x & 127) >> 3) << 8 | ((y & 127) >> 3) << 4 | ((z & 127) >> 3);
        if !bit(b, lower + LOWER_CHILD_MASK, n).unwrap_or(false) {
            return value(lower + LOWER_TABLE + 8 * n);
        }
        Block::Leaf((lower as i64 + u64_at(b, lower + LOWER_TABLE + 8 * n).unwrap_or(0) as i64) as usize)
    }

    /// The box of the active voxels and tiles, inclusive, in index space.
    pub fn active_box(&self) -> Option<([i32; 3], [i32; 3])> {
        self.active
    }

    /// The grid's space position of index-space point `p`.
    pub fn index_to_grid_space(&self, p: DVec3) -> DVec3 {
        self.matrix * p + self.translation
    }

    /// The tree's values on the lattice of voxels over the active box and
    /// one voxel past it on the high side, [lo, hi + 1] in index space (what
    /// the trilinear value up to the box's far faces reads), x fastest: the
    /// lattice's size, its values and `lo`. An error if it holds more than
    /// [`MAX_VOXELS`] voxels; `None` if nothing is active.
    pub fn dense(&self) -> Result<Option<Lattice>, String> {
        let Some((lo, hi)) = self.active else {
            return Ok(None);
        };
        let res = [0, 1, 2].map(|a| (i64::from(hi[a]) - i64::from(lo[a]) + 2) as u64);
        let voxels = res.iter().product::<u64>();
        if voxels > MAX_VOXELS {
            return Err(format!(
                "grid \"{}\": its active voxels span {}×{}×{} voxels, more than the {MAX_VOXELS} trazo reads (trazo makes the grid dense)",
                self.name, res[0], res[1], res[2]
            ));
        }
        let res = res.map(|n| n as usize);
        let mut values = Vec::new();
        values
            .try_reserve_exact(voxels as usize)
            .map_err(|_| format!("grid \"{}\": no memory for {voxels} voxels", self.name))?;
        let mut cached: Option<([i32; 3], Block)> = None;
        for z in 0..res[2] as i32 {
            for y in 0..res[1] as i32 {
                for x in 0..res[0] as i32 {
                    let ijk = [lo[0] + x, lo[1] + y, lo[2] + z];
                    let key = ijk.map(|c| c >> 3);
                    let block = match cached {
                        Some((k, b)) if k == key => b,
                        _ => {
                            let b = self.block(ijk);
                            cached = Some((key, b));
                            b
                        }
                    };
                    values.push(match block {
                        Block::Leaf(leaf) => self.leaf_value(leaf, ijk),
                        Block::Value(v) => v,
                    });
                }
            }
        }
        Ok(Some(Lattice { res, values, lo }))
    }

    /// The map from index space to the grid's space, as a matrix.
    fn index_to_space(&self) -> DMat4 {
        DMat4::from_translation(self.translation) * DMat4::from_mat3(self.matrix)
    }

    /// The grid as a dense voxel grid (values at the voxel centres of its
    /// unit cube, as media read them; [`NanoVdbGrid::dense`]) that reads 0
    /// outside [lo, hi + 1], and the map from its unit cube to the grid's
    /// space.
    pub fn to_voxel_grid(&self) -> Result<Option<(VoxelGrid, Mat4)>, String> {
        let Some(Lattice { res, values, lo }) = self.dense()? else {
            return Ok(None);
        };
        let mut grid = VoxelGrid::new(res, 1, values)?;
        grid.edge = GridEdge::Zero;
        let n = glam::Vec3::new(res[0] as f32, res[1] as f32, res[2] as f32);
        grid.support = Some((glam::Vec3::splat(0.5) / n, (n - 0.5) / n));
        // Unit cube → index space (the centre of voxel k at lo + k).
        let lo = DVec3::new(f64::from(lo[0]), f64::from(lo[1]), f64::from(lo[2]));
        let res = DVec3::new(res[0] as f64, res[1] as f64, res[2] as f64);
        let unit_to_index = DMat4::from_translation(lo - 0.5) * DMat4::from_scale(res);
        Ok(Some((grid, (self.index_to_space() * unit_to_index).as_mat4())))
    }

    /// The map from the unit cube of a lattice's values placed at its
    /// corners (value k at k / (res − 1), as signed distance grids read
    /// them) to the grid's space.
    pub fn lattice_to_space(&self, lattice: &Lattice) -> Mat4 {
        let lo = DVec3::new(
            f64::from(lattice.lo[0]),
            f64::from(lattice.lo[1]),
            f64::from(lattice.lo[2]),
        );
        let cells = DVec3::new(
            lattice.res[0] as f64 - 1.0,
            lattice.res[1] as f64 - 1.0,
            lattice.res[2] as f64 - 1.0,
        );
        (self.index_to_space() * DMat4::from_translation(lo) * DMat4::from_scale(cells)).as_mat4()
    }
}

/// A grid's values on a dense lattice of voxels ([`NanoVdbGrid::dense`]).
#[derive(Clone, Debug)]
pub struct Lattice {
    /// Voxels along x, y and z.
    pub res: [usize; 3],
    /// The values, x fastest.
    pub values: Vec<f32>,
    /// The index of the first voxel.
    pub lo: [i32; 3],
}

/// The address of a node `offset` bytes from `from`, checked to hold
/// `size` bytes inside `b`.
fn node(b: &[u8], from: usize, offset: i64, size: usize) -> Result<usize, String> {
    i64::try_from(from)
        .ok()
        .and_then(|f| f.checked_add(offset))
        .and_then(|a| usize::try_from(a).ok())
        .filter(|&a| a.checked_add(size).is_some_and(|e| e <= b.len()))
        .ok_or_else(|| format!("a child offset ({offset}) points outside the grid's bytes"))
}

/// An inclusive box of voxels, grown point by point.
#[derive(Default)]
struct Bounds(Option<([i32; 3], [i32; 3])>);

impl Bounds {
    fn add(&mut self, lo: [i32; 3], hi: [i32; 3]) {
        self.0 = Some(match self.0 {
            None => (lo, hi),
            Some((a, b)) => ([0, 1, 2].map(|k| a[k].min(lo[k])), [0, 1, 2].map(|k| b[k].max(hi[k]))),
        });
    }
    fn add_cube(&mut self, origin: [i32; 3], side: i32) {
        self.add(origin, origin.map(|c| c.saturating_add(side - 1)));
    }
    fn get(&self) -> Option<([i32; 3], [i32; 3])> {
        self.0
    }
}

/// Checks an upper node at `upper` (origin `origin`) and its children,
/// growing `active` by what is active in them.
fn check_upper(b: &[u8], upper: usize, origin: [i32; 3], active: &mut Bounds) -> Result<(), String> {
    for n in 0..32 * 32 * 32 {
        let at = [n >> 10, (n >> 5) & 31, n & 31].map(|c| c as i32 * 128);
        let child_origin = [0, 1, 2].map(|k| origin[k].wrapping_add(at[k]));
        if bit(b, upper + UPPER_CHILD_MASK, n)? {
            let offset = u64_at(b, upper + UPPER_TABLE + 8 * n)? as i64;
            let lower = node(b, upper, offset, LOWER_SIZE)?;
            check_lower(b, lower, child_origin, active)?;
        } else if bit(b, upper + UPPER_VALUE_MASK, n)? {
            active.add_cube(child_origin, 128);
        }
    }
    Ok(())
}

/// Checks a lower node and its leaves, as [`check_upper`].
fn check_lower(b: &[u8], lower: usize, origin: [i32; 3], active: &mut Bounds) -> Result<(), String> {
    for n in 0..16 * 16 * 16 {
        let at = [n >> 8, (n >> 4) & 15, n & 15].map(|c| c as i32 * 8);
        let leaf_origin = [0, 1, 2].map(|k| origin[k].wrapping_add(at[k]));
        if bit(b, lower + LOWER_CHILD_MASK, n)? {
            let offset = u64_at(b, lower + LOWER_TABLE + 8 * n)? as i64;
            let leaf = node(b, lower, offset, LEAF_SIZE)?;
            // The active voxels' box, from the leaf's value mask.
            for word in 0..16 {
                let mut bits = u32_at(b, leaf + LEAF_VALUE_MASK + 4 * word)?;
                while bits != 0 {
                    let v = word * 32 + bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let p = [v >> 6, (v >> 3) & 7, v & 7].map(|c| c as i32);
                    let p = [0, 1, 2].map(|k| leaf_origin[k].wrapping_add(p[k]));
                    active.add(p, p);
                }
            }
        } else if bit(b, lower + LOWER_VALUE_MASK, n)? {
            active.add_cube(leaf_origin, 8);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn fixture(name: &str) -> Vec<u8> {
        std::fs::read(format!("{}/tests/data/nanovdb/{name}", env!("CARGO_MANIFEST_DIR"))).unwrap()
    }

    /// The (world point, value) pairs NVIDIA Warp's sampler read from a
    /// grid of the fixture (tools/nanovdb/make-fixtures).
    fn warp_samples(grid: &str) -> Vec<(Vec3, f32)> {
        let text = String::from_utf8(fixture(&format!("smoke-{grid}.txt"))).unwrap();
        text.lines()
            .filter(|l| !l.starts_with('#'))
            .map(|l| {
                let v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
                (Vec3::new(v[0], v[1], v[2]), v[3])
            })
            .collect()
    }

    /// The same file with its grids stored uncompressed (codec 0).
    fn uncompressed(bytes: &[u8]) -> Vec<u8> {
        let grids = read_grids(bytes, &|_| true).unwrap();
        let mut out = bytes[..FILE_HEADER_SIZE].to_vec();
        out[14..16].copy_from_slice(&0u16.to_le_bytes());
        let mut at = FILE_HEADER_SIZE;
        for (name, _, _, _) in &grids {
            let mut meta = bytes[at..at + FILE_METADATA_SIZE + name.len() + 1].to_vec();
            let size = u64::from_le_bytes(meta[0..8].try_into().unwrap());
            meta[8..16].copy_from_slice(&size.to_le_bytes());
            meta[168..170].copy_from_slice(&0u16.to_le_bytes());
            out.extend_from_slice(&meta);
            at += meta.len();
        }
        for (_, _, _, data) in &grids {
            out.extend_from_slice(data.as_ref().unwrap());
        }
        out
    }

    #[test]
    fn dense_grids_read_what_warps_nanovdb_sampler_reads() {
        let bytes = fixture("smoke.nvdb");
        assert_eq!(grid_names(&bytes).unwrap(), ["density", "temperature"]);
        for file in [bytes.clone(), uncompressed(&bytes)] {
            for name in ["density", "temperature"] {
                let grid = NanoVdbGrid::from_file(&file, name).unwrap().unwrap();
                assert_eq!(grid.name, name);
                assert_eq!(grid.class, CLASS_FOG_VOLUME);
                let (dense, unit_to_space) = grid.to_voxel_grid().unwrap().unwrap();
                let space_to_unit = unit_to_space.inverse();
                let samples = warp_samples(name);
                assert!(samples.len() >= 100);
                for (p, expected) in samples {
                    let got = dense.lookup(space_to_unit.transform_point3(p)).x;
                    assert!(
                        (got - expected).abs() <= 2e-5 * expected.abs().max(1.0),
                        "{name} at {p}: {got}, Warp reads {expected}"
                    );
                }
            }
        }
        assert!(NanoVdbGrid::from_file(&bytes, "velocity").unwrap().is_none());
    }

    #[test]
    fn the_grid_reads_zero_outside_its_active_box() {
        let grid = NanoVdbGrid::from_file(&fixture("smoke.nvdb"), "density")
            .unwrap()
            .unwrap();
        let (lo, hi) = grid.active_box().unwrap();
        // Warp fills whole leaves, so the box is that of the 21×13×10 array
        // rounded up to 8³ leaves.
        assert_eq!((lo, hi), ([0, 0, 0], [23, 15, 15]));
        let (dense, unit_to_space) = grid.to_voxel_grid().unwrap().unwrap();
        let to_unit = unit_to_space.inverse();
        let at_index = |i: f64, j: f64, k: f64| {
            let p = grid.index_to_grid_space(DVec3::new(i, j, k)).as_vec3();
            dense.lookup(to_unit.transform_point3(p)).x
        };
        // Inside: the voxel's value; just past the box's faces [lo, hi + 1]: 0.
        assert!((at_index(3.0, 4.0, 5.0) - grid.value([3, 4, 5])).abs() < 1e-5);
        assert_eq!(at_index(-0.01, 4.0, 5.0), 0.0);
        assert_eq!(at_index(3.0, 16.01, 5.0), 0.0);
        assert!(at_index(0.01, 4.0, 5.0) > 0.0 || grid.value([0, 4, 5]) == 0.0);
    }

    #[test]
    fn malformed_files_are_errors_not_panics() {
        let bytes = uncompressed(&fixture("smoke.nvdb"));
        // Every truncation.
        for len in (0..bytes.len()).step_by(97).chain([1, 15, 16, 100, 191, 192, 200, 900]) {
            let r = NanoVdbGrid::from_file(&bytes[..len.min(bytes.len() - 1)], "density");
            assert!(r.is_err() || r.as_ref().unwrap().is_none(), "{len} bytes");
        }
        // Random corruption of the grids' bytes: an error or a grid, never
        // a panic, and whatever is read stays bounded.
        let mut rng = crate::sampling::rng::Pcg32::new(11, 0);
        for _ in 0..300 {
            let mut b = bytes.clone();
            for _ in 0..4 {
                let at = (rng.next_u32() as usize) % b.len();
                b[at] = rng.next_u32() as u8;
            }
            if let Ok(Some(g)) = NanoVdbGrid::from_file(&b, "density") {
                let _ = g.value([3, 4, 5]);
                if let Ok(Some((dense, _))) = g.to_voxel_grid() {
                    assert!(dense.data.len() as u64 <= MAX_VOXELS);
                }
            }
        }
        let mut wrong = bytes.clone();
        wrong[0] = b'X';
        assert!(
            NanoVdbGrid::from_file(&wrong, "density")
                .unwrap_err()
                .contains("not a NanoVDB file")
        );
        let mut old = bytes.clone();
        old[8..12].copy_from_slice(&(29u32 << 21 | 3 << 10).to_le_bytes());
        assert!(
            NanoVdbGrid::from_file(&old, "density")
                .unwrap_err()
                .contains("version 29.3.0")
        );
        let mut blosc = fixture("smoke.nvdb");
        blosc[14..16].copy_from_slice(&2u16.to_le_bytes());
        assert!(NanoVdbGrid::from_file(&blosc, "density").unwrap_err().contains("Blosc"));
        let mut doubles = bytes.clone();
        doubles[FILE_HEADER_SIZE + 32..FILE_HEADER_SIZE + 36].copy_from_slice(&2u32.to_le_bytes());
        assert!(
            NanoVdbGrid::from_file(&doubles, "density")
                .unwrap_err()
                .contains("double values")
        );
    }
}
