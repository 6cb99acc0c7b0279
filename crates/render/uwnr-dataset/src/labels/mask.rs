//! Segmentation label rasters (PNG): read with their values exactly as stored (grey, grey+alpha,
//! RGB, RGBA at 8 or 16 bits, palette indices with the palette), carried to the pair by
//! nearest-neighbour resampling, and written back in the same colour type, so class ids and
//! instance colours never blend. Sub-byte depths (1, 2, 4 bits) are written at 8 bits with the
//! same values.

use std::io::Cursor;
use std::path::Path;

use uwnr_core::io::DecodeLimits;

use super::geometry::Fit;

/// A decoded label raster.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LabelImage {
    pub width: usize,
    pub height: usize,
    pub color: png::ColorType,
    /// 8 or 16.
    pub bits: u8,
    /// Samples, row-major, one byte per sample at 8 bits, two (big-endian) at 16.
    pub data: Vec<u8>,
    pub palette: Option<Vec<u8>>,
    pub trns: Option<Vec<u8>>,
}

impl LabelImage {
    /// Bytes per pixel.
    #[must_use]
    pub fn pixel_bytes(&self) -> usize {
        self.color.samples() * usize::from(self.bits / 8)
    }

    /// Decodes a PNG label image, refusing other formats and sizes beyond `limits`.
    pub fn decode(bytes: &[u8], limits: &DecodeLimits) -> Result<Self, String> {
        if !bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
            return Err("not a PNG file (label masks must be PNG, whose values are exact)".into());
        }
        let mut decoder = png::Decoder::new_with_limits(
            Cursor::new(bytes),
            png::Limits {
                bytes: usize::MAX / 2,
            },
        );
        decoder.set_transformations(png::Transformations::IDENTITY);
        let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
        let info = reader.info();
        let (width, height) = (info.width as usize, info.height as usize);
        if info.width > limits.max_dimension
            || info.height > limits.max_dimension
            || (width as u64) * (height as u64) > limits.max_pixels
        {
            return Err(format!(
                "{width}x{height} is larger than the decoding limits allow"
            ));
        }
        let color = info.color_type;
        let depth = info.bit_depth as u8;
        let palette = info.palette.as_ref().map(|p| p.to_vec());
        let trns = info.trns.as_ref().map(|t| t.to_vec());
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| "the image is too large".to_string())?;
        let mut buf = vec![0; size];
        let out = reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
        let samples = color.samples();
        let data = if depth >= 8 {
            let row = width * samples * usize::from(depth / 8);
            let mut data = Vec::with_capacity(row * height);
            for y in 0..height {
                data.extend_from_slice(&buf[y * out.line_size..y * out.line_size + row]);
            }
            data
        } else {
            // Sub-byte samples (grey or palette, one sample per pixel), most significant first.
            let per_byte = 8 / usize::from(depth);
            let mask = (1u16 << depth) as u8 - 1;
            let mut data = Vec::with_capacity(width * height);
            for y in 0..height {
                let line = &buf[y * out.line_size..];
                for x in 0..width {
                    let byte = line[x / per_byte];
                    let shift = 8 - usize::from(depth) * (x % per_byte + 1);
                    data.push((byte >> shift) & mask);
                }
            }
            data
        };
        Ok(Self {
            width,
            height,
            color,
            bits: depth.max(8),
            data,
            palette,
            trns,
        })
    }

    /// Reads a PNG label image file.
    pub fn read(path: &Path, limits: &DecodeLimits) -> Result<Self, String> {
        let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
        Self::decode(&bytes, limits)
    }

    /// The raster carried to the pair (nearest neighbour, values unchanged).
    #[must_use]
    pub fn fitted(&self, fit: &Fit) -> Self {
        Self {
            width: fit.width,
            height: fit.height,
            data: fit.resample(&self.data, self.pixel_bytes()),
            ..self.clone()
        }
    }

    /// Encodes as PNG (deterministic: fixed compression, no timestamps).
    pub fn encode(&self) -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, self.width as u32, self.height as u32);
        enc.set_color(self.color);
        enc.set_depth(if self.bits == 16 {
            png::BitDepth::Sixteen
        } else {
            png::BitDepth::Eight
        });
        if let Some(p) = &self.palette {
            enc.set_palette(p.clone());
        }
        if let Some(t) = &self.trns {
            enc.set_trns(t.clone());
        }
        let mut w = enc.write_header().map_err(|e| e.to_string())?;
        w.write_image_data(&self.data).map_err(|e| e.to_string())?;
        w.finish().map_err(|e| e.to_string())?;
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::Size;

    fn limits() -> DecodeLimits {
        DecodeLimits::default()
    }

    #[test]
    fn palette_masks_keep_indices_and_palette() {
        let img = LabelImage {
            width: 4,
            height: 2,
            color: png::ColorType::Indexed,
            bits: 8,
            data: vec![0, 1, 2, 3, 3, 2, 1, 0],
            palette: Some(vec![0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0, 255]),
            trns: None,
        };
        let back = LabelImage::decode(&img.encode().unwrap(), &limits()).unwrap();
        assert_eq!(back, img);
        let fit = Fit::new(
            (4, 2),
            Size::Fixed {
                width: 16,
                height: 16,
            },
        );
        let big = img.fitted(&fit);
        assert_eq!((big.width, big.height), (16, 16));
        let mut values: Vec<u8> = big.data.clone();
        values.sort_unstable();
        values.dedup();
        // 4x2 covers 16x16 at 8x (32x16), cropped to the middle: source columns 1 and 2 only.
        assert_eq!(values, [1, 2]);
        assert_eq!(big.palette, img.palette);
    }

    #[test]
    fn sixteen_bit_and_rgb_masks_round_trip() {
        let grey16 = LabelImage {
            width: 2,
            height: 2,
            color: png::ColorType::Grayscale,
            bits: 16,
            data: vec![0, 1, 1, 0, 255, 255, 0x12, 0x34],
            palette: None,
            trns: None,
        };
        assert_eq!(
            LabelImage::decode(&grey16.encode().unwrap(), &limits()).unwrap(),
            grey16
        );
        let fit = Fit::new(
            (2, 2),
            Size::Fixed {
                width: 16,
                height: 16,
            },
        );
        let big = grey16.fitted(&fit);
        assert_eq!(&big.data[..4], &[0, 1, 0, 1]);
        let rgb = LabelImage {
            width: 1,
            height: 2,
            color: png::ColorType::Rgb,
            bits: 8,
            data: vec![10, 20, 30, 40, 50, 60],
            palette: None,
            trns: None,
        };
        assert_eq!(
            LabelImage::decode(&rgb.encode().unwrap(), &limits()).unwrap(),
            rgb
        );
    }

    #[test]
    fn one_bit_masks_are_read_with_their_values() {
        // A 1-bit grey PNG, 3x1, pixels 1,0,1, written by the png crate.
        let mut bytes = Vec::new();
        let mut enc = png::Encoder::new(&mut bytes, 3, 1);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::One);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&[0b1010_0000]).unwrap();
        w.finish().unwrap();
        let img = LabelImage::decode(&bytes, &limits()).unwrap();
        assert_eq!((img.bits, img.data.as_slice()), (8, &[1u8, 0, 1][..]));
    }

    #[test]
    fn other_formats_and_oversized_masks_are_refused() {
        let err = LabelImage::decode(b"GIF89a....", &limits()).unwrap_err();
        assert!(err.contains("not a PNG"), "{err}");
        let img = LabelImage {
            width: 8,
            height: 8,
            color: png::ColorType::Grayscale,
            bits: 8,
            data: vec![0; 64],
            palette: None,
            trns: None,
        };
        let small = DecodeLimits {
            max_pixels: 16,
            max_dimension: 100,
        };
        let err = LabelImage::decode(&img.encode().unwrap(), &small).unwrap_err();
        assert!(err.contains("8x8"), "{err}");
    }
}
