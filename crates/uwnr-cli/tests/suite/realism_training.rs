//! `uwnr train` with `config.adversarial` on the command line: the correction trained against
//! real photos of other scenes, its own log columns and messages, and its generator rendering
//! through `uwnr render --weights`.

use std::path::Path;

use uwnr_core::Image;
use uwnr_core::io::save_rgb;

use crate::common::{s, sample, stderr, uwnr};

/// A smooth image; `k` shifts its pattern, `cast` tints it.
fn image(side: usize, k: usize, cast: [f32; 3]) -> Image {
    let mut img = Image::filled(side, side, 3, 0.0);
    for (c, gain) in cast.into_iter().enumerate() {
        for (i, v) in img.plane_mut(c).iter_mut().enumerate() {
            let (x, y) = ((i % side) as f32, (i / side) as f32);
            *v = gain * (0.5 + 0.4 * (x * (0.2 + 0.05 * c as f32) + y * 0.13 + k as f32).sin());
        }
    }
    img
}

#[test]
fn the_correction_trains_against_real_photos_and_renders() {
    let tmp = tempfile::tempdir().unwrap();
    let pairs = tmp.path().join("pairs");
    for d in ["clean", "underwater"] {
        std::fs::create_dir_all(pairs.join(d)).unwrap();
    }
    for k in 0..4 {
        let name = format!("{k:03}.png");
        save_rgb(&pairs.join("clean").join(&name), &image(48, k, [1.0; 3])).unwrap();
        // "Real" photos of another scene: a green water.
        save_rgb(
            &pairs.join("underwater").join(&name),
            &image(48, k + 7, [0.25, 0.7, 0.6]),
        )
        .unwrap();
    }
    let config = tmp.path().join("realism.json");
    std::fs::write(
        &config,
        r#"{"model": {"in_channels": 9, "out_channels": 6, "base_width": 8,
                      "light_field": "absolute", "variant": "anchored",
                      "detail_retention": true, "anchor": "water"},
            "epochs": 2, "batch_size": 2, "crop": 32, "lr": 0.002,
            "loss": {"reconstruction": 0, "perceptual": 0, "dark_channel": 0, "light_field": 0},
            "adversarial": {"discriminator": {"width": 8, "layers": 2}},
            "log_every_steps": 1, "checkpoint_every_secs": 0, "val_every_epochs": 0}"#,
    )
    .unwrap();
    let run = tmp.path().join("run");
    let o = uwnr(&[
        "train",
        "--data",
        s(&pairs),
        "--run",
        s(&run),
        "--config",
        s(&config),
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("adversarial: 1 x L_G"), "{err}");
    assert!(
        !err.contains("perceptual term"),
        "a term of weight 0 is not announced: {err}"
    );
    let metrics = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    assert!(
        metrics.starts_with("step,epoch,lr,d_loss,adversarial,content,paired,total"),
        "{metrics}"
    );
    assert_eq!(metrics.lines().count(), 1 + 4, "{metrics}");

    // The trained generator renders through --weights, and its correction runs: the render
    // differs from the bundled model's, which has none.
    let weights = run.join("checkpoints/last/generator.safetensors");
    let (clean, reference) = (sample("clean-room.jpg"), sample("ref-green.png"));
    let render = |out: &Path, extra: &[&str]| {
        let mut v = vec![
            "render",
            s(&clean),
            "--reference",
            s(&reference),
            "-o",
            s(out),
        ];
        v.extend_from_slice(extra);
        let o = uwnr(&v);
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(out).unwrap()
    };
    let trained = render(&tmp.path().join("trained.png"), &["--weights", s(&weights)]);
    let bundled = render(&tmp.path().join("bundled.png"), &[]);
    assert_ne!(trained, bundled);
}
