//! The SO(3) helpers of the pose spline that [`crate::geom`] lacks: the hat
//! and vee maps, Exp over any [`Scalar`] (for jets), the right and left
//! Jacobians and their inverses (Sommer et al. 2020, §2; Barfoot, *State
//! Estimation for Robotics*, §7.1.3; Solà et al. 2018, "A micro Lie theory"). Exp and Log of f64 rotations and
//! the quaternion conversions are [`crate::geom`]'s
//! ([`exp_so3`](crate::geom::exp_so3), [`log_so3`](crate::geom::log_so3),
//! [`matrix_from_quat`](crate::geom::matrix_from_quat),
//! [`quat_from_matrix`](crate::geom::quat_from_matrix)).

use crate::geom::{dot, identity, mul_mm, M3, V3};
use crate::jet::Scalar;

/// Below this squared angle Exp and the Jacobians use their Taylor series.
const SMALL_ANGLE2: f64 = 1e-8;

/// `[w]×`, the skew matrix with `[w]× v = w × v`.
pub fn hat<S: Scalar>(w: V3<S>) -> M3<S> {
    let z = S::cst(0.0);
    [[z, -w[2], w[1]], [w[2], z, -w[0]], [-w[1], w[0], z]]
}

/// The vector of the skew-symmetric part of `m` (`vee(hat(w)) = w`).
pub(crate) fn vee(m: &M3) -> V3 {
    [
        0.5 * (m[2][1] - m[1][2]),
        0.5 * (m[0][2] - m[2][0]),
        0.5 * (m[1][0] - m[0][1]),
    ]
}

/// `I + a·[w]× + b·[w]×²`.
fn rodrigues_form<S: Scalar>(w: V3<S>, a: S, b: S) -> M3<S> {
    let k = hat(w);
    let k2 = mul_mm(&k, &k);
    let mut r = identity::<S>();
    for i in 0..3 {
        for j in 0..3 {
            r[i][j] += a * k[i][j] + b * k2[i][j];
        }
    }
    r
}

/// Exp of a rotation vector over any scalar (Rodrigues), exact in its
/// derivatives also at w = 0: below a small angle sin θ/θ and (1 − cos θ)/θ²
/// are series in θ², so no square root of zero appears.
pub fn exp_s<S: Scalar>(w: V3<S>) -> M3<S> {
    let th2 = dot(w, w);
    let (a, b) = if th2.value() < SMALL_ANGLE2 {
        (
            S::cst(1.0) - th2 * (1.0 / 6.0) + th2 * th2 * (1.0 / 120.0),
            S::cst(0.5) - th2 * (1.0 / 24.0) + th2 * th2 * (1.0 / 720.0),
        )
    } else {
        let th = th2.sqrt();
        let (s, c) = th.sin_cos();
        (s / th, (S::cst(1.0) - c) / th2)
    };
    rodrigues_form(w, a, b)
}

/// The right Jacobian J_r(φ): Exp(φ + δ) ≈ Exp(φ)·Exp(J_r(φ) δ);
/// `J_r(φ) = I − (1 − cos θ)/θ² [φ]× + (θ − sin θ)/θ³ [φ]×²`.
pub fn right_jacobian(phi: V3) -> M3 {
    let th2 = dot(phi, phi);
    let (a, b) = if th2 < SMALL_ANGLE2 {
        (0.5 - th2 / 24.0, 1.0 / 6.0 - th2 / 120.0)
    } else {
        let th = th2.sqrt();
        ((1.0 - th.cos()) / th2, (th - th.sin()) / (th2 * th))
    };
    rodrigues_form(phi, -a, b)
}

/// The left Jacobian J_l(φ) = J_r(−φ) = Exp(φ)·J_r(φ).
#[cfg(test)]
pub(crate) fn left_jacobian(phi: V3) -> M3 {
    right_jacobian([-phi[0], -phi[1], -phi[2]])
}

/// `J_r(φ)⁻¹ = I + ½[φ]× + (1/θ² − (1 + cos θ)/(2θ sin θ)) [φ]×²`, for θ < π
/// (it diverges as θ → 2π; near θ = π it is finite).
pub(crate) fn right_jacobian_inv(phi: V3) -> M3 {
    let th2 = dot(phi, phi);
    let c = if th2 < SMALL_ANGLE2 {
        1.0 / 12.0 + th2 / 720.0
    } else {
        let th = th2.sqrt();
        1.0 / th2 - (1.0 + th.cos()) / (2.0 * th * th.sin())
    };
    rodrigues_form(phi, 0.5, c)
}

/// J_l(φ)⁻¹ = J_r(−φ)⁻¹.
pub(crate) fn left_jacobian_inv(phi: V3) -> M3 {
    right_jacobian_inv([-phi[0], -phi[1], -phi[2]])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{exp_so3, log_so3, matrix_from_quat, quat_from_matrix, transpose};
    use crate::jet::Jet;

    fn max_diff(a: &M3, b: &M3) -> f64 {
        (0..9)
            .map(|k| (a[k / 3][k % 3] - b[k / 3][k % 3]).abs())
            .fold(0.0, f64::max)
    }

    /// exp([w]×) by its power series Σ [w]×ᵏ/k!.
    fn exp_series(w: V3) -> M3 {
        let k = hat(w);
        // term_n = [w]×ⁿ/n!, summed until it is far below rounding
        let (mut term, mut sum) = (identity::<f64>(), identity::<f64>());
        for n in 1..60 {
            term = mul_mm(&term, &k);
            for row in &mut term {
                for v in row {
                    *v /= n as f64;
                }
            }
            for i in 0..3 {
                for j in 0..3 {
                    sum[i][j] += term[i][j];
                }
            }
        }
        sum
    }

    const VECTORS: [V3; 6] = [
        [0.1, -0.2, 0.3],
        [2.0, 1.0, -0.5],
        [1e-9, 0.0, 2e-9],
        [0.0, 3.1, 0.0],
        [1e-5, -2e-5, 3e-5],
        [-1.2, 0.4, 1.9],
    ];

    #[test]
    fn exp_matches_the_power_series_and_geom() {
        let mut worst = 0.0f64;
        for w in VECTORS {
            let r = exp_s(w);
            worst = worst.max(max_diff(&r, &exp_series(w)));
            worst = worst.max(max_diff(&r, &exp_so3(w)));
        }
        assert!(worst < 1e-13, "Exp vs series: {worst:e}");
    }

    #[test]
    fn log_near_zero_and_near_pi() {
        let axis = {
            let a = [0.3f64, -0.5, 0.8];
            let n = dot(a, a).sqrt();
            a.map(|v| v / n)
        };
        for th in [1e-12, 1e-7, 0.5, 3.0, std::f64::consts::PI - 1e-7] {
            let w = axis.map(|v| v * th);
            let back = log_so3(&exp_series(w));
            let err = (0..3).map(|k| (back[k] - w[k]).abs()).fold(0.0, f64::max);
            assert!(err < 1e-9 * th.max(1e-3), "θ = {th}: err {err:e}");
        }
        // exactly π: ±axis·π, both the same rotation
        let w = axis.map(|v| v * std::f64::consts::PI);
        let back = log_so3(&exp_series(w));
        assert!((dot(back, back).sqrt() - std::f64::consts::PI).abs() < 1e-9);
        assert!(max_diff(&exp_s(back), &exp_series(w)) < 1e-12);
    }

    #[test]
    fn quaternion_round_trips_and_sign() {
        for w in VECTORS {
            let r = exp_s(w);
            let q = quat_from_matrix(&r);
            assert!(max_diff(&matrix_from_quat(q), &r) < 1e-14);
            assert!(max_diff(&matrix_from_quat(q.map(|v| -v)), &r) < 1e-14);
            // the quaternion of Exp(w) is (cos θ/2, sin θ/2 · w/θ) up to sign
            let th = dot(w, w).sqrt();
            let s = if th > 0.0 { (0.5 * th).sin() / th } else { 0.5 };
            let q2 = [(0.5 * th).cos(), w[0] * s, w[1] * s, w[2] * s];
            let d = (0..4).map(|k| (q[k] - q2[k]).abs()).fold(0.0, f64::max);
            assert!(d < 1e-14, "{q:?} vs {q2:?}");
        }
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let h = 1e-6;
        for phi in VECTORS {
            let jr = right_jacobian(phi);
            let jl = left_jacobian(phi);
            let r0t = transpose(&exp_s(phi));
            for c in 0..3 {
                let mut p = phi;
                let mut m = phi;
                p[c] += h;
                m[c] -= h;
                // Exp(φ)ᵀ Exp(φ ± h e_c) ≈ Exp(± h J_r e_c)
                let lp = log_so3(&mul_mm(&r0t, &exp_s(p)));
                let lm = log_so3(&mul_mm(&r0t, &exp_s(m)));
                let lpl = log_so3(&mul_mm(&exp_s(p), &r0t));
                let lml = log_so3(&mul_mm(&exp_s(m), &r0t));
                for i in 0..3 {
                    let fd = (lp[i] - lm[i]) / (2.0 * h);
                    let fdl = (lpl[i] - lml[i]) / (2.0 * h);
                    assert!((fd - jr[i][c]).abs() < 1e-8, "J_r {phi:?}");
                    assert!((fdl - jl[i][c]).abs() < 1e-8, "J_l {phi:?}");
                }
            }
            let ir = mul_mm(&right_jacobian_inv(phi), &jr);
            let il = mul_mm(&left_jacobian_inv(phi), &jl);
            assert!(max_diff(&ir, &identity()) < 1e-12);
            assert!(max_diff(&il, &identity()) < 1e-12);
        }
    }

    #[test]
    fn jet_exp_derivatives_at_zero_and_away() {
        for w0 in [[0.0, 0.0, 0.0], [0.4, -0.1, 0.2], [1e-6, 0.0, 0.0]] {
            let w: V3<Jet<3>> = [0, 1, 2].map(|k| Jet::variable(w0[k], k));
            let r = exp_s(w);
            let h = 1e-6;
            for c in 0..3 {
                let (mut p, mut m) = (w0, w0);
                p[c] += h;
                m[c] -= h;
                let (rp, rm) = (exp_s(p), exp_s(m));
                for i in 0..3 {
                    for j in 0..3 {
                        let fd = (rp[i][j] - rm[i][j]) / (2.0 * h);
                        assert!((r[i][j].d[c] - fd).abs() < 1e-9);
                    }
                }
            }
        }
    }
}
