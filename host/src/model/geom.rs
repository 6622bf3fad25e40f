//! Small fixed-size geometry over any [`Scalar`]: 3-vectors, 3×3 matrices
//! (row-major `m[row][col]`), elementary rotations and rigid transforms.

use super::jet::Scalar;

/// A 3-vector.
pub type V3<S = f64> = [S; 3];
/// A 3×3 matrix, row-major: `m[row][col]`.
pub type M3<S = f64> = [[S; 3]; 3];

/// The zero vector.
#[inline(always)]
pub fn zero3<S: Scalar>() -> V3<S> {
    [S::cst(0.0); 3]
}

/// `a + b`.
#[inline(always)]
pub fn add<S: Scalar>(a: V3<S>, b: V3<S>) -> V3<S> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`.
#[inline(always)]
pub fn sub<S: Scalar>(a: V3<S>, b: V3<S>) -> V3<S> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a · s` for a scalar `s`.
#[inline(always)]
pub fn scale<S: Scalar>(a: V3<S>, s: S) -> V3<S> {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Cross product `a × b`.
#[inline(always)]
pub fn cross<S: Scalar>(a: V3<S>, b: V3<S>) -> V3<S> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Dot product `a · b`.
#[inline(always)]
pub fn dot<S: Scalar>(a: V3<S>, b: V3<S>) -> S {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The identity matrix.
#[inline(always)]
pub fn identity<S: Scalar>() -> M3<S> {
    let (o, z) = (S::cst(1.0), S::cst(0.0));
    [[o, z, z], [z, o, z], [z, z, o]]
}

/// `M v`.
#[inline(always)]
pub fn mul_mv<S: Scalar>(m: &M3<S>, v: V3<S>) -> V3<S> {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// `Mᵀ v`.
#[inline(always)]
pub fn mul_mtv<S: Scalar>(m: &M3<S>, v: V3<S>) -> V3<S> {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

/// `A B`.
#[inline(always)]
pub fn mul_mm<S: Scalar>(a: &M3<S>, b: &M3<S>) -> M3<S> {
    let mut c = [[S::cst(0.0); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    c
}

/// `Mᵀ`.
#[inline(always)]
pub fn transpose<S: Scalar>(m: &M3<S>) -> M3<S> {
    [
        [m[0][0], m[1][0], m[2][0]],
        [m[0][1], m[1][1], m[2][1]],
        [m[0][2], m[1][2], m[2][2]],
    ]
}

/// Column `j` of `M`.
#[inline(always)]
pub fn col<S: Scalar>(m: &M3<S>, j: usize) -> V3<S> {
    [m[0][j], m[1][j], m[2][j]]
}

/// Rotation about x by `t`.
#[inline(always)]
pub fn rot_x<S: Scalar>(t: S) -> M3<S> {
    let (s, c) = t.sin_cos();
    let (o, z) = (S::cst(1.0), S::cst(0.0));
    [[o, z, z], [z, c, -s], [z, s, c]]
}

/// Rotation about y by `t`.
#[inline(always)]
pub fn rot_y<S: Scalar>(t: S) -> M3<S> {
    let (s, c) = t.sin_cos();
    let (o, z) = (S::cst(1.0), S::cst(0.0));
    [[c, z, s], [z, o, z], [-s, z, c]]
}

/// Rotation about z by `t`.
#[inline(always)]
pub fn rot_z<S: Scalar>(t: S) -> M3<S> {
    let (s, c) = t.sin_cos();
    let (o, z) = (S::cst(1.0), S::cst(0.0));
    [[c, -s, z], [s, c, z], [z, z, o]]
}

/// Z–Y–X Euler rotation `Rz(r[0])·Ry(r[1])·Rx(r[2])` for `r = (r_z, r_y, r_x)`.
#[inline(always)]
pub fn rot_zyx<S: Scalar>(r: V3<S>) -> M3<S> {
    mul_mm(&mul_mm(&rot_z(r[0]), &rot_y(r[1])), &rot_x(r[2]))
}

/// A rigid transform `[R p; 0 1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Iso<S = f64> {
    /// Rotation.
    pub r: M3<S>,
    /// Translation.
    pub p: V3<S>,
}

impl<S: Scalar> Iso<S> {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            r: identity(),
            p: zero3(),
        }
    }

    /// A pure rotation.
    pub fn rotation(r: M3<S>) -> Self {
        Self { r, p: zero3() }
    }

    /// A pure translation.
    pub fn translation(p: V3<S>) -> Self {
        Self { r: identity(), p }
    }

    /// `self · other`.
    pub fn compose(&self, other: &Self) -> Self {
        Self {
            r: mul_mm(&self.r, &other.r),
            p: add(mul_mv(&self.r, other.p), self.p),
        }
    }

    /// The image of point `x`: `R x + p`.
    pub fn apply(&self, x: V3<S>) -> V3<S> {
        add(mul_mv(&self.r, x), self.p)
    }
}
