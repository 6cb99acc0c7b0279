//! Border index rules: where a position outside `0..len` reads from.
//!
//! - [`reflect101`]: mirror about the first and last samples without repeating them,
//!   `gfedcb|abcdefgh|gfedcba` (OpenCV `BORDER_REFLECT_101`, NumPy `pad(mode="reflect")`,
//!   PyTorch `ReflectionPad2d`), repeated for paddings wider than the row.
//!
//! Not the same as scipy.ndimage's `reflect` mode, which repeats the edge sample
//! (`hgfedcba|abcdefgh|hgfedcba`, OpenCV `BORDER_REFLECT`): uwnr-metrics keeps its own index for
//! that rule (its `filter` module, matching scikit-image's SSIM), and the two must not be merged.

/// Index into `0..len` of position `p` of a row mirrored about its first and last samples
/// without repeating them (`dcb|abcd|cba`): OpenCV's `borderInterpolate(p, len,
/// BORDER_REFLECT_101)`, NumPy's `reflect` and PyTorch's `ReflectionPad`, repeated until the
/// position falls inside, so any `p` is accepted.
///
/// A row of one sample (and, as nothing can be indexed, an empty one) gives 0.
#[must_use]
pub fn reflect101(p: i64, len: usize) -> usize {
    if len <= 1 {
        return 0;
    }
    let len = len as i64;
    // Reflection about 0 and len - 1 repeats with period 2 (len - 1).
    let period = 2 * (len - 1);
    let p = p.rem_euclid(period);
    (if p >= len { period - p } else { p }) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflect101_repeats_without_the_edge() {
        // dcb|abcd|cba, repeated: positions -7..=10 of a length-4 row.
        let got: Vec<usize> = (-7..11).map(|p| reflect101(p, 4)).collect();
        assert_eq!(got, [1, 0, 1, 2, 3, 2, 1, 0, 1, 2, 3, 2, 1, 0, 1, 2, 3, 2]);
        let got: Vec<usize> = (0..9).map(|p| reflect101(p, 3)).collect();
        assert_eq!(got, [0, 1, 2, 1, 0, 1, 2, 1, 0]);
        assert_eq!(reflect101(-5, 1), 0);
        assert_eq!(reflect101(5, 1), 0);
        assert_eq!(reflect101(3, 0), 0);
    }

    #[test]
    fn reflect101_is_the_identity_inside() {
        for len in 1..6 {
            for p in 0..len {
                assert_eq!(reflect101(p as i64, len), p);
            }
        }
    }
}
