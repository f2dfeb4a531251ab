//! Checkpoints: the state of a render at the end of a pass, so that an
//! interrupted render can continue where it stopped.
//!
//! A checkpoint holds the job (the caller's settings as `key = value`
//! pairs: the command line stores the scene's absolute path, the `-D`
//! definitions and every flag that changes the image), the samples per
//! pixel asked for and done, the statistics so far and the film's exact
//! sums. Because a sample's random numbers depend only on its pixel, index
//! and seed, and the film's sums are exact, continuing from a checkpoint
//! gives the same image, bit for bit, as a render that was never
//! interrupted. The part files of a sharded render (`.trazo-part`) are
//! checkpoints too: their job names the shard and the samples per pixel
//! done are those of the shard's passes.
//!
//! The file is binary, little-endian:
//!
//! ```text
//! "TRAZOCKP"  version: u32
//! job: count u32, then per pair: key (len u32, UTF-8), value (len u32, UTF-8)
//! width u32, height u32, target spp u32, done spp u32, flags u32 (1: AOVs)
//! samples u64, rays u64, invalid samples u64, seconds f64
//! width·height pixels: Σw·L (3 × i128), Σw, Σw·Y² (i128), in units of 2⁻⁵⁰
//! if AOVs, width·height: Σalbedo (3 × i128), Σnormal (3 × i128), Σdepth, count,
//! Σsteps (i128 each)
//! state: length u64, then that many bytes (a progressive algorithm's
//! state, `Progressive::state`; empty for camera passes)
//! (version 1 held the same sums as f64, which are read and converted;
//! versions 1 and 2 had no Σsteps, read as 0; versions 1–3 no state)
//! FNV-1a 64 of everything above: u64
//! ```
//!
//! It is written atomically (temporary file, fsync, rename) and checked
//! whole when read: magic, version, sizes against the file's length before
//! anything is allocated, the checksum, and finite sums.

use super::RenderStats;
use crate::error::{Error, Result};
use crate::film::{AovSum, ExactSums, Film, FilmAov, FilmGBuffer, FilmPixel, GBUFFER_SUMS, PixelSum};
use crate::settings::{MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE, MAX_SPP};
use glam::DVec3;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The first bytes of every checkpoint.
pub const MAGIC: &[u8; 8] = b"TRAZOCKP";
/// The version of the layout this code reads and writes.
pub const VERSION: u32 = 4;
/// Largest job description accepted when reading, in bytes: room for the
/// settings and some hundred thousand recorded scene files.
const MAX_JOB_BYTES: usize = 32 << 20;
/// Bytes per pixel record and per AOV record.
const PIXEL_BYTES: usize = 5 * 16;
const AOV_BYTES: usize = 9 * 16;
/// Bytes of a pixel's G-buffer sums.
const GBUFFER_BYTES: usize = GBUFFER_SUMS * 16;

/// The state of a render between two passes.
#[derive(Clone, Debug, PartialEq)]
pub struct Checkpoint {
    /// The render's settings as the caller chose to record them, in order;
    /// a key may repeat.
    pub job: Vec<(String, String)>,
    /// Samples per pixel the render was asked for.
    pub target_spp: u32,
    /// The film after `stats.spp` samples per pixel.
    pub film: Film,
    /// Statistics up to this point (`spp` is the samples per pixel done).
    pub stats: RenderStats,
    /// A progressive algorithm's state (light tracing, BDPT, MLT: their
    /// sums and chains), from which it continues; empty for camera passes,
    /// whose state is the film.
    pub state: Vec<u8>,
}

/// The checkpoint that belongs to an output image: `OUT.trazo-checkpoint`
/// next to it.
pub fn checkpoint_path(output: &Path) -> PathBuf {
    let mut name = output.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    name.push(".trazo-checkpoint");
    output.with_file_name(name)
}

impl Checkpoint {
    /// The first value recorded for `key`.
    pub fn job_value(&self, key: &str) -> Option<&str> {
        self.job.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// Every value recorded for `key`, in order.
    pub fn job_values<'a>(&'a self, key: &'a str) -> impl Iterator<Item = &'a str> + 'a {
        self.job.iter().filter(move |(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// The file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let f = &self.film;
        let n = f.pixels.len();
        let mut b = Vec::with_capacity(
            64 + n
                * (PIXEL_BYTES
                    + if f.aovs.is_some() { AOV_BYTES } else { 0 }
                    + if f.gbuffer.is_some() { GBUFFER_BYTES } else { 0 }),
        );
        b.extend_from_slice(MAGIC);
        put_u32(&mut b, VERSION);
        put_u32(&mut b, self.job.len() as u32);
        for (k, v) in &self.job {
            for s in [k, v] {
                put_u32(&mut b, s.len() as u32);
                b.extend_from_slice(s.as_bytes());
            }
        }
        for v in [
            f.width,
            f.height,
            self.target_spp,
            self.stats.spp,
            u32::from(f.aovs.is_some()) | u32::from(f.gbuffer.is_some()) << 1,
        ] {
            put_u32(&mut b, v);
        }
        let s = &self.stats;
        for v in [s.samples, s.rays, s.invalid_samples, s.seconds.to_bits()] {
            put_u64(&mut b, v);
        }
        for p in &f.pixels {
            for v in p.0 {
                b.extend_from_slice(&v.to_le_bytes());
            }
        }
        if let Some(aovs) = &f.aovs {
            for a in aovs {
                for v in a.0 {
                    b.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        if let Some(gbuffer) = &f.gbuffer {
            for g in gbuffer {
                for v in g.0 {
                    b.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        put_u64(&mut b, self.state.len() as u64);
        b.extend_from_slice(&self.state);
        let sum = fnv1a(&b);
        put_u64(&mut b, sum);
        b
    }

    /// Parses and checks a checkpoint file's bytes. Errors are plain
    /// reasons ("truncated", "checksum mismatch", …).
    pub fn from_bytes(bytes: &[u8]) -> Result<Checkpoint, String> {
        if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
            return Err("not a trazo checkpoint (wrong magic bytes)".into());
        }
        let mut r = Reader {
            bytes,
            pos: MAGIC.len(),
        };
        let version = r.u32()?;
        if !(1..=VERSION).contains(&version) {
            return Err(format!(
                "checkpoint version {version} is not supported (this trazo reads version {VERSION})"
            ));
        }
        if bytes.len() < MAGIC.len() + 4 + 8 {
            return Err("truncated".into());
        }
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        let stored = u64::from_le_bytes(tail.try_into().expect("8 bytes"));
        if fnv1a(body) != stored {
            return Err("corrupt or truncated (checksum mismatch)".into());
        }
        let mut r = Reader {
            bytes: body,
            pos: r.pos,
        };
        let pairs = r.u32()? as usize;
        // Each pair needs at least its two lengths.
        if pairs > r.remaining() / 8 {
            return Err(format!("truncated: {pairs} settings announced"));
        }
        let mut job = Vec::with_capacity(pairs);
        let mut job_bytes = 0;
        for _ in 0..pairs {
            let k = r.string()?;
            let v = r.string()?;
            job_bytes += k.len() + v.len();
            if job_bytes > MAX_JOB_BYTES {
                return Err("the settings are larger than 1 MiB".into());
            }
            job.push((k, v));
        }
        let (width, height, target_spp, spp, flags) = (r.u32()?, r.u32()?, r.u32()?, r.u32()?, r.u32()?);
        if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
            return Err(format!("bad image size {width}×{height}"));
        }
        if width as u64 * height as u64 > MAX_IMAGE_PIXELS {
            return Err(format!("image of {width}×{height} pixels is larger than the limit"));
        }
        if target_spp == 0 || target_spp > MAX_SPP || spp > target_spp {
            return Err(format!("bad sample counts: {spp} of {target_spp} samples per pixel"));
        }
        // The G-buffer (flag 2) came with version 4's state.
        if flags > 3 || (flags & 2 != 0 && version < 4) {
            return Err(format!("unknown flags {flags:#x}"));
        }
        let (aovs, gbuffer) = (flags & 1 == 1, flags & 2 == 2);
        let mut stats = RenderStats {
            samples: r.u64()?,
            rays: r.u64()?,
            invalid_samples: r.u64()?,
            seconds: f64::from_bits(r.u64()?),
            spp,
            ..RenderStats::default()
        };
        if !(stats.seconds.is_finite() && stats.seconds >= 0.0) {
            return Err("bad render time".into());
        }
        let n = width as usize * height as usize;
        // Version 1's sums were f64.
        let word = if version == 1 { 8 } else { 16 };
        // Before version 3 the auxiliary sums had no steps.
        let (pixel_bytes, aov_bytes) = (5 * word, if version < 3 { 8 } else { 9 } * word);
        let gbuffer_bytes = GBUFFER_SUMS * word;
        let need = n as u128
            * (pixel_bytes + if aovs { aov_bytes } else { 0 } + if gbuffer { gbuffer_bytes } else { 0 }) as u128;
        let has_state = version >= 4;
        let sums_fit = if has_state {
            need + 8 <= r.remaining() as u128
        } else {
            need == r.remaining() as u128
        };
        if !sums_fit {
            return Err(format!(
                "{width}×{height} pixels need {need} bytes of sums, the file has {}",
                r.remaining()
            ));
        }
        let mut pixels = Vec::with_capacity(n);
        for _ in 0..n {
            let p = if version == 1 {
                let sum = PixelSum {
                    rgb: DVec3::new(r.f64()?, r.f64()?, r.f64()?),
                    weight: r.f64()?,
                    lum_sq: r.f64()?,
                };
                if !(sum.rgb.is_finite() && sum.weight.is_finite() && sum.lum_sq.is_finite()) {
                    return Err("a pixel sum is not a finite number".into());
                }
                FilmPixel::default().plus(&sum)
            } else {
                r.exact()?
            };
            if p.0[3] < 0 {
                return Err("a pixel's weight is negative".into());
            }
            pixels.push(p);
        }
        let aovs = if aovs {
            let mut v = Vec::with_capacity(n);
            for _ in 0..n {
                let a = if version == 1 {
                    let sum = AovSum {
                        albedo: DVec3::new(r.f64()?, r.f64()?, r.f64()?),
                        normal: DVec3::new(r.f64()?, r.f64()?, r.f64()?),
                        depth: r.f64()?,
                        count: r.f64()?,
                        steps: 0.0,
                    };
                    if !(sum.albedo.is_finite()
                        && sum.normal.is_finite()
                        && sum.depth.is_finite()
                        && sum.count.is_finite())
                    {
                        return Err("an auxiliary sum is not a finite number".into());
                    }
                    FilmAov::default().plus(&sum)
                } else if version == 2 {
                    let old: ExactSums<8> = r.exact()?;
                    let mut a = FilmAov::default();
                    a.0[..8].copy_from_slice(&old.0);
                    a
                } else {
                    r.exact()?
                };
                v.push(a);
            }
            Some(v)
        } else {
            None
        };
        let gbuffer = if gbuffer {
            let mut v = Vec::with_capacity(n);
            for _ in 0..n {
                let g: FilmGBuffer = r.exact()?;
                v.push(g);
            }
            Some(v)
        } else {
            None
        };
        let state = if has_state {
            let len = r.u64()?;
            if len != r.remaining() as u64 {
                return Err(format!(
                    "the algorithm's state should be {len} bytes, the file has {}",
                    r.remaining()
                ));
            }
            r.take(len as usize)?.to_vec()
        } else {
            Vec::new()
        };
        stats.threads = 0;
        Ok(Checkpoint {
            job,
            target_spp,
            film: Film {
                width,
                height,
                pixels,
                aovs,
                gbuffer,
                // The sums as rendered: the colour matrix is the scene's.
                output_transform: None,
            },
            stats,
            state,
        })
    }

    /// Writes the checkpoint atomically: a reader (or a later resume) sees
    /// the old file or the new one, never a part.
    pub fn write(&self, path: &Path) -> Result<()> {
        let bytes = self.to_bytes();
        crate::film::io::write_atomic(path, |f| f.write_all(&bytes).map_err(|e| e.to_string()))
    }

    /// Reads and checks a checkpoint file.
    pub fn read(path: &Path) -> Result<Checkpoint> {
        // The largest checkpoint: the largest image with AOVs, and a
        // progressive algorithm's state (its sums, BDPT's strategies'
        // images: up to 2 KiB a pixel; MLT's chains).
        let limit = MAX_IMAGE_PIXELS * (PIXEL_BYTES + AOV_BYTES + 2048) as u64 + (256 << 20);
        let bytes = crate::files::read_limited(path, limit)
            .map_err(|e| Error::file(path, format!("cannot read checkpoint: {e}")))?;
        Checkpoint::from_bytes(&bytes).map_err(|e| Error::file(path, format!("invalid checkpoint: {e}")))
    }
}

fn put_u32(b: &mut Vec<u8>, v: u32) {
    b.extend_from_slice(&v.to_le_bytes());
}

fn put_u64(b: &mut Vec<u8>, v: u64) {
    b.extend_from_slice(&v.to_le_bytes());
}

/// 64-bit FNV-1a: cheap, and enough to catch truncation and bit rot (it is
/// not meant to resist tampering).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// A cursor over bytes whose reads fail, rather than panic, at the end.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        if n > self.remaining() {
            return Err(format!("truncated at byte {}", self.pos));
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }

    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }

    fn f64(&mut self) -> Result<f64, String> {
        self.u64().map(f64::from_bits)
    }

    fn exact<const N: usize>(&mut self) -> Result<ExactSums<N>, String> {
        let mut sums = ExactSums::default();
        for v in &mut sums.0 {
            *v = i128::from_le_bytes(self.take(16)?.try_into().expect("16 bytes"));
        }
        Ok(sums)
    }

    fn string(&mut self) -> Result<String, String> {
        let len = self.u32()? as usize;
        let at = self.pos;
        let b = self.take(len)?;
        String::from_utf8(b.to_vec()).map_err(|_| format!("a setting at byte {at} is not UTF-8 text"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Checkpoint {
        let mut film = Film::new(3, 2);
        for (i, p) in film.pixels.iter_mut().enumerate() {
            let mut sum = PixelSum::default();
            sum.add(crate::Rgb::new(i as f32, 0.5, 1e-3), 1.0);
            p.add_sum(&sum);
        }
        film.aovs = Some(vec![
            FilmAov::default().plus(&AovSum {
                albedo: DVec3::splat(0.25),
                normal: DVec3::Z,
                depth: 3.5,
                count: 1.0,
                steps: 12.0,
            });
            6
        ]);
        Checkpoint {
            job: vec![
                ("scene".into(), "/tmp/a b/scène.toml".into()),
                ("define".into(), "spp=4".into()),
                ("define".into(), "x=".into()),
            ],
            target_spp: 16,
            film,
            stats: RenderStats {
                seconds: 1.25,
                samples: 6,
                rays: 12,
                invalid_samples: 1,
                spp: 1,
                ..RenderStats::default()
            },
            state: vec![7, 0, 255],
        }
    }

    #[test]
    fn round_trips_bit_for_bit() {
        let c = sample();
        let back = Checkpoint::from_bytes(&c.to_bytes()).unwrap();
        assert_eq!(back, c);
        assert_eq!(back.job_values("define").collect::<Vec<_>>(), ["spp=4", "x="]);
        assert_eq!(back.job_value("scene"), Some("/tmp/a b/scène.toml"));
        let mut plain = sample();
        plain.film.aovs = None;
        plain.state.clear();
        assert_eq!(Checkpoint::from_bytes(&plain.to_bytes()).unwrap(), plain);
        // A G-buffer film's sums, with and without auxiliary images.
        let surface = crate::film::GBufferSample {
            p: glam::Vec3::new(1.0, -2.0, 5.0),
            n: -glam::Vec3::Z,
            ns: -glam::Vec3::Z,
            uv: glam::Vec2::new(0.25, 0.75),
            dzdx: 0.125,
            dzdy: -0.5,
            albedo: crate::Rgb::splat(0.5),
        };
        let mut sums = FilmGBuffer::default();
        sums.add_sample(Some(&surface), 1.0, crate::Rgb::new(0.5, 2.0, 0.0));
        sums.add_sample(None, 0.5, crate::Rgb::ZERO);
        for aovs in [true, false] {
            let mut g = sample();
            g.film.gbuffer = Some(vec![sums; 6]);
            if !aovs {
                g.film.aovs = None;
            }
            let back = Checkpoint::from_bytes(&g.to_bytes()).unwrap();
            assert_eq!(back, g);
        }
    }

    /// The state's length must match what the file holds.
    #[test]
    fn a_state_of_the_wrong_length_is_refused() {
        let mut bytes = sample().to_bytes();
        bytes.truncate(bytes.len() - 8);
        let at = bytes.len() - 3 - 8;
        bytes[at] = 4;
        let sum = fnv1a(&bytes);
        put_u64(&mut bytes, sum);
        let e = Checkpoint::from_bytes(&bytes).unwrap_err();
        assert!(e.contains("state should be 4 bytes"), "{e}");
    }

    #[test]
    fn damaged_files_are_refused_with_a_reason() {
        let bytes = sample().to_bytes();
        for len in [0, 4, 8, 12, 20, bytes.len() / 2, bytes.len() - 1] {
            assert!(Checkpoint::from_bytes(&bytes[..len]).is_err(), "truncated to {len}");
        }
        let mut flipped = bytes.clone();
        flipped[bytes.len() / 2] ^= 1;
        let e = Checkpoint::from_bytes(&flipped).unwrap_err();
        assert!(e.contains("checksum"), "{e}");
        let mut version = bytes.clone();
        version[8] = 9;
        assert!(Checkpoint::from_bytes(&version).unwrap_err().contains("version"));
        assert!(Checkpoint::from_bytes(b"PNG\x89....").unwrap_err().contains("magic"));
    }

    #[test]
    fn absurd_sizes_are_refused_before_allocating() {
        // A valid checksum over a header that announces a huge image.
        let mut b = Vec::new();
        b.extend_from_slice(MAGIC);
        put_u32(&mut b, VERSION);
        put_u32(&mut b, 0);
        for v in [65_536, 4096, 16, 1, 0] {
            put_u32(&mut b, v);
        }
        for _ in 0..4 {
            put_u64(&mut b, 0);
        }
        let sum = fnv1a(&b);
        put_u64(&mut b, sum);
        let e = Checkpoint::from_bytes(&b).unwrap_err();
        assert!(e.contains("need"), "{e}");
    }

    /// Checkpoints of trazo before exact sums held f64 sums (version 1):
    /// they are still read, their sums converted.
    #[test]
    fn version_1_checkpoints_are_read() {
        let mut b = Vec::new();
        b.extend_from_slice(MAGIC);
        put_u32(&mut b, 1);
        put_u32(&mut b, 1);
        for s in ["scene", "/a.toml"] {
            put_u32(&mut b, s.len() as u32);
            b.extend_from_slice(s.as_bytes());
        }
        for v in [2, 1, 8, 2, 0] {
            put_u32(&mut b, v);
        }
        for v in [4, 40, 0, 1.5f64.to_bits()] {
            put_u64(&mut b, v);
        }
        for px in [[1.0, 2.0, 0.5, 2.0, 3.0], [0.25, 0.0, 0.0, 2.0, 0.125]] {
            for v in px {
                put_u64(&mut b, f64::to_bits(v));
            }
        }
        let sum = fnv1a(&b);
        put_u64(&mut b, sum);
        let c = Checkpoint::from_bytes(&b).unwrap();
        assert_eq!((c.film.width, c.film.height, c.target_spp, c.stats.spp), (2, 1, 8, 2));
        assert_eq!(c.film.pixels[0].value(), crate::Rgb::new(0.5, 1.0, 0.25));
        assert_eq!(c.film.pixels[1].sum().lum_sq, 0.125);
        assert_eq!(c.stats.seconds, 1.5);
    }

    /// Version 2 had eight auxiliary sums, without the steps.
    #[test]
    fn version_2_checkpoints_are_read_with_no_steps() {
        let mut b = Vec::new();
        b.extend_from_slice(MAGIC);
        put_u32(&mut b, 2);
        put_u32(&mut b, 0);
        for v in [1, 1, 4, 1, 1] {
            put_u32(&mut b, v);
        }
        for v in [1, 10, 0, 0.5f64.to_bits()] {
            put_u64(&mut b, v);
        }
        let mut px = FilmPixel::default();
        px.add([0.5, 0.5, 0.5, 1.0, 0.25]);
        let mut aov = ExactSums::<8>::default();
        aov.add([0.2, 0.3, 0.4, 0.0, 0.0, 1.0, 7.5, 1.0]);
        for v in px.0.iter().chain(aov.0.iter()) {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let sum = fnv1a(&b);
        put_u64(&mut b, sum);
        let c = Checkpoint::from_bytes(&b).unwrap();
        assert!(c.state.is_empty());
        let a = c.film.aovs.as_ref().unwrap()[0].sum();
        assert_eq!((a.depth, a.count, a.steps), (7.5, 1.0, 0.0));
        assert_eq!(c.film.pixels[0].value(), crate::Rgb::splat(0.5));
    }

    #[test]
    fn the_checkpoint_sits_next_to_the_output() {
        assert_eq!(
            checkpoint_path(Path::new("renders/box.exr")),
            PathBuf::from("renders/box.exr.trazo-checkpoint")
        );
    }
}
