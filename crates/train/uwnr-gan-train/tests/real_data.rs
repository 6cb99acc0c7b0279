//! A few GAN steps on the shared real data, when `../shared/data` (from the project root) is
//! present: NYU RGB-D images with their measured depth (`rgb_N.jpg` matched to
//! `sync_depth_N.png`) and Set5 with the built-in prior as the clean side, U45 as the
//! references. Small crops and networks keep it to seconds. Skips with a message otherwise.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use burn::tensor::Device;
use uwnr_gan_train::model::{DiscriminatorConfig, GeneratorConfig};
use uwnr_gan_train::{
    Event, GanConfig, GanTrainConfig, RunSettings, TrainOptions, load_generator, render,
};

fn shared() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../../shared/data")
}

#[test]
fn a_few_steps_on_real_rgbd_and_underwater_images() {
    let data = shared();
    let (nyu, set5, u45) = (
        data.join("rgbd/nyu"),
        data.join("inair/set5"),
        data.join("references/u45/U45"),
    );
    if !(nyu.is_dir() && set5.is_dir() && u45.is_dir()) {
        eprintln!("skipped: the shared data ({}) is absent", data.display());
        return;
    }
    let cfg = GanTrainConfig {
        model: GanConfig {
            generator: GeneratorConfig {
                z_dim: 16,
                widths: vec![8, 16],
                hidden: 16,
                encoder_size: 32,
                ..GeneratorConfig::default()
            },
            discriminator: DiscriminatorConfig {
                width: 8,
                layers: 3,
            },
        },
        epochs: 1,
        batch_size: 2,
        crop: 64,
        val_images: 2,
        run: RunSettings {
            val_sheet_pairs: 2,
            log_every_steps: 1,
            checkpoint_every_secs: 0,
            ..GanTrainConfig::default().run
        },
        max_images_per_dir: Some(12),
        ..GanTrainConfig::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let opts = TrainOptions::new(vec![nyu, set5], run.clone(), Device::flex());
    let mut report = String::new();
    let s = uwnr_gan_train::train(&cfg, &opts, &[u45], &AtomicBool::new(false), &mut |e| {
        if let Event::Message(m) = e {
            report.push_str(m);
        }
    })
    .unwrap();
    // NYU's three images found their maps; Set5 used the prior.
    assert!(report.contains("3 images, depth from maps"), "{report}");
    assert!(report.contains("built-in prior"), "{report}");
    assert!(!report.contains("skipped"), "{report}");
    assert_eq!(s.step, 4, "8 clean images in batches of 2");
    assert!(
        s.losses
            .iter()
            .all(|(_, v)| v.iter().all(|x| x.is_finite()))
    );
    let g = load_generator(&s.last_weights, &Device::flex()).unwrap();
    let clean = uwnr_core::Image::filled(40, 30, 3, 0.6);
    let depth = uwnr_core::Image::filled(40, 30, 1, 0.5);
    let out = render(&g, &clean, &depth, 1, &Device::flex()).unwrap();
    assert_eq!(out.size(), (40, 30));
}
