//! bf16 bits, one value at a time, through the `half` crate: an f32 rounded to bf16 (to nearest,
//! ties to even, as `vcvtne2ps2bf16`) and bf16 bits widened back to f32 (exact). The emulated kernels and run
//! rounding of [`super::bf16`] and the tail of the AVX512_BF16 run rounding use this rule.

/// `x` rounded to the nearest bf16, ties to even (NaN stays NaN, quietened): the `half` crate's
/// conversion.
#[inline(always)]
#[must_use]
pub fn round(x: f32) -> u16 {
    half::bf16::from_f32(x).to_bits()
}

/// The f32 value of bf16 bits `h` (exact).
#[inline(always)]
#[must_use]
pub fn widen(h: u16) -> f32 {
    half::bf16::from_bits(h).to_f32()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_is_to_nearest_even() {
        // 1 + 2^-8 is halfway between 1 and 1 + 2^-7: ties to the even 1.
        assert_eq!(round(1.0 + 2f32.powi(-8)), round(1.0));
        // 1 + 3 * 2^-8 is halfway between 1 + 2^-7 (odd) and 1 + 2^-6: up to the even one.
        assert_eq!(widen(round(1.0 + 3.0 * 2f32.powi(-8))), 1.0 + 2f32.powi(-6));
        // Just above halfway rounds up.
        assert_eq!(
            widen(round(1.0 + 2f32.powi(-8) + 2f32.powi(-20))),
            1.0 + 2f32.powi(-7)
        );
        assert_eq!(widen(round(-2.5)), -2.5);
        assert!(widen(round(f32::NAN)).is_nan());
        assert_eq!(widen(round(f32::INFINITY)), f32::INFINITY);
        assert_eq!(widen(round(f32::MAX)), f32::INFINITY);
        // Relative error at most 2^-8 over a sweep of magnitudes.
        let mut x = 1e-30f32;
        while x < 1e30 {
            for s in [1.0f32, -1.0] {
                let v = s * x;
                let rel = ((widen(round(v)) - v) / v).abs();
                assert!(rel <= 2f32.powi(-8), "{v}: {rel}");
            }
            x *= 1.013;
        }
    }
}
