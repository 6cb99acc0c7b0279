//! Small helpers shared by the depth sources: input checks and min-max normalisation.

use uwnr_core::Image;

use crate::error::{DepthError, Result};

/// Below this range (max - min) a map is treated as constant: min-max normalisation would only
/// amplify rounding noise.
pub(crate) const MIN_RANGE: f32 = 1e-12;

/// The R, G, B planes of a clean image; a grey image lends its one plane to all three.
pub(crate) fn rgb_planes(clean: &Image) -> Result<[&[f32]; 3]> {
    check_not_empty(clean)?;
    match clean.channels() {
        1 => Ok([clean.plane(0); 3]),
        3 => Ok([clean.plane(0), clean.plane(1), clean.plane(2)]),
        got => Err(DepthError::Channels { got }),
    }
}

/// Fails on an image with zero width or height.
pub(crate) fn check_not_empty(img: &Image) -> Result<()> {
    let (width, height) = img.size();
    if width == 0 || height == 0 {
        return Err(DepthError::EmptyImage { width, height });
    }
    Ok(())
}

/// Smallest and largest value of a slice (`None` when empty).
pub(crate) fn min_max(values: &[f32]) -> Option<(f32, f32)> {
    values.iter().fold(None, |acc, &v| match acc {
        None => Some((v, v)),
        Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
    })
}

/// Maps `values` linearly onto [0, 1] (`(v - min) / (max - min)`) in place and returns the
/// original `(min, max)`. A constant slice (range below [`MIN_RANGE`]) is left unchanged and
/// `None` is returned.
pub(crate) fn normalise_min_max(values: &mut [f32]) -> Option<(f32, f32)> {
    let (lo, hi) = min_max(values)?;
    if hi - lo < MIN_RANGE {
        return None;
    }
    let scale = 1.0 / (hi - lo);
    for v in values.iter_mut() {
        *v = ((*v - lo) * scale).clamp(0.0, 1.0);
    }
    Some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalise_maps_onto_unit_range() {
        let mut v = [2.0, 4.0, 3.0];
        assert_eq!(normalise_min_max(&mut v), Some((2.0, 4.0)));
        assert_eq!(v, [0.0, 1.0, 0.5]);
    }

    #[test]
    fn constant_is_left_alone() {
        let mut v = [0.3; 4];
        assert_eq!(normalise_min_max(&mut v), None);
        assert_eq!(v, [0.3; 4]);
    }
}
