//! [`Variant`]: what the generator's input and output planes mean (the paper's network or the
//! `anchored` one of [`crate::style`]), with the planes each has. Depends on nothing else in the
//! crate, so the config, the generator and the style stage all build on it.

use serde::{Deserialize, Serialize};

/// What the network's input and output planes mean.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// The released network: clean RGB, depth, light field in; the underwater RGB image out.
    #[default]
    Paper,
    /// Clean RGB, light field and the colour-transfer anchor in; a smooth gain and offset on
    /// the anchor out, followed by the depth-driven image-formation stage ([`crate::style`]).
    Anchored,
}

impl Variant {
    /// Input and output planes of the network body.
    #[must_use]
    pub fn channels(self) -> (usize, usize) {
        match self {
            Self::Paper => (7, 3),
            Self::Anchored => (ANCHORED_IN_CHANNELS, ANCHORED_OUT_CHANNELS),
        }
    }
}

/// Input planes of the anchored network: clean RGB, light field, anchor.
pub const ANCHORED_IN_CHANNELS: usize = 9;
/// Output planes of the anchored network: gain (3) and offset (3).
pub const ANCHORED_OUT_CHANNELS: usize = 6;
