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
