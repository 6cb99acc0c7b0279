//! Activations applied to a stored tile, written as plain loops over `f32` that the compiler
//! vectorises inside each instruction set's `#[target_feature]` kernel: LeakyReLU, ELU
//! (`alpha = 1`), tanh and sigmoid, the last three through one polynomial `exp`.
//!
//! `exp` is Cephes' `expf`: `x = n ln 2 + r` with `|r| <= ln 2 / 2` (`ln 2` split in two parts
//! so `r` is exact), `e^r` by a degree-6 polynomial, `2^n` built from the exponent bits. Its
//! relative error is below 2e-7 on [-87, 88]; inputs are clamped to that range.

use crate::Act;

/// LeakyReLU negative slope of the network (`nn.LeakyReLU()` default in FSU2.py).
pub const LEAKY_RELU_SLOPE: f32 = 0.01;

const EXP_HI: f32 = 88.376_26;
const EXP_LO: f32 = -87.336_55;
const LOG2E: f32 = std::f32::consts::LOG2_E;
const LN2_HI: f32 = 0.693_359_4;
const LN2_LO: f32 = -2.121_944_4e-4;
/// 1.5 * 2^23: adding and subtracting it rounds an f32 of magnitude < 2^22 to the nearest
/// integer (ties to even) without a rounding instruction, so the loop vectorises everywhere.
const ROUND_MAGIC: f32 = 12_582_912.0;
const EXP_P: [f32; 6] = [
    1.987_569_1e-4,
    1.398_199_9e-3,
    8.333_452e-3,
    4.166_579_6e-2,
    1.666_666_5e-1,
    5e-1,
];

/// `e^x` (Cephes `expf`).
#[inline(always)]
#[must_use]
pub fn exp(x: f32) -> f32 {
    let x = x.clamp(EXP_LO, EXP_HI);
    let shifted = x * LOG2E + ROUND_MAGIC;
    let n = shifted - ROUND_MAGIC;
    let r = x - n * LN2_HI - n * LN2_LO;
    let mut p = EXP_P[0];
    for c in &EXP_P[1..] {
        p = p * r + c;
    }
    let e = p * r * r + r + 1.0;
    // n is an integer in [-126, 127], held in the low mantissa bits of `shifted` (whose bits
    // are those of ROUND_MAGIC plus n): 2^n from the exponent field by integer arithmetic,
    // which vectorises where the saturating `n as i32` does not.
    let bits = (shifted
        .to_bits()
        .wrapping_sub(ROUND_MAGIC.to_bits())
        .wrapping_add(127))
        << 23;
    e * f32::from_bits(bits)
}

/// Applies `act` to every value of `v`.
#[inline(always)]
pub fn apply(act: Act, v: &mut [f32]) {
    match act {
        Act::Identity => {}
        Act::LeakyRelu => {
            for x in v {
                *x = x.max(*x * LEAKY_RELU_SLOPE);
            }
        }
        Act::Elu => {
            for x in v {
                let e = exp(x.min(0.0)) - 1.0;
                *x = if *x > 0.0 { *x } else { e };
            }
        }
        Act::Tanh => {
            for x in v {
                *x = tanh(*x);
            }
        }
    }
}

/// `tanh(x) = 1 - 2 / (e^(2x) + 1)`, absolute error below 3e-7.
#[inline(always)]
#[must_use]
pub fn tanh(x: f32) -> f32 {
    1.0 - 2.0 / (exp(2.0 * x) + 1.0)
}

/// `1 / (1 + e^-x)`.
#[inline(always)]
#[must_use]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + exp(-x))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_matches_std() {
        let mut worst = 0.0f64;
        for i in -8700..=8800 {
            let x = i as f32 * 0.01;
            let want = f64::from(x).exp();
            let rel = ((f64::from(exp(x)) - want) / want).abs();
            worst = worst.max(rel);
        }
        assert!(worst < 3e-7, "{worst}");
        assert_eq!(exp(-1000.0), exp(EXP_LO));
        assert!(exp(1000.0).is_finite());
    }

    #[test]
    fn activations_match_std() {
        for i in -2000..=2000 {
            let x = i as f32 * 0.005;
            assert!((tanh(x) - x.tanh()).abs() < 3e-7, "tanh {x}");
            let s = 1.0 / (1.0 + (-x).exp());
            assert!((sigmoid(x) - s).abs() < 3e-7, "sigmoid {x}");
            let mut v = [x];
            apply(Act::Elu, &mut v);
            let elu = if x > 0.0 { x } else { x.exp_m1() };
            assert!((v[0] - elu).abs() < 3e-7, "elu {x}");
            let mut v = [x];
            apply(Act::LeakyRelu, &mut v);
            assert_eq!(v[0], if x > 0.0 { x } else { x * LEAKY_RELU_SLOPE });
        }
        assert_eq!(tanh(100.0), 1.0);
        assert_eq!(tanh(-100.0), -1.0);
    }
}
