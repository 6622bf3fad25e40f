//! sin and cos of the model's angles, for one value ([`sin_cos`]) and, with
//! the same operations on any [`Real`] (the four lanes of
//! [`crate::lanes::F64x4`]), for several at once ([`reduced`] and
//! [`quadrant`]), so that both give the same bits (docs/model.md §4.4).
//!
//! The joint angles' sin and cos are needed at every sample of every pass;
//! the C library's `sincos` takes one value at a time (and saves and restores
//! the rounding mode on each call), which was 6 % of a whole `robimu
//! calibrate`. Here the argument is reduced to y = x − nπ/2, |y| ≤ π/4, with
//! a three-part Cody–Waite split of π/2 (exact products for |n| < 2²⁰; here
//! |n| < 2¹⁷) into a
//! head and tail y₀ + y₁ (as fdlibm's `__rem_pio2`), and sin y, cos y come from
//! fdlibm's minimax kernels (`__kernel_sin`, `__kernel_cos`: error < 1 ulp);
//! the quadrant n mod 4 swaps and negates them. Only +, −, × (no fused
//! multiply-add, which Rust never forms on its own): every lane computes
//! exactly what [`sin_cos`] computes for its value. Outside |x| ≤ [`LIMIT`]
//! (and for NaN, ±∞) the C library's `sincos` is used, lane by lane.

// fdlibm's constants, digit for digit (each rounds to the double fdlibm uses)
#![allow(clippy::excessive_precision)]

use core::ops::{Add, Mul, Sub};

/// What the reduction and the kernels compute with: `f64`, or several
/// `f64` lanes whose every operation acts lane by lane.
pub trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
{
    /// The constant `v` (in every lane).
    fn cst(v: f64) -> Self;
}

impl Real for f64 {
    #[inline(always)]
    fn cst(v: f64) -> Self {
        v
    }
}

/// Largest |x| reduced here (|n| < 2¹⁷, well inside the 2²⁰ of exact products).
pub(crate) const LIMIT: f64 = 1.0e5;

const TOINT: f64 = 1.5 / f64::EPSILON;
const INV_PIO2: f64 = std::f64::consts::FRAC_2_PI;
// π/2 = P₁ + P₂ + P₃: two 33-bit parts and the rest (fdlibm's pio2_1, pio2_2, pio2_2t)
const PIO2_1: f64 = 1.570_796_326_734_125_614_17e0;
const PIO2_2: f64 = 6.077_100_506_303_965_976_60e-11;
const PIO2_2T: f64 = 2.022_266_248_795_950_631_54e-21;
// fdlibm __kernel_sin
const S1: f64 = -1.666_666_666_666_663_243_48e-1;
const S2: f64 = 8.333_333_333_322_489_461_24e-3;
const S3: f64 = -1.984_126_982_985_794_931_34e-4;
const S4: f64 = 2.755_731_370_707_006_767_89e-6;
const S5: f64 = -2.505_076_025_340_686_341_95e-8;
const S6: f64 = 1.589_690_995_211_550_102_21e-10;
// fdlibm __kernel_cos
const C1: f64 = 4.166_666_666_666_660_190_37e-2;
const C2: f64 = -1.388_888_888_887_410_957_49e-3;
const C3: f64 = 2.480_158_728_947_672_941_78e-5;
const C4: f64 = -2.755_731_435_139_066_330_35e-7;
const C5: f64 = 2.087_572_321_298_174_827_90e-9;
const C6: f64 = -1.135_964_755_778_819_482_65e-11;

/// n = rint(x·2/π) and the reduced argument y₀ + y₁ = x − nπ/2, |n| < 2¹⁷:
/// x − n·P₁ and n·P₂ are exact (33-bit parts, Sterbenz), their difference
/// is split exactly into a sum and its rounding error (Knuth's two-sum),
/// and n·P₃ (π/2 − P₁ − P₂) enters the tail.
#[inline(always)]
fn reduce<S: Real>(x: S) -> (S, S, S) {
    let n = (x * INV_PIO2 + TOINT) - TOINT;
    let a = x - n * PIO2_1;
    let b = n * PIO2_2;
    let s = a - b;
    let v = s - a;
    let e = (a - (s - v)) - (b + v);
    let t = e - n * PIO2_2T;
    let y0 = s + t;
    let y1 = t - (y0 - s);
    (n, y0, y1)
}

/// sin(y₀ + y₁) and cos(y₀ + y₁) for |y₀| ≤ π/4 (fdlibm's kernels).
#[inline(always)]
fn kernels<S: Real>(x: S, y: S) -> (S, S) {
    let z = x * x;
    let w = z * z;
    // __kernel_sin(x, y, 1)
    let r = S::cst(S2) + z * (S::cst(S3) + z * S4) + z * w * (S::cst(S5) + z * S6);
    let v = z * x;
    let s = x - ((z * (y * 0.5 - v * r) - y) - v * S1);
    // __kernel_cos(x, y)
    let r = z * (S::cst(C1) + z * (S::cst(C2) + z * C3))
        + w * w * (S::cst(C4) + z * (S::cst(C5) + z * C6));
    let hz = z * 0.5;
    let w = S::cst(1.0) - hz;
    let c = w + (((S::cst(1.0) - w) - hz) + (z * r - x * y));
    (s, c)
}

/// n = rint(x·2/π) and the kernels' sin y, cos y of y = x − nπ/2, for x
/// with [`reducible`] true (in every lane); [`quadrant`] then gives
/// (sin x, cos x) from them.
#[inline(always)]
pub fn reduced<S: Real>(x: S) -> (S, S, S) {
    let (n, y0, y1) = reduce(x);
    let (s, c) = kernels(y0, y1);
    (n, s, c)
}

/// Whether x is reduced here (|x| ≤ [`LIMIT`], not NaN); else [`sin_cos`]
/// takes the C library's values.
#[inline(always)]
pub(crate) fn reducible(x: f64) -> bool {
    x.abs() <= LIMIT
}

/// (sin x, cos x) from the kernels' values in quadrant n mod 4 (x = ±0
/// keeps its sign in sin x, which the reduction's sums lose).
#[inline(always)]
pub(crate) fn quadrant(x: f64, n: f64, s: f64, c: f64) -> (f64, f64) {
    if x == 0.0 {
        return (x, 1.0);
    }
    match (n as i64) & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// (sin x, cos x), within 1 ulp of the exact values.
#[inline(always)]
pub fn sin_cos(x: f64) -> (f64, f64) {
    if !reducible(x) {
        return f64::sin_cos(x);
    }
    let (n, s, c) = reduced(x);
    quadrant(x, n, s, c)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Distance in units in the last place (same-sign finite values).
    fn ulps(a: f64, b: f64) -> u64 {
        if a == b {
            return 0;
        }
        let key = |v: f64| {
            let i = v.to_bits() as i64;
            if i < 0 {
                i64::MIN - i
            } else {
                i
            }
        };
        key(a).abs_diff(key(b))
    }

    /// Arguments: a dense sweep of the joint range, the neighbourhoods of
    /// multiples of π/4 (where the reduction cancels and the quadrant turns),
    /// tiny and signed zeros, and large values up to and beyond [`LIMIT`].
    pub(crate) fn arguments() -> Vec<f64> {
        let mut v: Vec<f64> = (0..200_001).map(|i| -10.0 + 1e-4 * i as f64).collect();
        for k in -400i32..=400 {
            let m = k as f64 * std::f64::consts::FRAC_PI_4;
            let mut x = m;
            for _ in 0..8 {
                v.push(x);
                x = x.next_up();
            }
            x = m;
            for _ in 0..8 {
                x = x.next_down();
                v.push(x);
            }
        }
        v.extend([
            0.0,
            -0.0,
            1e-300,
            -1e-300,
            1e-8,
            -3e-9,
            std::f64::consts::FRAC_PI_4.next_up(),
        ]);
        v.extend(
            (0..2000).map(|i| (i as f64 * 1.618).powf(1.5) * if i % 2 == 0 { 1.0 } else { -1.0 }),
        );
        v.extend([LIMIT, -LIMIT, LIMIT.next_up(), 1e6, 1e20, f64::MAX]);
        v
    }

    /// Within 1 ulp of the C library's (correctly rounded in practice) sin
    /// and cos everywhere, and exactly its values outside [`LIMIT`].
    #[test]
    fn sin_cos_is_within_one_ulp_of_the_c_library() {
        let mut worst = (0, 0.0);
        let mut differ = 0usize;
        let args = arguments();
        for &x in &args {
            let (s, c) = sin_cos(x);
            let (s0, c0) = f64::sin_cos(x);
            let d = ulps(s, s0).max(ulps(c, c0));
            if d > worst.0 {
                worst = (d, x);
            }
            differ += usize::from(d > 0);
            if x.abs() > LIMIT {
                assert_eq!((s.to_bits(), c.to_bits()), (s0.to_bits(), c0.to_bits()));
            }
        }
        assert!(worst.0 <= 1, "{} ulp at x = {:e}", worst.0, worst.1);
        // not the C library by another name: some last bits differ (6 % of
        // these arguments, each by one ulp)
        assert!(
            differ > 0 && differ < args.len() / 8,
            "{differ} of {}",
            args.len()
        );
        assert_eq!(sin_cos(-0.0).0.to_bits(), (-0.0f64).to_bits());
        assert!(sin_cos(f64::NAN).0.is_nan() && sin_cos(f64::INFINITY).1.is_nan());
    }

    /// Against an independent reference: sin and cos of x summed as Taylor
    /// series in double-double arithmetic after reducing by 2π in
    /// double-double (x ≤ 10 rad), to 1 ulp.
    #[test]
    fn sin_cos_matches_a_double_double_taylor_series() {
        // (hi, lo) pairs, error-free transformations
        fn two_sum(a: f64, b: f64) -> (f64, f64) {
            let s = a + b;
            let v = s - a;
            (s, (a - (s - v)) + (b - v))
        }
        fn two_prod(a: f64, b: f64) -> (f64, f64) {
            let p = a * b;
            (p, a.mul_add(b, -p))
        }
        fn add(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
            let (s, e) = two_sum(a.0, b.0);
            two_sum(s, e + a.1 + b.1)
        }
        fn mul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
            let (p, e) = two_prod(a.0, b.0);
            two_sum(p, e + a.0 * b.1 + a.1 * b.0)
        }
        fn div_n(a: (f64, f64), n: f64) -> (f64, f64) {
            let q = a.0 / n;
            let (p, e) = two_prod(q, n);
            let r = (a.0 - p - e + a.1) / n;
            two_sum(q, r)
        }
        // 2π as a double-double
        const TWO_PI: (f64, f64) = (std::f64::consts::TAU, 2.449_293_598_294_706_4e-16);
        let mut worst = 0;
        for i in 0..4001 {
            let x = -10.0 + 0.005 * i as f64 + 1e-7;
            let k = (x / TWO_PI.0).round();
            let y = add((x, 0.0), mul((-k, 0.0), TWO_PI));
            let (mut s, mut c) = ((0.0, 0.0), (1.0, 0.0));
            let mut term = (1.0, 0.0);
            for n in 1..40 {
                term = div_n(mul(term, y), n as f64);
                match n % 4 {
                    1 => s = add(s, term),
                    2 => c = add(c, (-term.0, -term.1)),
                    3 => s = add(s, (-term.0, -term.1)),
                    _ => c = add(c, term),
                }
            }
            let (fs, fc) = sin_cos(x);
            worst = worst.max(ulps(fs, s.0)).max(ulps(fc, c.0));
        }
        assert!(worst <= 1, "{worst} ulp");
    }
}
