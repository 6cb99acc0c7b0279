//! Detail retention: how much of an image's contrast is fine detail ([`detail_share`]), and the
//! anchor's detail brought to the reference's share ([`retain_detail`]), so that a render is as
//! sharp or as soft as the water it imitates.

use uwnr_core::Image;
use uwnr_core::resize::{fit_within, resize_bilinear};

use super::mean_std;
use crate::blur::blur_plane;
use crate::error::Result;

/// Longest side at which detail retention measures and separates detail, pixels: images are
/// shrunk to it (never enlarged), so a reference and a photo of other sizes are compared at
/// one scale. (A prototype of the step on a plain lαβ transfer, `uieb-val` at 1280x720: SSIM
/// 0.9386 measured at 512 px, 0.9387 at full size, 0.9384 at 256 px, 0.9314 without the step.)
pub const DETAIL_SIDE: usize = 512;
/// Blur that splits an image into its coarse part and its detail (detail retention), pixels
/// at the [`DETAIL_SIDE`] scale.
pub const DETAIL_SIGMA: f64 = 5.0;
/// Side of the square window of the local standard deviation detail retention compares
/// (SSIM's window).
pub const DETAIL_WINDOW: usize = 7;
/// Smallest and largest per-channel detail gain of detail retention.
pub const DETAIL_GAIN: (f32, f32) = (0.5, 2.0);
/// A channel whose overall standard deviation is below this is flat: its detail is left alone.
pub const DETAIL_FLAT_STD: f64 = 1e-3;

/// Per channel, the mean standard deviation over the [`DETAIL_WINDOW`]-pixel windows that fit
/// in the image, divided by the channel's overall standard deviation: how much of its contrast
/// is fine detail. Measured on the image shrunk to [`DETAIL_SIDE`] (never enlarged), so that
/// images of different sizes are measured at comparable scales. `NaN` for a flat channel (below
/// [`DETAIL_FLAT_STD`]) or an image smaller than a window; [`retain_detail`] leaves such a
/// channel alone.
#[must_use]
pub fn detail_share(img: &Image) -> [f32; 3] {
    detail_share_with(img, 0.0)
}

/// [`detail_share`] with each window's variance reduced by `noise_floor²` (at least 0): windows
/// whose variation is at the level of sensor or quantisation noise count as flat, so that
/// `±1` code value of noise on a dark, flat photo cannot swing its share (and with it the
/// detail gain of every edge in it). The water anchor measures with [`DETAIL_NOISE_FLOOR`].
#[must_use]
pub fn detail_share_with(img: &Image, noise_floor: f64) -> [f32; 3] {
    match fit_within(img, DETAIL_SIDE) {
        Ok(small) => share_as_is(&small, noise_floor),
        Err(_) => [f32::NAN; 3],
    }
}

/// The noise floor of the water anchor's detail retention ([`detail_share_with`]), RGB in
/// [0, 1]: two 8-bit code values. Without it, `±1` of noise moved a render of a dark dusk photo
/// by up to 21 code values at the edges of its bright parts; with it, by at most one.
pub const DETAIL_NOISE_FLOOR: f64 = 2.0 / 255.0;

/// [`detail_share_with`] of `img` at its own size.
fn share_as_is(img: &Image, noise_floor: f64) -> [f32; 3] {
    let (w, h) = img.size();
    let k = DETAIL_WINDOW;
    std::array::from_fn(|c| {
        if w < k || h < k {
            return f32::NAN;
        }
        let p = img.plane(c);
        // Summed-area tables of x and x^2, (w + 1) x (h + 1).
        let stride = w + 1;
        let mut s1 = vec![0.0f64; stride * (h + 1)];
        let mut s2 = vec![0.0f64; stride * (h + 1)];
        for y in 0..h {
            let (mut r1, mut r2) = (0.0f64, 0.0f64);
            for x in 0..w {
                let v = f64::from(p[y * w + x]);
                r1 += v;
                r2 += v * v;
                s1[(y + 1) * stride + x + 1] = s1[y * stride + x + 1] + r1;
                s2[(y + 1) * stride + x + 1] = s2[y * stride + x + 1] + r2;
            }
        }
        let n = (w * h) as f64;
        let (t1, t2) = (s1[h * stride + w], s2[h * stride + w]);
        let global = (t2 / n - (t1 / n).powi(2)).max(0.0).sqrt();
        if global < DETAIL_FLAT_STD {
            return f32::NAN;
        }
        let box_sum = |s: &[f64], x: usize, y: usize| {
            s[(y + k) * stride + x + k] - s[y * stride + x + k] - s[(y + k) * stride + x]
                + s[y * stride + x]
        };
        let kk = (k * k) as f64;
        let floor2 = noise_floor * noise_floor;
        let mut local = 0.0f64;
        for y in 0..=h - k {
            for x in 0..=w - k {
                let m = box_sum(&s1, x, y) / kk;
                local += (box_sum(&s2, x, y) / kk - m * m - floor2).max(0.0).sqrt();
            }
        }
        let windows = ((w - k + 1) * (h - k + 1)) as f64;
        (local / windows / global) as f32
    })
}

/// Detail retention: each channel of `anchor` split into its coarse part (a blur of
/// [`DETAIL_SIGMA`] at the [`DETAIL_SIDE`] scale, brought back to the anchor's size) and its
/// detail, the detail scaled by the ratio of the reference's share of detail (`reference`, from
/// [`detail_share`]) to the anchor's, clamped to [`DETAIL_GAIN`], then the channel scaled about
/// its mean back to its overall standard deviation: the colour transfer's statistics stay, only
/// the split of contrast between coarse and fine changes. A channel flat in either image is
/// left alone. `anchor` is taken and changed in place; a large photo holds one extra
/// plane at a time.
pub fn retain_detail(anchor: Image, reference: [f32; 3]) -> Result<Image> {
    retain_detail_with(anchor, reference, 0.0)
}

/// [`retain_detail`] with the anchor's share measured above `noise_floor`
/// ([`detail_share_with`]); `reference` must have been measured with the same floor.
pub fn retain_detail_with(anchor: Image, reference: [f32; 3], noise_floor: f64) -> Result<Image> {
    let (w, h) = anchor.size();
    let small = fit_within(&anchor, DETAIL_SIDE)?;
    let own = share_as_is(&small, noise_floor);
    let (sw, sh) = small.size();
    let mut out = anchor;
    for c in 0..3 {
        let gain = reference[c] / own[c];
        if !gain.is_finite() {
            continue;
        }
        let gain = gain.clamp(DETAIL_GAIN.0, DETAIL_GAIN.1);
        let mut coarse = small.plane(c).to_vec();
        blur_plane(&mut coarse, sw, sh, DETAIL_SIGMA);
        let coarse = Image::from_planar(sw, sh, 1, coarse)?;
        let coarse = resize_bilinear(&coarse, w, h)?;
        let plane = out.plane_mut(c);
        let (mean, spread) = mean_std(plane);
        for (v, &lo) in plane.iter_mut().zip(coarse.plane(0)) {
            *v = lo + gain * (*v - lo);
        }
        // The overall spread stays the transfer's: only its split between coarse and fine
        // changes (the shares are ratios, so this keeps the reference's).
        let (new_mean, new_spread) = mean_std(plane);
        let scale = if new_spread > 0.0 {
            spread / new_spread
        } else {
            1.0
        };
        for v in plane.iter_mut() {
            *v = ((f64::from(*v) - new_mean) * scale + mean).clamp(0.0, 1.0) as f32;
        }
    }
    Ok(out)
}
