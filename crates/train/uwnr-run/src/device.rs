//! The burn devices training runs on, chosen once at the edge by name: `flex` (burn's pure-Rust
//! multi-threaded CPU backend) and, with the `tch` feature, `tch` (libtorch on the CPU).
//! Rendering never comes here: it runs on `uwnr-engine`.

pub use burn::tensor::Device;

/// A device name this build does not provide.
#[derive(Debug, thiserror::Error)]
#[error("unknown device {name:?}; available: {available}")]
pub struct UnknownDevice {
    /// The name asked for.
    pub name: String,
    /// The names this build provides, comma-separated.
    pub available: String,
}

/// Names [`device_from_name`] accepts in this build.
#[must_use]
pub fn device_names() -> &'static [&'static str] {
    #[cfg(feature = "tch")]
    {
        &["flex", "tch"]
    }
    #[cfg(not(feature = "tch"))]
    {
        &["flex"]
    }
}

/// The compute device called `name`.
pub fn device_from_name(name: &str) -> Result<Device, UnknownDevice> {
    match name {
        "flex" => Ok(Device::flex()),
        // burn 0.22 deprecates its libtorch backend; it stays here as an optional reference
        // backend for speed and parity comparisons.
        #[cfg(feature = "tch")]
        #[allow(deprecated)]
        "tch" => Ok(Device::libtorch()),
        _ => Err(UnknownDevice {
            name: name.to_string(),
            available: device_names().join(", "),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_names_resolve() {
        for name in device_names() {
            device_from_name(name).unwrap();
        }
        let err = device_from_name("cuda").unwrap_err();
        assert!(err.to_string().contains("flex"), "{err}");
    }
}
