//! Scalars for the model functions: `f64` and the forward-mode jet.
//!
//! A [`Jet<N>`] carries a value and its gradient with respect to `N` seeded
//! inputs: `(a, ∇a) ∘ (b, ∇b)` follows the chain rule exactly, so a model
//! function written once over [`Scalar`] yields values (with `f64`) and exact
//! first derivatives (with `Jet<N>`). The fixed width keeps a jet on the stack.

use core::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A real number type the model functions are generic over (`f64`, [`Jet`]).
pub trait Scalar:
    Copy
    + core::fmt::Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
{
    /// A constant (zero gradient).
    fn cst(v: f64) -> Self;
    /// The value, without derivatives.
    fn value(self) -> f64;
    /// Sine.
    fn sin(self) -> Self;
    /// Cosine.
    fn cos(self) -> Self;
    /// Square root (the caller guarantees a positive argument).
    fn sqrt(self) -> Self;
    /// `(sin, cos)` together.
    fn sin_cos(self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
}

impl Scalar for f64 {
    #[inline(always)]
    fn cst(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn value(self) -> f64 {
        self
    }
    #[inline(always)]
    fn sin(self) -> Self {
        crate::trig::sin_cos(self).0
    }
    #[inline(always)]
    fn cos(self) -> Self {
        crate::trig::sin_cos(self).1
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        crate::trig::sin_cos(self)
    }
}

/// Forward-mode dual number: value `v` and gradient `d` (∂v/∂input_k for k < N).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jet<const N: usize> {
    /// Value.
    pub v: f64,
    /// Gradient with respect to the N seeded inputs.
    pub d: [f64; N],
}

impl<const N: usize> Jet<N> {
    /// The `k`-th independent variable with value `v` (gradient = unit vector k).
    ///
    /// # Panics
    /// If `k >= N`.
    #[track_caller]
    pub fn variable(v: f64, k: usize) -> Self {
        assert!(k < N, "jet variable index {k} out of range for width {N}");
        let mut d = [0.0; N];
        d[k] = 1.0;
        Self { v, d }
    }

    #[inline(always)]
    fn scale_grad(&self, s: f64) -> [f64; N] {
        let mut d = self.d;
        for x in &mut d {
            *x *= s;
        }
        d
    }
}

impl<const N: usize> Add for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn add(mut self, o: Self) -> Self {
        self.v += o.v;
        for (a, b) in self.d.iter_mut().zip(o.d.iter()) {
            *a += *b;
        }
        self
    }
}

impl<const N: usize> Sub for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(mut self, o: Self) -> Self {
        self.v -= o.v;
        for (a, b) in self.d.iter_mut().zip(o.d.iter()) {
            *a -= *b;
        }
        self
    }
}

impl<const N: usize> Mul for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let mut d = [0.0; N];
        for ((dk, a), b) in d.iter_mut().zip(&self.d).zip(&o.d) {
            *dk = a * o.v + b * self.v;
        }
        Self { v: self.v * o.v, d }
    }
}

impl<const N: usize> Div for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let v = self.v * inv;
        let mut d = [0.0; N];
        for ((dk, a), b) in d.iter_mut().zip(&self.d).zip(&o.d) {
            *dk = (a - v * b) * inv;
        }
        Self { v, d }
    }
}

impl<const N: usize> Neg for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self {
            v: -self.v,
            d: self.scale_grad(-1.0),
        }
    }
}

impl<const N: usize> Add<f64> for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn add(mut self, o: f64) -> Self {
        self.v += o;
        self
    }
}

impl<const N: usize> Sub<f64> for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(mut self, o: f64) -> Self {
        self.v -= o;
        self
    }
}

impl<const N: usize> Mul<f64> for Jet<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: f64) -> Self {
        Self {
            v: self.v * o,
            d: self.scale_grad(o),
        }
    }
}

impl<const N: usize> AddAssign for Jet<N> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<const N: usize> SubAssign for Jet<N> {
    #[inline(always)]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}

impl<const N: usize> MulAssign for Jet<N> {
    #[inline(always)]
    fn mul_assign(&mut self, o: Self) {
        *self = *self * o;
    }
}

impl<const N: usize> Scalar for Jet<N> {
    #[inline(always)]
    fn cst(v: f64) -> Self {
        Self { v, d: [0.0; N] }
    }
    #[inline(always)]
    fn value(self) -> f64 {
        self.v
    }
    #[inline(always)]
    fn sin(self) -> Self {
        let (s, c) = crate::trig::sin_cos(self.v);
        Self {
            v: s,
            d: self.scale_grad(c),
        }
    }
    #[inline(always)]
    fn cos(self) -> Self {
        let (s, c) = crate::trig::sin_cos(self.v);
        Self {
            v: c,
            d: self.scale_grad(-s),
        }
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let r = self.v.sqrt();
        Self {
            v: r,
            d: self.scale_grad(0.5 / r),
        }
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = crate::trig::sin_cos(self.v);
        (
            Self {
                v: s,
                d: self.scale_grad(c),
            },
            Self {
                v: c,
                d: self.scale_grad(-s),
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// f(x, y) = sin(x)·y / sqrt(x + y²) − cos(y), derivatives against the
    /// hand-derived closed form.
    #[test]
    fn jet_matches_closed_form_derivatives() {
        let (x0, y0) = (0.7, -1.3);
        let x = Jet::<2>::variable(x0, 0);
        let y = Jet::<2>::variable(y0, 1);
        let f = x.sin() * y / (x + y * y).sqrt() - y.cos();
        let r = (x0 + y0 * y0).sqrt();
        let fx = x0.cos() * y0 / r - 0.5 * x0.sin() * y0 / (r * r * r);
        let fy = x0.sin() / r - x0.sin() * y0 * y0 / (r * r * r) + y0.sin();
        assert!((f.v - (x0.sin() * y0 / r - y0.cos())).abs() < 1e-15);
        assert!((f.d[0] - fx).abs() < 1e-14, "{} vs {}", f.d[0], fx);
        assert!((f.d[1] - fy).abs() < 1e-14, "{} vs {}", f.d[1], fy);
    }
}
