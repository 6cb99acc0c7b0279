//! What turns a clean image into its underwater twin in a dataset run: a render method of
//! `uwnr-render` (the UWNR network, the UWGAN-style GAN baseline, the physical and statistical
//! baselines, or plain haze), shared with `uwnr render`, experiments and Python.

pub use uwnr_render::{ReferenceInput, Renderer, Worker, depth_record, fnv1a64};

#[cfg(test)]
mod tests {
    use super::*;
    use uwnr_core::Image;
    use uwnr_model::{GeneratorConfig, RenderOptions};

    #[test]
    fn a_run_whose_workers_cannot_start_is_incomplete_and_verify_agrees() {
        let tmp = tempfile::tempdir().unwrap();
        let (clean, refs) = (tmp.path().join("clean"), tmp.path().join("refs"));
        std::fs::create_dir_all(&clean).unwrap();
        std::fs::create_dir_all(&refs).unwrap();
        for k in 0..2 {
            let img = Image::filled(24, 20, 3, 0.2 + 0.3 * k as f32);
            uwnr_core::io::save_rgb(&clean.join(format!("c{k}.png")), &img).unwrap();
            uwnr_core::io::save_rgb(&refs.join(format!("r{k}.png")), &img).unwrap();
        }
        let config = GeneratorConfig::with_base_width(8);
        let tensors = uwnr_model::weights::keys::seeded_tensors(&config, 1);
        let (network, _) =
            uwnr_model::Network::from_tensors(&config, tensors, &uwnr_model::Backend::Engine)
                .unwrap();
        let renderer = Renderer::network(network, RenderOptions::default(), "test".into(), b"");
        // A worker takes its copy of the network under the lock: a poisoned lock stops every
        // worker from starting.
        let _ = std::thread::scope(|s| {
            s.spawn(|| {
                let _held = renderer.lock_network_for_test();
                panic!("poisoning the network's lock");
            })
            .join()
        });
        let spec = crate::Spec {
            clean: vec![clean],
            references: vec![refs],
            per_image: 1,
            seed: 1,
            size: crate::Size::Native,
            save_depth: false,
            save_lightfield: false,
            depth: uwnr_depth::DepthSource::Builtin,
            depth_policy: uwnr_render::DepthPolicy::default(),
            labels: crate::LabelInputs::default(),
            target: None,
            camera: uwnr_render::Camera::NONE,
        };
        let opts = crate::RunOptions {
            shard: None,
            jobs: 2,
            limits: uwnr_core::io::DecodeLimits::default(),
            gallery: true,
        };
        let out = tmp.path().join("out");
        let stop = std::sync::atomic::AtomicBool::new(false);
        let summary = crate::generate(&out, &spec, &renderer, &opts, &stop, &mut |_| {}).unwrap();
        assert_eq!(summary.rendered, 0);
        assert!(summary.failures.is_empty() && !summary.interrupted);
        assert!(!summary.complete && !summary.ok());
        assert_eq!(
            summary.worker_errors.len(),
            2,
            "{:?}",
            summary.worker_errors
        );
        let report = crate::verify(&out, &|_, _| {}).unwrap();
        assert!(!report.ok());
        assert!(
            report.problems.iter().any(|p| p.contains("missing")),
            "{:?}",
            report.problems
        );
    }
}
