use super::*;
use crate::reference::{self, test_values as values};
use crate::tensor::Planar;

/// `B^T` and `A^T` of F(4, 3) and F(2, 3), as `bt6` / `at6` and `bt4` / `at4` apply them.
const BT4: [[f64; 6]; 6] = [
    [4.0, 0.0, -5.0, 0.0, 1.0, 0.0],
    [0.0, -4.0, -4.0, 1.0, 1.0, 0.0],
    [0.0, 4.0, -4.0, -1.0, 1.0, 0.0],
    [0.0, -2.0, -1.0, 2.0, 1.0, 0.0],
    [0.0, 2.0, -1.0, -2.0, 1.0, 0.0],
    [0.0, 4.0, 0.0, -5.0, 0.0, 1.0],
];
const AT4: [[f64; 6]; 4] = [
    [1.0, 1.0, 1.0, 1.0, 1.0, 0.0],
    [0.0, 1.0, -1.0, 2.0, -2.0, 0.0],
    [0.0, 1.0, 1.0, 4.0, 4.0, 0.0],
    [0.0, 1.0, -1.0, 8.0, -8.0, 1.0],
];
const BT2: [[f64; 4]; 4] = [
    [1.0, 0.0, -1.0, 0.0],
    [0.0, 1.0, 1.0, 0.0],
    [0.0, -1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0, -1.0],
];
const AT2: [[f64; 4]; 2] = [[1.0, 1.0, 1.0, 0.0], [0.0, 1.0, -1.0, -1.0]];

/// A componentwise bound on `|bf16 Winograd - exact convolution|`, `[cout][h][w]`.
///
/// Output `(r, s)` of a tile is `y = sum_(i,j) AT[r][i] AT[s][j] M_ij` with
/// `M_e = sum_k V_ek U_ek` (`k` over `cin`), and each `M_e` is a bf16 dot product:
/// `|M^_e - M_e| <= r(cin) S_e` with `S_e = sum_k |V_ek| |U_ek|` ([`bf16::dot_bound`]).
/// So `|y^ - y| <= r(cin) sum_e |AT[r][i] AT[s][j]| S_e`, with `V` and `U` the exact (f64)
/// transforms here. The f32 arithmetic of the transforms, bias and epilogue is covered by
/// adding the f32 path's tolerance; the activations are 1-Lipschitz, so the bound holds
/// after them.
fn bf16_bound(tile: WinoTile, input: &Planar, weight: &[f32], cout: usize) -> Vec<f64> {
    let (cin, h, w) = (input.channels, input.height, input.width);
    let (m, t) = (tile.m(), tile.t());
    let bt = |i: usize, r: usize| if t == 6 { BT4[i][r] } else { BT2[i][r] };
    let at = |r: usize, i: usize| if t == 6 { AT4[r][i] } else { AT2[r][i] };
    let rel = bf16::dot_bound(cin);
    // |U[co][ci][e]|
    let u: Vec<f64> = (0..cout * cin)
        .flat_map(|oc| {
            let g = &weight[oc * 9..oc * 9 + 9];
            let gg: Vec<f64> = (0..t * 3)
                .map(|x| {
                    let (i, kx) = (x / 3, x % 3);
                    (0..3)
                        .map(|ky| tile.g(i, ky) * f64::from(g[ky * 3 + kx]))
                        .sum()
                })
                .collect();
            (0..t * t).map(move |e| {
                let (i, j) = (e / t, e % t);
                (0..3)
                    .map(|kx| gg[i * 3 + kx] * tile.g(j, kx))
                    .sum::<f64>()
                    .abs()
            })
        })
        .collect();
    let mut bound = vec![0.0f64; cout * h * w];
    let px = |c: usize, y: isize, x: isize| -> f64 {
        if y < 0 || x < 0 || y >= h as isize || x >= w as isize {
            0.0
        } else {
            f64::from(input.data[(c * h + y as usize) * w + x as usize])
        }
    };
    for oy in (0..h).step_by(m) {
        for ox in (0..w).step_by(m) {
            // |V[ci][e]| of this tile.
            let v: Vec<f64> = (0..cin)
                .flat_map(|ci| {
                    let d = move |r: usize, c: usize| {
                        px(ci, (oy + r) as isize - 1, (ox + c) as isize - 1)
                    };
                    (0..t * t).map(move |e| {
                        let (i, j) = (e / t, e % t);
                        let mut acc = 0.0;
                        for r in 0..t {
                            for c in 0..t {
                                acc += bt(i, r) * d(r, c) * bt(j, c);
                            }
                        }
                        acc.abs()
                    })
                })
                .collect();
            for co in 0..cout {
                let s_e: Vec<f64> = (0..t * t)
                    .map(|e| {
                        (0..cin)
                            .map(|ci| v[ci * t * t + e] * u[(co * cin + ci) * t * t + e])
                            .sum()
                    })
                    .collect();
                for r in 0..m.min(h - oy) {
                    for sx in 0..m.min(w - ox) {
                        let b: f64 = (0..t * t)
                            .map(|e| (at(r, e / t) * at(sx, e % t)).abs() * s_e[e])
                            .sum();
                        bound[(co * h + oy + r) * w + ox + sx] = rel * b;
                    }
                }
            }
        }
    }
    bound
}

#[test]
fn bf16_products_stay_within_the_rounding_bound() {
    // The network's block shapes (c -> c) and a decoder shape (c -> 2c, permuted), at
    // sizes that are not multiples of 4; an odd cin (a padded pair); F(2x2) on two.
    let cases = [
        (64, 64, 13, 19, WinoTile::F4),
        (128, 128, 9, 7, WinoTile::F4),
        (256, 512, 5, 6, WinoTile::F4),
        (512, 512, 4, 5, WinoTile::F4),
        (17, 24, 3, 5, WinoTile::F4),
        (16, 48, 9, 4, WinoTile::F2),
        (128, 64, 7, 6, WinoTile::F2),
    ];
    for (isa, dot) in bf16::test_variants() {
        for (i, &(cin, cout, h, w, tile)) in cases.iter().enumerate() {
            let scale = 1.5 / ((9 * cin) as f32).sqrt();
            let weight = values(i as u64 + 7, cout * cin * 9, scale);
            let bias = values(i as u64 + 70, cout, 0.1);
            let input = Planar {
                channels: cin,
                height: h,
                width: w,
                data: values(i as u64 + 700, cin * h * w, 1.0),
            };
            let order: Vec<usize> = (0..cout).map(|n| (n * 5) % cout).collect();
            let order = if cout % 5 == 0 {
                None
            } else {
                Some(&order[..])
            };
            let want = reference::activate(
                Act::Elu,
                reference::conv2d(&input, &weight, &bias, cout, 3, 1),
            );
            let bound = bf16_bound(tile, &input, &weight, cout);
            let run = |dot, schedule| {
                let conv =
                    Winograd::new(isa, dot, tile, &weight, &bias, cout, cin, Act::Elu, order);
                let src = Feature::from_planar(&input, 1);
                let mut dst = Feature::zeros(h, w, cout, 1);
                conv.run_scheduled(&src, &mut dst, &mut Pool::default(), schedule);
                dst.to_planar()
            };
            let got = run(dot, Schedule::Shared);
            let exact = run(Dot::F32, Schedule::Shared);
            // The local schedule does the same arithmetic per output.
            assert_eq!(
                run(dot, Schedule::Local { chunk: 3 }),
                got,
                "{isa:?} {dot:?} case {i}: local schedule"
            );
            let plane = h * w;
            let (mut worst, mut ratio, mut moved) = (0.0f64, 0.0f64, 0.0f32);
            for n in 0..cout {
                let o = order.map_or(n, |o| o[n]);
                for p in 0..plane {
                    let g = got.data[n * plane + p];
                    let err = (f64::from(g) - f64::from(want.data[o * plane + p])).abs();
                    let b = bound[o * plane + p] + 2e-5;
                    worst = worst.max(err);
                    ratio = ratio.max(err / b);
                    moved = moved.max((g - exact.data[n * plane + p]).abs());
                }
            }
            assert!(
                ratio <= 1.0,
                "{isa:?} {dot:?} case {i}: error {worst:e} is {ratio:.2} of its bound"
            );
            // The operands really are rounded: bf16 differs from the f32 path.
            assert!(moved > 1e-4, "{isa:?} {dot:?} case {i}: bf16 equals f32");
        }
    }
}

#[test]
fn every_isa_matches_the_reference() {
    // Sizes that are not multiples of 4 (partial tiles) and channel counts around the
    // panel widths; a permuted channel order as the decoder uses.
    // A reduction longer than KC (split into blocks that accumulate); both schedules, the
    // local one with a chunk that leaves a partial last chunk.
    let cases = [
        (16, 16, 8, 8),
        (24, 40, 5, 13),
        (32, 16, 1, 2),
        (16, 48, 9, 4),
        (200, 36, 6, 7),
    ];
    let schedules = [
        Schedule::Auto,
        Schedule::Shared,
        Schedule::Local { chunk: 1 },
        Schedule::Local { chunk: 5 },
    ];
    for (isa, tile, schedule) in Isa::supported().into_iter().flat_map(|i| {
        [WinoTile::F4, WinoTile::F2]
            .into_iter()
            .flat_map(move |t| schedules.map(|s| (i, t, s)))
    }) {
        for (i, &(cin, cout, h, w)) in cases.iter().enumerate() {
            let weight = values(i as u64 + 1, cout * cin * 9, 0.3);
            let bias = values(i as u64 + 50, cout, 0.5);
            let input = Planar {
                channels: cin,
                height: h,
                width: w,
                data: values(i as u64 + 90, cin * h * w, 1.0),
            };
            let order: Vec<usize> = (0..cout).rev().collect();
            let want = reference::activate(
                Act::Elu,
                reference::conv2d(&input, &weight, &bias, cout, 3, 1),
            );
            let conv = Winograd::new(
                isa,
                Dot::F32,
                tile,
                &weight,
                &bias,
                cout,
                cin,
                Act::Elu,
                Some(&order),
            );
            let src = Feature::from_planar(&input, 1);
            let mut dst = Feature::zeros(h, w, cout, 1);
            conv.run_scheduled(&src, &mut dst, &mut Pool::default(), schedule);
            let got = dst.to_planar();
            let mut diff = 0.0f32;
            for (n, &o) in order.iter().enumerate() {
                let plane = h * w;
                let g = &got.data[n * plane..(n + 1) * plane];
                let e = &want.data[o * plane..(o + 1) * plane];
                diff = diff.max(reference::max_abs_diff(g, e));
            }
            // f32 rounding grows with the outputs' magnitude (the long reduction).
            let scale = want.data.iter().fold(1.0f32, |m, v| m.max(v.abs()));
            assert!(
                diff < 2e-5 * scale,
                "{isa:?} {tile:?} {schedule:?} case {i}: {diff} (outputs up to {scale})"
            );
        }
    }
}
