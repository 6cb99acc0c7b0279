//! Dark channel (He, Sun & Tang, "Single Image Haze Removal Using Dark Channel Prior", 2009):
//! `D(x) = min over y in Omega(x) of min over c of I_c(y)`.
//!
//! UWNR's underwater dark-channel loss uses the G and B channels only and a 15x15 window
//! ([`UNDERWATER_CHANNELS`], [`UNDERWATER_WINDOW`]); the released code pads the image with edge
//! replication (`np.pad(..., 'edge')`) by `window / 2` and slides the window from there, so the
//! window of pixel `x` covers `[x - window/2, x - window/2 + window)`.
//!
//! The window minimum is separable (rows, then columns) and each 1-D pass uses the van Herk /
//! Gil-Werman algorithm: about three comparisons per sample whatever the window size.

use rayon::prelude::*;

use crate::error::{CoreError, Result};
use crate::image::Image;

/// Channels of the underwater dark channel: G and B (red is absorbed first under water).
pub const UNDERWATER_CHANNELS: [usize; 2] = [1, 2];
/// Window side of the underwater dark channel in the released training loss.
pub const UNDERWATER_WINDOW: usize = 15;

/// Dark channel of `img` over `channels` with a `window x window` minimum filter (edge
/// replication at the borders). Returns a 1-channel image of the same size.
pub fn dark_channel(img: &Image, channels: &[usize], window: usize) -> Result<Image> {
    let (w, h) = img.size();
    if channels.is_empty() {
        return Err(CoreError::InvalidArgument(
            "dark channel over no channels".into(),
        ));
    }
    if let Some(&c) = channels.iter().find(|&&c| c >= img.channels()) {
        return Err(CoreError::InvalidArgument(format!(
            "channel {c} requested from an image with {} channels",
            img.channels()
        )));
    }
    if window == 0 {
        return Err(CoreError::InvalidArgument(
            "window must be at least 1".into(),
        ));
    }
    if w == 0 || h == 0 {
        return Err(CoreError::Empty {
            width: w,
            height: h,
        });
    }

    let mut minimum = img.plane(channels[0]).to_vec();
    for &c in &channels[1..] {
        for (m, &v) in minimum.iter_mut().zip(img.plane(c)) {
            *m = m.min(v);
        }
    }
    let before = window / 2;
    let after = window - 1 - before;

    // Rows.
    let mut rows = vec![0.0_f32; w * h];
    rows.par_chunks_mut(w)
        .zip(minimum.par_chunks(w))
        .for_each_init(Scratch::default, |scratch, (dst, src)| {
            sliding_min(src, before, after, dst, scratch);
        });
    // Columns, through a transpose so that every pass reads contiguous memory.
    let transposed = transpose(&rows, w, h);
    let mut cols = vec![0.0_f32; w * h];
    cols.par_chunks_mut(h)
        .zip(transposed.par_chunks(h))
        .for_each_init(Scratch::default, |scratch, (dst, src)| {
            sliding_min(src, before, after, dst, scratch);
        });
    Image::from_planar(w, h, 1, transpose(&cols, h, w))
}

/// Buffers reused across the rows handled by one thread.
#[derive(Default)]
struct Scratch {
    padded: Vec<f32>,
    prefix: Vec<f32>,
    suffix: Vec<f32>,
}

/// `out[i] = min(src[clamp(i - before ..= i + after)])` by van Herk / Gil-Werman: the padded
/// signal is cut into blocks of the window length; a window spans the suffix of one block and
/// the prefix of the next.
fn sliding_min(src: &[f32], before: usize, after: usize, out: &mut [f32], s: &mut Scratch) {
    let window = before + after + 1;
    let (first, last) = (src[0], src[src.len() - 1]);
    s.padded.clear();
    s.padded.resize(before, first);
    s.padded.extend_from_slice(src);
    s.padded.resize(before + src.len() + after, last);
    let n = s.padded.len();

    s.prefix.clear();
    s.prefix.extend_from_slice(&s.padded);
    s.suffix.clear();
    s.suffix.extend_from_slice(&s.padded);
    for start in (0..n).step_by(window) {
        let end = (start + window).min(n);
        for i in start + 1..end {
            s.prefix[i] = s.prefix[i].min(s.prefix[i - 1]);
        }
        for i in (start..end - 1).rev() {
            s.suffix[i] = s.suffix[i].min(s.suffix[i + 1]);
        }
    }
    for (i, o) in out.iter_mut().enumerate() {
        *o = s.suffix[i].min(s.prefix[i + window - 1]);
    }
}

fn transpose(data: &[f32], w: usize, h: usize) -> Vec<f32> {
    let mut out = vec![0.0_f32; w * h];
    for (y, row) in data.chunks_exact(w).enumerate() {
        for (x, &v) in row.iter().enumerate() {
            out[x * h + y] = v;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sliding_min_matches_definition() {
        let src = [5.0, 3.0, 8.0, 1.0, 9.0, 7.0, 2.0];
        let mut out = [0.0; 7];
        sliding_min(&src, 1, 1, &mut out, &mut Scratch::default());
        assert_eq!(out, [3.0, 3.0, 1.0, 1.0, 1.0, 2.0, 2.0]);
        sliding_min(&src, 2, 1, &mut out, &mut Scratch::default());
        assert_eq!(out, [3.0, 3.0, 1.0, 1.0, 1.0, 1.0, 2.0]);
    }

    #[test]
    fn window_one_is_the_channel_minimum() {
        let img = Image::from_planar(2, 1, 3, vec![0.3, 0.2, 0.5, 0.4, 0.7, 0.1]).unwrap();
        let d = dark_channel(&img, &[0, 1, 2], 1).unwrap();
        assert_eq!(d.data(), &[0.3, 0.1]);
        let d = dark_channel(&img, &UNDERWATER_CHANNELS, 1).unwrap();
        assert_eq!(d.data(), &[0.5, 0.1]);
        assert!(dark_channel(&img, &[3], 1).is_err());
    }
}
