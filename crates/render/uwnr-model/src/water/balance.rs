//! The clean balance: per-channel gains that bring a photo taken in air to the white point of
//! the real pairs' clean sides before the water is applied.
//!
//! A real pair's clean side is an enhanced version of its underwater photo, and enhancement
//! leaves some of the water's cast: the clean sides of the bank's pairs (`uieb-train` and LSUI's
//! training part) have a mean chromaticity of (0.308, 0.348, 0.344) against (0.348, 0.340,
//! 0.312) for photos taken in air (`../shared/data/inair`). A bank water moves such a clean side
//! to its underwater photo, so it is the water from that white point, not from the air: applied
//! to an in-air photo alone it leaves the photo's warmth in the render. The balance is the ratio
//! of the two chromaticities ([`CleanBalance::BANK`], `tools/clean_balance.py`), a fixed white
//! balance that keeps the mean brightness; the photo's own colours are kept around it.
//!
//! The white point of a real clean side also follows its own water: enhancement leaves a share
//! of *that* water's cast. Over the bank's 160 pairs, a clean side's chromaticity minus the
//! bank's mean is [`BANK_WATER_SHARE`] (0.325) times its underwater side's minus theirs (least
//! squares over the three channels; 0.359 fitted on `uieb-train` alone, 0.334 on LSUI's
//! training part alone, and each lowers the other's residual, by 11 and 26 %). With a share,
//! the balance of a render follows its reference ([`CleanBalance::following`]): a green
//! reference's clean side is a little greener than the bank's mean, a blue one's bluer.
//! (`tools/clean_balance.py --bank-underwater` fits it.)
//!
//! The strength of a pair is then what real pairs measure, the distance of the underwater side
//! from a clean side at that white point: `uwnr dataset` calibrates the water against the
//! balanced photo, and records the pair's strength against the photo itself, which the pair
//! stores as its clean side (so a balanced pair sits a little farther apart than its target).

use serde::{Deserialize, Serialize};
use uwnr_core::Image;

use crate::error::{ModelError, Result};

/// Per-channel gains on the clean photo before the water, RGB.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct CleanBalance(pub [f32; 3]);

impl Default for CleanBalance {
    fn default() -> Self {
        Self::BANK
    }
}

/// Mean chromaticity (each channel's share of R + G + B, per image, then averaged) of the
/// bank's clean sides, 160 pairs at 128 x 128 px (`tools/clean_balance.py --bank-underwater`).
pub const BANK_CLEAN_CHROMATICITY: [f32; 3] = [0.3064, 0.3480, 0.3457];
/// The same of the bank's underwater sides.
pub const BANK_UNDERWATER_CHROMATICITY: [f32; 3] = [0.2232, 0.4215, 0.3553];
/// The share of its water's cast a real clean side keeps (module doc).
pub const BANK_WATER_SHARE: f32 = 0.325;

/// Each channel's share of R + G + B of `img`'s mean colour (RGB); `None` for a black or
/// non-RGB image.
#[must_use]
pub fn chromaticity(img: &Image) -> Option<[f32; 3]> {
    if img.channels() != 3 {
        return None;
    }
    let m = mean_colour(img);
    let sum = m.iter().sum::<f32>();
    (sum > 1e-6).then(|| m.map(|v| v / sum))
}

/// Mean of each channel of an RGB image.
#[must_use]
pub fn mean_colour(img: &Image) -> [f32; 3] {
    std::array::from_fn(|c| {
        let p = img.plane(c);
        (p.iter().map(|&v| f64::from(v)).sum::<f64>() / p.len().max(1) as f64) as f32
    })
}

/// Range of a balance gain.
pub const BALANCE_RANGE: (f32, f32) = (0.5, 2.0);

impl CleanBalance {
    /// No balance: the water applies to the photo as it is.
    pub const NONE: Self = Self([1.0; 3]);

    /// The bundled water bank's: its clean sides' mean chromaticity over in-air photos'
    /// (module doc; `tools/clean_balance.py`).
    pub const BANK: Self = Self([0.884, 1.024, 1.103]);

    /// Whether the balance changes nothing.
    #[must_use]
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// The balance for a water whose underwater photo has chromaticity `water` (RGB shares):
    /// each gain moved by `share` of the photo's departure from the bank's underwater mean,
    /// relative to the bank's clean mean (module doc), clamped to [`BALANCE_RANGE`]. The
    /// balance itself when `share` is 0; at the bank's mean water, the balance itself.
    #[must_use]
    pub fn following(&self, share: f32, water: [f32; 3]) -> Self {
        if share == 0.0 {
            return *self;
        }
        let (lo, hi) = BALANCE_RANGE;
        Self(std::array::from_fn(|c| {
            let moved =
                share * (water[c] - BANK_UNDERWATER_CHROMATICITY[c]) / BANK_CLEAN_CHROMATICITY[c];
            (self.0[c] * (1.0 + moved)).clamp(lo, hi)
        }))
    }

    /// Checks the gains: finite, within [`BALANCE_RANGE`].
    pub fn validate(&self) -> Result<()> {
        let (lo, hi) = BALANCE_RANGE;
        match self
            .0
            .iter()
            .find(|g| !(g.is_finite() && (lo..=hi).contains(*g)))
        {
            Some(g) => Err(ModelError::InvalidOptions(format!(
                "clean balance gain {g} must be within [{lo}, {hi}]"
            ))),
            None => Ok(()),
        }
    }

    /// `clean` (RGB in [0, 1]) at the balance's white point, clamped to [0, 1]; `clean` itself
    /// when the balance is none.
    pub fn apply<'a>(&self, clean: &'a Image) -> Result<std::borrow::Cow<'a, Image>> {
        if self.is_none() {
            return Ok(std::borrow::Cow::Borrowed(clean));
        }
        self.validate()?;
        if clean.channels() != 3 {
            return Err(ModelError::InvalidOptions(format!(
                "a clean balance applies to RGB images, got {} channel(s)",
                clean.channels()
            )));
        }
        let mut out = clean.clone();
        for (c, g) in self.0.iter().enumerate() {
            for v in out.plane_mut(c) {
                *v = (g * *v).clamp(0.0, 1.0);
            }
        }
        Ok(std::borrow::Cow::Owned(out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bank_balance_cools_a_photo_and_keeps_its_brightness() {
        let grey = Image::from_planar(4, 4, 3, vec![0.5; 48]).unwrap();
        let out = CleanBalance::BANK.apply(&grey).unwrap();
        let mean = |c: usize| out.plane(c).iter().sum::<f32>() / 16.0;
        assert!(mean(0) < 0.5 && mean(2) > 0.5, "{} {}", mean(0), mean(2));
        let brightness = (mean(0) + mean(1) + mean(2)) / 3.0;
        assert!((brightness - 0.5).abs() < 0.01, "{brightness}");
        // Clamped, and none leaves the image untouched (borrowed, not copied).
        let white = Image::from_planar(2, 2, 3, vec![1.0; 12]).unwrap();
        assert!(
            CleanBalance::BANK
                .apply(&white)
                .unwrap()
                .data()
                .iter()
                .all(|&v| v <= 1.0)
        );
        assert!(matches!(
            CleanBalance::NONE.apply(&grey).unwrap(),
            std::borrow::Cow::Borrowed(_)
        ));
    }

    #[test]
    fn a_balance_following_its_water_keeps_a_share_of_the_cast() {
        let bank = CleanBalance::BANK;
        assert_eq!(bank.following(0.0, [0.1, 0.8, 0.1]), bank);
        let at_mean = bank.following(BANK_WATER_SHARE, BANK_UNDERWATER_CHROMATICITY);
        for (a, b) in at_mean.0.iter().zip(bank.0) {
            assert!((a - b).abs() < 1e-6, "{a} {b}");
        }
        // A greener water than the bank's mean: a greener, less blue clean side; a bluer one
        // the other way; grey through both keeps its brightness within a few per cent.
        let grey = Image::from_planar(2, 2, 3, vec![0.5; 12]).unwrap();
        let means = |b: CleanBalance| {
            let out = b.apply(&grey).unwrap();
            std::array::from_fn::<f32, 3, _>(|c| out.plane(c)[0])
        };
        let base = means(bank);
        let green = means(bank.following(BANK_WATER_SHARE, [0.15, 0.55, 0.30]));
        let blue = means(bank.following(BANK_WATER_SHARE, [0.15, 0.35, 0.50]));
        assert!(
            green[1] > base[1] && green[2] < base[2],
            "{green:?} {base:?}"
        );
        assert!(blue[2] > base[2] && blue[1] < base[1], "{blue:?} {base:?}");
        for m in [green, blue] {
            let b = m.iter().sum::<f32>() / 3.0;
            assert!((b - 0.5).abs() < 0.03, "{m:?}");
        }
        // The gains stay in range however strong the water.
        let extreme = bank.following(1.0, [0.0, 0.0, 1.0]);
        assert!(extreme.validate().is_ok(), "{extreme:?}");
        assert_eq!(chromaticity(&grey), Some([1.0 / 3.0; 3]));
        let black = Image::from_planar(2, 2, 3, vec![0.0; 12]).unwrap();
        assert_eq!(chromaticity(&black), None);
    }

    #[test]
    fn a_balance_out_of_range_is_refused() {
        let grey = Image::from_planar(2, 2, 3, vec![0.5; 12]).unwrap();
        for bad in [[0.1, 1.0, 1.0], [1.0, f32::NAN, 1.0], [1.0, 1.0, 3.0]] {
            let e = CleanBalance(bad).apply(&grey).unwrap_err().to_string();
            assert!(e.contains("clean balance"), "{e}");
        }
        let grey1 = Image::from_planar(2, 2, 1, vec![0.5; 4]).unwrap();
        assert!(CleanBalance::BANK.apply(&grey1).is_err());
    }
}
