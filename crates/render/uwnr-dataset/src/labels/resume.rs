//! Resuming a labelled dataset: the label fingerprints of the settings compared image by image,
//! so that fixing one label file remakes only that image's pairs.

/// Compares the per-image label fingerprints (`labels.images`, `masks.images`) that `existing`
/// settings record with those of `requested`: returns `existing` with the requested
/// fingerprints (so that the rest is compared as usual) and the clean images whose labels
/// differ. Fixing a label file changes only its image, whose pairs the caller then makes if none
/// is made yet, and refuses otherwise.
#[must_use]
pub fn split_image_fingerprints(
    existing: &crate::manifest::Settings,
    requested: &crate::manifest::Settings,
) -> (crate::manifest::Settings, Vec<usize>) {
    let mut adjusted = existing.clone();
    let mut changed = Vec::new();
    for (ours, theirs) in [
        (&mut adjusted.labels, &requested.labels),
        (&mut adjusted.masks, &requested.masks),
    ] {
        let (Some(ours), Some(theirs)) = (ours.as_mut(), theirs.as_ref()) else {
            continue;
        };
        let (Some(a), Some(b)) = (ours["images"].as_array(), theirs["images"].as_array()) else {
            continue;
        };
        if a.len() != b.len() {
            continue;
        }
        changed.extend((0..a.len()).filter(|&i| a[i] != b[i]));
        ours["images"] = theirs["images"].clone();
    }
    changed.sort_unstable();
    changed.dedup();
    (adjusted, changed)
}
