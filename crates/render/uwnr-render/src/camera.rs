//! The camera stage: what a real underwater photo went through after the water and a render did
//! not, the lens's blur, the sensor's noise and the camera's JPEG. `uwnr dataset` applies it to
//! the underwater side of every pair, whatever the method, so that methods are compared on equal
//! terms; the clean side stays clean. It is recorded in `dataset.json` and a resume with another
//! camera is refused.
//!
//! The stage, in order, on the render quantised to 8 bits:
//! 1. a Gaussian point spread of `blur` pixels at a 256 px shorter side (scaled with the image,
//!    so a photo looks the same at any size);
//! 2. sensor noise: normal, with standard deviation `sqrt(read_noise^2 + shot_noise^2 v)` in
//!    8-bit levels at intensity `v` in [0, 1] (read noise, and shot noise growing with the
//!    light), drawn from the pair's seed;
//! 3. JPEG at `jpeg_quality` (the `image` crate's encoder, 4:2:0), decoded back.
//!
//! `clean` sets what the camera does to the clean side: nothing (`none`, the clean side stays
//! clean), the lens blur alone (`lens`), or the whole stage with the underwater side's noise
//! draws (`camera`). A real pair's clean side is made from the photo the camera took, so it keeps
//! the lens's point spread, the sensor's noise and the codec's blocks (measured by
//! `tools/pair_detail.py`: the finest detail band of real pairs' underwater sides is 0.99-1.05
//! times their clean sides', that of pairs with a clean clean side 0.62 with the typical camera
//! and 0.90 with the matched one, and real clean sides are as noisy as their underwater sides or
//! more).
//!
//! The default is [`Camera::MATCHED`]: the settings, of six tried, whose renders have the fine
//! detail and the noise of real underwater photos at the same size (half A of the realism
//! protocol, `docs/RESULTS.md`: finest band over middle band 0.721 against the photos' 0.722,
//! noise 1.29 levels against 1.30). [`Camera::TYPICAL`], the default before it, blurs renders
//! well past real photos (0.485) and teaches an enhancer trained on the pairs to sharpen what real
//! test pairs do not ask for. [`Camera::NONE`] leaves renders as the method made them.

use std::borrow::Cow;
use std::io::Cursor;

use image::ImageEncoder;
use image::codecs::jpeg::JpegEncoder;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use uwnr_core::Image;

use crate::error::{RenderError, Result};

/// Side, in pixels, that `blur` refers to.
const UNIT_SIDE: f32 = 256.0;
/// Mixed into a pair's seed for the camera's noise (a stream of its own).
const CAMERA_STREAM: u64 = 0xCA3E_7A57;

/// The camera stage's settings (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Camera {
    /// Sigma of the lens's Gaussian point spread, pixels at a 256 px shorter side; 0: none.
    pub blur: f32,
    /// Read noise, standard deviation in 8-bit levels.
    pub read_noise: f32,
    /// Shot noise, standard deviation in 8-bit levels at full intensity (it grows with the
    /// square root of the light).
    pub shot_noise: f32,
    /// JPEG quality, 1 to 100; 0: no JPEG.
    pub jpeg_quality: u8,
    /// What the camera does to the clean side ([`Camera::clean_side`]); `none` when a record
    /// lacks it (datasets made before the field existed had clean clean sides).
    #[serde(default, skip_serializing_if = "CleanCamera::is_none")]
    pub clean: CleanCamera,
}

/// What the camera stage does to a pair's clean side ([`Camera::clean_side`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CleanCamera {
    /// Nothing: the clean side stays clean.
    #[default]
    None,
    /// The lens blur alone.
    Lens,
    /// The whole stage, with the underwater side's noise draws (one photo's sensor noise,
    /// as a real pair's two sides share it).
    Camera,
}

impl CleanCamera {
    /// Whether the clean side is left alone.
    #[must_use]
    pub fn is_none(&self) -> bool {
        *self == Self::None
    }
}

impl Default for Camera {
    fn default() -> Self {
        Self::MATCHED
    }
}

impl Camera {
    /// No camera: renders as the method made them.
    pub const NONE: Self = Self {
        blur: 0.0,
        read_noise: 0.0,
        shot_noise: 0.0,
        jpeg_quality: 0,
        clean: CleanCamera::None,
    };

    /// A camera matched to real underwater photos' detail at a 256 px side (module doc): a 0.4 px
    /// blur, 1.5 levels of read noise and 3 of shot noise at full light, JPEG at quality 80.
    pub const MATCHED: Self = Self {
        blur: 0.4,
        read_noise: 1.5,
        shot_noise: 3.0,
        jpeg_quality: 80,
        clean: CleanCamera::None,
    };

    /// A compact underwater camera, the default until `matched`: a 0.8 px blur, 2 levels of read
    /// noise and 4 of shot noise at full light (about 3.5 levels at mid-grey), JPEG at quality 70.
    pub const TYPICAL: Self = Self {
        blur: 0.8,
        read_noise: 2.0,
        shot_noise: 4.0,
        jpeg_quality: 70,
        clean: CleanCamera::None,
    };

    /// Whether the stage changes nothing.
    #[must_use]
    pub fn is_none(&self) -> bool {
        self.blur == 0.0
            && self.read_noise == 0.0
            && self.shot_noise == 0.0
            && self.jpeg_quality == 0
    }

    /// Reads `none`, `matched`, `typical`, or a JSON object of the fields (missing ones take the
    /// default camera's, `matched`'s, values).
    pub fn parse(text: &str) -> Result<Self> {
        let camera = match text.trim() {
            "none" => Self::NONE,
            "matched" => Self::MATCHED,
            "typical" => Self::TYPICAL,
            json => serde_json::from_str(json).map_err(|e| {
                RenderError::Invalid(format!(
                    "camera {json:?}: expected none, matched, typical or a JSON object of blur, \
                     read_noise, shot_noise, jpeg_quality and clean ({e})"
                ))
            })?,
        };
        camera.validate()?;
        Ok(camera)
    }

    /// Checks the numbers: blur within [0, 10] px, noise within [0, 64] levels, quality 0..=100.
    pub fn validate(&self) -> Result<()> {
        let ok = |v: f32, max: f32| v.is_finite() && (0.0..=max).contains(&v);
        if !ok(self.blur, 10.0) {
            return Err(RenderError::Invalid(format!(
                "camera blur {} must be within [0, 10] px",
                self.blur
            )));
        }
        for (name, v) in [
            ("read_noise", self.read_noise),
            ("shot_noise", self.shot_noise),
        ] {
            if !ok(v, 64.0) {
                return Err(RenderError::Invalid(format!(
                    "camera {name} {v} must be within [0, 64] levels"
                )));
            }
        }
        if self.jpeg_quality > 100 {
            return Err(RenderError::Invalid(format!(
                "camera jpeg_quality {} must be within 0 (none) and 100",
                self.jpeg_quality
            )));
        }
        Ok(())
    }

    /// `img` (RGB in [0, 1]) through the camera, with noise drawn from `seed`; the output is on
    /// 8-bit levels.
    pub fn apply(&self, img: &Image, seed: u64) -> Result<Image> {
        self.apply_in_frame(img, seed, img.width().min(img.height()) as f32)
    }

    /// [`Self::apply`] on a crop of a larger frame: the lens blur sized for a frame whose
    /// shorter side is `frame` px (`apply` takes the image's own).
    pub fn apply_in_frame(&self, img: &Image, seed: u64, frame: f32) -> Result<Image> {
        let (w, h) = img.size();
        let mut out = self.blur_in_frame(img, frame)?;
        if self.read_noise > 0.0 || self.shot_noise > 0.0 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ CAMERA_STREAM);
            let (read2, shot2) = (self.read_noise.powi(2), self.shot_noise.powi(2));
            for v in out.data_mut() {
                let std = (read2 + shot2 * v.clamp(0.0, 1.0)).sqrt() / 255.0;
                *v += std * uwnr_model::effects::normal(&mut rng);
            }
        }
        out.clamp01();
        if self.jpeg_quality == 0 {
            return Ok(out.quantised());
        }
        let codes = interleaved_u8(&out);
        let mut bytes = Vec::new();
        JpegEncoder::new_with_quality(Cursor::new(&mut bytes), self.jpeg_quality)
            .write_image(&codes, w as u32, h as u32, image::ExtendedColorType::Rgb8)
            .map_err(|e| RenderError::Invalid(format!("camera JPEG: {e}")))?;
        let decoded = image::load_from_memory_with_format(&bytes, image::ImageFormat::Jpeg)
            .map_err(|e| RenderError::Invalid(format!("camera JPEG: {e}")))?
            .into_rgb8();
        let data: Vec<f32> = decoded
            .as_raw()
            .iter()
            .map(|&b| f32::from(b) / 255.0)
            .collect();
        Image::from_interleaved(w, h, 3, &data).map_err(|e| RenderError::Invalid(e.to_string()))
    }

    /// Whether [`Self::clean_side`] changes the clean side.
    #[must_use]
    pub fn touches_clean(&self) -> bool {
        match self.clean {
            CleanCamera::None => false,
            CleanCamera::Lens => self.blur > 0.0,
            CleanCamera::Camera => !self.is_none(),
        }
    }

    /// Step 1 alone: `img` (RGB) through the lens blur for a frame whose shorter side is
    /// `frame` px, after checking the settings and the image.
    fn blur_in_frame(&self, img: &Image, frame: f32) -> Result<Image> {
        self.validate()?;
        if !(frame.is_finite() && frame > 0.0) {
            return Err(RenderError::Invalid(format!(
                "camera frame side {frame} must be finite and > 0"
            )));
        }
        if img.channels() != 3 {
            return Err(RenderError::Invalid(format!(
                "the camera stage takes RGB images, got {} channel(s)",
                img.channels()
            )));
        }
        let (w, h) = img.size();
        let mut out = img.clone();
        if self.blur > 0.0 {
            let sigma = f64::from(self.blur * frame / UNIT_SIDE);
            for c in 0..3 {
                uwnr_model::blur::blur_plane(out.plane_mut(c), w, h, sigma);
            }
        }
        Ok(out)
    }

    /// The clean side of a pair through this camera, `seed` the one its underwater side was
    /// given ([`Self::apply`]): unchanged, through the lens blur alone (not quantised: the clean
    /// side is stored as any clean side is), or through the whole stage with the same noise draws.
    pub fn clean_side<'a>(&self, img: &'a Image, seed: u64) -> Result<Cow<'a, Image>> {
        if !self.touches_clean() {
            return Ok(Cow::Borrowed(img));
        }
        let frame = img.width().min(img.height()) as f32;
        match self.clean {
            CleanCamera::None => Ok(Cow::Borrowed(img)),
            CleanCamera::Lens => self.blur_in_frame(img, frame).map(Cow::Owned),
            CleanCamera::Camera => self.apply(img, seed).map(Cow::Owned),
        }
    }

    /// A pair's camera seed from its render seed.
    #[must_use]
    pub fn seed(render_seed: u64) -> u64 {
        uwnr_core::seed::mix(render_seed ^ CAMERA_STREAM)
    }
}

fn interleaved_u8(img: &Image) -> Vec<u8> {
    img.to_interleaved()
        .iter()
        .map(|&v| uwnr_core::image::quantise_u8(v))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: usize, h: usize) -> Image {
        let mut img = Image::filled(w, h, 3, 0.0);
        for c in 0..3 {
            for (i, v) in img.plane_mut(c).iter_mut().enumerate() {
                *v = ((i % w) as f32 / w as f32 + 0.1 * c as f32).min(1.0);
            }
        }
        img
    }

    #[test]
    fn a_crop_is_blurred_as_its_frame_is() {
        // `apply` sizes the lens blur by the image's own side; a 64 px crop of a 256 px frame
        // is blurred by the frame's sigma with `apply_in_frame(.., 256.0)`, 4x the crop's own.
        let cam = Camera {
            jpeg_quality: 0,
            read_noise: 0.0,
            shot_noise: 0.0,
            ..Camera::TYPICAL
        };
        let mut img = Image::filled(64, 64, 3, 0.2);
        for c in 0..3 {
            for (i, v) in img.plane_mut(c).iter_mut().enumerate() {
                if i % 64 >= 32 {
                    *v = 0.8;
                }
            }
        }
        let own = cam.apply(&img, 1).unwrap();
        assert_eq!(
            own.data(),
            cam.apply_in_frame(&img, 1, 64.0).unwrap().data()
        );
        let framed = cam.apply_in_frame(&img, 1, 256.0).unwrap();
        // The first bright pixel: nearly the bright side under the crop's own 0.2 px sigma,
        // pulled towards the edge's middle under the frame's 0.8 px.
        let (a, b) = (own.plane(0)[32], framed.plane(0)[32]);
        assert!(a > 0.78 && b < 0.7, "{a} {b}");
        assert!(cam.apply_in_frame(&img, 1, 0.0).is_err());
    }

    #[test]
    fn none_only_quantises_and_typical_is_seeded() {
        let img = gradient(64, 48);
        assert_eq!(Camera::NONE.apply(&img, 3).unwrap(), img.quantised());
        let a = Camera::TYPICAL.apply(&img, 3).unwrap();
        assert_eq!(a, Camera::TYPICAL.apply(&img, 3).unwrap());
        assert_ne!(a, Camera::TYPICAL.apply(&img, 4).unwrap());
        assert_eq!(a.size(), img.size());
        // Noise and compression move the image, but only by a few levels on average.
        let mean_abs = a
            .data()
            .iter()
            .zip(img.data())
            .map(|(x, y)| (x - y).abs())
            .sum::<f32>()
            / a.data().len() as f32;
        assert!(
            mean_abs > 0.5 / 255.0 && mean_abs < 8.0 / 255.0,
            "{}",
            mean_abs * 255.0
        );
    }

    #[test]
    fn the_clean_side_gets_nothing_the_lens_or_the_camera_and_old_records_read_as_none() {
        let img = gradient(64, 48);
        let with = |clean| Camera {
            clean,
            ..Camera::TYPICAL
        };
        // None: untouched.
        let none = with(CleanCamera::None);
        assert!(matches!(
            none.clean_side(&img, 5).unwrap(),
            Cow::Borrowed(_)
        ));
        // The lens: the underwater side's point spread, with no noise and no JPEG.
        let lens = with(CleanCamera::Lens).clean_side(&img, 5).unwrap();
        let lens_only = Camera {
            blur: Camera::TYPICAL.blur,
            ..Camera::NONE
        };
        let blurred = lens_only.apply(&img, 9).unwrap();
        let worst = lens
            .data()
            .iter()
            .zip(blurred.data())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst <= 0.5 / 255.0 + 1e-6, "{worst}");
        assert_ne!(lens.data(), img.data());
        // Nothing to blur with: the lens leaves it.
        let no_lens = Camera {
            blur: 0.0,
            ..with(CleanCamera::Lens)
        };
        assert!(matches!(
            no_lens.clean_side(&img, 5).unwrap(),
            Cow::Borrowed(_)
        ));
        // The camera: the whole stage with the underwater side's draws, so the clean side of
        // an image is what the underwater side of the same image would be.
        let full = with(CleanCamera::Camera);
        assert_eq!(
            full.clean_side(&img, 5).unwrap().into_owned(),
            full.apply(&img, 5).unwrap()
        );
        // A record without the field (datasets made before it) reads as none, and none is not
        // written, so those records stay as they were.
        let old = r#"{"blur":0.8,"read_noise":2.0,"shot_noise":4.0,"jpeg_quality":70}"#;
        let read = serde_json::from_str::<Camera>(old).unwrap();
        assert_eq!(read.clean, CleanCamera::None);
        assert_eq!(serde_json::to_string(&none).unwrap(), old);
        let written = serde_json::to_string(&full).unwrap();
        assert!(written.contains(r#""clean":"camera""#), "{written}");
        assert_eq!(
            Camera::parse(r#"{"clean": "lens"}"#).unwrap().clean,
            CleanCamera::Lens
        );
        assert!(Camera::parse(r#"{"clean": "sharp"}"#).is_err());
    }

    #[test]
    fn the_matched_camera_keeps_more_fine_detail_than_the_typical_one() {
        // A 256 px frame of 2 px stripes, 0.4 apart: far above either camera's noise.
        let mut img = Image::filled(256, 256, 3, 0.0);
        for c in 0..3 {
            for (i, v) in img.plane_mut(c).iter_mut().enumerate() {
                *v = if (i % 256) / 2 % 2 == 0 { 0.3 } else { 0.7 };
            }
        }
        let detail = |cam: Camera| {
            let out = cam.apply(&img, 7).unwrap();
            let p = out.plane(1);
            p.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f32>() / p.len() as f32
        };
        let (none, matched, typical) = (
            detail(Camera::NONE),
            detail(Camera::MATCHED),
            detail(Camera::TYPICAL),
        );
        assert!(
            none > matched && matched > 1.5 * typical,
            "{none} {matched} {typical}"
        );
    }

    #[test]
    fn parse_reads_names_and_json_and_refuses_nonsense() {
        assert_eq!(Camera::parse("none").unwrap(), Camera::NONE);
        assert_eq!(Camera::parse("typical").unwrap(), Camera::TYPICAL);
        assert_eq!(Camera::parse(" matched ").unwrap(), Camera::MATCHED);
        assert_eq!(Camera::default(), Camera::MATCHED);
        let c = Camera::parse(r#"{"jpeg_quality": 90}"#).unwrap();
        assert_eq!((c.jpeg_quality, c.blur), (90, Camera::MATCHED.blur));
        for bad in [
            r#"{"jpeg_quality": 101}"#,
            r#"{"blur": -1}"#,
            r#"{"iso": 100}"#,
            "nikon",
        ] {
            assert!(Camera::parse(bad).is_err(), "{bad}");
        }
    }
}
