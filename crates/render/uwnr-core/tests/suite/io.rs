//! Decoding, encoding, limits and atomic writes of `uwnr_core::io`.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageBuffer, ImageEncoder, ImageFormat, Luma, LumaA, Rgb, Rgba};
use tempfile::TempDir;
use uwnr_core::io::{
    DecodeLimits, is_image_path, load_gray, load_rgb, load_rgb_from_memory, save_gray, save_rgb,
    save_rgb16, to_rgb8, write_atomic, write_atomic_bytes,
};
use uwnr_core::{CoreError, Image};

fn limits() -> DecodeLimits {
    DecodeLimits::default()
}

/// A 16x8 RGB test pattern: left half red-ish, right half blue-ish, with a gradient.
fn pattern() -> image::RgbImage {
    ImageBuffer::from_fn(16, 8, |x, y| {
        if x < 8 {
            Rgb([200, (y * 10) as u8, 30])
        } else {
            Rgb([20, (x * 5) as u8, 220])
        }
    })
}

fn encode(img: &DynamicImage, format: ImageFormat) -> Vec<u8> {
    let mut bytes = Vec::new();
    img.write_to(&mut Cursor::new(&mut bytes), format).unwrap();
    bytes
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

fn assert_decode_error(result: uwnr_core::Result<Image>, what: &str) {
    match result {
        Err(CoreError::Decode { source, .. }) => {
            println!("{what}: {source}");
            assert!(!source.to_string().is_empty());
        }
        other => panic!("{what}: expected a decode error, got {other:?}"),
    }
}

#[test]
fn png_rgb8_loads_as_code_over_255() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("p.png");
    DynamicImage::ImageRgb8(pattern()).save(&path).unwrap();
    let img = load_rgb(&path, &limits()).unwrap();
    assert_eq!((img.width(), img.height(), img.channels()), (16, 8, 3));
    assert_eq!(img.get(0, 0, 0), 200.0 / 255.0);
    assert_eq!(img.get(1, 3, 2), 30.0 / 255.0);
    assert_eq!(img.get(2, 0, 15), 220.0 / 255.0);
    assert_eq!(to_rgb8(&img), pattern().into_raw());
}

#[test]
fn grey_grey_alpha_and_rgba_load() {
    let dir = TempDir::new().unwrap();
    let grey = ImageBuffer::from_fn(4, 3, |x, y| Luma([(x * 60 + y) as u8]));
    let path = dir.path().join("g.png");
    DynamicImage::ImageLuma8(grey.clone()).save(&path).unwrap();
    let rgb = load_rgb(&path, &limits()).unwrap();
    assert_eq!(rgb.channels(), 3);
    for c in 0..3 {
        assert_eq!(rgb.get(c, 2, 3), 182.0 / 255.0);
    }
    let g = load_gray(&path, &limits()).unwrap();
    assert_eq!(g.channels(), 1);
    assert_eq!(g.get(0, 1, 2), 121.0 / 255.0);

    let la = ImageBuffer::from_fn(4, 3, |x, _| LumaA([(x * 50) as u8, 7]));
    let path = dir.path().join("la.png");
    DynamicImage::ImageLumaA8(la).save(&path).unwrap();
    assert_eq!(
        load_gray(&path, &limits()).unwrap().get(0, 0, 3),
        150.0 / 255.0
    );

    // Alpha is dropped; the colour values are used as stored (not premultiplied).
    let rgba = ImageBuffer::from_fn(4, 3, |_, _| Rgba([10, 20, 30, 0]));
    let path = dir.path().join("rgba.png");
    DynamicImage::ImageRgba8(rgba).save(&path).unwrap();
    let img = load_rgb(&path, &limits()).unwrap();
    assert_eq!(to_rgb8(&img)[..3], [10, 20, 30]);
}

#[test]
fn sixteen_bit_and_float_images_load() {
    let dir = TempDir::new().unwrap();
    let depth = ImageBuffer::from_fn(5, 2, |x, y| Luma([(x * 10_000 + y * 7) as u16]));
    let path = dir.path().join("depth.png");
    DynamicImage::ImageLuma16(depth).save(&path).unwrap();
    let g = load_gray(&path, &limits()).unwrap();
    assert_eq!(g.get(0, 1, 4), 40_007.0 / 65_535.0);

    let rgb16 = ImageBuffer::from_fn(3, 2, |x, _| Rgb([x as u16 * 30_000, 65_535, 1]));
    let path = dir.path().join("rgb16.png");
    DynamicImage::ImageRgb16(rgb16).save(&path).unwrap();
    let img = load_rgb(&path, &limits()).unwrap();
    assert_eq!(img.get(0, 0, 2), 60_000.0 / 65_535.0);
    assert_eq!(img.get(1, 1, 1), 1.0);

    let float = ImageBuffer::from_fn(3, 2, |x, _| Rgb([x as f32 * 0.25, 2.0, -1.0]));
    let path = dir.path().join("f.tiff");
    DynamicImage::ImageRgb32F(float).save(&path).unwrap();
    let img = load_rgb(&path, &limits()).unwrap();
    assert_eq!(img.get(0, 0, 2), 0.5);
    // Floats are clamped to [0, 1].
    assert_eq!(img.get(1, 0, 0), 1.0);
    assert_eq!(img.get(2, 0, 0), 0.0);
}

#[test]
fn rgb_to_grey_is_pil_luma() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("c.png");
    let img = ImageBuffer::from_vec(3, 1, vec![200, 100, 50, 255, 255, 255, 1, 2, 250]).unwrap();
    DynamicImage::ImageRgb8(img).save(&path).unwrap();
    let g = load_gray(&path, &limits()).unwrap();
    // PIL: Image.new("RGB", (1, 1), c).convert("L") gives 124, 255, 30.
    let codes: Vec<f32> = g.data().iter().map(|v| (v * 255.0).round()).collect();
    assert_eq!(codes, [124.0, 255.0, 30.0]);
}

#[test]
fn exif_orientation_is_applied() {
    // TIFF structure (big endian) with one IFD entry: Orientation (0x0112) = 6, "rotate 90 CW".
    let exif: Vec<u8> = vec![
        b'M', b'M', 0, 42, 0, 0, 0, 8, // header, IFD at offset 8
        0, 1, // one entry
        0x01, 0x12, 0, 3, 0, 0, 0, 1, 0, 6, 0, 0, // Orientation, SHORT, count 1, value 6
        0, 0, 0, 0, // no next IFD
    ];
    let mut bytes = Vec::new();
    let mut encoder = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 95);
    encoder.set_exif_metadata(exif).unwrap();
    encoder
        .write_image(&pattern().into_raw(), 16, 8, image::ExtendedColorType::Rgb8)
        .unwrap();
    let img = load_rgb_from_memory(&bytes, &limits()).unwrap();
    assert_eq!(img.size(), (8, 16), "rotated by 90 degrees");
    // Rotating clockwise puts the left (red) half of the stored image on top.
    assert!(img.get(0, 2, 4) > 0.6 && img.get(2, 2, 4) < 0.3);
    assert!(img.get(0, 13, 4) < 0.3 && img.get(2, 13, 4) > 0.6);
}

#[test]
fn broken_files_are_decode_errors() {
    let dir = TempDir::new().unwrap();
    let png = encode(&DynamicImage::ImageRgb8(pattern()), ImageFormat::Png);
    let jpeg = encode(&DynamicImage::ImageRgb8(pattern()), ImageFormat::Jpeg);
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty.png", Vec::new()),
        ("truncated.png", png[..png.len() / 2].to_vec()),
        ("truncated.jpg", jpeg[..jpeg.len() / 2].to_vec()),
        ("header-only.jpg", jpeg[..20].to_vec()),
        ("corrupt.png", {
            let mut b = png.clone();
            for v in &mut b[40..] {
                *v = v.wrapping_mul(31).wrapping_add(7);
            }
            b
        }),
        ("text.png", b"this is not an image at all".to_vec()),
        ("notes.txt", b"plain text".to_vec()),
    ];
    for (name, bytes) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, &bytes).unwrap();
        assert_decode_error(load_rgb(&path, &limits()), name);
        assert_decode_error(load_rgb_from_memory(&bytes, &limits()), name);
    }
    // The untouched files decode.
    assert!(load_rgb_from_memory(&png, &limits()).is_ok());
    assert!(load_rgb_from_memory(&jpeg, &limits()).is_ok());
}

#[test]
fn missing_file_is_an_io_error() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("absent.png");
    match load_rgb(&path, &limits()) {
        Err(CoreError::Io { path: p, .. }) => assert_eq!(p, path),
        other => panic!("expected an io error, got {other:?}"),
    }
}

/// A PNG whose header claims `width x height`, followed by the first two bytes of a zlib
/// stream: enough for a decoder to read the header, far from enough pixel data.
fn png_claiming(width: u32, height: u32) -> Vec<u8> {
    fn crc32(bytes: &[u8]) -> u32 {
        let mut crc = 0xFFFF_FFFF_u32;
        for &b in bytes {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    }
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]); // 8-bit RGB
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend_from_slice(&13_u32.to_be_bytes());
    png.extend_from_slice(&ihdr);
    png.extend_from_slice(&crc32(&ihdr).to_be_bytes());
    let idat = b"IDAT\x78\x9c";
    png.extend_from_slice(&2_u32.to_be_bytes());
    png.extend_from_slice(idat);
    png.extend_from_slice(&crc32(idat).to_be_bytes());
    png
}

#[test]
fn oversized_headers_fail_before_decoding() {
    // 60000 x 60000 RGB would need 10.8 GB: it must be refused from the header alone.
    let bytes = png_claiming(60_000, 60_000);
    match load_rgb_from_memory(&bytes, &limits()) {
        Err(CoreError::TooLarge {
            width,
            height,
            max_pixels,
            ..
        }) => assert_eq!((width, height, max_pixels), (60_000, 60_000, 250_000_000)),
        other => panic!("expected TooLarge, got {other:?}"),
    }
    let bytes = png_claiming(70_000, 10);
    assert!(matches!(
        load_rgb_from_memory(&bytes, &limits()),
        Err(CoreError::DimensionTooLarge { width: 70_000, .. })
    ));

    // A real image above a custom limit.
    let png = encode(&DynamicImage::ImageRgb8(pattern()), ImageFormat::Png);
    let small = DecodeLimits {
        max_pixels: 100,
        max_dimension: 1000,
    };
    assert!(matches!(
        load_rgb_from_memory(&png, &small),
        Err(CoreError::TooLarge {
            width: 16,
            height: 8,
            ..
        })
    ));
    let narrow = DecodeLimits {
        max_pixels: 1000,
        max_dimension: 15,
    };
    assert!(matches!(
        load_rgb_from_memory(&png, &narrow),
        Err(CoreError::DimensionTooLarge { width: 16, .. })
    ));
}

#[test]
fn save_and_reload_png_jpeg_and_16bit() {
    let dir = TempDir::new().unwrap();
    let hwc: Vec<f32> = (0..6 * 4 * 3).map(|i| (i % 17) as f32 / 16.0).collect();
    let img = Image::from_interleaved(6, 4, 3, &hwc).unwrap();

    let png = dir.path().join("out.PNG");
    save_rgb(&png, &img).unwrap();
    let back = load_rgb(&png, &limits()).unwrap();
    assert_eq!(to_rgb8(&back), to_rgb8(&img));

    let jpg = dir.path().join("out.JPeG");
    save_rgb(&jpg, &img).unwrap();
    let back = load_rgb(&jpg, &limits()).unwrap();
    assert_eq!(back.size(), (6, 4));

    let png16 = dir.path().join("out16.png");
    save_rgb16(&png16, &img).unwrap();
    let back = load_rgb(&png16, &limits()).unwrap();
    for (a, b) in back.data().iter().zip(img.data()) {
        assert!((a - b).abs() <= 0.5 / 65_535.0 + 1e-7);
    }
    assert!(save_rgb16(&dir.path().join("out16.jpg"), &img).is_err());

    let grey = Image::from_planar(3, 2, 1, vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0]).unwrap();
    let gpath = dir.path().join("g.png");
    save_gray(&gpath, &grey).unwrap();
    let back = load_gray(&gpath, &limits()).unwrap();
    let codes: Vec<f32> = back.data().iter().map(|v| v * 255.0).collect();
    assert_eq!(codes, [0.0, 51.0, 102.0, 153.0, 204.0, 255.0]);
    // Wrong channel counts are refused.
    assert!(save_gray(&gpath, &img).is_err());
    assert!(save_rgb(&png, &grey).is_err());

    assert_eq!(
        files_in(dir.path()),
        ["g.png", "out.JPeG", "out.PNG", "out16.png"]
    );
}

#[test]
fn failed_saves_leave_nothing_behind() {
    let dir = TempDir::new().unwrap();
    let img = Image::filled(4, 4, 3, 0.5);

    // Unknown extension.
    match save_rgb(&dir.path().join("out.gif"), &img) {
        Err(CoreError::Encode { path, source }) => {
            assert!(path.ends_with("out.gif"));
            assert!(source.to_string().contains("gif"));
        }
        other => panic!("expected an encode error, got {other:?}"),
    }
    // Directory that does not exist.
    let missing = dir.path().join("no-such-dir").join("out.png");
    match save_rgb(&missing, &img) {
        Err(CoreError::Io { path, .. }) => assert_eq!(path, missing),
        other => panic!("expected an io error, got {other:?}"),
    }
    // The target is a directory: the rename fails after the temporary file was written.
    let target = dir.path().join("taken.png");
    std::fs::create_dir(&target).unwrap();
    std::fs::write(target.join("keep"), b"x").unwrap();
    assert!(matches!(save_rgb(&target, &img), Err(CoreError::Io { .. })));
    // The writer itself fails half way.
    let partial = dir.path().join("partial.bin");
    let result = write_atomic(&partial, |w| {
        w.write_all(b"half")?;
        Err(std::io::Error::other("disk full"))
    });
    assert!(matches!(result, Err(CoreError::Io { .. })));

    assert_eq!(files_in(dir.path()), ["taken.png"]);
}

#[test]
fn write_atomic_replaces_the_file() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("a.txt");
    std::fs::write(&path, b"old").unwrap();
    write_atomic(&path, |w| w.write_all(b"new")).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"new");
    assert_eq!(files_in(dir.path()), ["a.txt"]);
}

#[test]
fn write_atomic_bytes_writes_a_new_file_and_refuses_a_folder() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("b.bin");
    write_atomic_bytes(&path, &[1, 2, 3]).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), [1, 2, 3]);
    // An existing folder cannot be replaced by a file: the error names the target and the
    // temporary file is gone.
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    std::fs::write(sub.join("keep"), b"x").unwrap();
    assert!(matches!(
        write_atomic_bytes(&sub, b"y"),
        Err(CoreError::Io { path, .. }) if path == sub
    ));
    assert_eq!(files_in(dir.path()), ["b.bin", "sub"]);
}

#[test]
fn to_rgb8_rounds_half_up_and_clamps() {
    let img = Image::from_planar(
        5,
        1,
        1,
        vec![0.5 / 255.0, 0.49 / 255.0, 254.6 / 255.0, -0.3, 1.7],
    )
    .unwrap();
    let rgb = to_rgb8(&img);
    let reds: Vec<u8> = rgb.chunks(3).map(|p| p[0]).collect();
    assert_eq!(reds, [1, 0, 255, 0, 255]);
    assert!(rgb.chunks(3).all(|p| p[0] == p[1] && p[1] == p[2]));
}

#[test]
fn image_paths_by_extension() {
    for p in [
        "a.png", "b.JPG", "c.jpeg", "d.bmp", "e.tif", "f.TIFF", "g.webp",
    ] {
        assert!(is_image_path(Path::new(p)), "{p}");
    }
    for p in ["a.gif", "b", "c.png.txt", ".png"] {
        assert!(!is_image_path(Path::new(p)), "{p}");
    }
}

#[test]
fn paths_read_from_files_must_stay_inside_their_folder() {
    use uwnr_core::io::stays_inside;
    for ok in ["a.png", "underwater/a_0.png", "./clean/x.jpg", "a..b/c"] {
        assert!(stays_inside(Path::new(ok)), "{ok}");
    }
    for bad in [
        "",
        ".",
        "../secret.txt",
        "clean/../../x",
        "/etc/passwd",
        "a/../b",
    ] {
        assert!(!stays_inside(Path::new(bad)), "{bad}");
    }
}
