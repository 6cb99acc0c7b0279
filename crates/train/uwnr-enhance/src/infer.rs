//! Enhancing images of any size with a trained network (whole image, no tiling: the network is
//! fully convolutional and small, about 0.6 GMac per 256x256 image).

use burn::tensor::{Device, Tensor, TensorData};
use uwnr_core::Image;

use crate::error::{EnhanceError, Result};
use crate::model::{IMAGE_CHANNELS, ShallowUwnet};

/// Enhances one RGB image; the result is clamped to [0, 1] (as saving does in the released
/// code).
pub fn enhance(net: &ShallowUwnet, image: &Image, device: &Device) -> Result<Image> {
    if image.channels() != IMAGE_CHANNELS {
        return Err(EnhanceError::InvalidConfig(format!(
            "the enhancer takes RGB images, got {} channels",
            image.channels()
        )));
    }
    let (w, h) = image.size();
    let x = Tensor::<4>::from_data(
        TensorData::new(image.data().to_vec(), [1, IMAGE_CHANNELS, h, w]),
        device,
    );
    let y = net.forward(x).clamp(0.0, 1.0);
    let data = y
        .into_data()
        .try_into_vec::<f32>()
        .map_err(|e| uwnr_model::ModelError::Backend(format!("{e:?}")))?;
    Ok(Image::from_planar(w, h, IMAGE_CHANNELS, data)?)
}
