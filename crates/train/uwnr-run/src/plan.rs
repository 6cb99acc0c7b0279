//! Seeded sample plans: the data order of each epoch and the random crop, flip and quarter turn
//! of each sample, all pure functions of `(seed, epoch, position)`, so a run gives the same
//! batches whatever the thread timing and a resumed run continues exactly.
//!
//! As in the released UWNR data loader (`UWS_Dataset_Retinex.augData`): a random crop, a
//! horizontal flip with probability 1/2, then a rotation by 0/90/180/270 degrees
//! counter-clockwise (torchvision's `rotate`). A task that draws more per sample (UWNR's colour
//! cast) continues from the generator [`plan_crop`] returns, so its draws come after these.

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Stream tag of the per-epoch data order ("order").
const STREAM_ORDER: u64 = 0x006f_7264_6572;
/// Stream tag of the per-sample plan ("sample").
const STREAM_SAMPLE: u64 = 0x7361_6d70_6c65;

/// One SplitMix64 step (Steele et al. 2014): mixes a 64-bit word so nearby inputs give
/// unrelated seeds.
pub use uwnr_core::seed::mix as mix64;

/// A generator seeded from `(seed, stream, a, b)`: one independent stream per purpose (`stream`
/// is a tag such as the ASCII of its name) and per `(a, b)`.
#[must_use]
pub fn rng_for(seed: u64, stream: u64, a: u64, b: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(mix64(mix64(mix64(seed ^ stream) ^ a) ^ b))
}

/// The order in which epoch `epoch` visits the `n` pairs: a seeded permutation.
#[must_use]
pub fn epoch_order(seed: u64, epoch: usize, n: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(&mut rng_for(seed, STREAM_ORDER, epoch as u64, 0));
    order
}

/// Which geometric augmentations are on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Geometry {
    /// Horizontal flips.
    pub flip: bool,
    /// Quarter turns.
    pub rotate: bool,
}

/// The crop, flip and turn of one sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CropPlan {
    /// Index of the pair in the training set.
    pub pair: usize,
    /// Left column of the crop.
    pub x0: usize,
    /// Top row of the crop.
    pub y0: usize,
    /// Horizontal flip.
    pub flip: bool,
    /// Counter-clockwise quarter turns (0..4), after the flip.
    pub quarter_turns: u8,
}

impl CropPlan {
    /// The source pixel of output pixel `(x, y)`, an index into the pair's planes of width
    /// `width` ([`source_of`] inside the crop window).
    #[must_use]
    pub fn source_index(&self, x: usize, y: usize, crop: usize, width: usize) -> usize {
        let (sx, sy) = source_of(x, y, crop, self.flip, self.quarter_turns);
        (self.y0 + sy) * width + self.x0 + sx
    }
}

/// The plan of sample `position` of epoch `epoch`, for pair `index` of size `width x height`,
/// and the generator it was drawn from (for a task's further draws).
#[must_use]
pub fn plan_crop(
    seed: u64,
    epoch: usize,
    position: usize,
    (index, width, height): (usize, usize, usize),
    crop: usize,
    geometry: Geometry,
) -> (CropPlan, ChaCha8Rng) {
    let mut rng = rng_for(seed, STREAM_SAMPLE, epoch as u64, position as u64);
    let x0 = rng.random_range(0..=width.saturating_sub(crop));
    let y0 = rng.random_range(0..=height.saturating_sub(crop));
    // Always draw every value so that switching one augmentation off leaves the others' draws.
    let flip = rng.random_bool(0.5);
    let turns = rng.random_range(0..4_u8);
    let plan = CropPlan {
        pair: index,
        x0,
        y0,
        flip: geometry.flip && flip,
        quarter_turns: if geometry.rotate { turns } else { 0 },
    };
    (plan, rng)
}

/// The pixel of the un-augmented `crop x crop` window that output pixel `(x, y)` shows after a
/// flip (first) and `turns` counter-clockwise quarter turns.
#[must_use]
pub fn source_of(x: usize, y: usize, crop: usize, flip: bool, turns: u8) -> (usize, usize) {
    let last = crop - 1;
    // Undo the counter-clockwise quarter turns one by one: a CCW turn maps source (sx, sy) to
    // (sy, last - sx), so its inverse maps (x, y) to (last - y, x).
    let (mut sx, mut sy) = (x, y);
    for _ in 0..turns % 4 {
        (sx, sy) = (last - sy, sx);
    }
    if flip {
        sx = last - sx;
    }
    (sx, sy)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn epoch_order_is_a_seeded_permutation() {
        let a = epoch_order(1, 0, 50);
        let mut sorted = a.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..50).collect::<Vec<_>>());
        assert_eq!(a, epoch_order(1, 0, 50));
        assert_ne!(a, epoch_order(1, 1, 50));
        assert_ne!(a, epoch_order(2, 0, 50));
    }

    #[test]
    fn one_quarter_turn_is_counter_clockwise() {
        // A 2x2 crop [[a, b], [c, d]] turned CCW is [[b, d], [a, c]].
        let src = |x: usize, y: usize| ["ab", "cd"][y].as_bytes()[x] as char;
        let turned: String = (0..2)
            .flat_map(|y| (0..2).map(move |x| (x, y)))
            .map(|(x, y)| {
                let (sx, sy) = source_of(x, y, 2, false, 1);
                src(sx, sy)
            })
            .collect();
        assert_eq!(turned, "bdac");
        // Flip first: [[b, a], [d, c]], then CCW: [[a, c], [b, d]].
        let flipped: String = (0..2)
            .flat_map(|y| (0..2).map(move |x| (x, y)))
            .map(|(x, y)| {
                let (sx, sy) = source_of(x, y, 2, true, 1);
                src(sx, sy)
            })
            .collect();
        assert_eq!(flipped, "acbd");
        for turns in 0..4 {
            assert_eq!(source_of(0, 0, 5, false, turns * 4 % 4), (0, 0));
        }
    }

    #[test]
    fn plans_stay_inside_and_follow_the_switches() {
        let off = Geometry {
            flip: false,
            rotate: false,
        };
        for pos in 0..200 {
            let (p, _) = plan_crop(3, 1, pos, (0, 40, 30), 16, off);
            assert!(p.x0 + 16 <= 40 && p.y0 + 16 <= 30);
            assert!(!p.flip && p.quarter_turns == 0);
            let on = Geometry {
                flip: true,
                rotate: true,
            };
            let (q, _) = plan_crop(3, 1, pos, (0, 40, 30), 16, on);
            assert_eq!((q.x0, q.y0), (p.x0, p.y0), "switches leave the crop's draw");
        }
    }
}
