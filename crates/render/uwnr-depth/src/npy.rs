//! NumPy `.npy` depth maps (format versions 1-3): a 2-D array `(H, W)`, or `(1, H, W)` /
//! `(H, W, 1)`, of `float32`, `float64`, `uint16` or `uint8` (either byte order), in C order; how
//! monocular and metric depth networks usually save their output. Read with the `npyz` crate;
//! the shape is checked against the decoding limits before any value is read.

use std::path::Path;

use uwnr_core::Image;
use uwnr_core::io::DecodeLimits;

use crate::error::{DepthError, Result};

/// The magic string that opens every `.npy` file.
const MAGIC: &[u8] = b"\x93NUMPY";

/// Whether `path` ends in `.npy` (any case).
#[must_use]
pub fn is_npy_path(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
}

/// Reads a `.npy` map into one plane of its stored values, with the largest code its type can
/// hold (`255`, `65535`, or `1` for floats, whose values are kept as stored).
pub fn load_npy(path: &Path, limits: &DecodeLimits) -> Result<(Image, f32)> {
    let bytes = std::fs::read(path).map_err(|e| bad(path, format!("cannot read it: {e}")))?;
    parse_npy(&bytes, limits).map_err(|reason| bad(path, reason))
}

fn bad(path: &Path, reason: String) -> DepthError {
    DepthError::BadMapFile {
        path: path.to_path_buf(),
        reason,
    }
}

/// Parses the bytes of a `.npy` file (see [`load_npy`]) with the `npyz` crate, after checking
/// the shape against `limits` (before the data is read).
pub(crate) fn parse_npy(
    bytes: &[u8],
    limits: &DecodeLimits,
) -> std::result::Result<(Image, f32), String> {
    if !bytes.starts_with(MAGIC) {
        return Err("not a NumPy .npy file".into());
    }
    let file = npyz::NpyFile::new(bytes).map_err(|e| format!("unreadable .npy header: {e}"))?;
    if file.order() == npyz::Order::Fortran {
        return Err("Fortran-ordered arrays are not supported; save with C order".into());
    }
    let (h, w) = match *file.shape() {
        [h, w] | [1, h, w] | [h, w, 1] => (h, w),
        ref other => return Err(format!("shape {other:?} is not one map (H, W)")),
    };
    if w == 0 || h == 0 {
        return Err(format!("shape ({h}, {w}) is empty"));
    }
    let max_dim = u64::from(limits.max_dimension);
    if w > max_dim || h > max_dim {
        return Err(format!(
            "{w}x{h} exceeds the {max_dim}-pixel limit on a side"
        ));
    }
    if w * h > limits.max_pixels {
        return Err(format!(
            "{w}x{h} exceeds the limit of {} pixels",
            limits.max_pixels
        ));
    }
    let (w, h) = (w as usize, h as usize);
    let descr = match file.dtype() {
        npyz::DType::Plain(t) => t.to_string(),
        other => other.descr(),
    };
    let truncated =
        |e: std::io::Error| format!("truncated or unreadable data for {h}x{w} values: {e}");
    // Either byte order; the kinds depth maps are saved in.
    let (values, max_code): (Vec<f32>, f32) = match descr.get(1..) {
        Some("f4") => (file.into_vec::<f32>().map_err(truncated)?, 1.0),
        Some("f8") => {
            let v = file.into_vec::<f64>().map_err(truncated)?;
            (v.into_iter().map(|x| x as f32).collect(), 1.0)
        }
        Some("u2") => {
            let v = file.into_vec::<u16>().map_err(truncated)?;
            (v.into_iter().map(f32::from).collect(), f32::from(u16::MAX))
        }
        Some("u1") => {
            let v = file.into_vec::<u8>().map_err(truncated)?;
            (v.into_iter().map(f32::from).collect(), f32::from(u8::MAX))
        }
        _ => {
            return Err(format!(
                "dtype {descr} is not supported (float32, float64, uint16 or uint8)"
            ));
        }
    };
    let img = Image::from_planar(w, h, 1, values).map_err(|e| e.to_string())?;
    Ok((img, max_code))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A version-1 `.npy` file of `descr` with `shape` and raw little-endian `data`.
    pub(crate) fn npy(descr: &str, shape: &str, data: &[u8]) -> Vec<u8> {
        let mut header =
            format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(' ');
        }
        header.push('\n');
        let mut out = MAGIC.to_vec();
        out.extend([1, 0]);
        out.extend((header.len() as u16).to_le_bytes());
        out.extend(header.as_bytes());
        out.extend(data);
        out
    }

    #[test]
    fn float32_metres_are_read_as_stored() {
        let data: Vec<u8> = [1.5f32, 2.0, 0.0, 4.25, 3.0, 1.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let (img, max) = parse_npy(&npy("<f4", "(2, 3)", &data), &DecodeLimits::default()).unwrap();
        assert_eq!(max, 1.0);
        assert_eq!(img.size(), (3, 2));
        assert_eq!(img.data(), &[1.5, 2.0, 0.0, 4.25, 3.0, 1.0]);
    }

    #[test]
    fn uint16_and_leading_unit_axes_are_read() {
        let data: Vec<u8> = [1000u16, 2500]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let (img, max) =
            parse_npy(&npy("<u2", "(1, 1, 2)", &data), &DecodeLimits::default()).unwrap();
        assert_eq!(max, 65535.0);
        assert_eq!(img.data(), &[1000.0, 2500.0]);
    }

    #[test]
    fn big_endian_float64_is_read_too() {
        let data: Vec<u8> = [0.5f64, 7.0].iter().flat_map(|v| v.to_be_bytes()).collect();
        let (img, _) = parse_npy(&npy(">f8", "(2, 1)", &data), &DecodeLimits::default()).unwrap();
        assert_eq!((img.size(), img.data()), ((1, 2), &[0.5, 7.0][..]));
    }

    #[test]
    fn bad_files_say_what_is_wrong() {
        let limits = DecodeLimits::default();
        let err = |b: &[u8]| parse_npy(b, &limits).unwrap_err();
        assert!(err(b"PNG....").contains("not a NumPy"));
        assert!(err(&npy("<f4", "(2, 3)", &[0; 8])).contains("truncated"));
        assert!(err(&npy("<i8", "(1, 1)", &[0; 8])).contains("dtype <i8"));
        // Refused from the header, before 9 million values are read.
        let small = DecodeLimits {
            max_pixels: 1000,
            ..limits
        };
        let e = parse_npy(&npy("<f4", "(3000, 3000)", &[0; 8]), &small).unwrap_err();
        assert!(e.contains("limit of 1000 pixels"), "{e}");
        assert!(err(&npy("<f4", "(2, 2, 3)", &[0; 48])).contains("not one map"));
    }
}
