//! Four samples at once: [`F64x4`], a [`Scalar`] whose every operation acts
//! on four independent `f64` lanes, so that the measurement model
//! ([`crate::MeasurementModel::jacobians_x4`]) evaluates four IMU samples in
//! one pass with vector instructions (docs/model.md §4.4).
//!
//! Every lane computes exactly what the scalar code computes for its
//! sample — the same operations in the same order, no fused multiply-add —
//! so the four-lane results are bit-identical to four scalar evaluations
//! (tested in `measurement_tests.rs`; sin and cos by [`crate::trig`]). The
//! speed comes from the compiler
//! turning each lane-wise operation into one AVX instruction where the CPU
//! has it ([`has_avx2`]); elsewhere into two SSE2 instructions.

use core::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

use super::jet::Scalar;
use crate::trig;

/// Four `f64` lanes, one per sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
pub struct F64x4(pub [f64; 4]);

impl F64x4 {
    /// All lanes `v`.
    #[inline(always)]
    pub fn splat(v: f64) -> Self {
        Self([v; 4])
    }

    /// Lane `l`.
    #[inline(always)]
    pub fn lane(self, l: usize) -> f64 {
        self.0[l]
    }

    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> Self {
        Self(self.0.map(f))
    }

    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        Self([
            f(self.0[0], o.0[0]),
            f(self.0[1], o.0[1]),
            f(self.0[2], o.0[2]),
            f(self.0[3], o.0[3]),
        ])
    }
}

macro_rules! lane_op {
    ($tr:ident, $f:ident, $op:tt, $tra:ident, $fa:ident) => {
        impl $tr for F64x4 {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                self.zip(o, |a, b| a $op b)
            }
        }
        impl $tr<f64> for F64x4 {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: f64) -> Self {
                self.map(|a| a $op o)
            }
        }
        impl $tra for F64x4 {
            #[inline(always)]
            fn $fa(&mut self, o: Self) {
                *self = self.zip(o, |a, b| a $op b);
            }
        }
    };
}

lane_op!(Add, add, +, AddAssign, add_assign);
lane_op!(Sub, sub, -, SubAssign, sub_assign);
lane_op!(Mul, mul, *, MulAssign, mul_assign);

impl Div for F64x4 {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        self.zip(o, |a, b| a / b)
    }
}

impl Neg for F64x4 {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|a| -a)
    }
}

impl trig::Real for F64x4 {
    #[inline(always)]
    fn cst(v: f64) -> Self {
        Self::splat(v)
    }
}

impl Scalar for F64x4 {
    #[inline(always)]
    fn cst(v: f64) -> Self {
        Self::splat(v)
    }
    /// Lane 0 (a lane type has no single value; used only by code that
    /// inspects a value, which the four-lane paths do not).
    #[inline(always)]
    fn value(self) -> f64 {
        self.0[0]
    }
    #[inline(always)]
    fn sin(self) -> Self {
        self.sin_cos().0
    }
    #[inline(always)]
    fn cos(self) -> Self {
        self.sin_cos().1
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        self.map(f64::sqrt)
    }
    /// [`trig::sin_cos`] of each lane, the same bits: the reduction and
    /// kernels on the four lanes together, the quadrant lane by lane (every
    /// lane by the scalar function when one is not [`trig::reducible`]).
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let v: [(f64, f64); 4] = if self.0.iter().all(|&x| trig::reducible(x)) {
            let (n, s, c) = trig::reduced(self);
            std::array::from_fn(|l| trig::quadrant(self.0[l], n.0[l], s.0[l], c.0[l]))
        } else {
            self.0.map(trig::sin_cos)
        };
        (Self(v.map(|p| p.0)), Self(v.map(|p| p.1)))
    }
}

/// Whether the CPU has AVX2 (checked once, cached by `std`): the
/// four-lane kernels then run their copy compiled for it
/// (`#[target_feature(enable = "avx,avx2")]` around an `#[inline(always)]`
/// body). No FMA is enabled, so both copies compute the same bits.
#[inline]
pub fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `f()` run as compiled for AVX2 where the CPU has it ([`has_avx2`]), else
/// as is: the four-lane kernels `f` inlines (`#[inline(always)]`) then use
/// its vector instructions. The same bits either way.
#[inline(always)]
pub fn on_avx2<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx,avx2")]
        fn avx2<R>(f: impl FnOnce() -> R) -> R {
            f()
        }
        if has_avx2() {
            // SAFETY: the CPU has AVX and AVX2 (checked just above).
            return unsafe { avx2(f) };
        }
    }
    f()
}

/// The indices of `range` four at a time, one per lane of a four-lane call:
/// each quad's indices and how many of them are its own (a short last quad
/// repeats its last index in the other lanes, whose results are dropped).
pub fn quads(range: std::ops::Range<usize>) -> impl Iterator<Item = ([usize; 4], usize)> {
    let end = range.end;
    range.step_by(4).map(move |i| {
        let len = (end - i).min(4);
        (std::array::from_fn(|l| i + l.min(len - 1)), len)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_compute_what_scalars_compute() {
        let a = F64x4([0.3, -1.7, 2.5e-8, 1e300]);
        let b = F64x4([1.1, 0.25, -3.0, 7.0]);
        for l in 0..4 {
            let (x, y) = (a.0[l], b.0[l]);
            assert_eq!((a + b).0[l], x + y);
            assert_eq!((a - b).0[l], x - y);
            assert_eq!((a * b).0[l], x * y);
            assert_eq!((a / b).0[l], x / y);
            assert_eq!((-a).0[l], -x);
            assert_eq!((a * 0.7).0[l], x * 0.7);
            assert_eq!((a + 0.7).0[l], x + 0.7);
            assert_eq!(b.sin_cos().0 .0[l], Scalar::sin(y));
            assert_eq!(b.sin_cos().1 .0[l], Scalar::cos(y));
        }
    }

    /// sin and cos of four lanes give the bits of four scalar calls
    /// ([`trig::sin_cos`]) on the trig tests' arguments, also with a lane
    /// beyond [`trig::LIMIT`] (then every lane takes the scalar path), and
    /// compiled for AVX2.
    #[test]
    fn lanes_compute_the_scalar_sin_cos() {
        let args = trig::tests::arguments();
        for chunk in args.chunks_exact(4) {
            let x = F64x4([chunk[0], chunk[1], chunk[2], chunk[3]]);
            let (s, c) = x.sin_cos();
            for l in 0..4 {
                let (s1, c1) = trig::sin_cos(chunk[l]);
                assert_eq!(
                    (s.0[l].to_bits(), c.0[l].to_bits()),
                    (s1.to_bits(), c1.to_bits())
                );
            }
        }
        let x = F64x4([0.3, -2.0, 7.5, -1e-9]);
        let on = on_avx2(|| x.sin_cos());
        for l in 0..4 {
            let (s1, c1) = trig::sin_cos(x.0[l]);
            assert_eq!(
                (on.0 .0[l].to_bits(), on.1 .0[l].to_bits()),
                (s1.to_bits(), c1.to_bits())
            );
        }
    }

    /// Every index once, in order, four to a quad; a short last quad
    /// repeats its last index; an empty range gives no quad.
    #[test]
    fn quads_cover_the_range_in_order() {
        assert_eq!(quads(3..3).count(), 0);
        let q: Vec<_> = quads(5..11).collect();
        assert_eq!(q, vec![([5, 6, 7, 8], 4), ([9, 10, 10, 10], 2)]);
        for end in 0..13 {
            let own: Vec<usize> = quads(0..end)
                .flat_map(|(q, len)| q[..len].to_vec())
                .collect();
            assert_eq!(own, (0..end).collect::<Vec<_>>());
        }
    }
}
