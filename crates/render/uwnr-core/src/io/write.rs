//! Encoding and writing: planar f32 [`Image`]s to 8- and 16-bit PNG and JPEG, written through
//! [`write_atomic`] (a temporary file, synced, then renamed), so that no partial file is ever
//! left.

use std::fs::{self, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use image::codecs::jpeg::JpegEncoder;
use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder, ImageFormat};

use super::{JPEG_QUALITY, MEMORY_SOURCE};
use crate::error::{CoreError, Result};
use crate::image::{Image, quantise_u8};

/// Saves a 3-channel image as 8-bit PNG or JPEG (quality [`JPEG_QUALITY`]), chosen by the
/// extension (`.png`, `.jpg`, `.jpeg`, any case). Values are rounded as [`to_rgb8`] does.
pub fn save_rgb(path: &Path, img: &Image) -> Result<()> {
    let format = output_format(path)?;
    let (w, h) = checked_size(path, img, 3)?;
    let encoded = encode(path, format, &to_rgb8(img), w, h, ExtendedColorType::Rgb8)?;
    write_atomic_bytes(path, &encoded)
}

/// Encodes a 3-channel image as an 8-bit PNG in memory: the bytes [`save_rgb`] writes to a
/// `.png` file (a server can answer with exactly what `uwnr render` would have written).
pub fn encode_rgb_png(img: &Image) -> Result<Vec<u8>> {
    let path = Path::new(MEMORY_SOURCE);
    let (w, h) = checked_size(path, img, 3)?;
    encode(
        path,
        ImageFormat::Png,
        &to_rgb8(img),
        w,
        h,
        ExtendedColorType::Rgb8,
    )
}

/// Saves a 3-channel image as a 16-bit RGB PNG (`(v * 65535 + 0.5).clamp(0, 65535)`). The
/// extension must be `.png`.
pub fn save_rgb16(path: &Path, img: &Image) -> Result<()> {
    if output_format(path)? != ImageFormat::Png {
        return Err(CoreError::Encode {
            path: path.to_path_buf(),
            source: "16-bit images can only be saved as PNG".into(),
        });
    }
    let (w, h) = checked_size(path, img, 3)?;
    let bytes: Vec<u8> = img
        .to_interleaved()
        .iter()
        .flat_map(|&v| quantise_u16(v).to_ne_bytes())
        .collect();
    let encoded = encode(
        path,
        ImageFormat::Png,
        &bytes,
        w,
        h,
        ExtendedColorType::Rgb16,
    )?;
    write_atomic_bytes(path, &encoded)
}

/// Saves a 1-channel image as a 16-bit grey PNG (`(v * 65535 + 0.5).clamp(0, 65535)`), the form
/// depth maps keep their precision in ([`load_gray`] reads it back as `code / 65535`). The
/// extension must be `.png`.
pub fn save_gray16(path: &Path, img: &Image) -> Result<()> {
    if output_format(path)? != ImageFormat::Png {
        return Err(CoreError::Encode {
            path: path.to_path_buf(),
            source: "16-bit images can only be saved as PNG".into(),
        });
    }
    let (w, h) = checked_size(path, img, 1)?;
    let bytes: Vec<u8> = img
        .plane(0)
        .iter()
        .flat_map(|&v| quantise_u16(v).to_ne_bytes())
        .collect();
    let encoded = encode(path, ImageFormat::Png, &bytes, w, h, ExtendedColorType::L16)?;
    write_atomic_bytes(path, &encoded)
}

/// Saves a 1-channel image as 8-bit grey PNG or JPEG, chosen by the extension.
pub fn save_gray(path: &Path, img: &Image) -> Result<()> {
    let format = output_format(path)?;
    let (w, h) = checked_size(path, img, 1)?;
    let encoded = encode(
        path,
        format,
        &img.to_u8_codes(),
        w,
        h,
        ExtendedColorType::L8,
    )?;
    write_atomic_bytes(path, &encoded)
}

/// Interleaved 8-bit RGB of an image, rounding half up and clamping:
/// `(v * 255 + 0.5).clamp(0, 255) as u8` (torchvision `save_image`'s rule). A 1-channel image is
/// replicated to grey RGB; channels beyond the third are ignored; an image with 2 channels uses
/// its first channel for all three.
#[must_use]
pub fn to_rgb8(img: &Image) -> Vec<u8> {
    let n = img.width() * img.height();
    if img.channels() == 0 {
        return vec![0; n * 3];
    }
    let planes: [&[f32]; 3] = if img.channels() >= 3 {
        [img.plane(0), img.plane(1), img.plane(2)]
    } else {
        [img.plane(0); 3]
    };
    let mut out = vec![0_u8; n * 3];
    for (i, px) in out.chunks_exact_mut(3).enumerate() {
        for (dst, plane) in px.iter_mut().zip(planes) {
            *dst = quantise_u8(plane[i]);
        }
    }
    out
}

/// Writes a file atomically and durably, the one rule every file uwnr writes follows:
///
/// 1. a temporary file `.NAME.PID-N.tmp` is created in `path`'s directory (a rename is only
///    atomic within one file system; the name is what `uwnr-dataset` recognises as a leftover);
/// 2. `write` fills it through a buffer, which is flushed, and the file is `sync_all`ed, so its
///    bytes are on disk before its name is;
/// 3. it is renamed to `path`, replacing any earlier file;
/// 4. on unix the directory is then fsynced, best effort, so that the rename itself survives a
///    power cut (a failure there is ignored: some file systems cannot sync a directory, and the
///    file is complete under one name or the other either way).
///
/// A reader therefore sees the old file or the whole new one, never a part. On any failure up to
/// the rename the temporary file is removed and `path` is left as it was.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let io_err = |source| CoreError::Io {
        path: path.to_path_buf(),
        source,
    };
    let name = path
        .file_name()
        .ok_or_else(|| CoreError::InvalidArgument(format!("{path:?} does not name a file")))?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let tmp = dir.join(format!(
        ".{}.{}-{}.tmp",
        name.to_string_lossy(),
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&tmp)
        .map_err(io_err)?;
    let written = (|| {
        let mut out = BufWriter::new(file);
        write(&mut out)?;
        let file = out.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()
        // The file is closed here, before the rename.
    })();
    let result = written.and_then(|()| fs::rename(&tmp, path));
    if let Err(e) = result {
        // Best effort: the temporary file may not exist any more.
        let _ = fs::remove_file(&tmp);
        return Err(io_err(e));
    }
    sync_dir(dir);
    Ok(())
}

/// [`write_atomic`] of a buffer already in memory.
pub fn write_atomic_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |out| out.write_all(bytes))
}

/// Fsyncs a directory so that a rename into it is durable. Best effort: errors are ignored (see
/// [`write_atomic`]). Directories cannot be opened as files on Windows, where this does nothing.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = fs::File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

fn quantise_u16(v: f32) -> u16 {
    (v * 65_535.0 + 0.5).clamp(0.0, 65_535.0) as u16
}

fn output_format(path: &Path) -> Result<ImageFormat> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
    if ext.eq_ignore_ascii_case("png") {
        Ok(ImageFormat::Png)
    } else if ext.eq_ignore_ascii_case("jpg") || ext.eq_ignore_ascii_case("jpeg") {
        Ok(ImageFormat::Jpeg)
    } else {
        Err(CoreError::Encode {
            path: path.to_path_buf(),
            source: format!("unsupported output extension {ext:?} (use .png, .jpg or .jpeg)")
                .into(),
        })
    }
}

fn checked_size(path: &Path, img: &Image, channels: usize) -> Result<(u32, u32)> {
    if img.channels() != channels {
        return Err(CoreError::ShapeMismatch {
            expected: (channels, img.height(), img.width()),
            got: (img.channels(), img.height(), img.width()),
        });
    }
    if img.width() == 0 || img.height() == 0 {
        return Err(CoreError::Empty {
            width: img.width(),
            height: img.height(),
        });
    }
    let too_big = || CoreError::Encode {
        path: path.to_path_buf(),
        source: format!("{}x{} is too large to encode", img.width(), img.height()).into(),
    };
    Ok((
        u32::try_from(img.width()).map_err(|_| too_big())?,
        u32::try_from(img.height()).map_err(|_| too_big())?,
    ))
}

fn encode(
    path: &Path,
    format: ImageFormat,
    bytes: &[u8],
    w: u32,
    h: u32,
    colour: ExtendedColorType,
) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    let result = match format {
        ImageFormat::Jpeg => {
            JpegEncoder::new_with_quality(&mut out, JPEG_QUALITY).write_image(bytes, w, h, colour)
        }
        _ => PngEncoder::new(&mut out).write_image(bytes, w, h, colour),
    };
    result.map_err(|e| CoreError::Encode {
        path: PathBuf::from(path),
        source: e.into(),
    })?;
    Ok(out)
}
