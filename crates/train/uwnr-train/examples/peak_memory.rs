//! Peak memory and time of one full-width render at a given size with the default
//! [`RenderOptions`] (tiled above 1024 x 1024 px), random weights and a synthetic scene.
//!
//! `cargo run --release -p uwnr-train --example peak_memory -- 4000 3000`
//! prints the wall time and the process's peak resident set (VmHWM, Linux).

use std::time::Instant;

use uwnr_core::Image;
use uwnr_model::{GeneratorConfig, RenderOptions};
use uwnr_train::burn_render::render;
use uwnr_train::{Device, GeneratorInit};

fn vm_hwm_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let w: usize = args.next().map_or(Ok(4000), |a| a.parse())?;
    let h: usize = args.next().map_or(Ok(3000), |a| a.parse())?;
    let width: usize = args.next().map_or(Ok(64), |a| a.parse())?;

    let device = Device::flex();
    device.seed(0);
    let generator = GeneratorConfig::with_base_width(width).init(&device)?;
    let plane = |c: usize| {
        (0..h)
            .flat_map(move |y| (0..w).map(move |x| ((x * 7 + y * 3 + c * 11) % 256) as f32 / 255.0))
    };
    let clean = Image::from_planar(w, h, 3, (0..3).flat_map(plane).collect())?;
    let depth = Image::from_planar(w, h, 1, plane(5).collect())?;
    let lf = Image::from_planar(w, h, 3, (0..3).flat_map(|c| plane(c + 1)).collect())?;
    let before = vm_hwm_kib().unwrap_or(0);
    let t = Instant::now();
    let out = render(
        &generator,
        &clean,
        &depth,
        &lf,
        &RenderOptions::default(),
        &device,
    )?;
    let secs = t.elapsed().as_secs_f64();
    let peak = vm_hwm_kib().unwrap_or(0);
    println!(
        "render {w}x{h} width {width}: {secs:.1} s, output {}x{}, VmHWM {:.0} MiB (before the render, with the inputs: {:.0} MiB)",
        out.width(),
        out.height(),
        peak as f64 / 1024.0,
        before as f64 / 1024.0
    );
    Ok(())
}
