//! COCO's run-length encoded masks: `{"size": [h, w], "counts": [...]}` (uncompressed) or with
//! `counts` as a string (compressed, pycocotools' `maskApi.c` encoding). Runs alternate
//! background and foreground, starting with background, over the mask in column-major order.

use super::geometry::Fit;

/// A binary mask in COCO's layout: `height x width`, column-major (index `x * height + y`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mask {
    pub height: usize,
    pub width: usize,
    pub bits: Vec<bool>,
}

impl Mask {
    /// Decodes run lengths; `None` when they do not add up to the mask's size.
    #[must_use]
    pub fn from_counts(height: usize, width: usize, counts: &[u64]) -> Option<Self> {
        let n = height.checked_mul(width)?;
        let mut bits = Vec::with_capacity(n);
        let mut value = false;
        for &c in counts {
            let c = usize::try_from(c).ok()?;
            if bits.len() + c > n {
                return None;
            }
            bits.resize(bits.len() + c, value);
            value = !value;
        }
        (bits.len() == n).then_some(Self {
            height,
            width,
            bits,
        })
    }

    /// The run lengths, starting with a (possibly empty) background run.
    #[must_use]
    pub fn counts(&self) -> Vec<u64> {
        let mut out = Vec::new();
        let mut value = false;
        let mut run = 0u64;
        for &b in &self.bits {
            if b == value {
                run += 1;
            } else {
                out.push(run);
                value = b;
                run = 1;
            }
        }
        out.push(run);
        out
    }

    /// Foreground pixels.
    #[must_use]
    pub fn area(&self) -> usize {
        self.bits.iter().filter(|&&b| b).count()
    }

    /// The tight box `[x, y, w, h]` of the foreground (pycocotools' `toBbox`), zeros when empty.
    #[must_use]
    pub fn bbox(&self) -> [f64; 4] {
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for (i, _) in self.bits.iter().enumerate().filter(|(_, b)| **b) {
            let (x, y) = (i / self.height, i % self.height);
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x + 1);
            y1 = y1.max(y + 1);
        }
        if x0 == usize::MAX {
            return [0.0; 4];
        }
        [x0 as f64, y0 as f64, (x1 - x0) as f64, (y1 - y0) as f64]
    }

    /// The mask carried to the pair: resampled by nearest neighbour with the image's fit.
    #[must_use]
    pub fn fitted(&self, fit: &Fit) -> Self {
        // Row-major for the fit, then back to column-major.
        let (h, w) = (self.height, self.width);
        let mut row_major = vec![false; h * w];
        for x in 0..w {
            for y in 0..h {
                row_major[y * w + x] = self.bits[x * h + y];
            }
        }
        let out = fit.resample(&row_major, 1);
        let (oh, ow) = (fit.height, fit.width);
        let mut bits = vec![false; oh * ow];
        for y in 0..oh {
            for x in 0..ow {
                bits[x * oh + y] = out[y * ow + x];
            }
        }
        Self {
            height: oh,
            width: ow,
            bits,
        }
    }
}

/// Decodes pycocotools' compressed counts string (`rleFrString`); `None` for a malformed one.
#[must_use]
pub fn counts_from_string(s: &str) -> Option<Vec<u64>> {
    let bytes = s.as_bytes();
    let mut counts: Vec<i64> = Vec::new();
    let mut p = 0;
    while p < bytes.len() {
        let mut x: i64 = 0;
        let mut k = 0;
        loop {
            let c = i64::from(*bytes.get(p)?) - 48;
            if !(0..64).contains(&c) || k > 12 {
                return None;
            }
            x |= (c & 0x1f) << (5 * k);
            p += 1;
            k += 1;
            if c & 0x20 == 0 {
                if c & 0x10 != 0 {
                    x |= -1_i64 << (5 * k);
                }
                break;
            }
        }
        if counts.len() > 2 {
            x += counts[counts.len() - 2];
        }
        counts.push(x);
    }
    counts.into_iter().map(|c| u64::try_from(c).ok()).collect()
}

/// Encodes counts as pycocotools' compressed string (`rleToString`).
#[must_use]
pub fn counts_to_string(counts: &[u64]) -> String {
    let mut s = String::new();
    for i in 0..counts.len() {
        let mut x = counts[i] as i64;
        if i > 2 {
            x -= counts[i - 2] as i64;
        }
        loop {
            let mut c = x & 0x1f;
            x >>= 5;
            let more = if c & 0x10 != 0 { x != -1 } else { x != 0 };
            if more {
                c |= 0x20;
            }
            s.push(char::from((c + 48) as u8));
            if !more {
                break;
            }
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::Size;

    #[test]
    fn compressed_counts_round_trip() {
        for counts in [
            vec![0u64, 5, 3, 7],
            vec![10, 1, 1, 1, 100, 20000, 3],
            vec![0],
            vec![123_456, 7, 65_000, 2, 9],
        ] {
            let s = counts_to_string(&counts);
            assert_eq!(counts_from_string(&s), Some(counts.clone()), "{s}");
        }
        // Small counts are one character each, offset from '0'.
        assert_eq!(counts_to_string(&[1, 3]), "13");
        assert_eq!(counts_from_string("13"), Some(vec![1, 3]));
        assert_eq!(counts_from_string("\u{1}"), None);
    }

    #[test]
    fn masks_decode_encode_and_measure() {
        // 3 high, 2 wide, column-major: column 0 = [0,1,1], column 1 = [1,0,0].
        let m = Mask::from_counts(3, 2, &[1, 3, 2]).unwrap();
        assert_eq!(m.bits, [false, true, true, true, false, false]);
        assert_eq!(m.counts(), [1, 3, 2]);
        assert_eq!(m.area(), 3);
        assert_eq!(m.bbox(), [0.0, 0.0, 2.0, 3.0]);
        assert!(Mask::from_counts(3, 2, &[1, 3]).is_none());
        assert!(Mask::from_counts(3, 2, &[1, 9]).is_none());
        // A mask starting with foreground has an empty first run.
        let m = Mask::from_counts(1, 2, &[0, 1, 1]).unwrap();
        assert_eq!(m.counts(), [0, 1, 1]);
    }

    #[test]
    fn fitted_masks_double_with_the_image() {
        // 2 high x 2 wide with one pixel (x=1, y=0) set, fitted to 4x4: a 2x2 block at x 2..4.
        let m = Mask::from_counts(2, 2, &[2, 1, 1]).unwrap();
        let fit = Fit::new(
            (2, 2),
            Size::Fixed {
                width: 16,
                height: 16,
            },
        );
        let big = m.fitted(&fit);
        assert_eq!((big.height, big.width), (16, 16));
        assert_eq!(big.area(), 64);
        assert_eq!(big.bbox(), [8.0, 0.0, 8.0, 8.0]);
    }
}
