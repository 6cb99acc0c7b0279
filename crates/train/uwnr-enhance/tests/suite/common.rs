//! Tiny paired folders written to a temp dir.

use std::path::{Path, PathBuf};

use uwnr_core::Image;
use uwnr_core::io::save_rgb;

/// A smooth clean image and its "underwater" version (a colour cast plus haze).
pub fn pair(w: usize, h: usize, k: usize) -> (Image, Image) {
    let mut clean = Image::filled(w, h, 3, 0.0);
    for c in 0..3 {
        let p = clean.plane_mut(c);
        for y in 0..h {
            for x in 0..w {
                let t = (x as f32 * (0.21 + 0.05 * c as f32) + y as f32 * 0.13 + k as f32).sin();
                p[y * w + x] = 0.5 + 0.4 * t;
            }
        }
    }
    let gain = [0.35, 0.8, 0.9];
    let haze = [0.05, 0.15, 0.1];
    let mut uw = clean.clone();
    for c in 0..3 {
        for v in uw.plane_mut(c) {
            *v = *v * gain[c] + haze[c];
        }
    }
    (clean, uw)
}

/// `root/underwater/NNN.png` + `root/clean/NNN.png`, `n` pairs of `w x h`.
pub fn make_dir(root: &Path, n: usize, w: usize, h: usize) -> PathBuf {
    std::fs::create_dir_all(root.join("clean")).unwrap();
    std::fs::create_dir_all(root.join("underwater")).unwrap();
    for k in 0..n {
        let (c, u) = pair(w, h, k);
        let name = format!("{k:03}.png");
        save_rgb(&root.join("clean").join(&name), &c).unwrap();
        save_rgb(&root.join("underwater").join(&name), &u).unwrap();
    }
    root.to_path_buf()
}
