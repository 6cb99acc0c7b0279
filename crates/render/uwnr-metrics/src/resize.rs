//! The two resamplers feature extraction needs, each matching a stated definition:
//! - [`resize_bilinear_torch`]: `torch.nn.functional.interpolate(x, size, mode="bilinear",
//!   align_corners=False)` without antialiasing, the resize pytorch-fid applies before
//!   InceptionV3 (source coordinate `(i + 0.5) * in / out - 0.5`, clamped at 0; the
//!   coordinates in f32 as torch computes them, the blend in f64);
//! - [`resize_area`]: the exact area average of the source over each output pixel's
//!   footprint (OpenCV's `INTER_AREA` when shrinking), used to bring images to the fixed
//!   working size of [`crate::ColorTextureFeatures`] without aliasing.

use uwnr_core::Image;

use crate::error::{MetricsError, Result};

/// Per output index: `(i0, i1, w0, w1)` with `out = w0 in[i0] + w1 in[i1]` (torch's
/// `compute_source_index_and_lambda` for linear modes, `align_corners=False`).
fn torch_linear_taps(input: usize, output: usize) -> Vec<(usize, usize, f64, f64)> {
    if input == output {
        return (0..output).map(|i| (i, i, 1.0, 0.0)).collect();
    }
    let ratio = input as f32 / output as f32;
    (0..output)
        .map(|o| {
            let src = (ratio * (o as f32 + 0.5) - 0.5).max(0.0);
            let i0 = (src.floor() as usize).min(input - 1);
            let lambda1 = (src - i0 as f32).clamp(0.0, 1.0);
            let i1 = if i0 < input - 1 { i0 + 1 } else { i0 };
            (i0, i1, f64::from(1.0 - lambda1), f64::from(lambda1))
        })
        .collect()
}

/// Bilinear resize with PyTorch's `align_corners=False` convention and no antialiasing.
/// Returns a copy when the size already matches. Fails on empty input or output sizes.
pub fn resize_bilinear_torch(img: &Image, out_w: usize, out_h: usize) -> Result<Image> {
    let (w, h) = img.size();
    if w == 0 || h == 0 || out_w == 0 || out_h == 0 {
        return Err(MetricsError::InvalidArgument(format!(
            "cannot resize {w}x{h} to {out_w}x{out_h}"
        )));
    }
    if (w, h) == (out_w, out_h) {
        return Ok(img.clone());
    }
    let xt = torch_linear_taps(w, out_w);
    let yt = torch_linear_taps(h, out_h);
    let mut data = Vec::with_capacity(out_w * out_h * img.channels());
    for c in 0..img.channels() {
        let p = img.plane(c);
        for &(y0, y1, h0, h1) in &yt {
            let (r0, r1) = (&p[y0 * w..(y0 + 1) * w], &p[y1 * w..(y1 + 1) * w]);
            for &(x0, x1, w0, w1) in &xt {
                let top = w0 * f64::from(r0[x0]) + w1 * f64::from(r0[x1]);
                let bottom = w0 * f64::from(r1[x0]) + w1 * f64::from(r1[x1]);
                data.push((h0 * top + h1 * bottom) as f32);
            }
        }
    }
    Ok(Image::from_planar(out_w, out_h, img.channels(), data)?)
}

/// Per output index, the `(source index, weight)` pairs covering `[o s, (o + 1) s)`, s = in/out,
/// weights summing to 1.
fn area_taps(input: usize, output: usize) -> Vec<Vec<(usize, f64)>> {
    let scale = input as f64 / output as f64;
    (0..output)
        .map(|o| {
            let (start, end) = (o as f64 * scale, (o + 1) as f64 * scale);
            let mut taps = Vec::new();
            let mut i = start.floor() as usize;
            while (i as f64) < end && i < input {
                let cover = (end.min((i + 1) as f64) - start.max(i as f64)).max(0.0);
                if cover > 0.0 {
                    taps.push((i, cover / scale));
                }
                i += 1;
            }
            taps
        })
        .collect()
}

/// Area-average resize of every plane to `out_w x out_h` (f64 planes, row-major).
pub(crate) fn resize_area(img: &Image, out_w: usize, out_h: usize) -> Vec<Vec<f64>> {
    let (w, h) = img.size();
    let xt = area_taps(w, out_w);
    let yt = area_taps(h, out_h);
    (0..img.channels())
        .map(|c| {
            let p = img.plane(c);
            // Rows first: h x out_w.
            let mut rows = vec![0.0; h * out_w];
            for y in 0..h {
                let src = &p[y * w..(y + 1) * w];
                for (x, taps) in xt.iter().enumerate() {
                    rows[y * out_w + x] = taps.iter().map(|&(i, wt)| wt * f64::from(src[i])).sum();
                }
            }
            let mut out = vec![0.0; out_h * out_w];
            for (y, taps) in yt.iter().enumerate() {
                for &(i, wt) in taps {
                    let src = &rows[i * out_w..(i + 1) * out_w];
                    for (o, s) in out[y * out_w..(y + 1) * out_w].iter_mut().zip(src) {
                        *o += wt * s;
                    }
                }
            }
            out
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn torch_taps_for_doubling() {
        // in 2 -> out 4: sources -0.25 (clamped to 0), 0.25, 0.75, 1.25 (i0 = 1 = last).
        let t = torch_linear_taps(2, 4);
        assert_eq!(t[0], (0, 1, 1.0, 0.0));
        assert_eq!(t[1], (0, 1, 0.75, 0.25));
        assert_eq!(t[2], (0, 1, 0.25, 0.75));
        assert_eq!(t[3].0, 1);
        assert_eq!(t[3].1, 1);
    }

    #[test]
    fn bilinear_keeps_constants_and_interpolates_ramps() {
        let img = Image::filled(5, 3, 3, 0.25);
        let r = resize_bilinear_torch(&img, 17, 11).unwrap();
        assert!(r.data().iter().all(|&v| (v - 0.25).abs() < 1e-7));
        let ramp = Image::from_planar(2, 1, 1, vec![0.0, 1.0]).unwrap();
        let r = resize_bilinear_torch(&ramp, 4, 1).unwrap();
        assert_eq!(r.data(), &[0.0, 0.25, 0.75, 1.0]);
    }

    #[test]
    fn area_resize_averages_blocks_and_preserves_the_mean() {
        let img =
            Image::from_planar(4, 2, 1, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]).unwrap();
        let r = resize_area(&img, 2, 1);
        assert_eq!(r[0], vec![2.5, 4.5]);
        // A non-integer factor: 3 -> 2, each output covers 1.5 inputs.
        let img = Image::from_planar(3, 1, 1, vec![0.0, 3.0, 6.0]).unwrap();
        let r = resize_area(&img, 2, 1);
        assert!(
            (r[0][0] - 1.0).abs() < 1e-12 && (r[0][1] - 5.0).abs() < 1e-12,
            "{:?}",
            r[0]
        );
    }
}
