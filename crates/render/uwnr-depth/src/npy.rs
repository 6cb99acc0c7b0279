//! NumPy `.npy` depth maps (format versions 1-3): a 2-D array `(H, W)`, or `(1, H, W)` /
//! `(H, W, 1)`, of little-endian `float32`, `float64`, `uint16` or `uint8`, in C order; how
//! monocular and metric depth networks usually save their output.

use std::path::Path;

use uwnr_core::Image;
use uwnr_core::io::DecodeLimits;

use crate::error::{DepthError, Result};

/// The magic string that opens every `.npy` file.
const MAGIC: &[u8] = b"\x93NUMPY";

/// Reads one little-endian sample.
type ReadSample = fn(&[u8]) -> f32;

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

/// Parses the bytes of a `.npy` file (see [`load_npy`]).
pub(crate) fn parse_npy(
    bytes: &[u8],
    limits: &DecodeLimits,
) -> std::result::Result<(Image, f32), String> {
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        return Err("not a NumPy .npy file".into());
    }
    let (header_len, start) = match bytes[6] {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(format!("unsupported .npy version {v}")),
    };
    let header = bytes
        .get(start..start + header_len)
        .ok_or("truncated .npy header")?;
    let header = std::str::from_utf8(header).map_err(|_| "the .npy header is not text")?;
    let descr = field(header, "descr").ok_or("the .npy header has no descr")?;
    let descr = descr.trim().trim_matches(|c| c == '\'' || c == '"');
    if field(header, "fortran_order").is_some_and(|f| f.trim().starts_with("True")) {
        return Err("Fortran-ordered arrays are not supported; save with C order".into());
    }
    let shape = shape(header).ok_or("the .npy header has no readable shape")?;
    let (h, w) = match shape.as_slice() {
        [h, w] | [1, h, w] | [h, w, 1] => (*h, *w),
        other => return Err(format!("shape {other:?} is not one map (H, W)")),
    };
    if w == 0 || h == 0 {
        return Err(format!("shape ({h}, {w}) is empty"));
    }
    let max_dim = limits.max_dimension as usize;
    if w > max_dim || h > max_dim {
        return Err(format!(
            "{w}x{h} exceeds the {max_dim}-pixel limit on a side"
        ));
    }
    let n = w * h;
    let data = &bytes[start + header_len..];
    let (size, max_code, read): (usize, f32, ReadSample) = match descr {
        "<f4" => (4, 1.0, |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        "<f8" => (8, 1.0, |b| {
            f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f32
        }),
        "<u2" => (2, f32::from(u16::MAX), |b| {
            f32::from(u16::from_le_bytes([b[0], b[1]]))
        }),
        "|u1" | "<u1" => (1, f32::from(u8::MAX), |b| f32::from(b[0])),
        other => {
            return Err(format!(
                "dtype {other} is not supported (float32, float64, uint16 or uint8, little-endian)"
            ));
        }
    };
    if data.len() < n * size {
        return Err(format!(
            "truncated: {} bytes of data for {h}x{w} values of {size} bytes",
            data.len()
        ));
    }
    let values: Vec<f32> = data[..n * size].chunks_exact(size).map(read).collect();
    let img = Image::from_planar(w, h, 1, values).map_err(|e| e.to_string())?;
    Ok((img, max_code))
}

/// The text of `'key': value` in a header dict, up to the next top-level comma.
fn field<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header
        .find(&format!("'{key}'"))
        .or_else(|| header.find(&format!("\"{key}\"")))?;
    let rest = &header[at + key.len() + 2..];
    let rest = rest.trim_start().strip_prefix(':')?;
    let end = rest.find([',', '}']).unwrap_or(rest.len());
    Some(&rest[..end])
}

/// The `shape` tuple of a header dict.
fn shape(header: &str) -> Option<Vec<usize>> {
    let at = header
        .find("'shape'")
        .or_else(|| header.find("\"shape\""))?;
    let rest = &header[at..];
    let open = rest.find('(')?;
    let close = rest[open..].find(')')? + open;
    rest[open + 1..close]
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(|t| t.parse().ok())
        .collect()
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
    fn bad_files_say_what_is_wrong() {
        let limits = DecodeLimits::default();
        let err = |b: &[u8]| parse_npy(b, &limits).unwrap_err();
        assert!(err(b"PNG....").contains("not a NumPy"));
        assert!(err(&npy("<f4", "(2, 3)", &[0; 8])).contains("truncated"));
        assert!(err(&npy(">f4", "(1, 1)", &[0; 4])).contains("dtype >f4"));
        assert!(err(&npy("<f4", "(2, 2, 3)", &[0; 48])).contains("not one map"));
    }
}
