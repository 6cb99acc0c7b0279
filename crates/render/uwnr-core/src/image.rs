//! `Image`: a planar (CHW) f32 image with values nominally in [0, 1].
//!
//! Everything inside uwnr works on this type: decoding happens once at the edge
//! (`io`), and nothing deeper sees file paths or u8 pixels.

use crate::error::{CoreError, Result};

/// The largest 8-bit code, as the scale between codes and [0, 1] values.
const U8_CODE_MAX: f32 = 255.0;

/// The 8-bit code of a value in [0, 1]: `(v * 255 + 0.5).clamp(0, 255) as u8`, rounding half up
/// and clamping, as torchvision's `save_image` does. Every 8-bit file uwnr writes holds these
/// codes (NaN gives 0).
///
/// Not the rule of every reference port: UIQM quantises with `round_ties_even` in f64 and the
/// light-field map truncates (`np.uint8`), each as the code it reproduces.
#[must_use]
#[inline]
pub fn quantise_u8(v: f32) -> u8 {
    (v * U8_CODE_MAX + 0.5).clamp(0.0, U8_CODE_MAX) as u8
}

/// A planar f32 image: `channels` planes of `height x width`, row-major, values in [0, 1]
/// (RGB images have 3 channels in R, G, B order; grey maps have 1).
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    width: usize,
    height: usize,
    channels: usize,
    data: Vec<f32>,
}

/// A borrowed single channel of an [`Image`].
pub type Plane<'a> = &'a [f32];

impl Image {
    /// A new image filled with `value`.
    #[must_use]
    pub fn filled(width: usize, height: usize, channels: usize, value: f32) -> Self {
        Self {
            width,
            height,
            channels,
            data: vec![value; width * height * channels],
        }
    }

    /// Wraps planar CHW data. Fails when `data.len() != channels * height * width`.
    pub fn from_planar(
        width: usize,
        height: usize,
        channels: usize,
        data: Vec<f32>,
    ) -> Result<Self> {
        if data.len() != width * height * channels {
            return Err(CoreError::ShapeMismatch {
                expected: (channels, height, width),
                got: (data.len(), 0, 0),
            });
        }
        Ok(Self {
            width,
            height,
            channels,
            data,
        })
    }

    /// Builds an image from interleaved HWC data (as decoders produce it).
    pub fn from_interleaved(
        width: usize,
        height: usize,
        channels: usize,
        hwc: &[f32],
    ) -> Result<Self> {
        if hwc.len() != width * height * channels {
            return Err(CoreError::ShapeMismatch {
                expected: (height, width, channels),
                got: (hwc.len(), 0, 0),
            });
        }
        let n = width * height;
        let mut data = vec![0.0; n * channels];
        for (i, px) in hwc.chunks_exact(channels).enumerate() {
            for (c, &v) in px.iter().enumerate() {
                data[c * n + i] = v;
            }
        }
        Ok(Self {
            width,
            height,
            channels,
            data,
        })
    }

    /// Interleaved HWC copy of the data.
    #[must_use]
    pub fn to_interleaved(&self) -> Vec<f32> {
        let n = self.width * self.height;
        let mut out = vec![0.0; n * self.channels];
        for c in 0..self.channels {
            for (i, &v) in self.plane(c).iter().enumerate() {
                out[i * self.channels + c] = v;
            }
        }
        out
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of channels (planes).
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// `(width, height)`.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// All planes, CHW.
    #[must_use]
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// All planes, CHW, mutable.
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }

    /// Consumes the image, returning its CHW data.
    #[must_use]
    pub fn into_data(self) -> Vec<f32> {
        self.data
    }

    /// Channel `c` as a row-major `height x width` slice. Panics if `c >= channels`.
    #[must_use]
    pub fn plane(&self, c: usize) -> &[f32] {
        let n = self.width * self.height;
        &self.data[c * n..(c + 1) * n]
    }

    /// Channel `c`, mutable. Panics if `c >= channels`.
    pub fn plane_mut(&mut self, c: usize) -> &mut [f32] {
        let n = self.width * self.height;
        &mut self.data[c * n..(c + 1) * n]
    }

    /// Pixel value at channel `c`, row `y`, column `x`.
    #[must_use]
    pub fn get(&self, c: usize, y: usize, x: usize) -> f32 {
        self.data[(c * self.height + y) * self.width + x]
    }

    /// A copy of the rectangle `[x0, x0+w) x [y0, y0+h)`. Fails when it leaves the image.
    pub fn crop(&self, x0: usize, y0: usize, w: usize, h: usize) -> Result<Self> {
        if x0 + w > self.width || y0 + h > self.height {
            return Err(CoreError::InvalidArgument(format!(
                "crop {w}x{h}+{x0}+{y0} leaves the {}x{} image",
                self.width, self.height
            )));
        }
        let mut data = Vec::with_capacity(w * h * self.channels);
        for c in 0..self.channels {
            let p = self.plane(c);
            for y in y0..y0 + h {
                data.extend_from_slice(&p[y * self.width + x0..y * self.width + x0 + w]);
            }
        }
        Ok(Self {
            width: w,
            height: h,
            channels: self.channels,
            data,
        })
    }

    /// The planar (CHW) 8-bit codes of the image, each value quantised by [`quantise_u8`].
    #[must_use]
    pub fn to_u8_codes(&self) -> Vec<u8> {
        self.data.iter().map(|&v| quantise_u8(v)).collect()
    }

    /// An image from planar (CHW) 8-bit codes, each read as `code / 255`. Fails when
    /// `codes.len() != channels * height * width`.
    pub fn from_u8_codes(
        width: usize,
        height: usize,
        channels: usize,
        codes: &[u8],
    ) -> Result<Self> {
        let data = codes.iter().map(|&v| f32::from(v) / U8_CODE_MAX).collect();
        Self::from_planar(width, height, channels, data)
    }

    /// The image rounded to the 8-bit grid, `quantise_u8(v) / 255` per value: what a saved
    /// 8-bit PNG holds once it is read back.
    #[must_use]
    pub fn quantised(&self) -> Self {
        Self {
            width: self.width,
            height: self.height,
            channels: self.channels,
            data: self
                .data
                .iter()
                .map(|&v| f32::from(quantise_u8(v)) / U8_CODE_MAX)
                .collect(),
        }
    }

    /// Clamps every value to [0, 1] in place.
    pub fn clamp01(&mut self) {
        for v in &mut self.data {
            *v = v.clamp(0.0, 1.0);
        }
    }

    /// Stacks the planes of several images of the same size into one image.
    pub fn concat_channels(images: &[&Image]) -> Result<Self> {
        let first = images
            .first()
            .ok_or_else(|| CoreError::InvalidArgument("concat of no images".into()))?;
        let (w, h) = first.size();
        let mut data = Vec::new();
        let mut channels = 0;
        for im in images {
            if im.size() != (w, h) {
                return Err(CoreError::ShapeMismatch {
                    expected: (im.channels, h, w),
                    got: (im.channels, im.height, im.width),
                });
            }
            data.extend_from_slice(&im.data);
            channels += im.channels;
        }
        Ok(Self {
            width: w,
            height: h,
            channels,
            data,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interleaved_round_trip() {
        let hwc: Vec<f32> = (0..2 * 3 * 3).map(|v| v as f32).collect();
        let im = Image::from_interleaved(3, 2, 3, &hwc).unwrap();
        assert_eq!(im.get(1, 0, 0), 1.0);
        assert_eq!(im.get(0, 1, 2), 15.0);
        assert_eq!(im.to_interleaved(), hwc);
    }

    #[test]
    fn quantise_u8_rounds_half_up_and_clamps() {
        // 0.1 * 255 = 25.5 rounds up; 0.5 * 255 = 127.5 rounds up.
        assert_eq!(quantise_u8(0.1), 26);
        assert_eq!(quantise_u8(0.5), 128);
        assert_eq!(quantise_u8(0.0), 0);
        assert_eq!(quantise_u8(1.0), 255);
        assert_eq!(quantise_u8(1.2), 255);
        assert_eq!(quantise_u8(-0.1), 0);
        assert_eq!(quantise_u8(f32::NAN), 0);
        for code in 0..=255_u8 {
            assert_eq!(quantise_u8(f32::from(code) / 255.0), code);
        }
    }

    #[test]
    fn u8_codes_round_trip() {
        let im = Image::from_planar(2, 1, 2, vec![0.1, 0.5, 1.2, -0.1]).unwrap();
        let codes = im.to_u8_codes();
        assert_eq!(codes, [26, 128, 255, 0]);
        let back = Image::from_u8_codes(2, 1, 2, &codes).unwrap();
        assert_eq!(back.data(), &[26.0 / 255.0, 128.0 / 255.0, 1.0, 0.0]);
        assert_eq!(back, im.quantised());
        // Quantising twice changes nothing.
        assert_eq!(back.quantised(), back);
        assert!(Image::from_u8_codes(2, 2, 2, &codes).is_err());
    }

    #[test]
    fn crop_takes_the_rectangle() {
        let data: Vec<f32> = (0..16).map(|v| v as f32).collect();
        let im = Image::from_planar(4, 4, 1, data).unwrap();
        let c = im.crop(1, 2, 2, 2).unwrap();
        assert_eq!(c.data(), &[9.0, 10.0, 13.0, 14.0]);
        assert!(im.crop(3, 3, 2, 1).is_err());
    }
}
