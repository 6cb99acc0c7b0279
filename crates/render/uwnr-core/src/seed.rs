//! Seeds: SplitMix64 (Steele, Lea and Flood 2014), the mixer every seeded draw derives its
//! streams from: one step ([`mix`]) and the seed of a batch's item ([`item_seed`]).

/// SplitMix64's increment, the golden ratio in 64 bits: what a SplitMix64 stream adds to its
/// state before each output.
pub const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64's finaliser: mixes a 64-bit word so that neighbouring words give unrelated ones.
#[must_use]
fn finalise(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// One SplitMix64 step of `x`: add the golden-ratio increment, then the finaliser. Neighbouring
/// inputs give unrelated outputs.
#[must_use]
pub fn mix(x: u64) -> u64 {
    finalise(x.wrapping_add(GAMMA))
}

/// The seed of item `index` of a batch rendered with the run's `seed`: the two mixed with
/// SplitMix64's finaliser, so every image of a batch draws its own parameters and the batch is
/// reproducible. `uwnr render` and the Python package's `render` / `render_batch` use it, so a
/// batch gives the same images from either.
#[must_use]
pub fn item_seed(seed: u64, index: usize) -> u64 {
    finalise(seed ^ (index as u64).wrapping_mul(GAMMA))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitmix64_reference_values() {
        // The first outputs of SplitMix64 seeded with 0 (state advanced before each output).
        assert_eq!(mix(0), 0xE220_A839_7B1D_CDAF);
        assert_eq!(mix(0x9E37_79B9_7F4A_7C15), 0x6E78_9E6A_A1B9_65F4);
    }

    #[test]
    fn item_seeds_are_pinned() {
        // The seeds batches were rendered with before `item_seed` moved here: a change would
        // change every batch's images.
        assert_eq!(item_seed(0, 0), 0);
        assert_eq!(item_seed(7, 3), 0xE831_3FE1_D735_0611);
        assert_eq!(item_seed(42, 1), 0xBDD7_3226_2FEB_6E95);
    }
}
