//! The light-field map (UWNR's "LFR" module, paper Eq. 2-3) as training uses it, from
//! [`uwnr_core::lightfield`] (the released `MutiScaleLuminanceEstimation`, bit for bit):
//! - on a training crop, the released procedure at the crop's own size
//!   ([`light_field_raw`]), as `UWS_Dataset_Retinex.augData` computes it on each crop;
//! - for a whole validation image, the map at the network's 256x256 training scale resized to
//!   the image ([`light_field_for`]), as `uwnr render` does.

use uwnr_core::Image;

use crate::error::Result;

/// The released light-field procedure on `img` (3 channels, [0, 1]) at its own size.
pub fn light_field_raw(img: &Image) -> uwnr_core::Result<Image> {
    uwnr_core::lightfield::light_field_raw(img)
}

/// The light field of a whole reference image at `width x height`.
pub fn light_field_for(reference: &Image, width: usize, height: usize) -> Result<Image> {
    Ok(uwnr_core::lightfield::light_field_for(
        reference, width, height,
    )?)
}
