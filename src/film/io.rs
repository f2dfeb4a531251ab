//! Reading and writing images: PNG (8-bit sRGB), OpenEXR, Radiance HDR and
//! PFM (linear float).
//!
//! Every write is atomic: the data goes to a temporary file in the target's
//! folder, which is flushed to disk and then renamed over the target. A
//! render killed at any moment leaves either the old file or the new one.
//! No temporary file outlives its process: one being written is removed on
//! an error, a panic (a `TempFile`'s drop) and an abort by a second Ctrl-C
//! ([`remove_unfinished_temp_files`]); one left by a process killed outright
//! (`kill -9`) is removed by the next write to the same file.

use super::Image;
use crate::color::space::ColorSpace;
use crate::color::{Encoding, Rgb, linear_to_srgb};
use crate::error::{Error, Result};
use crate::files::{MAX_IMAGE_FILE_BYTES, read_limited};
use crate::settings::Tonemap;
use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Image file formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit sRGB PNG.
    Png,
    /// OpenEXR, 32-bit float RGB.
    Exr,
    /// Radiance RGBE.
    Hdr,
    /// Portable float map.
    Pfm,
}

impl ImageFormat {
    /// The format named by a path's extension.
    pub fn from_path(path: &Path) -> Result<ImageFormat> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "png" => Ok(ImageFormat::Png),
            "exr" => Ok(ImageFormat::Exr),
            "hdr" => Ok(ImageFormat::Hdr),
            "pfm" => Ok(ImageFormat::Pfm),
            "" => Err(Error::file(path, "no file extension: use .png, .exr, .hdr or .pfm")),
            other => Err(Error::file(
                path,
                format!("unsupported image format \".{other}\": use .png, .exr, .hdr or .pfm"),
            )),
        }
    }

    /// Whether the format stores linear floating-point values.
    pub fn is_hdr(&self) -> bool {
        !matches!(self, ImageFormat::Png)
    }
}

/// The factor an exposure of `exposure` stops multiplies radiance by.
pub fn exposure_scale(exposure: f32) -> f32 {
    2f32.powf(exposure)
}

/// Writes `image` (linear sRGB) in the format its extension names. 8-bit
/// formats get `exposure` (stops) and `tonemap` applied, then the sRGB
/// curve; float formats get the exposure only.
pub fn write_image(path: &Path, image: &Image, tonemap: Tonemap, exposure: f32) -> Result<()> {
    write_image_in(path, image, tonemap, exposure, ColorSpace::Srgb)
}

/// Whether an image written to `path` can record its colour space (only
/// OpenEXR's `chromaticities` can): [`write_image_in`] writes the others
/// in sRGB.
pub fn records_color_space(path: &Path) -> bool {
    ImageFormat::from_path(path).is_ok_and(|f| f == ImageFormat::Exr)
}

/// [`write_image`] for an image whose pixels are in `space`: OpenEXR files
/// record it in their `chromaticities` attribute; the other formats, which
/// cannot, get the pixels converted back to sRGB (their XYZ kept), as
/// pbrt-v4 writes them.
pub fn write_image_in(path: &Path, image: &Image, tonemap: Tonemap, exposure: f32, space: ColorSpace) -> Result<()> {
    let format = ImageFormat::from_path(path)?;
    let scale = exposure_scale(exposure);
    if space != ColorSpace::Srgb && format != ImageFormat::Exr {
        let to_srgb = space.to_srgb(true);
        let srgb = Image {
            width: image.width,
            height: image.height,
            pixels: image.pixels.iter().map(|&p| to_srgb * p).collect(),
        };
        return write_image_in(path, &srgb, tonemap, exposure, ColorSpace::Srgb);
    }
    match format {
        ImageFormat::Png => {
            let bytes = encode_png(image, tonemap, scale)?;
            write_atomic(path, |f| f.write_all(&bytes).map_err(|e| e.to_string()))
        }
        ImageFormat::Pfm => write_atomic(path, |f| {
            let mut w = BufWriter::new(f);
            write_pfm(&mut w, image, scale).map_err(|e| e.to_string())?;
            w.flush().map_err(|e| e.to_string())
        }),
        ImageFormat::Hdr => {
            let pixels: Vec<::image::Rgb<f32>> = image
                .pixels
                .iter()
                .map(|p| {
                    let c = (*p * scale).max(Rgb::ZERO);
                    ::image::Rgb([c.x, c.y, c.z])
                })
                .collect();
            write_atomic(path, |f| {
                let mut w = BufWriter::new(f);
                ::image::codecs::hdr::HdrEncoder::new(&mut w)
                    .encode(&pixels, image.width as usize, image.height as usize)
                    .map_err(|e| e.to_string())?;
                w.flush().map_err(|e| e.to_string())
            })
        }
        ImageFormat::Exr => write_atomic_path(path, |tmp| {
            use exr::prelude::{Image as ExrImage, SpecificChannels, WritableImage};
            let w = image.width as usize;
            let channels = SpecificChannels::rgb(|exr::math::Vec2(x, y): exr::math::Vec2<usize>| {
                let c = image.pixels[y * w + x] * scale;
                (c.x, c.y, c.z)
            });
            let mut exr = ExrImage::from_encoded_channels((w, image.height as usize), exr_encoding(), channels);
            record_space(&mut exr, space);
            exr.write().to_file(tmp).map_err(|e| e.to_string())
        }),
    }
}

/// The encoding trazo writes OpenEXR files with: blocks in increasing
/// order, not in the order the threads that compress them finish, so that
/// the same image gives the same file.
fn exr_encoding() -> exr::prelude::Encoding {
    exr::prelude::Encoding {
        line_order: exr::prelude::LineOrder::Increasing,
        ..exr::prelude::Encoding::FAST_LOSSLESS
    }
}

/// Records `space`, where it is not sRGB, in an OpenEXR image's
/// `chromaticities`.
fn record_space<L>(exr: &mut exr::prelude::Image<L>, space: ColorSpace) {
    if space != ColorSpace::Srgb {
        let v = |(x, y): (f32, f32)| exr::math::Vec2(x, y);
        let [red, green, blue, white] = space.primaries_and_white().map(v);
        exr.attributes.chromaticities = Some(exr::meta::attribute::Chromaticities {
            red,
            green,
            blue,
            white,
        });
    }
}

/// Writes a G-buffer film as pbrt-v4's `GBufferFilm` does: one OpenEXR
/// file of 32-bit float channels named as pbrt-v4 names them
/// ([`super::GBUFFER_CHANNELS`]), R, G, B from `image` (the film's image, in
/// `space`) times the exposure, the albedo converted to `space` (its XYZ
/// kept, as pbrt-v4 converts it), and the film's other G-buffer channels as
/// they are.
pub fn write_gbuffer_exr(
    path: &Path,
    image: &Image,
    film: &super::Film,
    exposure: f32,
    space: ColorSpace,
) -> Result<()> {
    let Some(mut channels) = film.gbuffer_channels() else {
        return Err(Error::file(path, "the film recorded no G-buffer"));
    };
    if ImageFormat::from_path(path)? != ImageFormat::Exr {
        return Err(Error::file(path, "a G-buffer is written to OpenEXR files only (.exr)"));
    }
    let scale = exposure_scale(exposure);
    let rgb = |c: usize| image.pixels.iter().map(|p| p[c] * scale).collect::<Vec<f32>>();
    let mut all = vec![rgb(0), rgb(1), rgb(2)];
    if let Some(m) = space.from_srgb()
        && let [r, g, b, ..] = &mut channels[..]
    {
        for ((r, g), b) in r.iter_mut().zip(g.iter_mut()).zip(b.iter_mut()) {
            let a = m * Rgb::new(*r, *g, *b);
            (*r, *g, *b) = (a.x, a.y, a.z);
        }
    }
    all.append(&mut channels);
    let (w, h) = (image.width as usize, image.height as usize);
    write_atomic_path(path, |tmp| {
        use exr::prelude::{AnyChannel, AnyChannels, FlatSamples, Image as ExrImage, WritableImage};
        let list = super::GBUFFER_CHANNELS
            .iter()
            .zip(all)
            .map(|(name, values)| AnyChannel::new(*name, FlatSamples::F32(values)))
            .collect();
        let mut exr = ExrImage::from_encoded_channels((w, h), exr_encoding(), AnyChannels::sort(list));
        record_space(&mut exr, space);
        exr.write().to_file(tmp).map_err(|e| e.to_string())
    })
}

/// PNG bytes of the tone-mapped image.
pub fn encode_png(image: &Image, tonemap: Tonemap, scale: f32) -> Result<Vec<u8>> {
    let mut rgb8 = Vec::with_capacity(image.pixels.len() * 3);
    for p in &image.pixels {
        let c = tonemap.apply(*p * scale);
        for v in [c.x, c.y, c.z] {
            rgb8.push((linear_to_srgb(v) * 255.0 + 0.5) as u8);
        }
    }
    let mut out = Vec::new();
    let encoder = ::image::codecs::png::PngEncoder::new(&mut out);
    use ::image::ImageEncoder;
    encoder
        .write_image(&rgb8, image.width, image.height, ::image::ExtendedColorType::Rgb8)
        .map_err(|e| Error::Invalid(format!("PNG encoding failed: {e}")))?;
    Ok(out)
}

fn write_pfm(w: &mut impl Write, image: &Image, scale: f32) -> std::io::Result<()> {
    // Negative scale: little-endian. Rows go bottom to top.
    write!(w, "PF\n{} {}\n-1.0\n", image.width, image.height)?;
    for y in (0..image.height).rev() {
        for x in 0..image.width {
            let c = image.get(x, y) * scale;
            for v in [c.x, c.y, c.z] {
                w.write_all(&v.to_le_bytes())?;
            }
        }
    }
    Ok(())
}

/// The temporary name of `path` for the process `pid`: `.NAME.PID.tmp.EXT`.
fn temp_name(path: &Path, pid: u32) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_default();
    // Keep the extension: some encoders pick the format from it.
    format!(".{name}.{pid}.tmp.{ext}")
}

/// A temporary path next to `path`, unique to this process.
fn temp_path_for(path: &Path) -> PathBuf {
    path.with_file_name(temp_name(path, std::process::id()))
}

/// The temporary files this process is writing now.
static UNFINISHED: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// A temporary file being written: listed in [`UNFINISHED`] while it
/// lives, and removed from the disk when dropped unless it was renamed.
struct TempFile(PathBuf);

impl TempFile {
    fn new(path: PathBuf) -> TempFile {
        UNFINISHED.lock().unwrap_or_else(|e| e.into_inner()).push(path.clone());
        TempFile(path)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let mut list = UNFINISHED.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(i) = list.iter().position(|p| *p == self.0) {
            list.swap_remove(i);
        }
        // After a successful rename the file is gone and this fails.
        let _ = fs::remove_file(&self.0);
    }
}

/// Removes every temporary file this process is writing, for a process
/// about to end without unwinding (a second Ctrl-C). Writes in flight then
/// fail, which no longer matters.
pub fn remove_unfinished_temp_files() {
    let list = UNFINISHED.lock().unwrap_or_else(|e| e.into_inner());
    for p in list.iter() {
        let _ = fs::remove_file(p);
    }
}

/// The folder a file is written in.
fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Removes temporary files of `path` left by processes that no longer run
/// (killed outright while writing it). Only where the system says which
/// processes run (Linux's /proc); a file of a running process is kept.
pub fn remove_stale_temp_files(path: &Path) {
    if !Path::new("/proc/self").is_dir() {
        return;
    }
    let Ok(entries) = fs::read_dir(folder_of(path)) else {
        return;
    };
    let own = std::process::id();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        // `.NAME.PID.tmp.EXT` with the same NAME and EXT as ours.
        let Some(pid) = stale_temp_pid(path, name) else {
            continue;
        };
        if pid != own && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = fs::remove_file(entry.path());
        }
    }
}

/// The process number in `name` if it is a temporary name of `path`.
fn stale_temp_pid(path: &Path, name: &str) -> Option<u32> {
    let template = temp_name(path, 0);
    let (head, tail) = template.split_once(".0.tmp.")?;
    let pid = name.strip_prefix(head)?.strip_prefix('.')?;
    let pid = pid.strip_suffix(tail)?.strip_suffix(".tmp.")?;
    pid.parse().ok().filter(|_| !pid.starts_with('+'))
}

/// Writes a file atomically through `write`, which gets the open
/// temporary file.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut File) -> Result<(), String>) -> Result<()> {
    write_atomic_path(path, |tmp| {
        let mut f = File::create(tmp).map_err(|e| e.to_string())?;
        write(&mut f)
    })
}

/// Writes a file atomically through `write`, which gets the temporary
/// file's path and must create it.
pub fn write_atomic_path(path: &Path, write: impl FnOnce(&Path) -> Result<(), String>) -> Result<()> {
    if path.is_dir() {
        return Err(Error::file(path, "cannot write the image: this is a folder"));
    }
    let dir = folder_of(path);
    if !dir.is_dir() {
        return Err(Error::file(
            path,
            format!("cannot write: the folder {} does not exist", dir.display()),
        ));
    }
    remove_stale_temp_files(path);
    let tmp = TempFile::new(temp_path_for(path));
    let result = write(&tmp.0)
        .and_then(|_| {
            // Flush the data to disk before the rename makes it visible.
            File::open(&tmp.0).and_then(|f| f.sync_all()).map_err(|e| e.to_string())
        })
        .and_then(|_| fs::rename(&tmp.0, path).map_err(|e| e.to_string()));
    drop(tmp);
    if let Err(e) = result {
        return Err(Error::file(path, format!("cannot write: {e}")));
    }
    // Make the rename itself durable.
    if let Ok(d) = File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// The first four bytes of every OpenEXR file.
pub const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Most pixels an OpenEXR file may describe per byte of its size. No EXR
/// compression packs more than a few hundred pixels into a byte, so a
/// header that claims more is lying, and is refused before the pixels are
/// allocated.
const MAX_EXR_PIXELS_PER_BYTE: u64 = 4096;

/// Reads an image of any supported format as linear RGB (8-bit images are
/// decoded from sRGB).
pub fn read_image(path: &Path) -> Result<Image> {
    let format = ImageFormat::from_path(path)?;
    let bytes = read_limited(path, MAX_IMAGE_FILE_BYTES).map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    decode_image(&bytes, format).map_err(|e| Error::file(path, e))
}

/// Decodes an image file held in memory, in the given format, as linear RGB
/// (8-bit images are decoded from sRGB). Sizes in headers are checked
/// against the data before pixels are allocated. Errors are plain reasons.
pub fn decode_image(bytes: &[u8], format: ImageFormat) -> Result<Image, String> {
    match format {
        ImageFormat::Exr => decode_exr(bytes),
        ImageFormat::Pfm => parse_pfm(bytes).map_err(|m| format!("not a valid PFM file: {m}")),
        ImageFormat::Png | ImageFormat::Hdr => decode_encoded(bytes, None, None).map(|(image, _)| image),
    }
}

/// Largest image read, in pixels (16k × 16k): textures, environment maps
/// and images compared.
pub const MAX_IMAGE_PIXELS: u64 = 16384 * 16384;

/// Decodes a PNG, JPEG, BMP, PPM, Radiance HDR, OpenEXR or PFM image held in memory,
/// told apart by their first bytes, as linear RGB: decoded by `encoding`,
/// or where it is `None`, integer images from sRGB and float images as they
/// are. Sizes in headers are checked before pixels are allocated.
/// Errors are plain reasons.
pub fn decode_any(bytes: &[u8], encoding: Option<Encoding>) -> Result<Image, String> {
    decode_any_named(bytes, encoding, None)
}

/// [`decode_any`] for a file of extension `ext`, which names the format
/// where the bytes cannot: Truevision TGA files have no signature.
pub fn decode_any_named(bytes: &[u8], encoding: Option<Encoding>, ext: Option<&str>) -> Result<Image, String> {
    decode_any_with_alpha(bytes, encoding, ext).map(|(image, _)| image)
}

/// [`decode_any_named`] with the image's alpha channel where it has one
/// (formats of the `image` crate only), decoded as the colours are:
/// pbrt-v4 decodes every channel of an 8-bit image by its encoding.
pub fn decode_any_with_alpha(
    bytes: &[u8],
    encoding: Option<Encoding>,
    ext: Option<&str>,
) -> Result<(Image, Option<Vec<f32>>), String> {
    let is_pfm = bytes.starts_with(b"PF") || bytes.starts_with(b"Pf");
    if !bytes.starts_with(&EXR_MAGIC) && !is_pfm {
        return decode_encoded(bytes, encoding, ext);
    }
    let mut image = decode_image(bytes, if is_pfm { ImageFormat::Pfm } else { ImageFormat::Exr })?;
    if let Some(e) = encoding.filter(|e| *e != Encoding::Linear) {
        for p in &mut image.pixels {
            *p = Rgb::new(e.to_linear(p.x), e.to_linear(p.y), e.to_linear(p.z));
        }
    }
    Ok((image, None))
}

/// [`decode_any`] for the formats of the `image` crate (PNG, JPEG, BMP, HDR,
/// TGA, PPM/PGM/PBM); `ext` names the format where the first bytes do not.
fn decode_encoded(
    bytes: &[u8],
    encoding: Option<Encoding>,
    ext: Option<&str>,
) -> Result<(Image, Option<Vec<f32>>), String> {
    let open = || -> Result<_, String> {
        let mut reader = ::image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| format!("cannot read image: {e}"))?;
        if reader.format().is_none() {
            if let Some(format) = ext.and_then(::image::ImageFormat::from_extension) {
                reader.set_format(format);
            }
        }
        Ok(reader)
    };
    let (w, h) = open()?
        .into_dimensions()
        .map_err(|e| format!("not a readable image: {e}"))?;
    // Checked before decoding, which allocates by the header's size.
    if w as u64 * h as u64 > MAX_IMAGE_PIXELS {
        return Err(format!(
            "image of {w}×{h} pixels is larger than the limit of 16384×16384"
        ));
    }
    let img = open()?.decode().map_err(|e| format!("cannot decode image: {e}"))?;
    let is_float = matches!(img.color(), ::image::ColorType::Rgb32F | ::image::ColorType::Rgba32F);
    let encoding = encoding.unwrap_or(if is_float { Encoding::Linear } else { Encoding::Srgb });
    let decode = |x: f32| encoding.to_linear(x);
    let alpha = img
        .color()
        .has_alpha()
        .then(|| img.to_rgba32f().pixels().map(|p| decode(p[3])).collect());
    let rgb = img.to_rgb32f();
    let pixels = rgb
        .pixels()
        .map(|p| Rgb::new(decode(p[0]), decode(p[1]), decode(p[2])))
        .collect();
    Ok((
        Image {
            width: rgb.width(),
            height: rgb.height(),
            pixels,
        },
        alpha,
    ))
}

/// The primaries and white (red, green, blue, white) of an OpenEXR file's
/// `chromaticities` attribute, where it has one; `None` also for bytes
/// that are not an OpenEXR file.
pub fn exr_chromaticities(bytes: &[u8]) -> Option<[(f32, f32); 4]> {
    if !bytes.starts_with(&EXR_MAGIC) {
        return None;
    }
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false).ok()?;
    let c = meta.headers.first()?.shared_attributes.chromaticities?;
    Some([c.red, c.green, c.blue, c.white].map(|v| (v.0, v.1)))
}

/// Reads the first RGB(A) layer of an OpenEXR file.
pub fn read_exr(path: &Path) -> Result<Image> {
    let bytes = read_limited(path, MAX_IMAGE_FILE_BYTES).map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    decode_exr(&bytes).map_err(|e| Error::file(path, e))
}

/// Decodes the first RGB(A) layer of an OpenEXR file held in memory. The
/// header's size is checked against the texture limit and the file's
/// length before the pixels are allocated.
pub fn decode_exr(bytes: &[u8]) -> Result<Image, String> {
    use exr::prelude::{ReadChannels, ReadLayers, read};
    let bad = |e: exr::error::Error| format!("cannot read OpenEXR image: {e}");
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false).map_err(bad)?;
    for header in &meta.headers {
        let size = header.layer_size;
        let pixels = size.width() as u64 * size.height() as u64;
        if pixels > MAX_IMAGE_PIXELS {
            return Err(format!(
                "OpenEXR image of {}×{} pixels is larger than the limit of 16384×16384",
                size.width(),
                size.height()
            ));
        }
        if pixels > bytes.len() as u64 * MAX_EXR_PIXELS_PER_BYTE {
            return Err(format!(
                "OpenEXR header claims {}×{} pixels, more than a file of {} bytes can hold",
                size.width(),
                size.height(),
                bytes.len()
            ));
        }
    }
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |res, _| super::Image::new(res.width() as u32, res.height() as u32),
            |img: &mut super::Image, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let w = img.width as usize;
                if let Some(p) = img.pixels.get_mut(pos.y() * w + pos.x()) {
                    *p = Rgb::new(r, g, b);
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(bad)?;
    Ok(img.layer_data.channel_data.pixels)
}

/// Reads a PFM file (colour "PF" or greyscale "Pf", either byte order).
pub fn read_pfm(path: &Path) -> Result<Image> {
    let bytes = read_limited(path, MAX_IMAGE_FILE_BYTES).map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    parse_pfm(&bytes).map_err(|m| Error::file(path, format!("not a valid PFM file: {m}")))
}

fn parse_pfm(bytes: &[u8]) -> Result<Image, String> {
    // Header: three whitespace-separated tokens after the magic, then one
    // whitespace byte before the data.
    let mut pos = 0;
    let mut token = || -> Result<String, String> {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos {
            return Err("truncated header".into());
        }
        Ok(String::from_utf8_lossy(&bytes[start..pos]).into_owned())
    };
    let magic = token()?;
    let channels = match magic.as_str() {
        "PF" => 3,
        "Pf" => 1,
        _ => return Err(format!("bad magic {magic:?}")),
    };
    let w: u32 = token()?.parse().map_err(|_| "bad width".to_string())?;
    let h: u32 = token()?.parse().map_err(|_| "bad height".to_string())?;
    let scale: f32 = token()?.parse().map_err(|_| "bad scale".to_string())?;
    if w == 0 || h == 0 {
        return Err(format!("an image of {w}×{h} pixels has no pixels"));
    }
    let data = &bytes[(pos + 1).min(bytes.len())..];
    let need = w as u128 * h as u128 * channels as u128 * 4;
    if (data.len() as u128) < need {
        return Err(format!(
            "{w}×{h} pixels need {need} bytes of data, the file has {}",
            data.len()
        ));
    }
    let little = scale < 0.0;
    let read = |i: usize| -> f32 {
        let b = [data[4 * i], data[4 * i + 1], data[4 * i + 2], data[4 * i + 3]];
        if little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    };
    let mut img = Image::new(w, h);
    for row in 0..h as usize {
        let y = h as usize - 1 - row;
        for x in 0..w as usize {
            let i = (row * w as usize + x) * channels;
            img.pixels[y * w as usize + x] = if channels == 3 {
                Rgb::new(read(i), read(i + 1), read(i + 2))
            } else {
                Rgb::splat(read(i))
            };
        }
    }
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient() -> Image {
        let mut img = Image::new(4, 3);
        for (i, p) in img.pixels.iter_mut().enumerate() {
            *p = Rgb::new(i as f32 * 0.1, 2.5, 1e-3 * i as f32);
        }
        img
    }

    /// A write that fails or panics half-way leaves no temporary file, and
    /// one left by a process that no longer runs is removed by the next
    /// write of the same file; a running process's is kept.
    #[test]
    fn no_temporary_file_outlives_its_writer() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.exr");
        let listing = || {
            let mut v: Vec<String> = fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name().into_string().unwrap())
                .collect();
            v.sort();
            v
        };
        let failed = write_atomic(&target, |f| {
            f.write_all(b"half").unwrap();
            Err("the encoder failed".into())
        });
        assert!(failed.is_err());
        assert!(listing().is_empty(), "{:?}", listing());
        let panicked = std::panic::catch_unwind(|| {
            let _ = write_atomic(&target, |f| {
                f.write_all(b"half").unwrap();
                panic!("the encoder panicked")
            });
        });
        assert!(panicked.is_err());
        assert!(listing().is_empty(), "{:?}", listing());
        assert!(!UNFINISHED.lock().unwrap().iter().any(|p| p.starts_with(dir.path())));

        // A process number above Linux's largest runs nowhere; process 1
        // always runs.
        let dead = dir.path().join(temp_name(&target, 4_194_999));
        let running = dir.path().join(temp_name(&target, 1));
        let other = dir.path().join(temp_name(&dir.path().join("other.exr"), 4_194_999));
        for p in [&dead, &running, &other] {
            fs::write(p, b"left over").unwrap();
        }
        write_atomic(&target, |f| f.write_all(b"done").map_err(|e| e.to_string())).unwrap();
        let mut expected = vec![
            "out.exr".to_string(),
            ".other.exr.4194999.tmp.exr".into(),
            ".out.exr.1.tmp.exr".into(),
        ];
        if !Path::new("/proc/self").is_dir() {
            expected.push(".out.exr.4194999.tmp.exr".into());
        }
        expected.sort();
        assert_eq!(listing(), expected);
        assert_eq!(stale_temp_pid(&target, ".out.exr.+12.tmp.exr"), None);
        assert_eq!(stale_temp_pid(&target, ".out.exr.12.tmp.exr"), Some(12));
        assert_eq!(stale_temp_pid(&target, ".out.exr.12.tmp.png"), None);
    }

    #[test]
    fn float_formats_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let img = gradient();
        for ext in ["exr", "pfm"] {
            let p = dir.path().join(format!("x.{ext}"));
            write_image(&p, &img, Tonemap::Clamp, 0.0).unwrap();
            let back = read_image(&p).unwrap();
            assert_eq!(back, img, "{ext}");
        }
        // RGBE keeps about 8 bits of mantissa per pixel.
        let p = dir.path().join("x.hdr");
        write_image(&p, &img, Tonemap::Clamp, 0.0).unwrap();
        let back = read_image(&p).unwrap();
        for (a, b) in back.pixels.iter().zip(&img.pixels) {
            assert!(
                (*a - *b).abs().max_element() <= 0.01 * b.max_element() + 1e-6,
                "{a} vs {b}"
            );
        }
    }

    #[test]
    fn png_is_tonemapped_srgb() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = Image::new(2, 1);
        img.pixels = vec![Rgb::splat(0.5), Rgb::splat(4.0)];
        let p = dir.path().join("x.png");
        write_image(&p, &img, Tonemap::Clamp, 0.0).unwrap();
        let png = ::image::open(&p).unwrap().to_rgb8();
        assert_eq!(png.get_pixel(0, 0)[0], (linear_to_srgb(0.5) * 255.0 + 0.5) as u8);
        assert_eq!(png.get_pixel(1, 0)[0], 255);
        // One stop down halves the linear value.
        write_image(&p, &img, Tonemap::Clamp, -1.0).unwrap();
        let png = ::image::open(&p).unwrap().to_rgb8();
        assert_eq!(png.get_pixel(0, 0)[0], (linear_to_srgb(0.25) * 255.0 + 0.5) as u8);
    }

    #[test]
    fn bad_targets_are_errors_and_leave_no_temp_files() {
        let dir = tempfile::tempdir().unwrap();
        let img = gradient();
        assert!(write_image(&dir.path().join("x.bmp"), &img, Tonemap::Clamp, 0.0).is_err());
        assert!(write_image(&dir.path().join("x"), &img, Tonemap::Clamp, 0.0).is_err());
        assert!(write_image(&dir.path().join("missing/x.png"), &img, Tonemap::Clamp, 0.0).is_err());
        assert!(write_image(dir.path(), &img, Tonemap::Clamp, 0.0).is_err());
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn overwrite_replaces_whole_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.pfm");
        fs::write(&p, b"old").unwrap();
        write_image(&p, &gradient(), Tonemap::Clamp, 0.0).unwrap();
        assert_eq!(read_image(&p).unwrap(), gradient());
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn truncated_pfm_is_rejected() {
        assert!(parse_pfm(b"PF\n4 4\n-1.0\n\0\0\0\0").is_err());
        assert!(parse_pfm(b"P6\n1 1\n255\n").is_err());
        assert!(parse_pfm(b"PF\n").is_err());
    }
}
