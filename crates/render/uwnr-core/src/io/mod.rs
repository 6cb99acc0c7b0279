//! Image decoding and encoding at the edge of uwnr: files (PNG, JPEG, TIFF, BMP, WebP) to planar
//! f32 [`Image`]s in [0, 1] and back.
//!
//! Conventions, chosen to match what the released UWNR code sees through PIL / OpenCV and writes
//! with torchvision's `save_image`:
//! - integer samples map to `code / max_code` (8-bit `/255`, 16-bit `/65535`); float samples are
//!   used as stored, clamped to [0, 1] (non-finite values become 0);
//! - alpha is dropped: the colour values are used as stored (neither premultiplied nor
//!   composited onto a background);
//! - RGB to grey is ITU-R 601 luma exactly as PIL's `convert("L")`
//!   (`(19595 R + 38470 G + 7471 B + 0x8000) >> 16` on 8-bit data);
//! - f32 to u8 rounds half up and clamps, `(v * 255 + 0.5).clamp(0, 255) as u8`
//!   (torchvision `save_image`; [`quantise_u8`]);
//! - the EXIF orientation of JPEG, TIFF and WebP files is applied.
//!
//! Decoding checks the dimensions in the header against [`DecodeLimits`] before any pixel buffer
//! is allocated. Writing goes to a temporary file in the target directory that is synced to disk
//! and renamed into place ([`write_atomic`]), so an interrupted or failed write, or a crash, leaves
//! no partial file.

use std::fs;
use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageDecoder, ImageFormat, ImageReader, Limits};

use crate::error::{CoreError, Result};
use crate::image::Image;

mod write;

pub use write::{
    encode_rgb_png, save_gray, save_gray16, save_rgb, save_rgb16, to_rgb8, write_atomic,
    write_atomic_bytes,
};

/// Default [`DecodeLimits::max_pixels`]: 250 megapixels (about 3 GB as planar f32 RGB).
pub const DEFAULT_MAX_PIXELS: u64 = 250_000_000;
/// Default [`DecodeLimits::max_dimension`]: the largest side a JPEG can express.
pub const DEFAULT_MAX_DIMENSION: u32 = 65_535;
/// JPEG quality of saved images (the quality PIL users typically pick for near-lossless output).
pub const JPEG_QUALITY: u8 = 95;
/// File extensions (lower case) that [`is_image_path`] accepts.
pub const IMAGE_EXTENSIONS: [&str; 7] = ["png", "jpg", "jpeg", "bmp", "tif", "tiff", "webp"];

/// Largest number of bytes per decoded pixel (RGBA f32): bounds the decoder's own allocations.
const MAX_BYTES_PER_PIXEL: u64 = 16;
/// Minimum allocation budget handed to the decoders (the `image` crate's own default).
const MIN_DECODER_ALLOC: u64 = 512 * 1024 * 1024;
/// Name used in errors for images decoded from memory.
const MEMORY_SOURCE: &str = "<memory>";

/// ITU-R 601 luma weights in PIL's 16-bit fixed point (`libImaging/Convert.c`, `L24`).
const PIL_LUMA_R: u32 = 19_595;
const PIL_LUMA_G: u32 = 38_470;
const PIL_LUMA_B: u32 = 7_471;
const PIL_LUMA_ROUND: u32 = 0x8000;
const PIL_LUMA_SHIFT: u32 = 16;
/// ITU-R 601 luma weights for 16-bit and float data.
const LUMA_601: [f32; 3] = [0.299, 0.587, 0.114];

/// Limits checked against an image header before its pixels are decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DecodeLimits {
    /// Largest accepted `width * height`.
    pub max_pixels: u64,
    /// Largest accepted width or height.
    pub max_dimension: u32,
}

impl Default for DecodeLimits {
    fn default() -> Self {
        Self {
            max_pixels: DEFAULT_MAX_PIXELS,
            max_dimension: DEFAULT_MAX_DIMENSION,
        }
    }
}

/// Decodes an image file into 3 channels (R, G, B) in [0, 1]. Grey images are replicated to
/// three channels; alpha is dropped; EXIF orientation is applied. The header is checked against
/// `limits` before any pixel is decoded ([`CoreError::TooLarge`],
/// [`CoreError::DimensionTooLarge`]); unreadable content gives [`CoreError::Decode`].
pub fn load_rgb(path: &Path, limits: &DecodeLimits) -> Result<Image> {
    let bytes = read_file(path)?;
    let decoded = decode(&bytes, path, limits)?;
    to_planar(&decoded, Target::Rgb)
}

/// Decodes an encoded image held in memory into 3 channels in [0, 1] (as [`load_rgb`]).
pub fn load_rgb_from_memory(bytes: &[u8], limits: &DecodeLimits) -> Result<Image> {
    let decoded = decode(bytes, Path::new(MEMORY_SOURCE), limits)?;
    to_planar(&decoded, Target::Rgb)
}

/// An encoded image's width, height and bytes per decoded pixel (its sample layout as stored),
/// from the header alone: what decoding it will allocate, known before any pixel is decoded.
pub fn probe_memory(bytes: &[u8]) -> Result<(u32, u32, u64)> {
    let path = Path::new(MEMORY_SOURCE);
    let decoder = ImageReader::new(Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| decode_error(path, e))?
        .into_decoder()
        .map_err(|e| decode_error(path, e))?;
    let (w, h) = decoder.dimensions();
    Ok((w, h, u64::from(decoder.color_type().bytes_per_pixel())))
}

/// Decodes an encoded image held in memory with the checks of [`load_rgb_from_memory`], without
/// converting its pixels: its `(width, height)`. What accepting a file needs, in the decoded
/// size as stored (3 bytes a pixel for 8-bit RGB) instead of 12 more for planar f32.
pub fn check_decodes(bytes: &[u8], limits: &DecodeLimits) -> Result<(usize, usize)> {
    let decoded = decode(bytes, Path::new(MEMORY_SOURCE), limits)?;
    Ok((decoded.width() as usize, decoded.height() as usize))
}

/// Decodes an image file into 1 channel: the raw code value over the maximum code (8-bit `/255`,
/// 16-bit `/65535`). Colour images are converted to ITU-R 601 luma as PIL's `convert("L")` does.
pub fn load_gray(path: &Path, limits: &DecodeLimits) -> Result<Image> {
    let bytes = read_file(path)?;
    let decoded = decode(&bytes, path, limits)?;
    to_planar(&decoded, Target::Gray)
}

/// Decodes an encoded grey map held in memory (as [`load_gray`]).
pub fn load_gray_from_memory(bytes: &[u8], limits: &DecodeLimits) -> Result<Image> {
    let decoded = decode(bytes, Path::new(MEMORY_SOURCE), limits)?;
    to_planar(&decoded, Target::Gray)
}

/// Decodes a grey map file into 1 channel of raw code values, with the largest code its sample
/// type can hold: `(codes, 255)` for 8-bit files, `(codes, 65535)` for 16-bit files and
/// `(values, 1)` for float files (32-bit float TIFF), whose values are kept as stored. Metric
/// depth maps need the codes themselves (16-bit millimetres), not [`load_gray`]'s fraction.
pub fn load_gray_codes(path: &Path, limits: &DecodeLimits) -> Result<(Image, f32)> {
    let bytes = read_file(path)?;
    gray_codes(&bytes, path, limits)
}

/// Decodes an encoded grey map held in memory into its raw codes (as [`load_gray_codes`]).
pub fn load_gray_codes_from_memory(bytes: &[u8], limits: &DecodeLimits) -> Result<(Image, f32)> {
    gray_codes(bytes, Path::new(MEMORY_SOURCE), limits)
}

fn gray_codes(bytes: &[u8], path: &Path, limits: &DecodeLimits) -> Result<(Image, f32)> {
    let decoded = decode(bytes, path, limits)?;
    let max_code = match decoded.color().bytes_per_pixel() / decoded.color().channel_count() {
        1 => f32::from(u8::MAX),
        2 => f32::from(u16::MAX),
        _ => 1.0,
    };
    let mut img = to_planar(&decoded, Target::Gray)?;
    if max_code != 1.0 {
        for v in img.plane_mut(0) {
            *v = (*v * max_code).round();
        }
    }
    Ok((img, max_code))
}

/// Whether the path has an image extension uwnr reads: png, jpg, jpeg, bmp, tif, tiff, webp
/// (any case).
#[must_use]
pub fn is_image_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| IMAGE_EXTENSIONS.iter().any(|x| e.eq_ignore_ascii_case(x)))
}

/// Whether `rel`, a path read from a file (a manifest line, a settings file), names something
/// inside the folder it is relative to: not empty, not absolute, no root or drive prefix and no
/// `..` component. Paths that fail it must be refused before they are joined onto a folder: a
/// crafted `../secret.txt` would otherwise read or write outside it.
#[must_use]
pub fn stays_inside(rel: &Path) -> bool {
    use std::path::Component;
    let mut normal = false;
    for c in rel.components() {
        match c {
            Component::Normal(_) => normal = true,
            Component::CurDir => {}
            Component::ParentDir | Component::RootDir | Component::Prefix(_) => return false,
        }
    }
    normal
}

fn read_file(path: &Path) -> Result<Vec<u8>> {
    fs::read(path).map_err(|source| CoreError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn decode_error(path: &Path, reason: impl Into<crate::error::Cause>) -> CoreError {
    CoreError::Decode {
        path: path.to_path_buf(),
        source: reason.into(),
    }
}

/// Decodes `bytes`, checking the header against `limits` first and applying EXIF orientation.
fn decode(bytes: &[u8], path: &Path, limits: &DecodeLimits) -> Result<DynamicImage> {
    if bytes.is_empty() {
        return Err(decode_error(path, "empty file"));
    }
    let reader = |limits: Limits| -> Result<ImageReader<Cursor<&[u8]>>> {
        let mut r = ImageReader::new(Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| decode_error(path, e))?;
        if r.format().is_none() {
            return Err(decode_error(path, "unrecognised image format"));
        }
        r.limits(limits);
        Ok(r)
    };
    // First pass: the header only, without the `image` crate's allocation limit, so that an
    // oversized image is reported with its dimensions.
    let probe = reader(Limits::no_limits())?;
    let format = probe.format();
    let (width, height) = probe.into_dimensions().map_err(|e| decode_error(path, e))?;
    check_limits(path, width, height, limits)?;
    if format == Some(ImageFormat::Jpeg) {
        check_jpeg_complete(bytes).map_err(|reason| decode_error(path, reason))?;
    }

    let mut decoder_limits = Limits::default();
    decoder_limits.max_image_width = Some(limits.max_dimension);
    decoder_limits.max_image_height = Some(limits.max_dimension);
    decoder_limits.max_alloc = Some(
        limits
            .max_pixels
            .saturating_mul(MAX_BYTES_PER_PIXEL)
            .max(MIN_DECODER_ALLOC),
    );
    let mut decoder = reader(decoder_limits)?
        .into_decoder()
        .map_err(|e| decode_error(path, e))?;
    // A malformed EXIF block should not make an otherwise readable image unreadable.
    let orientation = decoder.orientation().ok();
    let mut image = DynamicImage::from_decoder(decoder).map_err(|e| decode_error(path, e))?;
    if let Some(o) = orientation {
        image.apply_orientation(o);
    }
    if image.width() == 0 || image.height() == 0 {
        return Err(decode_error(path, "image has no pixels"));
    }
    Ok(image)
}

fn check_limits(path: &Path, width: u32, height: u32, limits: &DecodeLimits) -> Result<()> {
    if width > limits.max_dimension || height > limits.max_dimension {
        return Err(CoreError::DimensionTooLarge {
            path: path.to_path_buf(),
            width: width.into(),
            height: height.into(),
            max_dimension: limits.max_dimension,
        });
    }
    if u64::from(width) * u64::from(height) > limits.max_pixels {
        return Err(CoreError::TooLarge {
            path: path.to_path_buf(),
            width: width.into(),
            height: height.into(),
            max_pixels: limits.max_pixels,
        });
    }
    Ok(())
}

/// Walks the JPEG marker structure and fails unless an end-of-image marker is reached.
///
/// The JPEG decoder behind `image` is lenient and fills a truncated file's missing data with
/// grey; a truncated reference would silently give a wrong light-field map, so it is rejected.
fn check_jpeg_complete(bytes: &[u8]) -> std::result::Result<(), String> {
    const MARKER: u8 = 0xFF;
    const SOI: u8 = 0xD8;
    const EOI: u8 = 0xD9;
    const SOS: u8 = 0xDA;
    const TEM: u8 = 0x01;
    const RST: std::ops::RangeInclusive<u8> = 0xD0..=0xD7;
    const STUFFED: u8 = 0x00;
    let truncated = || "truncated JPEG (no end-of-image marker)".to_string();

    if bytes.len() < 2 || bytes[0] != MARKER || bytes[1] != SOI {
        return Err("not a JPEG stream".into());
    }
    let mut pos = 2;
    loop {
        // Skip to the next marker (tolerating stray bytes, as libjpeg does) and fill bytes.
        while pos < bytes.len() && bytes[pos] != MARKER {
            pos += 1;
        }
        while pos < bytes.len() && bytes[pos] == MARKER {
            pos += 1;
        }
        let Some(&marker) = bytes.get(pos) else {
            return Err(truncated());
        };
        pos += 1;
        if marker == EOI {
            return Ok(());
        }
        if marker == TEM || RST.contains(&marker) || marker == STUFFED {
            continue;
        }
        let (Some(&hi), Some(&lo)) = (bytes.get(pos), bytes.get(pos + 1)) else {
            return Err(truncated());
        };
        let len = usize::from(u16::from_be_bytes([hi, lo]));
        if len < 2 {
            return Err(format!("corrupt JPEG segment length {len}"));
        }
        pos += len;
        if pos > bytes.len() {
            return Err(truncated());
        }
        if marker == SOS {
            // Entropy-coded data runs until a marker that is neither stuffing nor a restart.
            loop {
                let (Some(&b), Some(&next)) = (bytes.get(pos), bytes.get(pos + 1)) else {
                    return Err(truncated());
                };
                if b == MARKER && next != STUFFED && next != MARKER && !RST.contains(&next) {
                    break;
                }
                pos += if b == MARKER && next != MARKER { 2 } else { 1 };
            }
        }
    }
}

/// What a decoded image is converted to.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Target {
    Rgb,
    Gray,
}

/// Interleaved samples of a decoded image.
enum Samples<'a> {
    U8(&'a [u8]),
    U16(&'a [u16]),
    F32(&'a [f32]),
}

fn to_planar(decoded: &DynamicImage, target: Target) -> Result<Image> {
    let (w, h) = (decoded.width() as usize, decoded.height() as usize);
    // Variants this code does not know (the enum is non-exhaustive) go through RGBA f32.
    let converted;
    let img = match decoded {
        DynamicImage::ImageLuma8(_)
        | DynamicImage::ImageLumaA8(_)
        | DynamicImage::ImageRgb8(_)
        | DynamicImage::ImageRgba8(_)
        | DynamicImage::ImageLuma16(_)
        | DynamicImage::ImageLumaA16(_)
        | DynamicImage::ImageRgb16(_)
        | DynamicImage::ImageRgba16(_)
        | DynamicImage::ImageRgb32F(_)
        | DynamicImage::ImageRgba32F(_) => decoded,
        other => {
            converted = DynamicImage::ImageRgba32F(other.to_rgba32f());
            &converted
        }
    };
    let stride = usize::from(img.color().channel_count());
    let colour = if img.color().has_color() { 3 } else { 1 };
    let samples = match img {
        DynamicImage::ImageLuma8(b) => Samples::U8(b.as_raw()),
        DynamicImage::ImageLumaA8(b) => Samples::U8(b.as_raw()),
        DynamicImage::ImageRgb8(b) => Samples::U8(b.as_raw()),
        DynamicImage::ImageRgba8(b) => Samples::U8(b.as_raw()),
        DynamicImage::ImageLuma16(b) => Samples::U16(b.as_raw()),
        DynamicImage::ImageLumaA16(b) => Samples::U16(b.as_raw()),
        DynamicImage::ImageRgb16(b) => Samples::U16(b.as_raw()),
        DynamicImage::ImageRgba16(b) => Samples::U16(b.as_raw()),
        DynamicImage::ImageRgb32F(b) => Samples::F32(b.as_raw()),
        DynamicImage::ImageRgba32F(b) => Samples::F32(b.as_raw()),
        // Unreachable: every other variant was converted to RGBA f32 above.
        _ => Samples::F32(&[]),
    };
    let n = w * h;
    match (target, colour, samples) {
        // PIL's exact 8-bit luma.
        (Target::Gray, 3, Samples::U8(s)) => {
            let data = s
                .chunks_exact(stride)
                .map(|p| {
                    let l = (PIL_LUMA_R * u32::from(p[0])
                        + PIL_LUMA_G * u32::from(p[1])
                        + PIL_LUMA_B * u32::from(p[2])
                        + PIL_LUMA_ROUND)
                        >> PIL_LUMA_SHIFT;
                    l as f32 / f32::from(u8::MAX)
                })
                .collect();
            Image::from_planar(w, h, 1, data)
        }
        (target, colour, samples) => {
            let values: Vec<f32> = match samples {
                Samples::U8(s) => s
                    .iter()
                    .map(|&v| f32::from(v) / f32::from(u8::MAX))
                    .collect(),
                Samples::U16(s) => s
                    .iter()
                    .map(|&v| f32::from(v) / f32::from(u16::MAX))
                    .collect(),
                Samples::F32(s) => s
                    .iter()
                    .map(|&v| {
                        if v.is_finite() {
                            v.clamp(0.0, 1.0)
                        } else {
                            0.0
                        }
                    })
                    .collect(),
            };
            let out_channels = if target == Target::Rgb { 3 } else { 1 };
            let mut data = vec![0.0_f32; n * out_channels];
            for (i, p) in values.chunks_exact(stride).enumerate() {
                match (target, colour) {
                    (Target::Rgb, 3) => {
                        for c in 0..3 {
                            data[c * n + i] = p[c];
                        }
                    }
                    (Target::Rgb, _) => {
                        for c in 0..3 {
                            data[c * n + i] = p[0];
                        }
                    }
                    (Target::Gray, 3) => {
                        data[i] = LUMA_601[0] * p[0] + LUMA_601[1] * p[1] + LUMA_601[2] * p[2];
                    }
                    (Target::Gray, _) => data[i] = p[0],
                }
            }
            Image::from_planar(w, h, out_channels, data)
        }
    }
}
