//! Small fixed-size geometry over any [`Scalar`]: 3-vectors, 3×3 matrices
//! (row-major `m[row][col]`), elementary rotations and rigid transforms.

use super::jet::Scalar;

/// A 3-vector.
pub type V3<S = f64> = [S; 3];
/// A 3×3 matrix, row-major: `m[row][col]`.
pub type M3<S = f64> = [[S; 3]; 3];

/// The zero vector.
#[inline(always)]
pub(crate) fn zero3<S: Scalar>() -> V3<S> {
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
pub(crate) fn rot_zyx<S: Scalar>(r: V3<S>) -> M3<S> {
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

// ---------------------------------------------------------------- SO(3)

/// exp of a rotation vector (Rodrigues).
pub fn exp_so3(w: V3) -> M3 {
    let th = dot(w, w).sqrt();
    let k = [[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]];
    let (a, b) = if th < 1e-8 {
        (1.0, 0.5)
    } else {
        (th.sin() / th, (1.0 - th.cos()) / (th * th))
    };
    let k2 = mul_mm(&k, &k);
    let mut r = identity();
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] += a * k[i][j] + b * k2[i][j];
        }
    }
    r
}

/// Unit quaternion `[w, x, y, z]` (w ≥ 0) of a rotation matrix.
pub fn quat_from_matrix(r: &M3) -> [f64; 4] {
    let tr = r[0][0] + r[1][1] + r[2][2];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [
            0.25 * s,
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
        ]
    } else if r[0][0] > r[1][1] && r[0][0] > r[2][2] {
        let s = (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt() * 2.0;
        [
            (r[2][1] - r[1][2]) / s,
            0.25 * s,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
        ]
    } else if r[1][1] > r[2][2] {
        let s = (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt() * 2.0;
        [
            (r[0][2] - r[2][0]) / s,
            (r[0][1] + r[1][0]) / s,
            0.25 * s,
            (r[1][2] + r[2][1]) / s,
        ]
    } else {
        let s = (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt() * 2.0;
        [
            (r[1][0] - r[0][1]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            0.25 * s,
        ]
    };
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
    q.map(|v| sign * v / n)
}

/// Rotation matrix of a quaternion `[w, x, y, z]` (normalised first).
pub fn matrix_from_quat(q: [f64; 4]) -> M3 {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let [w, x, y, z] = q.map(|v| v / n);
    [
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ]
}

/// log of a rotation matrix: the rotation vector (angle ≤ π).
pub fn log_so3(r: &M3) -> V3 {
    let q = quat_from_matrix(r);
    let v = [q[1], q[2], q[3]];
    let s = dot(v, v).sqrt();
    if s < 1e-12 {
        return scale(v, 2.0);
    }
    scale(v, 2.0 * s.atan2(q[0]) / s)
}

/// Quaternion product a ⊗ b, `[w, x, y, z]`.
pub fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    let (va, vb) = ([a[1], a[2], a[3]], [b[1], b[2], b[3]]);
    let v = add(add(scale(vb, a[0]), scale(va, b[0])), cross(va, vb));
    [a[0] * b[0] - dot(va, vb), v[0], v[1], v[2]]
}

/// Inverse of a 3×3 matrix by cofactors; `None` when (nearly) singular.
pub fn inverse3(m: &M3) -> Option<M3> {
    let c = |i: usize, j: usize| {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
        m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    let scale = m.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
    if !det.is_finite() || det.abs() <= 1e-12 * scale.powi(3) {
        return None;
    }
    let mut inv = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            inv[j][i] = c(i, j) / det;
        }
    }
    Some(inv)
}

/// The rotation nearest to `m` (its polar factor, for det m > 0), by the
/// averaging iteration R ← (R + R⁻ᵀ)/2; `None` when an iterate is singular.
pub fn nearest_rotation(m: &M3) -> Option<M3> {
    let mut r = *m;
    for _ in 0..100 {
        let inv = inverse3(&r)?;
        let mut next = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                next[i][j] = 0.5 * (r[i][j] + inv[j][i]);
            }
        }
        let diff: f64 = (0..9)
            .map(|k| (next[k / 3][k % 3] - r[k / 3][k % 3]).abs())
            .sum();
        r = next;
        if diff < 1e-15 {
            break;
        }
    }
    Some(r)
}

impl Iso<f64> {
    /// The inverse transform: `(Rᵀ, −Rᵀ p)`.
    pub fn inverse(&self) -> Self {
        let rt = transpose(&self.r);
        Self {
            r: rt,
            p: scale(mul_mv(&rt, self.p), -1.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_maps_round_trip() {
        for w in [
            [0.1, -0.2, 0.3],
            [2.0, 1.0, -0.5],
            [1e-9, 0.0, 0.0],
            [0.0, 3.1, 0.0],
        ] {
            let r = exp_so3(w);
            let back = log_so3(&r);
            for k in 0..3 {
                assert!((back[k] - w[k]).abs() < 1e-9, "{w:?} -> {back:?}");
            }
            let r2 = matrix_from_quat(quat_from_matrix(&r));
            for i in 0..3 {
                for j in 0..3 {
                    assert!((r[i][j] - r2[i][j]).abs() < 1e-12);
                }
            }
        }
        // q ⊗ q* = identity
        let q = quat_from_matrix(&exp_so3([0.3, 0.2, -0.7]));
        let e = quat_mul(q, [q[0], -q[1], -q[2], -q[3]]);
        assert!((e[0] - 1.0).abs() < 1e-12 && e[1].abs() < 1e-12);
    }
}
