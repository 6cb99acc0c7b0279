//! Pixels across the boundary: contiguous interleaved bytes with their shape, as 8-bit codes
//! (read as `code / 255`, as the image decoder does) or native-endian f32 in [0, 1], decoded into
//! uwnr's planar f32 [`Image`] and encoded back.

use pyo3::prelude::*;
use pyo3::types::PyBytes;
use uwnr_core::Image;

use crate::Failure;

/// Channels of an RGB image.
pub(crate) const RGB: usize = 3;
/// Bytes of one f32 sample.
const F32_BYTES: usize = 4;

/// The sample type of pixel bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Dtype {
    /// 8-bit codes, `code / 255`.
    U8,
    /// Native-endian f32 in [0, 1].
    F32,
}

impl Dtype {
    pub(crate) fn parse(name: &str) -> Result<Self, Failure> {
        match name {
            "uint8" => Ok(Self::U8),
            "float32" => Ok(Self::F32),
            other => Err(Failure::Value(format!(
                "pixel dtype {other:?} is not supported (uint8 or float32)"
            ))),
        }
    }
}

/// Pixels as the Python half passes them: `(bytes, height, width, channels, dtype)`.
#[derive(FromPyObject)]
pub(crate) struct Pixels<'py>(Bound<'py, PyBytes>, usize, usize, usize, String);

impl Pixels<'_> {
    /// The same pixels, borrowed for use without the GIL.
    pub(crate) fn view(&self) -> Result<PixelView<'_>, Failure> {
        Ok(PixelView {
            data: self.0.as_bytes(),
            height: self.1,
            width: self.2,
            channels: self.3,
            dtype: Dtype::parse(&self.4)?,
        })
    }
}

/// Pixel bytes with their shape, borrowed.
pub(crate) struct PixelView<'a> {
    pub(crate) data: &'a [u8],
    pub(crate) height: usize,
    pub(crate) width: usize,
    pub(crate) channels: usize,
    pub(crate) dtype: Dtype,
}

impl PixelView<'_> {
    /// Decodes the bytes into a planar f32 image in [0, 1].
    pub(crate) fn image(&self) -> Result<Image, Failure> {
        let (h, w, c) = (self.height, self.width, self.channels);
        if h == 0 || w == 0 {
            return Err(Failure::Value(format!("image is empty ({h}x{w})")));
        }
        let n = h
            .checked_mul(w)
            .and_then(|p| p.checked_mul(c))
            .ok_or_else(|| Failure::Value(format!("image shape {h}x{w}x{c} is too large")))?;
        let values: Vec<f32> = match self.dtype {
            Dtype::U8 => {
                check_len(self.data.len(), n, h, w, c)?;
                self.data
                    .iter()
                    .map(|&v| f32::from(v) / f32::from(u8::MAX))
                    .collect()
            }
            Dtype::F32 => {
                check_len(self.data.len(), n * F32_BYTES, h, w, c)?;
                self.data
                    .chunks_exact(F32_BYTES)
                    .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
                    .collect()
            }
        };
        Image::from_interleaved(w, h, c, &values).map_err(crate::value)
    }

    /// [`PixelView::image`] of a 3-channel image.
    pub(crate) fn rgb(&self) -> Result<Image, Failure> {
        if self.channels != RGB {
            return Err(Failure::Value(format!(
                "expected {RGB} channels, got {}",
                self.channels
            )));
        }
        self.image()
    }
}

fn check_len(got: usize, expected: usize, h: usize, w: usize, c: usize) -> Result<(), Failure> {
    if got == expected {
        Ok(())
    } else {
        Err(Failure::Value(format!(
            "pixel buffer has {got} bytes, {expected} expected for shape {h}x{w}x{c}"
        )))
    }
}

/// Interleaved bytes of `img` in `dtype` (8-bit with the encoder's rounding, so a uint8 result
/// equals the PNG `uwnr render` writes).
pub(crate) fn encode(img: &Image, dtype: Dtype) -> Vec<u8> {
    match dtype {
        Dtype::U8 => uwnr_core::io::to_rgb8(img),
        Dtype::F32 => img
            .to_interleaved()
            .iter()
            .flat_map(|v| v.to_ne_bytes())
            .collect(),
    }
}

/// [`encode`] as a Python `bytes`.
pub(crate) fn image_bytes<'py>(py: Python<'py>, img: &Image, dtype: Dtype) -> Bound<'py, PyBytes> {
    PyBytes::new(py, &encode(img, dtype))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(data: &[u8], h: usize, w: usize, c: usize, dtype: Dtype) -> PixelView<'_> {
        PixelView {
            data,
            height: h,
            width: w,
            channels: c,
            dtype,
        }
    }

    fn message(f: Failure) -> String {
        match f {
            Failure::Value(m) => m,
            Failure::Model(m) => panic!("a value error was expected, got {m}"),
        }
    }

    #[test]
    fn eight_bit_codes_read_as_code_over_255_and_interleaved_becomes_planar() {
        // 1x2 RGB: (0, 51, 255), (255, 102, 0).
        let img = view(&[0, 51, 255, 255, 102, 0], 1, 2, 3, Dtype::U8)
            .rgb()
            .unwrap();
        assert_eq!(img.size(), (2, 1));
        assert_eq!(img.plane(0), &[0.0, 1.0]);
        assert_eq!(img.plane(1), &[0.2, 0.4]);
        assert_eq!(img.plane(2), &[1.0, 0.0]);
        assert_eq!(encode(&img, Dtype::U8), vec![0, 51, 255, 255, 102, 0]);
    }

    #[test]
    fn f32_bytes_round_trip_exactly() {
        let values = [0.0f32, 0.25, 1.0, 0.125, 0.5, 0.75];
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_ne_bytes()).collect();
        let img = view(&bytes, 2, 1, 3, Dtype::F32).image().unwrap();
        assert_eq!(img.plane(1), &[0.25, 0.5]);
        assert_eq!(encode(&img, Dtype::F32), bytes);
    }

    #[test]
    fn wrong_lengths_shapes_and_dtypes_are_value_errors() {
        let e = message(view(&[0; 5], 1, 2, 3, Dtype::U8).image().unwrap_err());
        assert!(e.contains("5 bytes, 6 expected"), "{e}");
        let e = message(view(&[0; 6], 1, 2, 3, Dtype::F32).image().unwrap_err());
        assert!(e.contains("24 expected"), "{e}");
        let e = message(view(&[], 0, 2, 3, Dtype::U8).image().unwrap_err());
        assert!(e.contains("empty"), "{e}");
        let e = message(view(&[0; 8], 2, 2, 2, Dtype::U8).rgb().unwrap_err());
        assert!(e.contains("expected 3 channels, got 2"), "{e}");
        let e = message(view(&[], usize::MAX, 2, 3, Dtype::U8).image().unwrap_err());
        assert!(e.contains("too large"), "{e}");
        assert!(Dtype::parse("float64").is_err());
        assert_eq!(Dtype::parse("uint8").unwrap(), Dtype::U8);
    }

    #[test]
    fn eight_bit_encoding_rounds_as_the_png_encoder() {
        let img = Image::from_interleaved(1, 1, 3, &[0.5, 0.001, 0.999]).unwrap();
        assert_eq!(encode(&img, Dtype::U8), uwnr_core::io::to_rgb8(&img));
        assert_eq!(encode(&img, Dtype::U8), vec![128, 0, 255]);
    }
}
