//! What a pair's manifest line records of its labels: the annotations dropped under the
//! [`super::rules`] and the fingerprints of the label files written, so that `verify` notices a
//! label file edited after the pair was made.

use serde::{Deserialize, Serialize};

use super::rules::DropCounts;

/// The `labels_info` of a manifest line.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LabelsInfo {
    /// Annotations dropped, by reason.
    #[serde(default, skip_serializing_if = "DropCounts::is_empty")]
    pub dropped: DropCounts,
    /// Fingerprint of `labels/NAME_k.json|txt` as written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels_fingerprint: Option<String>,
    /// Fingerprint of `masks/NAME_k.png` as written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask_fingerprint: Option<String>,
}
