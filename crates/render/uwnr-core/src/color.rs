//! Colour conversions shared by the baselines and the metrics: sRGB <-> CIE XYZ <-> CIE L*a*b*
//! (D65, 2° observer) exactly as scikit-image's `rgb2lab` / `lab2rgb` compute them, and
//! Ruderman's l-alpha-beta space as used by Reinhard et al. 2001 colour transfer.

use crate::error::{CoreError, Result};
use crate::image::Image;

/// D65 reference white (2° observer) in XYZ, as scikit-image's `xyz_ref_white` defaults.
pub const D65_WHITE: [f64; 3] = [0.95047, 1.0, 1.08883];

/// sRGB (linear) -> XYZ matrix, scikit-image's `xyz_from_rgb`.
pub const XYZ_FROM_RGB: [[f64; 3]; 3] = [
    [0.412453, 0.357580, 0.180423],
    [0.212671, 0.715160, 0.072169],
    [0.019334, 0.119193, 0.950227],
];

/// Inverse of [`XYZ_FROM_RGB`] (scikit-image computes it with `linalg.inv`).
pub const RGB_FROM_XYZ: [[f64; 3]; 3] = [
    [3.2404813432005266, -1.5371515162713183, -0.4985363261688878],
    [-0.9692549499965682, 1.8759900014898907, 0.04155592655829284],
    [
        0.055646639135177166,
        -0.20404133836651123,
        1.0573110696453443,
    ],
];

/// CIE epsilon (216/24389 rounded as scikit-image uses it) and the linear-segment slope.
const LAB_EPS: f64 = 0.008856;
const LAB_KAPPA_SLOPE: f64 = 7.787;

/// sRGB gamma decoding (IEC 61966-2-1), value in [0,1].
#[must_use]
pub fn srgb_to_linear(v: f64) -> f64 {
    if v > 0.04045 {
        ((v + 0.055) / 1.055).powf(2.4)
    } else {
        v / 12.92
    }
}

/// sRGB gamma encoding, the inverse of [`srgb_to_linear`].
#[must_use]
pub fn linear_to_srgb(v: f64) -> f64 {
    if v > 0.0031308 {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    } else {
        12.92 * v
    }
}

fn mat3(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

/// One sRGB pixel (components in [0,1]) to L*a*b* (L in [0,100]), as `skimage.color.rgb2lab`.
#[must_use]
pub fn rgb_to_lab_px(rgb: [f64; 3]) -> [f64; 3] {
    let lin = [
        srgb_to_linear(rgb[0]),
        srgb_to_linear(rgb[1]),
        srgb_to_linear(rgb[2]),
    ];
    let xyz = mat3(&XYZ_FROM_RGB, lin);
    let f = |t: f64| {
        if t > LAB_EPS {
            t.cbrt()
        } else {
            LAB_KAPPA_SLOPE * t + 16.0 / 116.0
        }
    };
    let fx = f(xyz[0] / D65_WHITE[0]);
    let fy = f(xyz[1] / D65_WHITE[1]);
    let fz = f(xyz[2] / D65_WHITE[2]);
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// One L*a*b* pixel back to sRGB in [0,1] (clipped), as `skimage.color.lab2rgb`.
#[must_use]
pub fn lab_to_rgb_px(lab: [f64; 3]) -> [f64; 3] {
    let fy = (lab[0] + 16.0) / 116.0;
    let fx = lab[1] / 500.0 + fy;
    let fz = (fy - lab[2] / 200.0).max(0.0);
    let finv = |t: f64| {
        let t3 = t * t * t;
        if t3 > LAB_EPS {
            t3
        } else {
            (t - 16.0 / 116.0) / LAB_KAPPA_SLOPE
        }
    };
    let xyz = [
        finv(fx) * D65_WHITE[0],
        finv(fy) * D65_WHITE[1],
        finv(fz) * D65_WHITE[2],
    ];
    let lin = mat3(&RGB_FROM_XYZ, xyz);
    [
        linear_to_srgb(lin[0].max(0.0)).clamp(0.0, 1.0),
        linear_to_srgb(lin[1].max(0.0)).clamp(0.0, 1.0),
        linear_to_srgb(lin[2].max(0.0)).clamp(0.0, 1.0),
    ]
}

fn require_rgb(img: &Image) -> Result<()> {
    if img.channels() != 3 {
        return Err(CoreError::ShapeMismatch {
            expected: (3, img.height(), img.width()),
            got: (img.channels(), img.height(), img.width()),
        });
    }
    Ok(())
}

/// Applies a per-pixel 3 -> 3 map to an RGB image, returning f64 planes.
fn map_pixels(img: &Image, f: impl Fn([f64; 3]) -> [f64; 3]) -> [Vec<f64>; 3] {
    let (r, g, b) = (img.plane(0), img.plane(1), img.plane(2));
    let n = r.len();
    let mut out = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    for i in 0..n {
        let v = f([f64::from(r[i]), f64::from(g[i]), f64::from(b[i])]);
        out[0][i] = v[0];
        out[1][i] = v[1];
        out[2][i] = v[2];
    }
    out
}

/// sRGB image to L*a*b* planes (f64 for the metrics' precision), as `skimage.color.rgb2lab`.
pub fn rgb_to_lab(img: &Image) -> Result<[Vec<f64>; 3]> {
    require_rgb(img)?;
    Ok(map_pixels(img, rgb_to_lab_px))
}

/// L*a*b* planes back to an sRGB image of the given size, clipped to [0,1].
pub fn lab_to_rgb(lab: &[Vec<f64>; 3], width: usize, height: usize) -> Result<Image> {
    let n = width * height;
    if lab.iter().any(|p| p.len() != n) {
        return Err(CoreError::ShapeMismatch {
            expected: (3, height, width),
            got: (3, lab[0].len(), 1),
        });
    }
    let mut data = vec![0.0f32; 3 * n];
    for i in 0..n {
        let rgb = lab_to_rgb_px([lab[0][i], lab[1][i], lab[2][i]]);
        for c in 0..3 {
            data[c * n + i] = rgb[c] as f32;
        }
    }
    Image::from_planar(width, height, 3, data)
}

/// Ruderman et al.'s l-alpha-beta of one linear-RGB-free pixel, as Reinhard et al. 2001 define it:
/// RGB -> LMS (their matrix), log10, then the decorrelating rotation. `floor` keeps log10 finite.
#[must_use]
pub fn rgb_to_lalphabeta_px(rgb: [f64; 3], floor: f64) -> [f64; 3] {
    const LMS_FROM_RGB: [[f64; 3]; 3] = [
        [0.3811, 0.5783, 0.0402],
        [0.1967, 0.7244, 0.0782],
        [0.0241, 0.1288, 0.8444],
    ];
    let lms = mat3(&LMS_FROM_RGB, rgb);
    let l = lms.map(|v| v.max(floor).log10());
    let s3 = 3f64.sqrt();
    let s6 = 6f64.sqrt();
    let s2 = 2f64.sqrt();
    [
        (l[0] + l[1] + l[2]) / s3,
        (l[0] + l[1] - 2.0 * l[2]) / s6,
        (l[0] - l[1]) / s2,
    ]
}

/// Inverse of [`rgb_to_lalphabeta_px`] (RGB not clipped).
#[must_use]
pub fn lalphabeta_to_rgb_px(lab: [f64; 3]) -> [f64; 3] {
    // The exact inverse of LMS_FROM_RGB: the paper's printed 4-decimal inverse is off by up to
    // 0.7%, which would make a self-transfer change the image.
    const RGB_FROM_LMS: [[f64; 3]; 3] = [
        [4.468669863496255, -3.5886759034721267, 0.11960436657860116],
        [
            -1.2197166276177631,
            2.3830879129554567,
            -0.16263011175140055,
        ],
        [0.058508476938545856, -0.2610784390276937, 1.205665908525623],
    ];
    let s3 = 3f64.sqrt();
    let s6 = 6f64.sqrt();
    let s2 = 2f64.sqrt();
    let a = lab[0] / s3;
    let b = lab[1] / s6;
    let c = lab[2] / s2;
    let log_lms = [a + b + c, a + b - c, a - 2.0 * b];
    let lms = log_lms.map(|v| 10f64.powf(v));
    mat3(&RGB_FROM_LMS, lms)
}

/// HSV saturation of one pixel (max - min) / max, 0 for black; as OpenCV/skimage define it.
#[must_use]
pub fn saturation_px(rgb: [f64; 3]) -> f64 {
    let max = rgb[0].max(rgb[1]).max(rgb[2]);
    let min = rgb[0].min(rgb[1]).min(rgb[2]);
    if max <= 0.0 { 0.0 } else { (max - min) / max }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lab_of_white_black_and_red_match_skimage() {
        // Values from skimage.color.rgb2lab (0.26).
        let w = rgb_to_lab_px([1.0, 1.0, 1.0]);
        assert!(
            (w[0] - 100.0).abs() < 1e-3 && w[1].abs() < 1e-2 && w[2].abs() < 1e-2,
            "{w:?}"
        );
        let k = rgb_to_lab_px([0.0, 0.0, 0.0]);
        assert!(k.iter().all(|v| v.abs() < 1e-9), "{k:?}");
        let r = rgb_to_lab_px([1.0, 0.0, 0.0]);
        let want = [53.240_587_94, 80.092_308_23, 67.202_751_04];
        for i in 0..3 {
            assert!((r[i] - want[i]).abs() < 1e-3, "{r:?} vs {want:?}");
        }
    }

    #[test]
    fn lab_round_trip() {
        for rgb in [[0.2, 0.5, 0.7], [0.9, 0.1, 0.3], [0.01, 0.02, 0.03]] {
            let back = lab_to_rgb_px(rgb_to_lab_px(rgb));
            for i in 0..3 {
                assert!((back[i] - rgb[i]).abs() < 1e-4, "{rgb:?} -> {back:?}");
            }
        }
    }

    #[test]
    fn lalphabeta_round_trip() {
        for rgb in [[0.2, 0.5, 0.7], [0.9, 0.1, 0.3]] {
            let back = lalphabeta_to_rgb_px(rgb_to_lalphabeta_px(rgb, 1e-6));
            for i in 0..3 {
                assert!((back[i] - rgb[i]).abs() < 2e-3, "{rgb:?} -> {back:?}");
            }
        }
    }
}
